//! Semantic checks of a parsed scenario: every error names the field.

use glam::DVec2;

use super::*;

impl Scenario {
    /// Semantic checks; the error names the field.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let fail = |field: &str, msg: &str| Err((field.to_string(), msg.to_string()));
        let positive = |field: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err((
                    field.to_string(),
                    format!("must be a finite number > 0, got {v}"),
                ))
            }
        };
        let finite = |field: &str, vs: &[f64]| {
            if vs.iter().all(|v| v.is_finite()) {
                Ok(())
            } else {
                Err((
                    field.to_string(),
                    "must be finite (no nan or inf)".to_string(),
                ))
            }
        };
        let fraction = |field: &str, v: f64| {
            if (0.0..1.0).contains(&v) {
                Ok(())
            } else {
                Err((field.to_string(), format!("must be in [0, 1), got {v}")))
            }
        };

        let r = &self.robot;
        positive("robot.footprint_radius", r.footprint_radius)?;
        positive("robot.track_width", r.track_width)?;
        positive("robot.wheel_radius", r.wheel_radius)?;
        positive("robot.max_wheel_speed", r.max_wheel_speed)?;
        positive("robot.max_speed", r.max_speed)?;
        positive("robot.max_turn_rate", r.max_turn_rate)?;
        positive("robot.max_accel", r.max_accel)?;
        positive("robot.brake_decel", r.brake_decel)?;
        positive("robot.motor_time_constant_s", r.motor_time_constant_s)?;
        positive("robot.motor_no_load_speed", r.motor_no_load_speed)?;
        finite("robot.max_reverse_speed", &[r.max_reverse_speed])?;
        if r.ticks_per_rev == 0 {
            return fail("robot.ticks_per_rev", "must be > 0");
        }
        fraction("robot.motor_dead_band", r.motor_dead_band)?;

        if let Some(b) = self.map.bounds {
            finite("map.bounds.min", &b.min)?;
            finite("map.bounds.max", &b.max)?;
            if b.min[0] >= b.max[0] || b.min[1] >= b.max[1] {
                return fail("map.bounds", "`min` must lie below and left of `max`");
            }
            let inside =
                |p: DVec2| p.x > b.min[0] && p.y > b.min[1] && p.x < b.max[0] && p.y < b.max[1];
            for (i, r) in self.robots.iter().enumerate() {
                if !inside(DVec2::new(r.start.x, r.start.y)) {
                    return fail(&format!("robots[{i}].start"), "lies outside `map.bounds`");
                }
            }
            for (i, p) in self.route.points().iter().enumerate() {
                if !inside(*p) {
                    let field = if i + 1 == self.route.points().len() {
                        "route.goal".to_string()
                    } else {
                        format!("route.waypoints[{i}]")
                    };
                    return fail(&field, "lies outside `map.bounds`");
                }
            }
        }
        for (i, o) in self.map.obstacles.iter().enumerate() {
            let field = format!("map.obstacles[{i}]");
            o.check(&field)?;
            let at = |name: &str| format!("{field}.{name}");
            if let Some(c) = o.center {
                finite(&at("center"), &c)?;
            }
            if let Some(r) = o.radius {
                positive(&at("radius"), r)?;
            }
            for (name, p) in [
                ("from", o.from),
                ("to", o.to),
                ("min", o.min),
                ("max", o.max),
            ] {
                if let Some(p) = p {
                    finite(&at(name), &p)?;
                }
            }
            if o.kind == ObstacleKind::Segment && o.from == o.to {
                return fail(&at("to"), "a segment needs two distinct ends");
            }
            if let (Some(lo), Some(hi)) = (o.min, o.max) {
                if !(lo[0] < hi[0] && lo[1] < hi[1]) {
                    return fail(&at("max"), "max must be above and right of min");
                }
            }
            if let Some(points) = &o.points {
                if points.len() < 3 {
                    return fail(&at("points"), "a polygon needs at least 3 points");
                }
                for (j, p) in points.iter().enumerate() {
                    finite(&format!("{field}.points[{j}]"), p)?;
                }
            }
        }
        let map = self.build_map();

        if self.robots.is_empty() {
            return fail("robots", "at least a leader and one follower are needed");
        }
        let leaders = self
            .robots
            .iter()
            .filter(|r| r.role == Role::Leader)
            .count();
        if leaders != 1 {
            return fail(
                "robots",
                &format!("exactly one robot must have role = \"leader\", found {leaders}"),
            );
        }
        if self.followers().is_empty() {
            return fail("robots", "at least one follower is needed");
        }
        for (i, robot) in self.robots.iter().enumerate() {
            let field = format!("robots[{i}]");
            if robot.id == u16::MAX {
                return fail(&format!("{field}.id"), "id 65535 is reserved");
            }
            if self.robots[..i].iter().any(|o| o.id == robot.id) {
                return fail(
                    &format!("{field}.id"),
                    &format!("id {} is used twice", robot.id),
                );
            }
            let s = robot.start;
            finite(&format!("{field}.start"), &[s.x, s.y, s.heading_deg])?;
            finite(&format!("{field}.initial_speed"), &[robot.initial_speed])?;
            let clear = map.clearance(DVec2::new(s.x, s.y), 10.0);
            if clear < r.footprint_radius {
                return fail(
                    &format!("{field}.start"),
                    "the robot starts inside or touching an obstacle",
                );
            }
        }

        let f = &self.formation;
        positive("formation.distance", f.distance)?;
        finite("formation.angle_deg", &[f.angle_deg])?;
        if f.line_spacing < 2.0 * r.footprint_radius || !f.line_spacing.is_finite() {
            return fail(
                "formation.line_spacing",
                "must be at least two footprint radii (robots would touch)",
            );
        }
        finite("formation.margin", &[f.margin])?;
        positive("formation.transition_s", f.transition_s)?;
        finite("formation.min_dwell_s", &[f.min_dwell_s])?;
        positive("formation.lookahead", f.lookahead)?;
        if f.shape == ShapeName::Custom {
            if f.slots.len() != self.followers().len() {
                return fail(
                    "formation.slots",
                    &format!(
                        "one slot per follower: {} followers, {} slots",
                        self.followers().len(),
                        f.slots.len()
                    ),
                );
            }
            for (i, s) in f.slots.iter().enumerate() {
                positive(&format!("formation.slots[{i}].distance"), s.distance)?;
                finite(&format!("formation.slots[{i}].angle_deg"), &[s.angle_deg])?;
            }
        }

        let route = self.route.points();
        if route.is_empty() {
            return fail("route", "give a goal or at least one waypoint");
        }
        for (i, p) in route.iter().enumerate() {
            let field = if i < self.route.waypoints.len() {
                format!("route.waypoints[{i}]")
            } else {
                "route.goal".to_string()
            };
            finite(&field, &[p.x, p.y])?;
            if map.clearance(*p, 10.0) < r.footprint_radius {
                return fail(
                    &field,
                    "the point is inside or too close to an obstacle for the robot",
                );
            }
        }
        positive("route.arrival_tolerance", self.route.arrival_tolerance)?;
        positive("route.waypoint_tolerance", self.route.waypoint_tolerance)?;

        let p = &self.planner;
        positive("planner.k_a", p.k_a)?;
        positive("planner.k_r", p.k_r)?;
        positive("planner.r_det", p.r_det)?;
        positive("planner.attraction_saturation", p.attraction_saturation)?;
        positive("planner.max_speed", p.max_speed)?;
        positive("planner.max_turn_rate", p.max_turn_rate)?;
        positive("planner.max_accel", p.max_accel)?;
        positive("planner.heading_gain", p.heading_gain)?;
        positive("planner.follow_clearance", p.follow_clearance)?;
        positive(
            "planner.wait_for_followers_above",
            p.wait_for_followers_above,
        )?;

        let g = &self.follower;
        positive("follower.k1", g.k1)?;
        positive("follower.k2", g.k2)?;
        positive("follower.d", g.d)?;
        if g.leader_timeout_ms == 0 {
            return fail("follower.leader_timeout_ms", "must be > 0");
        }

        let l = &self.link;
        finite("link.latency_ms", &[l.latency_ms, l.jitter_ms])?;
        if l.latency_ms < 0.0 || l.jitter_ms < 0.0 {
            return fail("link.latency_ms", "latency and jitter must be ≥ 0");
        }
        fraction("link.loss", l.loss)?;
        fraction("link.byte_corruption", l.byte_corruption)?;
        if l.baud == 0 {
            return fail("link.baud", "must be > 0");
        }
        let z = &self.localization;
        finite(
            "localization.sigma_m",
            &[z.sigma_m, z.heading_sigma_deg, z.latency_ms],
        )?;
        positive("localization.rate_hz", z.rate_hz)?;
        positive("sim.duration_s", self.sim.duration_s)?;
        for (i, f) in self.faults.iter().enumerate() {
            let at = |name: &str| format!("faults[{i}].{name}");
            finite(&at("at_s"), &[f.at_s])?;
            if f.at_s < 0.0 {
                return fail(&at("at_s"), "must be ≥ 0");
            }
            if let Some(d) = f.duration_s {
                positive(&at("duration_s"), d)?;
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
                (true, None) => return fail(&format!("faults[{i}]"), "this fault needs `robot`"),
                (true, Some(id)) if !self.robots.iter().any(|r| r.id == id) => {
                    return fail(&at("robot"), &format!("no robot with id {id}"))
                }
                (false, Some(_)) => return fail(&at("robot"), "this fault does not take `robot`"),
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
            );
            match (needs_value, f.value) {
                (true, None) => return fail(&format!("faults[{i}]"), "this fault needs `value`"),
                (true, Some(v)) => positive(&at("value"), v)?,
                (false, Some(_)) => return fail(&at("value"), "this fault does not take `value`"),
                _ => {}
            }
        }
        if self.sim.physics_step_ms == 0 || 100 % self.sim.physics_step_ms != 0 {
            return fail(
                "sim.physics_step_ms",
                "must divide the 100 ms control period",
            );
        }
        Ok(())
    }
}
