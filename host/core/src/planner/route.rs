//! The global layer: a route over the known site map, planned before the start and again
//! when the way is blocked.
//!
//! **Method: A\* on a clearance grid, then string-pulling.** The map becomes a grid of
//! cells (0.1 m) holding each cell centre's distance to the nearest obstacle surface,
//! capped at a few metres: exact within a band around every obstacle (where the decision
//! "does the robot fit" is made), and beyond it a lower bound from a Euclidean distance
//! transform of the cells the surfaces cross (at most a cell's diagonal low, which only
//! makes the route a little more cautious about width). A\* runs 8-connected over it:
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

use std::borrow::Cow;
use std::cmp::Reverse;

use glam::DVec2;
use radix_heap::RadixHeapMap;

use crate::formation::FormationSpec;
use crate::geometry::map::Map;
use crate::geometry::Obstacle;

/// Most cells of a grid; larger sites get coarser cells.
pub const MAX_CELLS: usize = 4_000_000;
/// Cells × edges of a polygon measured the plain way at most; a larger or more detailed
/// one is stamped edge by edge ([`ClearanceGrid::stamp`]).
const POLYGON_WORK: f64 = 50e6;

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
        let mut cell = cell.max((size.x * size.y / MAX_CELLS as f64).sqrt());
        let cells = |cell: f64| ((size.x / cell).ceil() + 1.0) * ((size.y / cell).ceil() + 1.0);
        // A long thin area has more cells than its surface says (a row at least): coarser
        // until the count, not the surface, is within the budget.
        while cells(cell) > MAX_CELLS as f64 {
            cell *= 1.25;
        }
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
    /// The grid over `extent`: clearances exact up to `band` from the surfaces, a lower
    /// bound (by at most a cell's diagonal) beyond, all capped at `cap`.
    pub fn build(map: &Map, extent: Extent, band: f64, cap: f64) -> Self {
        let Extent { cell, nx, ny, .. } = extent;
        let mut grid = Self {
            origin: extent.origin,
            cell,
            nx,
            ny,
            cap: cap as f32,
            clear: vec![f32::INFINITY; nx * ny],
        };
        // A sparse map (the cells within `cap` of its obstacles fewer than the grid's):
        // every clearance exact out to the cap, no transform over the whole grid.
        let reach_cells: f64 = map
            .obstacles()
            .iter()
            .map(|o| {
                let [lo, hi] = o.bounds();
                let size = (hi - lo) + DVec2::splat(2.0 * cap);
                size.x * size.y / (cell * cell)
            })
            .sum();
        let half_diagonal = (cell * std::f64::consts::FRAC_1_SQRT_2) as f32;
        if reach_cells < (nx * ny) as f64 {
            for o in map.obstacles() {
                grid.stamp(o, cap);
            }
            // Beyond the band, as cautious as the transform's bound below (half a diagonal
            // under the exact value): the routes, and the shape changes along them, stay
            // those of dense maps (exact values let routes graze the wide formation's
            // clearance, and a bin on the start line then cost two needless changes).
            let (band, cap) = (band as f32, cap as f32);
            for c in &mut grid.clear {
                if *c > band {
                    *c = (*c - half_diagonal).max(band);
                }
                *c = c.min(cap);
            }
            return grid;
        }
        for o in map.obstacles() {
            grid.stamp(o, band);
        }
        // Cells a surface crosses seed the transform; beyond the band, the distance to the
        // nearest seed centre less half a diagonal is a lower bound of the true clearance.
        let seeds: Vec<bool> = grid.clear.iter().map(|c| *c <= half_diagonal).collect();
        let limit = (cap / cell + 2.0).powi(2) as f32;
        let squared = distance_transform(&seeds, nx, ny, limit);
        let (band, cap) = (band as f32, cap as f32);
        for (c, d2) in grid.clear.iter_mut().zip(squared) {
            if *c > band {
                let estimate = d2.sqrt() * cell as f32 - half_diagonal;
                *c = c.min(estimate).max(band);
            }
            *c = c.min(cap);
        }
        grid
    }

    /// The cells (i0..=i1, j0..=j1) of the box `[blo, bhi]` grown by `reach`.
    fn cells_of(&self, blo: DVec2, bhi: DVec2, reach: f64) -> (usize, usize, usize, usize) {
        let (lo, cell) = (self.origin, self.cell);
        let i0 = ((blo.x - reach - lo.x) / cell).floor().max(0.0) as usize;
        let j0 = ((blo.y - reach - lo.y) / cell).floor().max(0.0) as usize;
        let i1 = (((bhi.x + reach - lo.x) / cell).ceil().max(0.0) as usize).min(self.nx - 1);
        let j1 = (((bhi.y + reach - lo.y) / cell).ceil().max(0.0) as usize).min(self.ny - 1);
        (i0, i1, j0, j1)
    }

    /// Lowers the clearances within `reach` of `o` to the exact distance to it.
    pub fn stamp(&mut self, o: &Obstacle, reach: f64) {
        let (lo, cell) = (self.origin, self.cell);
        let [blo, bhi] = o.bounds();
        let (i0, i1, j0, j1) = self.cells_of(blo, bhi, reach);
        if let Obstacle::Polygon { points } = o {
            let work = (i1 + 1 - i0) as f64 * (j1 + 1 - j0) as f64 * points.len() as f64;
            if work > POLYGON_WORK {
                return self.stamp_large_polygon(points, reach);
            }
        }
        for j in j0..=j1 {
            let y = lo.y + j as f64 * cell;
            let row = &mut self.clear[j * self.nx..(j + 1) * self.nx];
            for (i, c) in row.iter_mut().enumerate().take(i1 + 1).skip(i0) {
                let p = DVec2::new(lo.x + i as f64 * cell, y);
                let d = o.nearest(p).distance.max(0.0) as f32;
                if d < *c {
                    *c = d;
                }
            }
        }
    }

    /// [`ClearanceGrid::stamp`] for a polygon too large or detailed to measure every
    /// edge from every cell of its box (a hostile or careless site file): each edge
    /// lowers only the cells within `reach` of it, and the cells inside are filled row by
    /// row (the crossing rule of `point_in_polygon`). Exact within `reach`; beyond it,
    /// cells keep what they had.
    fn stamp_large_polygon(&mut self, points: &[DVec2], reach: f64) {
        let (lo, cell, n) = (self.origin, self.cell, points.len());
        let piece = reach.max(cell);
        for k in 0..n {
            let (a, b) = (points[k], points[(k + 1) % n]);
            let pieces = ((b - a).length() / piece).ceil().max(1.0) as usize;
            for m in 0..pieces {
                let pa = a.lerp(b, m as f64 / pieces as f64);
                let pb = a.lerp(b, (m + 1) as f64 / pieces as f64);
                let (i0, i1, j0, j1) = self.cells_of(pa.min(pb), pa.max(pb), reach);
                for j in j0..=j1 {
                    for i in i0..=i1 {
                        let p = lo + DVec2::new(i as f64, j as f64) * cell;
                        let q = crate::geometry::closest_on_segment(p, a, b);
                        let d = (p - q).length() as f32;
                        let c = &mut self.clear[j * self.nx + i];
                        if d <= reach as f32 && d < *c {
                            *c = d;
                        }
                    }
                }
            }
        }
        let [blo, bhi] = Obstacle::Polygon {
            points: points.to_vec(),
        }
        .bounds();
        let (i0, i1, j0, j1) = self.cells_of(blo, bhi, 0.0);
        let mut crossings = Vec::new();
        for j in j0..=j1 {
            let y = lo.y + j as f64 * cell;
            crossings.clear();
            let mut prev = n - 1;
            for k in 0..n {
                let (a, b) = (points[k], points[prev]);
                if (a.y > y) != (b.y > y) {
                    crossings.push((b.x - a.x) * (y - a.y) / (b.y - a.y) + a.x);
                }
                prev = k;
            }
            crossings.sort_by(f64::total_cmp);
            for i in i0..=i1 {
                let x = lo.x + i as f64 * cell;
                // Inside when an odd number of crossings lie right of the cell's centre.
                let right = crossings.len() - crossings.partition_point(|c| *c <= x);
                if right % 2 == 1 {
                    self.clear[j * self.nx + i] = 0.0;
                }
            }
        }
    }

    /// Lowers the clearances near an obstacle that was not on the map (sensed), out to the
    /// cap.
    pub fn add(&mut self, o: &Obstacle) {
        self.stamp(o, self.cap as f64);
    }

    /// Raises the clearances near obstacles that are gone (sensed ones forgotten, or a
    /// person who walked on) to what `map`, which no longer holds them, gives there.
    /// Boxes that overlap are restored once, as their union: a track's marks are a
    /// cluster of points a few centimetres apart, and each point's box is most of the
    /// cluster's (restored point by point, that took a sixth of a crowd's run).
    pub fn restore_all(&mut self, gone: &[Obstacle], map: &Map) {
        let mut groups: Vec<([DVec2; 2], Vec<&Obstacle>)> = Vec::new();
        for o in gone {
            let (mut b, mut members) = (o.bounds(), vec![o]);
            // Fold every box it overlaps into it, until none does.
            while let Some(k) = groups.iter().position(|(c, _)| overlap(c, &b)) {
                let (c, more) = groups.swap_remove(k);
                b = [b[0].min(c[0]), b[1].max(c[1])];
                members.extend(more);
            }
            groups.push((b, members));
        }
        for (b, members) in groups {
            self.restore_box(b, &members, map);
        }
    }

    /// [`Self::restore_all`] over one box: only the cells one of `gone` was the nearest
    /// surface of (the rest keep what another surface gives them).
    fn restore_box(&mut self, [blo, bhi]: [DVec2; 2], gone: &[&Obstacle], map: &Map) {
        let (lo, cell, cap) = (self.origin, self.cell, self.cap as f64);
        let i0 = ((blo.x - cap - lo.x) / cell).floor().max(0.0) as usize;
        let j0 = ((blo.y - cap - lo.y) / cell).floor().max(0.0) as usize;
        let i1 = (((bhi.x + cap - lo.x) / cell).ceil().max(0.0) as usize).min(self.nx - 1);
        let j1 = (((bhi.y + cap - lo.y) / cell).ceil().max(0.0) as usize).min(self.ny - 1);
        for j in j0..=j1 {
            for i in i0..=i1 {
                let p = lo + DVec2::new(i as f64, j as f64) * cell;
                let k = j * self.nx + i;
                let was = self.clear[k] as f64;
                let nearest = gone
                    .iter()
                    .any(|o| o.nearest(p).distance <= was + RESTORE_SLACK_M);
                if nearest {
                    self.clear[k] = map.clearance(p, cap).max(0.0) as f32;
                }
            }
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

    /// The cell nearest to cell `k` with some clearance, no farther than `reach`.
    fn nearest_free(&self, k: usize, reach: f64) -> Option<usize> {
        let n = (reach / self.cell).ceil() as i64;
        let (i0, j0) = ((k % self.nx) as i64, (k / self.nx) as i64);
        let mut best: Option<(i64, usize)> = None;
        for j in (j0 - n).max(0)..=(j0 + n).min(self.ny as i64 - 1) {
            for i in (i0 - n).max(0)..=(i0 + n).min(self.nx as i64 - 1) {
                let d2 = (i - i0).pow(2) + (j - j0).pow(2);
                let c = j as usize * self.nx + i as usize;
                if d2 <= n * n && self.clear[c] > 0.0 && best.is_none_or(|(b, _)| d2 < b) {
                    best = Some((d2, c));
                }
            }
        }
        best.map(|(_, c)| c)
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

/// The octile distance of (di, dj) cells in metres: admissible and consistent for the
/// search (a metre costs at least 1). By column and row, which the expansion has at hand
/// (no division by the row length per neighbour).
fn octile(di: i64, dj: i64, cell: f32) -> f32 {
    let (di, dj) = (di.unsigned_abs() as f32, dj.unsigned_abs() as f32);
    (di.max(dj) + (std::f32::consts::SQRT_2 - 1.0) * di.min(dj)) * cell
}

/// The cells from `s` to `t` by their parents (`parent[k]`: k's parent + 1).
fn walk_back(parent: &[u32], s: usize, t: usize) -> Vec<usize> {
    let mut cells = vec![t];
    while let Some(&k) = cells.last() {
        if k == s {
            break;
        }
        cells.push(parent[k] as usize - 1);
    }
    cells.reverse();
    cells
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

const NEIGHBOURS: [(i64, i64, f32); 8] = [
    (1, 0, 1.0),
    (-1, 0, 1.0),
    (0, 1, 1.0),
    (0, -1, 1.0),
    (1, 1, std::f32::consts::SQRT_2),
    (1, -1, std::f32::consts::SQRT_2),
    (-1, 1, std::f32::consts::SQRT_2),
    (-1, -1, std::f32::consts::SQRT_2),
];

impl RoutePlanner {
    /// A planner over `map`, its grid covering the obstacles and `points` (starts,
    /// waypoints) with `params.border` around.
    pub fn new(map: &Map, points: &[DVec2], params: RouteParams) -> Self {
        let cap = params.soft_clearance.max(params.wide_clearance) + params.cell;
        // Exact where the robot's fit is decided, with room for a cell's error beyond.
        let band = params.hard_clearance + 3.0 * params.cell;
        let grid = ClearanceGrid::build(map, Self::extent(map, points, &params), band, cap);
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

    /// Adds an obstacle the map did not hold (sensed) to the grid.
    pub fn add_obstacle(&mut self, o: &Obstacle) {
        self.grid.add(o);
    }

    /// Takes sensed obstacles out of the grid again; `map`: what remains.
    pub fn remove_obstacles(&mut self, gone: &[Obstacle], map: &Map) {
        self.grid.restore_all(gone, map);
    }

    /// Extra cost per metre of a cell with clearance `c` (∞ when blocked).
    fn penalty(&self, c: f32) -> f32 {
        let p = &self.params;
        // Most cells are open (the soft clearance is at least the wide one): a metre there
        // costs a metre, without the arithmetic below on every neighbour of every step.
        if c as f64 >= p.soft_clearance {
            return 1.0;
        }
        let c = c as f64;
        if c < p.hard_clearance {
            return f32::INFINITY;
        }
        let narrow = if c < p.wide_clearance {
            p.narrow_penalty
        } else {
            0.0
        };
        let span = (p.soft_clearance - p.hard_clearance).max(1e-6);
        let wall = ((p.soft_clearance - c) / span).clamp(0.0, 1.0);
        (1.0 + narrow + p.wall_penalty * wall * wall) as f32
    }

    /// The clearances a plan from `start` sees: the grid's, with the `blocked` discs as
    /// obstacles and, when the start is tighter than the margin (a robot starting by a
    /// bin), the cells near it that it may leave through without touching made passable.
    fn clearances(&self, start: DVec2, blocked: &[(DVec2, f64)]) -> Cow<'_, [f32]> {
        let g = &self.grid;
        let hard = self.params.hard_clearance as f32;
        let start_c = g.at(start) as f32;
        if blocked.is_empty() && start_c >= hard {
            return Cow::Borrowed(&g.clear);
        }
        let mut field = g.clone();
        for (centre, r) in blocked {
            field.add(&Obstacle::Circle {
                center: *centre,
                radius: *r,
            });
        }
        if start_c < hard {
            let escape = 1.5;
            let lo = start - DVec2::splat(escape);
            let hi = start + DVec2::splat(escape);
            let (Some(a), Some(b)) = (g.index(lo.max(g.origin)), g.index(hi)) else {
                return Cow::Owned(field.clear);
            };
            let (i0, j0, i1, j1) = (a % g.nx, a / g.nx, b % g.nx, b / g.nx);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let k = j * g.nx + i;
                    let c = field.clear[k];
                    let near = (g.centre(k) - start).length() < escape;
                    if near && c > 0.0 && c >= start_c.min(hard) && c < hard {
                        field.clear[k] = hard;
                    }
                }
            }
        }
        Cow::Owned(field.clear)
    }

    /// A route from `start` to `target`; `blocked`: extra discs (centre, radius) the route
    /// must avoid like obstacles (a way found blocked).
    pub fn plan(
        &self,
        start: DVec2,
        target: DVec2,
        blocked: &[(DVec2, f64)],
    ) -> Result<Route, NoRoute> {
        let g = &self.grid;
        let (Some(s), Some(t)) = (g.index(start), g.index(target)) else {
            return Err(match g.index(start) {
                None => NoRoute::StartBlocked { start },
                Some(_) => NoRoute::TargetBlocked {
                    target,
                    clearance: 0.0,
                },
            });
        };
        // Inside a mark (a person who stopped beside the leader, marked with their
        // personal space round them): the way out is to the nearest free cell.
        let s = if g.clear[s] > 0.0 {
            s
        } else {
            g.nearest_free(s, STEP_OUT_M)
                .ok_or(NoRoute::StartBlocked { start })?
        };
        let clear = self.clearances(start, blocked);
        let tc = clear[t] as f64;
        if tc < self.params.hard_clearance {
            return Err(NoRoute::TargetBlocked {
                target,
                clearance: tc,
            });
        }
        let fine = Lattice {
            clear: &clear,
            nx: g.nx,
            ny: g.ny,
            cell: g.cell as f32,
        };
        // A coarse search first (a coarse cell blocked only where all its fine cells are,
        // so a fine way is always a coarse way; see `coarsen`), then the fine search inside
        // a corridor around the coarse route; the whole grid only when the corridor holds
        // no way.
        let hard = self.params.hard_clearance as f32;
        let coarse_clear = coarsen(&clear, g.nx, g.ny, COARSE, hard);
        let coarse = Lattice {
            clear: &coarse_clear,
            nx: g.nx.div_ceil(COARSE),
            ny: g.ny.div_ceil(COARSE),
            cell: g.cell as f32 * COARSE as f32,
        };
        let to_coarse = |k: usize| (k / g.nx / COARSE) * coarse.nx + (k % g.nx) / COARSE;
        let found = match self.search(&coarse, to_coarse(s), to_coarse(t), None) {
            Ok(way) => {
                let corridor = coarse.dilate(&way, CORRIDOR);
                let cnx = coarse.nx;
                let inside = |i: usize, j: usize| corridor[(j / COARSE) * cnx + i / COARSE];
                self.search(&fine, s, t, Some(&inside))
                    .or_else(|_| self.search(&fine, s, t, None))
            }
            Err(_) => self.search(&fine, s, t, None),
        };
        let cells = match found {
            Ok(cells) => cells,
            Err(closest) => {
                return Err(NoRoute::Unreachable {
                    target,
                    closest: g.centre(closest),
                })
            }
        };
        let mut points: Vec<DVec2> = cells.iter().map(|k| g.centre(*k)).collect();
        points[0] = start;
        *points.last_mut().expect("two ends") = target;
        let at = |p: DVec2| g.index(p).map_or(0.0, |k| clear[k] as f64);
        Ok(Route::new(self.pull_strings(&points, &at)))
    }

    /// A\* over `lattice` from cell `s` to `t`, through the cells (column, row) `inside`
    /// allows: the cells of the cheapest way, or the cell that came closest to `t`.
    fn search(
        &self,
        lattice: &Lattice,
        s: usize,
        t: usize,
        inside: Option<&dyn Fn(usize, usize) -> bool>,
    ) -> Result<Vec<usize>, usize> {
        let Lattice {
            clear,
            nx,
            ny,
            cell,
        } = *lattice;
        let wide = self.params.wide_clearance as f32;
        let entry = self.params.narrow_entry as f32;
        let (ti, tj) = ((t % nx) as i64, (t / nx) as i64);
        let h = |i: i64, j: i64| octile(i - ti, j - tj, cell);
        // Zeroed, so the allocator hands over fresh pages that only the cells the search
        // touches fault in (a corridor search on a large grid touches few): `parent` holds
        // a cell's parent + 1, 0 for none yet, and `cost` counts only where it is set.
        let mut cost = vec![0f32; clear.len()];
        let mut parent = vec![0u32; clear.len()];
        let reached = |parent: &[u32], m: usize| m == s || parent[m] != 0;
        // A monotone queue (the heuristic is consistent, so f never falls below the last
        // popped; a rounding step below is lifted to it) keyed by the f-cost's bits:
        // non-negative floats order as their bits. Ties pop last-in first.
        let mut open = RadixHeapMap::<Reverse<u32>, u32>::new();
        let push = |open: &mut RadixHeapMap<Reverse<u32>, u32>, f: f32, k: usize| {
            let floor = open.top().map_or(0, |Reverse(b)| b);
            open.push(Reverse(f.to_bits().max(floor)), k as u32);
        };
        cost[s] = 0.0;
        let (si, sj) = ((s % nx) as i64, (s / nx) as i64);
        push(&mut open, h(si, sj), s);
        let mut closest = (f32::INFINITY, s);
        let (nxi, nyi) = (nx as i64, ny as i64);
        while let Some((Reverse(f), k)) = open.pop() {
            let k = k as usize;
            let (i, j) = ((k % nx) as i64, (k / nx) as i64);
            let hk = h(i, j);
            if f32::from_bits(f) > cost[k] + hk + 1e-3 {
                continue;
            }
            if hk < closest.0 {
                closest = (hk, k);
            }
            if k == t {
                break;
            }
            let leaving_wide = clear[k] >= wide;
            for (di, dj, len) in NEIGHBOURS {
                let (ni, nj) = (i + di, j + dj);
                if ni < 0 || nj < 0 || ni >= nxi || nj >= nyi {
                    continue;
                }
                let m = (nj * nxi + ni) as usize;
                let c = clear[m];
                let step = self.penalty(c);
                if !step.is_finite()
                    || inside.is_some_and(|allowed| !allowed(ni as usize, nj as usize))
                {
                    continue;
                }
                let narrowing = if c < wide && leaving_wide { entry } else { 0.0 };
                let ng = cost[k] + step * len * cell + narrowing;
                if !reached(&parent, m) || ng < cost[m] {
                    cost[m] = ng;
                    parent[m] = k as u32 + 1;
                    push(&mut open, ng + h(ni, nj), m);
                }
            }
        }
        if !reached(&parent, t) {
            return Err(closest.1);
        }
        Ok(walk_back(&parent, s, t))
    }

    /// Shortens the grid path: a shortcut from point i to j replaces the points between
    /// when every point along it keeps the least clearance those points had (up to the
    /// preferred clearance), so the way stays as wide as the search chose. The farthest
    /// shortcut is found by doubling then halving the reach (a few segment checks per
    /// vertex, not one per point: linear-logarithmic in the route's length).
    fn pull_strings(&self, path: &[DVec2], clearance: &dyn Fn(DVec2) -> f64) -> Vec<DVec2> {
        if path.len() < 3 {
            return path.to_vec();
        }
        let soft = self.params.soft_clearance;
        let step = 0.5 * self.grid.cell;
        let class: Vec<f64> = path.iter().map(|p| clearance(*p).min(soft)).collect();
        let shortcut = |i: usize, j: usize| {
            let least = class[i + 1..j].iter().copied().fold(soft, f64::min);
            let (a, b) = (path[i], path[j]);
            let n = ((b - a).length() / step).ceil() as usize;
            (1..n).all(|k| clearance(a.lerp(b, k as f64 / n as f64)) >= least - 1e-6)
        };
        let last = path.len() - 1;
        let mut out = vec![path[0]];
        let mut i = 0;
        while i < last {
            // Doubling: the first reach that fails bounds the search.
            let mut ok = i + 1;
            let mut reach = 2;
            let mut fail = None;
            while ok < last {
                let j = (i + reach).min(last);
                if shortcut(i, j) {
                    ok = j;
                    reach *= 2;
                } else {
                    fail = Some(j);
                    break;
                }
            }
            // Halving between the last reach that held and the first that failed.
            if let Some(mut hi) = fail {
                while hi - ok > 1 {
                    let mid = (ok + hi) / 2;
                    if shortcut(i, mid) {
                        ok = mid;
                    } else {
                        hi = mid;
                    }
                }
            }
            out.push(path[ok]);
            i = ok;
        }
        out
    }
}

/// Fine cells per coarse cell side in the first search.
const COARSE: usize = 5;
/// A start inside a mark steps out to a free cell this near, m.
const STEP_OUT_M: f64 = 1.5;
/// Coarse cells either side of the coarse route that the fine search may use.
const CORRIDOR: usize = 3;

/// A grid of clearances to search.
#[derive(Clone, Copy)]
struct Lattice<'a> {
    clear: &'a [f32],
    nx: usize,
    ny: usize,
    cell: f32,
}

impl Lattice<'_> {
    /// The cells within `r` (Chebyshev) of `cells`.
    fn dilate(&self, cells: &[usize], r: usize) -> Vec<bool> {
        let mut mask = vec![false; self.nx * self.ny];
        for &k in cells {
            let (i, j) = (k % self.nx, k / self.nx);
            for jj in j.saturating_sub(r)..=(j + r).min(self.ny - 1) {
                for ii in i.saturating_sub(r)..=(i + r).min(self.nx - 1) {
                    mask[jj * self.nx + ii] = true;
                }
            }
        }
        mask
    }
}

/// Each `f` × `f` block's clearance for the coarse search: below `hard` (blocked) only if
/// every cell of it is, so a fine way is always a coarse way; otherwise its least clearance
/// (at least `hard`), so the coarse route costs a narrow line through the block as the fine
/// search will (its largest clearance let the coarse route slip through a gap one cell
/// thick that the fine route then paid a narrow entry for).
fn coarsen(clear: &[f32], nx: usize, ny: usize, f: usize, hard: f32) -> Vec<f32> {
    let cnx = nx.div_ceil(f);
    let blocks = cnx * ny.div_ceil(f);
    let (mut most, mut least) = (vec![0f32; blocks], vec![f32::INFINITY; blocks]);
    for (j, row) in clear.chunks(nx).enumerate() {
        let at = (j / f) * cnx;
        for (i, c) in row.iter().enumerate() {
            most[at + i / f] = most[at + i / f].max(*c);
            least[at + i / f] = least[at + i / f].min(*c);
        }
    }
    most.iter()
        .zip(least)
        .map(|(m, l)| if *m < hard { *m } else { l.max(hard) })
        .collect()
}

/// The squared distance, in cells, from each cell to the nearest seed, exact below `limit`
/// (at or above it, some value at or above it; ∞ without seeds): Felzenszwalb and
/// Huttenlocher's transform, columns then rows, both swept in memory order. A parabola at
/// or above `limit` cannot bring a cell below it, so rows far from every seed are skipped.
fn distance_transform(seeds: &[bool], nx: usize, ny: usize, limit: f32) -> Vec<f32> {
    let mut d = vec![f32::INFINITY; nx * ny];
    // Columns: the distance to the nearest seed above or below, by two sweeps over rows.
    let mut nearest = vec![f32::INFINITY; nx];
    for j in 0..ny {
        let row = &mut d[j * nx..(j + 1) * nx];
        for i in 0..nx {
            nearest[i] = if seeds[j * nx + i] {
                0.0
            } else {
                nearest[i] + 1.0
            };
            row[i] = nearest[i];
        }
    }
    nearest.fill(f32::INFINITY);
    for j in (0..ny).rev() {
        let row = &mut d[j * nx..(j + 1) * nx];
        for i in 0..nx {
            nearest[i] = if seeds[j * nx + i] {
                0.0
            } else {
                nearest[i] + 1.0
            };
            let v = row[i].min(nearest[i]);
            row[i] = v * v;
        }
    }
    // Rows: the lower envelope of the parabolas (x − q)² + f(q).
    let mut f = vec![0f32; nx];
    let mut v = vec![0usize; nx];
    let mut z = vec![0f32; nx + 1];
    for row in d.chunks_mut(nx) {
        f.copy_from_slice(row);
        let mut k: isize = -1;
        for q in 0..nx {
            if f[q] >= limit {
                continue;
            }
            let qf = q as f32;
            loop {
                if k < 0 {
                    k = 0;
                    v[0] = q;
                    z[0] = f32::NEG_INFINITY;
                    z[1] = f32::INFINITY;
                    break;
                }
                let p = v[k as usize];
                let pf = p as f32;
                let s = ((f[q] + qf * qf) - (f[p] + pf * pf)) / (2.0 * (qf - pf));
                if s <= z[k as usize] {
                    k -= 1;
                    continue;
                }
                k += 1;
                v[k as usize] = q;
                z[k as usize] = s;
                z[k as usize + 1] = f32::INFINITY;
                break;
            }
        }
        if k < 0 {
            continue;
        }
        let mut k = 0usize;
        for (x, out) in row.iter_mut().enumerate() {
            let xf = x as f32;
            while z[k + 1] < xf {
                k += 1;
            }
            let dx = xf - v[k] as f32;
            *out = dx * dx + f[v[k]];
        }
    }
    d
}

/// A cell's clearance within this of a removed obstacle's distance was (or may have
/// been, in f32) that obstacle's, m.
const RESTORE_SLACK_M: f64 = 1e-3;

/// Whether two boxes overlap (or touch).
fn overlap(a: &[DVec2; 2], b: &[DVec2; 2]) -> bool {
    a[0].x <= b[1].x && b[0].x <= a[1].x && a[0].y <= b[1].y && b[0].y <= a[1].y
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Obstacle;

    fn rect(lo: (f64, f64), hi: (f64, f64)) -> Obstacle {
        Obstacle::rectangle(DVec2::new(lo.0, lo.1), DVec2::new(hi.0, hi.1))
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
    fn a_start_inside_a_mark_steps_out_of_it() {
        // A person who stopped beside the leader, marked with 0.8 m round them: the leader
        // stands inside the mark and still has a way out (it had "no route" for 260 s).
        let person = Obstacle::Circle {
            center: DVec2::new(5.0, 0.5),
            radius: 1.1,
        };
        let map = Map::new(vec![person]);
        let rp = RoutePlanner::new(&map, &[DVec2::ZERO, DVec2::new(20.0, 0.0)], params());
        let start = DVec2::new(5.0, 0.0);
        assert!(map.clearance(start, 5.0) <= 0.0);
        let route = rp
            .plan(start, DVec2::new(20.0, 0.0), &[])
            .expect("a way out of the mark");
        assert_eq!(route.points[0], start);
        // A wall the robot stands in is not a mark it can step out of by 1.5 m.
        let wall = Map::new(vec![rect((3.0, -5.0), (7.0, 5.0))]);
        let rp = RoutePlanner::new(&wall, &[DVec2::ZERO, DVec2::new(20.0, 0.0)], params());
        assert!(matches!(
            rp.plan(start, DVec2::new(20.0, 0.0), &[]),
            Err(NoRoute::StartBlocked { .. })
        ));
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
    fn the_distance_transform_is_exact() {
        let (nx, ny) = (37, 23);
        let mut state = 7u64;
        let seeds: Vec<bool> = (0..nx * ny)
            .map(|_| {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1);
                (state >> 33).is_multiple_of(41)
            })
            .collect();
        let d = distance_transform(&seeds, nx, ny, f32::INFINITY);
        for (k, dk) in d.iter().enumerate() {
            let (i, j) = ((k % nx) as f32, (k / nx) as f32);
            let brute = (0..nx * ny)
                .filter(|q| seeds[*q])
                .map(|q| {
                    let (a, b) = ((q % nx) as f32 - i, (q / nx) as f32 - j);
                    a * a + b * b
                })
                .fold(f32::INFINITY, f32::min);
            assert_eq!(*dk, brute, "cell {k}");
        }
        assert!(distance_transform(&[false; 6], 3, 2, f32::INFINITY)
            .iter()
            .all(|v| v.is_infinite()));
    }

    #[test]
    fn clearances_are_exact_near_surfaces_and_never_too_high_beyond() {
        let map = Map::new(vec![
            Obstacle::Circle {
                center: DVec2::new(3.0, 2.0),
                radius: 0.7,
            },
            Obstacle::Segment {
                a: DVec2::new(-1.0, 6.0),
                b: DVec2::new(6.0, 4.5),
            },
            rect((7.0, -1.0), (8.0, 5.0)),
        ]);
        let (band, cap) = (0.64, 2.4);
        let extent = Extent::new(DVec2::splat(-3.0), DVec2::new(11.0, 9.0), 0.1);
        let grid = ClearanceGrid::build(&map, extent, band, cap);
        for k in 0..grid.clear.len() {
            let p = grid.centre(k);
            let truth = map.clearance(p, 10.0).max(0.0).min(cap);
            let c = grid.clear[k] as f64;
            if truth <= band {
                assert!((c - truth).abs() < 1e-5, "{p}: {c} vs {truth}");
            } else {
                assert!(c <= truth + 1e-5, "{p}: {c} above the truth {truth}");
                assert!(c >= truth - 0.15, "{p}: {c} far below the truth {truth}");
            }
        }
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
