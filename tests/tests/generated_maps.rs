//! The fleet on maps nobody tuned for: generated per seed (bin fields with a free way,
//! streets with pinches and bends, a bin on the start line, scattered starts, traps,
//! alleys down to 1.3 m, V formations of 3, 4, 5 and 7 followers, maps with no way).
//! Every map with a way: goal reached, 0 contacts, every follower's max tracking error
//! after its join ≤ 0.35 m, mean |ω| ≤ 0.05 rad/s on the leader's straight legs and where
//! each follower's own reference runs straight (each where a run has 5 s of it), at most
//! two shape changes per narrow section of the leader's path. Every map without one:
//! refused up front, naming the waypoint. Obstacles the map does not hold are sensed and
//! routed round (a `replanned` event).
//!
//! A failing map is written to `target/generated-maps/NAME.toml`: `basestation sim` it.
//! `GENERATED_MAP_SEEDS=N` widens every suite to seeds 1..=N;
//! `GENERATED_MAP_FIRST_SEED=S` starts them at S instead (fresh maps: S=101).

mod common;

use base_station::scenario::Scenario;
use common::generate::{self, Generated};
use glam::DVec2;
use hil_sim::report::Report;
use hil_sim::world::World;

/// Seeds 1..=6 per suite; `GENERATED_MAP_SEEDS=N` runs N seeds (wider sweeps by hand),
/// from `GENERATED_MAP_FIRST_SEED` (default 1: maps nobody tuned for start at any other).
fn seeds() -> std::ops::RangeInclusive<u64> {
    common::generate::seeds("GENERATED_MAP_FIRST_SEED", "GENERATED_MAP_SEEDS", 6)
}

fn save(g: &Generated) -> String {
    g.save("generated-maps")
}

/// Stretches of the leader's driven path where the wide formation does not fit: the way
/// narrower than the formation, or a wide slot point (the leader's pose as driven) where
/// its follower would touch an obstacle, as the formation manager judges it.
fn narrow_sections(world: &World) -> usize {
    let spec = world.scenario.formation_spec();
    let half = 0.5 * (spec.wide_width() + spec.margin);
    let manager = base_station::formation::FormationManager::new(spec);
    let leader = world
        .robots
        .iter()
        .position(|r| r.id == world.scenario.leader().id);
    let Some(l) = leader else { return 0 };
    let mut sections = 0;
    let mut inside = false;
    for s in &world.recorder.samples {
        let r = &s.robots[l];
        let motion = base_station::formation::LeaderMotion {
            pose: base_station::planner::PlanPose {
                position: DVec2::new(r.x, r.y),
                heading: r.heading,
            },
            v: r.v,
            omega: r.omega,
        };
        let narrow = world.map.clearance(motion.pose.position, half) < half
            || manager.wide_slot_blocked(&world.map, motion, manager.slot_need());
        if narrow && !inside {
            sections += 1;
        }
        inside = narrow;
    }
    sections
}

/// Runs a map with a way; returns a one-line summary or what went wrong.
fn check_way(g: &Generated, seed: u64) -> Result<String, String> {
    check_way_then(g, seed, |_| Ok(String::new()))
}

/// [`check_way`], and `more` judges the run's report too (what it returns goes on the
/// summary line).
fn check_way_then(
    g: &Generated,
    seed: u64,
    more: impl Fn(&Report) -> Result<String, String>,
) -> Result<String, String> {
    let path = save(g);
    let s =
        Scenario::parse(&g.toml, &g.name).map_err(|e| format!("{path}: does not parse: {e}"))?;
    let problems = s.route_problems();
    if !problems.is_empty() {
        return Err(format!(
            "{path}: refused although a way exists: {problems:?}"
        ));
    }
    let (r, world): (Report, World) = common::run(s, seed);
    let sections = narrow_sections(&world);
    let changes = r.transformations.len();
    let errors: Vec<f64> = r
        .robots
        .iter()
        .filter_map(|x| x.max_tracking_error_m)
        .collect();
    let worst = errors.iter().copied().fold(0.0, f64::max);
    let joined = r
        .robots
        .iter()
        .filter(|x| x.role == "follower")
        .map(|x| x.joined_at_s.unwrap_or(f64::INFINITY))
        .fold(0.0, f64::max);
    let jitter = r
        .robots
        .iter()
        .filter(|x| x.role == "follower")
        .filter_map(|x| x.straight_avg_abs_omega_radps)
        .fold(0.0, f64::max);
    let legs = r.straight_leg_time_s;
    // Each follower where its own reference runs straight (5 s of it at least).
    let own_jitter = r
        .robots
        .iter()
        .filter_map(common::own_straight_omega)
        .fold(0.0, f64::max);
    let detours = r.events_named("follower_detour").count();
    let mut line = format!(
        "{:<34} goal {:>6} contacts {} min clearance {:.2} m joined {:>5.1} s max error {worst:.3} m straight |ω| {jitter:.3} ({legs:.0} s) own {own_jitter:.3} changes {changes} sections {sections} detours {detours}",
        g.name,
        r.time_to_goal_s.map_or("never".into(), |t| format!("{t:.1}")),
        r.collisions,
        r.min_obstacle_clearance_m,
        joined,
    );
    let mut bad = Vec::new();
    if !r.goal_reached {
        bad.push("goal not reached".to_string());
    }
    if r.collisions > 0 {
        bad.push(format!("{} contacts", r.collisions));
    }
    if worst > 0.35 {
        bad.push(format!("max tracking error {worst:.3} m"));
    }
    if legs >= common::STRAIGHT_LEGS_MIN_S && jitter > common::STRAIGHT_OMEGA_MAX {
        bad.push(format!("followers turn {jitter:.3} rad/s on straight legs"));
    }
    if own_jitter > common::STRAIGHT_OMEGA_MAX {
        bad.push(format!(
            "a follower turns {own_jitter:.3} rad/s where its reference runs straight"
        ));
    }
    if changes > 2 * sections {
        bad.push(format!(
            "{changes} shape changes for {sections} narrow sections"
        ));
    }
    match more(&r) {
        Ok(extra) => line.push_str(&extra),
        Err(e) => bad.push(e),
    }
    if bad.is_empty() {
        Ok(line)
    } else {
        Err(format!("{line}\n    {path}: {}", bad.join(", ")))
    }
}

fn suite(name: &str, make: impl Fn(u64) -> Generated) {
    suite_with(name, make, check_way);
}

/// Every seed's map through `check`; fails with every failing map listed.
fn suite_with(
    name: &str,
    make: impl Fn(u64) -> Generated,
    check: impl Fn(&Generated, u64) -> Result<String, String>,
) {
    let mut failures = Vec::new();
    let bar = common::progress(name, seeds().count() as u64);
    for seed in seeds() {
        let g = make(seed);
        match check(&g, seed) {
            Ok(line) => bar.suspend(|| println!("ok   {line}")),
            Err(e) => {
                bar.suspend(|| println!("FAIL {e}"));
                failures.push(e);
            }
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    assert!(
        failures.is_empty(),
        "{name}: {} of {} maps failed:\n{}",
        failures.len(),
        seeds().count(),
        failures.join("\n")
    );
}

#[test]
fn bin_fields_with_a_free_way() {
    suite("bin fields", |seed| generate::bin_field(seed, 60, 2));
}

#[test]
fn dense_bin_fields_with_a_free_way() {
    suite("dense bin fields", |seed| generate::bin_field(seed, 200, 2));
}

#[test]
fn streets_with_pinches_and_bends() {
    suite("streets", |seed| generate::street(seed, 2));
}

#[test]
fn a_bin_on_the_start_line() {
    suite("bin on the line", generate::bin_on_the_line);
}

#[test]
fn scattered_starts_join_without_contact() {
    suite("scattered starts", generate::scattered_starts);
}

#[test]
fn u_traps_open_toward_the_start() {
    suite("traps", generate::trap);
}

#[test]
fn alleys_with_a_bend_down_to_1_3_m() {
    suite("alleys 2 m", |seed| generate::alley(seed, 2.0));
    suite("alleys 1.3 m", |seed| generate::alley(seed, 1.3));
}

#[test]
fn three_follower_v_in_bin_fields() {
    suite("3-follower V in bin fields", |seed| {
        generate::bin_field(seed, 50, 3)
    });
}

#[test]
fn four_follower_v_in_streets() {
    suite("4-follower V in streets", |seed| generate::street(seed, 4));
}

#[test]
fn five_follower_v_in_bin_fields() {
    suite("5-follower V in bin fields", |seed| {
        generate::bin_field(seed, 40, 5)
    });
}

#[test]
fn seven_follower_v_in_streets() {
    suite("7-follower V in streets", |seed| generate::street(seed, 7));
}

/// `g` with its V in rows of three abreast.
fn in_rows(g: Generated) -> Generated {
    g.in_rows(3).expect("a V to put in rows")
}

/// Not yet: the generator starts the fleet in a V, whose rear lies off these maps.
#[test]
#[ignore = "issue 55, item 3: no start layout for rows on bin fields"]
fn fifteen_followers_in_rows_in_bin_fields() {
    suite("15 followers in rows in bin fields", |seed| {
        in_rows(generate::bin_field(seed, 40, 15))
    });
}

/// Not yet: the rows' change into the line and back loses the rear (0.66–3.35 m off on
/// seeds 1–6, one map short of the goal), as a large V's does.
#[test]
#[ignore = "issue 55, item 3: 15 followers in rows fail in streets"]
fn fifteen_followers_in_rows_in_streets() {
    suite("15 followers in rows in streets", |seed| {
        in_rows(generate::street(seed, 15))
    });
}

/// The map on which a follower used to stand behind a bin for good (21.6 m from its slot
/// at the goal, 230 s): its straight way to its reference ran into the bin, and its ring
/// held it there. The station now sends it round, and it catches up.
#[test]
fn a_follower_held_behind_a_bin_is_sent_round_it_and_catches_up() {
    let g = generate::bin_field(110, 45, 5);
    let path = save(&g);
    let s = Scenario::parse(&g.toml, &g.name).expect("parses");
    let (r, world) = common::run(s, 10);
    let events = |name: &str| {
        r.events_named(name)
            .map(|e| (e.robot, e.at_s))
            .collect::<Vec<_>>()
    };
    for e in r.station_events.iter().filter(|e| e.event != "linked") {
        println!("{path}: {:>6.2} s {} {:?}", e.at_s, e.event, e.robot);
    }
    assert!(r.goal_reached, "{path}: goal not reached");
    assert_eq!(r.collisions, 0, "{path}: contacts");
    assert!(!events("follower_detour").is_empty(), "{path}: no detour");
    // Every follower left behind caught up again.
    let behind = events("follower_behind");
    let caught_up = events("follower_caught_up");
    for (robot, at) in &behind {
        assert!(
            caught_up
                .iter()
                .any(|(who, when)| who == robot && when > at),
            "{path}: robot {robot:?} left behind at {at} s for good"
        );
    }
    // And every follower ends within the bound of its slot, the goal reached long before
    // the run's end (304 s when the leader crept on waiting).
    let last = world.recorder.samples.last().expect("samples");
    for (i, robot) in last.robots.iter().enumerate() {
        if let Some(e) = robot.error {
            assert!(
                e <= 0.35,
                "{path}: robot index {i} ends {e:.2} m off its slot"
            );
        }
    }
    assert!(
        r.time_to_goal_s.is_some_and(|t| t < 200.0),
        "{path}: {:?}",
        r.time_to_goal_s
    );
}

/// [`check_way`], and the run must have planned again at least once.
fn check_replanned(g: &Generated, seed: u64) -> Result<String, String> {
    check_way_then(g, seed, |r| {
        let replans = r.events_named("replanned").count();
        if replans == 0 {
            Err("never planned again".to_string())
        } else {
            Ok(format!(" replans {replans}"))
        }
    })
}

#[test]
fn an_unmapped_van_is_sensed_and_routed_round() {
    suite_with(
        "unmapped vans",
        |seed| generate::unmapped_in_the_way(2 * seed),
        check_replanned,
    );
}

#[test]
fn an_unmapped_barrier_turns_the_route_to_the_other_street() {
    suite_with(
        "unmapped barriers",
        |seed| generate::unmapped_in_the_way(2 * seed - 1),
        check_replanned,
    );
}

#[test]
fn maps_without_a_way_are_refused_up_front() {
    for seed in 1..9 {
        let g = generate::no_way(seed);
        let path = save(&g);
        let s = Scenario::parse(&g.toml, &g.name).expect("parses");
        let problems = s.route_problems();
        println!("{}: {problems:?}", g.name);
        assert!(!problems.is_empty(), "{path}: no way, yet accepted");
        assert_eq!(problems[0].0, "route.goal", "{path}");
    }
}
