//! Sweeping areas: the coverage route the station hands the leader ([`plan`]), the
//! swath the formation's brushes sweep side by side ([`swath`]), and the ground a run
//! swept ([`grid`]).

pub mod grid;
pub mod lines;
pub mod plan;
pub mod watch;

use glam::DVec2;

use crate::formation::FormationSpec;

/// The swath of the formation's wide shape: the brushes (`brush` wide, one per robot,
/// centred on it) side by side across the leader's path, as far as they join up without
/// a gap on both sides of the leader (a symmetric swath, so a pass swept one way and the
/// next the other tile), and the gaps the slots leave, m.
pub fn swath(formation: &FormationSpec, brush: f64) -> Swath {
    let mut lateral: Vec<f64> = formation
        .wide_slots()
        .iter()
        .map(|(l, phi)| l * phi.sin())
        .chain([0.0])
        .collect();
    lateral.sort_by(f64::total_cmp);
    let half = 0.5 * brush;
    // From the leader outward on each side, while the next brush touches the last.
    let reach = |side: &mut dyn Iterator<Item = f64>| {
        let mut edge = half;
        for y in side {
            if y - half > edge + 1e-9 {
                return (edge, Some(y - half - edge));
            }
            edge = edge.max(y + half);
        }
        (edge, None)
    };
    let (left, left_gap) = reach(&mut lateral.iter().copied().filter(|y| *y > 0.0));
    let (right, right_gap) = reach(&mut lateral.iter().rev().map(|y| -y).filter(|y| *y > 0.0));
    let gap = left_gap.into_iter().chain(right_gap).fold(0.0, f64::max);
    Swath {
        width: 2.0 * left.min(right),
        brush,
        gap,
    }
}

/// What the formation sweeps in one pass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Swath {
    /// The width swept without a gap, symmetric about the leader's path, m.
    pub width: f64,
    /// One robot's brush, m (the line's swath).
    pub brush: f64,
    /// The widest gap between neighbouring brushes across the wide shape, m (0: none).
    pub gap: f64,
}

/// How far behind the leader the rearmost robot of the wide shape drives, m.
pub fn trail(formation: &FormationSpec) -> f64 {
    formation
        .wide_slots()
        .iter()
        .map(|(l, phi)| -(l * phi.cos()))
        .fold(0.0, f64::max)
}

/// A robot heading within this of an area's passes sweeps, rad (30°).
pub const ALONG: f64 = std::f64::consts::FRAC_PI_6;

/// Whether a robot at `position` heading `heading` has its brushes down: inside an area's
/// outline grown by half a brush, heading along that area's passes (`directions`, rad,
/// either way) within [`ALONG`]; the brushes are lifted to turn between passes and on
/// links across the passes. The same rule for the station's estimate and the simulator's
/// truth.
pub fn brush_down(
    grid: &grid::Coverage,
    directions: &[f64],
    position: DVec2,
    heading: f64,
) -> bool {
    grid.area_at(position)
        .and_then(|a| directions.get(a))
        .is_some_and(|d| (heading - d).sin().abs() <= ALONG.sin())
}

/// A polygon's area (shoelace), m².
pub fn area(polygon: &[DVec2]) -> f64 {
    let n = polygon.len();
    let twice: f64 = (0..n)
        .map(|i| polygon[i].perp_dot(polygon[(i + 1) % n]))
        .sum();
    0.5 * twice.abs()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formation::WideShape;

    fn triangle(distance: f64, angle_deg: f64) -> FormationSpec {
        FormationSpec {
            wide: WideShape::V {
                distance,
                angle: angle_deg.to_radians(),
            },
            followers: 2,
            line_spacing: 1.5,
            margin: 0.5,
            transition_s: 3.5,
            min_dwell_s: 2.0,
            lookahead: 6.0,
            footprint: 0.3,
            slot_speed: 0.8,
            top_speed: 1.0,
        }
    }

    #[test]
    fn three_brushes_side_by_side_sweep_three_times_one() {
        // Followers 0.6 m either side, brushes 0.7 m: joined, 1.9 m in all.
        let s = swath(&triangle(1.2, 150.0), 0.7);
        assert!((s.width - 1.9).abs() < 1e-9, "{s:?}");
        assert_eq!(s.gap, 0.0);
        assert!((trail(&triangle(1.2, 150.0)) - 1.2 * 30f64.to_radians().cos()).abs() < 1e-9);
    }

    #[test]
    fn the_papers_wide_triangle_leaves_gaps_and_sweeps_one_brush() {
        // Followers 1.5 m either side of a 0.7 m brush: 0.8 m gaps.
        let s = swath(&triangle(3.0, 150.0), 0.7);
        assert!((s.width - 0.7).abs() < 1e-9, "{s:?}");
        assert!((s.gap - 0.8).abs() < 1e-9, "{s:?}");
    }
}
