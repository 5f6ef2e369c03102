//! `basestation robots SCENARIO --udp ADDR | --pty`: the scenario's robots (bodies,
//! sensors, their control code natively or as firmware in QEMU) in real time behind a real
//! transport, for `basestation run` to drive exactly as it drives real robots. The simulated
//! radio sits between the transport and the robots, with the scenario's `[link]`.
//!
//! Prints one line on standard output once the transport is open:
//! `udp ADDR` (the bound address) or `pty PATH` (the device for `run --port`). At the end
//! (goal reached and settled, `--duration`, or Ctrl-C) writes the report `sim` writes.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context;
use base_station::transport::{Transport, UdpAnswer};
use clap::Args;
use hil_sim::world::{BaseSide, FixPath, SimOptions, World};

use crate::live::feeds::localization::{FixPublisher, PublishArg};

#[derive(Args, Debug)]
pub struct RobotsArgs {
    /// A scenario file, or a shipped scenario's name (paper-obstacles, paper-passage,
    /// street-crossing, plaza-crowd, plaza-sweep, street-block-sweep).
    pub scenario: String,
    /// Listen for the base station on this UDP address; answer whoever sent last.
    #[arg(long, conflicts_with = "pty", required_unless_present = "pty")]
    pub udp: Option<SocketAddr>,
    /// Behind a pseudo-terminal pair that behaves as a serial radio modem; its device path
    /// is printed for `run --port`.
    #[arg(long)]
    pub pty: bool,
    /// Write the run's report here when it ends (the schema of `sim`'s report); none
    /// without it.
    #[arg(long, value_name = "FILE.json")]
    pub report: Option<PathBuf>,
    /// End after this many seconds [default: the scenario's duration].
    #[arg(long)]
    pub duration: Option<f64>,
    /// Publish the robots' position fixes to the base station instead of handing them to
    /// the robots directly: `feed:ADDR` (the line feed over UDP) or `nmea:ID=ADDR` (NMEA
    /// 0183 over UDP for robot ID; repeat per robot). See docs/operating.md#4-localization.
    #[arg(long = "publish-fixes", value_name = "KIND:ADDR")]
    pub publish_fixes: Vec<PublishArg>,
    /// Send the leader's scans (hits on what the map does not hold, 10 Hz) as the scan
    /// feed to this UDP address, for `run --scan-feed`.
    #[arg(long, value_name = "ADDR")]
    pub publish_scan: Option<std::net::SocketAddr>,
    /// Stop publishing fixes after this many seconds (a localization source that fails).
    #[arg(long, value_name = "S")]
    pub fixes_stop_at: Option<f64>,
    #[command(flatten)]
    pub robots: super::SimulatedArgs,
    #[command(flatten)]
    pub key: crate::key::KeyArgs,
}

/// How much longer than the settling time the robots wait after their goal, s.
const STATION_GRACE_S: f64 = 2.0;

/// The robots' side of the link: UDP answering the station, or a pseudo-terminal.
fn open_air(args: &RobotsArgs) -> anyhow::Result<Box<dyn Transport>> {
    if args.pty {
        let pty = crate::pty::Pty::open()?;
        println!("pty {}", pty.path()?.display());
        return Ok(Box::new(pty));
    }
    let addr = args.udp.expect("clap requires --udp or --pty");
    let udp = UdpAnswer::bind(addr).with_context(|| format!("cannot bind {addr}"))?;
    println!("udp {}", udp.local_addr()?);
    Ok(Box::new(udp))
}

/// Everything waiting on `air` now (never blocks).
fn poll(air: &mut dyn Transport, out: &mut Vec<u8>) -> anyhow::Result<()> {
    let mut buf = [0u8; 2048];
    loop {
        match air.recv(&mut buf, Duration::ZERO)? {
            0 => return Ok(()),
            n => out.extend_from_slice(&buf[..n]),
        }
    }
}

pub fn run(args: RobotsArgs) -> anyhow::Result<()> {
    let scenario = super::load_scenario(&args.scenario)?;
    let end_s = args.duration.unwrap_or(scenario.sim.duration_s);
    let step_us = scenario.sim.physics_step_ms as u64 * 1000;
    let mut r = Rehearsal::open(&args, scenario)?;
    use std::io::Write;
    std::io::stdout().flush()?;
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst)).context("installing Ctrl-C")?;
    // The wall clock paces the world; nothing simulated reads it.
    let wall = Instant::now();
    r.epoch_unix_ms = super::unix_ms()?;
    while !stop.load(Ordering::SeqCst) && (r.world.t_us as f64) < end_s * 1e6 {
        // The station settles as long after its own arrival, which may come a little
        // later: give it time to finish before the robots go away.
        if let Some(goal) = r.world.goal_time_s() {
            if r.world.t_us as f64 / 1e6 >= goal + r.settle_s + STATION_GRACE_S {
                break;
            }
        }
        r.step(step_us, args.fixes_stop_at)?;
        let ahead = Duration::from_micros(r.world.t_us).saturating_sub(wall.elapsed());
        std::thread::sleep(ahead);
    }
    r.finish(&args, wall.elapsed().as_secs_f64())
}

/// The scenario's robots behind a real transport, and what they publish.
struct Rehearsal {
    world: World,
    air: Box<dyn Transport>,
    listening: String,
    publisher: FixPublisher,
    scans: Option<crate::live::feeds::scan::ScanPublisher>,
    epoch_unix_ms: u64,
    settle_s: f64,
    heard: Vec<u8>,
    diagnosis: crate::live::diagnosis::RobotsDiagnosis,
    looked_s: u64,
}

impl Rehearsal {
    fn open(args: &RobotsArgs, scenario: base_station::scenario::Scenario) -> anyhow::Result<Self> {
        let key = crate::key::require_key(&args.key)?;
        let mut options = SimOptions::new(args.robots.seed.unwrap_or(scenario.sim.seed));
        options.firmware = args.robots.firmware.into();
        options.base = BaseSide::External;
        let publisher = FixPublisher::open(&args.publish_fixes, &scenario, &key)?;
        let scans = args
            .publish_scan
            .map(|to| crate::live::feeds::scan::ScanPublisher::open(to, &key))
            .transpose()?;
        options.key = Some(Arc::new(key));
        if !args.publish_fixes.is_empty() {
            options.fixes = FixPath::Published;
        }
        let settle_s = options.settle_s;
        let world = World::new(scenario, options).context("cannot start the robots")?;
        let air = open_air(args)?;
        let listening = air.describe();
        Ok(Self {
            world,
            air,
            listening,
            publisher,
            scans,
            epoch_unix_ms: super::unix_ms()?,
            settle_s,
            heard: Vec::new(),
            diagnosis: crate::live::diagnosis::RobotsDiagnosis::default(),
            looked_s: 0,
        })
    }

    /// One physics step: what the station sent in, the world on, what the robots send
    /// out, the fixes and the scan published (fixes until `fixes_stop_at`, s).
    fn step(&mut self, step_us: u64, fixes_stop_at: Option<f64>) -> anyhow::Result<()> {
        self.heard.clear();
        poll(self.air.as_mut(), &mut self.heard)?;
        self.diagnosis.heard(self.heard.len());
        self.world.base_transmit(&self.heard);
        self.world
            .step(step_us)
            .context("a robot's controller failed")?;
        let out = self.world.take_base_inbox();
        if !out.is_empty() {
            self.air.send(&out)?;
        }
        let t_s = self.world.t_us as f64 / 1e6;
        let fixes = self.world.take_published_fixes();
        if fixes_stop_at.is_none_or(|stop| t_s < stop) {
            self.publisher.publish(&fixes, self.epoch_unix_ms);
        }
        let scan = self.world.take_scan();
        if let Some(scans) = &mut self.scans {
            scans.publish(&scan, self.epoch_unix_ms + self.world.t_us / 1000);
        }
        // Once a second: a station not heard, frames the robots refuse.
        if self.world.t_us / 1_000_000 != self.looked_s {
            self.looked_s = self.world.t_us / 1_000_000;
            let mut rejects = protocol::RejectCounts::default();
            for r in &self.world.robots {
                rejects.merge(&r.brain.rejects());
            }
            let now_ms = (self.world.t_us / 1000) as u32;
            self.diagnosis.look(rejects, now_ms, &self.listening);
        }
        Ok(())
    }

    /// The report and trace where asked, and a line on how it went.
    fn finish(&self, args: &RobotsArgs, wall_s: f64) -> anyhow::Result<()> {
        let world = &self.world;
        let mut report = hil_sim::run::report_of(world, wall_s);
        report.started_unix_ms = Some(self.epoch_unix_ms);
        if let Some(path) = &args.report {
            super::create_parent(path)?;
            super::write_report(&report, path)?;
        }
        if let Some(path) = &args.robots.trace {
            super::create_parent(path)?;
            super::write_trace(world, path)?;
        }
        eprintln!(
            "robots: {:.1} s, goal {}, {} contacts{}",
            world.t_us as f64 / 1e6,
            match report.time_to_goal_s {
                Some(t) => format!("reached at {t:.1} s"),
                None => "not reached".into(),
            },
            report.collisions,
            args.report
                .as_ref()
                .map_or(String::new(), |p| format!("; report {}", p.display()))
        );
        Ok(())
    }
}
