//! Obstacles and the distances the planner needs: to the surface, not the centre; the
//! site's map of them ([`map`]) and things by grid cell ([`cells`]).

pub mod cells;
pub mod map;

use glam::DVec2;
use serde::Serialize;

/// An angle in (−π, π]: the control core's, in double precision.
pub use control_core::math::wrap_angle_f64 as wrap_angle;

/// A robot's pose in the site frame, as the planner and the formation manager see it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanPose {
    pub position: DVec2,
    /// Counter-clockwise from the site's x axis, rad.
    pub heading: f64,
}

/// Distance along the unit ray `o + t·dir` to a circle's rim, if it hits it from outside.
pub fn ray_circle(o: DVec2, dir: DVec2, c: DVec2, r: f64) -> Option<f64> {
    let oc = o - c;
    let b = oc.dot(dir);
    let disc = b * b - (oc.length_squared() - r * r);
    if disc < 0.0 {
        return None;
    }
    let t = -b - disc.sqrt();
    (t >= 0.0).then_some(t)
}

/// An obstacle on the map.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Obstacle {
    /// A bin, a pole, a bench end.
    Circle { center: DVec2, radius: f64 },
    /// A thin wall or kerb line.
    Segment { a: DVec2, b: DVec2 },
    /// A solid block: a building, a wall with thickness. Vertices in order.
    Polygon { points: Vec<DVec2> },
}

/// Where the nearest surface point is and how far.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Nearest {
    /// Signed distance to the surface: negative inside a circle or polygon.
    pub distance: f64,
    /// Unit vector from the surface toward the point (outward).
    pub normal: DVec2,
}

/// The point of segment a–b nearest to `p`.
pub(crate) fn closest_on_segment(p: DVec2, a: DVec2, b: DVec2) -> DVec2 {
    let ab = b - a;
    let len2 = ab.length_squared();
    if len2 == 0.0 {
        return a;
    }
    let t = ((p - a).dot(ab) / len2).clamp(0.0, 1.0);
    a + ab * t
}

/// The unit vector of `v`, or `fallback` for a zero vector.
fn unit_or(v: DVec2, fallback: DVec2) -> DVec2 {
    let n = v.length();
    if n > 1e-12 {
        v / n
    } else {
        fallback
    }
}

/// Whether `p` is inside the polygon `pts` (even-odd).
pub fn point_in_polygon(p: DVec2, pts: &[DVec2]) -> bool {
    let mut inside = false;
    let mut j = pts.len() - 1;
    for i in 0..pts.len() {
        let (a, b) = (pts[i], pts[j]);
        if (a.y > p.y) != (b.y > p.y) && p.x < (b.x - a.x) * (p.y - a.y) / (b.y - a.y) + a.x {
            inside = !inside;
        }
        j = i;
    }
    inside
}

impl Obstacle {
    /// An axis-aligned block from its lower-left to its upper-right corner.
    pub fn rectangle(lo: DVec2, hi: DVec2) -> Obstacle {
        Obstacle::Polygon {
            points: vec![lo, DVec2::new(hi.x, lo.y), hi, DVec2::new(lo.x, hi.y)],
        }
    }

    pub fn nearest(&self, p: DVec2) -> Nearest {
        match self {
            Obstacle::Circle { center, radius } => {
                let d = p - *center;
                Nearest {
                    distance: d.length() - radius,
                    normal: unit_or(d, DVec2::X),
                }
            }
            Obstacle::Segment { a, b } => {
                let q = closest_on_segment(p, *a, *b);
                Nearest {
                    distance: (p - q).length(),
                    normal: unit_or(p - q, (*b - *a).perp().normalize_or(DVec2::X)),
                }
            }
            Obstacle::Polygon { points } => {
                let mut best = (f64::INFINITY, DVec2::ZERO, DVec2::X);
                for i in 0..points.len() {
                    let (a, b) = (points[i], points[(i + 1) % points.len()]);
                    let q = closest_on_segment(p, a, b);
                    let d = (p - q).length();
                    if d < best.0 {
                        best = (d, q, (b - a).perp());
                    }
                }
                let inside = point_in_polygon(p, points);
                let away = unit_or(p - best.1, best.2.normalize_or(DVec2::X));
                Nearest {
                    distance: if inside { -best.0 } else { best.0 },
                    normal: if inside { -away } else { away },
                }
            }
        }
    }

    /// Axis-aligned bounds, `[min, max]`.
    pub fn bounds(&self) -> [DVec2; 2] {
        match self {
            Obstacle::Circle { center, radius } => [
                *center - DVec2::splat(*radius),
                *center + DVec2::splat(*radius),
            ],
            Obstacle::Segment { a, b } => [a.min(*b), a.max(*b)],
            Obstacle::Polygon { points } => {
                let lo = points
                    .iter()
                    .fold(DVec2::splat(f64::INFINITY), |m, p| m.min(*p));
                let hi = points
                    .iter()
                    .fold(DVec2::splat(f64::NEG_INFINITY), |m, p| m.max(*p));
                [lo, hi]
            }
        }
    }

    /// Distance along the unit ray `o + t·dir` to the first surface hit, if any.
    pub fn ray_cast(&self, o: DVec2, dir: DVec2) -> Option<f64> {
        match self {
            Obstacle::Circle { center, radius } => {
                let oc = o - *center;
                let b = oc.dot(dir);
                let c = oc.length_squared() - radius * radius;
                if c <= 0.0 {
                    return Some(0.0);
                }
                let disc = b * b - c;
                if disc < 0.0 {
                    return None;
                }
                let t = -b - disc.sqrt();
                (t >= 0.0).then_some(t)
            }
            Obstacle::Segment { a, b } => ray_segment(o, dir, *a, *b),
            Obstacle::Polygon { points } => {
                if point_in_polygon(o, points) {
                    return Some(0.0);
                }
                (0..points.len())
                    .filter_map(|i| ray_segment(o, dir, points[i], points[(i + 1) % points.len()]))
                    .min_by(f64::total_cmp)
            }
        }
    }
}

fn ray_segment(o: DVec2, dir: DVec2, a: DVec2, b: DVec2) -> Option<f64> {
    let e = b - a;
    let denom = dir.perp_dot(e);
    if denom.abs() < 1e-12 {
        return None;
    }
    let w = a - o;
    let t = w.perp_dot(e) / denom;
    let u = w.perp_dot(dir) / denom;
    (t >= 0.0 && (0.0..=1.0).contains(&u)).then_some(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances_to_surfaces() {
        let c = Obstacle::Circle {
            center: DVec2::new(1.0, 0.0),
            radius: 0.5,
        };
        let n = c.nearest(DVec2::new(3.0, 0.0));
        assert!((n.distance - 1.5).abs() < 1e-12 && n.normal == DVec2::X);
        let block = Obstacle::Polygon {
            points: vec![
                DVec2::new(0.0, 0.0),
                DVec2::new(2.0, 0.0),
                DVec2::new(2.0, 1.0),
                DVec2::new(0.0, 1.0),
            ],
        };
        let n = block.nearest(DVec2::new(1.0, 3.0));
        assert!((n.distance - 2.0).abs() < 1e-12 && (n.normal - DVec2::Y).length() < 1e-12);
        let n = block.nearest(DVec2::new(1.0, 0.8));
        assert!((n.distance + 0.2).abs() < 1e-12 && (n.normal - DVec2::Y).length() < 1e-12);
        let wall = Obstacle::Segment {
            a: DVec2::new(0.0, 0.0),
            b: DVec2::new(0.0, 4.0),
        };
        assert!((wall.nearest(DVec2::new(-1.0, 5.0)).distance - 2f64.sqrt()).abs() < 1e-12);
        assert_eq!(wall.ray_cast(DVec2::new(-1.0, 1.0), DVec2::X), Some(1.0));
        assert_eq!(block.ray_cast(DVec2::new(1.0, 3.0), -DVec2::Y), Some(2.0));
        assert_eq!(c.ray_cast(DVec2::new(-1.0, 0.0), DVec2::X), Some(1.5));
        assert_eq!(c.ray_cast(DVec2::new(-1.0, 0.0), -DVec2::X), None);
    }
}
