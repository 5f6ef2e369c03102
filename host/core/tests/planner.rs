//! The planner alone, driving an ideal unicycle at 10 Hz: each local-minimum case escapes
//! and reaches the goal without touching anything.

use base_station::geometry::map::Map;
use base_station::geometry::Obstacle;
use base_station::planner::{Mode, Pace, PlanPose, Planner, PlannerParams};
use glam::DVec2;

const FOOTPRINT: f64 = 0.3;

struct Outcome {
    reached_at: Option<f64>,
    min_clearance: f64,
    escapes: u32,
}

fn drive(map: &Map, start: PlanPose, goal: DVec2, limit_s: f64) -> Outcome {
    let mut planner = Planner::new(PlannerParams::DEFAULT, vec![goal], 0.0);
    let mut pose = start;
    let mut min_clearance = f64::INFINITY;
    let dt = 0.1;
    let mut t = 0.0;
    while t < limit_s {
        let cmd = planner.step(t, dt, pose, map, 0.0, 1.0);
        if cmd.mode == Mode::Arrived {
            return Outcome {
                reached_at: Some(t),
                min_clearance,
                escapes: planner.escapes(),
            };
        }
        pose.position += DVec2::new(pose.heading.cos(), pose.heading.sin()) * cmd.v * dt;
        pose.heading += cmd.omega * dt;
        min_clearance = min_clearance.min(map.clearance(pose.position, 10.0) - FOOTPRINT);
        t += dt;
    }
    Outcome {
        reached_at: None,
        min_clearance,
        escapes: planner.escapes(),
    }
}

fn wall(a: (f64, f64), b: (f64, f64)) -> Obstacle {
    Obstacle::Segment {
        a: DVec2::new(a.0, a.1),
        b: DVec2::new(b.0, b.1),
    }
}

fn start() -> PlanPose {
    PlanPose {
        position: DVec2::ZERO,
        heading: 0.0,
    }
}

fn report(name: &str, o: &Outcome) {
    println!(
        "{name}: reached after {:?} s, min clearance {:.2} m, {} escape(s)",
        o.reached_at, o.min_clearance, o.escapes
    );
}

#[test]
fn open_field_goes_straight() {
    let o = drive(&Map::new(vec![]), start(), DVec2::new(10.0, 0.0), 100.0);
    report("open", &o);
    let t = o.reached_at.expect("goal reached");
    // 10 m at 0.45 m/s with the acceleration ramp and the slow last metre.
    assert!(t < 30.0, "{t}");
    assert_eq!(o.escapes, 0);
}

#[test]
fn u_shaped_trap() {
    let map = Map::new(vec![
        wall((5.0, -2.5), (5.0, 2.5)),
        wall((2.0, 2.5), (5.0, 2.5)),
        wall((2.0, -2.5), (5.0, -2.5)),
    ]);
    let o = drive(&map, start(), DVec2::new(10.0, 0.0), 300.0);
    report("U trap", &o);
    assert!(o.reached_at.is_some());
    assert!(o.escapes >= 1, "the trap must have caught it");
    assert!(o.min_clearance > 0.0);
}

#[test]
fn obstacle_right_before_the_goal() {
    let map = Map::new(vec![Obstacle::Circle {
        center: DVec2::new(5.0, 0.0),
        radius: 0.5,
    }]);
    let o = drive(&map, start(), DVec2::new(6.3, 0.0), 200.0);
    report("pole before goal", &o);
    assert!(o.reached_at.is_some());
    assert!(o.min_clearance > 0.0);
}

#[test]
fn symmetric_gap_too_narrow_for_comfort() {
    let pole = |y| Obstacle::Circle {
        center: DVec2::new(5.0, y),
        radius: 0.5,
    };
    let map = Map::new(vec![pole(0.9), pole(-0.9)]);
    let o = drive(&map, start(), DVec2::new(10.0, 0.0), 200.0);
    report("symmetric gap", &o);
    assert!(o.reached_at.is_some());
    assert!(o.min_clearance > 0.0);
}

/// A route behind the leader, with a formation's slots 3 m out: the turn on the spot is
/// limited to 0.8 / 3 rad/s and takes longer than the stuck window. It is a turn, not a
/// blockage: no replanning, the leader arrives.
#[test]
fn a_u_turn_toward_the_route_is_not_a_blockage() {
    use base_station::planner::route::RouteParams;
    let map = Map::new(vec![wall((-30.0, 5.0), (10.0, 5.0))]);
    let goal = DVec2::new(-20.0, 0.0);
    let mut planner = Planner::routed(
        PlannerParams::DEFAULT,
        vec![goal],
        0.0,
        RouteParams::for_fleet(FOOTPRINT, 3.0, 0.4),
    );
    planner.set_formation(3.0, 0.8, 0.5);
    let turn_s = std::f64::consts::PI / planner.turn_limit();
    assert!(turn_s > PlannerParams::DEFAULT.stuck_window_s, "{turn_s} s");
    let mut pose = start();
    let dt = 0.1;
    let mut arrived = None;
    for k in 0..1200 {
        let t = k as f64 * dt;
        let cmd = planner.step(t, dt, pose, &map, 0.0, 1.0);
        if cmd.mode == Mode::Arrived {
            arrived = Some(t);
            break;
        }
        pose.position += DVec2::new(pose.heading.cos(), pose.heading.sin()) * cmd.v * dt;
        pose.heading += cmd.omega * dt;
    }
    println!(
        "U-turn {turn_s:.1} s, arrived {arrived:?}, replans {}",
        planner.replans()
    );
    assert_eq!(planner.replans(), 0, "the turn was taken for a blockage");
    assert!(arrived.is_some());
}

/// Mean |ω| the routed planner commands over 20 m of open field, with the leader's heading
/// seen through fixes' noise (σ ≈ 0.5°, deterministic), and where it ends up across.
fn straight_run(params: PlannerParams) -> (f64, f64) {
    use base_station::planner::route::RouteParams;
    let goal = DVec2::new(25.0, 0.0);
    let mut planner = Planner::routed(
        params,
        vec![goal],
        0.0,
        RouteParams::for_fleet(FOOTPRINT, 3.0, 0.4),
    );
    planner.set_formation(6.0, 0.8, 0.5);
    let mut pose = start();
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let mut noise = || {
        // xorshift64, then a sum of four uniforms: about normal, σ ≈ 0.5°.
        let mut sum = 0.0;
        for _ in 0..4 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            sum += (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        }
        sum * 0.5f64.to_radians() / (4.0f64 / 12.0).sqrt()
    };
    let (mut sum, mut n) = (0.0, 0);
    let dt = 0.1;
    for k in 0..600 {
        let seen = PlanPose {
            heading: pose.heading + noise(),
            ..pose
        };
        let cmd = planner.step(k as f64 * dt, dt, seen, &Map::new(vec![]), 0.0, 1.0);
        if (3.0..20.0).contains(&pose.position.x) {
            sum += cmd.omega.abs();
            n += 1;
        }
        pose.position += DVec2::new(pose.heading.cos(), pose.heading.sin()) * cmd.v * dt;
        pose.heading += cmd.omega * dt;
    }
    (sum / n as f64, pose.position.y)
}

#[test]
fn the_leader_does_not_steer_on_the_noise_of_its_fixes() {
    let (with, across) = straight_run(PlannerParams::DEFAULT);
    let (without, _) = straight_run(PlannerParams {
        turn_dead_band: 0.0,
        ..PlannerParams::DEFAULT
    });
    println!("mean |ω| on a straight leg: {with:.4} rad/s (without the dead band {without:.4}); {across:.3} m across at the end");
    // A 6 m V's rear slot swings 6·ω across: 0.002 rad/s is 1.2 cm/s.
    assert!(with < 0.002, "{with}");
    assert!(without > 3.0 * with.max(0.001), "{without} vs {with}");
    assert!(across.abs() < 0.1, "{across} m off the route");
}

#[test]
fn the_dead_band_still_turns_onto_a_heading_off_by_ten_degrees() {
    let map = Map::new(vec![]);
    let mut planner = Planner::new(PlannerParams::DEFAULT, vec![DVec2::new(20.0, 0.0)], 0.0);
    let mut pose = PlanPose {
        heading: 10f64.to_radians(),
        ..start()
    };
    let dt = 0.1;
    for k in 0..200 {
        let cmd = planner.step(k as f64 * dt, dt, pose, &map, 0.0, 1.0);
        pose.position += DVec2::new(pose.heading.cos(), pose.heading.sin()) * cmd.v * dt;
        pose.heading += cmd.omega * dt;
    }
    // Left with at most the dead band's heading error: 0.04 / 1.2 rad (1.9°).
    assert!(
        pose.heading.abs() < 0.04 / 1.2 + 1e-3,
        "{}",
        pose.heading.to_degrees()
    );
}

/// Held by movers, the leader plans again where marks only narrow the way (people standing
/// round it) at most every `HELD_REPLAN_S`, not every second: in a crowd such replans
/// swung the route from one side to the other. Where marks block the way, it plans again
/// at once, held or not.
#[test]
fn held_by_movers_a_narrowed_way_is_planned_again_seldom_a_blocked_one_at_once() {
    use base_station::planner::route::RouteParams;
    use base_station::planner::HELD_REPLAN_S;
    let goal = DVec2::new(20.0, 0.0);
    // 0.9 m off the way: narrower than the wide shape needs, wide enough for a robot.
    let narrowing = Obstacle::Circle {
        center: DVec2::new(6.0, 1.0),
        radius: 0.1,
    };
    let blocking = Obstacle::Circle {
        center: DVec2::new(8.0, 0.05),
        radius: 0.1,
    };
    let replans = |held: bool, sensed: &Obstacle, for_s: f64| {
        let mut planner = Planner::routed(
            PlannerParams::DEFAULT,
            vec![goal],
            0.0,
            RouteParams::for_fleet(FOOTPRINT, 3.0, 0.4),
        );
        let empty = Map::new(Vec::new());
        planner.step(0.0, 0.1, start(), &empty, 0.0, 1.0);
        assert_eq!(planner.replans(), 0);
        let map = Map::new(vec![sensed.clone()]);
        for k in 1..=(for_s * 10.0).round() as usize {
            if k % 10 == 1 {
                // Sensed again each second, as scans renew what they see.
                planner.add_obstacles(std::slice::from_ref(sensed));
            }
            let pace = Pace {
                held,
                ..Pace::from(0.0)
            };
            planner.step(k as f64 * 0.1, 0.1, start(), &map, 0.0, pace);
        }
        planner.replans()
    };
    assert_eq!(
        replans(false, &narrowing, 1.5),
        1,
        "narrowed, moving: planned again"
    );
    assert_eq!(
        replans(true, &narrowing, 2.0),
        0,
        "narrowed, held: the route is kept"
    );
    let later = HELD_REPLAN_S + 0.5;
    assert_eq!(
        replans(true, &narrowing, later),
        1,
        "held: planned again, later"
    );
    assert_eq!(
        replans(true, &blocking, 2.0),
        1,
        "blocked, held: planned again"
    );
}
