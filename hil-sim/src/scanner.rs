//! The leader's range scanner: a planar lidar ([`RAYS`] beams over a full turn, out to
//! `[perception] max_range_m`) that sees the site as it is, movers included. A 360° lidar
//! of 30 m on the leader's roof is what an autonomous sweeper carries (its makers fit
//! 3D lidars of 100 m or 2D ones of 20–40 m): it sees a cyclist coming down the street
//! behind the formation some 4 s before they reach its last robot, where an 8 m scanner
//! gave under a second. It reports only hits on what the map does not hold (where
//! nothing on the site is nearer along the beam): the base station ignores hits on
//! mapped surfaces anyway, and leaving them out spares the simulator the casts on maps
//! without anything unmapped. Hits are registered in the site frame from the leader's
//! true pose (perfect registration).

use std::f64::consts::TAU;

use base_station::geometry::map::Map;
use base_station::scenario::Scenario;
use glam::DVec2;

use crate::movers::MoverState;

/// Beams per scan: half a degree apart, 0.26 m at 30 m, so that a person (0.5 m across)
/// is hit by at least one beam anywhere in reach.
pub const RAYS: usize = 720;

pub struct Scanner {
    /// `None` when the site holds nothing the map does not.
    unmapped: Option<Map>,
    /// Each beam's direction (a unit vector), worked out once.
    beams: Vec<DVec2>,
    /// How far it sees, m.
    range: f64,
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
            .map(|k| DVec2::from_angle(k as f64 * TAU / RAYS as f64))
            .collect();
        Self {
            unmapped,
            beams,
            range: scenario.perception.max_range_m,
        }
    }

    /// How far it sees, m.
    pub fn range(&self) -> f64 {
        self.range
    }

    /// One scan from `at` over `site` (everything on it, mapped or not) and the movers
    /// on it: the points where a beam first meets something unmapped or a mover.
    pub fn scan(&self, at: DVec2, site: &Map, movers: &[MoverState]) -> Vec<DVec2> {
        let range = self.range;
        let unmapped = self
            .unmapped
            .as_ref()
            .filter(|u| u.near(at, range).next().is_some());
        let mut d: Vec<f64> = match unmapped {
            Some(u) => self
                .beams
                .iter()
                .map(|dir| u.ray_cast(at, *dir, range))
                .collect(),
            None => vec![range; RAYS],
        };
        for m in movers {
            self.cast_at(at, m, &mut d);
        }
        d.iter()
            .zip(&self.beams)
            .filter(|(d, dir)| {
                // The site holds that obstacle too: nothing nearer means the cast gives d.
                **d < range && site.ray_cast(at, **dir, **d) >= **d
            })
            .map(|(d, dir)| at + *dir * *d)
            .collect()
    }

    /// The beams that can meet `m` (those within the angle it subtends from `at`), each
    /// shortened to where it does.
    fn cast_at(&self, at: DVec2, m: &MoverState, d: &mut [f64]) {
        let to = m.position - at;
        let (dist, reach) = (to.length(), m.shape.reach());
        if dist >= self.range + reach {
            return;
        }
        let step = TAU / RAYS as f64;
        let (first, last) = if dist <= reach {
            (0, RAYS as i64 - 1)
        } else {
            let half = (reach / dist).asin();
            let bearing = to.to_angle();
            (
                ((bearing - half) / step).floor() as i64,
                ((bearing + half) / step).ceil() as i64,
            )
        };
        for k in first..=last {
            let k = k.rem_euclid(RAYS as i64) as usize;
            if let Some(t) = m.ray(at, self.beams[k]) {
                d[k] = d[k].min(t);
            }
        }
    }
}
