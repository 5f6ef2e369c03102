//! The control code every robot runs, written once: on the MCU (firmware), in the native
//! software-in-the-loop fleet (hil-sim) and in host tests.
//!
//! - [`kinematics`]: differential drive, (v, ω) ↔ wheel speeds, limits.
//! - [`pid`]: one wheel-speed PID per wheel.
//! - [`odometry`]: pose from encoder ticks, corrected by pose fixes.
//! - [`follower`]: the L-φ leader-follower law (singularity-free form), slots, prediction.
//! - [`controller`]: modes (idle, joining, in formation, transforming, failsafe, leading,
//!   emergency stop) and one control step from sensors to motor duties.
//! - [`ring`]: the ultrasonic ring's stop rule, with the closing speed of what it sees.
//! - [`node`]: the robot's radio node: link, messages in, telemetry out, control step.
//!
//! no_std, no heap; every bound is a const. Time is always passed in (milliseconds since
//! boot); nothing here reads a clock. All maths goes through [`math`] so that host tests
//! run the same float code as the MCU.
#![cfg_attr(not(feature = "std"), no_std)]
#![deny(unsafe_code)]

#[cfg(test)]
extern crate std;

pub mod config;
pub mod controller;
pub mod follower;
pub mod kinematics;
pub mod math;
pub mod node;
pub mod odometry;
pub mod pid;
pub mod ring;

pub use config::RobotConfig;
pub use controller::{Controller, MotorOutput, Sensors};
pub use node::RobotNode;
pub use protocol::units::NonFinite;

/// A planar pose: position in metres, heading in radians.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Pose {
    pub x: f32,
    pub y: f32,
    pub heading: f32,
}

impl Pose {
    pub const fn new(x: f32, y: f32, heading: f32) -> Self {
        Self { x, y, heading }
    }

    pub fn is_finite(&self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.heading.is_finite()
    }

    /// The point `d` ahead of this pose along its heading.
    pub fn ahead(&self, d: f32) -> (f32, f32) {
        let (s, c) = math::sin_cos(self.heading);
        (self.x + d * c, self.y + d * s)
    }
}

/// Linear and angular velocity of a robot's reference point (m/s, rad/s).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Twist {
    pub v: f32,
    pub omega: f32,
}

impl Twist {
    pub const ZERO: Twist = Twist { v: 0.0, omega: 0.0 };

    pub const fn new(v: f32, omega: f32) -> Self {
        Self { v, omega }
    }

    pub fn is_finite(&self) -> bool {
        self.v.is_finite() && self.omega.is_finite()
    }
}
