//! Software-in-the-loop: the robots' bodies, sensors and radio simulated around their real
//! control code (natively, or the firmware in QEMU) and the real base station.
//!
//! Module map:
//!
//! - [`world`]: everything on one simulated clock, a step in named phases (faults,
//!   radio arrivals, localization, scan and station, control, bodies, observation);
//! - [`plant`]: differential-drive bodies, motors, encoders;
//! - [`movers`]: people, cyclists and vehicles, oblivious or social (the social force
//!   model), and crowds;
//! - sensors: [`scanner`] (the leader's lidar) and [`ring`] (each robot's ultrasonic
//!   ring), which see the movers as they see obstacles;
//! - [`radio`]: the byte pipe between nodes: latency, jitter, loss, corruption, baud;
//! - [`brain`]: the control code a robot runs, natively or in [`qemu`];
//! - [`faults`]: faults and attacks injected on schedule; [`observer`]: what the judge
//!   hears on the air when the station is another process;
//! - [`metrics`]: what a run measured ([`swept`]: the ground the brushes swept); [`exposure`]: the parked fleet a moving one is
//!   judged against among oblivious movers; [`report`], [`plot`], [`trace`], [`recording`]: its
//!   report, figure, CSV trace and MCAP; [`run`]: one run, start to report.

pub mod brain;
pub mod exposure;
pub mod faults;
pub mod metrics;
pub mod movers;
pub mod observer;
pub mod plant;
pub mod plot;
pub mod qemu;
pub mod radio;
pub mod recording;
pub mod report;
pub mod ring;
pub mod run;
pub mod scanner;
pub mod swept;
pub mod trace;
pub mod tracking_bench;
pub mod world;
