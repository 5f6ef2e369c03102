//! Things indexed by the square cells they touch, for "what is near this point" in
//! scans, crowds and fleets rebuilt at every step.
//!
//! Built once from (cell, item) pairs, with a fast (non-cryptographic) hash: the keys
//! are cells of a bounded scan, crowd or fleet, not input an attacker picks freely.

use glam::DVec2;
use rustc_hash::FxHashMap;

/// A cell of the grid: floor of the coordinates over the cell's side.
pub type Cell = (i64, i64);

/// Items (indices into the caller's slice) by the cells they touch.
#[derive(Debug, Clone, Default)]
pub struct CellIndex {
    side: f64,
    cells: FxHashMap<Cell, Vec<usize>>,
}

impl CellIndex {
    /// An index of side `side` (m) over `entries`: each item with a cell it touches (an
    /// item may touch several). Within a cell, items keep the order of `entries`.
    pub fn new(side: f64, entries: impl IntoIterator<Item = (Cell, usize)>) -> Self {
        let mut cells: FxHashMap<Cell, Vec<usize>> = FxHashMap::default();
        for (c, i) in entries {
            cells.entry(c).or_default().push(i);
        }
        Self { side, cells }
    }

    /// An index of points, each in the cell it lies in.
    pub fn of_points(side: f64, points: impl IntoIterator<Item = DVec2>) -> Self {
        let entries = points
            .into_iter()
            .enumerate()
            .map(|(i, p)| (cell_of(p, side), i));
        Self::new(side, entries)
    }

    /// The cell `p` lies in.
    pub fn cell(&self, p: DVec2) -> Cell {
        cell_of(p, self.side)
    }

    /// The items of cell `c`.
    pub fn at(&self, c: Cell) -> &[usize] {
        self.cells.get(&c).map_or(&[], Vec::as_slice)
    }

    /// The items of the 3 × 3 cells round `p`'s (row by row of x, then y): everything
    /// within one side of `p`, and some farther.
    pub fn around(&self, p: DVec2) -> impl Iterator<Item = usize> + '_ {
        let (cx, cy) = self.cell(p);
        (-1..=1)
            .flat_map(move |dx| (-1..=1).map(move |dy| (cx + dx, cy + dy)))
            .flat_map(|c| self.at(c).iter().copied())
    }
}

/// The cell of side `side` that `p` lies in.
pub fn cell_of(p: DVec2, side: f64) -> Cell {
    ((p.x / side).floor() as i64, (p.y / side).floor() as i64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn around_finds_the_neighbours_and_not_the_far() {
        let points = [
            DVec2::new(0.5, 0.5),
            DVec2::new(1.5, 0.2),
            DVec2::new(5.0, 5.0),
            DVec2::new(-0.5, -0.5),
        ];
        let index = CellIndex::of_points(1.0, points);
        let mut near: Vec<usize> = index.around(DVec2::new(0.6, 0.4)).collect();
        near.sort();
        assert_eq!(near, vec![0, 1, 3]);
        assert_eq!(index.at((5, 5)), &[2]);
        assert!(index.at((9, 9)).is_empty());
    }

    #[test]
    fn an_item_in_several_cells_is_found_from_each() {
        let index = CellIndex::new(1.0, [((0, 0), 2), ((1, 0), 7), ((0, 0), 7)]);
        assert_eq!(index.at((0, 0)), &[2, 7]);
        assert_eq!(index.at((1, 0)), &[7]);
    }
}
