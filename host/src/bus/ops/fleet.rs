//! What `ops` knows of every formation on the bus: the last sample of each key, whether its
//! station is live, and the alerts an operations team acts on. Fed by the bus's samples and
//! liveliness changes; read as the page's JSON. Time here is the wall clock's (`Instant`):
//! `ops` watches live fleets, it simulates nothing.

use std::collections::{BTreeMap, HashMap, VecDeque};
use std::time::{Duration, Instant, SystemTime};

use serde_json::{json, Value};

use crate::bus::keys::{self, Formation, Topic};

/// Events kept per formation.
const EVENTS_KEPT: usize = 8;
/// What `ops` holds at most, whatever a station publishes: a payload's bytes (a city
/// block's map is tens of KiB), formations, robots per formation.
pub const MAX_PAYLOAD: usize = 1 << 20;
pub const MAX_FORMATIONS: usize = 1024;
pub const MAX_ROBOTS: usize = 256;
/// A live station that published nothing for this long is shown as silent.
pub const SILENT_AFTER: Duration = Duration::from_secs(2);

/// Whether a formation's station is on the bus.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Presence {
    /// Seen in samples, its liveliness not yet known.
    Unknown,
    Live,
    Lost {
        since: Instant,
    },
}

#[derive(Default)]
struct Robot {
    pose: Value,
    state: Value,
    link: Value,
}

struct View {
    presence: Presence,
    formation: Value,
    robots: BTreeMap<u16, Robot>,
    route: Value,
    map: Value,
    events: VecDeque<Value>,
    last_sample: Option<Instant>,
    /// Bumped when the map or the route changes: the page fetches them again.
    rev: u64,
}

impl View {
    fn new() -> Self {
        Self {
            presence: Presence::Unknown,
            formation: Value::Null,
            robots: BTreeMap::new(),
            route: Value::Null,
            map: Value::Null,
            events: VecDeque::new(),
            last_sample: None,
            rev: 0,
        }
    }
}

/// Latencies kept for the percentiles: the last minute of a 50-formation city.
const LATENCIES_KEPT: usize = 20_000;
/// A station publishes each key every period (0.1 s of its clock); a gap longer than
/// this between two samples of one key lost samples in between.
const PERIOD_S: f64 = 0.1;

/// Every formation `ops` has seen since it started (or learnt of from the bus's memory).
#[derive(Default)]
pub struct Fleet {
    views: BTreeMap<Formation, View>,
    /// Samples taken, and those whose payload was not what the key space says.
    pub samples: u64,
    pub malformed: u64,
    /// Samples a station published every period that never came (from gaps in `t_s`).
    pub lost: u64,
    /// Publish-to-`ops` latencies (ms) of the last samples, from their timestamps.
    latencies: VecDeque<f64>,
    /// Each per-period key's last `t_s`.
    last_t: HashMap<String, f64>,
    /// Whether a client `ops` reaches a router (`None`: `ops` is the router).
    pub router_reached: Option<bool>,
}

impl Fleet {
    /// A sample on `key`; `fresh` is false for an answer to the start-up query, which never
    /// replaces what a live sample brought.
    pub fn sample(&mut self, key: &str, payload: &[u8], now: Instant, fresh: bool) {
        let Some((formation, topic)) = keys::parse(key) else {
            return;
        };
        let known = self.views.contains_key(&formation);
        let room = known || self.views.len() < MAX_FORMATIONS;
        let parsed = (payload.len() <= MAX_PAYLOAD && room)
            .then(|| serde_json::from_slice::<Value>(payload).ok())
            .flatten();
        let Some(value) = parsed else {
            self.malformed += 1;
            return;
        };
        self.samples += 1;
        if fresh && matches!(topic, Topic::Formation | Topic::Robot { .. }) {
            self.count_gaps(key, &value);
        }
        let view = self.views.entry(formation).or_insert_with(View::new);
        view.last_sample = Some(now);
        let slow = matches!(topic, Topic::Route | Topic::Map);
        let slot = match topic {
            Topic::Formation => &mut view.formation,
            Topic::Route => &mut view.route,
            Topic::Map => &mut view.map,
            Topic::Events => {
                view.events.push_back(value);
                if view.events.len() > EVENTS_KEPT {
                    view.events.pop_front();
                }
                return;
            }
            Topic::Robot { id, topic } => {
                if !view.robots.contains_key(&id) && view.robots.len() >= MAX_ROBOTS {
                    self.malformed += 1;
                    return;
                }
                let robot = view.robots.entry(id).or_default();
                match topic.as_str() {
                    "pose" => &mut robot.pose,
                    "state" => &mut robot.state,
                    "link" => &mut robot.link,
                    _ => return,
                }
            }
            Topic::Station | Topic::Command => return,
        };
        if !fresh && !slot.is_null() {
            return;
        }
        if slow && *slot != value {
            view.rev += 1;
        }
        *slot = value;
    }

    /// A sample's publish time (its timestamp): its latency is kept.
    pub fn sent_at(&mut self, sent: SystemTime) {
        let ms = SystemTime::now()
            .duration_since(sent)
            .map_or(0.0, |d| d.as_secs_f64() * 1e3);
        if self.latencies.len() == LATENCIES_KEPT {
            self.latencies.pop_front();
        }
        self.latencies.push_back(ms);
    }

    fn count_gaps(&mut self, key: &str, value: &Value) {
        let Some(t) = value["t_s"].as_f64() else {
            return;
        };
        // The key is copied once, the first time it is seen.
        let Some(last) = self.last_t.get_mut(key) else {
            self.last_t.insert(key.to_string(), t);
            return;
        };
        let missed = ((t - *last) / PERIOD_S).round() as i64 - 1;
        // A restarted station's clock starts again: no gap to count.
        if missed > 0 && t > *last {
            self.lost += missed as u64;
        }
        *last = t;
    }

    /// The bus as `ops` sees it: samples, malformed, lost, and latency percentiles (ms).
    pub fn bus(&self) -> Value {
        let mut l: Vec<f64> = self.latencies.iter().copied().collect();
        l.sort_by(f64::total_cmp);
        let at = |q: f64| (!l.is_empty()).then(|| l[((l.len() - 1) as f64 * q) as usize]);
        json!({
            "samples": self.samples,
            "malformed": self.malformed,
            "lost": self.lost,
            "latency_ms": { "p50": at(0.5), "p99": at(0.99), "max": l.last(), "of": l.len() },
        })
    }

    /// A station's liveliness token came (`live`) or went.
    pub fn presence(&mut self, key: &str, live: bool, now: Instant) {
        let Some((formation, Topic::Station)) = keys::parse(key) else {
            return;
        };
        if !self.views.contains_key(&formation) && self.views.len() >= MAX_FORMATIONS {
            return;
        }
        let view = self.views.entry(formation).or_insert_with(View::new);
        view.presence = if live {
            Presence::Live
        } else {
            Presence::Lost { since: now }
        };
    }

    /// Every formation known but not in `live` lost its station (before `ops` started).
    pub fn mark_gone_except(&mut self, live: &[Formation], now: Instant) {
        for (f, v) in self.views.iter_mut() {
            if v.presence == Presence::Unknown && !live.contains(f) {
                v.presence = Presence::Lost { since: now };
            }
        }
    }

    /// The page's state: every formation, by site, with its alerts.
    pub fn state(&self, now: Instant) -> Value {
        let mut all_alerts = Vec::new();
        if self.router_reached == Some(false) {
            all_alerts.push(json!({
                "formation": "ops",
                "alert": "the bus's router is out of reach: the page shows what it last heard",
            }));
        }
        let formations: Vec<Value> = self
            .views
            .iter()
            .map(|(f, v)| {
                let alerts = alerts(v, now);
                for a in &alerts {
                    all_alerts.push(json!({ "formation": f.label(), "alert": a }));
                }
                view_json(f, v, alerts, now)
            })
            .collect();
        json!({
            "formations": formations,
            "alerts": all_alerts,
            "bus": self.bus(),
        })
    }

    /// Every formation's map and route, for the page to draw under the robots.
    pub fn maps(&self) -> Value {
        let maps: serde_json::Map<String, Value> = self
            .views
            .iter()
            .map(|(f, v)| {
                let m = json!({ "map": v.map, "route": v.route["points"], "rev": v.rev });
                (f.label(), m)
            })
            .collect();
        Value::Object(maps)
    }

    /// The formations `ops` knows, by label.
    pub fn labels(&self) -> Vec<String> {
        self.views.keys().map(Formation::label).collect()
    }
}

fn view_json(f: &Formation, v: &View, alerts: Vec<String>, now: Instant) -> Value {
    let (station, lost_for_s) = match v.presence {
        Presence::Unknown => ("unknown", None),
        Presence::Live => ("live", None),
        Presence::Lost { .. } if !v.formation["finished"].is_null() => ("finished", None),
        Presence::Lost { since } => ("lost", Some(now.duration_since(since).as_secs_f64())),
    };
    let robots: Vec<Value> = v
        .robots
        .iter()
        .map(|(id, r)| json!({ "id": id, "pose": r.pose, "state": r.state, "link": r.link }))
        .collect();
    json!({
        "site": f.site,
        "name": f.name,
        "label": f.label(),
        "station": station,
        "lost_for_s": lost_for_s,
        "quiet_s": v.last_sample.map(|t| now.duration_since(t).as_secs_f64()),
        "formation": v.formation,
        "robots": robots,
        "events": v.events,
        "alerts": alerts,
        "rev": v.rev,
    })
}

/// What an operations team must see of one formation: a lost station, a halted or
/// stopped formation, a robot whose link is lost, a station gone quiet.
fn alerts(v: &View, now: Instant) -> Vec<String> {
    let mut alerts = Vec::new();
    let f = &v.formation;
    // A station that said its run finished leaves the bus as it should.
    if matches!(v.presence, Presence::Lost { .. }) && f["finished"].is_null() {
        alerts.push("station lost".to_string());
    }
    if f["finished"].is_null() {
        match f["gate"].as_str() {
            Some("halted") => alerts.push("formation halted".into()),
            Some("leader_lost") => alerts.push("leader lost: followers stopped".into()),
            _ => {}
        }
        if let Some(hold) = f["hold"].as_str() {
            alerts.push(format!("held by the operator ({})", hold.replace('_', " ")));
        }
    }
    if v.presence == Presence::Live {
        let quiet = v.last_sample.map(|t| now.duration_since(t));
        if quiet.is_some_and(|q| q > SILENT_AFTER) {
            alerts.push("station live but silent".into());
        }
        for (id, r) in &v.robots {
            let late = match (
                r.link["seen_ms_ago"].as_f64(),
                r.link["lost_after_ms"].as_f64(),
            ) {
                (Some(seen), Some(limit)) => seen > limit,
                _ => false,
            };
            if r.link["linked"] == json!(false) || late {
                alerts.push(format!("robot {id} lost"));
            }
        }
    }
    alerts
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_build_a_view_and_alerts_follow() {
        let mut fleet = Fleet::default();
        let t0 = Instant::now();
        fleet.presence("sweeper/north/a/station", true, t0);
        fleet.sample(
            "sweeper/north/a/formation",
            br#"{"gate":"running","hold":null}"#,
            t0,
            true,
        );
        fleet.sample(
            "sweeper/north/a/robot/2/link",
            br#"{"linked":true,"seen_ms_ago":900,"lost_after_ms":500}"#,
            t0,
            true,
        );
        fleet.sample("sweeper/north/a/robot/2/pose", b"not json", t0, true);
        let s = fleet.state(t0);
        assert_eq!(s["formations"][0]["station"], "live");
        assert_eq!(s["alerts"][0]["alert"], "robot 2 lost");
        assert_eq!((fleet.samples, fleet.malformed), (2, 1));
        // One period skipped on a key: one sample lost.
        let pose = |t: f64| format!(r#"{{"t_s":{t},"x":0,"y":0,"heading":0}}"#);
        for t in [1.0, 1.1, 1.3, 1.4] {
            fleet.sample("sweeper/north/a/robot/2/pose", pose(t).as_bytes(), t0, true);
        }
        assert_eq!(fleet.lost, 1);
        // The station goes: lost, and its robots' links are no longer judged.
        fleet.presence("sweeper/north/a/station", false, t0);
        let s = fleet.state(t0 + SILENT_AFTER * 2);
        assert_eq!(s["formations"][0]["alerts"], json!(["station lost"]));
    }

    #[test]
    fn what_a_station_publishes_is_bounded() {
        let mut fleet = Fleet::default();
        let t0 = Instant::now();
        let huge = vec![b' '; MAX_PAYLOAD + 1];
        fleet.sample("sweeper/s/f/formation", &huge, t0, true);
        for id in 0..=MAX_ROBOTS as u16 {
            let key = format!("sweeper/s/f/robot/{id}/pose");
            fleet.sample(&key, br#"{"t_s":1}"#, t0, true);
        }
        assert_eq!(fleet.malformed, 2);
        assert_eq!(
            fleet.state(t0)["formations"][0]["robots"]
                .as_array()
                .unwrap()
                .len(),
            MAX_ROBOTS
        );
        for i in 0..MAX_FORMATIONS + 5 {
            fleet.sample(&format!("sweeper/s/g{i}/formation"), b"{}", t0, true);
        }
        assert_eq!(fleet.labels().len(), MAX_FORMATIONS);
    }

    #[test]
    fn a_start_up_answer_never_replaces_a_live_sample() {
        let mut fleet = Fleet::default();
        let t0 = Instant::now();
        fleet.sample("sweeper/s/f/formation", br#"{"gate":"running"}"#, t0, true);
        fleet.sample("sweeper/s/f/formation", br#"{"gate":"waiting"}"#, t0, false);
        assert_eq!(
            fleet.state(t0)["formations"][0]["formation"]["gate"],
            "running"
        );
        fleet.sample("sweeper/s/g/route", br#"{"points":[[0,0]]}"#, t0, false);
        assert_eq!(fleet.maps()["s/g"]["rev"], 1);
        assert_eq!(fleet.labels(), ["s/f", "s/g"]);
    }
}
