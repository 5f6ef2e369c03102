//! Scan lines: where a horizontal line crosses a polygon, comes near an obstacle, and what
//! is left free. Exact for circles, segments and polygons grown by a clearance (each
//! grown shape meets a line in intervals that are computed, not sampled).

use glam::DVec2;

use crate::geometry::Obstacle;

/// An interval of x, `lo <= hi`.
pub type Span = (f64, f64);

/// Where the line at `y` is inside `polygon` (even-odd), in order.
pub fn inside(polygon: &[DVec2], y: f64) -> Vec<Span> {
    let mut xs: Vec<f64> = Vec::new();
    let n = polygon.len();
    for i in 0..n {
        let (a, b) = (polygon[i], polygon[(i + 1) % n]);
        if (a.y > y) != (b.y > y) {
            xs.push(a.x + (y - a.y) * (b.x - a.x) / (b.y - a.y));
        }
    }
    xs.sort_by(f64::total_cmp);
    xs.chunks_exact(2).map(|p| (p[0], p[1])).collect()
}

/// Where the line at `y` comes within `c` of the segment a–b (a capsule: convex, so one
/// interval, bounded by the end circles and the two offset sides).
fn capsule(a: DVec2, b: DVec2, c: f64, y: f64) -> Option<Span> {
    let mut xs = Vec::with_capacity(6);
    for p in [a, b] {
        let dy = y - p.y;
        if dy.abs() < c {
            let dx = (c * c - dy * dy).sqrt();
            xs.extend([p.x - dx, p.x + dx]);
        }
    }
    let d = b - a;
    let len = d.length();
    if len > 1e-12 {
        let normal = DVec2::new(-d.y, d.x) / len * c;
        for off in [normal, -normal] {
            let (p, q) = (a + off, b + off);
            if (p.y > y) != (q.y > y) {
                xs.push(p.x + (y - p.y) * (q.x - p.x) / (q.y - p.y));
            }
        }
    }
    let lo = xs.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = xs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    (lo < hi).then_some((lo, hi))
}

/// Where the line at `y` comes within `c` of `o` (or is inside it).
pub fn blocked_by(o: &Obstacle, c: f64, y: f64, out: &mut Vec<Span>) {
    match o {
        Obstacle::Circle { center, radius } => {
            let (r, dy) = (radius + c, y - center.y);
            if dy.abs() < r {
                let dx = (r * r - dy * dy).sqrt();
                out.push((center.x - dx, center.x + dx));
            }
        }
        Obstacle::Segment { a, b } => out.extend(capsule(*a, *b, c, y)),
        Obstacle::Polygon { points } => {
            out.extend(inside(points, y));
            let n = points.len();
            out.extend((0..n).filter_map(|i| capsule(points[i], points[(i + 1) % n], c, y)));
        }
    }
}

/// `spans` merged where they overlap, in order.
pub fn merged(mut spans: Vec<Span>) -> Vec<Span> {
    spans.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut out: Vec<Span> = Vec::with_capacity(spans.len());
    for s in spans {
        match out.last_mut() {
            Some(last) if s.0 <= last.1 => last.1 = last.1.max(s.1),
            _ => out.push(s),
        }
    }
    out
}

/// `free` less `blocked` (both in order, `blocked` merged).
pub fn subtract(free: &[Span], blocked: &[Span]) -> Vec<Span> {
    let mut out = Vec::new();
    for &(mut lo, hi) in free {
        for &(blo, bhi) in blocked {
            if bhi <= lo || blo >= hi {
                continue;
            }
            if blo > lo {
                out.push((lo, blo));
            }
            lo = lo.max(bhi);
        }
        if lo < hi {
            out.push((lo, hi));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_square_with_a_post_leaves_two_spans() {
        let square = [
            DVec2::new(0.0, 0.0),
            DVec2::new(10.0, 0.0),
            DVec2::new(10.0, 10.0),
            DVec2::new(0.0, 10.0),
        ];
        assert_eq!(inside(&square, 5.0), vec![(0.0, 10.0)]);
        let post = Obstacle::Circle {
            center: DVec2::new(5.0, 5.0),
            radius: 0.5,
        };
        let mut b = Vec::new();
        blocked_by(&post, 0.5, 5.0, &mut b);
        let free = subtract(&inside(&square, 5.0), &merged(b));
        assert_eq!(free, vec![(0.0, 4.0), (6.0, 10.0)]);
    }

    #[test]
    fn a_grown_wall_blocks_as_far_as_its_capsule() {
        let wall = Obstacle::Segment {
            a: DVec2::new(0.0, 0.0),
            b: DVec2::new(0.0, 4.0),
        };
        let mut b = Vec::new();
        blocked_by(&wall, 1.0, 2.0, &mut b);
        assert_eq!(b, vec![(-1.0, 1.0)]);
        b.clear();
        blocked_by(&wall, 1.0, 4.6, &mut b);
        assert!((b[0].1 - 0.8).abs() < 1e-9, "{b:?}");
        b.clear();
        blocked_by(&wall, 1.0, 5.1, &mut b);
        assert!(b.is_empty());
    }

    #[test]
    fn a_block_grown_by_its_clearance() {
        let block = Obstacle::rectangle(DVec2::new(2.0, 2.0), DVec2::new(4.0, 4.0));
        let mut b = Vec::new();
        blocked_by(&block, 0.5, 3.0, &mut b);
        assert_eq!(merged(b), vec![(1.5, 4.5)]);
    }
}
