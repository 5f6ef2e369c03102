//! The global layer: a route over the known site map, planned before the start and again
//! when the way is blocked.
//!
//! **Method: A\* on a clearance grid, then string-pulling.** The map becomes a grid of
//! cells (0.1 m) holding each cell centre's exact distance to the nearest obstacle surface
//! (capped at a few metres; computed per obstacle over its neighbourhood, so the cost grows
//! with the obstacles, not with the empty site). A\* runs 8-connected over it:
//!
//! - a cell closer than `hard_clearance` (footprint + a margin) is blocked: the line of
//!   robots, driving the leader's path, fits wherever the route goes, down to passages of
//!   footprint + 2 × 0.1 m;
//! - each metre costs 1, plus `narrow_penalty` where the wide formation would not fit
//!   (clearance under `wide_clearance`), plus `narrow_entry` once per entry into such a
//!   stretch (it costs two shape changes), plus a term growing toward the walls up to
//!   `soft_clearance`: the route takes the wide way unless the line-only passage is much
//!   shorter, and keeps to the middle of whatever it drives through.
//!
//! Why this and not a visibility graph or hybrid A\*: the clearance grid gives the width
//! of the way everywhere at once (what the formation needs: one lookup), works for any
//! obstacle shape, and its A\* is bounded by the cells (≤ `MAX_CELLS`); the leader's APF
//! layer smooths the corners a diff-drive robot cannot take on the spot, so a kinematic
//! search buys little here. The grid path is then shortened (string pulling) as long as a
//! shortcut keeps the clearance class of the cells it replaces.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use glam::DVec2;

use crate::formation::FormationSpec;
use crate::map::Map;

/// Most cells of a grid; larger sites get coarser cells.
pub const MAX_CELLS: usize = 4_000_000;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RouteParams {
    /// Grid cell, m.
    pub cell: f64,
    /// Below this clearance a cell is blocked (footprint + margin), m.
    pub hard_clearance: f64,
    /// The wide formation fits at or above this clearance, m.
    pub wide_clearance: f64,
    /// Extra cost per metre where only the line fits.
    pub narrow_penalty: f64,
    /// Extra cost of entering a stretch where only the line fits (two shape changes and
    /// the slow driving around them), m.
    pub narrow_entry: f64,
    /// Clearance the route prefers everywhere, m.
    pub soft_clearance: f64,
    /// Extra cost per metre at `hard_clearance`, falling to 0 at `soft_clearance`.
    pub wall_penalty: f64,
    /// Grid margin around the obstacles, starts and waypoints, m.
    pub border: f64,
}

impl RouteParams {
    /// For the robots and the wide shape of `formation`.
    pub fn for_formation(formation: &FormationSpec) -> Self {
        Self::for_fleet(
            formation.footprint,
            formation.wide_width(),
            formation.margin,
        )
    }

    /// For a robot of `footprint` radius and a wide formation of `wide_width` (footprints
    /// included) needing `margin` beside it.
    pub fn for_fleet(footprint: f64, wide_width: f64, margin: f64) -> Self {
        // A quarter metre over what the formation manager asks, for the leader's tracking.
        let wide_clearance = 0.5 * (wide_width + margin) + 0.25;
        Self {
            cell: 0.1,
            hard_clearance: footprint + 0.04,
            wide_clearance,
            narrow_penalty: 1.0,
            narrow_entry: 15.0,
            soft_clearance: wide_clearance.max(footprint + 1.0),
            wall_penalty: 2.0,
            border: 5.0,
        }
    }
}

/// Where a grid lies: its first cell centre, its cell size and its cells along x and y.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Extent {
    origin: DVec2,
    cell: f64,
    nx: usize,
    ny: usize,
}

impl Extent {
    /// Over `[lo, hi]` with cells of at least `cell` (coarser if the area needs more than
    /// `MAX_CELLS`).
    pub fn new(lo: DVec2, hi: DVec2, cell: f64) -> Self {
        let size = (hi - lo).max(DVec2::splat(cell));
        let cell = cell.max((size.x * size.y / MAX_CELLS as f64).sqrt());
        Self {
            origin: lo,
            cell,
            nx: (size.x / cell).ceil() as usize + 1,
            ny: (size.y / cell).ceil() as usize + 1,
        }
    }

    /// Whether `p` lies at least `margin` inside.
    pub fn covers(&self, p: DVec2, margin: f64) -> bool {
        let hi = self.origin + DVec2::new((self.nx - 1) as f64, (self.ny - 1) as f64) * self.cell;
        p.x >= self.origin.x + margin
            && p.y >= self.origin.y + margin
            && p.x <= hi.x - margin
            && p.y <= hi.y - margin
    }
}

/// The distance from each cell centre to the nearest obstacle surface (0 inside), capped.
#[derive(Debug, Clone)]
pub struct ClearanceGrid {
    origin: DVec2,
    cell: f64,
    nx: usize,
    ny: usize,
    cap: f32,
    clear: Vec<f32>,
}

impl ClearanceGrid {
    /// The grid over `extent`, clearances exact at the centres up to `cap`.
    pub fn build(map: &Map, extent: Extent, cap: f64) -> Self {
        let Extent {
            origin: lo,
            cell,
            nx,
            ny,
        } = extent;
        let mut clear = vec![cap as f32; nx * ny];
        for o in map.obstacles() {
            let [blo, bhi] = o.bounds();
            let i0 = (((blo.x - cap - lo.x) / cell).floor().max(0.0)) as usize;
            let j0 = (((blo.y - cap - lo.y) / cell).floor().max(0.0)) as usize;
            let i1 = ((((bhi.x + cap - lo.x) / cell).ceil()) as usize).min(nx - 1);
            let j1 = ((((bhi.y + cap - lo.y) / cell).ceil()) as usize).min(ny - 1);
            for j in j0..=j1 {
                let y = lo.y + j as f64 * cell;
                for i in i0..=i1 {
                    let p = DVec2::new(lo.x + i as f64 * cell, y);
                    let d = o.nearest(p).distance.max(0.0) as f32;
                    let c = &mut clear[j * nx + i];
                    if d < *c {
                        *c = d;
                    }
                }
            }
        }
        Self {
            origin: lo,
            cell,
            nx,
            ny,
            cap: cap as f32,
            clear,
        }
    }

    pub fn extent(&self) -> Extent {
        Extent {
            origin: self.origin,
            cell: self.cell,
            nx: self.nx,
            ny: self.ny,
        }
    }

    pub fn cell_size(&self) -> f64 {
        self.cell
    }

    fn index(&self, p: DVec2) -> Option<usize> {
        let q = (p - self.origin) / self.cell;
        let (i, j) = (q.x.round(), q.y.round());
        (i >= 0.0 && j >= 0.0 && (i as usize) < self.nx && (j as usize) < self.ny)
            .then(|| j as usize * self.nx + i as usize)
    }

    fn centre(&self, k: usize) -> DVec2 {
        self.origin + DVec2::new((k % self.nx) as f64, (k / self.nx) as f64) * self.cell
    }

    /// Clearance at the cell containing `p`; 0 outside the grid (the route stays in it).
    pub fn at(&self, p: DVec2) -> f64 {
        self.index(p).map_or(0.0, |k| self.clear[k] as f64)
    }

    pub fn cap(&self) -> f64 {
        self.cap as f64
    }
}

/// A planned route: a polyline and, per vertex, the least clearance of the way to the next.
#[derive(Debug, Clone, PartialEq)]
pub struct Route {
    pub points: Vec<DVec2>,
    /// Arc length at each point, m.
    pub arc: Vec<f64>,
}

impl Route {
    pub fn new(points: Vec<DVec2>) -> Self {
        let mut arc = Vec::with_capacity(points.len());
        let mut s = 0.0;
        for (i, p) in points.iter().enumerate() {
            if i > 0 {
                s += (*p - points[i - 1]).length();
            }
            arc.push(s);
        }
        Self { points, arc }
    }

    pub fn length(&self) -> f64 {
        self.arc.last().copied().unwrap_or(0.0)
    }

    /// The point at arc length `s` (clamped to the route).
    pub fn point_at(&self, s: f64) -> DVec2 {
        let Some(&first) = self.points.first() else {
            return DVec2::ZERO;
        };
        if s <= 0.0 {
            return first;
        }
        let k = self.arc.partition_point(|a| *a < s);
        if k >= self.points.len() {
            return *self.points.last().expect("not empty");
        }
        let (a, b) = (self.points[k - 1], self.points[k]);
        let seg = self.arc[k] - self.arc[k - 1];
        if seg < 1e-12 {
            return b;
        }
        a.lerp(b, (s - self.arc[k - 1]) / seg)
    }

    /// The unit direction of the route at arc length `s`.
    pub fn tangent_at(&self, s: f64) -> DVec2 {
        let k = self
            .arc
            .partition_point(|a| *a <= s)
            .clamp(1, self.points.len().max(2) - 1);
        if self.points.len() < 2 {
            return DVec2::ZERO;
        }
        (self.points[k] - self.points[k - 1]).normalize_or_zero()
    }

    /// The arc length of the point of the route nearest `p` within `[from, to]`.
    pub fn project(&self, p: DVec2, from: f64, to: f64) -> f64 {
        let mut best = (f64::INFINITY, from.clamp(0.0, self.length()));
        for k in 1..self.points.len() {
            if self.arc[k] < from || self.arc[k - 1] > to {
                continue;
            }
            let (a, b) = (self.points[k - 1], self.points[k]);
            let ab = b - a;
            let len2 = ab.length_squared();
            let t = if len2 > 0.0 {
                ((p - a).dot(ab) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let s = (self.arc[k - 1] + t * len2.sqrt()).clamp(from, to);
            let d = (self.point_at(s) - p).length_squared();
            if d < best.0 {
                best = (d, s);
            }
        }
        best.1
    }

    /// Points every `step` metres from arc length `from` for `length` metres.
    pub fn sample(&self, from: f64, length: f64, step: f64) -> Vec<DVec2> {
        let n = (length / step).ceil().max(0.0) as usize;
        (0..=n)
            .map(|i| from + i as f64 * step)
            .take_while(|s| *s <= self.length() + 1e-9)
            .map(|s| self.point_at(s))
            .collect()
    }
}

/// Why no route was found.
#[derive(Debug, Clone, PartialEq)]
pub enum NoRoute {
    /// The target lies where the robot does not fit (inside or against an obstacle).
    TargetBlocked { target: DVec2, clearance: f64 },
    /// The start lies inside an obstacle.
    StartBlocked { start: DVec2 },
    /// Nothing connects them: `closest` is the nearest the robot can get to the target.
    Unreachable { target: DVec2, closest: DVec2 },
}

impl std::fmt::Display for NoRoute {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NoRoute::TargetBlocked { target, clearance } => write!(
                f,
                "({:.2}, {:.2}) is {clearance:.2} m from an obstacle: the robot does not fit there",
                target.x, target.y
            ),
            NoRoute::StartBlocked { start } => {
                write!(
                    f,
                    "the start ({:.2}, {:.2}) is inside an obstacle",
                    start.x, start.y
                )
            }
            NoRoute::Unreachable { target, closest } => write!(
                f,
                "no way to ({:.2}, {:.2}) wide enough for the line of robots; the way is \
                 blocked near ({:.2}, {:.2}), the closest the fleet can get",
                target.x, target.y, closest.x, closest.y
            ),
        }
    }
}

/// The route planner: the clearance grid of the site map and the cost model.
#[derive(Debug, Clone)]
pub struct RoutePlanner {
    pub params: RouteParams,
    grid: ClearanceGrid,
}

const NEIGHBOURS: [(i64, i64, f64); 8] = [
    (1, 0, 1.0),
    (-1, 0, 1.0),
    (0, 1, 1.0),
    (0, -1, 1.0),
    (1, 1, std::f64::consts::SQRT_2),
    (1, -1, std::f64::consts::SQRT_2),
    (-1, 1, std::f64::consts::SQRT_2),
    (-1, -1, std::f64::consts::SQRT_2),
];

impl RoutePlanner {
    /// A planner over `map`, its grid covering the obstacles and `points` (starts,
    /// waypoints) with `params.border` around.
    pub fn new(map: &Map, points: &[DVec2], params: RouteParams) -> Self {
        let cap = params.soft_clearance.max(params.wide_clearance) + params.cell;
        let grid = ClearanceGrid::build(map, Self::extent(map, points, &params), cap);
        Self { params, grid }
    }

    /// The grid [`RoutePlanner::new`] would build for `map` and `points` (cheap: bounds
    /// only).
    pub fn extent(map: &Map, points: &[DVec2], params: &RouteParams) -> Extent {
        let mut lo = DVec2::splat(f64::INFINITY);
        let mut hi = DVec2::splat(f64::NEG_INFINITY);
        for p in points {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        for o in map.obstacles() {
            let [a, b] = o.bounds();
            lo = lo.min(a);
            hi = hi.max(b);
        }
        if !lo.is_finite() {
            lo = DVec2::ZERO;
            hi = DVec2::ZERO;
        }
        let border = DVec2::splat(params.border);
        Extent::new(lo - border, hi + border, params.cell)
    }

    pub fn grid(&self) -> &ClearanceGrid {
        &self.grid
    }

    /// Whether the grid covers `p` with a border of a few metres.
    pub fn covers(&self, p: DVec2) -> bool {
        self.grid.extent().covers(p, 0.5 * self.params.border)
    }

    /// Clearance at `p` from the grid, m.
    pub fn clearance(&self, p: DVec2) -> f64 {
        self.grid.at(p)
    }

    /// Extra cost per metre of a cell with clearance `c` (∞ when blocked).
    fn penalty(&self, c: f64) -> f64 {
        let p = &self.params;
        if c < p.hard_clearance {
            return f64::INFINITY;
        }
        let narrow = if c < p.wide_clearance {
            p.narrow_penalty
        } else {
            0.0
        };
        let span = (p.soft_clearance - p.hard_clearance).max(1e-6);
        let wall = ((p.soft_clearance - c) / span).clamp(0.0, 1.0);
        1.0 + narrow + p.wall_penalty * wall * wall
    }

    /// A route from `start` to `target`; `blocked`: extra discs (centre, radius) the route
    /// must avoid (sensed obstacles, a way found blocked).
    pub fn plan(
        &self,
        start: DVec2,
        target: DVec2,
        blocked: &[(DVec2, f64)],
    ) -> Result<Route, NoRoute> {
        let g = &self.grid;
        let hard = self.params.hard_clearance;
        let inside_blocked = |p: DVec2| blocked.iter().any(|(c, r)| (p - *c).length() < *r);
        let clearance_with = |p: DVec2| {
            let mut c = g.at(p);
            for (centre, r) in blocked {
                c = c.min(((p - *centre).length() - r).max(0.0));
            }
            c
        };
        let Some(s) = g.index(start) else {
            return Err(NoRoute::StartBlocked { start });
        };
        if g.clear[s] <= 0.0 {
            return Err(NoRoute::StartBlocked { start });
        }
        let Some(t) = g.index(target) else {
            return Err(NoRoute::TargetBlocked {
                target,
                clearance: 0.0,
            });
        };
        let tc = clearance_with(target);
        if tc < hard {
            return Err(NoRoute::TargetBlocked {
                target,
                clearance: tc,
            });
        }
        // Cells near the start may be tighter than the margin (a robot starting by a bin):
        // it may leave through them as long as it does not touch.
        let start_c = g.clear[s] as f64;
        let escape_radius = 1.5;
        let n = g.nx * g.ny;
        let mut cost = vec![f32::INFINITY; n];
        let mut parent = vec![u32::MAX; n];
        let mut open = BinaryHeap::new();
        let h = |k: usize| {
            let d = (g.centre(k) - g.centre(t)).abs();
            (d.x.max(d.y) + (std::f64::consts::SQRT_2 - 1.0) * d.x.min(d.y)) as f32
        };
        cost[s] = 0.0;
        open.push(Reverse((OrdF32(h(s)), s as u32)));
        let mut closest = (f64::INFINITY, s);
        while let Some(Reverse((OrdF32(f), k))) = open.pop() {
            let k = k as usize;
            if f - h(k) > cost[k] + 1e-3 {
                continue;
            }
            let d_target = (g.centre(k) - target).length();
            if d_target < closest.0 {
                closest = (d_target, k);
            }
            if k == t {
                break;
            }
            let (i, j) = ((k % g.nx) as i64, (k / g.nx) as i64);
            for (di, dj, len) in NEIGHBOURS {
                let (ni, nj) = (i + di, j + dj);
                if ni < 0 || nj < 0 || ni >= g.nx as i64 || nj >= g.ny as i64 {
                    continue;
                }
                let m = nj as usize * g.nx + ni as usize;
                let p = g.centre(m);
                let c = g.clear[m] as f64;
                let near_start = (p - start).length() < escape_radius;
                let mut step = self.penalty(c);
                if !step.is_finite() && near_start && c >= start_c.min(hard) - 1e-6 && c > 0.0 {
                    step = 1.0 + self.params.narrow_penalty + self.params.wall_penalty;
                }
                if !step.is_finite() || (!blocked.is_empty() && inside_blocked(p)) {
                    continue;
                }
                let extra = if blocked.is_empty() {
                    0.0
                } else {
                    self.penalty(clearance_with(p)).min(4.0) - self.penalty(c).min(4.0)
                };
                let wide = self.params.wide_clearance;
                let entry = if c < wide && (g.clear[k] as f64) >= wide {
                    self.params.narrow_entry
                } else {
                    0.0
                };
                let ng = cost[k] + ((step + extra.max(0.0)) * len * g.cell + entry) as f32;
                if ng < cost[m] {
                    cost[m] = ng;
                    parent[m] = k as u32;
                    open.push(Reverse((OrdF32(ng + h(m)), m as u32)));
                }
            }
        }
        if parent[t] == u32::MAX && s != t {
            return Err(NoRoute::Unreachable {
                target,
                closest: g.centre(closest.1),
            });
        }
        let mut cells = vec![t];
        while let Some(&k) = cells.last() {
            if k == s {
                break;
            }
            cells.push(parent[k] as usize);
        }
        cells.reverse();
        let mut points: Vec<DVec2> = cells.iter().map(|k| g.centre(*k)).collect();
        points[0] = start;
        *points.last_mut().expect("two ends") = target;
        Ok(Route::new(self.pull_strings(&points, &clearance_with)))
    }

    /// Shortens the grid path: a shortcut from point i to j replaces the cells between
    /// when every point along it keeps the least clearance those cells had (up to the
    /// preferred clearance), so the way stays as wide as the search chose.
    fn pull_strings(&self, path: &[DVec2], clearance: &dyn Fn(DVec2) -> f64) -> Vec<DVec2> {
        if path.len() < 3 {
            return path.to_vec();
        }
        let soft = self.params.soft_clearance;
        let step = 0.5 * self.grid.cell;
        let mut out = vec![path[0]];
        let mut i = 0;
        while i + 1 < path.len() {
            let mut best = i + 1;
            let mut class = clearance(path[i + 1]).min(soft);
            for j in i + 2..path.len() {
                class = class.min(clearance(path[j]).min(soft));
                let (a, b) = (path[i], path[j]);
                let n = ((b - a).length() / step).ceil() as usize;
                let ok = (1..n).all(|k| clearance(a.lerp(b, k as f64 / n as f64)) >= class - 1e-6);
                if !ok {
                    break;
                }
                best = j;
            }
            out.push(path[best]);
            i = best;
        }
        out
    }
}

/// An f32 that orders (the costs here are never NaN).
#[derive(Debug, Clone, Copy, PartialEq)]
struct OrdF32(f32);

impl Eq for OrdF32 {}

impl PartialOrd for OrdF32 {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for OrdF32 {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Obstacle;

    fn rect(lo: (f64, f64), hi: (f64, f64)) -> Obstacle {
        Obstacle::Polygon {
            points: vec![
                DVec2::new(lo.0, lo.1),
                DVec2::new(hi.0, lo.1),
                DVec2::new(hi.0, hi.1),
                DVec2::new(lo.0, hi.1),
            ],
        }
    }

    fn params() -> RouteParams {
        RouteParams::for_fleet(0.3, 3.6, 0.5)
    }

    /// A wall across x = 10 with one gap of `gap` m centred on y = 0.
    fn wall_with_gap(gap: f64) -> Map {
        Map::new(vec![
            rect((10.0, -30.0), (10.5, -gap / 2.0)),
            rect((10.0, gap / 2.0), (10.5, 30.0)),
        ])
    }

    fn min_clearance(route: &Route, map: &Map) -> f64 {
        route
            .sample(0.0, route.length(), 0.02)
            .iter()
            .map(|p| map.clearance(*p, 5.0))
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn a_gap_of_footprint_plus_two_tenths_is_usable() {
        let map = wall_with_gap(0.8);
        let rp = RoutePlanner::new(
            &map,
            &[DVec2::new(0.0, 0.0), DVec2::new(20.0, 0.0)],
            params(),
        );
        let route = rp
            .plan(DVec2::new(0.0, 0.0), DVec2::new(20.0, 0.0), &[])
            .expect("the 0.8 m gap is the way");
        assert!(route.length() < 21.0, "went round: {}", route.length());
        let c = min_clearance(&route, &map);
        assert!(c >= 0.3, "the route touches: clearance {c}");
    }

    #[test]
    fn a_door_narrower_than_the_robot_is_refused_and_named() {
        // A 20 × 20 m room around the start, its only door 0.6 m wide at x = 10.
        let map = Map::new(vec![
            rect((-10.0, -10.5), (10.5, -10.0)),
            rect((-10.0, 10.0), (10.5, 10.5)),
            rect((-10.5, -10.5), (-10.0, 10.5)),
            rect((10.0, -10.5), (10.5, -0.3)),
            rect((10.0, 0.3), (10.5, 10.5)),
        ]);
        let rp = RoutePlanner::new(
            &map,
            &[DVec2::new(0.0, 0.0), DVec2::new(20.0, 0.0)],
            params(),
        );
        match rp.plan(DVec2::new(0.0, 0.0), DVec2::new(20.0, 0.0), &[]) {
            Err(NoRoute::Unreachable { closest, .. }) => {
                assert!(closest.x < 10.0 && closest.x > 9.0, "{closest}")
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn prefers_the_wide_way_unless_the_narrow_one_is_much_shorter() {
        // A 1.5 m gap at y = 0 and a 6 m gap at y = 4: the wide one costs 1 m more.
        let map = Map::new(vec![
            rect((10.0, -30.0), (10.5, -0.75)),
            rect((10.0, 0.75), (10.5, 1.0)),
            rect((10.0, 7.0), (10.5, 30.0)),
        ]);
        let (a, b) = (DVec2::new(0.0, 0.0), DVec2::new(20.0, 0.0));
        let rp = RoutePlanner::new(&map, &[a, b], params());
        let route = rp.plan(a, b, &[]).unwrap();
        let at_wall = route.point_at(route.project(DVec2::new(10.25, 4.0), 0.0, 1e9));
        assert!(at_wall.y > 2.5, "took the narrow gap: {at_wall}");
    }

    #[test]
    fn a_goal_against_an_obstacle_or_boxed_in_is_refused() {
        let bin = Obstacle::Circle {
            center: DVec2::new(10.0, 0.0),
            radius: 0.5,
        };
        let map = Map::new(vec![bin]);
        let rp = RoutePlanner::new(&map, &[DVec2::ZERO], params());
        assert!(matches!(
            rp.plan(DVec2::ZERO, DVec2::new(10.6, 0.0), &[]),
            Err(NoRoute::TargetBlocked { .. })
        ));
        let boxed = Map::new(vec![
            rect((8.0, -2.0), (12.0, -1.8)),
            rect((8.0, 1.8), (12.0, 2.0)),
            rect((8.0, -2.0), (8.2, 2.0)),
            rect((11.8, -2.0), (12.0, 2.0)),
        ]);
        let rp = RoutePlanner::new(&boxed, &[DVec2::ZERO], params());
        assert!(matches!(
            rp.plan(DVec2::ZERO, DVec2::new(10.0, 0.0), &[]),
            Err(NoRoute::Unreachable { .. })
        ));
    }

    #[test]
    fn string_pulling_keeps_an_open_route_straight() {
        let map = Map::new(Vec::new());
        let (a, b) = (DVec2::new(0.0, 0.0), DVec2::new(17.0, 9.0));
        let rp = RoutePlanner::new(&map, &[a, b], params());
        let route = rp.plan(a, b, &[]).unwrap();
        assert_eq!(route.points.len(), 2, "{:?}", route.points);
        assert!((route.length() - (b - a).length()).abs() < 1e-9);
    }

    #[test]
    fn route_geometry() {
        let r = Route::new(vec![
            DVec2::ZERO,
            DVec2::new(2.0, 0.0),
            DVec2::new(2.0, 2.0),
        ]);
        assert_eq!(r.length(), 4.0);
        assert_eq!(r.point_at(3.0), DVec2::new(2.0, 1.0));
        assert_eq!(r.tangent_at(3.0), DVec2::Y);
        assert!((r.project(DVec2::new(3.0, 1.5), 0.0, 10.0) - 3.5).abs() < 1e-12);
        assert_eq!(r.sample(0.0, 4.0, 1.0).len(), 5);
    }
}
