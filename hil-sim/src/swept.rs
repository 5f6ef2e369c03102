//! What a sweep swept: each robot's brush along its true path, only while it is down,
//! on the coverage grid ([`base_station::coverage::grid`]); the sweep's time and the
//! leader's distance with its brushes down, and the time the leader stood for people
//! while sweeping.
//!
//! **Brushes down** (a model of the station's brush command, which the radio does not
//! carry yet): [`base_station::coverage::brush_down`], the rule the station's own
//! estimate uses.

use base_station::coverage::brush_down;
use base_station::coverage::grid::{Coverage, Swept};
use base_station::geometry::map::Map;
use base_station::scenario::Scenario;
use glam::DVec2;
use serde::Serialize;

use crate::movers::MoverState;

/// A robot after a physics step, as the sweep needs it.
#[derive(Debug, Clone, Copy)]
pub struct Brush {
    pub id: u16,
    pub leads: bool,
    pub position: DVec2,
    pub heading: f64,
    /// Forward speed, m/s.
    pub v: f64,
}

/// The leader slower than this stands, m/s.
const STANDING: f64 = 0.05;
/// A person within this of the leader's footprint is what it stands for, m.
const STANDING_FOR_WITHIN: f64 = 3.0;

/// The sweep in the report (schema 5).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SweepReport {
    #[serde(flatten)]
    pub swept: Swept,
    /// From the first brush down to the last brush up, s.
    pub time_s: f64,
    /// The leader's distance with its brushes down, m.
    pub distance_m: f64,
    /// While sweeping, the leader standing with a person within 3 m, s.
    pub stood_for_people_s: f64,
}

/// The sweep as it goes.
#[derive(Debug, Clone)]
pub struct Sweeping {
    grid: Coverage,
    last: Vec<Option<(DVec2, f64)>>,
    first_down_s: Option<f64>,
    last_down_s: f64,
    distance_m: f64,
    stood_for_people_s: f64,
    footprint: f64,
    /// Each area's passes' direction, rad.
    directions: Vec<f64>,
}

impl Sweeping {
    /// For `scenario`'s areas on `map` (what the robots can touch), `None` without any.
    pub fn new(scenario: &Scenario, map: &Map) -> Option<Self> {
        if scenario.sweep.is_empty() {
            return None;
        }
        let areas: Vec<Vec<DVec2>> = scenario.sweep.iter().map(|a| a.points()).collect();
        let r = &scenario.robot;
        let mut directions = vec![0.0; areas.len()];
        for a in scenario.sweep_plan().into_iter().flat_map(|p| p.areas) {
            directions[a.index] = a.plan.direction;
        }
        Some(Self {
            directions,
            grid: Coverage::new(&areas, map, r.footprint_radius, r.brush_width),
            last: vec![None; scenario.robots.len()],
            first_down_s: None,
            last_down_s: 0.0,
            distance_m: 0.0,
            stood_for_people_s: 0.0,
            footprint: r.footprint_radius,
        })
    }

    /// After a physics step of `dt` s ending at `t_s`.
    pub fn observe(
        &mut self,
        t_s: f64,
        dt: f64,
        robots: impl Iterator<Item = Brush>,
        movers: &[MoverState],
    ) {
        for (i, r) in robots.enumerate() {
            let now = (r.position, r.heading);
            let before = self.last.get_mut(i).and_then(|l| l.replace(now));
            if !brush_down(&self.grid, &self.directions, now.0, now.1) {
                continue;
            }
            self.first_down_s.get_or_insert(t_s);
            self.last_down_s = t_s;
            let from = before.unwrap_or(now);
            self.grid.sweep(r.id, from, now, t_s);
            if r.leads {
                self.distance_m += (now.0 - from.0).length();
                let near = movers
                    .iter()
                    .any(|m| m.position.distance(now.0) - self.footprint < STANDING_FOR_WITHIN);
                if near && r.v.abs() < STANDING {
                    self.stood_for_people_s += dt;
                }
            }
        }
    }

    /// The grid, for the figure and the recording.
    pub fn grid(&self) -> &Coverage {
        &self.grid
    }

    pub fn report(&self) -> SweepReport {
        SweepReport {
            swept: self.grid.summary(),
            time_s: self.first_down_s.map_or(0.0, |f| self.last_down_s - f),
            distance_m: self.distance_m,
            stood_for_people_s: self.stood_for_people_s,
        }
    }
}
