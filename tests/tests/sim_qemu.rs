//! The real firmware ELF in QEMU, one per robot, lockstep with the simulator: the paper's
//! bounds, runs identical to the native control core's (under CPU load, on a lossy link,
//! with faults, with six robots, on generated maps of every kind), and a crash or hang that fails the run with a clear
//! message instead of hanging it. Needs `qemu-system-arm` and the firmware
//! (`./scripts/build-firmware.sh`); `./scripts/test-all.sh` provides both.

mod common;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use base_station::scenario::{FaultKind, FaultSpec, Scenario};
use common::{assert_paper_bounds, generate, shipped};
use hil_sim::report::Report;
use hil_sim::run::simulate;
use hil_sim::trace::write_csv;
use hil_sim::world::{Firmware, SimOptions, World};
use protocol::body::FirmwareFault;

fn qemu(seed: u64) -> SimOptions {
    let mut o = SimOptions::new(seed);
    o.firmware = Firmware::Qemu;
    o
}

/// Busy threads beside a run, until dropped: a CI machine is never quiet.
struct CpuHogs {
    stop: Arc<AtomicBool>,
    threads: Vec<std::thread::JoinHandle<()>>,
}

impl CpuHogs {
    fn start(n: usize) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let threads = (0..n)
            .map(|_| {
                let stop = stop.clone();
                std::thread::spawn(move || {
                    let mut x = 0u64;
                    while !stop.load(Ordering::Relaxed) {
                        x = std::hint::black_box(
                            x.wrapping_mul(6364136223846793005).wrapping_add(1),
                        );
                    }
                })
            })
            .collect();
        Self { stop, threads }
    }
}

impl Drop for CpuHogs {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// Everything a run produced that must not depend on the brain: the report without the
/// wall time and the brain's name, and the trace (every robot at every sample, as CSV).
fn outcome(report: &Report, world: &World) -> (serde_json::Value, String) {
    let mut json = serde_json::to_value(report).expect("reports serialize");
    let fields = json.as_object_mut().expect("an object");
    fields.remove("wall_time_s");
    fields.remove("firmware");
    let roles: Vec<_> = world.robots.iter().map(|r| (r.id, r.role)).collect();
    let mut csv = Vec::new();
    write_csv(&world.recorder, &roles, &mut csv).expect("trace");
    (json, String::from_utf8(csv).expect("utf-8"))
}

/// The QEMU run of `scenario` is identical to the native one: every report field but the
/// wall time, every trajectory sample, bit for bit. Returns the QEMU report.
fn assert_identical(scenario: Scenario, seed: u64) -> Report {
    let name = scenario.name.clone();
    let (native, nw) = simulate(scenario.clone(), SimOptions::new(seed)).expect("native run");
    let (q, qw) =
        simulate(scenario, qemu(seed)).unwrap_or_else(|e| panic!("{name}: QEMU run: {e}"));
    assert_eq!(q.firmware, "qemu");
    let (n_json, n_trace) = outcome(&native, &nw);
    let (q_json, q_trace) = outcome(&q, &qw);
    if let Some((i, (a, b))) = n_trace
        .lines()
        .zip(q_trace.lines())
        .enumerate()
        .find(|(_, (a, b))| a != b)
    {
        panic!(
            "{name}, seed {seed}: traces differ first at line {}:\n native {a}\n qemu   {b}",
            i + 1
        );
    }
    assert_eq!(n_trace.len(), q_trace.len(), "{name}: trace lengths");
    assert_eq!(n_json, q_json, "{name}, seed {seed}: reports differ");
    let cycles: Vec<u32> = qw
        .robots
        .iter()
        .flat_map(|r| r.brain.step_cycles())
        .collect();
    assert!(!cycles.is_empty(), "control steps were measured");
    q
}

/// Both paper scenarios: the bounds, and the QEMU run identical to the native one (the
/// same f32 code, micromath everywhere, on both targets; the lockstep link makes every
/// event happen at the same simulated time).
#[test]
fn paper_obstacles_in_qemu() {
    assert_paper_bounds(&assert_identical(shipped("paper-obstacles"), 1));
}

/// Median SysTick counts of `cycles` as instructions (`-icount shift=5`: 32 ns per
/// instruction; SysTick at 25 MHz, 40 ns).
fn median_instructions(mut cycles: Vec<u32>) -> f64 {
    assert!(!cycles.is_empty(), "measured");
    cycles.sort_unstable();
    cycles[cycles.len() / 2] as f64 * 40.0 / 32.0
}

/// The firmware's cost per period, counted in instructions (which no machine load
/// changes): a fall in the QEMU runs' speed shows here first. Today (opt-level "s",
/// BLAKE2s unrolled): a follower's step 9,170, its leader-state frame 5,698, the
/// leader's step 7,566 and its two frames 10,725 (docs/sim.md#the-firmware-in-qemu);
/// bounds 20 % above.
#[test]
fn the_firmware_keeps_its_instruction_budget() {
    let (_, world) = simulate(shipped("paper-obstacles"), qemu(1)).expect("QEMU run");
    for r in &world.robots {
        let step = median_instructions(r.brain.step_cycles());
        let rx = median_instructions(r.brain.rx_cycles());
        let (step_max, rx_max) = match r.role {
            base_station::scenario::Role::Leader => (9_100.0, 12_900.0),
            base_station::scenario::Role::Follower => (11_000.0, 6_840.0),
        };
        assert!(
            step <= step_max && rx <= rx_max,
            "robot {}: a control step takes {step:.0} instructions (at most {step_max}), \
             receiving a period's frames {rx:.0} (at most {rx_max})",
            r.id
        );
    }
}

#[test]
fn paper_passage_in_qemu() {
    assert_paper_bounds(&assert_identical(shipped("paper-passage"), 1));
}

/// Nothing in the lockstep depends on the wall clock: with busy threads on every core,
/// `QEMU_LOAD_RUNS` (default 20) consecutive runs are each identical to the native run.
#[test]
fn identical_to_native_under_cpu_load() {
    let runs: u64 = std::env::var("QEMU_LOAD_RUNS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(20);
    let _hogs = CpuHogs::start(4);
    let bar = common::progress("QEMU runs under load", runs);
    for run in 0..runs {
        let started = std::time::Instant::now();
        assert_identical(shipped("paper-obstacles"), 1 + run % 3);
        bar.suspend(|| {
            println!(
                "run {run}: identical ({:.1} s)",
                started.elapsed().as_secs_f64()
            )
        });
        bar.inc(1);
    }
    bar.finish_and_clear();
}

/// 20 % loss, 150 ms latency, ±50 ms jitter: frames cross and arrive late, still
/// identical.
#[test]
fn identical_to_native_on_a_lossy_jittery_link() {
    let mut s = shipped("paper-obstacles");
    s.link.loss = 0.2;
    s.link.latency_ms = 150.0;
    s.link.jitter_ms = 50.0;
    let r = assert_identical(s, 1);
    assert!(r.link.frames_rejected > 0 || r.link.frames_delivered < r.link.frames_sent);
}

/// Reboots (a new QEMU mid-run), a base-station restart, a loss burst, corruption and a
/// replaying attacker: identical, rejects by reason included.
#[test]
fn identical_to_native_with_faults_injected() {
    let mut s = shipped("paper-passage");
    let fault = |at_s, kind, duration_s, robot, value| FaultSpec {
        at_s,
        kind,
        duration_s,
        robot,
        value,
    };
    s.faults = vec![
        fault(8.0, FaultKind::Reboot, None, Some(1), None),
        fault(15.0, FaultKind::LossBurst, Some(1.5), None, None),
        fault(20.0, FaultKind::Corruption, Some(5.0), None, Some(0.002)),
        fault(22.0, FaultKind::ReplayAttacker, Some(10.0), None, Some(2.0)),
        fault(30.0, FaultKind::BaseRestart, None, None, None),
    ];
    let r = assert_identical(s, 3);
    println!("{:?}", r.link);
    assert!(
        r.link.rejects_by_reason.len() >= 2,
        "faults produced rejects of several kinds"
    );
}

/// Six robots (a V of five followers) across a generated bin field.
#[test]
fn identical_to_native_with_six_robots() {
    let g = generate::bin_field(2, 40, 5);
    let s = Scenario::parse(&g.toml, &g.name).expect("generated scenarios parse");
    assert_eq!(s.robots.len(), 6);
    assert_identical(s, 2);
}

/// The map on which the station sends a follower round a bin that holds it (a `Detour`):
/// the firmware makes for the point and back to its slot as the native core does.
#[test]
fn identical_to_native_going_round_a_bin() {
    let g = generate::bin_field(110, 45, 5);
    let s = Scenario::parse(&g.toml, &g.name).expect("generated scenarios parse");
    let r = assert_identical(s, 10);
    let detours = r.events_named("follower_detour").count();
    assert!(detours > 0, "{}: no detour", g.name);
}

/// Among movers: the shipped street crossing (people and a cyclist crossing, the ring's
/// closing-speed rule, tracks, yielding and the crowd line all at work), and an oblivious
/// walker standing in the way, identical in QEMU.
#[test]
fn identical_to_native_among_movers() {
    let r = assert_identical(shipped("street-crossing"), 1);
    assert!(r.movers.count > 0 && r.goal_reached);
    let g = generate::movers::standing_person(3, false);
    let s = Scenario::parse(&g.toml, &g.name).expect("generated scenarios parse");
    assert!(assert_identical(s, 3).movers.count > 0);
}

/// One generated map of each other kind the suite runs: a street with pinches and bends
/// (shape changes), a 1.3 m alley (the ultrasonic ring at work), scattered starts
/// (joining from 8–15 m), an unmapped barrier (the leader's scanner, replanning, a U-turn).
#[test]
fn identical_to_native_on_generated_maps() {
    for g in [
        generate::street(1, 2),
        generate::alley(1, 1.3),
        generate::scattered_starts(1),
        generate::unmapped_in_the_way(1),
    ] {
        let s = Scenario::parse(&g.toml, &g.name).expect("generated scenarios parse");
        let r = assert_identical(s, 1);
        println!("{}: identical, goal {:?}", g.name, r.time_to_goal_s);
    }
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
    // The panic handler logs "panic" only (its message and location cost ~7 KiB of flash).
    assert!(msg.contains("ERROR panic"), "the panic is logged: {msg}");
    assert!(msg.contains("exit status: 101"), "{msg}");
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

/// A sweep: an open yard swept back and forth (the passes, the U-turns, the touch-up
/// watch), identical in QEMU, coverage included.
#[test]
fn identical_to_native_on_a_sweep() {
    let g = generate::sweeps::open_yard(3);
    let s = Scenario::parse(&g.toml, &g.name).expect("generated scenarios parse");
    let r = assert_identical(s, 3);
    let c = r.coverage.expect("a sweep reports its coverage");
    println!(
        "{}: identical, {:.1} % swept",
        g.name,
        100.0 * c.swept.swept_fraction
    );
    assert!(r.goal_reached);
}

/// Seven followers sharing one 64 kbps channel on the station's schedule, reporting every
/// few periods as the station tells them: identical in QEMU, the channel's figures too.
#[test]
fn identical_to_native_on_a_shared_channel() {
    let g = generate::open_lot(2, 7);
    let mut s = Scenario::parse(&g.toml, &g.name).expect("generated scenarios parse");
    s.link.radio = Some("sik-64k".into());
    s.link.access = base_station::scenario::radio::Access::Scheduled;
    let r = assert_identical(s, 2);
    let c = &r.link.channel;
    println!(
        "{}: identical, {:.0} % of the air, {} collisions",
        g.name,
        100.0 * c.utilisation,
        c.collisions
    );
    assert_eq!(c.collisions, 0);
    assert!(r.goal_reached);
}
