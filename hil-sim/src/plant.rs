//! A robot's body: differential drive (the paper's kinematics), two wheel motors with a
//! first-order lag, saturation and a dead band, quantised encoders.

use control_core::controller::MotorOutput;

/// The body's physical parameters (from the scenario's `[robot]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyParams {
    pub footprint: f64,
    pub track_width: f64,
    pub wheel_radius: f64,
    pub ticks_per_rev: u32,
    /// Motor lag, s.
    pub tau: f64,
    /// Rim speed at full duty, m/s.
    pub no_load_speed: f64,
    /// Duties below this do not turn the wheel.
    pub dead_band: f64,
}

/// What is wrong with the body (fault injection).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BodyFaults {
    /// The wheel is blocked (left, right).
    pub stuck: [bool; 2],
    /// Torque factor of each motor (1 = healthy).
    pub torque: [f64; 2],
    /// The encoder no longer counts.
    pub encoder_dead: [bool; 2],
}

#[derive(Debug, Clone)]
pub struct Body {
    pub params: BodyParams,
    pub x: f64,
    pub y: f64,
    pub heading: f64,
    /// Rim speeds, m/s.
    pub wheel: [f64; 2],
    travel: [f64; 2],
    counted: [f64; 2],
    pub faults: BodyFaults,
}

impl Body {
    pub fn new(params: BodyParams, x: f64, y: f64, heading: f64) -> Self {
        Self {
            params,
            x,
            y,
            heading,
            wheel: [0.0; 2],
            travel: [0.0; 2],
            counted: [0.0; 2],
            faults: BodyFaults {
                torque: [1.0; 2],
                ..Default::default()
            },
        }
    }

    /// Linear and angular speed of the body now.
    pub fn twist(&self) -> (f64, f64) {
        let [l, r] = self.wheel;
        (0.5 * (l + r), (r - l) / self.params.track_width)
    }

    /// The point `d` ahead of the axle.
    pub fn ahead(&self, d: f64) -> (f64, f64) {
        (
            self.x + d * self.heading.cos(),
            self.y + d * self.heading.sin(),
        )
    }

    /// Cumulative encoder counts, as the MCU's timers would hold them (wrapping).
    pub fn ticks(&self) -> [i32; 2] {
        let per_tick =
            std::f64::consts::TAU * self.params.wheel_radius / self.params.ticks_per_rev as f64;
        self.counted.map(|t| ((t / per_tick).floor() as i64) as i32)
    }

    /// Advances by `dt` seconds under constant duties.
    pub fn step(&mut self, out: &MotorOutput, dt: f64) {
        let p = self.params;
        let k = 1.0 - (-dt / p.tau).exp();
        for i in 0..2 {
            let duty = (out.duty[i] as f64).clamp(-1.0, 1.0);
            let effective = if duty.abs() <= p.dead_band {
                0.0
            } else {
                (duty - p.dead_band * duty.signum()) / (1.0 - p.dead_band)
            };
            let target = effective * p.no_load_speed * self.faults.torque[i];
            self.wheel[i] += (target - self.wheel[i]) * k;
            if self.faults.stuck[i] {
                self.wheel[i] = 0.0;
            }
            self.travel[i] += self.wheel[i] * dt;
            if !self.faults.encoder_dead[i] {
                self.counted[i] += self.wheel[i] * dt;
            }
        }
        let (v, w) = self.twist();
        let dh = w * dt;
        if dh.abs() < 1e-9 {
            self.x += v * dt * self.heading.cos();
            self.y += v * dt * self.heading.sin();
        } else {
            let r = v / w;
            self.x += r * ((self.heading + dh).sin() - self.heading.sin());
            self.y -= r * ((self.heading + dh).cos() - self.heading.cos());
        }
        self.heading = (self.heading + dh + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
            - std::f64::consts::PI;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> BodyParams {
        BodyParams {
            footprint: 0.3,
            track_width: 0.4,
            wheel_radius: 0.08,
            ticks_per_rev: 2048,
            tau: 0.1,
            no_load_speed: 1.2,
            dead_band: 0.03,
        }
    }

    #[test]
    fn lag_saturation_dead_band_and_ticks() {
        let mut b = Body::new(params(), 0.0, 0.0, 0.0);
        b.step(&MotorOutput { duty: [0.02, 0.02] }, 1.0);
        assert_eq!(b.wheel, [0.0, 0.0]);
        for _ in 0..100 {
            b.step(&MotorOutput { duty: [5.0, 5.0] }, 0.01);
        }
        assert!((b.wheel[0] - 1.2).abs() < 1e-3, "{:?}", b.wheel);
        let per_tick = std::f64::consts::TAU * 0.08 / 2048.0;
        assert!(((b.ticks()[0] as f64) * per_tick - b.x).abs() < 2.0 * per_tick);
        b.faults.stuck[1] = true;
        b.step(&MotorOutput { duty: [1.0, 1.0] }, 0.01);
        assert_eq!(b.wheel[1], 0.0);
    }
}
