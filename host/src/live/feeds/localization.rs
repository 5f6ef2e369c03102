//! Localization in and out. In: `run --fix-feed ADDR` and `run --nmea ID=SOURCE` read fixes
//! (one thread per source, lines through a bounded channel) for the station to forward.
//! Every source seals what it sends with its own key (`base_station::seal`: the line feed
//! is source `fixes`, robot N's receiver source `nmea-N`); nothing unsealed reaches a
//! robot. Out: `robots --publish-fixes` sends the simulated robots' fixes the same ways,
//! sealed, so the whole path is tested end to end.

use std::collections::BTreeMap;
use std::net::{SocketAddr, UdpSocket};
use std::str::FromStr;
use std::sync::mpsc::{self, Receiver, SyncSender};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{bail, Context};
use base_station::localization::{self, feed, nmea::NmeaReceiver, Fix, InputCounts, LineError};
use base_station::planner::PlanPose;
use base_station::scenario::Scenario;
use base_station::seal::{Sealer, SourceKey};
use base_station::station::{BaseStation, NotForwarded};
use control_core::odometry::PoseFixSample;
use glam::DVec2;
use protocol::MasterKey;
use serde::Serialize;

use super::gate::{AllowNet, Gate, GateCounts, GateTally};

/// Longest input line taken, bytes (an NMEA sentence is at most 82).
const MAX_LINE: usize = 1024;
/// The source name of the line feed: its key is `MasterKey::source_bytes("fixes")`.
pub const FEED_SOURCE: &str = "fixes";

/// The source name of robot `id`'s GNSS receiver.
pub fn nmea_source(id: u16) -> String {
    format!("nmea-{id}")
}
/// Lines waiting for the main loop; more are dropped (and counted).
const QUEUE: usize = 1024;
/// A fix older than this when it arrives is not forwarded, ms.
const MAX_FIX_AGE_MS: u64 = 1000;
/// A fix stamped this far ahead of the station's clock is not believed, ms.
const MAX_FIX_LEAD_MS: u64 = 500;

/// Where a source's bytes come from.
#[derive(Debug, Clone)]
pub enum Source {
    /// Datagrams to this local address.
    Udp(SocketAddr),
    /// A TCP server to connect to (reconnecting when it drops).
    Tcp(String),
    /// A serial port, `PATH` or `PATH@BAUD`.
    Serial { path: String, baud: u32 },
}

impl FromStr for Source {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let (kind, rest) = s.split_once(':').ok_or_else(|| {
            format!("{s}: expected udp:ADDR, tcp:HOST:PORT or serial:PATH[@BAUD]")
        })?;
        match kind {
            "udp" => rest
                .parse()
                .map(Source::Udp)
                .map_err(|e| format!("{s}: {e}")),
            "tcp" => Ok(Source::Tcp(rest.to_string())),
            "serial" => {
                let (path, baud) = match rest.rsplit_once('@') {
                    Some((p, b)) => (p, b.parse().map_err(|_| format!("{s}: baud {b:?}"))?),
                    None => (rest, 9600),
                };
                Ok(Source::Serial {
                    path: path.to_string(),
                    baud,
                })
            }
            _ => Err(format!(
                "{s}: unknown source kind {kind:?} (udp, tcp, serial)"
            )),
        }
    }
}

/// `ID=SOURCE`: robot ID's GNSS receiver.
#[derive(Debug, Clone)]
pub struct NmeaArg {
    pub robot: u16,
    pub source: Source,
}

impl FromStr for NmeaArg {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let (id, source) = s
            .split_once('=')
            .ok_or_else(|| format!("{s}: expected ROBOT_ID=SOURCE"))?;
        Ok(Self {
            robot: id.parse().map_err(|_| format!("{s}: robot id {id:?}"))?,
            source: source.parse()?,
        })
    }
}

/// One line from a source, and when it arrived (Unix ms).
struct Line {
    source: usize,
    text: Result<String, LineError>,
    unix_ms: u64,
}

enum Parser {
    Feed,
    Nmea(NmeaReceiver),
}

struct Input {
    name: String,
    parser: Parser,
    counts: InputCounts,
    gate: Arc<GateCounts>,
}

/// What one input delivered and what it dropped, for the run's report.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct InputReport {
    #[serde(flatten)]
    pub lines: InputCounts,
    #[serde(flatten)]
    pub gate: GateTally,
}

/// Every localization source of a run, read on their own threads.
pub struct Localization {
    inputs: Vec<Input>,
    lines: Receiver<Line>,
    /// Lines dropped because the main loop fell behind.
    dropped: std::sync::Arc<std::sync::atomic::AtomicU64>,
}

impl Localization {
    /// Opens the sources; `None` when there are none. Their records must be sealed with
    /// their sources' keys (derived from `master`) and, over UDP, come from `allow`'s
    /// addresses (any, when empty).
    pub fn open(
        feed: Option<SocketAddr>,
        nmea: &[NmeaArg],
        scenario: &Scenario,
        master: &MasterKey,
        allow: Arc<[AllowNet]>,
    ) -> anyhow::Result<Option<Self>> {
        if feed.is_none() && nmea.is_empty() {
            return Ok(None);
        }
        let ids: Vec<u16> = scenario.robots.iter().map(|r| r.id).collect();
        if let Some(stray) = nmea.iter().find(|n| !ids.contains(&n.robot)) {
            let list: Vec<String> = ids.iter().map(u16::to_string).collect();
            anyhow::bail!(
                "--nmea {}=…: the site has no robot {} (its robots: {})",
                stray.robot,
                stray.robot,
                list.join(", ")
            );
        }
        let (tx, lines) = mpsc::sync_channel(QUEUE);
        let dropped = std::sync::Arc::new(std::sync::atomic::AtomicU64::new(0));
        let mut inputs = Vec::new();
        if let Some(addr) = feed {
            let name = format!("feed udp:{addr}");
            let gate = Gate::new(&name, FEED_SOURCE, master, allow.clone());
            let counts = gate.counts();
            spawn(
                inputs.len(),
                &Source::Udp(addr),
                gate,
                tx.clone(),
                dropped.clone(),
            )?;
            inputs.push(Input {
                name,
                parser: Parser::Feed,
                counts: InputCounts::default(),
                gate: counts,
            });
        }
        for arg in nmea {
            let Some(origin) = scenario.localization.origin else {
                bail!("--nmea needs the site's origin on the globe: [localization] origin = {{ lat_deg = …, lon_deg = …, x_axis_bearing_deg = … }} in the site file");
            };
            if !scenario.robots.iter().any(|r| r.id == arg.robot) {
                bail!(
                    "--nmea {}=…: the site has no robot {} (its robots: {})",
                    arg.robot,
                    arg.robot,
                    scenario
                        .robots
                        .iter()
                        .map(|r| r.id.to_string())
                        .collect::<Vec<_>>()
                        .join(", ")
                );
            }
            let name = format!("nmea robot {}", arg.robot);
            let gate = Gate::new(&name, &nmea_source(arg.robot), master, allow.clone());
            let counts = gate.counts();
            spawn(inputs.len(), &arg.source, gate, tx.clone(), dropped.clone())?;
            inputs.push(Input {
                name,
                parser: Parser::Nmea(NmeaReceiver::new(arg.robot, origin)),
                counts: InputCounts::default(),
                gate: counts,
            });
        }
        Ok(Some(Self {
            inputs,
            lines,
            dropped,
        }))
    }

    /// Parses what arrived and hands the fixes to the station. `start_unix_ms`: the
    /// station clock's zero on the Unix clock.
    pub fn poll(&mut self, station: &mut BaseStation, start_unix_ms: u64, now_ms: u32) {
        while let Ok(line) = self.lines.try_recv() {
            let input = &mut self.inputs[line.source];
            let parsed = line.text.and_then(|text| match &mut input.parser {
                Parser::Feed => feed::parse(&text),
                Parser::Nmea(rx) => rx.line(&text, line.unix_ms),
            });
            let fix = match parsed {
                Ok(Some(fix)) => fix,
                Ok(None) => continue,
                Err(e) => {
                    tracing::debug!(source = %input.name, "localization line dropped: {e}");
                    input.counts.count(&e);
                    continue;
                }
            };
            let now_unix = start_unix_ms + now_ms as u64;
            tracing::trace!(
                robot = fix.robot,
                age_ms = now_unix as i64 - fix.unix_ms as i64,
                "fix"
            );
            if fix.unix_ms + MAX_FIX_AGE_MS < now_unix
                || fix.unix_ms > now_unix + MAX_FIX_LEAD_MS
                || fix.unix_ms < start_unix_ms
            {
                input.counts.out_of_time += 1;
                continue;
            }
            let valid_at = (fix.unix_ms - start_unix_ms) as u32;
            let pose = PlanPose {
                position: fix.position,
                heading: fix.heading,
            };
            match station.forward_fix(fix.robot, pose, fix.sigma, valid_at, now_ms) {
                Ok(()) => input.counts.fixes += 1,
                Err(NotForwarded::UnknownRobot) => input.counts.unknown_robot += 1,
                Err(NotForwarded::RateLimited | NotForwarded::NotLinked) => {
                    input.counts.rate_limited += 1
                }
                Err(NotForwarded::OutOfRange) => input.counts.malformed += 1,
                Err(NotForwarded::Outlier) => input.counts.outliers += 1,
            }
        }
    }

    /// One log line per source: what it delivered and what was dropped.
    pub fn log(&self) {
        for input in &self.inputs {
            let c = &input.counts;
            let g = input.gate.tally();
            tracing::info!(
                source = %input.name,
                not_allowed = g.not_allowed,
                unsealed = g.unsealed,
                bad_seal = g.bad_seal,
                replayed = g.replayed,
                ahead = g.ahead,
                stale = g.stale,
                taken = c.fixes,
                malformed = c.malformed,
                no_solution = c.no_solution,
                no_heading = c.no_heading,
                unknown_robot = c.unknown_robot,
                out_of_time = c.out_of_time,
                held_back = c.rate_limited,
                outliers = c.outliers,
                "localization"
            );
        }
        let dropped = self.dropped.load(std::sync::atomic::Ordering::Relaxed);
        if dropped > 0 {
            tracing::warn!(
                dropped,
                "localization lines dropped: the station fell behind"
            );
        }
    }

    /// Counts per source, for the summary at the end of a run.
    pub fn counts(&self) -> BTreeMap<String, InputReport> {
        self.inputs
            .iter()
            .map(|i| {
                let report = InputReport {
                    lines: i.counts,
                    gate: i.gate.tally(),
                };
                (i.name.clone(), report)
            })
            .collect()
    }
}

/// Reads `source` on its own thread, record by record through `gate`, line by line into
/// `tx`.
fn spawn(
    index: usize,
    source: &Source,
    mut gate: Gate,
    tx: SyncSender<Line>,
    dropped: std::sync::Arc<std::sync::atomic::AtomicU64>,
) -> anyhow::Result<()> {
    let mut send = move |bytes: &[u8]| {
        let line = Line {
            source: index,
            text: text_of(bytes),
            unix_ms: crate::commands::unix_ms().unwrap_or(0),
        };
        super::gate::offer(&tx, line, &dropped)
    };
    match source.clone() {
        Source::Udp(addr) => {
            let socket = UdpSocket::bind(addr).with_context(|| format!("cannot bind {addr}"))?;
            super::gate::read_udp_records(socket, "localization", gate, send)?;
        }
        Source::Tcp(addr) => {
            std::thread::spawn(move || loop {
                match std::net::TcpStream::connect(&addr) {
                    Ok(stream) => {
                        if !super::gate::read_stream_records(stream, &mut gate, &mut send) {
                            return;
                        }
                        tracing::warn!(%addr, "localization source closed; reconnecting");
                    }
                    Err(e) => {
                        tracing::warn!(%addr, "cannot connect to the localization source: {e}")
                    }
                }
                std::thread::sleep(Duration::from_secs(1));
            });
        }
        Source::Serial { path, baud } => {
            let port = serialport::new(&path, baud)
                .timeout(Duration::from_secs(3600))
                .open()
                .with_context(|| format!("cannot open {path}"))?;
            std::thread::spawn(move || {
                super::gate::read_stream_records(port, &mut gate, &mut send);
                tracing::warn!(%path, "localization source closed");
            });
        }
    }
    Ok(())
}

fn text_of(bytes: &[u8]) -> Result<String, LineError> {
    if bytes.len() > MAX_LINE {
        return Err(LineError::Malformed(format!(
            "a line over {MAX_LINE} bytes"
        )));
    }
    std::str::from_utf8(bytes)
        .map(|s| s.trim_end_matches(['\r', '\n']).to_string())
        .map_err(|_| LineError::Malformed("not UTF-8".into()))
}

/// `robots --publish-fixes`: where the simulated fixes go.
#[derive(Debug, Clone)]
pub enum PublishArg {
    /// The line feed, every robot, to this UDP address.
    Feed(SocketAddr),
    /// NMEA 0183 of one robot's receiver, to this UDP address.
    Nmea { robot: u16, to: SocketAddr },
}

impl FromStr for PublishArg {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let bad = || format!("{s}: expected feed:ADDR or nmea:ID=ADDR");
        match s.split_once(':').ok_or_else(bad)? {
            ("feed", addr) => addr
                .parse()
                .map(PublishArg::Feed)
                .map_err(|e| format!("{s}: {e}")),
            ("nmea", rest) => {
                let (id, addr) = rest.split_once('=').ok_or_else(bad)?;
                Ok(PublishArg::Nmea {
                    robot: id.parse().map_err(|_| format!("{s}: robot id {id:?}"))?,
                    to: addr.parse().map_err(|e| format!("{s}: {e}"))?,
                })
            }
            _ => Err(bad()),
        }
    }
}

/// Sends simulated fixes as a site's localization system would, sealed with each source's
/// key.
pub struct FixPublisher {
    socket: Option<UdpSocket>,
    feeds: Vec<SocketAddr>,
    feed_seal: Sealer,
    nmea: BTreeMap<u16, (SocketAddr, Sealer)>,
    origin: Option<localization::SiteOrigin>,
}

impl FixPublisher {
    pub fn open(
        args: &[PublishArg],
        scenario: &Scenario,
        master: &MasterKey,
    ) -> anyhow::Result<Self> {
        let mut publisher = Self {
            socket: None,
            feeds: Vec::new(),
            feed_seal: Sealer::new(SourceKey::derive(master, FEED_SOURCE)),
            nmea: BTreeMap::new(),
            origin: scenario.localization.origin,
        };
        for arg in args {
            match arg {
                PublishArg::Feed(to) => publisher.feeds.push(*to),
                PublishArg::Nmea { robot, to } => {
                    if publisher.origin.is_none() {
                        bail!("publishing NMEA needs the site's origin: [localization] origin in the scenario");
                    }
                    let key = SourceKey::derive(master, &nmea_source(*robot));
                    publisher.nmea.insert(*robot, (*to, Sealer::new(key)));
                }
            }
        }
        if !args.is_empty() {
            publisher.socket = Some(UdpSocket::bind("0.0.0.0:0")?);
        }
        Ok(publisher)
    }

    /// Sends `fixes` (stamped with the world's clock, ms, which started at
    /// `epoch_unix_ms`). A datagram that cannot go is the source's loss, not an error.
    pub fn publish(&mut self, fixes: &[(u16, PoseFixSample)], epoch_unix_ms: u64) {
        let Some(socket) = &self.socket else {
            return;
        };
        let clock_us = crate::commands::unix_ms().unwrap_or(0) * 1000;
        let mut feed = String::new();
        for (robot, sample) in fixes {
            let fix = Fix {
                robot: *robot,
                unix_ms: epoch_unix_ms + sample.time_ms as u64,
                position: DVec2::new(sample.pose.x as f64, sample.pose.y as f64),
                heading: sample.pose.heading as f64,
                sigma: sample.sigma as f64,
            };
            feed.push_str(&feed::format(&fix));
            if let (Some((to, sealer)), Some(origin)) = (self.nmea.get_mut(robot), &self.origin) {
                // Heading first: a receiver's position goes with the heading before it.
                let lines = localization::nmea::sentences(&fix, origin);
                let _ = socket.send_to(sealer.seal(&lines, clock_us).as_bytes(), *to);
            }
        }
        if !feed.is_empty() && !self.feeds.is_empty() {
            let record = self.feed_seal.seal(&feed, clock_us);
            for to in &self.feeds {
                let _ = socket.send_to(record.as_bytes(), to);
            }
        }
    }
}
