//! What recording costs: the wall time of a simulation recorded as `basestation sim`
//! records (the MCAP written on its own thread while the simulation runs) against the
//! same simulation unrecorded, the wall time of writing the MCAP after the run (the
//! writer's own work), and the file's size, for `paper-obstacles` and an hour of sweeping
//! an empty lot. `cargo bench -p hil-sim --bench recording` (prints a table: 21 pairs for
//! the paper run, 9 for the hour, each a plain simulation and a recorded one back to back;
//! the cost is the median of the pairs' ratios, shown with the lowest and highest).

use std::time::Instant;

use base_station::scenario::Scenario;
use hil_sim::recording::Recording;
use hil_sim::run::{simulate, simulate_with};
use hil_sim::world::SimOptions;

fn paper_obstacles() -> Scenario {
    let path = format!(
        "{}/../scenarios/paper-obstacles.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    Scenario::load(std::path::Path::new(&path)).unwrap()
}

/// The paper's fleet sweeping a 120 × 40 m lot back and forth for a simulated hour.
fn an_hour_on_a_lot() -> Scenario {
    let mut s = paper_obstacles();
    s.name = "an-hour-on-a-lot".into();
    s.map.obstacles.clear();
    s.map.bounds = None;
    s.robots[0].start.x = 5.0;
    s.robots[0].start.y = 5.0;
    s.robots[1].start.x = 2.2;
    s.robots[1].start.y = 6.5;
    s.robots[2].start.x = 2.2;
    s.robots[2].start.y = 3.5;
    s.route.waypoints = (0..14)
        .flat_map(|i| {
            let y = 5.0 + (i % 7) as f64 * 5.0;
            let (a, b) = if i % 2 == 0 {
                (5.0, 115.0)
            } else {
                (115.0, 5.0)
            };
            [[a, y], [b, y]]
        })
        .skip(1)
        .collect();
    s.route.goal = s.route.waypoints.pop();
    s.sim.duration_s = 3600.0;
    s
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn range(v: &[f64]) -> (f64, f64) {
    v.iter()
        .fold((f64::MAX, f64::MIN), |(lo, hi), &x| (lo.min(x), hi.max(x)))
}

/// Wall time of `f`, s.
fn timed(f: impl FnOnce()) -> f64 {
    let t = Instant::now();
    f();
    t.elapsed().as_secs_f64()
}

fn main() {
    println!("| run | simulated | pairs | simulate (wall, median) | simulate, recording as `sim` does (wall, median) | recording's cost (median of pairs; lowest–highest) | writing after the run (wall, median) | MCAP size |");
    println!("| --- | --- | --- | --- | --- | --- | --- | --- |");
    let dir = std::env::temp_dir();
    // Pairs run back to back, so the machine's drift (other work, clocks) hits both sides
    // of a pair alike; the cost is the median of the pairs' ratios.
    for (scenario, pairs) in [(paper_obstacles(), 21), (an_hour_on_a_lot(), 9)] {
        let path = dir.join(format!("{}-bench.mcap", scenario.name));
        let (mut sims, mut recorded, mut costs, mut writes, mut sim_s) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new(), 0.0);
        for pair in 0..pairs {
            let mut plain = None;
            let sim =
                timed(|| plain = Some(simulate(scenario.clone(), SimOptions::new(1)).unwrap()));
            let (report, world) = plain.unwrap();
            sim_s = report.sim_time_s;

            // As `basestation sim` records: handed over every `FEED_EVERY_US` of simulated
            // time, written on the writer's thread while the simulation goes on. Into a new
            // file: truncating the last one (24 MB) took 10 ms.
            let _ = std::fs::remove_file(&path);
            let mut recorded_run = None;
            let streamed = timed(|| {
                let mut recording = None;
                let (report, world) =
                    simulate_with(
                        scenario.clone(),
                        SimOptions::new(1),
                        |w| match &mut recording {
                            None => recording = Some(Recording::create(w, &path).unwrap()),
                            Some(r) if w.t_us.is_multiple_of(Recording::FEED_EVERY_US) => r.feed(w),
                            Some(_) => {}
                        },
                    )
                    .unwrap();
                recording.unwrap().finish(&world, &report).unwrap();
                // Dropped outside the timing, as the plain run's world is.
                recorded_run = Some(world);
            });
            drop(recorded_run);
            sims.push(sim);
            recorded.push(streamed);
            costs.push(streamed / sim - 1.0);

            if pair % 3 == 0 {
                writes.push(timed(|| {
                    hil_sim::recording::write_mcap(&world, &report, &path).unwrap();
                }));
            }
        }
        let size = std::fs::metadata(&path).unwrap().len();
        let (lo, hi) = range(&costs);
        let (sim, write) = (median(sims), median(writes));
        println!(
            "| {} | {sim_s:.0} s | {pairs} | {:.0} ms | {:.0} ms | {:+.0} % ({:+.0} … {:+.0} %) | {:.0} ms ({:.0} %) | {:.1} MB |",
            scenario.name,
            sim * 1e3,
            median(recorded) * 1e3,
            median(costs) * 100.0,
            lo * 100.0,
            hi * 100.0,
            write * 1e3,
            write / sim * 100.0,
            size as f64 / 1e6
        );
    }
}
