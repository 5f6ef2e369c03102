use base_station::scenario::Scenario;
use hil_sim::world::{SimOptions, World};
fn main() {
    let text = std::fs::read_to_string("scenarios/paper-obstacles.toml").unwrap();
    let s = Scenario::parse(&text, "p").unwrap();
    let mut w = World::new(s, SimOptions::new(1)).unwrap();
    w.run().unwrap();
    let mut by: std::collections::BTreeMap<(usize, usize), usize> = Default::default();
    for (_, from, bytes) in &w.transmitted {
        for f in bytes.split_inclusive(|b| *b == 0) {
            *by.entry((*from, f.len())).or_default() += 1;
        }
    }
    for ((from, len), n) in by {
        println!("node {from} len {len}: {n}");
    }
}
