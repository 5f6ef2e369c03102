//! Speed of the simulator: wall time and real-time factor of `paper-obstacles`, of the
//! same with 20 social pedestrians walking across it (scanner, ring and tracking all see
//! them), and of formations of 10, 100 and 1,000 robots on an open map (30 s simulated
//! each).
//! `cargo bench -p hil-sim --bench sim_speed` (prints a table; not a criterion bench:
//! one run of a 1,000-robot fleet is the measurement).

use std::time::Instant;

use base_station::scenario::movers::{Behavior, CrowdSpec};
use base_station::scenario::{
    BoundsSpec, RobotEntry, Role, Scenario, ShapeName, SlotSpec, StartPose,
};
use hil_sim::run::simulate;
use hil_sim::world::SimOptions;

fn paper_obstacles() -> Scenario {
    let path = format!(
        "{}/../scenarios/paper-obstacles.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    Scenario::load(std::path::Path::new(&path)).unwrap()
}

/// `paper-obstacles` with 20 social pedestrians walking between random points of the
/// 20 m × 20 m the formation crosses.
fn paper_with_pedestrians() -> Scenario {
    let mut s = paper_obstacles();
    s.name = "paper-obstacles+20p".into();
    s.crowds.push(CrowdSpec {
        area: BoundsSpec {
            min: [0.0, 0.0],
            max: [20.0, 20.0],
        },
        density: 0.05,
        speed_mean: 1.3,
        speed_sd: 0.25,
        seed: 1,
        behavior: Behavior::Social,
        start_s: 0.0,
    });
    s.validate().expect("valid crowd scenario");
    assert_eq!(s.crowds[0].persons(), 20);
    s
}

/// A leader and `n − 1` followers in a grid behind it (rows of 10, 2 m apart), open map.
fn fleet(n: usize) -> Scenario {
    let mut s = paper_obstacles();
    s.name = format!("open-{n}");
    s.map.obstacles.clear();
    s.map.bounds = None;
    s.route.goal = Some([400.0, 0.0]);
    s.sim.duration_s = 30.0;
    s.formation.shape = ShapeName::Custom;
    s.formation.slots.clear();
    s.robots.clear();
    s.robots.push(RobotEntry {
        id: 0,
        role: Role::Leader,
        start: StartPose {
            x: 0.0,
            y: 0.0,
            heading_deg: 0.0,
        },
        initial_speed: 0.0,
    });
    for k in 0..n - 1 {
        let (row, col) = ((k / 10 + 1) as f64, (k % 10) as f64 - 4.5);
        let (x, y) = (-2.0 * row, 2.0 * col);
        s.formation.slots.push(SlotSpec {
            distance: x.hypot(y),
            angle_deg: y.atan2(x).to_degrees(),
        });
        s.robots.push(RobotEntry {
            id: k as u16 + 1,
            role: Role::Follower,
            start: StartPose {
                x: x - 0.2,
                y,
                heading_deg: 0.0,
            },
            initial_speed: 0.0,
        });
    }
    s.validate().expect("valid fleet scenario");
    s
}

fn measure(s: Scenario) -> (String, usize, f64, f64) {
    let name = s.name.clone();
    let robots = s.robots.len();
    let start = Instant::now();
    let (report, _) = simulate(s, SimOptions::new(1)).unwrap();
    let wall = start.elapsed().as_secs_f64();
    (name, robots, report.sim_time_s, wall)
}

fn main() {
    // `cargo test` runs benches with --bench absent: do nothing then.
    if !std::env::args().any(|a| a == "--bench") {
        return;
    }
    println!(
        "{:<18} {:>7} {:>10} {:>10} {:>12} {:>14}",
        "scenario", "robots", "sim (s)", "wall (s)", "real-time ×", "µs/robot·s"
    );
    let runs = [
        measure(paper_obstacles()),
        measure(paper_with_pedestrians()),
        measure(fleet(10)),
        measure(fleet(100)),
        measure(fleet(1000)),
    ];
    for (name, robots, sim, wall) in runs {
        println!(
            "{name:<18} {robots:>7} {sim:>10.1} {wall:>10.3} {:>12.0} {:>14.2}",
            sim / wall,
            wall * 1e6 / (robots as f64 * sim)
        );
    }
}
