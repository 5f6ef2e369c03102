//! A minimal robot body for the core's tests: first-order wheel motors, encoders.
#![allow(dead_code)]

use control_core::config::RobotConfig;
use control_core::controller::{MotorOutput, Sensors};
use control_core::odometry::PoseFixSample;
use control_core::Pose;

pub struct Body {
    pub pose: Pose,
    /// Wheel rim speeds, m/s.
    pub wheel: [f32; 2],
    /// Travelled distance per wheel, m (exact), and the ticks they give.
    pub travel: [f64; 2],
    pub tau: f32,
    pub no_load_speed: f32,
}

impl Body {
    pub fn new(pose: Pose) -> Self {
        Self {
            pose,
            wheel: [0.0; 2],
            travel: [0.0; 2],
            tau: 0.1,
            no_load_speed: 1.2,
        }
    }

    pub fn sensors(&self, cfg: &RobotConfig, fix_at: Option<u32>) -> Sensors {
        let per_tick = cfg.metres_per_tick() as f64;
        Sensors {
            ticks: [
                (self.travel[0] / per_tick).floor() as i32,
                (self.travel[1] / per_tick).floor() as i32,
            ],
            pose_fix: fix_at.map(|t| PoseFixSample {
                pose: self.pose,
                // As good as a localization gets (σ 0 is refused: no source is perfect).
                sigma: 0.005,
                time_ms: t,
            }),
            proximity: [None, None],
        }
    }

    /// Advances by `dt` under constant duties, in `n` sub-steps.
    pub fn advance(&mut self, out: &MotorOutput, cfg: &RobotConfig, dt: f32, n: u32) {
        let h = dt / n as f32;
        for _ in 0..n {
            for i in 0..2 {
                let target = out.duty[i] * self.no_load_speed;
                self.wheel[i] += (target - self.wheel[i]) * (h / self.tau);
                self.travel[i] += (self.wheel[i] * h) as f64;
            }
            let v = 0.5 * (self.wheel[0] + self.wheel[1]);
            let w = (self.wheel[1] - self.wheel[0]) / cfg.drive.track_width;
            self.pose.x += v * self.pose.heading.cos() * h;
            self.pose.y += v * self.pose.heading.sin() * h;
            self.pose.heading += w * h;
        }
    }
}
