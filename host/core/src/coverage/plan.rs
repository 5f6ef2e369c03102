//! The coverage route of one area: boustrophedon cells, passes oriented for the fewest
//! of them, cells in the order nearest first.
//!
//! **Method.** The area's polygon and the map's obstacles near it are turned so that the
//! passes run along x. Scan lines, one per pass, are spaced evenly at most `spacing`
//! apart with the first and last half a swath inside the area; on each, the spans the
//! leader may drive are the area's (over the whole swath's band) less every obstacle
//! grown by `clearance` ([`super::lines`], exact). Spans of neighbouring lines that
//! overlap one to one form a cell (Choset's boustrophedon decomposition: a cell splits
//! and merges where an obstacle begins and ends; a bin or a post, up to [`DETOUR`] across
//! grown, splits nothing: the pass goes round it); a cell is swept back and forth, and the
//! next cell is the one whose nearest corner is nearest. The direction tried are the
//! polygon's edges' (a pass along a side leaves no slivers there); the one with the fewest
//! passes wins (turns cost more than metres), then the shortest.
//!
//! Why not a grid-based planner (wavefront, spanning tree): their routes follow the grid,
//! with a turn at every cell of a slanted edge; a boustrophedon route has one turn per
//! pass and straight passes the followers hold their slots on.

use glam::DVec2;

use super::lines::{blocked_by, inside, merged, subtract, Span};
use crate::geometry::map::Map;
use crate::geometry::Obstacle;

/// How one area is swept.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepParams {
    /// The width one pass sweeps (the formation's brushes side by side), m.
    pub swath: f64,
    /// The most between neighbouring passes' centre lines (the swath less the overlap), m.
    pub spacing: f64,
    /// How far the leader's centre keeps from what the map holds, m.
    pub clearance: f64,
    /// How far the rearmost brush trails the leader: each pass runs on so far past the
    /// area where there is room, m.
    pub trail: f64,
    /// The passes' direction, rad (`None`: the one with the fewest passes).
    pub direction: Option<f64>,
}

/// One pass: the leader drives from `from` to `to` in a straight line, by way of `round`:
/// where it leaves and rejoins the line to go round a bin or a post.
#[derive(Debug, Clone, PartialEq)]
pub struct Pass {
    pub from: DVec2,
    pub round: Vec<DVec2>,
    pub to: DVec2,
}

impl Pass {
    /// Its points in the order driven.
    pub fn points(&self) -> impl Iterator<Item = DVec2> + '_ {
        std::iter::once(self.from)
            .chain(self.round.iter().copied())
            .chain(std::iter::once(self.to))
    }
}

/// The plan of one area.
#[derive(Debug, Clone, PartialEq)]
pub struct AreaPlan {
    /// The passes' direction, rad.
    pub direction: f64,
    /// In the order driven.
    pub passes: Vec<Pass>,
    /// Boustrophedon cells.
    pub cells: usize,
}

impl AreaPlan {
    /// The passes' length and the straight links between them, m.
    pub fn length(&self) -> f64 {
        let passes: f64 = self.passes.iter().map(|p| (p.to - p.from).length()).sum();
        let links: f64 = self
            .passes
            .windows(2)
            .map(|w| (w[1].from - w[0].to).length())
            .sum();
        passes + links
    }
}

/// Spans shorter than this are not worth a pass (the brushes sweep them from the
/// neighbouring passes or not at all), m.
const MIN_SPAN: f64 = 0.2;
/// The widest obstacle (grown by the clearance) a pass goes round rather than ending at:
/// a bin, a post, a bench end, m.
const DETOUR: f64 = 2.5;
/// Directions closer than this are the same, rad (1°).
const SAME_DIRECTION: f64 = 0.0175;

/// What the planner works on, turned so the passes run along x.
struct Turned {
    polygon: Vec<DVec2>,
    obstacles: Vec<Obstacle>,
}

fn rotate(p: DVec2, angle: f64) -> DVec2 {
    DVec2::from_angle(angle).rotate(p)
}

fn turn_obstacle(o: &Obstacle, angle: f64) -> Obstacle {
    match o {
        Obstacle::Circle { center, radius } => Obstacle::Circle {
            center: rotate(*center, angle),
            radius: *radius,
        },
        Obstacle::Segment { a, b } => Obstacle::Segment {
            a: rotate(*a, angle),
            b: rotate(*b, angle),
        },
        Obstacle::Polygon { points } => Obstacle::Polygon {
            points: points.iter().map(|p| rotate(*p, angle)).collect(),
        },
    }
}

/// One scan line: its y, the spans the leader drives on it, and the gaps within them it
/// goes round.
struct Line {
    y: f64,
    spans: Vec<Span>,
    gaps: Vec<Span>,
}

impl Turned {
    fn new(polygon: &[DVec2], near: &[&Obstacle], angle: f64) -> Self {
        Self {
            polygon: polygon.iter().map(|p| rotate(*p, -angle)).collect(),
            obstacles: near.iter().map(|o| turn_obstacle(o, -angle)).collect(),
        }
    }

    /// Where the leader may not be on the line at `y`.
    fn blocked(&self, y: f64, clearance: f64) -> Vec<Span> {
        let mut out = Vec::new();
        for o in &self.obstacles {
            let [lo, hi] = o.bounds();
            if y > lo.y - clearance && y < hi.y + clearance {
                blocked_by(o, clearance, y, &mut out);
            }
        }
        merged(out)
    }

    /// The scan lines, evenly spaced, the first and last half a swath inside.
    fn lines(&self, p: &SweepParams) -> Vec<Line> {
        let lo = self
            .polygon
            .iter()
            .map(|q| q.y)
            .fold(f64::INFINITY, f64::min);
        let hi = self
            .polygon
            .iter()
            .map(|q| q.y)
            .fold(f64::NEG_INFINITY, f64::max);
        let (first, last) = (lo + 0.5 * p.swath, hi - 0.5 * p.swath);
        let ys: Vec<f64> = if last <= first {
            vec![0.5 * (lo + hi)]
        } else {
            let n = ((last - first) / p.spacing).ceil() as usize + 1;
            (0..n)
                .map(|k| first + (last - first) * k as f64 / (n - 1) as f64)
                .collect()
        };
        let band = 0.45 * p.swath;
        ys.into_iter()
            .map(|y| {
                let area = merged(
                    [y - band, y, y + band]
                        .iter()
                        .flat_map(|&v| inside(&self.polygon, v))
                        .collect(),
                );
                let blocked = self.blocked(y, p.clearance);
                let mut gaps = Vec::new();
                let spans = area
                    .iter()
                    .flat_map(|a| around_small(subtract(&[*a], &blocked), &mut gaps))
                    .filter(|s| s.1 - s.0 >= MIN_SPAN)
                    .collect();
                Line { y, spans, gaps }
            })
            .collect()
    }
}

/// `spans` of one stretch of the area joined across gaps of at most [`DETOUR`]: a pass
/// goes round a bin or a post (the station's route does), it is not split in two.
/// The gaps joined go to `gaps`.
fn around_small(spans: Vec<Span>, gaps: &mut Vec<Span>) -> Vec<Span> {
    let mut out: Vec<Span> = Vec::with_capacity(spans.len());
    for s in spans {
        match out.last_mut() {
            Some(last) if s.0 - last.1 <= DETOUR => {
                gaps.push((last.1, s.0));
                last.1 = s.1;
            }
            _ => out.push(s),
        }
    }
    out
}

/// A cell: (line, span) in line order.
type Cell = Vec<(usize, Span)>;

/// Spans of neighbouring lines that overlap one to one, chained into cells.
fn cells(lines: &[Line]) -> Vec<Cell> {
    let overlap = |a: Span, b: Span| a.0 < b.1 && b.0 < a.1;
    let mut cells: Vec<Cell> = Vec::new();
    let mut open: Vec<(Span, usize)> = Vec::new();
    for (k, line) in lines.iter().enumerate() {
        let mut next = Vec::new();
        for &s in &line.spans {
            let above: Vec<&(Span, usize)> = open.iter().filter(|(o, _)| overlap(*o, s)).collect();
            let one_to_one = above.len() == 1
                && line
                    .spans
                    .iter()
                    .filter(|t| overlap(above[0].0, **t))
                    .count()
                    == 1;
            let cell = if one_to_one {
                above[0].1
            } else {
                cells.push(Vec::new());
                cells.len() - 1
            };
            cells[cell].push((k, s));
            next.push((s, cell));
        }
        open = next;
    }
    cells
}

/// The cells swept nearest first from `at`, back and forth within each: the passes, in
/// the turned frame.
fn order(cells: &[Cell], lines: &[Line], mut at: DVec2) -> Vec<Pass> {
    let mut left: Vec<usize> = (0..cells.len()).collect();
    let mut passes = Vec::new();
    while !left.is_empty() {
        // Each cell's four corners: (first or last line, left or right end).
        let corner = |c: &Cell, last: bool, right: bool| {
            let (k, s) = if last { c[c.len() - 1] } else { c[0] };
            DVec2::new(if right { s.1 } else { s.0 }, lines[k].y)
        };
        let (i, last, right) = left
            .iter()
            .enumerate()
            .flat_map(|(i, &c)| {
                [(false, false), (false, true), (true, false), (true, true)]
                    .map(|(l, r)| (i, l, r, corner(&cells[c], l, r).distance(at)))
            })
            .min_by(|a, b| a.3.total_cmp(&b.3))
            .map(|(i, l, r, _)| (i, l, r))
            .expect("a cell is left");
        let cell = &cells[left.swap_remove(i)];
        let mut rightward = !right;
        let rows: Vec<&(usize, Span)> = if last {
            cell.iter().rev().collect()
        } else {
            cell.iter().collect()
        };
        for &&(k, (lo, hi)) in &rows {
            let y = lines[k].y;
            let mut round: Vec<DVec2> = lines[k]
                .gaps
                .iter()
                .filter(|g| g.0 > lo && g.1 < hi)
                .flat_map(|g| [DVec2::new(g.0, y), DVec2::new(g.1, y)])
                .collect();
            let (a, b) = if rightward { (lo, hi) } else { (hi, lo) };
            if !rightward {
                round.reverse();
            }
            passes.push(Pass {
                from: DVec2::new(a, y),
                round,
                to: DVec2::new(b, y),
            });
            rightward = !rightward;
        }
        at = passes.last().map_or(at, |p| p.to);
    }
    passes
}

/// Each pass run on past its end by up to `trail`, where the line has room for the leader
/// (the area's edge is not a wall; what the map holds is), so the trailing brushes reach
/// the edge; at its start they come in behind the leader anyway.
fn run_on(turned: &Turned, passes: &mut [Pass], p: &SweepParams) {
    for Pass { from: a, to: b, .. } in passes.iter_mut() {
        let a = &*a;
        let room = subtract(
            &[(f64::NEG_INFINITY, f64::INFINITY)],
            &turned.blocked(a.y, p.clearance),
        );
        let within = |x: f64| {
            room.iter()
                .find(|r| r.0 <= x + 1e-9 && r.1 >= x - 1e-9)
                .copied()
        };
        let sign = (b.x - a.x).signum();
        if let Some((lo, hi)) = within(b.x) {
            b.x = (b.x + sign * p.trail).clamp(lo, hi);
        }
    }
}

/// The directions worth trying: along each edge of `polygon` (or the one given).
fn directions(polygon: &[DVec2], given: Option<f64>) -> Vec<f64> {
    if let Some(d) = given {
        return vec![d];
    }
    let mut out: Vec<f64> = Vec::new();
    for i in 0..polygon.len() {
        let e = polygon[(i + 1) % polygon.len()] - polygon[i];
        let a = e.y.atan2(e.x).rem_euclid(std::f64::consts::PI);
        let same = |b: &f64| {
            let d = (a - b).abs();
            d.min(std::f64::consts::PI - d) < SAME_DIRECTION
        };
        if e.length() > 1e-6 && !out.iter().any(same) {
            out.push(a);
        }
    }
    out
}

/// The coverage route of the area `polygon` on `map`, starting nearest `from`.
pub fn plan_area(polygon: &[DVec2], map: &Map, p: &SweepParams, from: DVec2) -> AreaPlan {
    let lo = polygon.iter().fold(DVec2::INFINITY, |m, q| m.min(*q));
    let hi = polygon.iter().fold(DVec2::NEG_INFINITY, |m, q| m.max(*q));
    let reach = 0.5 * (hi - lo).length() + p.clearance + p.trail + p.swath;
    let near: Vec<&Obstacle> = map.near(0.5 * (lo + hi), reach).collect();
    let best = directions(polygon, p.direction)
        .into_iter()
        .map(|angle| {
            let turned = Turned::new(polygon, &near, angle);
            let lines = turned.lines(p);
            let passes: usize = lines.iter().map(|l| l.spans.len()).sum();
            let length: f64 = lines.iter().flat_map(|l| &l.spans).map(|s| s.1 - s.0).sum();
            (angle, turned, lines, passes, length)
        })
        .min_by(|a, b| a.3.cmp(&b.3).then(a.4.total_cmp(&b.4)));
    let Some((angle, turned, lines, _, _)) = best else {
        return AreaPlan {
            direction: 0.0,
            passes: Vec::new(),
            cells: 0,
        };
    };
    let cells = cells(&lines);
    let mut passes = order(&cells, &lines, rotate(from, -angle));
    run_on(&turned, &mut passes, p);
    AreaPlan {
        direction: angle,
        passes: passes
            .into_iter()
            .map(|p| Pass {
                from: rotate(p.from, angle),
                round: p.round.iter().map(|q| rotate(*q, angle)).collect(),
                to: rotate(p.to, angle),
            })
            .collect(),
        cells: cells.len(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> SweepParams {
        SweepParams {
            swath: 2.0,
            spacing: 1.8,
            clearance: 0.4,
            trail: 1.0,
            direction: None,
        }
    }

    fn rect(w: f64, h: f64) -> Vec<DVec2> {
        vec![
            DVec2::ZERO,
            DVec2::new(w, 0.0),
            DVec2::new(w, h),
            DVec2::new(0.0, h),
        ]
    }

    #[test]
    fn an_open_yard_is_swept_along_its_long_side_back_and_forth() {
        let plan = plan_area(
            &rect(40.0, 10.0),
            &Map::new(Vec::new()),
            &params(),
            DVec2::ZERO,
        );
        assert_eq!(plan.cells, 1);
        // (10 - 2) / 1.8 → 5 gaps, 6 passes, along x.
        assert_eq!(plan.passes.len(), 6);
        assert!(plan.direction.sin().abs() < 1e-9);
        for (k, w) in plan.passes.windows(2).enumerate() {
            let (d0, d1) = (w[0].to - w[0].from, w[1].to - w[1].from);
            assert!(d0.dot(d1) < 0.0, "pass {k} and the next go opposite ways");
            assert!((w[1].from.y - w[0].to.y).abs() <= 1.8 + 1e-9);
        }
        // Each starts at the edge and runs on past the other by the trail (open area).
        for p in &plan.passes {
            let east = p.to.x > p.from.x;
            assert_eq!(p.from.x, if east { 0.0 } else { 40.0 }, "{p:?}");
            assert_eq!(p.to.x, if east { 41.0 } else { -1.0 }, "{p:?}");
        }
        assert!((plan.passes[0].from.y - 1.0).abs() < 1e-9);
    }

    #[test]
    fn a_block_in_the_middle_splits_the_yard_into_cells() {
        let block = Obstacle::rectangle(DVec2::new(15.0, 4.0), DVec2::new(25.0, 16.0));
        let map = Map::new(vec![block]);
        let plan = plan_area(&rect(40.0, 20.0), &map, &params(), DVec2::ZERO);
        assert!(plan.cells >= 4, "{} cells", plan.cells);
        for p in &plan.passes {
            for t in 0..=20 {
                let q = p.from.lerp(p.to, t as f64 / 20.0);
                assert!(map.clearance(q, 1.0) >= 0.4 - 1e-6, "{q} on {p:?}");
            }
        }
    }

    #[test]
    fn a_bin_in_the_way_is_gone_round_not_split() {
        let bin = Obstacle::Circle {
            center: DVec2::new(20.0, 5.0),
            radius: 0.4,
        };
        let plan = plan_area(
            &rect(40.0, 10.0),
            &Map::new(vec![bin]),
            &params(),
            DVec2::ZERO,
        );
        assert_eq!(plan.cells, 1);
        assert_eq!(plan.passes.len(), 6);
        // The pass through the bin leaves the line before it and rejoins after.
        let through: Vec<&Pass> = plan.passes.iter().filter(|p| !p.round.is_empty()).collect();
        assert!(!through.is_empty());
        for p in through {
            let xs: Vec<f64> = p.points().map(|q| q.x).collect();
            assert!(
                xs.windows(2).all(|w| (w[1] - w[0]) * (xs[1] - xs[0]) > 0.0),
                "{xs:?}"
            );
        }
    }

    #[test]
    fn a_slanted_strip_is_swept_along_its_slant() {
        let angle: f64 = 0.5;
        let strip: Vec<DVec2> = rect(30.0, 4.0).iter().map(|p| rotate(*p, angle)).collect();
        let plan = plan_area(&strip, &Map::new(Vec::new()), &params(), DVec2::ZERO);
        assert!((plan.direction - angle).abs() < 1e-9, "{}", plan.direction);
        // 4 m: two swaths of 2 m would leave no overlap; 1.8 m apart takes three.
        assert_eq!(plan.passes.len(), 3);
    }
}
