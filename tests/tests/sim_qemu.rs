//! The real firmware ELF in QEMU, one per robot, lockstep with the simulator: the paper's
//! bounds, agreement with the native control core, and a crash or hang that fails the run
//! with a clear message instead of hanging it. Needs `qemu-system-arm` and the firmware
//! (`./scripts/build-firmware.sh`); `./scripts/test-all.sh` provides both.

mod common;

use std::time::Duration;

use common::{assert_paper_bounds, shipped};
use hil_sim::run::simulate;
use hil_sim::world::{Firmware, SimOptions, World};
use protocol::body::FirmwareFault;

fn qemu(seed: u64) -> SimOptions {
    let mut o = SimOptions::new(seed);
    o.firmware = Firmware::Qemu;
    o
}

/// QEMU and native runs of one scenario: both meet the bounds and the follower
/// trajectories agree within 1 mm at every sample (they are in fact identical: the same
/// f32 code, micromath everywhere, on both targets; events happen at the same simulated
/// times).
fn qemu_matches_native(name: &str) {
    let (native, nw) = simulate(shipped(name), SimOptions::new(1)).expect("native run");
    let (q, qw) = simulate(shipped(name), qemu(1)).unwrap_or_else(|e| panic!("QEMU run: {e}"));
    println!("{}", serde_json::to_string_pretty(&q).unwrap());
    assert_eq!(q.firmware, "qemu");
    assert_paper_bounds(&q);
    assert_eq!(native.transformations, q.transformations);
    let mut worst = 0.0f64;
    for (a, b) in nw.recorder.samples.iter().zip(&qw.recorder.samples) {
        for (ra, rb) in a.robots.iter().zip(&b.robots) {
            worst = worst.max((ra.x - rb.x).hypot(ra.y - rb.y));
        }
    }
    println!("{name}: largest native/QEMU position difference {worst:e} m");
    assert_eq!(nw.recorder.samples.len(), qw.recorder.samples.len());
    assert!(worst <= 1e-3, "{name}: trajectories differ by {worst} m");
    let cycles: Vec<u32> = qw
        .robots
        .iter()
        .flat_map(|r| r.brain.step_cycles())
        .collect();
    assert!(!cycles.is_empty(), "control steps were measured");
}

#[test]
fn paper_obstacles_in_qemu() {
    qemu_matches_native("paper-obstacles");
}

#[test]
fn paper_passage_in_qemu() {
    qemu_matches_native("paper-passage");
}

fn fail_one_robot(fault: FirmwareFault) -> String {
    let mut options = qemu(1);
    options.step_timeout = Duration::from_secs(2);
    let mut world = World::new(shipped("paper-passage"), options).expect("boots");
    for _ in 0..300 {
        world.step(10_000).expect("healthy for 3 s");
    }
    world.robots[1].brain.inject(fault).expect("sent");
    let started = std::time::Instant::now();
    let err = world.run().expect_err("the run must fail");
    assert!(
        started.elapsed() < Duration::from_secs(20),
        "it failed, but slowly"
    );
    err.to_string()
}

#[test]
fn a_crashing_firmware_fails_the_run_with_its_last_logs() {
    let msg = fail_one_robot(FirmwareFault::Panic);
    println!("{msg}");
    assert!(msg.contains("robot 1"), "{msg}");
    assert!(
        msg.contains("panic: panicked at"),
        "the panic message is shown: {msg}"
    );
    assert!(
        msg.contains("exit status: 101") || msg.contains("closed its UART"),
        "{msg}"
    );
}

#[test]
fn a_hanging_firmware_fails_the_run_instead_of_hanging_it() {
    let msg = fail_one_robot(FirmwareFault::Hang);
    println!("{msg}");
    assert!(msg.contains("robot 1"), "{msg}");
    assert!(msg.contains("did not answer within 2.0 s"), "{msg}");
    assert!(
        msg.contains("hanging, as the harness asked"),
        "its last log line: {msg}"
    );
}
