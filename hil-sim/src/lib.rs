//! Software-in-the-loop: the robots' bodies, sensors and radio simulated around their real
//! control code (natively, or the firmware in QEMU) and the real base station.
//!
//! - [`plant`]: differential-drive bodies, motors, encoders;
//! - [`radio`]: the byte pipe between nodes: latency, jitter, loss, corruption, baud;
//! - [`brain`]: the control code a robot runs;
//! - [`world`]: everything on one simulated clock;
//! - [`metrics`]: what a run measured; [`report`], [`plot`], [`trace`]: its report, figure
//!   and CSV trace; [`run`]: one run, start to report.

pub mod brain;
pub mod faults;
pub mod metrics;
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
pub mod trace;
pub mod world;
