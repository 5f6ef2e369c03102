//! The station's own account of a sweep: each robot's brush stamped on a coverage grid
//! from where the station estimates it, and, when the leader has driven an area's last
//! pass, the strips left unswept (people held the fleet, a detour, the line's narrow
//! swath beside a bin) gone back for before the fleet leaves the area: each missed patch
//! of at least [`MIN_PATCH_M2`] swept with passes one brush apart, nearest first. Once per
//! area: what a second round would still miss is reported, not chased.

use glam::DVec2;

use super::brush_down;
use super::grid::Coverage;
use super::plan::{plan_area, SweepParams};
use crate::geometry::map::Map;

/// A missed patch smaller than this is not worth going back for, m² (a brush's width
/// by a metre and a half).
pub const MIN_PATCH_M2: f64 = 1.0;
/// A touch-up whose next point the leader has not reached for this long is given up, s
/// (a pass and two turns take well under a minute).
pub const GIVE_UP_AFTER_S: f64 = 60.0;
/// Coming this much nearer the next point is progress, m.
const PROGRESS_M: f64 = 0.5;

/// One area as the station sweeps it.
#[derive(Debug, Clone, PartialEq)]
pub struct AreaSetup {
    pub name: String,
    pub polygon: Vec<DVec2>,
    /// The passes' direction, rad.
    pub direction: f64,
    /// The route point (index) after which the area's passes are all driven.
    pub last_point: usize,
    /// Between touch-up passes' centre lines: a brush less the area's overlap, m.
    pub spacing: f64,
}

/// What the station needs to watch a sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepSetup {
    pub areas: Vec<AreaSetup>,
    pub brush: f64,
    pub footprint: f64,
    /// How far a touch-up pass keeps the leader from what the map holds, m.
    pub clearance: f64,
}

/// Going back for an area's missed strips.
#[derive(Debug, Clone, PartialEq)]
pub struct TouchUp {
    pub area: usize,
    /// Put next on the leader's route.
    pub points: Vec<DVec2>,
    /// Patches gone back for, and their ground, m².
    pub patches: usize,
    pub missed_m2: f64,
}

/// A touch-up under way, and the leader's last progress on it.
#[derive(Debug, Clone, Copy)]
struct Touching {
    /// The route point (index) it runs up to.
    end: usize,
    /// Route points passed, and the distance to the next, at the last progress.
    passed: usize,
    nearest: f64,
    since_s: f64,
}

#[derive(Debug, Clone)]
pub struct SweepWatch {
    setup: SweepSetup,
    grid: Coverage,
    directions: Vec<f64>,
    /// Per area: touched up (or found nothing to touch up).
    done: Vec<bool>,
    /// Each robot's last pose (id, position, heading).
    last: Vec<(u16, DVec2, f64)>,
    /// The touch-up under way.
    touching: Option<Touching>,
}

impl SweepWatch {
    pub fn new(setup: SweepSetup, map: &Map) -> Self {
        let polygons: Vec<Vec<DVec2>> = setup.areas.iter().map(|a| a.polygon.clone()).collect();
        let grid = Coverage::new(&polygons, map, setup.footprint, setup.brush);
        Self {
            directions: setup.areas.iter().map(|a| a.direction).collect(),
            done: vec![false; setup.areas.len()],
            last: Vec::new(),
            touching: None,
            grid,
            setup,
        }
    }

    /// Each robot `(id, position, heading)` as estimated now, at `now_s`.
    pub fn observe(&mut self, robots: impl Iterator<Item = (u16, DVec2, f64)>, now_s: f64) {
        for (id, at, heading) in robots {
            let before = match self.last.iter_mut().find(|l| l.0 == id) {
                Some(l) => std::mem::replace(l, (id, at, heading)),
                None => {
                    self.last.push((id, at, heading));
                    (id, at, heading)
                }
            };
            if brush_down(&self.grid, &self.directions, at, heading) {
                self.grid
                    .sweep(id, (before.1, before.2), (at, heading), now_s);
            }
        }
    }

    /// With `passed` route points behind the leader (at `at`; `arrived` at the last one):
    /// the touch-up of the first area whose passes are all driven, if it missed anything
    /// worth going back for. The later areas' route points move on by the points put in.
    pub fn decide(
        &mut self,
        passed: usize,
        arrived: bool,
        at: DVec2,
        map: &Map,
        now_s: f64,
    ) -> Option<TouchUp> {
        let i = (0..self.setup.areas.len())
            .find(|i| !self.done[*i] && (passed > self.setup.areas[*i].last_point || arrived))?;
        self.done[i] = true;
        let area = &self.setup.areas[i];
        let patches: Vec<Vec<DVec2>> = self
            .grid
            .missed_in(i)
            .into_iter()
            .filter(|p| p.len() as f64 * super::grid::CELL.powi(2) >= MIN_PATCH_M2)
            .collect();
        let mut points = Vec::new();
        let mut from = at;
        for patch in nearest_first(&patches, at) {
            let outline = patch_outline(patch, area.direction, 0.5 * self.setup.brush);
            let params = SweepParams {
                swath: self.setup.brush,
                spacing: area.spacing,
                clearance: self.setup.clearance,
                trail: 0.5 * self.setup.brush,
                direction: Some(area.direction),
            };
            let plan = plan_area(&outline, map, &params, from);
            from = plan.passes.last().map_or(from, |p| p.to);
            points.extend(plan.passes.iter().flat_map(|p| p.points()));
        }
        if points.is_empty() {
            return None;
        }
        for later in &mut self.setup.areas[i + 1..] {
            later.last_point += points.len();
        }
        self.touching = Some(Touching {
            end: passed + points.len(),
            passed,
            nearest: f64::INFINITY,
            since_s: now_s,
        });
        Some(TouchUp {
            area: i,
            patches: patches.len(),
            missed_m2: patches.iter().map(Vec::len).sum::<usize>() as f64
                * super::grid::CELL.powi(2),
            points,
        })
    }

    /// With `passed` route points behind the leader, at `at` making for `next` at `now_s`:
    /// how many points of a touch-up to give up, when the leader has come no nearer its
    /// next point for [`GIVE_UP_AFTER_S`] (a tight spot the fleet cannot sweep: better
    /// missed than stuck).
    pub fn give_up(
        &mut self,
        passed: usize,
        at: DVec2,
        next: Option<DVec2>,
        now_s: f64,
    ) -> Option<usize> {
        let t = self.touching.as_mut()?;
        if passed >= t.end {
            self.touching = None;
            return None;
        }
        let distance = next.map_or(0.0, |n| n.distance(at));
        if passed > t.passed || distance < t.nearest - PROGRESS_M {
            (t.passed, t.nearest, t.since_s) = (passed, distance, now_s);
            return None;
        }
        if now_s - t.since_s < GIVE_UP_AFTER_S {
            return None;
        }
        let end = t.end;
        self.touching = None;
        for later in self.setup.areas.iter_mut().filter(|a| a.last_point >= end) {
            later.last_point -= end - passed;
        }
        Some(end - passed)
    }

    /// The share of the areas swept, as the station estimates its robots' brushes.
    pub fn swept_fraction(&self) -> f64 {
        self.grid.swept_fraction()
    }

    /// The station's estimate of the ground swept.
    pub fn grid(&self) -> &Coverage {
        &self.grid
    }

    /// Area `i`'s name.
    pub fn name(&self, i: usize) -> &str {
        &self.setup.areas[i].name
    }
}

/// The patches in the order nearest first from `at` (each from where the last ended,
/// taken as its centre).
fn nearest_first(patches: &[Vec<DVec2>], mut at: DVec2) -> Vec<&Vec<DVec2>> {
    let centre = |p: &Vec<DVec2>| p.iter().fold(DVec2::ZERO, |s, q| s + *q) / p.len() as f64;
    let mut left: Vec<&Vec<DVec2>> = patches.iter().collect();
    let mut out = Vec::with_capacity(left.len());
    while !left.is_empty() {
        let k = (0..left.len())
            .min_by(|a, b| {
                let (da, db) = (centre(left[*a]).distance(at), centre(left[*b]).distance(at));
                da.total_cmp(&db)
            })
            .expect("a patch is left");
        let p = left.swap_remove(k);
        at = centre(p);
        out.push(p);
    }
    out
}

/// The rectangle along `direction` round a patch's cells, grown by `grow`.
fn patch_outline(cells: &[DVec2], direction: f64, grow: f64) -> Vec<DVec2> {
    let (along, across) = (
        DVec2::from_angle(direction),
        DVec2::from_angle(direction).perp(),
    );
    let (mut lo, mut hi) = (DVec2::INFINITY, DVec2::NEG_INFINITY);
    for c in cells {
        let q = DVec2::new(c.dot(along), c.dot(across));
        lo = lo.min(q);
        hi = hi.max(q);
    }
    let (lo, hi) = (lo - DVec2::splat(grow), hi + DVec2::splat(grow));
    [(lo.x, lo.y), (hi.x, lo.y), (hi.x, hi.y), (lo.x, hi.y)]
        .iter()
        .map(|(a, b)| along * *a + across * *b)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn setup() -> SweepSetup {
        SweepSetup {
            areas: vec![AreaSetup {
                name: "yard".into(),
                polygon: vec![
                    DVec2::ZERO,
                    DVec2::new(20.0, 0.0),
                    DVec2::new(20.0, 4.0),
                    DVec2::new(0.0, 4.0),
                ],
                direction: 0.0,
                last_point: 3,
                spacing: 0.6,
            }],
            brush: 0.7,
            footprint: 0.3,
            clearance: 0.5,
        }
    }

    #[test]
    fn a_strip_left_unswept_is_gone_back_for_once() {
        let map = Map::new(Vec::new());
        let mut w = SweepWatch::new(setup(), &map);
        // Brushes along both edges; the middle strip (0.7..3.3) is missed.
        for (id, y) in [(0u16, 0.35), (1, 3.65)] {
            for k in 0..=200 {
                let at = DVec2::new(k as f64 * 0.1, y);
                w.observe(std::iter::once((id, at, 0.0)), k as f64 * 0.1);
            }
        }
        assert!(
            w.decide(3, false, DVec2::ZERO, &map, 0.0).is_none(),
            "not yet passed"
        );
        let t = w
            .decide(4, false, DVec2::new(20.0, 3.0), &map, 30.0)
            .expect("a touch-up");
        assert_eq!(t.patches, 1);
        assert!((t.missed_m2 - 52.0).abs() < 3.0, "{}", t.missed_m2);
        // Passes along x within the strip, from the end nearest the leader.
        assert!(
            t.points.iter().all(|p| p.y > 0.6 && p.y < 3.4),
            "{:?}",
            t.points
        );
        assert!(t.points.len() >= 8, "{:?}", t.points);
        assert!(t.points[0].x > 15.0);
        assert!(
            w.decide(9, false, DVec2::ZERO, &map, 31.0).is_none(),
            "once per area"
        );
        // Coming nearer is progress; stuck short of its second point, given up a minute
        // after the last progress.
        let next = Some(DVec2::new(10.0, 2.0));
        assert_eq!(w.give_up(4, DVec2::new(20.0, 2.0), next, 40.0), None);
        assert_eq!(w.give_up(4, DVec2::new(15.0, 2.0), next, 90.0), None);
        assert_eq!(w.give_up(5, DVec2::new(12.0, 2.0), next, 120.0), None);
        assert_eq!(w.give_up(5, DVec2::new(11.9, 2.0), next, 179.0), None);
        let left = w.give_up(5, DVec2::new(11.9, 2.0), next, 180.5);
        assert_eq!(left, Some(t.points.len() - 1));
        assert_eq!(w.give_up(5, DVec2::new(11.9, 2.0), next, 300.0), None);
    }
}
