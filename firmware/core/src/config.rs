//! Everything a robot needs to know about itself. One image serves every robot: the
//! values come from the robot's configuration (flash page, scenario file), not the code.

use crate::kinematics::DiffDrive;
use crate::pid::PidGains;

/// What a robot does in the formation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Role {
    /// Drives the base station's velocity commands.
    Leader,
    /// Holds a slot relative to the leader with the L-φ law.
    Follower,
}

/// Speed limits of a robot's reference point.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Limits {
    /// Forward speed, m/s.
    pub max_v: f32,
    /// Reverse speed, m/s (positive number).
    pub max_reverse: f32,
    /// Turn rate, rad/s.
    pub max_omega: f32,
    /// Speed change in normal driving, m/s².
    pub max_accel: f32,
    /// Deceleration when stopping for a fault, m/s².
    pub brake_decel: f32,
}

/// The L-φ law's gains.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FollowerGains {
    /// Distance gain k1, 1/s.
    pub k1: f32,
    /// Bearing gain k2, 1/s.
    pub k2: f32,
    /// Control point offset d ahead of the wheel axle, m (> 0).
    pub d: f32,
}

/// Staleness limits, milliseconds.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Timeouts {
    /// A follower whose newest leader state is older than this brakes to a stop.
    pub leader_state_ms: u32,
    /// A leader whose newest velocity command is older than this brakes to a stop.
    pub command_ms: u32,
    /// No pose fix for this long sets `POSE_FIX_STALE` (odometry goes on alone).
    pub pose_fix_ms: u32,
    /// Leader states are predicted forward at most this far.
    pub max_prediction_ms: u32,
}

#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RobotConfig {
    pub drive: DiffDrive,
    /// Encoder ticks per wheel revolution (after quadrature decoding).
    pub ticks_per_rev: u32,
    pub limits: Limits,
    pub gains: FollowerGains,
    pub pid: PidGains,
    pub timeouts: Timeouts,
    /// Control period, ms (the paper's 10 Hz: 100).
    pub period_ms: u32,
    /// Tracking error under which a joining follower counts as in formation, m.
    pub in_formation_below: f32,
    /// Tracking error over which a follower in formation counts as joining again, m.
    pub joining_above: f32,
    /// Pose-fix blending gain per fix, 0..1 (complementary filter), for a perfect fix; a
    /// fix with σ counts `1 / (1 + (σ / 0.1 m)²)` of it.
    pub fix_gain: f32,
    /// A fix farther than this from the odometry (plus 3σ) is an outlier, m.
    pub fix_gate: f32,
    /// The proximity layer stops the robot this far from what its sensors see, m.
    pub proximity_stop: f32,
    /// The deceleration the proximity layer plans to stop with, m/s²: toward an obstacle
    /// the speed is at most √(2·proximity_decel·(free − proximity_stop)).
    pub proximity_decel: f32,
}

impl RobotConfig {
    /// The sanitation robot of the shipped scenarios.
    pub const DEFAULT: RobotConfig = RobotConfig {
        drive: DiffDrive {
            track_width: 0.4,
            wheel_radius: 0.08,
            max_wheel_speed: 1.1,
        },
        ticks_per_rev: 2048,
        limits: Limits {
            max_v: 1.0,
            max_reverse: 0.3,
            max_omega: 1.5,
            max_accel: 1.0,
            brake_decel: 1.0,
        },
        gains: FollowerGains {
            k1: 0.5,
            k2: 0.3,
            d: 0.2,
        },
        pid: PidGains {
            kp: 0.3,
            ki: 1.0,
            kd: 0.0,
            kff: 1.0 / 1.2,
            limit: 1.0,
        },
        timeouts: Timeouts {
            leader_state_ms: 500,
            command_ms: 500,
            pose_fix_ms: 1000,
            max_prediction_ms: 500,
        },
        period_ms: 100,
        in_formation_below: 0.10,
        joining_above: 0.30,
        fix_gain: 0.05,
        fix_gate: 0.5,
        proximity_stop: 0.15,
        proximity_decel: 0.5,
    };

    pub fn period_s(&self) -> f32 {
        self.period_ms as f32 / 1000.0
    }

    /// Metres of travel per encoder tick.
    pub fn metres_per_tick(&self) -> f32 {
        crate::math::TAU * self.drive.wheel_radius / self.ticks_per_rev as f32
    }

    /// How far a robot can travel after the last fresh leader state (or command) before
    /// it stands still: it keeps tracking until the timeout is noticed (≤ timeout + one
    /// period), then brakes from at most `max_v`, plus one more period for the wheels'
    /// lag. A bound, not an estimate.
    pub fn stop_distance_bound(&self) -> f32 {
        let v = self.limits.max_v;
        let t = (self.timeouts.leader_state_ms.max(self.timeouts.command_ms) + 2 * self.period_ms)
            as f32
            / 1000.0;
        v * t + v * v / (2.0 * self.limits.brake_decel)
    }
}

impl Default for RobotConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}
