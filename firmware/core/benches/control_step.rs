//! One control step on the host: odometry + L-φ law + two wheel PIDs (+ a pose fix).
//! `cargo bench -p control-core --bench control_step`. The MCU figure comes with the
//! firmware (instructions per step under QEMU).

use std::hint::black_box;

use control_core::config::{RobotConfig, Role};
use control_core::controller::{Controller, Sensors};
use control_core::follower::{LeaderSnapshot, Slots};
use control_core::odometry::PoseFixSample;
use control_core::Pose;
use criterion::{criterion_group, criterion_main, Criterion};

fn bench(c: &mut Criterion) {
    let mut ctl = Controller::new(RobotConfig::DEFAULT, Role::Follower);
    ctl.set_slots(Slots {
        wide: (3.0, 2.618),
        line: (1.5, std::f32::consts::PI),
    })
    .unwrap();
    let fix = |t| PoseFixSample {
        pose: Pose::new(-2.6, 1.5, 0.0),
        sigma: 0.02,
        time_ms: t,
    };
    ctl.step(
        0,
        &Sensors {
            ticks: [0, 0],
            pose_fix: Some(fix(0)),
            proximity: [None, None],
        },
    );
    let mut t = 0u32;
    let mut ticks = [0i32; 2];
    c.bench_function("control_step/follower", |b| {
        b.iter(|| {
            t += 100;
            ticks[0] += 700;
            ticks[1] += 705;
            let leader = LeaderSnapshot {
                pose: Pose::new(t as f32 * 4e-4, 0.0, 0.0),
                v: 0.4,
                omega: 0.0,
            };
            ctl.set_leader_state(leader, t - 50, 0.0, t).unwrap();
            let sensors = Sensors {
                ticks,
                pose_fix: Some(fix(t - 30)),
                proximity: [None, None],
            };
            black_box(ctl.step(t, &sensors))
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
