//! A wheel-speed PID: feed-forward from the set-point, derivative on the measurement,
//! output saturation and conditional-integration anti-windup. A pure function of its
//! inputs and `dt`: the same code runs on the MCU, in the SIL and in tests.

use crate::math;

/// Gains of one wheel loop. Units: duty per (m/s) of error.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PidGains {
    pub kp: f32,
    /// Integral gain, duty per (m/s · s).
    pub ki: f32,
    /// Derivative gain on the measurement, duty per (m/s²).
    pub kd: f32,
    /// Feed-forward, duty per (m/s) of set-point: 1 / (no-load speed at full duty).
    pub kff: f32,
    /// Output limit: duty in [-limit, limit].
    pub limit: f32,
}

#[derive(Debug, Clone)]
pub struct Pid {
    pub gains: PidGains,
    integral: f32,
    last_measurement: Option<f32>,
}

impl Pid {
    pub const fn new(gains: PidGains) -> Self {
        Self {
            gains,
            integral: 0.0,
            last_measurement: None,
        }
    }

    /// Forgets the integral and the derivative history (on a mode change, or after the
    /// motors were off).
    pub fn reset(&mut self) {
        self.integral = 0.0;
        self.last_measurement = None;
    }

    pub fn integral(&self) -> f32 {
        self.integral
    }

    /// One step: duty for the set-point and the measured wheel speed, `dt` seconds after
    /// the previous step.
    pub fn update(&mut self, setpoint: f32, measured: f32, dt: f32) -> f32 {
        let g = self.gains;
        let error = setpoint - measured;
        let derivative = match self.last_measurement {
            Some(prev) if dt > 0.0 => -(measured - prev) / dt,
            _ => 0.0,
        };
        self.last_measurement = Some(measured);

        let without_i = g.kff * setpoint + g.kp * error + g.kd * derivative;
        let candidate = self.integral + g.ki * error * dt;
        let unclamped = without_i + candidate;
        // Integrate only while the output is not saturated in the error's direction, so
        // the integral cannot wind up while the motor is at its limit.
        let saturated_up = unclamped > g.limit && error > 0.0;
        let saturated_down = unclamped < -g.limit && error < 0.0;
        if !(saturated_up || saturated_down) {
            self.integral = math::clamp(candidate, -g.limit, g.limit);
        }
        math::clamp(without_i + self.integral, -g.limit, g.limit)
    }
}
