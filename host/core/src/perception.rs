//! What the leader's range scanner sees that the site map does not hold (a parked van, a
//! skip, a bin moved into the street): scan hits become small obstacles the planner
//! avoids and routes round.
//!
//! A hit within `EXPLAINED` of a mapped surface is the map's own obstacle and ignored;
//! the others are kept one per `CELL`-sized cell, as discs of radius `CELL / 2` centred on
//! the first hit of that cell. They are never forgotten (a route planned round something
//! stays valid), and their number is bounded: past `MAX_SENSED` new hits are dropped and
//! counted.

use std::collections::HashSet;

use glam::DVec2;

use crate::geometry::Obstacle;
use crate::map::Map;

/// Side of the cells hits are merged in, m.
pub const CELL: f64 = 0.2;
/// A hit closer than this to a mapped surface is that surface, m.
pub const EXPLAINED: f64 = 0.15;
/// Most sensed obstacles kept.
pub const MAX_SENSED: usize = 8192;

#[derive(Debug, Clone, Default)]
pub struct Perception {
    cells: HashSet<(i64, i64)>,
    obstacles: Vec<Obstacle>,
    dropped: u64,
}

impl Perception {
    /// Takes one scan's hits (site frame); returns the obstacles it adds.
    pub fn absorb(&mut self, hits: &[DVec2], known: &Map) -> Vec<Obstacle> {
        let mut added = Vec::new();
        for &hit in hits {
            if !hit.is_finite() || known.clearance(hit, EXPLAINED) < EXPLAINED {
                continue;
            }
            let cell = ((hit.x / CELL).floor() as i64, (hit.y / CELL).floor() as i64);
            if self.cells.contains(&cell) {
                continue;
            }
            if self.obstacles.len() >= MAX_SENSED {
                self.dropped += 1;
                continue;
            }
            self.cells.insert(cell);
            let o = Obstacle::Circle {
                center: hit,
                radius: 0.5 * CELL,
            };
            self.obstacles.push(o.clone());
            added.push(o);
        }
        added
    }

    /// Everything sensed so far.
    pub fn obstacles(&self) -> &[Obstacle] {
        &self.obstacles
    }

    /// Hits dropped because `MAX_SENSED` obstacles were already kept.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mapped_surfaces_are_ignored_and_new_ones_kept_once_per_cell() {
        let known = Map::new(vec![Obstacle::Circle {
            center: DVec2::new(5.0, 0.0),
            radius: 1.0,
        }]);
        let mut p = Perception::default();
        let added = p.absorb(
            &[
                DVec2::new(4.0, 0.0),   // on the mapped bin
                DVec2::new(0.0, 3.01),  // new
                DVec2::new(0.05, 3.05), // same cell
                DVec2::new(0.0, 3.5),   // next cell
                DVec2::new(f64::NAN, 0.0),
            ],
            &known,
        );
        assert_eq!(added.len(), 2);
        assert_eq!(p.obstacles().len(), 2);
        assert!(p.absorb(&[DVec2::new(0.0, 3.02)], &known).is_empty());
    }
}
