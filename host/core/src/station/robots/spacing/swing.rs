//! Whether a follower's next motion swings its body clear of the robots beside it, judged
//! with the fleet's one forward model (`station::model`: the firmware's own detour law or
//! L-φ law, through its limits) from where it stands. A differential drive does not move
//! its centre along a straight line to where it is sent: it backs and swings round, and
//! a body moving otherwise than the straight line the station assumed touched another.

use control_core::controller::{DETOUR_GAIN, DETOUR_SPEED};
use control_core::follower::{self, SlotRef};
use control_core::{Pose, Twist};
use glam::DVec2;

use super::{slot_of, Body, Fleet, KEEP_M};
use crate::station::model::{Robot, STEP_S};

/// A step aside is rolled out this long, s.
const STEP_ROLLOUT_S: f32 = 3.0;
/// A standing follower's setting off is rolled out this long, s, against the robots
/// within this beyond touching distance, m.
const SET_OFF_ROLLOUT_S: f32 = 1.0;
const SET_OFF_NEAR_M: f64 = 0.2;
/// What a step aside may close on a robot within touching distance, rounding aside, m.
const STEP_SLACK_M: f64 = 0.01;

/// Whether `stepper`, standing, keeps from every other robot all the way while its control
/// point makes for `point` as its firmware drives a detour: none comes within [`KEEP_M`]
/// beyond both footprints, nor, where it is that near already, nearer than now. A
/// differential drive brings its control point aside by swinging its body round: a
/// follower stepping aside backs its flank into the one held for it, where neither ring
/// looks.
pub(super) fn steps_clear(stepper: &Body, point: DVec2, fleet: &Fleet) -> bool {
    let target = (point.x as f32, point.y as f32);
    let d = fleet.offset as f32;
    let law =
        |_: f32, pose: &Pose| Some(follower::toward(target, pose, d, DETOUR_GAIN, DETOUR_SPEED));
    swings_clear(stepper, fleet, STEP_ROLLOUT_S, |_| true, law)
}

/// Whether a standing follower setting off for its slot swings clear of the robots beside
/// it over its first [`SET_OFF_ROLLOUT_S`], driving its own L-φ law toward the slot as
/// it stands from the leader now, the leader driving on as it was last told. Its way
/// judged as a straight line to the slot, a follower let go backs and swings its flank
/// into one standing beside it.
pub(super) fn sets_off_clear(f: &Body, slots: &[(u16, DVec2)], fleet: &Fleet) -> bool {
    let (Some(leader), Some(slot)) = (fleet.leader, slot_of(slots, f.id)) else {
        return true;
    };
    let (l, phi) = follower::as_slot(&leader.pose, (slot.x as f32, slot.y as f32));
    let slot = SlotRef {
        l,
        phi,
        ..SlotRef::default()
    };
    let gains = fleet.robot.gains;
    let law =
        |t: f32, pose: &Pose| follower::lphi_law(&leader.predict(t), pose, &slot, &gains).ok();
    let near = 2.0 * fleet.footprint + KEEP_M + SET_OFF_NEAR_M;
    // What its ring sees ahead or behind is the ring's to keep from.
    let watched = |r: &Body| {
        !f.sees(1.0, r.position)
            && !f.sees(-1.0, r.position)
            && r.position.distance(f.position) <= near
    };
    swings_clear(f, fleet, SET_OFF_ROLLOUT_S, watched, law)
}

/// Whether `stepper`, standing, driving `law` (the twist it asks, at a time from now and a
/// pose) through its firmware's limits for `horizon_s`, keeps from every other robot that
/// it `watches`: none comes within [`KEEP_M`] beyond both footprints, nor, where it is
/// that near already, nearer than now.
fn swings_clear(
    stepper: &Body,
    fleet: &Fleet,
    horizon_s: f32,
    watches: impl Fn(&Body) -> bool,
    law: impl Fn(f32, &Pose) -> Option<Twist>,
) -> bool {
    let reach = 2.0 * fleet.footprint + KEEP_M;
    let least: Vec<(DVec2, f64)> = fleet
        .robots
        .iter()
        .filter(|r| r.id != stepper.id && watches(r))
        .map(|r| (r.position, r.position.distance(stepper.position).min(reach)))
        .collect();
    let mut robot = Robot::new(stepper.position, stepper.heading, 0.0);
    let dt = STEP_S as f32;
    for k in 0..(horizon_s / dt) as usize {
        let Some(asked) = law(k as f32 * dt, &robot.pose) else {
            return true;
        };
        robot.drive(&fleet.robot, asked, dt);
        let centre = robot.position();
        if least
            .iter()
            .any(|(p, least)| centre.distance(*p) < least - STEP_SLACK_M)
        {
            return false;
        }
    }
    true
}
