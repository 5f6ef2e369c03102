//! The leader's range scanner: a planar lidar (`RAYS` beams over a full turn, `RANGE`
//! metres) that sees the site as it is, movers included. It reports only hits on what the
//! map does not hold (where nothing on the site is nearer along the beam): the base station ignores
//! hits on mapped surfaces anyway, and leaving them out spares the simulator the casts on
//! maps without anything unmapped. Hits are registered in the site frame from the
//! leader's true pose (perfect registration).

use base_station::geometry::map::Map;
use base_station::scenario::Scenario;
use glam::DVec2;

use crate::movers::MoverState;

/// Beams per scan.
pub const RAYS: usize = 180;
/// Range, m.
pub const RANGE: f64 = 8.0;

pub struct Scanner {
    /// `None` when the site holds nothing the map does not.
    unmapped: Option<Map>,
    /// Each beam's direction (a unit vector), worked out once.
    beams: Vec<DVec2>,
}

impl Scanner {
    pub fn new(scenario: &Scenario) -> Self {
        let unmapped = (!scenario.map.unmapped.is_empty()).then(|| {
            Map::new(
                scenario
                    .map
                    .unmapped
                    .iter()
                    .map(|o| o.to_obstacle())
                    .collect(),
            )
        });
        let beams = (0..RAYS)
            .map(|k| DVec2::from_angle(k as f64 * std::f64::consts::TAU / RAYS as f64))
            .collect();
        Self { unmapped, beams }
    }

    /// One scan from `at` over `site` (everything on it, mapped or not) and the movers
    /// on it: the points where a beam first meets something unmapped or a mover.
    pub fn scan(&self, at: DVec2, site: &Map, movers: &[MoverState]) -> Vec<DVec2> {
        let near: Vec<&MoverState> = movers
            .iter()
            .filter(|m| m.position.distance(at) < RANGE + m.shape.reach())
            .collect();
        let unmapped = self
            .unmapped
            .as_ref()
            .filter(|u| u.near(at, RANGE).next().is_some());
        if unmapped.is_none() && near.is_empty() {
            return Vec::new();
        }
        self.beams
            .iter()
            .filter_map(|&dir| {
                let d = unmapped.map_or(RANGE, |u| u.ray_cast(at, dir, RANGE));
                let d = near.iter().filter_map(|m| m.ray(at, dir)).fold(d, f64::min);
                // The site holds that obstacle too: nothing nearer means the cast gives d.
                let seen = d < RANGE && site.ray_cast(at, dir, d) >= d;
                seen.then(|| at + dir * d)
            })
            .collect()
    }
}
