//! `[[sweep]]`: areas to sweep, and the route that sweeps them (the leader's waypoints,
//! pass by pass, before the route's own).

use glam::DVec2;
use serde::{Deserialize, Serialize};

use super::Scenario;
use crate::coverage::plan::{plan_area, AreaPlan, SweepParams};
use crate::coverage::watch::{AreaSetup, SweepSetup};
use crate::coverage::{self, Swath};
use crate::planner::route::RouteParams;

/// One area to sweep.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SweepSpec {
    /// As events and the report name it (default: `area N`).
    #[serde(default)]
    pub name: Option<String>,
    /// The area's outline, vertices in order; what the map holds inside is left out.
    pub polygon: Vec<[f64; 2]>,
    /// How much neighbouring passes overlap, m: the followers' tracking error and the
    /// brushes' wear eat into the swath.
    #[serde(default = "default_overlap")]
    pub overlap: f64,
    /// Areas are swept by `order` (lower first), then in the file's order.
    #[serde(default)]
    pub order: i32,
    /// The passes' direction, degrees from +x (default: the one with the fewest passes).
    #[serde(default)]
    pub direction_deg: Option<f64>,
    /// Where the sweep of this area begins: the pass nearest this point.
    #[serde(default)]
    pub entry: Option<[f64; 2]>,
    /// Where the fleet goes when the area is swept, before the next one.
    #[serde(default)]
    pub exit: Option<[f64; 2]>,
}

/// Beyond the route planner's own clearance: its grid measures to a cell, m.
const PASS_MARGIN: f64 = 0.15;

fn default_overlap() -> f64 {
    0.15
}

impl SweepSpec {
    pub fn points(&self) -> Vec<DVec2> {
        self.polygon
            .iter()
            .map(|p| DVec2::new(p[0], p[1]))
            .collect()
    }
}

/// The plan of one area, with what it was planned for.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedArea {
    /// Index in the file's `sweep`.
    pub index: usize,
    pub name: String,
    pub plan: AreaPlan,
    /// The area's outline's area, m².
    pub outline_m2: f64,
}

/// The whole sweep: its areas in the order swept, and the swath planned for.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepPlan {
    pub areas: Vec<PlannedArea>,
    pub swath: Swath,
    pub spacing: f64,
}

impl SweepPlan {
    /// The leader's waypoints: every pass's ends, each area's exit after it.
    pub fn waypoints(&self, specs: &[SweepSpec]) -> Vec<DVec2> {
        let mut out = Vec::new();
        for a in &self.areas {
            out.extend(a.plan.passes.iter().flat_map(|p| p.points()));
            out.extend(specs[a.index].exit.map(|e| DVec2::new(e[0], e[1])));
        }
        out
    }

    /// The passes in all.
    pub fn passes(&self) -> usize {
        self.areas.iter().map(|a| a.plan.passes.len()).sum()
    }
}

impl Scenario {
    /// The swath the formation's wide shape sweeps with `[robot] brush_width`.
    pub fn swath(&self) -> Swath {
        coverage::swath(&self.formation_spec(), self.robot.brush_width)
    }

    /// The coverage route of every `[[sweep]]` area, in order (`None` without any).
    pub fn sweep_plan(&self) -> Option<SweepPlan> {
        if self.sweep.is_empty() {
            return None;
        }
        let formation = self.formation_spec();
        let swath = self.swath();
        let route = RouteParams::for_formation(&formation);
        let map = self.build_map();
        let mut order: Vec<usize> = (0..self.sweep.len()).collect();
        order.sort_by_key(|i| (self.sweep[*i].order, *i));
        let start = self.leader().start;
        let mut at = DVec2::new(start.x, start.y);
        let mut spacing = f64::INFINITY;
        let mut areas = Vec::new();
        for i in order {
            let spec = &self.sweep[i];
            let params = SweepParams {
                swath: swath.width,
                spacing: (swath.width - spec.overlap).max(0.05),
                clearance: route.hard_clearance + PASS_MARGIN,
                trail: coverage::trail(&formation),
                direction: spec.direction_deg.map(f64::to_radians),
            };
            spacing = spacing.min(params.spacing);
            let from = spec.entry.map_or(at, |e| DVec2::new(e[0], e[1]));
            let polygon = spec.points();
            let plan = plan_area(&polygon, &map, &params, from);
            at = plan.passes.last().map_or(from, |p| p.to);
            at = spec.exit.map_or(at, |e| DVec2::new(e[0], e[1]));
            areas.push(PlannedArea {
                index: i,
                name: spec.name.clone().unwrap_or_else(|| format!("area {i}")),
                outline_m2: coverage::area(&polygon),
                plan,
            });
        }
        Some(SweepPlan {
            areas,
            swath,
            spacing,
        })
    }

    /// What the station needs to watch the sweep and go back for what it missed.
    pub fn sweep_setup(&self) -> Option<SweepSetup> {
        let plan = self.sweep_plan()?;
        let brush = self.robot.brush_width;
        let mut points = 0;
        let areas = plan
            .areas
            .iter()
            .map(|a| {
                let spec = &self.sweep[a.index];
                points += a
                    .plan
                    .passes
                    .iter()
                    .map(|p| p.points().count())
                    .sum::<usize>();
                points += usize::from(spec.exit.is_some());
                AreaSetup {
                    name: a.name.clone(),
                    polygon: spec.points(),
                    direction: a.plan.direction,
                    last_point: points.saturating_sub(1),
                    spacing: (brush - spec.overlap).max(0.5 * brush),
                }
            })
            .collect();
        let route = RouteParams::for_formation(&self.formation_spec());
        Some(SweepSetup {
            areas,
            brush,
            footprint: self.robot.footprint_radius,
            clearance: route.hard_clearance + PASS_MARGIN,
        })
    }

    /// The points the leader drives to, in order: the sweep's, then the route's.
    pub fn route_points(&self) -> Vec<DVec2> {
        let mut points = self
            .sweep_plan()
            .map(|plan| plan.waypoints(&self.sweep))
            .unwrap_or_default();
        points.extend(self.route.points());
        points
    }
}
