//! Odometry from ticks, pose fixes blended in, outliers dropped.

mod common;

use common::Body;
use control_core::config::RobotConfig;
use control_core::controller::MotorOutput;
use control_core::odometry::{FixOutcome, Odometry, PoseFixSample};
use control_core::Pose;

const CFG: RobotConfig = RobotConfig::DEFAULT;

fn fix(pose: Pose, t: u32) -> PoseFixSample {
    PoseFixSample {
        pose,
        sigma: 0.02,
        time_ms: t,
    }
}

#[test]
fn dead_reckoning_follows_an_arc() {
    let mut body = Body::new(Pose::new(1.0, 2.0, 0.5));
    let mut odo = Odometry::new();
    odo.update(body.sensors(&CFG, None).ticks, 0, &CFG);
    assert_eq!(
        odo.apply_fix(&fix(body.pose, 0), 0, &CFG),
        FixOutcome::Initialized
    );
    let out = MotorOutput { duty: [0.3, 0.4] };
    for i in 1..=300 {
        body.advance(&out, &CFG, 0.1, 20);
        odo.update(body.sensors(&CFG, None).ticks, i * 100, &CFG);
    }
    let p = odo.pose().unwrap();
    let err = (p.x - body.pose.x).hypot(p.y - body.pose.y);
    println!("30 s of dead reckoning on an arc: {err:.4} m off");
    // ~12 m driven: quantisation and micromath's trig keep it within 0.5 %.
    assert!(err < 0.06, "{err}");
}

#[test]
fn fixes_pull_the_pose_and_outliers_are_dropped() {
    let mut odo = Odometry::new();
    odo.update([0, 0], 0, &CFG);
    odo.apply_fix(&fix(Pose::new(0.0, 0.0, 0.0), 0), 0, &CFG);
    // 10 s of fixes: the gain per fix is small (a 2 s time constant at 10 Hz).
    for i in 1..=100 {
        odo.update([0, 0], i * 100, &CFG);
        let o = odo.apply_fix(&fix(Pose::new(0.2, 0.0, 0.0), i * 100), i * 100, &CFG);
        assert_eq!(o, FixOutcome::Applied);
    }
    assert!((odo.pose().unwrap().x - 0.2).abs() < 0.01);

    // A fix one metre off is an outlier.
    odo.update([0, 0], 10100, &CFG);
    let o = odo.apply_fix(&fix(Pose::new(1.2, 0.0, 0.0), 10100), 10100, &CFG);
    assert_eq!(o, FixOutcome::Rejected);
    assert!((odo.pose().unwrap().x - 0.2).abs() < 0.01);

    // Fifty consistent ones (5 s) mean the odometry is what is wrong.
    let mut last = o;
    for i in 102..=150 {
        odo.update([0, 0], i * 100, &CFG);
        last = odo.apply_fix(&fix(Pose::new(1.2, 0.0, 0.0), i * 100), i * 100, &CFG);
    }
    assert_eq!(last, FixOutcome::Relocalized);
    assert!((odo.pose().unwrap().x - 1.2).abs() < 0.01);

    let bad = fix(Pose::new(f32::NAN, 0.0, 0.0), 15200);
    assert_eq!(odo.apply_fix(&bad, 15200, &CFG), FixOutcome::Invalid);
}

/// Issue 13: a fix with a larger σ counts for less (the gate widens with σ, the pull
/// shrinks): the same 0.3 m offset, σ 0.02 m vs 0.3 m.
#[test]
fn a_vaguer_fix_pulls_less() {
    let pull = |sigma: f32| {
        let mut odo = Odometry::new();
        odo.update([0, 0], 0, &CFG);
        odo.apply_fix(&fix(Pose::new(0.0, 0.0, 0.0), 0), 0, &CFG);
        let off = PoseFixSample {
            pose: Pose::new(0.3, 0.0, 0.0),
            sigma,
            time_ms: 100,
        };
        assert_eq!(odo.apply_fix(&off, 100, &CFG), FixOutcome::Applied);
        odo.pose().unwrap().x
    };
    let (sharp, vague) = (pull(0.02), pull(0.3));
    println!("0.3 m offset: pulled {sharp:.3} m by a 0.02 m fix, {vague:.3} m by a 0.3 m fix");
    // σ 0.02 m: (0.02 / 0.1)² = 0.04, the pull is 0.3 · fix_gain / 1.04.
    let expected = 0.3 * CFG.fix_gain / 1.04;
    assert!(
        (sharp - expected).abs() < 0.05 * expected,
        "{sharp} vs {expected}"
    );
    assert!(vague < sharp / 5.0, "{vague} vs {sharp}");
}

/// Issue 27, finding 1: a fix's heading is gated like its position (it used to be taken
/// whatever it said), and a fix claiming σ = 0 is not a fix (it used to get the tightest
/// gate and the strongest pull).
#[test]
fn a_fix_turned_away_or_claiming_no_error_is_refused() {
    let mut odo = Odometry::new();
    odo.update([0, 0], 0, &CFG);
    odo.apply_fix(&fix(Pose::new(0.0, 0.0, 0.0), 0), 0, &CFG);
    odo.update([0, 0], 100, &CFG);
    let turned = fix(Pose::new(0.0, 0.0, 0.6), 100);
    assert_eq!(odo.apply_fix(&turned, 100, &CFG), FixOutcome::Rejected);
    assert_eq!(odo.pose().unwrap().heading, 0.0);
    let slight = fix(Pose::new(0.0, 0.0, 0.05), 100);
    assert_eq!(odo.apply_fix(&slight, 100, &CFG), FixOutcome::Applied);
    let perfect = PoseFixSample {
        sigma: 0.0,
        ..fix(Pose::new(0.1, 0.0, 0.0), 100)
    };
    assert_eq!(odo.apply_fix(&perfect, 100, &CFG), FixOutcome::Invalid);
}
