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

    /// Removes an obstacle equal to `o` (one found on the way and forgotten since), if the
    /// map holds one; the last obstacle takes its index.
    pub fn remove(&mut self, o: &Obstacle) -> bool {
        let [lo, hi] = o.bounds();
        let Some(i) = self
            .index
            .locate_in_envelope_intersecting(&aabb(lo, hi))
            .map(|e| e.data)
            .find(|i| self.obstacles[*i] == *o)
        else {
            return false;
        };
        let entry = |i: usize, o: &Obstacle| {
            let [lo, hi] = o.bounds();
            GeomWithData::new(Rectangle::from_corners([lo.x, lo.y], [hi.x, hi.y]), i)
        };
        self.index.remove(&entry(i, o));
        let last = self.obstacles.len() - 1;
        if i != last {
            let moved = self.obstacles[last].clone();
            self.index.remove(&entry(last, &moved));
            self.index.insert(entry(i, &moved));
        }
        self.obstacles.swap_remove(i);
        true
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_removed_obstacle_is_gone_and_the_others_stay_found() {
        let disc = |x: f64| Obstacle::Circle {
            center: DVec2::new(x, 0.0),
            radius: 0.1,
        };
        let mut map = Map::new(vec![disc(0.0), disc(5.0)]);
        map.insert(disc(10.0));
        assert!(map.remove(&disc(0.0)));
        assert!(!map.remove(&disc(0.0)));
        assert_eq!(map.obstacles().len(), 2);
        assert_eq!(map.clearance(DVec2::new(0.0, 0.0), 1.0), 1.0);
        for x in [5.0, 10.0] {
            assert!(map.clearance(DVec2::new(x, 0.5), 1.0) < 0.5, "{x}");
        }
        assert!(map.remove(&disc(10.0)));
        assert!(map.clearance(DVec2::new(5.0, 0.5), 1.0) < 0.5);
    }
}
