//! A station on the bus (`run|sim … --zenoh CONFIG`): publishes its formation under its own
//! keys, holds a liveliness token, answers late joiners with the last of each key, and takes
//! commands as queries. Everything Zenoh does runs on a thread of its own: the station's
//! loop hands over a snapshot and takes commands out, and never waits on the bus, so a bus
//! that is slow or gone changes nothing the station does with its robots.

use std::collections::{BTreeMap, HashMap};
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use base_station::station::OperatorCommand;
use serde_json::{json, Value};
use zenoh::bytes::Encoding;
use zenoh::query::Query;
use zenoh::Wait;

use super::keys::Formation;
use super::payload;

/// Snapshots waiting for the bus thread: a slow bus drops the oldest view, never the loop.
const QUEUE: usize = 4;
/// How often the slow keys (route, map) are published again, in station periods.
const SLOW_EVERY: u64 = 50;
/// How long to wait between tries to open the session while the router is away.
const RETRY: Duration = Duration::from_secs(2);

/// What the station's loop hands the bus thread.
enum Out {
    Snapshot(Arc<Value>),
    Answer(u64, Result<Value, String>),
    Close,
}

/// A command from the bus, with the number its answer must carry.
pub struct BusCommand {
    pub id: u64,
    pub command: OperatorCommand,
}

pub struct StationBus {
    tx: SyncSender<Out>,
    commands: Receiver<BusCommand>,
    thread: Option<JoinHandle<()>>,
    /// Snapshots the bus thread was too slow to take.
    pub dropped: u64,
}

impl StationBus {
    /// Joins the bus with Zenoh's own configuration file, as `formation`; the session opens
    /// on the bus thread (and is tried again until the router answers).
    pub fn open(
        mut config: zenoh::Config,
        formation: Formation,
        map: Value,
    ) -> anyhow::Result<Self> {
        // Every sample carries its publish time (the session's HLC): readers measure the
        // bus's latency, storages order samples.
        config
            .insert_json5("timestamping/enabled", "true")
            .map_err(|e| anyhow::anyhow!("timestamping: {e}"))?;
        let (tx, rx) = mpsc::sync_channel(QUEUE);
        let (command_tx, commands) = mpsc::sync_channel(16);
        let thread = std::thread::Builder::new()
            .name("bus".into())
            .spawn(move || Worker::run(config, formation, map, rx, command_tx))?;
        Ok(Self {
            tx,
            commands,
            thread: Some(thread),
            dropped: 0,
        })
    }

    /// The formation as it is now (the console's snapshot); never waits.
    pub fn publish(&mut self, snapshot: &Value) {
        match self.tx.try_send(Out::Snapshot(Arc::new(snapshot.clone()))) {
            Ok(()) => {}
            Err(TrySendError::Full(_)) => self.dropped += 1,
            Err(TrySendError::Disconnected(_)) => {}
        }
    }

    /// The commands the bus brought since the last call.
    pub fn commands(&self) -> Vec<BusCommand> {
        self.commands.try_iter().collect()
    }

    /// What was done with command `id` (or why it was refused), for the client that sent it.
    pub fn answer(&self, id: u64, result: Result<Value, String>) {
        // The answer waits if it must: it is what a client is waiting for.
        let _ = self.tx.send(Out::Answer(id, result));
    }
}

impl Drop for StationBus {
    fn drop(&mut self) {
        let _ = self.tx.send(Out::Close);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The last sample of each key, for clients that join late.
type Latest = Arc<Mutex<BTreeMap<String, Vec<u8>>>>;

struct Worker {
    session: zenoh::Session,
    formation: Formation,
    latest: Latest,
    publishers: HashMap<String, zenoh::pubsub::Publisher<'static>>,
    pending: HashMap<u64, Query>,
    next_id: u64,
    events_published: u64,
    periods: u64,
    map: Value,
}

impl Worker {
    fn run(
        config: zenoh::Config,
        formation: Formation,
        map: Value,
        rx: Receiver<Out>,
        commands: SyncSender<BusCommand>,
    ) {
        let Some(session) = open_until_ready(&config, &rx) else {
            return;
        };
        let label = formation.label();
        let joined = Joined::declare(&session, &formation);
        let Joined {
            token,
            commands: queries,
            cache: _cache,
            latest,
        } = match joined {
            Ok(j) => j,
            Err(e) => return tracing::error!("bus: cannot join as {label}: {e}"),
        };
        tracing::info!("bus: joined as {label}");
        let mut worker = Worker {
            latest,
            session,
            formation,
            publishers: HashMap::new(),
            pending: HashMap::new(),
            next_id: 0,
            events_published: 0,
            periods: 0,
            map,
        };
        loop {
            match rx.recv_timeout(Duration::from_millis(20)) {
                Ok(Out::Snapshot(s)) => worker.publish(&s),
                Ok(Out::Answer(id, result)) => worker.answer(id, result),
                Ok(Out::Close) | Err(mpsc::RecvTimeoutError::Disconnected) => break,
                Err(mpsc::RecvTimeoutError::Timeout) => {}
            }
            while let Ok(Some(query)) = queries.try_recv() {
                worker.take(query, &commands);
            }
        }
        let _ = token.undeclare().wait();
        let _ = worker.session.close().wait();
    }

    /// A query on the command key: parsed and handed to the station's loop, or refused.
    fn take(&mut self, query: Query, commands: &SyncSender<BusCommand>) {
        if query.key_expr().as_str() != self.formation.key("command") {
            return; // a query for every key (a late joiner's): the cache answers it
        }
        let body = query
            .payload()
            .and_then(|p| p.try_to_string().ok().map(|s| s.to_string()));
        let Some(command) = body
            .as_deref()
            .and_then(crate::live::console::parse_command)
        else {
            let _ = query
                .reply_err(r#"expected {"command": "stop" | "emergency_stop" | "resume"}"#)
                .wait();
            return;
        };
        let id = self.next_id;
        self.next_id += 1;
        match commands.try_send(BusCommand { id, command }) {
            Ok(()) => {
                self.pending.insert(id, query);
            }
            Err(_) => {
                let _ = query.reply_err("too many commands waiting").wait();
            }
        }
    }

    fn answer(&mut self, id: u64, result: Result<Value, String>) {
        let Some(query) = self.pending.remove(&id) else {
            return;
        };
        let key = self.formation.key("command");
        let sent = match result {
            Ok(v) => query
                .reply(key, v.to_string())
                .encoding(Encoding::APPLICATION_JSON)
                .wait(),
            Err(why) => query.reply_err(why).wait(),
        };
        if let Err(e) = sent {
            tracing::warn!("bus: the answer to a command was not sent: {e}");
        }
    }

    /// One snapshot, as the samples of each key.
    fn publish(&mut self, snapshot: &Value) {
        let f = self.formation.clone();
        let mut samples = payload::per_period(&f, snapshot);
        let new_events = payload::new_events(snapshot, &mut self.events_published);
        if self.periods.is_multiple_of(SLOW_EVERY) || snapshot.get("finished").is_some() {
            samples.push((f.key("route"), payload::route(snapshot)));
            samples.push((f.key("map"), self.map.clone()));
        }
        self.periods += 1;
        for (key, value) in samples {
            self.put(key, &value);
        }
        // The cache keeps the last event: a late joiner sees what happened last.
        for event in new_events {
            self.put(f.key("events"), &event);
        }
    }

    fn put(&mut self, key: String, value: &Value) {
        let bytes = value.to_string().into_bytes();
        if let Ok(mut latest) = self.latest.lock() {
            latest.insert(key.clone(), bytes.clone());
        }
        let publisher = match self.publishers.get(&key) {
            Some(p) => p,
            None => {
                let declared = self
                    .session
                    .declare_publisher(key.clone())
                    .encoding(Encoding::APPLICATION_JSON)
                    .wait();
                match declared {
                    Ok(p) => self.publishers.entry(key).or_insert(p),
                    Err(e) => return tracing::warn!("bus: cannot publish {key}: {e}"),
                }
            }
        };
        if let Err(e) = publisher.put(bytes).wait() {
            tracing::debug!("bus: a sample was not sent: {e}");
        }
    }
}

/// Opens the session, trying again every [`RETRY`] while the router is away; `None` if the
/// station closed first.
fn open_until_ready(config: &zenoh::Config, rx: &Receiver<Out>) -> Option<zenoh::Session> {
    let mut said = false;
    loop {
        match zenoh::open(config.clone()).wait() {
            Ok(s) => return Some(s),
            Err(e) if !said => {
                tracing::warn!("bus: cannot open a session yet ({e}); trying again every 2 s");
                said = true;
            }
            Err(_) => {}
        }
        // Snapshots meanwhile are dropped: the bus shows the formation once it is there.
        let until = std::time::Instant::now() + RETRY;
        while let Some(left) = until.checked_duration_since(std::time::Instant::now()) {
            match rx.recv_timeout(left) {
                Ok(Out::Close) | Err(mpsc::RecvTimeoutError::Disconnected) => return None,
                _ => {}
            }
        }
    }
}

/// What a station declares on joining.
struct Joined {
    token: zenoh::liveliness::LivelinessToken,
    commands: zenoh::query::Queryable<zenoh::handlers::FifoChannelHandler<Query>>,
    /// Answers late joiners from `latest` while it is held.
    cache: zenoh::query::Queryable<()>,
    latest: Latest,
}

impl Joined {
    fn declare(session: &zenoh::Session, f: &Formation) -> zenoh::Result<Self> {
        // Two stations must not speak for one formation.
        let station = f.key("station");
        let live = session
            .liveliness()
            .get(station.clone())
            .timeout(Duration::from_millis(500))
            .wait()?;
        if let Ok(Some(reply)) = live.recv_timeout(Duration::from_millis(600)) {
            if reply.result().is_ok() {
                return Err(format!("another station is live as {}", f.label()).into());
            }
        }
        let token = session.liveliness().declare_token(station).wait()?;
        let commands = session.declare_queryable(f.key("command")).wait()?;
        let latest: Latest = Arc::default();
        let held = latest.clone();
        let cache = session
            .declare_queryable(f.key("**"))
            .callback(move |query| answer_from(&held, &query))
            .wait()?;
        Ok(Self {
            token,
            commands,
            cache,
            latest,
        })
    }
}

/// A late joiner's query: the last sample of each key it covers.
fn answer_from(latest: &Latest, query: &Query) {
    let Ok(latest) = latest.lock() else {
        return;
    };
    let asked = query.key_expr().clone();
    for (key, bytes) in latest.iter() {
        let Ok(k) = zenoh::key_expr::KeyExpr::try_from(key.as_str()) else {
            continue;
        };
        if asked.intersects(&k) {
            let _ = query
                .reply(k, bytes.clone())
                .encoding(Encoding::APPLICATION_JSON)
                .wait();
        }
    }
}

/// Carries out a command from the bus on `station`, as the console's are: what was done,
/// or why it was refused.
pub fn obey(
    station: &mut base_station::station::BaseStation,
    command: OperatorCommand,
    now_ms: u32,
) -> Result<Value, String> {
    let halted = matches!(station.gate(), base_station::station::Gate::Halted);
    if command == OperatorCommand::Resume && halted {
        return Err(
            "refused: the fleet halted for good (a robot cannot drive as told); \
                    clear the fault and start the run again"
                .into(),
        );
    }
    station.operator(command, now_ms);
    Ok(json!({
        "done": command.name(),
        "hold": station.operator_hold().map(|h| h.name()),
        "robots": station.robots().len(),
        "t_s": now_ms as f64 / 1000.0,
    }))
}
