//! Semantic checks of a parsed scenario: every error names the field, and every error in
//! the file is listed (checks that need a part found bad are skipped, not failed again).

use glam::DVec2;
use protocol::messages::WireTwist;

use super::movers::{
    CrowdSpec, MoverSpec, MAX_MOVERS, MAX_MOVER_SIZE, MAX_MOVER_SPEED, MAX_PATH_POINTS,
};
use super::*;
use crate::coverage::grid::CELL;

/// How far from the site's origin any coordinate may lie, m: a city is smaller.
pub const MAX_COORDINATE: f64 = 1e6;
/// Most obstacles in `map.obstacles`, and again in `map.unmapped`.
pub const MAX_OBSTACLES: usize = 100_000;
/// Most points of one polygon.
pub const MAX_POLYGON_POINTS: usize = 1_000;
/// Most polygon points of a whole map.
pub const MAX_MAP_POINTS: usize = 200_000;
/// Most waypoints of a route.
pub const MAX_WAYPOINTS: usize = 10_000;
/// Most robots of a fleet (the base station's link table).
pub const MAX_FLEET: usize = 1024;
/// Most faults a simulation injects.
pub const MAX_FAULTS: usize = 1_000;
/// Areas to sweep in one file.
pub const MAX_AREAS: usize = 256;
/// Cells of the coverage grid over every area's box (about 50 MB for the station and
/// as much for the simulator's truth).
pub const MAX_COVERAGE_CELLS: f64 = 4e6;
/// How many times over the obstacles' boxes, each weighted by its points (1 for a circle
/// or segment), may cover the site's box: the planner measures every cell of a box from
/// every edge, so this bounds its work (a city map covers its site a few times).
pub const MAX_COVER: f64 = 1000.0;
/// Problems listed at most; the rest are counted.
const MAX_PROBLEMS: usize = 100;
/// The most followers abreast in a row: wider, a shape is a line sideways.
const MAX_PER_ROW: usize = 8;

/// The problems found so far, as `(field, message)`.
#[derive(Default)]
struct Problems(Vec<(String, String)>, usize);

impl Problems {
    /// How many problems so far.
    fn count(&self) -> usize {
        self.0.len() + self.1
    }

    fn fail(&mut self, field: &str, msg: &str) {
        if self.0.len() < MAX_PROBLEMS {
            self.0.push((field.to_string(), msg.to_string()));
        } else {
            self.1 += 1;
        }
    }

    /// Whether every coordinate is finite and within [`MAX_COORDINATE`] of the origin.
    fn coordinates(&mut self, field: &str, vs: &[f64]) -> bool {
        if !self.finite(field, vs) {
            return false;
        }
        let ok = vs.iter().all(|v| v.abs() <= MAX_COORDINATE);
        if !ok {
            self.fail(
                field,
                "must lie within 1,000,000 m of the site's origin (x and y)",
            );
        }
        ok
    }

    /// Whether `list` holds at most `max` items.
    fn at_most(&mut self, field: &str, len: usize, max: usize, what: &str) -> bool {
        let ok = len <= max;
        if !ok {
            self.fail(field, &format!("{len} {what}: at most {max}"));
        }
        ok
    }

    fn positive(&mut self, field: &str, v: f64) -> bool {
        let ok = v.is_finite() && v > 0.0;
        if !ok {
            self.fail(field, &format!("must be a finite number > 0, got {v}"));
        }
        ok
    }

    fn finite(&mut self, field: &str, vs: &[f64]) -> bool {
        let ok = vs.iter().all(|v| v.is_finite());
        if !ok {
            self.fail(field, "must be finite (no nan or inf)");
        }
        ok
    }

    fn non_negative(&mut self, field: &str, v: f64) -> bool {
        let ok = v.is_finite() && v >= 0.0;
        if !ok {
            self.fail(field, &format!("must be a finite number >= 0, got {v}"));
        }
        ok
    }

    fn fraction(&mut self, field: &str, v: f64) -> bool {
        let ok = (0.0..1.0).contains(&v);
        if !ok {
            self.fail(field, &format!("must be in [0, 1), got {v}"));
        }
        ok
    }
}

impl Scenario {
    /// Semantic checks: every problem, each naming its field.
    pub fn validate(&self) -> Result<(), Vec<(String, String)>> {
        let mut p = Problems::default();
        if !self.check_sizes(&mut p) {
            // Too large to check item by item: say so, and nothing else.
            return Err(p.0);
        }
        self.check_name(&mut p);
        self.check_robot(&mut p);
        let map_ok = self.check_map(&mut p);
        let robots_ok = self.check_robots(&mut p, map_ok);
        self.check_formation(&mut p, robots_ok);
        self.check_route(&mut p, map_ok);
        self.check_gains(&mut p);
        self.check_sim(&mut p);
        self.check_movers(&mut p);
        self.check_sweeps(&mut p);
        if p.1 > 0 {
            let more = format!("and {} more problems", p.1);
            p.0.push((String::new(), more));
        }
        if p.0.is_empty() {
            Ok(())
        } else {
            Err(p.0)
        }
    }

    /// The name is a plain file name: it names the report, figure and recording under
    /// `out/`, and a path (`../x`, `/etc/x`) would write them elsewhere.
    fn check_name(&self, p: &mut Problems) {
        let n = &self.name;
        let plain = |c: char| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.');
        let ok = !n.is_empty() && n.len() <= 100 && !n.starts_with('.') && n.chars().all(plain);
        if !ok {
            p.fail(
                "name",
                "must be a plain file name of up to 100 letters, digits, '-', '_' or '.' \
                 (not starting with '.'): it names the files written under out/",
            );
        }
    }

    /// The counts a file may not exceed: whether all are within theirs.
    fn check_sizes(&self, p: &mut Problems) -> bool {
        let mut ok = true;
        for (field, list) in [
            ("map.obstacles", &self.map.obstacles),
            ("map.unmapped", &self.map.unmapped),
        ] {
            ok &= p.at_most(field, list.len(), MAX_OBSTACLES, "obstacles");
            let mut points = 0;
            for (i, o) in list.iter().enumerate() {
                let n = o.points.as_ref().map_or(0, Vec::len);
                points += n;
                if n > MAX_POLYGON_POINTS {
                    let field = format!("{field}[{i}].points");
                    ok &= p.at_most(&field, n, MAX_POLYGON_POINTS, "points");
                }
            }
            ok &= p.at_most(field, points, MAX_MAP_POINTS, "polygon points in all");
        }
        ok &= p.at_most(
            "route.waypoints",
            self.route.waypoints.len(),
            MAX_WAYPOINTS,
            "waypoints",
        );
        ok &= p.at_most("robots", self.robots.len(), MAX_FLEET, "robots");
        ok &= p.at_most("sweep", self.sweep.len(), MAX_AREAS, "areas");
        for (i, a) in self.sweep.iter().enumerate() {
            let field = format!("sweep[{i}].polygon");
            ok &= p.at_most(&field, a.polygon.len(), MAX_POLYGON_POINTS, "points");
        }
        ok &= p.at_most("faults", self.faults.len(), MAX_FAULTS, "faults");
        let persons: usize = self
            .crowds
            .iter()
            .map(|c| c.persons().min(MAX_MOVERS + 1))
            .sum();
        ok &= p.at_most(
            "movers",
            self.movers.len() + persons,
            MAX_MOVERS,
            "movers (crowds' persons included)",
        );
        for (i, m) in self.movers.iter().enumerate() {
            let field = format!("movers[{i}].path");
            ok &= p.at_most(&field, m.path.len(), MAX_PATH_POINTS, "points");
        }
        ok && self.check_cover(p)
    }

    /// Whether the obstacles' boxes (weighted by points) cover the site at most
    /// [`MAX_COVER`] times over.
    fn check_cover(&self, p: &mut Problems) -> bool {
        let obstacles = || self.map.obstacles.iter().chain(&self.map.unmapped);
        let boxes: Vec<([DVec2; 2], f64)> = obstacles()
            .filter(|o| o.check("").is_ok())
            .map(|o| {
                let o = o.to_obstacle();
                let weight = match &o {
                    crate::geometry::Obstacle::Polygon { points } => points.len() as f64,
                    _ => 1.0,
                };
                (o.bounds(), weight)
            })
            // An obstacle out of bounds is refused by its own field's check.
            .filter(|([lo, hi], _)| {
                let within =
                    |q: DVec2| q.is_finite() && q.abs().max_element() <= 2.0 * MAX_COORDINATE;
                within(*lo) && within(*hi)
            })
            .collect();
        let mut lo = DVec2::splat(f64::INFINITY);
        let mut hi = DVec2::splat(f64::NEG_INFINITY);
        let starts = self.robots.iter().map(|r| DVec2::new(r.start.x, r.start.y));
        for q in boxes
            .iter()
            .flat_map(|(b, _)| *b)
            .chain(starts)
            .chain(self.route.points())
            .filter(|q| q.is_finite())
        {
            lo = lo.min(q);
            hi = hi.max(q);
        }
        let border = DVec2::splat(5.0);
        let site = (hi - lo + 2.0 * border).max(DVec2::ONE);
        let cover: f64 = boxes
            .iter()
            .map(|([a, b], w)| ((*b - *a).x + 0.1) * ((*b - *a).y + 0.1) * w)
            .sum::<f64>()
            / (site.x * site.y);
        let ok = cover <= MAX_COVER;
        if !ok {
            p.fail(
                "map.obstacles",
                &format!(
                    "the obstacles' boxes, each counted once per polygon point, cover the \
                     site {cover:.0} times over (at most {MAX_COVER:.0}): describe each \
                     obstacle once, as a simple shape"
                ),
            );
        }
        ok
    }

    fn check_robot(&self, p: &mut Problems) {
        let r = &self.robot;
        p.positive("robot.footprint_radius", r.footprint_radius);
        p.positive("robot.track_width", r.track_width);
        p.positive("robot.wheel_radius", r.wheel_radius);
        p.positive("robot.max_wheel_speed", r.max_wheel_speed);
        // The leader-state frame carries v and ω to ±2.047 (m/s, rad/s).
        let wire = f64::from(WireTwist::LIMIT) / 1000.0;
        for (field, v) in [
            ("robot.max_speed", r.max_speed),
            ("robot.max_turn_rate", r.max_turn_rate),
        ] {
            if p.positive(field, v) && v > wire {
                p.fail(
                    field,
                    &format!("{v}: at most {wire} (the leader-state frame's range)"),
                );
            }
        }
        p.positive("robot.max_accel", r.max_accel);
        p.positive("robot.brake_decel", r.brake_decel);
        p.positive("robot.motor_time_constant_s", r.motor_time_constant_s);
        p.positive("robot.motor_no_load_speed", r.motor_no_load_speed);
        p.positive("robot.mass_kg", r.mass_kg);
        p.finite("robot.max_reverse_speed", &[r.max_reverse_speed]);
        if r.ticks_per_rev == 0 {
            p.fail("robot.ticks_per_rev", "must be > 0");
        }
        p.fraction("robot.motor_dead_band", r.motor_dead_band);
    }

    /// The site's bounds and obstacles; whether the map can be built.
    fn check_map(&self, p: &mut Problems) -> bool {
        let before = p.0.len();
        if let Some(b) = self.map.bounds {
            let finite =
                p.coordinates("map.bounds.min", &b.min) & p.coordinates("map.bounds.max", &b.max);
            if finite && (b.min[0] >= b.max[0] || b.min[1] >= b.max[1]) {
                p.fail("map.bounds", "`min` must lie below and left of `max`");
            } else if finite {
                let inside =
                    |q: DVec2| q.x > b.min[0] && q.y > b.min[1] && q.x < b.max[0] && q.y < b.max[1];
                for (i, r) in self.robots.iter().enumerate() {
                    if !inside(DVec2::new(r.start.x, r.start.y)) {
                        p.fail(&format!("robots[{i}].start"), "lies outside `map.bounds`");
                    }
                }
                let points = self.route.points();
                for (i, q) in points.iter().enumerate() {
                    if !inside(*q) {
                        p.fail(&self.route_field(i), "lies outside `map.bounds`");
                    }
                }
            }
        }
        for (list, obstacles) in [
            ("map.obstacles", &self.map.obstacles),
            ("map.unmapped", &self.map.unmapped),
        ] {
            for (i, o) in obstacles.iter().enumerate() {
                check_obstacle(p, &format!("{list}[{i}]"), o);
            }
        }
        p.0.len() == before
    }

    /// The robots and their starts; whether there is one leader and a follower.
    fn check_robots(&self, p: &mut Problems, map_ok: bool) -> bool {
        if self.robots.is_empty() {
            p.fail("robots", "at least a leader and one follower are needed");
            return false;
        }
        let leaders = self
            .robots
            .iter()
            .filter(|r| r.role == Role::Leader)
            .count();
        let mut ok = true;
        if leaders != 1 {
            p.fail(
                "robots",
                &format!("exactly one robot must have role = \"leader\", found {leaders}"),
            );
            ok = false;
        }
        if self.followers().is_empty() {
            p.fail("robots", "at least one follower is needed");
            ok = false;
        }
        let site = map_ok.then(|| self.build_site());
        let footprint = self.robot.footprint_radius;
        for (i, robot) in self.robots.iter().enumerate() {
            let field = format!("robots[{i}]");
            if robot.id == u16::MAX {
                p.fail(&format!("{field}.id"), "id 65535 is reserved");
            }
            if self.robots[..i].iter().any(|o| o.id == robot.id) {
                p.fail(
                    &format!("{field}.id"),
                    &format!("id {} is used twice", robot.id),
                );
            }
            let s = robot.start;
            let start_ok = p.coordinates(&format!("{field}.start"), &[s.x, s.y])
                && p.finite(&format!("{field}.start"), &[s.heading_deg]);
            p.finite(&format!("{field}.initial_speed"), &[robot.initial_speed]);
            if let (true, Some(site)) = (start_ok, &site) {
                if site.clearance(DVec2::new(s.x, s.y), 10.0) < footprint {
                    p.fail(
                        &format!("{field}.start"),
                        "the robot starts inside or touching an obstacle",
                    );
                }
            }
        }
        ok
    }

    fn check_formation(&self, p: &mut Problems, robots_ok: bool) {
        let f = &self.formation;
        let before = p.count();
        p.positive("formation.distance", f.distance);
        p.finite("formation.angle_deg", &[f.angle_deg]);
        if f.line_spacing < 2.0 * self.robot.footprint_radius || !f.line_spacing.is_finite() {
            p.fail(
                "formation.line_spacing",
                "must be at least two footprint radii (robots would touch)",
            );
        }
        p.finite("formation.margin", &[f.margin]);
        p.positive("formation.transition_s", f.transition_s);
        p.finite("formation.min_dwell_s", &[f.min_dwell_s]);
        p.positive("formation.lookahead", f.lookahead);
        if f.shape == ShapeName::Rows && !(1..=MAX_PER_ROW).contains(&f.per_row) {
            p.fail(
                "formation.per_row",
                &format!("must be 1 to {MAX_PER_ROW} followers abreast"),
            );
        }
        if f.shape == ShapeName::Custom {
            if robots_ok && f.slots.len() != self.followers().len() {
                p.fail(
                    "formation.slots",
                    &format!(
                        "one slot per follower: {} followers, {} slots",
                        self.followers().len(),
                        f.slots.len()
                    ),
                );
            }
            for (i, s) in f.slots.iter().enumerate() {
                p.positive(&format!("formation.slots[{i}].distance"), s.distance);
                p.finite(&format!("formation.slots[{i}].angle_deg"), &[s.angle_deg]);
            }
        }
        if robots_ok && p.count() == before {
            self.check_shape_room(p);
        }
    }

    /// The wide shape must leave every robot room: no slot within two footprint radii of
    /// the leader or of another slot (the robots would touch standing in it).
    fn check_shape_room(&self, p: &mut Problems) {
        let spec = self.formation_spec();
        let field = |k: usize| match self.formation.shape {
            ShapeName::Custom => format!("formation.slots[{k}]"),
            ShapeName::Rows => "formation.line_spacing".to_string(),
            _ => "formation.distance".to_string(),
        };
        let at = |(l, a): (f64, f64)| DVec2::new(l * a.cos(), l * a.sin());
        let mut points = vec![("the leader".to_string(), DVec2::ZERO)];
        points.extend(
            spec.wide_slots()
                .into_iter()
                .enumerate()
                .map(|(k, s)| (format!("slot {k}"), at(s))),
        );
        let need = 2.0 * self.robot.footprint_radius;
        for (k, (name, q)) in points.iter().enumerate().skip(1) {
            let near = points[..k].iter().find(|(_, o)| o.distance(*q) < need);
            if let Some((other, o)) = near {
                p.fail(
                    &field(k - 1),
                    &format!(
                        "{name} is {:.2} m from {other}: robots {need:.2} m across would touch \
                         (set the slots farther apart)",
                        o.distance(*q)
                    ),
                );
                return;
            }
        }
    }

    fn route_field(&self, i: usize) -> String {
        if i < self.route.waypoints.len() {
            format!("route.waypoints[{i}]")
        } else {
            "route.goal".to_string()
        }
    }

    fn check_route(&self, p: &mut Problems, map_ok: bool) {
        let route = self.route.points();
        if route.is_empty() && self.sweep.is_empty() {
            p.fail("route", "give a goal, a waypoint or an area to sweep");
        }
        // The known map: a waypoint beside something unmapped is the route's problem to
        // solve on the way, not the file's.
        let map = map_ok.then(|| self.build_map());
        for (i, q) in route.iter().enumerate() {
            let field = self.route_field(i);
            if !p.coordinates(&field, &[q.x, q.y]) {
                continue;
            }
            if let Some(map) = &map {
                if map.clearance(*q, 10.0) < self.robot.footprint_radius {
                    p.fail(
                        &field,
                        "the point is inside or too close to an obstacle for the robot",
                    );
                }
            }
        }
        p.positive("route.arrival_tolerance", self.route.arrival_tolerance);
        p.positive("route.waypoint_tolerance", self.route.waypoint_tolerance);
    }

    /// Each area: an outline of at least three points, not crossing itself, within reach of
    /// coordinates; an overlap less than the swath; entry and exit points.
    fn check_sweeps(&self, p: &mut Problems) {
        if self.sweep.is_empty() {
            return;
        }
        let swath = self.swath();
        p.positive("robot.brush_width", self.robot.brush_width);
        let corners = self.sweep.iter().flat_map(|a| a.polygon.iter());
        let (lo, hi) = corners.fold(([f64::MAX; 2], [f64::MIN; 2]), |(lo, hi), q| {
            (
                [lo[0].min(q[0]), lo[1].min(q[1])],
                [hi[0].max(q[0]), hi[1].max(q[1])],
            )
        });
        let cells = ((hi[0] - lo[0]) / CELL + 1.0) * ((hi[1] - lo[1]) / CELL + 1.0);
        if cells > MAX_COVERAGE_CELLS {
            p.fail(
                "sweep",
                &format!(
                    "the areas' box is {:.0} m²: at most {:.0} m² (the coverage grid's {} cells \
                     of {CELL} m); sweep a larger site in several runs",
                    cells * CELL * CELL,
                    MAX_COVERAGE_CELLS * CELL * CELL,
                    MAX_COVERAGE_CELLS
                ),
            );
        }
        for (i, a) in self.sweep.iter().enumerate() {
            let field = format!("sweep[{i}].polygon");
            let flat: Vec<f64> = a.polygon.iter().flatten().copied().collect();
            if a.polygon.len() < 3 {
                p.fail(&field, "give at least three points");
            } else if p.coordinates(&field, &flat) {
                let points = a.points();
                if crosses_itself(&points) {
                    p.fail(&field, "the outline crosses itself");
                } else if crate::coverage::area(&points) < 1.0 {
                    p.fail(&field, "the area is under 1 m²");
                }
            }
            let overlap = format!("sweep[{i}].overlap");
            if p.non_negative(&overlap, a.overlap) && a.overlap >= 0.5 * swath.width {
                p.fail(
                    &overlap,
                    &format!(
                        "must be under half the swath ({:.2} m of {:.2} m)",
                        0.5 * swath.width,
                        swath.width
                    ),
                );
            }
            if let Some(d) = a.direction_deg {
                p.finite(&format!("sweep[{i}].direction_deg"), &[d]);
            }
            for (name, q) in [("entry", a.entry), ("exit", a.exit)] {
                if let Some(q) = q {
                    p.coordinates(&format!("sweep[{i}].{name}"), &q);
                }
            }
        }
    }

    fn check_gains(&self, p: &mut Problems) {
        let g = &self.planner;
        p.positive("planner.k_a", g.k_a);
        p.positive("planner.k_r", g.k_r);
        p.positive("planner.r_det", g.r_det);
        p.positive("planner.attraction_saturation", g.attraction_saturation);
        p.positive("planner.max_speed", g.max_speed);
        p.positive("planner.max_turn_rate", g.max_turn_rate);
        p.positive("planner.max_accel", g.max_accel);
        p.positive("planner.heading_gain", g.heading_gain);
        p.non_negative("planner.turn_dead_band", g.turn_dead_band);
        p.positive("planner.follow_clearance", g.follow_clearance);
        p.positive(
            "planner.wait_for_followers_above",
            g.wait_for_followers_above,
        );

        let f = &self.follower;
        p.positive("follower.k1", f.k1);
        p.positive("follower.k2", f.k2);
        p.positive("follower.d", f.d);
        if f.leader_timeout_ms == 0 {
            p.fail("follower.leader_timeout_ms", "must be > 0");
        }
    }

    fn check_sim(&self, p: &mut Problems) {
        self.check_link(p);
        self.check_localization(p);
        p.positive("sim.duration_s", self.sim.duration_s);
        for (i, f) in self.faults.iter().enumerate() {
            self.check_fault(p, i, f);
        }
        if self.sim.physics_step_ms == 0 || 100 % self.sim.physics_step_ms != 0 {
            p.fail(
                "sim.physics_step_ms",
                "must divide the 100 ms control period",
            );
        }
    }

    fn check_link(&self, p: &mut Problems) {
        let l = &self.link;
        if p.finite("link.latency_ms", &[l.latency_ms, l.jitter_ms])
            && (l.latency_ms < 0.0 || l.jitter_ms < 0.0)
        {
            p.fail("link.latency_ms", "latency and jitter must be ≥ 0");
        }
        p.fraction("link.loss", l.loss);
        p.fraction("link.byte_corruption", l.byte_corruption);
        if l.baud == 0 {
            p.fail("link.baud", "must be > 0");
        }
        if let Err((field, msg)) = l.channel() {
            p.fail(field, &msg);
        }
    }

    /// `[localization]`, and `[perception]`'s limits.
    fn check_localization(&self, p: &mut Problems) {
        let z = &self.localization;
        if p.finite(
            "localization.sigma_m",
            &[z.sigma_m, z.heading_sigma_deg, z.latency_ms],
        ) && z.sigma_m < 0.001
        {
            // The robots refuse a fix that claims no error at all: no source is perfect.
            p.fail("localization.sigma_m", "must be at least 0.001 m");
        }
        p.positive("localization.rate_hz", z.rate_hz);
        p.positive("perception.max_range_m", self.perception.max_range_m);
        p.positive("perception.forget_after_s", self.perception.forget_after_s);
        p.positive("localization.forward_hz", z.forward_hz);
        if p.positive("localization.lost_after_s", z.lost_after_s)
            && p.positive("localization.stop_after_s", z.stop_after_s)
            && z.stop_after_s < z.lost_after_s
        {
            p.fail("localization.stop_after_s", "must be ≥ lost_after_s");
        }
        if let Some(o) = &z.origin {
            if !(o.lat_deg.is_finite() && o.lat_deg.abs() < 90.0) {
                p.fail(
                    "localization.origin.lat_deg",
                    "must be a latitude in (−90, 90)",
                );
            }
            if !(o.lon_deg.is_finite() && o.lon_deg.abs() <= 180.0) {
                p.fail(
                    "localization.origin.lon_deg",
                    "must be a longitude in [−180, 180]",
                );
            }
            p.finite(
                "localization.origin.x_axis_bearing_deg",
                &[o.x_axis_bearing_deg],
            );
        }
    }

    /// `faults[i]`: its time, and the robot and value its kind takes.
    fn check_fault(&self, p: &mut Problems, i: usize, f: &FaultSpec) {
        let at = |name: &str| format!("faults[{i}].{name}");
        if p.finite(&at("at_s"), &[f.at_s]) && f.at_s < 0.0 {
            p.fail(&at("at_s"), "must be ≥ 0");
        }
        if let Some(d) = f.duration_s {
            p.positive(&at("duration_s"), d);
        }
        let needs_robot = matches!(
            f.kind,
            FaultKind::Reboot
                | FaultKind::StuckWheel
                | FaultKind::WeakMotor
                | FaultKind::EncoderDead
                | FaultKind::PoseJump
        );
        match (needs_robot, f.robot) {
            (true, None) => p.fail(&format!("faults[{i}]"), "this fault needs `robot`"),
            (true, Some(id)) if !self.robots.iter().any(|r| r.id == id) => {
                p.fail(&at("robot"), &format!("no robot with id {id}"))
            }
            (false, Some(_)) => p.fail(&at("robot"), "this fault does not take `robot`"),
            _ => {}
        }
        let needs_value = matches!(
            f.kind,
            FaultKind::LatencySpike
                | FaultKind::WrongKeyAttacker
                | FaultKind::ReplayAttacker
                | FaultKind::GarbageFlood
                | FaultKind::WeakMotor
                | FaultKind::PoseJump
                | FaultKind::Reorder
                | FaultKind::Corruption
                | FaultKind::DelayRelay
                | FaultKind::HelloReplay
                | FaultKind::WelcomeHoldback
                | FaultKind::CapturedRobot
        );
        match (needs_value, f.value) {
            (true, None) => p.fail(&format!("faults[{i}]"), "this fault needs `value`"),
            (true, Some(v)) => {
                p.positive(&at("value"), v);
            }
            (false, Some(_)) => p.fail(&at("value"), "this fault does not take `value`"),
            _ => {}
        }
    }
}

impl Scenario {
    /// `[yielding]`, `[[movers]]` and `[[crowds]]`.
    fn check_movers(&self, p: &mut Problems) {
        let y = &self.yielding;
        p.non_negative("yielding.personal_space_m", y.personal_space_m);
        p.positive("yielding.horizon_s", y.horizon_s);
        p.positive("yielding.replan_after_s", y.replan_after_s);
        if p.positive("yielding.passing_share", y.passing_share) && y.passing_share > 1.0 {
            p.fail(
                "yielding.passing_share",
                &format!(
                    "must be at most 1 (the leader's full pace), got {}",
                    y.passing_share
                ),
            );
        }
        for (i, m) in self.movers.iter().enumerate() {
            check_mover(p, &format!("movers[{i}]"), m);
        }
        for (i, c) in self.crowds.iter().enumerate() {
            check_crowd(p, &format!("crowds[{i}]"), c);
        }
    }
}

fn check_mover(p: &mut Problems, field: &str, m: &MoverSpec) {
    let at = |name: &str| format!("{field}.{name}");
    if m.path.is_empty() {
        p.fail(&at("path"), "give at least one point");
    }
    for (j, q) in m.path.iter().enumerate() {
        p.coordinates(&format!("{field}.path[{j}]"), q);
    }
    if p.positive(&at("speed"), m.speed) && m.speed > MAX_MOVER_SPEED {
        p.fail(&at("speed"), "must be at most 30 m/s");
    }
    p.non_negative(&at("start_s"), m.start_s);
    match (m.radius, m.length, m.width) {
        (None, None, None) => {}
        (Some(r), None, None) => size(p, &at("radius"), r),
        (None, Some(l), Some(w)) => {
            size(p, &at("length"), l);
            size(p, &at("width"), w);
        }
        _ => p.fail(
            field,
            "a footprint is `radius` (a circle) or `length` and `width` (a rectangle)",
        ),
    }
    for (j, pause) in m.pauses.iter().enumerate() {
        if pause.at >= m.path.len() {
            let msg = format!("point {} of a {}-point path", pause.at, m.path.len());
            p.fail(&format!("{field}.pauses[{j}].at"), &msg);
        }
        p.positive(&format!("{field}.pauses[{j}].for_s"), pause.for_s);
    }
}

/// A footprint's radius or side: positive, at most [`MAX_MOVER_SIZE`].
fn size(p: &mut Problems, field: &str, v: f64) {
    if p.positive(field, v) && v > MAX_MOVER_SIZE {
        p.fail(field, "must be at most 20 m");
    }
}

fn check_crowd(p: &mut Problems, field: &str, c: &CrowdSpec) {
    let at = |name: &str| format!("{field}.{name}");
    let b = c.area;
    if p.coordinates(&at("area.min"), &b.min) & p.coordinates(&at("area.max"), &b.max)
        && (b.min[0] >= b.max[0] || b.min[1] >= b.max[1])
    {
        p.fail(&at("area"), "`min` must lie below and left of `max`");
    }
    if p.positive(&at("density"), c.density) && c.density > 2.0 {
        p.fail(&at("density"), "at most 2 persons/m² (a packed crowd)");
    }
    if p.positive(&at("speed_mean"), c.speed_mean) && c.speed_mean > 3.0 {
        p.fail(&at("speed_mean"), "a walking speed, at most 3 m/s");
    }
    p.non_negative(&at("speed_sd"), c.speed_sd);
    p.non_negative(&at("start_s"), c.start_s);
}

/// One obstacle's fields, under `field`.
fn check_obstacle(p: &mut Problems, field: &str, o: &ObstacleSpec) {
    if let Err((f, msg)) = o.check(field) {
        p.fail(&f, &msg);
        return;
    }
    let at = |name: &str| format!("{field}.{name}");
    if let Some(c) = o.center {
        p.coordinates(&at("center"), &c);
    }
    if let Some(r) = o.radius {
        if p.positive(&at("radius"), r) && r > MAX_COORDINATE {
            p.fail(&at("radius"), "must be at most 1,000,000 m");
        }
    }
    for (name, q) in [
        ("from", o.from),
        ("to", o.to),
        ("min", o.min),
        ("max", o.max),
    ] {
        if let Some(q) = q {
            p.coordinates(&at(name), &q);
        }
    }
    if o.kind == ObstacleKind::Segment && o.from == o.to {
        p.fail(&at("to"), "a segment needs two distinct ends");
    }
    if let (Some(lo), Some(hi)) = (o.min, o.max) {
        if !(lo[0] < hi[0] && lo[1] < hi[1]) {
            p.fail(&at("max"), "max must be above and right of min");
        }
    }
    if let Some(points) = &o.points {
        if points.len() < 3 {
            p.fail(&at("points"), "a polygon needs at least 3 points");
        }
        for (j, q) in points.iter().enumerate() {
            p.coordinates(&format!("{field}.points[{j}]"), q);
        }
    }
}

/// Whether two edges of the closed outline `points` cross (neighbours share a corner).
fn crosses_itself(points: &[DVec2]) -> bool {
    let n = points.len();
    let edge = |i: usize| (points[i], points[(i + 1) % n]);
    let cross = |(a, b): (DVec2, DVec2), (c, d): (DVec2, DVec2)| {
        let side = |p: DVec2, q: DVec2, r: DVec2| (q - p).perp_dot(r - p);
        side(a, b, c) * side(a, b, d) < 0.0 && side(c, d, a) * side(c, d, b) < 0.0
    };
    (0..n).any(|i| ((i + 2)..n).any(|j| (i + n - j) % n != 1 && cross(edge(i), edge(j))))
}
