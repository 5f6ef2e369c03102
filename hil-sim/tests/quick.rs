use hil_sim::run::simulate;
use hil_sim::world::SimOptions;

#[test]
fn quick() {
    for name in ["paper-obstacles", "paper-passage"] {
        let path = format!("{}/../scenarios/{name}.toml", env!("CARGO_MANIFEST_DIR"));
        let s = base_station::scenario::Scenario::load(std::path::Path::new(&path)).unwrap();
        let (report, world) = simulate(s, SimOptions::new(1)).unwrap();
        hil_sim::plot::write_svg(
            &world,
            &report,
            std::path::Path::new(&format!("/tmp/{name}.svg")),
        )
        .unwrap();
        println!("{}", serde_json::to_string_pretty(&report).unwrap());
    }
}

#[test]
fn stable_debug() {
    let path = format!(
        "{}/../scenarios/paper-passage.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let s = base_station::scenario::Scenario::load(std::path::Path::new(&path)).unwrap();
    let (_, world) = simulate(s, SimOptions::new(1)).unwrap();
    let n = world
        .recorder
        .samples
        .iter()
        .filter(|s| !s.near_obstacle)
        .count();
    println!("not near: {n} of {}", world.recorder.samples.len());
    println!(
        "{:?}",
        world
            .recorder
            .samples
            .iter()
            .take(3)
            .map(|s| (s.t, s.near_obstacle))
            .collect::<Vec<_>>()
    );
}
