//! `basestation ops`: the operations view. Joins the bus, keeps [`fleet::Fleet`] from every
//! formation's samples and its station's liveliness, asks the bus at start for the last
//! sample of every key (stations answer from their cache, so a late `ops` shows every live
//! formation at once), and serves one page with the console's server and guard. Commands go
//! to one formation as Zenoh queries, from a thread of their own (Zenoh's blocking calls may
//! not run on the page server's runtime), each answered or reported undelivered within
//! [`COMMAND_TIMEOUT`].

pub mod fleet;

use std::sync::mpsc::{self, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use bytes::Bytes;
use http_body_util::Full;
use hyper::Response;
use serde_json::{json, Value};
use zenoh::sample::SampleKind;
use zenoh::Wait;

use crate::bus::keys::{self, Formation};
use crate::live::console::server::{self, json as json_response, respond};
use fleet::Fleet;

/// How long a command may take to reach its station and be answered.
pub const COMMAND_TIMEOUT: Duration = Duration::from_secs(1);
/// Commands waiting for the commander thread.
const COMMANDS: usize = 16;

const PAGE: &str = include_str!("page.html");

/// What was asked of a formation, and where its answer goes.
struct Ask {
    formation: Formation,
    body: String,
    reply: tokio::sync::oneshot::Sender<(u16, Value)>,
}

/// `ops` on the bus: its session, the subscriptions that feed the fleet, and the page's side.
pub struct Ops {
    pub fleet: Arc<Mutex<Fleet>>,
    _session: zenoh::Session,
    _samples: zenoh::pubsub::Subscriber<()>,
    _stations: zenoh::pubsub::Subscriber<()>,
    asks: SyncSender<Ask>,
}

impl Ops {
    /// Joins the bus with `config` and fills the fleet from what the bus remembers.
    pub fn join(config: zenoh::Config) -> anyhow::Result<Self> {
        let client = config.get_json("mode").is_ok_and(|m| m.contains("client"));
        let session = zenoh::open(config)
            .wait()
            .map_err(|e| anyhow::anyhow!("cannot join the bus: {e}"))?;
        let fleet = Arc::new(Mutex::new(Fleet::default()));
        // What the bus remembers first: every sample after it is newer.
        remember(&session, &fleet);
        let f = fleet.clone();
        let samples = session
            .declare_subscriber(keys::ALL)
            .callback(move |s| {
                if s.kind() == SampleKind::Put {
                    if let Ok(mut fleet) = f.lock() {
                        let bytes = s.payload().to_bytes();
                        fleet.sample(s.key_expr().as_str(), &bytes, Instant::now(), true);
                        if let Some(t) = s.timestamp() {
                            fleet.sent_at(t.get_time().to_system_time());
                        }
                    }
                }
            })
            .wait()
            .map_err(|e| anyhow::anyhow!("cannot subscribe to {}: {e}", keys::ALL))?;
        let f = fleet.clone();
        let stations = session
            .liveliness()
            .declare_subscriber(keys::ALL_STATIONS)
            .history(true)
            .callback(move |s| {
                if let Ok(mut fleet) = f.lock() {
                    let live = s.kind() == SampleKind::Put;
                    fleet.presence(s.key_expr().as_str(), live, Instant::now());
                }
            })
            .wait()
            .map_err(|e| anyhow::anyhow!("cannot watch the stations: {e}"))?;
        let asks = commander(session.clone())?;
        if client {
            watch_router(session.clone(), fleet.clone())?;
        }
        Ok(Self {
            fleet,
            _session: session,
            _samples: samples,
            _stations: stations,
            asks,
        })
    }

    /// What the page server serves.
    pub fn backend(&self) -> View {
        View {
            fleet: self.fleet.clone(),
            asks: self.asks.clone(),
        }
    }
}

/// What the bus remembers: the last sample of every key from the router's storage (every
/// formation it has seen, gone ones too), and from each live station's cache. Asked
/// formation by formation too: access control lets a reader ask a station for its own keys
/// and no more. A formation remembered whose station is not live is shown lost.
fn remember(session: &zenoh::Session, fleet: &Arc<Mutex<Fleet>>) {
    let live = live_formations(session);
    let mut selectors = vec![keys::ALL.to_string()];
    selectors.extend(live.iter().map(|f| f.key("**")));
    let asked: Vec<_> = selectors
        .iter()
        .filter_map(|k| {
            let asked = session.get(k).timeout(Duration::from_secs(1)).wait();
            asked
                .map_err(|e| tracing::warn!("ops: cannot ask {k}: {e}"))
                .ok()
        })
        .collect();
    let mut remembered = 0;
    for replies in asked {
        while let Ok(reply) = replies.recv() {
            if let (Ok(sample), Ok(mut fleet)) = (reply.result(), fleet.lock()) {
                let bytes = sample.payload().to_bytes();
                fleet.sample(sample.key_expr().as_str(), &bytes, Instant::now(), false);
                remembered += 1;
            }
        }
    }
    if let Ok(mut fleet) = fleet.lock() {
        fleet.mark_gone_except(&live, Instant::now());
    }
    tracing::info!(
        "ops: {} live formation(s), {remembered} remembered sample(s)",
        live.len()
    );
}

/// The formations whose station holds its token now.
fn live_formations(session: &zenoh::Session) -> Vec<Formation> {
    let stations = match session
        .liveliness()
        .get(keys::ALL_STATIONS)
        .timeout(Duration::from_secs(1))
        .wait()
    {
        Ok(r) => r,
        Err(e) => {
            tracing::warn!("ops: the stations cannot be asked: {e}");
            return Vec::new();
        }
    };
    std::iter::from_fn(|| stations.recv().ok())
        .filter_map(|r| r.result().ok().map(|s| s.key_expr().as_str().to_string()))
        .filter_map(|k| keys::parse(&k).map(|(f, _)| f))
        .collect()
}

/// How often `ops` checks that it still reaches a router.
const ROUTER_CHECK: Duration = Duration::from_millis(500);

/// A client `ops` says when it has lost its router: what it shows is then the last it
/// heard, and every station looks lost. (A router `ops` is the bus itself.)
fn watch_router(session: zenoh::Session, fleet: Arc<Mutex<Fleet>>) -> anyhow::Result<()> {
    std::thread::Builder::new()
        .name("ops-router".into())
        .spawn(move || loop {
            let routers = session.info().routers_zid().wait().count();
            if let Ok(mut fleet) = fleet.lock() {
                fleet.router_reached = Some(routers > 0);
            }
            std::thread::sleep(ROUTER_CHECK);
        })?;
    Ok(())
}

/// The thread that sends commands and waits for their answers.
fn commander(session: zenoh::Session) -> anyhow::Result<SyncSender<Ask>> {
    let (tx, rx) = mpsc::sync_channel::<Ask>(COMMANDS);
    std::thread::Builder::new()
        .name("ops-commands".into())
        .spawn(move || {
            for ask in rx {
                let answer = ask_station(&session, &ask.formation, &ask.body);
                let _ = ask.reply.send(answer);
            }
        })?;
    Ok(tx)
}

/// One command to one formation's station: its answer, its refusal, or that it did not
/// arrive within [`COMMAND_TIMEOUT`].
fn ask_station(session: &zenoh::Session, formation: &Formation, body: &str) -> (u16, Value) {
    let key = formation.key("command");
    let undelivered = |why: String| {
        (
            504,
            json!({ "formation": formation.label(), "delivered": false, "why": why }),
        )
    };
    let replies = match session
        .get(&key)
        .payload(body.to_string())
        .timeout(COMMAND_TIMEOUT)
        .wait()
    {
        Ok(r) => r,
        Err(e) => return undelivered(format!("the bus refused the query: {e}")),
    };
    let deadline = Instant::now() + COMMAND_TIMEOUT;
    match replies.recv_deadline(deadline) {
        Ok(Some(reply)) => match reply.result() {
            Ok(sample) => {
                let answer = serde_json::from_slice::<Value>(&sample.payload().to_bytes())
                    .unwrap_or(Value::Null);
                let label = formation.label();
                (
                    200,
                    json!({ "formation": label, "delivered": true, "answer": answer }),
                )
            }
            Err(e) => {
                let why = e.payload().try_to_string().map(|s| s.to_string());
                let why = why.unwrap_or_else(|_| "refused".into());
                let label = formation.label();
                (
                    409,
                    json!({ "formation": label, "delivered": true, "refused": why }),
                )
            }
        },
        _ => undelivered(format!(
            "no answer within {} s: the station is gone, or this client may not command it",
            COMMAND_TIMEOUT.as_secs_f64()
        )),
    }
}

/// The page's side of `ops`.
pub struct View {
    fleet: Arc<Mutex<Fleet>>,
    asks: SyncSender<Ask>,
}

impl server::Backend for View {
    fn page(&self) -> &'static str {
        PAGE
    }

    fn map(&self) -> String {
        self.fleet
            .lock()
            .map(|f| f.maps().to_string())
            .unwrap_or_default()
    }

    fn state(&self) -> String {
        self.fleet
            .lock()
            .map(|f| f.state(Instant::now()).to_string())
            .unwrap_or_default()
    }

    async fn command(&self, body: Bytes) -> Response<Full<Bytes>> {
        let (formation, command) = match parse(&body) {
            Ok(parsed) => parsed,
            Err(why) => return respond(400, "text/plain", why),
        };
        let (reply, answer) = tokio::sync::oneshot::channel();
        let body = json!({ "command": command }).to_string();
        match self.asks.try_send(Ask {
            formation,
            body,
            reply,
        }) {
            Ok(()) => {}
            Err(TrySendError::Full(_)) => {
                return respond(503, "text/plain", "too many commands waiting")
            }
            Err(TrySendError::Disconnected(_)) => {
                return respond(500, "text/plain", "the bus is closed")
            }
        }
        match answer.await {
            Ok((status, v)) => json_response(status, v.to_string()),
            Err(_) => respond(500, "text/plain", "the command was lost"),
        }
    }
}

/// `{"formation": "<site>/<name>", "command": "stop" | "emergency_stop" | "resume"}`.
fn parse(body: &[u8]) -> Result<(Formation, &'static str), &'static str> {
    const EXPECTED: &str = "expected {\"formation\": \"<site>/<name>\", \
                            \"command\": \"stop\" | \"emergency_stop\" | \"resume\"}";
    let v: Value = serde_json::from_slice(body).map_err(|_| EXPECTED)?;
    let label = v["formation"].as_str().ok_or(EXPECTED)?;
    let (site, name) = label.split_once('/').ok_or(EXPECTED)?;
    let formation = Formation::new(site, name).map_err(|_| EXPECTED)?;
    let name = v["command"].as_str().ok_or(EXPECTED)?;
    let c = crate::live::console::command_named(name).ok_or(EXPECTED)?;
    Ok((formation, c.name()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_command_names_one_formation_and_one_command() {
        let (f, c) = parse(br#"{"formation":"north/a","command":"emergency_stop"}"#).expect("ok");
        assert_eq!((f.label().as_str(), c), ("north/a", "emergency_stop"));
        for bad in [
            &br#"{"formation":"north/*","command":"stop"}"#[..],
            br#"{"formation":"north","command":"stop"}"#,
            br#"{"formation":"north/a","command":"explode"}"#,
            br#"{"command":"stop"}"#,
            b"\xff",
        ] {
            assert!(parse(bad).is_err(), "{:?}", String::from_utf8_lossy(bad));
        }
    }
}
