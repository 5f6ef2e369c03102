//! The operator's console: `run --console [ADDR]` and `sim --realtime --console [ADDR]`
//! serve a page (plain HTML/JS in the binary, no build step) with the live map, each
//! robot's mode and link, the station's events, and Stop / Emergency stop / Resume, which
//! the station sends to the robots over the authenticated radio.
//!
//! [`server`]: the HTTP server, on a thread and runtime of its own, every resource a
//! client can make it hold bounded; the station's loop publishes a snapshot each period
//! and takes the commands between periods, so the station itself is never touched from
//! another thread. [`guard`]: who may use it (the console's own names only, a pairing code
//! or the session cookie it gives, requests that change something from the console's own
//! origin as JSON), on the loopback as on the network.

pub mod guard;
pub use guard::same;
pub mod server;

use std::net::{IpAddr, SocketAddr};
use std::sync::mpsc::{self, Receiver};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use base_station::station::{BaseStation, Gate, OperatorCommand};
use serde_json::{json, Value};

/// Events the page shows, newest last.
const EVENTS_SHOWN: usize = 30;
/// Tracks the page shows at most (the nearest to the leader first): a dense crowd's
/// hundreds would make every snapshot heavy.
const TRACKS_SHOWN: usize = 150;

pub struct Console {
    shared: Arc<server::Shared<server::Station>>,
    commands: Receiver<OperatorCommand>,
    thread: JoinHandle<()>,
    /// The page with its pairing code, on the first of the console's addresses.
    pub url: String,
    /// Every address the console can be opened at (the interfaces', bound to all).
    pub urls: Vec<String>,
    /// Whether its end was reported already.
    reported_dead: std::cell::Cell<bool>,
}

/// The addresses a listener bound to `bound` answers on: `bound`'s own, or every
/// interface's of its family when it is the unspecified address. Non-loopback first.
fn reachable_at(bound: SocketAddr) -> Vec<IpAddr> {
    let ip = bound.ip();
    if !ip.is_unspecified() {
        return vec![ip];
    }
    let mut addresses: Vec<IpAddr> = nix::ifaddrs::getifaddrs()
        .map(|ifs| {
            ifs.filter_map(|i| i.address)
                .filter_map(|a| {
                    a.as_sockaddr_in()
                        .map(|v4| IpAddr::V4(v4.ip()))
                        .or_else(|| a.as_sockaddr_in6().map(|v6| IpAddr::V6(v6.ip())))
                })
                .filter(|a| a.is_ipv4() == ip.is_ipv4())
                // Link-local v6 addresses need a zone a browser's URL cannot carry.
                .filter(|a| !matches!(a, IpAddr::V6(v6) if v6.segments()[0] & 0xffc0 == 0xfe80))
                .collect()
        })
        .unwrap_or_default();
    addresses.sort_by_key(|a| (a.is_loopback(), *a));
    addresses.dedup();
    if addresses.is_empty() {
        addresses.push(if ip.is_ipv4() {
            IpAddr::V4(std::net::Ipv4Addr::LOCALHOST)
        } else {
            IpAddr::V6(std::net::Ipv6Addr::LOCALHOST)
        });
    }
    addresses
}

fn url_of(ip: IpAddr, port: u16) -> String {
    match ip {
        IpAddr::V4(v4) => format!("http://{v4}:{port}/"),
        IpAddr::V6(v6) => format!("http://[{v6}]:{port}/"),
    }
}

impl Console {
    /// Serves the console on `addr` (port 0: any free port), with the site's static
    /// picture (`map`: obstacles and bounds).
    pub fn start(addr: SocketAddr, map: Value) -> anyhow::Result<Self> {
        let (tx, commands) = mpsc::sync_channel(server::COMMANDS);
        let station = server::Station {
            snapshot: Mutex::new(Arc::from("{}")),
            map: Arc::from(map.to_string()),
            commands: tx,
        };
        let served = server::open("console", addr, station)?;
        Ok(Self {
            shared: served.shared,
            commands,
            thread: served.thread,
            url: served.url,
            urls: served.urls,
            reported_dead: std::cell::Cell::new(false),
        })
    }

    /// [`Console::start`] when `addr` is given, saying where on standard error.
    pub fn open(
        addr: Option<SocketAddr>,
        scenario: &base_station::scenario::Scenario,
    ) -> anyhow::Result<Option<Self>> {
        let Some(addr) = addr else {
            return Ok(None);
        };
        let console = Self::start(addr, map_json(scenario))?;
        eprintln!("console: {}", console.url);
        eprintln!(
            "console: pairing code {} (open {})",
            console.shared.guard.code(),
            console.urls.join(" or ")
        );
        // A tablet at the kerb scans it: the address with its pairing code.
        let on_lan = !addr.ip().is_loopback();
        if on_lan && std::io::IsTerminal::is_terminal(&std::io::stderr()) {
            if let Some(code) = qr_text(&console.url) {
                eprintln!("{code}");
            }
        }
        Ok(Some(console))
    }

    /// The fleet as the page shows it now.
    pub fn publish(&self, snapshot: &Value) {
        let text: Arc<str> = Arc::from(snapshot.to_string());
        if let Ok(mut s) = self.shared.backend.snapshot.lock() {
            *s = text;
        }
    }

    /// The operator's commands since the last call.
    pub fn commands(&self) -> Vec<OperatorCommand> {
        self.commands.try_iter().collect()
    }

    /// Whether the console still serves; the first time it does not, that is logged as
    /// an error (the run goes on: Ctrl-C still stops the fleet).
    pub fn alive(&self) -> bool {
        if !self.thread.is_finished() {
            return true;
        }
        if !self.reported_dead.replace(true) {
            tracing::error!(
                "the console stopped serving: the operator's page is dead; the run goes on \
                 (Ctrl-C stops the fleet)"
            );
        }
        false
    }
}

pub fn parse_command(body: &str) -> Option<OperatorCommand> {
    let v: Value = serde_json::from_str(body).ok()?;
    command_named(v.get("command")?.as_str()?)
}

/// The operator's command by its name on the wire (`stop`, `emergency_stop`, `resume`).
pub fn command_named(name: &str) -> Option<OperatorCommand> {
    [
        OperatorCommand::Stop,
        OperatorCommand::EmergencyStop,
        OperatorCommand::Resume,
    ]
    .into_iter()
    .find(|c| c.name() == name)
}

/// `text` as a QR code in terminal characters (two rows a character), light on dark
/// inverted so that phones read it on a dark terminal; `None` if it does not fit one.
pub fn qr_text(text: &str) -> Option<String> {
    let code = qrcode::QrCode::new(text.as_bytes()).ok()?;
    Some(
        code.render::<qrcode::render::unicode::Dense1x2>()
            .dark_color(qrcode::render::unicode::Dense1x2::Light)
            .light_color(qrcode::render::unicode::Dense1x2::Dark)
            .quiet_zone(true)
            .build(),
    )
}

/// The site's static picture for the page: the map's obstacles and the route's goal.
pub fn map_json(scenario: &base_station::scenario::Scenario) -> Value {
    json!({
        "obstacles": scenario.build_site().obstacles(),
        "goal": scenario.route_points().last().map(|g| [g.x, g.y]),
    })
}

/// How long a run's end stays served before the process exits: the page polls four
/// times a second.
pub const FINISHED_SHOWN: std::time::Duration = std::time::Duration::from_millis(1500);

/// The last snapshot of a run that ended, with how (`goal reached`, `stopped by the
/// operator`…): the page says the run finished, not that the station is gone.
pub fn finished(mut snapshot: Value, how: &str) -> Value {
    snapshot["finished"] = json!(how);
    snapshot
}

/// The fleet as the station knows it at `now_ms`: what the page draws.
pub fn snapshot(station: &BaseStation, now_ms: u32) -> Value {
    let leader = station.config().leader;
    let robots: Vec<Value> = station
        .robots()
        .iter()
        .map(|(id, status)| {
            let peer = station.link().peer(protocol::Address::Robot(*id));
            let t = status.telemetry;
            json!({
                "id": id,
                "role": if *id == leader { "leader" } else { "follower" },
                "pose": t.map(|t| { let (x, y, h) = t.pose.to_si(); [x, y, h] }),
                "mode": t.map(|t| mode_words(t.mode)),
                "faults": faults_of(station, *id, t.map_or(0, |t| t.faults)),
                "linked": peer.is_some_and(|p| p.is_linked()),
                "seen_ms_ago": peer.and_then(|p| p.last_rx_ms).map(|r| now_ms.wrapping_sub(r)),
                "v": t.map(|t| 0.5e-3 * (t.wheel_mm_s[0] as f64 + t.wheel_mm_s[1] as f64)),
                "tracking_error_m": t
                    .filter(|_| *id != leader)
                    .map(|t| t.tracking_error_mm as f64 / 1000.0),
            })
        })
        .collect();
    let slots: Vec<[f64; 2]> = station
        .leader_estimate(now_ms)
        .map(|l| {
            station
                .formation()
                .slot_points(l.pose)
                .iter()
                .map(|p| [p.x, p.y])
                .collect()
        })
        .unwrap_or_default();
    let route: Vec<[f64; 2]> = station
        .route()
        .map(|r| r.points.iter().map(|p| [p.x, p.y]).collect())
        .unwrap_or_default();
    let tracks = tracks_json(station, now_ms);
    let events = station.events();
    let events: Vec<Value> = events[events.len().saturating_sub(EVENTS_SHOWN)..]
        .iter()
        .map(|e| {
            let (at_ms, event, robot) = e.describe(leader);
            let severity = base_station::station::Severity::of(&event).name();
            json!({ "at_s": at_ms as f64 / 1000.0, "event": event, "robot": robot, "severity": severity })
        })
        .collect();
    let gate = match station.gate() {
        Gate::Waiting => "waiting",
        Gate::Assembling => "assembling",
        Gate::Running => "running",
        Gate::LeaderLost { .. } => "leader_lost",
        Gate::Halted => "halted",
    };
    json!({
        "t_s": now_ms as f64 / 1000.0,
        "gate": gate,
        "lost_after_ms": station.config().telemetry_timeout_ms,
        "footprint_m": station.formation().spec().footprint,
        "robots": robots,
        "slots": slots,
        "route": route,
        "shape": format!("{:?}", station.formation().target()).to_lowercase(),
        "blend": station.formation().blend(),
        "hold": station.operator_hold().map(|h| h.name()),
        "arrived": station.arrived(),
        "progress": station.progress(now_ms),
        "events": events,
        "events_total": station.events().len(),
        "tracks": tracks,
    })
}

/// A robot's mode as the operator reads it.
fn mode_words(mode: protocol::messages::RobotMode) -> &'static str {
    use protocol::messages::RobotMode as M;
    match mode {
        M::Idle => "idle",
        M::Joining => "joining",
        M::InFormation => "in formation",
        M::Transforming => "changing shape",
        M::Failsafe => "fail-safe stop",
        M::Leading => "leading",
        M::EmergencyStop => "emergency stop",
    }
}

/// A robot's faults: those its telemetry reports now, and those the station recorded
/// for it (a stalled wheel that halted the fleet reads clear once the robot stands).
fn faults_of(station: &BaseStation, robot: u16, flags: u16) -> Vec<&'static str> {
    let mut names = fault_names(flags);
    for e in station.events() {
        if let base_station::station::StationEvent::RobotFault {
            robot: r, fault, ..
        } = e
        {
            if *r == robot && !names.contains(fault) {
                names.push(fault);
            }
        }
    }
    names
}

/// The fault flags a robot reports, by name.
fn fault_names(flags: u16) -> Vec<&'static str> {
    base_station::station::FAULT_NAMES
        .iter()
        .filter(|(bit, _)| flags & bit != 0)
        .map(|(_, name)| *name)
        .collect()
}

/// What the station believes moves or stands on the site: each track's place, velocity,
/// size (grown by its uncertainty) and motion.
fn tracks_json(station: &BaseStation, now_ms: u32) -> Vec<Value> {
    let near = station
        .leader_estimate(now_ms)
        .map_or(glam::DVec2::ZERO, |l| l.pose.position);
    let mut tracks: Vec<_> = station.tracks(now_ms).collect();
    tracks.sort_by(|a, b| {
        a.position
            .distance(near)
            .total_cmp(&b.position.distance(near))
    });
    tracks
        .iter()
        .take(TRACKS_SHOWN)
        .map(|t| {
            json!({
                "at": [t.position.x, t.position.y],
                "v": [t.velocity.x, t.velocity.y],
                "r": t.radius + t.position_sigma,
                "motion": t.motion,
                "person": t.person,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn modes_and_faults_read_as_words() {
        assert_eq!(
            mode_words(protocol::messages::RobotMode::InFormation),
            "in formation"
        );
        let flags =
            protocol::messages::faults::WHEEL_STALL_LEFT | protocol::messages::faults::NOT_LINKED;
        assert_eq!(fault_names(flags), ["wheel_stall_left", "not_linked"]);
        assert!(fault_names(0).is_empty());
    }

    #[test]
    fn commands_parse_and_nothing_else_does() {
        assert_eq!(
            parse_command(r#"{"command":"emergency_stop"}"#),
            Some(OperatorCommand::EmergencyStop)
        );
        assert_eq!(
            parse_command(r#"{"command":"resume"}"#),
            Some(OperatorCommand::Resume)
        );
        for bad in [
            "",
            "{}",
            r#"{"command":"explode"}"#,
            "\u{0}\u{ff}",
            r#"{"command":1}"#,
        ] {
            assert_eq!(parse_command(bad), None, "{bad:?}");
        }
        assert!(guard::same(b"abc", b"abc") && !guard::same(b"abc", b"abd"));
        assert!(!guard::same(b"abc", b"ab"));
    }

    #[test]
    fn the_address_fits_a_qr_code() {
        let url = "http://192.168.100.200:45123/#pair=abcde-fghij";
        let text = qr_text(url).expect("a QR code");
        let rows = text.lines().count();
        // Version 3 or so: 29 modules and a quiet zone, two rows a line.
        assert!((15..=30).contains(&rows), "{rows} rows");
        assert!(text.contains('█') || text.contains('▀') || text.contains('▄'));
    }
}
