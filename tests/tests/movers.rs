//! The fleet among people and vehicles, on generated worlds (one seed each): a person
//! crossing in front of the formation, one walking against it in a 3 m alley, a cyclist
//! overtaking, a car pulling out across the street, a person standing 20 s in the way,
//! crowds of 0.05, 0.1, 0.2 and 0.3 persons/m² on a plaza (social and oblivious), movers
//! among unmapped obstacles. Each world also runs without its movers, for the time to
//! goal against the empty site.
//!
//! Bounds (issue 29): no contact while a robot moves, on every world; no contact with the
//! site or between robots; oblivious walkers walk into a standing robot in under 1 % of
//! runs (over every oblivious world of the run); social crowds up to 0.2 persons/m²: the
//! goal reached on at least 99 % of the worlds, mean personal-space intrusion ≤ 1 s per
//! run; at 0.1 persons/m², mean time to goal ≤ 1.3 × the empty site's. The rates are
//! printed per suite as the crowd-navigation benchmarks report them (success, contact,
//! timeout).
//!
//! The oblivious crowds' bounds are not met: that test is `#[ignore]`d with the reason
//! (run it with `--include-ignored`), and so is the social crowds' (its intrusion at 0.2
//! persons/m² is over 1 s; its time holds); docs/results.md#movers has the figures.
//!
//! A failing world is written to `target/mover-worlds/NAME.toml`: `basestation sim` it.
//! `MOVER_SEEDS=N` runs N seeds per suite (default 4), from `MOVER_FIRST_SEED` (default
//! 1: fresh worlds start at any other).

mod common;

use base_station::scenario::Scenario;
use common::generate::movers as gen;
use common::generate::Generated;
use hil_sim::report::Report;

fn seeds() -> std::ops::RangeInclusive<u64> {
    common::generate::seeds("MOVER_FIRST_SEED", "MOVER_SEEDS", 4)
}

fn save(g: &Generated) -> String {
    g.save("mover-worlds")
}

/// One world's run, and the same world's without its movers.
struct Outcome {
    name: String,
    path: String,
    report: Report,
    empty_s: Option<f64>,
}

impl Outcome {
    fn static_contacts(&self) -> u32 {
        let m = &self.report.movers;
        self.report.collisions - m.contacts_moving - m.contacts_standing
    }

    fn ratio(&self) -> Option<f64> {
        Some(self.report.time_to_goal_s? / self.empty_s?)
    }

    fn line(&self) -> String {
        let r = &self.report;
        let m = &r.movers;
        let num = |v: Option<f64>| v.map_or("never".to_string(), |v| format!("{v:.1}"));
        format!(
            "{:<34} goal {:>6} empty {:>6} ratio {:>5} contacts moving {} standing {} static {} least person {} intrusion {:.1} s freezing {:.1} s movers {}",
            self.name,
            num(r.time_to_goal_s),
            num(self.empty_s),
            self.ratio().map_or("—".to_string(), |x| format!("{x:.2}")),
            m.contacts_moving,
            m.contacts_standing,
            self.static_contacts(),
            m.min_person_clearance_m
                .map_or("—".to_string(), |c| format!("{c:.2} m")),
            m.intrusion_s,
            m.freezing_s,
            m.count,
        )
    }
}

fn run(g: &Generated, seed: u64) -> Outcome {
    let path = save(g);
    let s = Scenario::parse(&g.toml, &g.name).unwrap_or_else(|e| panic!("{path}: {e}"));
    let mut empty = s.clone();
    empty.movers.clear();
    empty.crowds.clear();
    let (report, _) = common::run(s, seed);
    let (bare, _) = common::run(empty, seed);
    Outcome {
        name: g.name.clone(),
        path,
        report,
        empty_s: bare.time_to_goal_s,
    }
}

/// A suite's rates, as the crowd-navigation benchmarks report them.
struct Rates {
    n: usize,
    success: f64,
    /// Worlds with a contact while a robot moved.
    contact: f64,
    /// Worlds where a standing robot was walked into.
    walked_into: f64,
    timeout: f64,
    intrusion_s: f64,
    /// Half the 95 % confidence interval of the mean intrusion, s: a world's intrusion
    /// swings by seconds with a small change anywhere (1.6 s standard deviation over 192
    /// worlds at 0.2 persons/m²), so a set of 64 pins the mean only to about ±0.4 s.
    intrusion_95: f64,
    /// The 95 % (Wilson) interval of the success rate.
    success_95: (f64, f64),
    /// The leader's share of the robots' intrusion time, robot by robot (NaN: none).
    leader_share: f64,
    freezing_s: f64,
    /// Mean time to goal over the empty site's, where both reached it, and half its 95 %
    /// confidence interval.
    ratio: Option<f64>,
    ratio_95: f64,
}

fn rates(outcomes: &[Outcome]) -> Rates {
    let n = outcomes.len();
    let share =
        |f: &dyn Fn(&Outcome) -> bool| outcomes.iter().filter(|o| f(o)).count() as f64 / n as f64;
    let mean = |f: &dyn Fn(&Outcome) -> f64| outcomes.iter().map(f).sum::<f64>() / n as f64;
    let ratios: Vec<f64> = outcomes.iter().filter_map(Outcome::ratio).collect();
    Rates {
        n,
        success: share(&|o| o.report.goal_reached),
        contact: share(&|o| o.report.movers.contacts_moving > 0),
        walked_into: share(&|o| o.report.movers.contacts_standing > 0),
        timeout: share(&|o| !o.report.goal_reached),
        intrusion_s: mean(&|o| o.report.movers.intrusion_s),
        intrusion_95: half_95(
            &outcomes
                .iter()
                .map(|o| o.report.movers.intrusion_s)
                .collect::<Vec<_>>(),
        ),
        success_95: wilson_95(share(&|o| o.report.goal_reached), n),
        leader_share: leader_share(outcomes),
        freezing_s: mean(&|o| o.report.movers.freezing_s),
        ratio: (!ratios.is_empty()).then(|| ratios.iter().sum::<f64>() / ratios.len() as f64),
        ratio_95: half_95(&ratios),
    }
}

/// Half the 95 % confidence interval of the mean of `xs` (normal approximation).
fn half_95(xs: &[f64]) -> f64 {
    let n = xs.len() as f64;
    if xs.len() < 2 {
        return f64::NAN;
    }
    let mean = xs.iter().sum::<f64>() / n;
    let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    1.96 * (var / n).sqrt()
}

/// The 95 % Wilson score interval of a rate `p` over `n` worlds: it stays inside [0, 1]
/// and is not empty at 0 % or 100 % (every world of 64 reaching the goal says only that
/// the rate is likely over 94 %).
fn wilson_95(p: f64, n: usize) -> (f64, f64) {
    let (z, n) = (1.96_f64, n as f64);
    let centre = (p + z * z / (2.0 * n)) / (1.0 + z * z / n);
    let half = z / (1.0 + z * z / n) * (p * (1.0 - p) / n + z * z / (4.0 * n * n)).sqrt();
    ((centre - half).max(0.0), (centre + half).min(1.0))
}

/// The leader's share of every robot's intrusion time over the suite.
fn leader_share(outcomes: &[Outcome]) -> f64 {
    let (mut leader, mut all) = (0.0, 0.0);
    for o in outcomes {
        let by_robot = &o.report.movers.intrusion_by_robot_s;
        for (robot, s) in o.report.robots.iter().zip(by_robot) {
            leader += if robot.role == "leader" { *s } else { 0.0 };
            all += s;
        }
    }
    leader / all
}

/// Runs a suite; prints the lines and the rates, and returns the outcomes for the
/// bounds.
fn suite(name: &str, make: impl Fn(u64) -> Generated) -> (Rates, Vec<Outcome>) {
    let bar = common::progress(name, seeds().count() as u64);
    let mut outcomes = Vec::new();
    for seed in seeds() {
        let o = run(&make(seed), seed);
        bar.suspend(|| println!("{}", o.line()));
        outcomes.push(o);
        bar.inc(1);
    }
    bar.finish_and_clear();
    let r = rates(&outcomes);
    println!(
        "suite {name}: {} worlds, success {:.0} % (95 %: {:.0}–{:.0} %), contact {:.0} %, walked into {:.0} %, timeout {:.0} %, mean intrusion {:.2} s (± {:.2} s, 95 %), mean freezing {:.1} s, time {} × empty, leader's share of intrusion {}",
        r.n,
        100.0 * r.success,
        100.0 * r.success_95.0,
        100.0 * r.success_95.1,
        100.0 * r.contact,
        100.0 * r.walked_into,
        100.0 * r.timeout,
        r.intrusion_s,
        r.intrusion_95,
        r.freezing_s,
        r.ratio.map_or("—".to_string(), |x| format!(
            "{x:.2} (± {:.2}, 95 %)",
            r.ratio_95
        )),
        if r.leader_share.is_nan() {
            "—".to_string()
        } else {
            format!("{:.0} %", 100.0 * r.leader_share)
        }
    );
    (r, outcomes)
}

/// The worlds with a contact while a robot moved or with the site, if any.
fn touched(name: &str, outcomes: &[Outcome]) -> Option<String> {
    let bad: Vec<String> = outcomes
        .iter()
        .filter(|o| o.report.movers.contacts_moving > 0 || o.static_contacts() > 0)
        .map(|o| format!("{}\n    {}", o.line(), o.path))
        .collect();
    (!bad.is_empty()).then(|| {
        format!(
            "{name}: contacts while moving or with the site:\n{}",
            bad.join("\n")
        )
    })
}

/// Every world: no contact while a robot moved, none with the site.
fn no_contacts(name: &str, outcomes: &[Outcome]) {
    if let Some(bad) = touched(name, outcomes) {
        panic!("{bad}");
    }
}

/// Every world reaches its goal.
fn all_arrive(name: &str, outcomes: &[Outcome]) {
    let late: Vec<String> = outcomes
        .iter()
        .filter(|o| !o.report.goal_reached)
        .map(|o| format!("{}\n    {}", o.line(), o.path))
        .collect();
    assert!(
        late.is_empty(),
        "{name}: goal not reached:\n{}",
        late.join("\n")
    );
}

/// Oblivious walkers may walk into a standing robot: under 1 % of runs.
fn rarely_walked_into(name: &str, outcomes: &[Outcome]) {
    let hit: Vec<String> = outcomes
        .iter()
        .filter(|o| o.report.movers.contacts_standing > 0)
        .map(|o| format!("{}\n    {}", o.line(), o.path))
        .collect();
    assert!(
        hit.len() * 100 < outcomes.len().max(1),
        "{name}: a standing robot walked into in {} of {} runs:\n{}",
        hit.len(),
        outcomes.len(),
        hit.join("\n")
    );
}

#[test]
fn a_person_crossing_in_front() {
    for social in [true, false] {
        let name = format!("crossing-{}", gen::behavior_name(social));
        let (_, o) = suite(&name, |s| gen::crossing(s, social));
        no_contacts(&name, &o);
        all_arrive(&name, &o);
    }
}

/// The robots keep aside in the alley (`station/passing.rs`): no robot within this of the
/// walker's footprint, m. Standing in the middle, they were passed at 0.002–0.29 m
/// (seeds 1–4 and 301–332); keeping aside, at 0.38–0.93 m.
const ALLEY_KEPT_M: f64 = 0.3;

#[test]
fn a_person_walking_against_the_formation_in_a_3m_alley() {
    for social in [true, false] {
        let name = format!("oncoming-{}", gen::behavior_name(social));
        let (_, o) = suite(&name, |s| gen::oncoming_alley(s, social));
        no_contacts(&name, &o);
        all_arrive(&name, &o);
        let close: Vec<String> = o
            .iter()
            .filter(|o| {
                let least = o.report.movers.min_person_clearance_m;
                least.is_none_or(|c| c < ALLEY_KEPT_M)
            })
            .map(|o| format!("{}\n    {}", o.line(), o.path))
            .collect();
        assert!(
            close.is_empty(),
            "{name}: a robot within {ALLEY_KEPT_M} m of the walker:\n{}",
            close.join("\n")
        );
    }
}

#[test]
fn a_cyclist_overtaking() {
    for social in [true, false] {
        let name = format!("cyclist-{}", gen::behavior_name(social));
        let (_, o) = suite(&name, |s| gen::cyclist_overtaking(s, social));
        no_contacts(&name, &o);
        all_arrive(&name, &o);
    }
}

#[test]
fn a_car_pulling_out_across_the_street() {
    let (_, o) = suite("car-pulling-out", gen::car_pulling_out);
    no_contacts("car-pulling-out", &o);
    all_arrive("car-pulling-out", &o);
}

#[test]
fn a_person_standing_20s_in_the_way() {
    for social in [true, false] {
        let name = format!("standing-{}", gen::behavior_name(social));
        let (_, o) = suite(&name, |s| gen::standing_person(s, social));
        no_contacts(&name, &o);
        all_arrive(&name, &o);
    }
}

/// With the fitted tracker (2026-12-04 night) 0.1 takes 1.13-1.20 × the empty time,
/// but the intrusion at 0.2 is over its bound: 1.9 s on seeds 1-4 (5.2 s on seed 4),
/// 1.2 s on 301-332 and 333-396, 1.9 s on 701-732; since a narrowed way is replanned
/// at most every 5 s while the leader is held, 1.18 s on 1301-1364 with 1501-1564 and
/// 0.98 s on 1601-1664, every world reaching the goal (before, one world in 64 or 96 of
/// several sets timed out; docs/results.md#movers). A world's intrusion swings by seconds
/// (1.6-2.0 s standard deviation), so a set of 32 or 64 pins the mean to ±0.4-0.9 s: the
/// suite line gives the 95 % interval.
#[test]
#[ignore = "issue 29's bound is not met yet: mean intrusion at 0.2 persons/m² is over \
            1 s on most seed sets (1.18 s on 1301-1364 and 1501-1564, 0.98 s on \
            1601-1664, 1.42 s on 1701-1732, 1.31 s on 1733-1796, 1.75 ± 0.86 s on \
            1797-1828; 1.29 ± 0.17 s over 448 worlds on d1cef64)"]
fn social_crowds_on_a_plaza() {
    let mut failed = Vec::new();
    for density in [0.05, 0.1, 0.2, 0.3] {
        let name = format!("plaza-{density}-social");
        let (r, o) = suite(&name, |s| gen::plaza_crowd(s, density, true));
        failed.extend(touched(&name, &o));
        if density <= 0.2 && r.success < 0.99 {
            failed.push(format!("{name}: success {:.2}", r.success));
        }
        if density <= 0.2 && r.intrusion_s > 1.0 {
            failed.push(format!("{name}: mean intrusion {:.2} s", r.intrusion_s));
        }
        let ratio = r.ratio.unwrap_or(f64::INFINITY);
        if density == 0.1 && ratio > 1.3 {
            failed.push(format!(
                "{name}: time to goal {ratio:.2} × the empty site's"
            ));
        }
    }
    assert!(failed.is_empty(), "{}", failed.join("\n"));
}

#[test]
#[ignore = "issue 29's bound is not met yet: oblivious crowds walk into moving robots \
            (3 of 4 worlds at 0.05 persons/m², every world above) and into standing ones \
            on every world; docs/results.md#movers. Run with --ignored"]
fn oblivious_crowds_on_a_plaza() {
    let (mut all, mut failed) = (Vec::new(), Vec::new());
    for density in [0.05, 0.1, 0.2, 0.3] {
        let name = format!("plaza-{density}-oblivious");
        let (_, o) = suite(&name, |s| gen::plaza_crowd(s, density, false));
        failed.extend(touched(&name, &o));
        all.extend(o);
    }
    assert!(failed.is_empty(), "{}", failed.join("\n"));
    rarely_walked_into("plaza-oblivious", &all);
}

/// Robots standing close in a dense crowd keep apart where their rings cannot see each
/// other (`station/spacing.rs`): the worlds of the plaza suites' fresh seeds where a
/// follower crossing to its slot clipped another standing square to its side, where
/// the leader crept into a follower 65° off its heading, where a follower sent aside
/// for another backed its flank into it (1033), and where two followers tracking slots
/// that swung with the leader converged flank to flank (1324).
#[test]
fn robots_keep_apart_in_dense_crowds() {
    let mut touched = Vec::new();
    for (density, seed) in [(0.2, 331), (0.3, 305), (0.2, 304), (0.2, 1033), (0.3, 1324)] {
        let g = gen::plaza_crowd(seed, density, true);
        let path = save(&g);
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
/// order its followers stand (`station/order.rs`): on this fresh seed the follower left
/// behind followed the other at its ring's distance, 2 m off its slot, and the leader
/// waited for it at its floor pace until the world's time was up.
#[test]
fn a_line_out_of_order_reaches_the_goal() {
    let g = gen::standing_person(107, false);
    let path = save(&g);
    let s = Scenario::parse(&g.toml, &g.name).unwrap_or_else(|e| panic!("{path}: {e}"));
    let (r, _) = common::run(s, 107);
    let reordered = r.events_named("line_reordered").next().is_some();
    assert!(reordered, "{path}: the line was never reordered");
    assert!(r.goal_reached, "{path}: goal not reached");
}

#[test]
fn movers_among_unmapped_obstacles() {
    let (_, o) = suite("movers-unmapped", gen::movers_and_unmapped);
    no_contacts("movers-unmapped", &o);
    all_arrive("movers-unmapped", &o);
}

/// Since the leader steps back out of a late-seen walker's way (2026-12-06,
/// `station/stepping_back.rs`): 3 of the 400 worlds of seeds 1-4, 101-108, 301-332,
/// 601-624 and 701-732 (0.75 %), all people who stopped and set off again close by
/// (docs/results.md#movers); 4 of 400 before. On fresh seeds 1701-1796, 3 of 384
/// (0.78 %), but 2 of the 128 of 1701-1732 alone. Over every fresh seed 1701-2148, 17 of
/// 1,792 (0.95 %, 95 %: 0.59-1.51 %): at the bound's edge, and this test failed on
/// 1957-2020 (4 of 256) and 2021-2148 (6 of 512). Since the leader hurries across a
/// stranger's way early (2026-12-07), 16 of 2,304 over 1701-2276 (0.69 %, 95 %:
/// 0.43-1.13 %; 19 before): per set 6 of 1,024 on 1701-1956, 5 of 512 on 2021-2148
/// and 2 of 512 on 2149-2276 pass, 3 of 256 on 1957-2020 still fails.
#[test]
fn oblivious_walkers_rarely_walk_into_a_standing_robot() {
    let mut all = Vec::new();
    all.extend(suite("crossing-oblivious", |s| gen::crossing(s, false)).1);
    all.extend(suite("oncoming-oblivious", |s| gen::oncoming_alley(s, false)).1);
    all.extend(suite("cyclist-oblivious", |s| gen::cyclist_overtaking(s, false)).1);
    all.extend(suite("standing-oblivious", |s| gen::standing_person(s, false)).1);
    rarely_walked_into("oblivious walkers", &all);
}
