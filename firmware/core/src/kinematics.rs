//! Differential drive: v = (v_L + v_R)/2, ω = (v_R − v_L)/b.

use crate::math;
use crate::Twist;

/// Left and right wheel rim speeds, m/s.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WheelSpeeds {
    pub left: f32,
    pub right: f32,
}

/// A differential-drive base.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DiffDrive {
    /// Track width b: distance between the wheels' contact points, m.
    pub track_width: f32,
    /// Wheel radius r, m.
    pub wheel_radius: f32,
    /// Largest rim speed a wheel can hold, m/s.
    pub max_wheel_speed: f32,
}

impl DiffDrive {
    pub fn wheels(&self, t: Twist) -> WheelSpeeds {
        let half = 0.5 * self.track_width * t.omega;
        WheelSpeeds {
            left: t.v - half,
            right: t.v + half,
        }
    }

    pub fn twist(&self, w: WheelSpeeds) -> Twist {
        Twist {
            v: 0.5 * (w.left + w.right),
            omega: (w.right - w.left) / self.track_width,
        }
    }

    /// Scales both wheels by one factor so that neither exceeds the limit.
    ///
    /// This keeps the curvature ω/v: the robot slows down but stays on the arc the
    /// controller chose (the arc that avoids an obstacle, or closes on the slot). Keeping
    /// ω instead would trade forward speed for turning and bend the path.
    pub fn limit(&self, w: WheelSpeeds) -> WheelSpeeds {
        let peak = math::abs(w.left).max(math::abs(w.right));
        if peak <= self.max_wheel_speed {
            return w;
        }
        let k = self.max_wheel_speed / peak;
        WheelSpeeds {
            left: w.left * k,
            right: w.right * k,
        }
    }

    /// Wheel angular speed (rad/s) for a rim speed.
    pub fn wheel_rate(&self, rim_speed: f32) -> f32 {
        rim_speed / self.wheel_radius
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DRIVE: DiffDrive = DiffDrive {
        track_width: 0.5,
        wheel_radius: 0.1,
        max_wheel_speed: 1.0,
    };

    #[test]
    fn round_trip() {
        let t = Twist::new(0.4, 0.6);
        let back = DRIVE.twist(DRIVE.wheels(t));
        assert!((back.v - t.v).abs() < 1e-6 && (back.omega - t.omega).abs() < 1e-6);
        let w = DRIVE.wheels(t);
        assert!((w.left - 0.25).abs() < 1e-6 && (w.right - 0.55).abs() < 1e-6);
    }

    #[test]
    fn limit_keeps_curvature() {
        let t = Twist::new(1.5, 2.0);
        let w = DRIVE.limit(DRIVE.wheels(t));
        assert!((w.right - 1.0).abs() < 1e-6);
        let out = DRIVE.twist(w);
        assert!((out.omega / out.v - t.omega / t.v).abs() < 1e-5);
    }
}
