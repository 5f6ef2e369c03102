//! Whether the fleet can reach every waypoint and the goal: the route planner, run on the
//! site map before anything moves. A scenario with no way is refused up front.

use glam::DVec2;

use super::{locate, Scenario, ScenarioError};
use crate::planner::route::{RouteParams, RoutePlanner};

impl Scenario {
    /// The route planner this scenario's fleet uses.
    pub fn route_planner(&self) -> RoutePlanner {
        let params = RouteParams::for_formation(&self.formation_spec());
        let start = self.leader().start;
        let mut points = self.route_points();
        points.push(DVec2::new(start.x, start.y));
        RoutePlanner::new(&self.build_map(), &points, params)
    }

    /// Every waypoint (and the goal) the line of robots cannot reach from the leader's
    /// start, in order, as `(field, why)`: all of them, not just the first (each leg is
    /// tried from the last waypoint that could be reached).
    pub fn route_problems(&self) -> Vec<(String, String)> {
        let planner = self.route_planner();
        let start = self.leader().start;
        let points = self.route.points();
        let mut from = DVec2::new(start.x, start.y);
        let mut problems = self.sweep_problems(&planner, &mut from);
        for (i, p) in points.iter().enumerate() {
            let field = if i + 1 == points.len() {
                "route.goal".to_string()
            } else {
                format!("route.waypoints[{i}]")
            };
            match planner.plan(from, *p, &[]) {
                Ok(_) => from = *p,
                Err(e) => problems.push((field, format!("cannot be reached: {e}"))),
            }
        }
        problems
    }
}

impl Scenario {
    /// Every area nothing can sweep: no room for a pass, or no way to its first pass from
    /// where the fleet is by then (`from`, moved on past each area swept).
    fn sweep_problems(&self, planner: &RoutePlanner, from: &mut DVec2) -> Vec<(String, String)> {
        let Some(plan) = self.sweep_plan() else {
            return Vec::new();
        };
        let mut problems = Vec::new();
        for area in &plan.areas {
            let field = format!("sweep[{}].polygon", area.index);
            let (Some(first), Some(last)) = (area.plan.passes.first(), area.plan.passes.last())
            else {
                problems.push((
                    field,
                    "no pass fits: the area has no room for the leader".to_string(),
                ));
                continue;
            };
            match planner.plan(*from, first.from, &[]) {
                Ok(_) => *from = last.to,
                Err(e) => problems.push((field, format!("cannot be reached: {e}"))),
            }
            if let Some(exit) = self.sweep[area.index].exit {
                *from = DVec2::new(exit[0], exit[1]);
            }
        }
        problems
    }

    /// [`Scenario::route_problems`] as errors located in the file's text `src`.
    pub fn route_errors(&self, src: &str, file: &str) -> Vec<ScenarioError> {
        self.route_problems()
            .into_iter()
            .map(|(field, message)| ScenarioError {
                file: file.to_string(),
                position: locate(src, &field),
                field,
                message,
            })
            .collect()
    }
}
