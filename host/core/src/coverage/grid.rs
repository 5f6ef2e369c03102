//! The ground the brushes swept: a grid of [`CELL`] cells over the areas to sweep. A cell
//! is *to sweep* when its centre is inside an area, outside every obstacle, and a brush
//! can reach it: a robot's centre may come within half a brush of it, that is its
//! clearance is at least the footprint less half the brush (cells in slits narrower than a
//! robot, or under a wall, are not asked of the fleet). A brush sweeps the cells its
//! segment (across the robot, `brush_width` wide) passes over; a cell swept again by
//! another robot, or by the same one after [`AGAIN_S`], counts as swept twice.

use glam::DVec2;
use serde::Serialize;

use crate::geometry::map::Map;
use crate::geometry::point_in_polygon;

/// The grid's cell, m.
pub const CELL: f64 = 0.1;
/// The same brush over the same cell again after this long is a second sweep, s.
const AGAIN_S: f64 = 3.0;
/// Missed patches listed in a summary, largest first.
const MISSED_LISTED: usize = 50;

#[derive(Debug, Clone, Copy, Default)]
struct Cell {
    /// Which area (1-based) the cell is to be swept for; 0: none.
    area: u8,
    /// Which area's outline, grown by half a brush, holds the cell (1-based; 0: none):
    /// a robot whose centre is there may have its brushes down.
    down: u8,
    sweeps: u8,
    last_robot: u16,
    last_s: f32,
}

/// The coverage of one run.
#[derive(Debug, Clone)]
pub struct Coverage {
    origin: DVec2,
    nx: usize,
    ny: usize,
    cells: Vec<Cell>,
    brush: f64,
    /// Cells to sweep, and of them swept.
    to_sweep: usize,
    swept: usize,
}

/// A patch the brushes missed: its cells' bounds and area.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Missed {
    pub min: [f64; 2],
    pub max: [f64; 2],
    pub area_m2: f64,
}

/// What a run swept.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Swept {
    /// Free ground within the brushes' reach in every area, m².
    pub to_sweep_m2: f64,
    pub swept_m2: f64,
    /// `swept_m2 / to_sweep_m2`.
    pub swept_fraction: f64,
    /// Swept twice or more, m².
    pub swept_twice_m2: f64,
    /// `swept_twice_m2 / swept_m2`.
    pub overlap_fraction: f64,
    /// Patches of at least one cell not swept, largest first (at most 50).
    pub missed: Vec<Missed>,
    /// Missed patches in all.
    pub missed_patches: usize,
}

/// Whether `p` is inside `polygon` or within `within` of its outline.
fn near_or_in(p: DVec2, polygon: &[DVec2], within: f64) -> bool {
    let n = polygon.len();
    point_in_polygon(p, polygon)
        || (0..n).any(|i| {
            let q = crate::geometry::closest_on_segment(p, polygon[i], polygon[(i + 1) % n]);
            q.distance(p) <= within
        })
}

impl Coverage {
    /// The grid over `areas` on `map`, for robots of radius `footprint` with brushes
    /// `brush` wide.
    pub fn new(areas: &[Vec<DVec2>], map: &Map, footprint: f64, brush: f64) -> Self {
        let lo = areas
            .iter()
            .flatten()
            .fold(DVec2::INFINITY, |m, q| m.min(*q));
        let hi = areas
            .iter()
            .flatten()
            .fold(DVec2::NEG_INFINITY, |m, q| m.max(*q));
        let (lo, hi) = if lo.is_finite() {
            (lo - DVec2::splat(brush), hi + DVec2::splat(brush))
        } else {
            (DVec2::ZERO, DVec2::ZERO)
        };
        let nx = ((hi.x - lo.x) / CELL).ceil().max(0.0) as usize;
        let ny = ((hi.y - lo.y) / CELL).ceil().max(0.0) as usize;
        let mut cells = vec![Cell::default(); nx * ny];
        let reach = footprint - 0.5 * brush;
        for (i, cell) in cells.iter_mut().enumerate() {
            let c = lo + (DVec2::new((i % nx) as f64, (i / nx) as f64) + 0.5) * CELL;
            cell.down = areas
                .iter()
                .position(|poly| near_or_in(c, poly, 0.5 * brush))
                .map_or(0, |a| (a + 1).min(255) as u8);
            let Some(a) = areas.iter().position(|poly| point_in_polygon(c, poly)) else {
                continue;
            };
            let clear = map.clearance(c, reach.max(0.0) + CELL);
            if clear > 0.0 && clear >= reach {
                cell.area = (a + 1).min(255) as u8;
            }
        }
        let to_sweep = cells.iter().filter(|c| c.area > 0).count();
        Self {
            origin: lo,
            nx,
            ny,
            cells,
            brush,
            to_sweep,
            swept: 0,
        }
    }

    fn index(&self, p: DVec2) -> Option<usize> {
        let q = (p - self.origin) / CELL;
        let (x, y) = (q.x.floor(), q.y.floor());
        (x >= 0.0 && y >= 0.0 && (x as usize) < self.nx && (y as usize) < self.ny)
            .then(|| y as usize * self.nx + x as usize)
    }

    /// The area (index) whose outline, grown by half a brush, holds `p`: where a robot's
    /// brushes may be down.
    pub fn area_at(&self, p: DVec2) -> Option<usize> {
        self.index(p)
            .map(|i| self.cells[i].down)
            .filter(|a| *a > 0)
            .map(|a| a as usize - 1)
    }

    /// Robot `robot`'s brush moved from the pose (`from`, `from_heading`) to (`to`,
    /// `to_heading`) at `t_s`: the cells it passed over are swept.
    pub fn sweep(&mut self, robot: u16, from: (DVec2, f64), to: (DVec2, f64), t_s: f64) {
        let steps = (((to.0 - from.0).length() / (0.5 * CELL)).ceil() as usize).max(1);
        let across = ((self.brush / (0.5 * CELL)).ceil() as usize).max(1);
        for s in 0..=steps {
            let f = s as f64 / steps as f64;
            let at = from.0.lerp(to.0, f);
            let heading = from.1 + (to.1 - from.1) * f;
            let side = DVec2::new(-heading.sin(), heading.cos());
            for k in 0..=across {
                let off = (k as f64 / across as f64 - 0.5) * self.brush;
                let Some(i) = self.index(at + side * off) else {
                    continue;
                };
                // A cell is swept when the brush passes over its centre.
                let centre = self.centre(i);
                if (centre - at).dot(side).abs() <= 0.5 * self.brush + 1e-9 {
                    self.mark(i, robot, t_s);
                }
            }
        }
    }

    fn mark(&mut self, i: usize, robot: u16, t_s: f64) {
        let c = &mut self.cells[i];
        if c.area == 0 {
            return;
        }
        if c.sweeps == 0 {
            self.swept += 1;
        }
        let again = c.sweeps == 0 || c.last_robot != robot || t_s - c.last_s as f64 > AGAIN_S;
        if again {
            c.sweeps = c.sweeps.saturating_add(1);
        }
        c.last_robot = robot;
        c.last_s = t_s as f32;
    }

    fn centre(&self, i: usize) -> DVec2 {
        self.origin + (DVec2::new((i % self.nx) as f64, (i / self.nx) as f64) + 0.5) * CELL
    }

    /// Each cell to sweep: its centre and how often it was swept.
    pub fn cells(&self) -> impl Iterator<Item = (DVec2, u8)> + '_ {
        self.cells
            .iter()
            .enumerate()
            .filter(|(_, c)| c.area > 0)
            .map(|(i, c)| (self.centre(i), c.sweeps))
    }

    /// The cells to sweep as runs along x of the same count (0, 1, 2 for twice or more):
    /// `(lower-left corner, length, count)`, for a figure of a few thousand shapes.
    pub fn runs(&self) -> Vec<(DVec2, f64, u8)> {
        let mut out = Vec::new();
        for y in 0..self.ny {
            let mut x = 0;
            while x < self.nx {
                let c = self.cells[y * self.nx + x];
                if c.area == 0 {
                    x += 1;
                    continue;
                }
                let count = c.sweeps.min(2);
                let start = x;
                while x < self.nx && {
                    let d = self.cells[y * self.nx + x];
                    d.area > 0 && d.sweeps.min(2) == count
                } {
                    x += 1;
                }
                let corner = self.origin + DVec2::new(start as f64, y as f64) * CELL;
                out.push((corner, (x - start) as f64 * CELL, count));
            }
        }
        out
    }

    /// The share of the ground to sweep swept so far (1 with nothing to sweep).
    pub fn swept_fraction(&self) -> f64 {
        if self.to_sweep == 0 {
            1.0
        } else {
            self.swept as f64 / self.to_sweep as f64
        }
    }

    /// The grid's lower-left corner and its cells along x and y.
    pub fn shape(&self) -> (DVec2, usize, usize) {
        (self.origin, self.nx, self.ny)
    }

    /// The grid as an image, row by row from the lower-left, 4 bytes (red, green, blue,
    /// alpha) a cell: swept once pale green, twice or more green, missed pale red, what is
    /// not asked for clear.
    pub fn rgba(&self) -> Vec<u8> {
        self.cells
            .iter()
            .flat_map(|c| match (c.area, c.sweeps) {
                (0, _) => [0, 0, 0, 0],
                (_, 0) => [250, 160, 160, 200],
                (_, 1) => [170, 225, 170, 200],
                _ => [90, 180, 90, 200],
            })
            .collect()
    }

    /// What was swept, and the patches missed.
    pub fn summary(&self) -> Swept {
        let area = CELL * CELL;
        let to_sweep = self.cells.iter().filter(|c| c.area > 0).count();
        let swept = self
            .cells
            .iter()
            .filter(|c| c.area > 0 && c.sweeps > 0)
            .count();
        let twice = self
            .cells
            .iter()
            .filter(|c| c.area > 0 && c.sweeps > 1)
            .count();
        let mut missed = self.missed();
        let patches = missed.len();
        missed.truncate(MISSED_LISTED);
        Swept {
            to_sweep_m2: to_sweep as f64 * area,
            swept_m2: swept as f64 * area,
            swept_fraction: if to_sweep == 0 {
                1.0
            } else {
                swept as f64 / to_sweep as f64
            },
            swept_twice_m2: twice as f64 * area,
            overlap_fraction: if swept == 0 {
                0.0
            } else {
                twice as f64 / swept as f64
            },
            missed,
            missed_patches: patches,
        }
    }

    /// The missed cells in 4-connected patches, largest first.
    fn missed(&self) -> Vec<Missed> {
        let mut out: Vec<Missed> = self
            .patches(None)
            .iter()
            .map(|cells| {
                let lo = cells
                    .iter()
                    .fold(DVec2::INFINITY, |m, i| m.min(self.centre(*i)));
                let hi = cells
                    .iter()
                    .fold(DVec2::NEG_INFINITY, |m, i| m.max(self.centre(*i)));
                let half = DVec2::splat(0.5 * CELL);
                let (a, b) = (lo - half, hi + half);
                Missed {
                    min: [a.x, a.y],
                    max: [b.x, b.y],
                    area_m2: cells.len() as f64 * CELL * CELL,
                }
            })
            .collect();
        out.sort_by(|a, b| b.area_m2.total_cmp(&a.area_m2));
        out
    }

    /// Area `area`'s missed patches (every area's with `None`), each as its cells'
    /// centres.
    pub fn missed_in(&self, area: usize) -> Vec<Vec<DVec2>> {
        let area = (area + 1).min(255) as u8;
        self.patches(Some(area))
            .iter()
            .map(|cells| cells.iter().map(|i| self.centre(*i)).collect())
            .collect()
    }

    /// The missed cells (of `area`, 1-based, or of any) in 4-connected patches.
    fn patches(&self, area: Option<u8>) -> Vec<Vec<usize>> {
        let open = |c: &Cell| c.area > 0 && area.is_none_or(|a| c.area == a) && c.sweeps == 0;
        let mut seen = vec![false; self.cells.len()];
        let mut out = Vec::new();
        for start in 0..self.cells.len() {
            if seen[start] || !open(&self.cells[start]) {
                continue;
            }
            seen[start] = true;
            let mut stack = vec![start];
            let mut patch = Vec::new();
            while let Some(i) = stack.pop() {
                patch.push(i);
                let (x, y) = (i % self.nx, i / self.nx);
                let mut push = |j: usize| {
                    if !seen[j] && open(&self.cells[j]) {
                        seen[j] = true;
                        stack.push(j);
                    }
                };
                if x > 0 {
                    push(i - 1);
                }
                if x + 1 < self.nx {
                    push(i + 1);
                }
                if y > 0 {
                    push(i - self.nx);
                }
                if y + 1 < self.ny {
                    push(i + self.nx);
                }
            }
            out.push(patch);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(side: f64) -> Vec<DVec2> {
        vec![
            DVec2::ZERO,
            DVec2::new(side, 0.0),
            DVec2::new(side, side),
            DVec2::new(0.0, side),
        ]
    }

    #[test]
    fn one_pass_sweeps_its_strip_and_a_second_robot_counts_twice() {
        let mut c = Coverage::new(&[square(10.0)], &Map::new(Vec::new()), 0.3, 1.0);
        let s = c.summary();
        assert!((s.to_sweep_m2 - 100.0).abs() < 1e-6);
        assert_eq!(s.swept_m2, 0.0);
        c.sweep(
            0,
            (DVec2::new(0.0, 5.0), 0.0),
            (DVec2::new(10.0, 5.0), 0.0),
            0.0,
        );
        let s = c.summary();
        assert!((s.swept_m2 - 10.0).abs() < 1.1, "{}", s.swept_m2);
        assert!((c.swept_fraction() - s.swept_fraction).abs() < 1e-12);
        assert_eq!(s.swept_twice_m2, 0.0);
        // The same brush dwelling is not a second sweep; another robot is.
        c.sweep(
            0,
            (DVec2::new(10.0, 5.0), 0.0),
            (DVec2::new(10.0, 5.0), 0.0),
            1.0,
        );
        assert_eq!(c.summary().swept_twice_m2, 0.0);
        c.sweep(
            1,
            (DVec2::new(0.0, 5.0), 0.0),
            (DVec2::new(10.0, 5.0), 0.0),
            2.0,
        );
        assert!((c.summary().swept_twice_m2 - 10.0).abs() < 1.1);
        // Two patches missed, above and below the strip.
        let s = c.summary();
        assert_eq!(s.missed_patches, 2);
        assert!((s.missed[0].area_m2 - 45.0).abs() < 1.1, "{:?}", s.missed);
    }

    #[test]
    fn ground_under_an_obstacle_is_not_asked_for() {
        let post = crate::geometry::Obstacle::Circle {
            center: DVec2::new(5.0, 5.0),
            radius: 1.0,
        };
        let c = Coverage::new(&[square(10.0)], &Map::new(vec![post]), 0.3, 0.7);
        let expected = 100.0 - std::f64::consts::PI;
        assert!((c.summary().to_sweep_m2 - expected).abs() < 0.3);
    }
}

#[cfg(test)]
mod formation_tests {
    use super::*;

    #[test]
    fn three_brushes_side_by_side_overlap_only_where_they_touch() {
        let area = vec![
            DVec2::ZERO,
            DVec2::new(20.0, 0.0),
            DVec2::new(20.0, 10.0),
            DVec2::new(0.0, 10.0),
        ];
        let mut c = Coverage::new(&[area], &Map::new(Vec::new()), 0.3, 0.7);
        for step in 0..20_000 {
            let x = step as f64 * 0.001;
            for (robot, dy) in [(0u16, 0.0f64), (1, 0.6), (2, -0.6)] {
                let p = |x: f64| (DVec2::new(x - dy.abs() * 1.7, 5.03 + dy), 0.0);
                c.sweep(robot, p(x), p(x + 0.001), step as f64 * 0.002);
            }
        }
        let s = c.summary();
        assert!(s.overlap_fraction < 0.15, "{}", s.overlap_fraction);
    }
}
