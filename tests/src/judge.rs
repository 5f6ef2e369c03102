//! What a suite's reports say, as the issues judge them: goals, contacts by who did what
//! (issue 51: a robot must never drive into a person; being walked into is judged by the
//! robot's speed and by the rate a parked fleet has in the same worlds), intrusion, time
//! against the empty site. Read from the report's JSON, the public interface.

use serde_json::Value;

use crate::stats::{half_95, mean, quantile, wilson_95};

/// One run's figures.
#[derive(Debug, Clone)]
pub struct Run {
    pub name: String,
    pub goal: bool,
    pub time_to_goal_s: Option<f64>,
    pub empty_s: Option<f64>,
    pub drove_into: u64,
    pub walked_into: u64,
    pub contacts_moving: u64,
    /// Contacts with the site or between robots.
    pub static_contacts: u64,
    pub intrusion_s: f64,
    pub robot_hours: f64,
    /// Robots standing where these were, per robot-hour (oblivious movers only).
    pub parked_rate: Option<f64>,
    /// The robot's speed at each listed walked-into contact, m/s.
    pub walked_speeds: Vec<f64>,
    /// The report without its wall time: equal texts, identical runs.
    pub text: String,
}

fn u(v: &Value) -> u64 {
    v.as_u64().unwrap_or(0)
}

impl Run {
    pub fn parse(name: &str, json: &str) -> Result<Self, String> {
        let mut r: Value = serde_json::from_str(json).map_err(|e| format!("{name}: {e}"))?;
        if let Some(o) = r.as_object_mut() {
            o.remove("wall_time_s");
        }
        let m = &r["movers"];
        let drove_into = u(&m["drove_into"]);
        let walked_into = u(&m["walked_into_standing"]) + u(&m["walked_into_braking"]);
        let robots = r["robots"].as_array().map_or(0, Vec::len);
        let walked_speeds = m["contacts"]
            .as_array()
            .into_iter()
            .flatten()
            .filter(|c| c["class"] != "drove_into")
            .filter_map(|c| c["robot_speed_mps"].as_f64())
            .collect();
        Ok(Self {
            name: name.to_string(),
            goal: r["goal_reached"].as_bool().unwrap_or(false),
            time_to_goal_s: r["time_to_goal_s"].as_f64(),
            empty_s: m["time_to_goal_empty_s"].as_f64(),
            drove_into,
            walked_into,
            contacts_moving: u(&m["contacts_moving"]),
            static_contacts: u(&r["collisions"]).saturating_sub(drove_into + walked_into),
            intrusion_s: m["intrusion_s"].as_f64().unwrap_or(0.0),
            robot_hours: robots as f64 * r["sim_time_s"].as_f64().unwrap_or(0.0) / 3600.0,
            parked_rate: m["parked_contacts_per_robot_hour"].as_f64(),
            walked_speeds,
            text: r.to_string(),
        })
    }

    pub fn ratio(&self) -> Option<f64> {
        Some(self.time_to_goal_s? / self.empty_s?)
    }
}

/// A suite's figures over its runs.
#[derive(Debug, Clone)]
pub struct Figures {
    pub n: usize,
    pub goals: usize,
    pub drove_into_worlds: usize,
    pub moving_contact_worlds: usize,
    pub walked_into_worlds: usize,
    pub static_contact_worlds: usize,
    pub contacts_per_robot_hour: f64,
    /// Robots standing where the fleet went, per robot-hour, over the runs that have it.
    pub parked_per_robot_hour: Option<f64>,
    /// The robot's speed at walked-into contacts: p50, p95, max, m/s.
    pub walked_speed: Option<(f64, f64, f64)>,
    pub intrusion_s: f64,
    pub intrusion_95: f64,
    pub ratio: Option<(f64, f64)>,
}

impl Figures {
    pub fn of(runs: &[&Run]) -> Self {
        let count = |f: &dyn Fn(&Run) -> bool| runs.iter().filter(|r| f(r)).count();
        let speeds: Vec<f64> = runs.iter().flat_map(|r| r.walked_speeds.clone()).collect();
        let contacts: u64 = runs.iter().map(|r| r.drove_into + r.walked_into).sum();
        let hours: f64 = runs.iter().map(|r| r.robot_hours).sum();
        let parked: Vec<(f64, f64)> = runs
            .iter()
            .filter_map(|r| Some((r.parked_rate? * r.robot_hours, r.robot_hours)))
            .collect();
        let parked_hours: f64 = parked.iter().map(|p| p.1).sum();
        let intrusion: Vec<f64> = runs.iter().map(|r| r.intrusion_s).collect();
        let ratios: Vec<f64> = runs.iter().filter_map(|r| r.ratio()).collect();
        Self {
            n: runs.len(),
            goals: count(&|r| r.goal),
            drove_into_worlds: count(&|r| r.drove_into > 0),
            moving_contact_worlds: count(&|r| r.contacts_moving > 0),
            walked_into_worlds: count(&|r| r.walked_into > 0),
            static_contact_worlds: count(&|r| r.static_contacts > 0),
            contacts_per_robot_hour: if hours > 0.0 {
                contacts as f64 / hours
            } else {
                0.0
            },
            parked_per_robot_hour: (parked_hours > 0.0)
                .then(|| parked.iter().map(|p| p.0).sum::<f64>() / parked_hours),
            walked_speed: quantile(&speeds, 0.5)
                .zip(quantile(&speeds, 0.95))
                .map(|(a, b)| {
                    let max = speeds.iter().copied().fold(0.0, f64::max);
                    (a, b, max)
                }),
            intrusion_s: mean(&intrusion),
            intrusion_95: half_95(&intrusion),
            ratio: (!ratios.is_empty()).then(|| (mean(&ratios), half_95(&ratios))),
        }
    }

    /// The 95 % Wilson interval of the share of worlds walked into.
    pub fn walked_into_95(&self) -> (f64, f64) {
        wilson_95(
            self.walked_into_worlds as f64 / self.n.max(1) as f64,
            self.n,
        )
    }
}

fn pct(k: usize, n: usize) -> String {
    format!("{k} ({:.1} %)", 100.0 * k as f64 / n.max(1) as f64)
}

fn speeds(s: Option<(f64, f64, f64)>) -> String {
    s.map_or("—".to_string(), |(a, b, c)| {
        format!("{a:.2} / {b:.2} / {c:.2}")
    })
}

fn rate(r: Option<f64>) -> String {
    r.map_or("—".to_string(), |r| format!("{r:.2}"))
}

fn ratio(r: Option<(f64, f64)>) -> String {
    r.map_or("—".to_string(), |(m, h)| format!("{m:.2} ± {h:.2}"))
}

/// `old → new`, or one value where both agree.
fn pair(a: String, b: String) -> String {
    if a == b {
        a
    } else {
        format!("{a} → {b}")
    }
}

/// The markdown table of paired runs, a row per suite in `order` and one for all.
pub fn paired_table(order: &[&str], pairs: &[(String, Run, Run)]) -> String {
    let mut out = String::from(
        "| suite | worlds | goals | drove into | contact while moving | walked into | walked-into speed p50 / p95 / max, m/s | contacts per robot-hour | parked where it went, per robot-hour | static contacts | mean intrusion, s | paired Δ intrusion (95 %) | time × empty | reports changed |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let rows = order.iter().map(|s| (s.to_string(), Some(*s)));
    for (label, suite) in rows.chain(std::iter::once(("all".to_string(), None))) {
        let of = |r: &(String, Run, Run)| suite.is_none_or(|s| r.0 == s);
        let here: Vec<&(String, Run, Run)> = pairs.iter().filter(|p| of(p)).collect();
        if here.is_empty() {
            continue;
        }
        out.push_str(&row(&label, &here));
    }
    out
}

fn row(label: &str, here: &[&(String, Run, Run)]) -> String {
    let old: Vec<&Run> = here.iter().map(|p| &p.1).collect();
    let new: Vec<&Run> = here.iter().map(|p| &p.2).collect();
    let (a, b) = (Figures::of(&old), Figures::of(&new));
    let diffs: Vec<f64> = here
        .iter()
        .map(|p| p.2.intrusion_s - p.1.intrusion_s)
        .collect();
    let changed = here.iter().filter(|p| p.1.text != p.2.text).count();
    let n = a.n;
    format!(
        "| {label} | {n} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {:+.3} ± {:.3} | {} | {changed} |\n",
        pair(a.goals.to_string(), b.goals.to_string()),
        pair(pct(a.drove_into_worlds, n), pct(b.drove_into_worlds, n)),
        pair(pct(a.moving_contact_worlds, n), pct(b.moving_contact_worlds, n)),
        pair(pct(a.walked_into_worlds, n), pct(b.walked_into_worlds, n)),
        pair(speeds(a.walked_speed), speeds(b.walked_speed)),
        pair(
            format!("{:.2}", a.contacts_per_robot_hour),
            format!("{:.2}", b.contacts_per_robot_hour)
        ),
        pair(rate(a.parked_per_robot_hour), rate(b.parked_per_robot_hour)),
        pair(a.static_contact_worlds.to_string(), b.static_contact_worlds.to_string()),
        pair(format!("{:.3}", a.intrusion_s), format!("{:.3}", b.intrusion_s)),
        mean(&diffs),
        half_95(&diffs),
        pair(ratio(a.ratio), ratio(b.ratio)),
    )
}
