//! The artificial potential field, with the paper's slips fixed (`paper-notes.md`).
//!
//! - Attraction points **toward** the goal and is **saturated**:
//!   `F_att = k_a · min(l_g, s) · û_goal`. The paper's raw `k_a · l_g` reaches 10 at 10 m,
//!   which drowns every repulsion (1.5 at 0.5 m): far from the goal the robot would not
//!   turn away from anything. With `s` = 1 m the attraction is at most `k_a`, and it still
//!   fades linearly inside the last metre (a smooth stop at the goal).
//! - Repulsion points **away** from the obstacle and uses the paper's *force*,
//!   `k_r (1/l² − 1/(l·R_det))` for `l ≤ R_det`, 0 beyond. It is not the gradient of the
//!   paper's potential (that jumps by `k_r/R_det³` at `R_det`); the paper's force is
//!   continuous and vanishes at `R_det`, so the robot feels no kick when an obstacle enters
//!   the detection radius. We keep it.
//! - `l` is the **clearance**: distance from the robot's footprint (radius `footprint`) to
//!   the obstacle's surface, floored at `MIN_CLEARANCE` to stay finite on contact.
//! - Near the goal the repulsion is scaled by `(l_g / R_det)²` (Ge and Cui): an obstacle
//!   beside the goal cannot hold the robot off it, while attraction (linear in `l_g`) wins.

use glam::DVec2;

use crate::geometry::map::Map;

/// Clearance floor: the force stays finite (195 with the paper's gains) on contact.
pub const MIN_CLEARANCE: f64 = 0.05;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ApfParams {
    pub k_a: f64,
    pub k_r: f64,
    pub r_det: f64,
    /// Distance beyond which the attraction stops growing, m.
    pub attraction_saturation: f64,
    /// Robot footprint radius, m.
    pub footprint: f64,
}

impl ApfParams {
    /// The paper's gains, this project's footprint and saturation.
    pub const PAPER: ApfParams = ApfParams {
        k_a: 1.0,
        k_r: 0.5,
        r_det: 2.0,
        attraction_saturation: 1.0,
        footprint: 0.3,
    };
}

/// Attraction toward `goal`, saturated.
pub fn attraction(p: DVec2, goal: DVec2, a: &ApfParams) -> DVec2 {
    let d = goal - p;
    let l = d.length();
    if l < 1e-9 {
        return DVec2::ZERO;
    }
    d / l * a.k_a * l.min(a.attraction_saturation)
}

/// The paper's repulsion magnitude at clearance `l`.
pub fn repulsion_magnitude(l: f64, a: &ApfParams) -> f64 {
    if l > a.r_det {
        return 0.0;
    }
    let l = l.max(MIN_CLEARANCE);
    a.k_r * (1.0 / (l * l) - 1.0 / (l * a.r_det))
}

/// Sum of the repulsions on a robot at `p`, each obstacle once (its nearest surface point).
pub fn repulsion(p: DVec2, map: &Map, a: &ApfParams) -> DVec2 {
    map.near(p, a.r_det + a.footprint)
        .map(|o| {
            let n = o.nearest(p);
            n.normal * repulsion_magnitude(n.distance - a.footprint, a)
        })
        .sum()
}

/// The goal-distance scaling of repulsion (Ge and Cui).
pub fn goal_scale(p: DVec2, goal: DVec2, a: &ApfParams) -> f64 {
    ((goal - p).length() / a.r_det).min(1.0).powi(2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Obstacle;

    const A: ApfParams = ApfParams::PAPER;

    fn pole() -> Map {
        Map::new(vec![Obstacle::Circle {
            center: DVec2::ZERO,
            radius: 0.5,
        }])
    }

    #[test]
    fn attraction_points_to_the_goal_and_saturates() {
        let f = attraction(DVec2::ZERO, DVec2::new(10.0, 0.0), &A);
        assert_eq!(f, DVec2::new(1.0, 0.0));
        let f = attraction(DVec2::ZERO, DVec2::new(0.0, -0.4), &A);
        assert!((f - DVec2::new(0.0, -0.4)).length() < 1e-12);
        assert_eq!(attraction(DVec2::ONE, DVec2::ONE, &A), DVec2::ZERO);
    }

    #[test]
    fn repulsion_at_known_points() {
        // Clearance 0.5 m (centre 1.3 m from a 0.5 m pole, 0.3 m footprint): 1.5, away.
        let f = repulsion(DVec2::new(1.3, 0.0), &pole(), &A);
        assert!((f - DVec2::new(1.5, 0.0)).length() < 1e-9, "{f}");
        let f = repulsion(DVec2::new(0.0, -1.8), &pole(), &A);
        assert!((f - DVec2::new(0.0, -0.25)).length() < 1e-9, "{f}");
    }

    #[test]
    fn repulsion_vanishes_continuously_at_r_det() {
        let inside = repulsion(DVec2::new(0.8 + 2.0 - 1e-6, 0.0), &pole(), &A);
        let outside = repulsion(DVec2::new(0.8 + 2.0 + 1e-6, 0.0), &pole(), &A);
        assert!(inside.x > 0.0 && inside.x < 1e-6, "{inside}");
        assert_eq!(outside, DVec2::ZERO);
        // Just inside, it grows smoothly: no jump of k_r/R³ = 0.0625.
        let a_bit = repulsion(DVec2::new(0.8 + 1.9, 0.0), &pole(), &A);
        assert!(a_bit.x > 0.0 && a_bit.x < 0.01);
    }

    #[test]
    fn contact_stays_finite() {
        let f = repulsion(DVec2::new(0.6, 0.0), &pole(), &A);
        assert!(f.x.is_finite() && f.x > 100.0);
    }
}
