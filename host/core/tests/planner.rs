//! The planner alone, driving an ideal unicycle at 10 Hz: each local-minimum case escapes
//! and reaches the goal without touching anything.

use base_station::geometry::Obstacle;
use base_station::map::Map;
use base_station::planner::{Mode, PlanPose, Planner, PlannerParams};
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
