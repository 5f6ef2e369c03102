//! The site map: obstacles behind an R-tree, so that a query costs the obstacles near
//! the point, not all of them.

use glam::DVec2;
use rstar::primitives::{GeomWithData, Rectangle};
use rstar::{RTree, AABB};

use crate::geometry::{Nearest, Obstacle};

type Entry = GeomWithData<Rectangle<[f64; 2]>, usize>;

#[derive(Debug, Clone)]
pub struct Map {
    obstacles: Vec<Obstacle>,
    index: RTree<Entry>,
}

fn aabb(lo: DVec2, hi: DVec2) -> AABB<[f64; 2]> {
    AABB::from_corners([lo.x, lo.y], [hi.x, hi.y])
}

impl Map {
    pub fn new(obstacles: Vec<Obstacle>) -> Self {
        let entries = obstacles
            .iter()
            .enumerate()
            .map(|(i, o)| {
                let [lo, hi] = o.bounds();
                GeomWithData::new(Rectangle::from_corners([lo.x, lo.y], [hi.x, hi.y]), i)
            })
            .collect();
        Self {
            obstacles,
            index: RTree::bulk_load(entries),
        }
    }

    /// Adds an obstacle (one found on the way): an R-tree insertion, not a rebuild.
    pub fn insert(&mut self, o: Obstacle) {
        let [lo, hi] = o.bounds();
        let entry = GeomWithData::new(
            Rectangle::from_corners([lo.x, lo.y], [hi.x, hi.y]),
            self.obstacles.len(),
        );
        self.obstacles.push(o);
        self.index.insert(entry);
    }

    pub fn obstacles(&self) -> &[Obstacle] {
        &self.obstacles
    }

    /// Obstacles whose bounds come within `radius` of `p`.
    pub fn near(&self, p: DVec2, radius: f64) -> impl Iterator<Item = &Obstacle> + '_ {
        let r = DVec2::splat(radius);
        self.index
            .locate_in_envelope_intersecting(&aabb(p - r, p + r))
            .map(|e| &self.obstacles[e.data])
    }

    /// The nearest obstacle surface within `radius`, if any.
    pub fn nearest(&self, p: DVec2, radius: f64) -> Option<Nearest> {
        self.near(p, radius)
            .map(|o| o.nearest(p))
            .filter(|n| n.distance <= radius)
            .min_by(|a, b| a.distance.total_cmp(&b.distance))
    }

    /// Distance from `p` to the nearest surface, or `radius` when nothing is closer.
    pub fn clearance(&self, p: DVec2, radius: f64) -> f64 {
        self.nearest(p, radius).map_or(radius, |n| n.distance)
    }

    /// Free distance along the unit ray from `o` in `dir`, at most `max`.
    pub fn ray_cast(&self, o: DVec2, dir: DVec2, max: f64) -> f64 {
        let end = o + dir * max;
        self.index
            .locate_in_envelope_intersecting(&aabb(o.min(end), o.max(end)))
            .filter_map(|e| self.obstacles[e.data].ray_cast(o, dir))
            .fold(max, f64::min)
    }
}
