//! The turn rate the followers are told the leader drives, smoothed where it only jitters.
//!
//! A follower feeds the leader's turn rate forward through its slot: the law's `L·ω`
//! term, which its control point `d` ahead turns into `L/d` times as much turn rate of its
//! own (45× for a 5-follower V's rear slot 9 m back). The leader's command wiggles by a
//! few mrad/s as it steers past bins and on noisy fixes, and the rear followers weaved at
//! 0.06–0.11 rad/s on straight legs. A low-pass filter would calm that but lag real turns
//! (a fixed time constant of 0.3 s tore the triangle at the barrier's U-turn), so the
//! filter adapts, as the 1€ filter does (Casiez et al., CHI 2012): a change much smaller
//! than `jitter` moves the output by `slowest` of itself per step, a change of `jitter`
//! or more passes whole.

/// An adaptive low-pass filter of the broadcast turn rate, stepped once per broadcast.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TurnRateSmoother {
    /// The fraction of a small change taken per step (0 < slowest ≤ 1).
    slowest: f64,
    /// A change this large or larger (rad/s) is taken whole.
    jitter: f64,
    omega: f64,
}

impl TurnRateSmoother {
    pub const fn new(slowest: f64, jitter: f64) -> Self {
        Self {
            slowest,
            jitter,
            omega: 0.0,
        }
    }

    /// The smoothed turn rate after the leader was told `omega`.
    pub fn step(&mut self, omega: f64) -> f64 {
        let change = omega - self.omega;
        let taken = self.slowest + (1.0 - self.slowest) * (change.abs() / self.jitter).min(1.0);
        self.omega += taken * change;
        self.omega
    }

    /// The smoothed turn rate it last gave.
    pub fn omega(&self) -> f64 {
        self.omega
    }
}

impl Default for TurnRateSmoother {
    /// Measured on the 20-seed sweep of generated maps (docs/sim.md).
    fn default() -> Self {
        Self::new(0.2, 0.02)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jitter_is_calmed_and_turns_pass() {
        let mut s = TurnRateSmoother::default();
        // A wiggle of ±4 mrad/s around a straight leg comes out at a third or less.
        let out: Vec<f64> = (0..50)
            .map(|i| s.step(if i % 2 == 0 { 0.004 } else { -0.004 }))
            .collect();
        let peak = out[10..].iter().fold(0.0f64, |m, w| m.max(w.abs()));
        assert!(peak < 0.0015, "{peak}");
        // A turn of 0.2 rad/s is taken within a step.
        assert!((s.step(0.2) - 0.2).abs() < 0.01);
        // And holding a turn, the output settles on it.
        (0..20).for_each(|_| {
            s.step(0.2);
        });
        assert!((s.step(0.2) - 0.2).abs() < 1e-6);
    }
}
