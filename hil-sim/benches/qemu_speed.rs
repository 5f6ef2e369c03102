//! The firmware in QEMU: wall time and real-time factor of `paper-obstacles` with all three
//! robots in QEMU, with six and with sixteen (more followers behind, a V), QEMU boot time, and
//! instructions per control step on the MCU.
//! `cargo bench -p hil-sim --bench qemu_speed` (needs qemu-system-arm and the firmware:
//! `./scripts/build-firmware.sh`). Prints a table; one run is the measurement.
//!
//! Instructions: QEMU runs with `-icount shift=5` (each instruction advances the virtual
//! clock by 2⁵ = 32 ns) and SysTick counts that clock at 25 MHz (40 ns), so one control step
//! (node tick: L-φ law + PIDs + odometry + telemetry frame) takes counts × 40 / 32
//! instructions.

use std::time::Instant;

use base_station::scenario::Scenario;
use hil_sim::world::{Firmware, SimOptions, World};

/// `paper-obstacles` with more followers behind the start (`extra`: their starts), a V.
fn more_robots(text: &str, extra: &[(f64, f64)]) -> Scenario {
    let n = 3 + extra.len();
    let mut t = text
        .replace(
            "name = \"paper-obstacles\"",
            &format!("name = \"paper-obstacles-{n}\""),
        )
        .replace("shape = \"triangle\"", "shape = \"v\"");
    for (i, (x, y)) in extra.iter().enumerate() {
        let id = 3 + i;
        t += &format!(
            "\n[[robots]]\nid = {id}\nrole = \"follower\"\nstart = {{ x = {x:.1}, y = {y:.1}, heading_deg = 45.0 }}\n"
        );
    }
    Scenario::parse(&t, "paper-obstacles-more").expect("the larger fleet parses")
}

/// Three more followers: six robots.
const SIX: [(f64, f64); 3] = [(-5.0, -2.0), (-2.0, -5.0), (-7.0, -6.0)];
/// Thirteen more, on a grid behind the start: sixteen robots.
const SIXTEEN: [(f64, f64); 13] = [
    (-6.0, -6.0),
    (-3.5, -6.0),
    (-1.0, -6.0),
    (1.5, -6.0),
    (-6.0, -3.5),
    (-3.5, -3.5),
    (-1.0, -3.5),
    (1.0, -2.0),
    (-6.0, -1.0),
    (-3.5, -1.0),
    (-1.0, -1.0),
    (-6.5, 1.5),
    (-1.5, 1.5),
];

/// Boots and runs one scenario with every robot in QEMU; prints its speed.
fn measure(scenario: Scenario) -> World {
    let (name, n) = (scenario.name.clone(), scenario.robots.len());
    let mut options = SimOptions::new(1);
    options.firmware = Firmware::Qemu;
    let boot = Instant::now();
    let mut world = World::new(scenario, options).expect("the QEMUs boot");
    let boot_s = boot.elapsed().as_secs_f64();
    let run = Instant::now();
    world.run().expect("the run completes");
    let wall = run.elapsed().as_secs_f64();
    let sim = world.t_us as f64 / 1e6;
    println!("QEMU boot of {n} robots (spawn, configure): {boot_s:.3} s");
    println!(
        "{name}, {n} robots in QEMU: {sim:.1} s simulated in {wall:.2} s wall: {:.1}x real time",
        sim / wall
    );
    world
}

fn main() {
    if !std::env::args().any(|a| a == "--bench") {
        return;
    }
    let path = format!(
        "{}/../scenarios/paper-obstacles.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(&path).unwrap();
    let world = measure(Scenario::parse(&text, &path).unwrap());
    measure(more_robots(&text, &SIX));
    measure(more_robots(&text, &SIXTEEN));
    println!(
        "{:<6} {:>8} {:>13} {:>8} {:>8} {:>16} {:>8}",
        "robot", "periods", "control step", "p99", "max", "radio rx/period", "p99"
    );
    let insns = |v: u32| v as f64 * 40.0 / 32.0;
    let at = |c: &[u32], q: f64| c[((c.len() - 1) as f64 * q) as usize];
    for r in &world.robots {
        let mut c: Vec<u32> = r.brain.step_cycles();
        let mut rx: Vec<u32> = r.brain.rx_cycles();
        c.sort_unstable();
        rx.sort_unstable();
        println!(
            "{:<6} {:>8} {:>13.0} {:>8.0} {:>8.0} {:>16.0} {:>8.0}",
            r.id,
            c.len(),
            insns(at(&c, 0.5)),
            insns(at(&c, 0.99)),
            insns(*c.last().unwrap()),
            insns(at(&rx, 0.5)),
            insns(at(&rx, 0.99)),
        );
    }
    println!("(instructions, medians unless marked)");
}
