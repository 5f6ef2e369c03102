//! Semantic checks of a parsed scenario: every error names the field, and every error in
//! the file is listed (checks that need a part found bad are skipped, not failed again).

use glam::DVec2;

use super::*;

/// The problems found so far, as `(field, message)`.
#[derive(Default)]
struct Problems(Vec<(String, String)>);

impl Problems {
    fn fail(&mut self, field: &str, msg: &str) {
        self.0.push((field.to_string(), msg.to_string()));
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
        self.check_robot(&mut p);
        let map_ok = self.check_map(&mut p);
        let robots_ok = self.check_robots(&mut p, map_ok);
        self.check_formation(&mut p, robots_ok);
        self.check_route(&mut p, map_ok);
        self.check_gains(&mut p);
        self.check_sim(&mut p);
        if p.0.is_empty() {
            Ok(())
        } else {
            Err(p.0)
        }
    }

    fn check_robot(&self, p: &mut Problems) {
        let r = &self.robot;
        p.positive("robot.footprint_radius", r.footprint_radius);
        p.positive("robot.track_width", r.track_width);
        p.positive("robot.wheel_radius", r.wheel_radius);
        p.positive("robot.max_wheel_speed", r.max_wheel_speed);
        p.positive("robot.max_speed", r.max_speed);
        p.positive("robot.max_turn_rate", r.max_turn_rate);
        p.positive("robot.max_accel", r.max_accel);
        p.positive("robot.brake_decel", r.brake_decel);
        p.positive("robot.motor_time_constant_s", r.motor_time_constant_s);
        p.positive("robot.motor_no_load_speed", r.motor_no_load_speed);
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
            let finite = p.finite("map.bounds.min", &b.min) & p.finite("map.bounds.max", &b.max);
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
            let start_ok = p.finite(&format!("{field}.start"), &[s.x, s.y, s.heading_deg]);
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
        if route.is_empty() {
            p.fail("route", "give a goal or at least one waypoint");
        }
        // The known map: a waypoint beside something unmapped is the route's problem to
        // solve on the way, not the file's.
        let map = map_ok.then(|| self.build_map());
        for (i, q) in route.iter().enumerate() {
            let field = self.route_field(i);
            if !p.finite(&field, &[q.x, q.y]) {
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
        p.positive("sim.duration_s", self.sim.duration_s);
        for (i, f) in self.faults.iter().enumerate() {
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
        if self.sim.physics_step_ms == 0 || 100 % self.sim.physics_step_ms != 0 {
            p.fail(
                "sim.physics_step_ms",
                "must divide the 100 ms control period",
            );
        }
    }
}

/// One obstacle's fields, under `field`.
fn check_obstacle(p: &mut Problems, field: &str, o: &ObstacleSpec) {
    if let Err((f, msg)) = o.check(field) {
        p.fail(&f, &msg);
        return;
    }
    let at = |name: &str| format!("{field}.{name}");
    if let Some(c) = o.center {
        p.finite(&at("center"), &c);
    }
    if let Some(r) = o.radius {
        p.positive(&at("radius"), r);
    }
    for (name, q) in [
        ("from", o.from),
        ("to", o.to),
        ("min", o.min),
        ("max", o.max),
    ] {
        if let Some(q) = q {
            p.finite(&at(name), &q);
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
            p.finite(&format!("{field}.points[{j}]"), q);
        }
    }
}
