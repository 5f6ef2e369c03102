//! Speed of the simulator: wall time and real-time factor of `paper-obstacles`, of the
//! same with 20 social pedestrians walking across it (scanner, ring and tracking all see
//! them), and of formations of 10, 100 and 1,000 robots on an open map (30 s simulated
//! each).
//! `cargo bench -p hil-sim --bench sim_speed` (prints a table; not a criterion bench:
//! each scenario runs at least 3 times and for 3 s, and the table gives the median run
//! and the range). A word after `--` runs only the scenarios whose name holds it:
//! `cargo bench -p hil-sim --bench sim_speed -- 20p`.

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
    s.name = "paper-obstacles-20p".into();
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

/// Runs `s` at least [`MIN_RUNS`] times and until [`MIN_WALL_S`] have passed (on a
/// shared machine one 0.2 s run moves by a third): its name, robots, simulated time,
/// runs, and the median, least and greatest wall time of a run.
fn measure(s: Scenario) -> (String, usize, f64, usize, [f64; 3]) {
    let (name, robots) = (s.name.clone(), s.robots.len());
    let (mut walls, mut sim) = (Vec::new(), 0.0);
    while walls.len() < MIN_RUNS || walls.iter().sum::<f64>() < MIN_WALL_S {
        let start = Instant::now();
        let (report, _) = simulate(s.clone(), SimOptions::new(1)).unwrap();
        walls.push(start.elapsed().as_secs_f64());
        sim = report.sim_time_s;
    }
    walls.sort_by(f64::total_cmp);
    let median = walls[walls.len() / 2];
    let spread = [median, walls[0], walls[walls.len() - 1]];
    (name, robots, sim, walls.len(), spread)
}

const MIN_RUNS: usize = 3;
const MIN_WALL_S: f64 = 3.0;

fn main() {
    // `cargo test` runs benches with --bench absent: do nothing then.
    if !std::env::args().any(|a| a == "--bench") {
        return;
    }
    println!(
        "{:<20} {:>6} {:>8} {:>5} {:>16} {:>18} {:>11}",
        "scenario", "robots", "sim (s)", "runs", "wall (s) median", "real-time ×", "µs/robot·s"
    );
    let filter = std::env::args()
        .skip(1)
        .find(|a| !a.starts_with("--"))
        .unwrap_or_default();
    let scenarios: [fn() -> Scenario; 5] = [
        paper_obstacles,
        paper_with_pedestrians,
        || fleet(10),
        || fleet(100),
        || fleet(1000),
    ];
    let runs = scenarios
        .iter()
        .map(|make| make())
        .filter(|s| s.name.contains(&filter))
        .map(measure);
    for (name, robots, sim, n, [wall, least, most]) in runs {
        println!(
            "{name:<20} {robots:>6} {sim:>8.1} {n:>5} {wall:>16.3} {:>18} {:>11.2}",
            format!("{:.0} ({:.0}–{:.0})", sim / wall, sim / most, sim / least),
            wall * 1e6 / (robots as f64 * sim)
        );
    }
}
