//! What happened round a moment of a run: every robot and every mover within reach of
//! the robots, each sample from T0 to T1 (s). For reading a contact the report lists.
//!
//! `cargo run --release -p hil-sim --example around -- WORLD.toml SEED T0 T1`

use base_station::scenario::Scenario;
use hil_sim::run::simulate_with;
use hil_sim::world::SimOptions;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let [_, path, seed, t0, t1] = &args[..] else {
        eprintln!("usage: around WORLD.toml SEED T0 T1");
        std::process::exit(2);
    };
    let s = Scenario::load(std::path::Path::new(path)).expect("a scenario");
    let seed: u64 = seed.parse().expect("a seed");
    let (t0, t1): (f64, f64) = (t0.parse().expect("T0"), t1.parse().expect("T1"));
    let _ = simulate_with(s, SimOptions::new(seed), |w| {
        let t = w.t_us as f64 / 1e6;
        if t < t0 || t > t1 || !w.t_us.is_multiple_of(100_000) {
            return;
        }
        for r in &w.robots {
            let (v, om) = r.body.twist();
            println!(
                "{t:6.1} robot {} at ({:.2}, {:.2}) heading {:4.0}° v {:.2} ω {:.2}",
                r.id,
                r.body.x,
                r.body.y,
                r.body.heading.to_degrees(),
                v,
                om
            );
        }
        for m in &w.mover_states {
            let near = w
                .robots
                .iter()
                .any(|r| glam::DVec2::new(r.body.x, r.body.y).distance(m.position) < 3.0);
            if near {
                println!(
                    "{t:6.1}   mover {} at ({:.2}, {:.2}) v ({:.2}, {:.2})",
                    m.index, m.position.x, m.position.y, m.velocity.x, m.velocity.y
                );
            }
        }
    });
}
