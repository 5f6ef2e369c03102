//! The station's tracker on generated crowds, alone (`hil_sim::tracking_bench`): a
//! scanner carried across the plaza at the leader's pace through social crowds of 0.1,
//! 0.2 and 0.3 persons/m². What yielding relies on is where a track says a person will
//! be a second on: up to 0.2 persons/m² it must be nearer the truth than where the track
//! is now by a tenth (a track whose velocity says nothing would be as good standing
//! still; before 2026-12-04 at 0.2 it was: 1.05 m against 1.05 m).
//!
//! `MOVER_SEEDS=N` runs N seeds per density (default 2), from `MOVER_FIRST_SEED`.

mod common;

use base_station::scenario::Scenario;
use common::generate::movers as gen;
use hil_sim::tracking_bench::{self, TrackingFigures};

fn seeds() -> std::ops::RangeInclusive<u64> {
    common::generate::seeds("MOVER_FIRST_SEED", "MOVER_SEEDS", 2)
}

/// The plaza's crossing takes about a minute at the bench's pace.
const DURATION_S: f64 = 60.0;

fn figures(density: f64) -> Vec<(String, TrackingFigures)> {
    seeds()
        .map(|seed| {
            let g = gen::plaza_crowd(seed, density, true);
            let scenario = Scenario::parse(&g.toml, &g.name).expect("a generated world parses");
            (
                g.name.clone(),
                tracking_bench::run(&scenario, seed, DURATION_S),
            )
        })
        .collect()
}

#[test]
fn tracks_predict_people_in_crowds_better_than_standing_still() {
    for density in [0.1, 0.2, 0.3] {
        let runs = figures(density);
        for (name, f) in &runs {
            println!(
                "{name:<28} samples {:>6} detected {:.2} position {:.2} m velocity {:.2} m/s \
                 a second on: predicted {:.2} m standing {:.2} m",
                f.samples,
                f.detected_fraction,
                f.position_error_m,
                f.velocity_error_mps,
                f.predicted_error_m,
                f.standing_error_m
            );
        }
        let mean = |g: fn(&TrackingFigures) -> f64| {
            runs.iter().map(|(_, f)| g(f)).sum::<f64>() / runs.len() as f64
        };
        let (predicted, standing) = (mean(|f| f.predicted_error_m), mean(|f| f.standing_error_m));
        println!("density {density}: predicted {predicted:.2} m, standing {standing:.2} m");
        assert!(
            runs.iter().all(|(_, f)| f.samples > 1000),
            "too few samples"
        );
        // At 0.3 persons/m² the tracks are not there yet (0.94 m against 0.99 m on seeds
        // 301-316): printed, not bound.
        assert!(
            density > 0.25 || predicted < 0.9 * standing,
            "{density} persons/m²: a second on, the tracks are {predicted:.2} m off, \
             standing still {standing:.2} m"
        );
    }
}
