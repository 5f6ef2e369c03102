//! What a run measured: samples at 10 Hz for the figure and the report, contacts and
//! clearances at every physics step.
//!
//! Definitions (also in `docs/sim.md`): tracking error = distance from a follower's
//! control point to its reference slot point: from the true leader pose and path and the
//! station's current blend, by the followers' own `Slots::reference` (it moves
//! continuously during a transformation). Clearance = footprint to
//! obstacle surface. Robot separation = footprint to footprint.

use std::collections::HashSet;

use base_station::formation::Target;
use base_station::map::Map;
use base_station::scenario::{Role, Scenario};
use base_station::station::BaseStation;
use control_core::follower::{Slots, Trail};
use control_core::Pose;
use glam::DVec2;
use serde::Serialize;

use crate::world::SimRobot;

/// One robot at one sample.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct RobotSample {
    pub x: f64,
    pub y: f64,
    pub heading: f64,
    pub v: f64,
    pub omega: f64,
    /// Followers: distance from the control point to the reference slot point.
    pub error: Option<f64>,
}

#[derive(Debug, Clone, Serialize)]
pub struct Sample {
    pub t: f64,
    pub robots: Vec<RobotSample>,
    pub blend: f64,
    /// Some robot has an obstacle within R_det.
    pub near_obstacle: bool,
}

#[derive(Debug, Clone)]
pub struct Recorder {
    footprint: f64,
    d: f64,
    r_det: f64,
    pub samples: Vec<Sample>,
    pub min_clearance: f64,
    pub min_separation: f64,
    pub contacts: u32,
    touching: HashSet<(usize, usize)>,
    /// The true leader's path: the line's reference, as the followers compute it.
    trail: Trail,
}

const OBSTACLE: usize = usize::MAX;

impl Recorder {
    pub fn new(s: &Scenario) -> Self {
        Self {
            footprint: s.robot.footprint_radius,
            d: s.follower.d,
            r_det: s.planner.r_det,
            samples: Vec::new(),
            min_clearance: f64::INFINITY,
            min_separation: f64::INFINITY,
            contacts: 0,
            touching: HashSet::new(),
            trail: Trail::new(),
        }
    }

    fn contact(&mut self, pair: (usize, usize), now: bool) {
        if now {
            if self.touching.insert(pair) {
                self.contacts += 1;
            }
        } else {
            self.touching.remove(&pair);
        }
    }

    /// Called after every physics step.
    pub fn observe(&mut self, t_us: u64, robots: &[SimRobot], map: &Map, station: &BaseStation) {
        let fp = self.footprint;
        let reach = self.r_det + fp;
        let mut near = false;
        for (i, r) in robots.iter().enumerate() {
            let p = DVec2::new(r.body.x, r.body.y);
            let Some(surface) = map.nearest(p, reach) else {
                self.contact((i, OBSTACLE), false);
                continue;
            };
            let clearance = surface.distance - fp;
            near |= clearance < self.r_det;
            self.min_clearance = self.min_clearance.min(clearance);
            self.contact((i, OBSTACLE), clearance < 0.0);
        }
        // Robot pairs: only neighbours in a grid matter; the fleets here are small or
        // spread, so a sort along x bounds the work.
        let mut order: Vec<usize> = (0..robots.len()).collect();
        order.sort_by(|a, b| robots[*a].body.x.total_cmp(&robots[*b].body.x));
        for (k, &i) in order.iter().enumerate() {
            for &j in &order[k + 1..] {
                let (a, b) = (&robots[i].body, &robots[j].body);
                if b.x - a.x > 2.0 * fp + 1.0 {
                    break;
                }
                let gap = ((a.x - b.x).powi(2) + (a.y - b.y).powi(2)).sqrt() - 2.0 * fp;
                self.min_separation = self.min_separation.min(gap);
                self.contact((i.min(j), i.max(j)), gap < 0.0);
            }
        }
        if !t_us.is_multiple_of(100_000) {
            return;
        }
        let leader = robots
            .iter()
            .find(|r| r.role == Role::Leader)
            .map(|r| &r.body);
        let formation = station.formation();
        let mut followers: Vec<(u16, usize)> = robots
            .iter()
            .enumerate()
            .filter(|(_, r)| r.role == Role::Follower)
            .map(|(i, r)| (r.id, i))
            .collect();
        followers.sort();
        let slot_of: std::collections::HashMap<usize, usize> = followers
            .iter()
            .enumerate()
            .map(|(k, (_, i))| (*i, k))
            .collect();
        let samples = robots
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let (v, omega) = r.body.twist();
                let error = match (r.role, leader) {
                    (Role::Follower, Some(l)) => {
                        let k = slot_of[&i];
                        let f32s = |(a, b): (f64, f64)| (a as f32, b as f32);
                        let slots = Slots {
                            wide: f32s(formation.wide_slots()[k]),
                            line: f32s(formation.line_slots()[k]),
                        };
                        let pose = Pose::new(l.x as f32, l.y as f32, l.heading as f32);
                        let (rx, ry) =
                            slots.reference(&pose, formation.blend() as f32, &self.trail);
                        let (cx, cy) = r.body.ahead(self.d);
                        Some((DVec2::new(cx, cy) - DVec2::new(rx as f64, ry as f64)).length())
                    }
                    _ => None,
                };
                RobotSample {
                    x: r.body.x,
                    y: r.body.y,
                    heading: r.body.heading,
                    v,
                    omega,
                    error,
                }
            })
            .collect();
        self.samples.push(Sample {
            t: t_us as f64 / 1e6,
            robots: samples,
            blend: formation.blend(),
            near_obstacle: near,
        });
    }
}

/// A shape change as the report shows it.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct TransformationReport {
    pub to: String,
    pub start_s: f64,
    /// From the start until the slots reached the new shape and every follower is back
    /// under 0.1 m; null if that never happened.
    pub duration_s: Option<f64>,
}

#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct RobotReport {
    pub id: u16,
    pub role: String,
    pub avg_speed_mps: f64,
    pub avg_abs_omega_radps: f64,
    pub max_tracking_error_m: Option<f64>,
    pub stable_max_tracking_error_m: Option<f64>,
}

#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct LinkReport {
    pub frames_sent: u64,
    pub frames_delivered: u64,
    pub frames_rejected: u64,
    /// Rejected frames by reason, over every receiver.
    pub rejects_by_reason: std::collections::BTreeMap<String, u64>,
}

/// Something the base station noticed, for the report.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct StationEventReport {
    pub at_s: f64,
    pub event: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub robot: Option<u16>,
}

/// The run's report: a public interface (`schema_version` 1, keys fixed by the issue).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Report {
    pub schema_version: u32,
    pub scenario: String,
    pub seed: u64,
    pub firmware: String,
    pub sim_time_s: f64,
    pub wall_time_s: f64,
    pub goal_reached: bool,
    pub time_to_goal_s: Option<f64>,
    pub collisions: u32,
    pub min_obstacle_clearance_m: f64,
    pub min_robot_separation_m: f64,
    pub convergence_time_s: Option<f64>,
    pub robots: Vec<RobotReport>,
    pub transformations: Vec<TransformationReport>,
    pub link: LinkReport,
    /// What the base station noticed (links, formation changes, a lost leader, …).
    pub station_events: Vec<StationEventReport>,
}

/// Follower errors of a sample (all followers), if every one is known.
fn errors(s: &Sample) -> Vec<f64> {
    s.robots.iter().filter_map(|r| r.error).collect()
}

/// The transformations, with their durations measured on the samples.
pub fn transformations(
    rec: &Recorder,
    station: &BaseStation,
    wide_name: &str,
    transition_s: f64,
) -> Vec<TransformationReport> {
    station
        .formation()
        .transformations()
        .iter()
        .map(|tr| {
            let shaped = tr.start_s + transition_s;
            let done = rec
                .samples
                .iter()
                .find(|s| s.t >= shaped - 1e-9 && errors(s).iter().all(|e| *e < 0.1))
                .map(|s| s.t - tr.start_s);
            TransformationReport {
                to: match tr.to {
                    Target::Line => "line".to_string(),
                    Target::Wide => wide_name.to_string(),
                },
                start_s: tr.start_s,
                duration_s: done,
            }
        })
        .collect()
}

#[allow(clippy::too_many_arguments)]
pub fn build_report(
    rec: &Recorder,
    scenario: &Scenario,
    roles: &[(u16, Role)],
    transformations: Vec<TransformationReport>,
    seed: u64,
    firmware: &str,
    sim_time_s: f64,
    wall_time_s: f64,
    time_to_goal_s: Option<f64>,
    link: LinkReport,
) -> Report {
    let convergence = rec
        .samples
        .iter()
        .find(|s| errors(s).iter().all(|e| *e < 0.1))
        .map(|s| s.t);
    let busy: Vec<(f64, f64)> = transformations
        .iter()
        .map(|t| {
            let end = t.start_s
                + scenario
                    .formation
                    .transition_s
                    .max(t.duration_s.unwrap_or(f64::INFINITY));
            (t.start_s, end + 3.0)
        })
        .collect();
    let moving_until = time_to_goal_s.unwrap_or(sim_time_s);
    let robots = roles
        .iter()
        .enumerate()
        .map(|(i, (id, role))| {
            let moving: Vec<&RobotSample> = rec
                .samples
                .iter()
                .filter(|s| s.t <= moving_until)
                .map(|s| &s.robots[i])
                .collect();
            let n = moving.len().max(1) as f64;
            let after = |stable: bool| {
                rec.samples
                    .iter()
                    .filter(|s| convergence.is_some_and(|c| s.t >= c))
                    .filter(|s| {
                        !stable
                            || (!s.near_obstacle
                                && !busy.iter().any(|(a, b)| s.t >= *a && s.t <= *b))
                    })
                    .filter_map(|s| s.robots[i].error)
                    .fold(None, |m: Option<f64>, e| Some(m.map_or(e, |m| m.max(e))))
            };
            RobotReport {
                id: *id,
                role: match role {
                    Role::Leader => "leader".into(),
                    Role::Follower => "follower".into(),
                },
                avg_speed_mps: moving.iter().map(|r| r.v.abs()).sum::<f64>() / n,
                avg_abs_omega_radps: moving.iter().map(|r| r.omega.abs()).sum::<f64>() / n,
                max_tracking_error_m: if *role == Role::Follower {
                    after(false)
                } else {
                    None
                },
                stable_max_tracking_error_m: if *role == Role::Follower {
                    after(true)
                } else {
                    None
                },
            }
        })
        .collect();
    Report {
        schema_version: 1,
        scenario: scenario.name.clone(),
        seed,
        firmware: firmware.to_string(),
        sim_time_s,
        wall_time_s,
        goal_reached: time_to_goal_s.is_some(),
        time_to_goal_s,
        collisions: rec.contacts,
        min_obstacle_clearance_m: rec.min_clearance,
        min_robot_separation_m: rec.min_separation,
        convergence_time_s: convergence,
        robots,
        transformations,
        link,
        station_events: Vec::new(),
    }
}
