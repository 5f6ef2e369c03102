//! How well a fix from the localization source agrees with what its robot believes: the
//! robot's own pose (odometry corrected by the fixes it took), as its latest telemetry
//! reports it, carried to the fix's instant by the wheel speeds it reports. The station
//! forwards, of the fixes that arrive for one slot, the one that agrees best
//! ([`super::fixes::FixWatch`]).

use glam::DVec2;
use protocol::messages::{faults, Telemetry};
use protocol::units;

use crate::geometry::wrap_angle;

/// What the robot believes: its telemetry and the station time its pose was valid at.
#[derive(Debug, Clone, Copy)]
pub struct Belief {
    pub telemetry: Telemetry,
    pub at_ms: u32,
    pub track_width: f64,
}

/// The position error that counts as much as one heading radian of
/// [`HEADING_SCALE`]: a fix's own σ, never less than this, m.
const POSITION_FLOOR: f64 = 0.02;
/// Heading disagreement counted as one σ, rad.
const HEADING_SCALE: f64 = 0.05;
/// Longest a telemetry pose is carried forward or back to a fix's instant, ms.
const MAX_CARRY_MS: f64 = 1000.0;
/// The robot's own gates (control-core's `RobotConfig::fix_gate` and the odometry's
/// heading gate): a fix farther than `POSITION_GATE + 3σ` or turned more than
/// `HEADING_GATE` from what the robot believes is an outlier to it.
const POSITION_GATE: f64 = 0.5;
const HEADING_GATE: f64 = 0.35;

impl Belief {
    /// The robot's pose carried to `at_ms` (station clock), `None` while it has none.
    pub fn pose_at(&self, at_ms: u32) -> Option<(DVec2, f64)> {
        let t = &self.telemetry;
        if t.faults & faults::NOT_LOCALIZED != 0 {
            return None;
        }
        let (x, y, h) = t.pose.to_si();
        let vl = units::from_milli_i16(t.wheel_mm_s[0]) as f64;
        let vr = units::from_milli_i16(t.wheel_mm_s[1]) as f64;
        let (v, omega) = (0.5 * (vl + vr), (vr - vl) / self.track_width);
        let dt = (at_ms.wrapping_sub(self.at_ms) as i32 as f64).clamp(-MAX_CARRY_MS, MAX_CARRY_MS)
            / 1000.0;
        let mid = h as f64 + 0.5 * omega * dt;
        let p = DVec2::new(x as f64, y as f64) + DVec2::new(mid.cos(), mid.sin()) * v * dt;
        Some((p, wrap_angle(h as f64 + omega * dt)))
    }

    /// The fix's disagreement with the robot at the fix's instant, in σ squared (position
    /// by the fix's σ, heading by [`HEADING_SCALE`]), and whether the robot would take it
    /// for an outlier; (0, false) while the robot has no pose.
    pub fn judge(&self, position: DVec2, heading: f64, sigma: f64, at_ms: u32) -> (f64, bool) {
        let Some((p, h)) = self.pose_at(at_ms) else {
            return (0.0, false);
        };
        let (dp, dh) = ((position - p).length(), wrap_angle(heading - h));
        let outlier = dp > POSITION_GATE + 3.0 * sigma || dh.abs() > HEADING_GATE;
        let (dp, dh) = (dp / sigma.max(POSITION_FLOOR), dh / HEADING_SCALE);
        (dp * dp + dh * dh, outlier)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::messages::WirePose;

    fn belief(x: f32, v_mm_s: i16, at_ms: u32) -> Belief {
        Belief {
            telemetry: Telemetry {
                pose: WirePose::from_si(x, 0.0, 0.0).unwrap(),
                wheel_mm_s: [v_mm_s, v_mm_s],
                ..Telemetry::default()
            },
            at_ms,
            track_width: 0.4,
        }
    }

    #[test]
    fn a_fix_where_the_robot_has_driven_to_agrees_and_one_ahead_does_not() {
        // At 1 m/s, 0.3 s after its telemetry, the robot is 0.3 m on.
        let b = belief(2.0, 1000, 1000);
        let (p, h) = b.pose_at(1300).unwrap();
        assert!((p.x - 2.3).abs() < 1e-6 && h.abs() < 1e-9);
        let on_track = b.judge(DVec2::new(2.31, 0.0), 0.0, 0.02, 1300);
        let ahead = b.judge(DVec2::new(2.75, 0.0), 0.0, 0.02, 1300);
        let far = b.judge(DVec2::new(3.0, 0.0), 0.0, 0.02, 1300);
        let turned = b.judge(DVec2::new(2.3, 0.0), 0.4, 0.02, 1300);
        assert!(on_track.0 < 1.0 && !on_track.1, "{on_track:?}");
        assert!(ahead.0 > 400.0 && !ahead.1, "{ahead:?}");
        assert!(far.1 && turned.1, "{far:?} {turned:?}");
        // A claimed σ of 0 does not make a fix more convincing than a σ of 2 cm.
        assert_eq!(b.judge(DVec2::new(2.75, 0.0), 0.0, 0.0, 1300).0, ahead.0);
    }

    #[test]
    fn a_robot_without_a_pose_takes_any_fix() {
        let mut b = belief(2.0, 0, 0);
        b.telemetry.faults = faults::NOT_LOCALIZED;
        assert_eq!(b.judge(DVec2::new(50.0, 0.0), 3.0, 0.02, 10), (0.0, false));
    }
}
