//! The operator's console: `run --console [ADDR]` and `sim --realtime --console [ADDR]`
//! serve a page (plain HTML/JS in the binary, no build step) with the live map, each
//! robot's mode and link, the station's events, and Stop / Emergency stop / Resume, which
//! the station sends to the robots over the authenticated radio.
//!
//! The HTTP server (`tiny_http`) runs on its own thread; the station's loop publishes a
//! snapshot each period and takes the commands between periods, so the station itself is
//! never touched from another thread. A console drives robots: on any address but the
//! loopback, every request must carry the token printed at start (`?token=` or the
//! `X-Console-Token` header).

use std::net::SocketAddr;
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Mutex};

use anyhow::Context;
use base_station::station::{BaseStation, OperatorCommand};
use serde_json::{json, Value};
use tiny_http::{Header, Method, Response, Server};

const PAGE: &str = include_str!("page.html");
/// Events the page shows, newest last.
const EVENTS_SHOWN: usize = 30;

pub struct Console {
    snapshot: Arc<Mutex<String>>,
    commands: Receiver<OperatorCommand>,
    pub url: String,
}

impl Console {
    /// Serves the console on `addr` (port 0: any free port), with the site's static
    /// picture (`map`: obstacles and bounds).
    pub fn start(addr: SocketAddr, map: Value) -> anyhow::Result<Self> {
        let server = Server::http(addr)
            .map_err(|e| anyhow::anyhow!("cannot serve the console on {addr}: {e}"))?;
        let bound = server
            .server_addr()
            .to_ip()
            .context("the console is not on an IP address")?;
        let token = (!addr.ip().is_loopback()).then(new_token).transpose()?;
        let url = match &token {
            Some(t) => format!("http://{bound}/?token={t}"),
            None => format!("http://{bound}/"),
        };
        let snapshot = Arc::new(Mutex::new("{}".to_string()));
        let (tx, commands) = mpsc::channel();
        let shared = snapshot.clone();
        let map = map.to_string();
        std::thread::spawn(move || serve(server, token, &map, &shared, &tx));
        Ok(Self {
            snapshot,
            commands,
            url,
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
        Ok(Some(console))
    }

    /// The fleet as the page shows it now.
    pub fn publish(&self, snapshot: &Value) {
        if let Ok(mut s) = self.snapshot.lock() {
            *s = snapshot.to_string();
        }
    }

    /// The operator's commands since the last call.
    pub fn commands(&self) -> Vec<OperatorCommand> {
        self.commands.try_iter().collect()
    }
}

fn new_token() -> anyhow::Result<String> {
    let mut bytes = [0u8; 16];
    getrandom::fill(&mut bytes).map_err(|e| anyhow::anyhow!("no OS randomness: {e}"))?;
    Ok(hex::encode(bytes))
}

/// Compares in time independent of where the first difference is.
fn same(a: &str, b: &str) -> bool {
    a.len() == b.len() && a.bytes().zip(b.bytes()).fold(0u8, |d, (x, y)| d | (x ^ y)) == 0
}

fn serve(
    server: Server,
    token: Option<String>,
    map: &str,
    snapshot: &Mutex<String>,
    commands: &Sender<OperatorCommand>,
) {
    let json_type = Header::from_bytes("Content-Type", "application/json").expect("a header");
    for mut request in server.incoming_requests() {
        let (path, query) = request
            .url()
            .split_once('?')
            .map_or((request.url().to_string(), String::new()), |(p, q)| {
                (p.to_string(), q.to_string())
            });
        if let Some(token) = &token {
            let given = query
                .split('&')
                .find_map(|kv| kv.strip_prefix("token="))
                .map(str::to_string)
                .or_else(|| {
                    request
                        .headers()
                        .iter()
                        .find(|h| h.field.equiv("X-Console-Token"))
                        .map(|h| h.value.to_string())
                });
            if !given.is_some_and(|g| same(&g, token)) {
                let _ = request
                    .respond(Response::from_string("a token is needed").with_status_code(403));
                continue;
            }
        }
        let response = match (request.method(), path.as_str()) {
            (Method::Get, "/") => Response::from_string(PAGE).with_header(
                Header::from_bytes("Content-Type", "text/html; charset=utf-8").expect("a header"),
            ),
            (Method::Get, "/api/map") => {
                Response::from_string(map.to_string()).with_header(json_type.clone())
            }
            (Method::Get, "/api/state") => {
                let body = snapshot.lock().map(|s| s.clone()).unwrap_or_default();
                Response::from_string(body).with_header(json_type.clone())
            }
            (Method::Post, "/api/command") => {
                let mut body = String::new();
                let _ = std::io::Read::read_to_string(
                    &mut std::io::Read::take(request.as_reader(), 256),
                    &mut body,
                );
                match parse_command(&body) {
                    Some(c) if commands.send(c).is_ok() => {
                        Response::from_string(format!("{{\"sent\":\"{}\"}}", c.name()))
                            .with_header(json_type.clone())
                    }
                    Some(_) => Response::from_string("the run has ended").with_status_code(410),
                    None => Response::from_string(
                        "expected {\"command\": \"stop\" | \"emergency_stop\" | \"resume\"}",
                    )
                    .with_status_code(400),
                }
            }
            _ => Response::from_string("not found").with_status_code(404),
        };
        let _ = request.respond(response);
    }
}

fn parse_command(body: &str) -> Option<OperatorCommand> {
    let v: Value = serde_json::from_str(body).ok()?;
    match v.get("command")?.as_str()? {
        "stop" => Some(OperatorCommand::Stop),
        "emergency_stop" => Some(OperatorCommand::EmergencyStop),
        "resume" => Some(OperatorCommand::Resume),
        _ => None,
    }
}

/// The site's static picture for the page: the map's obstacles and the route's goal.
pub fn map_json(scenario: &base_station::scenario::Scenario) -> Value {
    json!({
        "obstacles": scenario.build_site().obstacles(),
        "goal": scenario.route.points().last().map(|g| [g.x, g.y]),
    })
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
                "mode": t.map(|t| format!("{:?}", t.mode)),
                "faults": t.map(|t| t.faults),
                "linked": peer.is_some_and(|p| p.is_linked()),
                "seen_ms_ago": peer.and_then(|p| p.last_rx_ms).map(|r| now_ms.wrapping_sub(r)),
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
        .planner()
        .route()
        .map(|r| r.points.iter().map(|p| [p.x, p.y]).collect())
        .unwrap_or_default();
    let events = station.events();
    let events: Vec<Value> = events[events.len().saturating_sub(EVENTS_SHOWN)..]
        .iter()
        .map(|e| {
            let (at_ms, event, robot) = e.describe(leader);
            json!({ "at_s": at_ms as f64 / 1000.0, "event": event, "robot": robot })
        })
        .collect();
    json!({
        "t_s": now_ms as f64 / 1000.0,
        "robots": robots,
        "slots": slots,
        "route": route,
        "shape": format!("{:?}", station.formation().target()).to_lowercase(),
        "blend": station.formation().blend(),
        "hold": station.operator_hold().map(|h| h.name()),
        "arrived": station.planner().arrived(),
        "events": events,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

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
        assert!(same("abc", "abc") && !same("abc", "abd") && !same("abc", "ab"));
    }
}
