//! `basestation run SCENARIO --port DEV [--baud N]` or `--udp ADDR`: drive real robots.
//!
//! The station steps at 10 Hz on the wall clock. The fleet key is required (file or
//! environment); there is no built-in key. Ctrl-C sends a Stop to every robot before
//! exiting.

use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context;
use base_station::station::{BaseStation, StationConfig};
use base_station::transport::{Serial, Transport, Udp};
use clap::Args;
use serde_json::json;

#[derive(Args, Debug)]
#[command(group(clap::ArgGroup::new("transport").required(true).args(["port", "udp"])))]
pub struct RunArgs {
    /// A scenario file, or a shipped scenario's name (paper-obstacles, paper-passage,
    /// street-crossing, plaza-crowd, plaza-sweep, street-block-sweep).
    pub scenario: String,
    /// Serial device of the radio modem (e.g. /dev/ttyUSB0).
    #[arg(long)]
    pub port: Option<String>,
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
    /// Send frames as UDP datagrams to this address (a radio bridge or broadcast):
    /// HOST:PORT, a name or an IP address.
    #[arg(long, value_parser = peer_address)]
    pub udp: Option<SocketAddr>,
    /// Local UDP address to bind.
    #[arg(long, default_value = "0.0.0.0:0")]
    pub bind: SocketAddr,
    /// Stop after this many seconds (default: until the goal is reached or Ctrl-C).
    #[arg(long)]
    pub duration: Option<f64>,
    /// After the goal, keep the formation going this long (followers settle into their
    /// slots) before stopping the fleet, s.
    #[arg(long, default_value_t = 5.0)]
    pub settle: f64,
    /// Read the line feed of fixes (docs/operating.md#4-localization) from UDP datagrams to
    /// this local address, and forward them to the robots.
    #[arg(long, value_name = "ADDR")]
    pub fix_feed: Option<SocketAddr>,
    /// Read robot ID's GNSS receiver (NMEA 0183): `ID=udp:ADDR`, `ID=tcp:HOST:PORT` or
    /// `ID=serial:PATH[@BAUD]`; repeat per robot. Needs `[localization] origin`.
    #[arg(long, value_name = "ID=SOURCE")]
    pub nmea: Vec<crate::live::feeds::localization::NmeaArg>,
    /// Read the leader's scans (the scan feed: `TIME_S,X_M,Y_M,X_M,Y_M…` per line, hits in
    /// the site frame; docs/operating.md#obstacles-the-map-does-not-hold) from UDP
    /// datagrams to this local address: what the map does not hold is routed round.
    #[arg(long, value_name = "ADDR")]
    pub scan_feed: Option<SocketAddr>,
    /// Take localization and scan datagrams only from these addresses (`ADDR` or
    /// `ADDR/PREFIX`, repeatable; default: any, sealed records only). Bind the feeds to
    /// the localization network's interface too (docs/operating.md#who-may-speak-on-the-feeds).
    #[arg(long, value_name = "NET")]
    pub feed_allow: Vec<crate::live::feeds::gate::AllowNet>,
    /// Write what the run did (station events, link and localization counts) here at the
    /// end, as JSON (docs/operating.md#6-the-run).
    #[arg(long, value_name = "FILE.json")]
    pub report: Option<std::path::PathBuf>,
    /// Record the run as MCAP: radio bytes both ways, the station's events (at their
    /// severity), the site map, the robots as reported, the route, the formation, the
    /// station's tracks and sensed marks (docs/sim.md#the-recording).
    #[arg(long, value_name = "FILE.mcap")]
    pub mcap: Option<std::path::PathBuf>,
    /// Write a Foxglove / Lichtblick layout for this fleet here (the shipped one with
    /// its plots for these robots): open it with the recording.
    #[arg(long, value_name = "FILE.json")]
    pub layout: Option<std::path::PathBuf>,
    #[command(flatten)]
    pub serve: super::ServeArgs,
    #[command(flatten)]
    pub key: crate::key::KeyArgs,
}

pub fn run(args: RunArgs) -> anyhow::Result<super::outcome::Outcome> {
    let scenario = super::load_scenario(&args.scenario)?;
    if let Some(path) = &args.layout {
        super::create_parent(path)?;
        crate::live::recording::layout::write(&scenario, path)?;
    }
    let mut live = Live::open(&args, &scenario)?;
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst)).context("installing Ctrl-C")?;
    tracing::info!(scenario = %scenario.name, "base station running");
    let ids: Vec<u16> = scenario.robots.iter().map(|r| r.id).collect();
    let mut arrived_ms = None;
    while !stop.load(Ordering::SeqCst) {
        let now_ms = live.now_ms();
        if args.duration.is_some_and(|d| now_ms as f64 / 1000.0 >= d) {
            break;
        }
        live.receive_until_tick();
        let now_ms = live.tick(&ids);
        if args.duration.is_none() && live.station.arrived() {
            let at = *arrived_ms.get_or_insert_with(|| {
                tracing::info!("goal reached");
                now_ms
            });
            if now_ms.wrapping_sub(at) as f64 >= args.settle * 1000.0 {
                break;
            }
        }
    }
    live.finish(&scenario.name, &args, stop.load(Ordering::SeqCst))
}

/// A run under way: the station, its radio, the site's feeds, the console and the
/// recording, on the wall clock.
struct Live {
    station: BaseStation,
    transport: Modem,
    localization: Option<crate::live::feeds::localization::Localization>,
    scans: Option<crate::live::feeds::scan::ScanFeed>,
    console: Option<crate::live::console::Console>,
    bus: Option<crate::bus::station::StationBus>,
    recording: Option<crate::live::recording::LiveRecording>,
    start: Instant,
    /// The station clock's zero on the Unix clock: fixes are stamped with the latter.
    start_unix_ms: u64,
    next: Instant,
    buf: Vec<u8>,
    last_report: u32,
    refusals: crate::live::feeds::gate::Bulk,
    timing: crate::live::timing::LoopTiming,
    diagnosis: crate::live::diagnosis::Diagnosis,
}

/// The station's 10 Hz period.
const PERIOD: Duration = Duration::from_millis(100);

impl Live {
    /// Opens the radio, the station with a fresh session, the feeds, the console and the
    /// recording.
    fn open(args: &RunArgs, scenario: &base_station::scenario::Scenario) -> anyhow::Result<Self> {
        let key = crate::key::require_key(&args.key)?;
        let transport = Modem {
            transport: open_transport(args)?,
            warned: None,
        };
        let station = new_station(scenario, &key)?;
        let allow: Arc<[crate::live::feeds::gate::AllowNet]> = Arc::from(args.feed_allow.clone());
        let localization = crate::live::feeds::localization::Localization::open(
            args.fix_feed,
            &args.nmea,
            scenario,
            &key,
            allow.clone(),
        )?;
        let mut station = station;
        match &localization {
            Some(_) => station.watch_fixes(0),
            None => tracing::warn!(
                "no localization source (--fix-feed, --nmea): the station forwards no fixes, so robots without fixes of their own (a rehearsal's simulated robots have them) drive on odometry alone"
            ),
        }
        let scans = args
            .scan_feed
            .map(|addr| crate::live::feeds::scan::ScanFeed::open(addr, &key, allow.clone()))
            .transpose()?;
        let console = crate::live::console::Console::open(args.serve.console, scenario)?;
        let bus = args.serve.bus(scenario)?;
        let recording = match (&args.mcap, args.serve.live) {
            (None, None) => None,
            (mcap, live) => Some(crate::live::recording::LiveRecording::create(
                scenario,
                mcap.as_deref(),
                live,
                &args.serve.live_origin,
                station.robots().keys().copied(),
            )?),
        };
        let start = Instant::now();
        Ok(Self {
            station,
            transport,
            localization,
            scans,
            console,
            bus,
            recording,
            start,
            start_unix_ms: super::unix_ms()?,
            next: start,
            buf: vec![0u8; 2048],
            last_report: 0,
            refusals: Default::default(),
            timing: crate::live::timing::LoopTiming::default(),
            diagnosis: crate::live::diagnosis::Diagnosis::default(),
        })
    }

    fn now_ms(&self) -> u32 {
        self.start.elapsed().as_millis() as u32
    }

    /// Receives until the next tick. Handshake answers go at once: a robot takes the
    /// answer's stamp as our clock at the middle of its round trip, so holding it to the
    /// next tick would skew its clock offset by up to half a period.
    fn receive_until_tick(&mut self) {
        let now_ns = crate::live::recording::now_ns;
        loop {
            let left = self.next.saturating_duration_since(Instant::now());
            if left.is_zero() {
                break;
            }
            let n = self.transport.recv(&mut self.buf, left);
            if n == 0 {
                continue;
            }
            self.station.receive(&self.buf[..n], self.now_ms());
            if let Some(r) = &self.recording {
                r.radio("air", &self.buf[..n], now_ns());
            }
            let answers = self.station.take_outbox();
            if !answers.is_empty() {
                self.transport.send(&answers);
                if let Some(r) = &self.recording {
                    r.radio("base", &answers, now_ns());
                }
            }
        }
    }

    /// One period: the feeds, the operator, the station's step and what it sends, the
    /// recording, the status lines. The station's clock then.
    fn tick(&mut self, ids: &[u16]) -> u32 {
        let now_ns = crate::live::recording::now_ns;
        let tick = self.next;
        self.next += PERIOD;
        let began = Instant::now();
        let now_ms = self.now_ms();
        if let Some(l) = &mut self.localization {
            l.poll(&mut self.station, self.start_unix_ms, now_ms);
        }
        if let Some(feed) = &mut self.scans {
            feed.poll(
                &mut self.station,
                self.start_unix_ms + now_ms as u64,
                now_ms,
            );
        }
        if let Some(console) = self.console.as_ref().filter(|c| c.alive()) {
            for command in console.commands() {
                self.station.operator(command, now_ms);
            }
        }
        if let Some(bus) = &self.bus {
            for c in bus.commands() {
                let done = crate::bus::station::obey(&mut self.station, c.command, now_ms);
                bus.answer(c.id, done);
            }
        }
        self.station.step(now_ms);
        if self.console.is_some() || self.bus.is_some() {
            let snapshot = crate::live::console::snapshot(&self.station, now_ms);
            if let Some(console) = &self.console {
                console.publish(&snapshot);
            }
            if let Some(bus) = self.bus.as_mut() {
                bus.publish(&snapshot);
            }
        }
        let out = self.station.take_outbox();
        self.transport.send(&out);
        if let Some(r) = self.recording.as_mut() {
            r.radio("base", &out, now_ns());
            r.station(&self.station, now_ms, now_ns());
            r.scene(&self.station, now_ms, now_ns());
        }
        self.timing
            .period(began.saturating_duration_since(tick), began.elapsed());
        self.status(ids, now_ms);
        now_ms
    }

    /// Once a second: the diagnosis; every 5 s a status line, each robot's every 15 s.
    fn status(&mut self, ids: &[u16], now_ms: u32) {
        if now_ms / 1000 == self.last_report {
            return;
        }
        self.last_report = now_ms / 1000;
        self.diagnosis.look(&self.station, ids, now_ms);
        self.tell_refusals(now_ms);
        if self.last_report.is_multiple_of(5) {
            if let Some(p) = self.station.progress(now_ms) {
                tracing::info!("{}", super::sim::progress_words(&p));
            }
            log_link(&self.station, now_ms, self.last_report.is_multiple_of(15));
            if let Some(l) = &self.localization {
                l.log();
            }
        }
    }

    /// Each feed that refused records in bulk in the last second, as a station event.
    fn tell_refusals(&mut self, now_ms: u32) {
        let mut totals: Vec<(String, u64)> = Vec::new();
        if let Some(l) = &self.localization {
            totals.extend(l.counts().into_iter().map(|(n, r)| (n, r.gate.refused())));
        }
        if let Some(s) = &self.scans {
            totals.push(("scan feed".to_string(), s.counts().gate.refused()));
        }
        for (input, total) in totals {
            if let Some(n) = self.refusals.check(&input, total, now_ms) {
                self.station.feed_refused(&input, n, now_ms);
            }
        }
    }

    /// Leaves the fleet standing, closes the recording, prints and writes the summary,
    /// shows the console how it ended; the outcome.
    fn finish(
        mut self,
        scenario: &str,
        args: &RunArgs,
        interrupted: bool,
    ) -> anyhow::Result<super::outcome::Outcome> {
        let now_ns = crate::live::recording::now_ns;
        self.station.broadcast_stop(self.now_ms());
        let out = self.station.take_outbox();
        self.transport.send(&out);
        if let Some(r) = self.recording.take() {
            r.radio("base", &out, now_ns());
            r.close()?;
        }
        let ending = self.station.ending(self.now_ms(), interrupted);
        let mut summary = self.summary(scenario)?;
        summary["ending"] = json!(ending.kind());
        summary["why"] = json!(ending.why());
        eprintln!("{}", serde_json::to_string(&summary)?);
        if let Some(path) = &args.report {
            let text = serde_json::to_string_pretty(&summary)? + "\n";
            super::replace(path, |partial| {
                std::fs::write(partial, &text)
                    .with_context(|| format!("cannot write {}", partial.display()))
            })?;
        }
        eprintln!("{}", ending.why());
        let outcome = super::outcome::Outcome::of(&ending);
        // The page and the bus say the run finished and how, not that the station is gone.
        let last = crate::live::console::snapshot(&self.station, self.now_ms());
        let last = crate::live::console::finished(last, &ending.why());
        if let Some(bus) = self.bus.as_mut() {
            bus.publish(&last);
        }
        if let Some(console) = self.console.as_ref().filter(|c| c.alive()) {
            console.publish(&last);
            std::thread::sleep(crate::live::console::FINISHED_SHOWN);
        }
        if outcome == super::outcome::Outcome::NeverLinked {
            eprintln!(
                "no robot ever linked: check the transport's address (--udp / --port) and that the station and the robots share the fleet key"
            );
        }
        Ok(outcome)
    }

    /// The summary with the loop's timing, the station's clock zero on the Unix clock
    /// (`robots`' report has its own, so the two processes' times line up) and the
    /// console's addresses.
    fn summary(&self, scenario: &str) -> anyhow::Result<serde_json::Value> {
        let mut summary = summary(
            scenario,
            &self.station,
            self.localization.as_ref(),
            self.scans.as_ref().map(|s| s.counts()),
        );
        summary["loop"] = serde_json::to_value(self.timing.report())?;
        summary["started_unix_ms"] = json!(self.start_unix_ms);
        if let Some(console) = &self.console {
            summary["console"] = json!({ "alive": console.alive(), "urls": console.urls });
        }
        Ok(summary)
    }
}

/// The radio the command line names.
fn open_transport(args: &RunArgs) -> anyhow::Result<Box<dyn Transport>> {
    Ok(match (&args.port, args.udp) {
        (Some(port), _) => {
            Box::new(Serial::open(port, args.baud).with_context(|| format!("cannot open {port}"))?)
        }
        (None, Some(peer)) => {
            Box::new(Udp::open(args.bind, peer).context("cannot open the UDP socket")?)
        }
        (None, None) => anyhow::bail!("no radio: give --port DEV or --udp HOST:PORT"),
    })
}

/// A station with a fresh random session, its nonces counting on from the Unix clock.
fn new_station(
    scenario: &base_station::scenario::Scenario,
    key: &protocol::MasterKey,
) -> anyhow::Result<BaseStation> {
    let mut random = [0u8; 8];
    getrandom::fill(&mut random).map_err(|e| anyhow::anyhow!("no OS randomness: {e}"))?;
    let session = u32::from_le_bytes(random[..4].try_into().expect("4 bytes"));
    let nonce_base = base_station::station::nonce_base(
        super::unix_ms()?,
        u32::from_le_bytes(random[4..8].try_into().expect("4 bytes")),
    );
    Ok(BaseStation::new(
        StationConfig::from_scenario(scenario),
        key,
        session,
        nonce_base,
    ))
}

/// `--udp`'s HOST:PORT, a name resolved (its first IPv4 address, else its first).
fn peer_address(text: &str) -> Result<SocketAddr, String> {
    use std::net::ToSocketAddrs;
    let all: Vec<SocketAddr> = text
        .to_socket_addrs()
        .map_err(|e| format!("{text}: not HOST:PORT, or the name does not resolve ({e})"))?
        .collect();
    all.iter()
        .find(|a| a.is_ipv4())
        .or(all.first())
        .copied()
        .ok_or_else(|| format!("{text}: the name has no address"))
}

/// The transport, failing soft: a modem that errors (unplugged, its peer gone) is logged
/// every few seconds and the run goes on; the robots stop by themselves when nothing
/// reaches them, and resume when it does again.
struct Modem {
    transport: Box<dyn Transport>,
    warned: Option<Instant>,
}

impl Modem {
    fn warn(&mut self, what: &str, e: std::io::Error) {
        if self
            .warned
            .is_none_or(|t| t.elapsed() >= Duration::from_secs(5))
        {
            tracing::warn!("radio {what} failed: {e}");
            self.warned = Some(Instant::now());
        }
    }

    fn send(&mut self, bytes: &[u8]) {
        if let Err(e) = self.transport.send(bytes) {
            self.warn("send", e);
        }
    }

    /// Bytes within `timeout`; none (after waiting it out) when the transport failed.
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> usize {
        self.transport.recv(buf, timeout).unwrap_or_else(|e| {
            self.warn("receive", e);
            std::thread::sleep(timeout);
            0
        })
    }
}

/// The link's totals every second; each robot's link health when `per_robot`.
fn log_link(station: &BaseStation, now_ms: u32, per_robot: bool) {
    let stats = station.link().stats();
    tracing::info!(
        accepted = stats.accepted,
        rejected = stats.rejects.total(),
        lost = stats.lost,
        planner = station.guidance().planner().mode().name(),
        "link"
    );
    if !per_robot {
        return;
    }
    // Last seen, accepted, lost, rejects by reason.
    for peer in station.link().peers() {
        let seen = peer
            .last_rx_ms
            .map(|t| format!("{} ms ago", now_ms.wrapping_sub(t)))
            .unwrap_or_else(|| "never".into());
        let rejects: Vec<String> = protocol::Reject::ALL
            .iter()
            .filter(|r| peer.rejects.get(**r) > 0)
            .map(|r| format!("{}={}", r.name(), peer.rejects.get(*r)))
            .collect();
        tracing::info!(
            robot = %peer.address,
            linked = peer.is_linked(),
            seen = %seen,
            accepted = peer.accepted,
            lost = peer.lost,
            rejects = %rejects.join(","),
            "robot link"
        );
    }
}

/// What the run did, as the station saw it: printed at the end, and `--report`.
fn summary(
    scenario: &str,
    station: &BaseStation,
    localization: Option<&crate::live::feeds::localization::Localization>,
    scans: Option<crate::live::feeds::scan::ScanCounts>,
) -> serde_json::Value {
    let leader = station.config().leader;
    let events: Vec<_> = station
        .events()
        .iter()
        .map(|e| {
            let (at_ms, event, robot) = e.describe(leader);
            json!({ "at_s": at_ms as f64 / 1000.0, "event": event, "robot": robot })
        })
        .collect();
    let stats = station.link().stats();
    let rejects: serde_json::Map<_, _> = protocol::Reject::ALL
        .iter()
        .filter(|r| stats.rejects.get(**r) > 0)
        .map(|r| (r.name().to_string(), json!(stats.rejects.get(*r))))
        .collect();
    json!({
        "scenario": scenario,
        "goal_reached": station.arrived(),
        "station_events": events,
        "link": {
            "accepted": stats.accepted,
            "rejected": stats.rejects.total(),
            "lost": stats.lost,
            "rejects_by_reason": rejects,
        },
        "localization": localization.map(|l| l.counts()),
        "scan_feed": scans,
        "sensed_obstacles": station.perception().len(),
        "perception": station.perception().counts(),
    })
}
