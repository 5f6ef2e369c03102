//! Each robot's ultrasonic ring, as its board reports it: how far the footprint can drive
//! ahead (and behind) before it touches what a transducer sees. Five beams over ±40° each
//! way, `RANGE` beyond the footprint; echoes from the site (mapped or not) and from the
//! other robots. Beside the leader's scanner ([`crate::scanner`]), the other sensor that
//! sees the world.

use base_station::geometry;
use base_station::geometry::cells::CellIndex;
use base_station::geometry::map::Map;
use glam::DVec2;

use crate::movers::MoverState;

/// How far the ring sees beyond the footprint, m.
pub const RANGE: f64 = 2.0;
/// Grid cell for robot neighbour queries, m (≥ range + two footprints).
const CELL: f64 = 3.0;
/// How much wider a side than the footprint the corridor is in which an echo slows a
/// robot, m: it also turns.
const SIDE_MARGIN: f64 = 0.2;
/// The transducers' bearings off the way the robot faces, degrees.
const BEAMS_DEG: [f64; 5] = [-40.0, -20.0, 0.0, 20.0, 40.0];

/// How far a footprint of radius `fp` can drive ahead before it touches an echo `echo`
/// metres away on a beam `beam` radians off its heading: as far as a disc `SIDE_MARGIN`
/// wider can, plus that margin (so straight ahead, `echo − fp`). `None` when the echo is
/// beside the corridor that disc sweeps: a robot passing a bin or driving down an alley is
/// not slowed by what it is not driving into (a 1.3 m alley's walls slowed the last
/// follower and made it weave).
pub fn free_ahead(echo: f64, beam: f64, fp: f64) -> Option<f64> {
    let (ahead, aside) = (echo * beam.cos(), echo * beam.sin().abs());
    let corridor = fp + SIDE_MARGIN;
    (aside < corridor).then(|| ahead - (corridor * corridor - aside * aside).sqrt() + SIDE_MARGIN)
}

/// The robots' positions by grid cell, for neighbour queries.
pub struct Neighbours {
    grid: CellIndex,
    at: Vec<DVec2>,
}

impl Neighbours {
    pub fn new(at: Vec<DVec2>) -> Self {
        let grid = CellIndex::of_points(CELL, at.iter().copied());
        Self { grid, at }
    }

    /// The robots other than `i` in the cells around it.
    fn around(&self, i: usize) -> Vec<DVec2> {
        self.grid
            .around(self.at[i])
            .filter(|j| *j != i)
            .map(|j| self.at[j])
            .collect()
    }
}

/// Robot `i`'s ring at heading `heading` with footprint `fp`, over the site `map`, the
/// other robots and the movers: the free distance ahead and behind, where something is
/// within range.
pub fn sense(
    i: usize,
    heading: f64,
    fp: f64,
    map: &Map,
    robots: &Neighbours,
    movers: &[MoverState],
) -> [Option<f32>; 2] {
    let p = robots.at[i];
    let reach = RANGE + fp;
    let others = robots.around(i);
    let near: Vec<&MoverState> = movers
        .iter()
        .filter(|m| m.position.distance(p) < reach + m.shape.reach())
        .collect();
    let facing = |base: f64| {
        let free = BEAMS_DEG
            .iter()
            .filter_map(|deg| {
                let a = base + deg.to_radians();
                let dir = DVec2::new(a.cos(), a.sin());
                let wall = map.ray_cast(p, dir, reach);
                let echo = others
                    .iter()
                    .filter_map(|q| geometry::ray_circle(p, dir, *q, fp))
                    .fold(wall, f64::min);
                let echo = near
                    .iter()
                    .filter_map(|m| m.ray(p, dir))
                    .fold(echo, f64::min);
                (echo < reach)
                    .then(|| free_ahead(echo, deg.to_radians(), fp))
                    .flatten()
            })
            .fold(f64::INFINITY, f64::min);
        (free < RANGE).then_some(free.max(0.0) as f32)
    };
    [facing(heading), facing(heading + std::f64::consts::PI)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ring_counts_what_the_robot_drives_into() {
        let fp = 0.3;
        // Straight ahead: the gap in front of the footprint.
        assert!((free_ahead(1.0, 0.0, fp).unwrap() - 0.7).abs() < 1e-12);
        // A 1.3 m alley's wall, 0.65 m beside the centre, seen by the 40° beam: not in the way.
        let wall = 0.65 / 40f64.to_radians().sin();
        assert_eq!(free_ahead(wall, 40f64.to_radians(), fp), None);
        assert_eq!(free_ahead(wall, -40f64.to_radians(), fp), None);
        // Inside the corridor: the nearer the middle, the less room; never more than the
        // footprint has before it touches the echo.
        let at = |ahead: f64, aside: f64| {
            free_ahead(ahead.hypot(aside), aside.atan2(ahead), fp).expect("in the corridor")
        };
        let room = [0.0, 0.1, 0.2, 0.29, 0.4, 0.49].map(|aside| at(1.0, aside));
        assert!(room.windows(2).all(|w| w[0] < w[1]), "{room:?}");
        for (aside, r) in [0.0, 0.1, 0.2, 0.29].iter().zip(room) {
            let touches = 1.0 - (fp * fp - aside * aside).sqrt();
            assert!(r <= touches + 1e-12, "{aside}: {r} > {touches}");
        }
    }
}
