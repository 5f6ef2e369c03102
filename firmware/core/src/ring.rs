//! The ultrasonic ring's stop rule, with closing speed: whatever the law or the base
//! station asks, a robot does not drive into what its ring sees, standing or coming.
//!
//! Each side (front, back) keeps its last reading; from two readings a period apart the
//! thing seen is coming at `u` = the gap's shrinking rate less the robot's own speed
//! toward it (low-passed; under 0.3 m/s, the robot's own turning against a wall, or going
//! away, it counts as nothing coming and leaves the static rule).
//! To stop before the gap is down to `proximity_stop` while both close it, the robot's
//! speed toward that side obeys v²/(2a) + u·v/a ≤ room, that is
//!
//! ```text
//! v ≤ √(u² + 2·a·room) − u        room = free − proximity_stop, a = proximity_decel
//! ```
//!
//! which is the static rule √(2·a·room) where nothing comes (u = 0), and a standstill
//! when someone walks at it from close by (the time to collision is under the time it
//! takes to brake). It never backs away: a standing robot that is walked into has not
//! driven into anyone.

use crate::{math, Twist};

/// The fastest anything seen may be coming, m/s (faster: a jump between two things, not
/// one thing coming).
const MAX_CLOSING: f32 = 3.0;
/// Slower than this is the robot's own turning and wheel slip against a wall, not
/// something coming (a walker comes at 1 m/s or more), m/s.
const MIN_CLOSING: f32 = 0.3;
/// Turning faster than this, rad/s, the ring's rays sweep (see [`Ring::observe`]).
const TURNING: f32 = 0.2;

/// The ring's last readings and how fast what it sees is coming, per side.
#[derive(Debug, Clone, Copy, Default)]
pub struct Ring {
    last: [Option<f32>; 2],
    coming: [f32; 2],
}

impl Ring {
    /// Takes this period's readings (free distance ahead, behind), `dt` after the last,
    /// the robot having driven at `moved` meanwhile. Turning, a ray sweeps from one
    /// surface to another: those readings tell nothing of closing speed.
    pub fn observe(&mut self, proximity: &[Option<f32>; 2], moved: Twist, dt: f32) {
        let turning = math::abs(moved.omega) > TURNING;
        let v = moved.v;
        for (side, toward) in [(0, v), (1, -v)] {
            let coming = match (self.last[side], proximity[side]) {
                (Some(before), Some(now)) if dt > 0.0 && !turning => {
                    let u = (before - now) / dt - toward;
                    if !(MIN_CLOSING..=MAX_CLOSING).contains(&u) {
                        0.0
                    } else {
                        u
                    }
                }
                _ => 0.0,
            };
            self.coming[side] = 0.5 * (self.coming[side] + coming);
            self.last[side] = proximity[side];
        }
    }

    /// The fastest the robot may drive toward `side` (0 front, 1 back) with `free` metres
    /// free there.
    pub fn cap(&self, side: usize, free: Option<f32>, stop: f32, decel: f32) -> f32 {
        free.map_or(f32::INFINITY, |d| {
            let room = (d - stop).max(0.0);
            let u = self.coming[side];
            (math::sqrt(u * u + 2.0 * decel * room) - u).max(0.0)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const STOP: f32 = 0.15;
    const DECEL: f32 = 0.5;

    #[test]
    fn a_standing_obstacle_keeps_the_static_rule() {
        let mut ring = Ring::default();
        // Driving at 0.3 m/s toward a wall: the gap shrinks by the robot's own speed.
        ring.observe(&[Some(1.03), None], Twist { v: 0.3, omega: 0.0 }, 0.1);
        ring.observe(&[Some(1.0), None], Twist { v: 0.3, omega: 0.0 }, 0.1);
        let cap = ring.cap(0, Some(1.0), STOP, DECEL);
        let stat = math::sqrt(2.0 * DECEL * (1.0 - STOP));
        assert!((cap - stat).abs() < 1e-3, "{cap} vs {stat}");
    }

    #[test]
    fn someone_coming_at_the_robot_brings_it_to_a_stop_sooner() {
        let mut ring = Ring::default();
        // Standing; a person walks at the front at 1.3 m/s.
        let mut d = 1.6;
        for _ in 0..5 {
            ring.observe(&[Some(d), None], Twist::ZERO, 0.1);
            d -= 0.13;
        }
        let coming = ring.cap(0, Some(d), STOP, DECEL);
        let stat = math::sqrt(2.0 * DECEL * (d - STOP));
        assert!(coming < 0.5 * stat, "{coming} vs static {stat}");
        // From close by it crawls at most (0.43 m free: 0.10 m/s, against 0.53 m/s for a
        // wall there), and at the stop distance it stands…
        for _ in 0..4 {
            ring.observe(&[Some(d), None], Twist::ZERO, 0.1);
            d -= 0.13;
        }
        assert!(ring.cap(0, Some(d), STOP, DECEL) < 0.11, "{d}");
        assert!(ring.cap(0, Some(STOP), STOP, DECEL) < 1e-6);
        // …and nothing is asked of the other side (it never backs away).
        assert_eq!(ring.cap(1, None, STOP, DECEL), f32::INFINITY);
    }

    #[test]
    fn something_going_away_or_a_jump_is_not_coming() {
        let mut ring = Ring::default();
        ring.observe(&[Some(0.5), None], Twist::ZERO, 0.1);
        ring.observe(&[Some(0.8), None], Twist::ZERO, 0.1);
        assert_eq!(ring.coming[0], 0.0);
        // A new, nearer thing in view: a jump of 0.7 m in a period is not a speed.
        ring.observe(&[Some(0.1), None], Twist::ZERO, 0.1);
        assert_eq!(ring.coming[0], 0.0);
    }
}
