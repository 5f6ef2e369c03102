//! What a scenario lowers itself to, in one place: the station's site map and the
//! simulated site, the planner's parameters, the formation's spec, and the robots' own
//! configuration (`control_core::config::RobotConfig`).

use control_core::config::{self, RobotConfig};
use control_core::kinematics::DiffDrive;
use control_core::pid::PidGains;
use glam::DVec2;

use super::{ObstacleSpec, PlannerMode, Scenario, ShapeName, SLOT_SPEED_OF_MAX};
use crate::formation::{FormationSpec, WideShape};
use crate::geometry::map::Map;
use crate::geometry::Obstacle;
use crate::planner::apf::ApfParams;
use crate::planner::{Guidance, PlannerParams};

impl Scenario {
    /// The site map the base station holds: the obstacles, and the site's edge as four
    /// walls.
    pub fn build_map(&self) -> Map {
        Map::new(self.map_obstacles())
    }

    /// The site as it is (what the simulated robots meet): the map and what it does not
    /// hold (`map.unmapped`).
    pub fn build_site(&self) -> Map {
        let mut obstacles = self.map_obstacles();
        obstacles.extend(self.map.unmapped.iter().map(ObstacleSpec::to_obstacle));
        Map::new(obstacles)
    }

    fn map_obstacles(&self) -> Vec<Obstacle> {
        let mut obstacles: Vec<Obstacle> = self
            .map
            .obstacles
            .iter()
            .map(ObstacleSpec::to_obstacle)
            .collect();
        if let Some(b) = self.map.bounds {
            let (lo, hi) = (DVec2::from(b.min), DVec2::from(b.max));
            let corners = [lo, DVec2::new(hi.x, lo.y), hi, DVec2::new(lo.x, hi.y)];
            for i in 0..4 {
                obstacles.push(Obstacle::Segment {
                    a: corners[i],
                    b: corners[(i + 1) % 4],
                });
            }
        }
        obstacles
    }

    pub fn planner_params(&self) -> PlannerParams {
        let p = &self.planner;
        PlannerParams {
            apf: ApfParams {
                k_a: p.k_a,
                k_r: p.k_r,
                r_det: p.r_det,
                attraction_saturation: p.attraction_saturation,
                footprint: self.robot.footprint_radius,
            },
            max_speed: p.max_speed,
            max_turn_rate: p.max_turn_rate,
            max_accel: p.max_accel,
            heading_gain: p.heading_gain,
            turn_dead_band: p.turn_dead_band,
            arrival_tolerance: self.route.arrival_tolerance,
            waypoint_tolerance: self.route.waypoint_tolerance,
            follow_clearance: p.follow_clearance,
            guidance: match p.mode {
                PlannerMode::Route => Guidance::Route,
                PlannerMode::Apf => Guidance::Field,
            },
            ..PlannerParams::DEFAULT
        }
    }

    pub fn formation_spec(&self) -> FormationSpec {
        let f = &self.formation;
        let wide = match f.shape {
            ShapeName::Triangle | ShapeName::V => WideShape::V {
                distance: f.distance,
                angle: f.angle_deg.to_radians(),
            },
            ShapeName::Rows => WideShape::Rows {
                per_row: f.per_row,
                spacing: f.line_spacing,
            },
            ShapeName::Custom => WideShape::Custom(
                f.slots
                    .iter()
                    .map(|s| (s.distance, s.angle_deg.to_radians()))
                    .collect(),
            ),
        };
        FormationSpec {
            wide,
            followers: self.followers().len(),
            line_spacing: f.line_spacing,
            margin: f.margin,
            transition_s: f.transition_s,
            min_dwell_s: f.min_dwell_s,
            lookahead: f.lookahead,
            footprint: self.robot.footprint_radius,
            slot_speed: SLOT_SPEED_OF_MAX * self.robot.max_speed,
            top_speed: self.robot.max_speed,
        }
    }

    /// The robots' control configuration: what a robot built for this scenario runs
    /// (the firmware image carries `RobotConfig::DEFAULT`).
    pub fn robot_config(&self) -> RobotConfig {
        let s = self;
        let r = &s.robot;
        let d = RobotConfig::DEFAULT;
        RobotConfig {
            drive: DiffDrive {
                track_width: r.track_width as f32,
                wheel_radius: r.wheel_radius as f32,
                max_wheel_speed: r.max_wheel_speed as f32,
            },
            ticks_per_rev: r.ticks_per_rev,
            limits: config::Limits {
                max_v: r.max_speed as f32,
                max_reverse: r.max_reverse_speed as f32,
                max_omega: r.max_turn_rate as f32,
                max_accel: r.max_accel as f32,
                brake_decel: r.brake_decel as f32,
            },
            gains: config::FollowerGains {
                k1: s.follower.k1 as f32,
                k2: s.follower.k2 as f32,
                d: s.follower.d as f32,
            },
            pid: PidGains {
                kff: 1.0 / r.motor_no_load_speed as f32,
                ..d.pid
            },
            timeouts: config::Timeouts {
                leader_state_ms: s.follower.leader_timeout_ms,
                command_ms: s.follower.leader_timeout_ms,
                ..d.timeouts
            },
            ..d
        }
    }
}
