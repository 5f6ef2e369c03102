//! The leader's planner: the APF toward the route's next waypoint, with the whole
//! formation's footprint in the field, and a way out of local minima.
//!
//! - **Cohesion**: the leader's field treats the leader as wide as the formation: the
//!   clearance in the repulsion is measured from the robot's footprint **inflated by the
//!   formation's lateral half-width** (which shrinks smoothly to 0 as the formation becomes
//!   a line). The leader thus keeps the whole formation clear, not just itself: with the
//!   paper's method as written the followers clip what the leader passed. We first
//!   evaluated the repulsion at the followers' slot points and applied it to the leader;
//!   in the simulated passage that loop is unstable (a force on a rear slot turns the
//!   leader, which swings the slot further toward the wall) and we dropped it. The
//!   followers add their own local layer: a proximity sensor caps their speed near
//!   anything in front of them (`control-core`).
//! - **Stuck or oscillating** (a U-shaped trap, an obstacle right before the goal, a gap
//!   that makes the heading swing): the distance to the goal improved by less than
//!   `stuck_progress` over `stuck_window_s`, or the heading error changed sign
//!   `oscillation_flips` times in that window. Escape: **boundary following** (a tangential
//!   field) around the nearest obstacle, on the side that first turns toward the goal,
//!   keeping `follow_clearance`; leave (Bug2's rule) once closer to the goal than on entry
//!   and the straight way to the goal is free. A failed escape (no progress for
//!   `escape_timeout_s`) switches sides.
//! - **Speed**: `max_speed` scaled by the field's strength relative to full attraction
//!   (so it slows in front of obstacles and over the last metre to the goal) and by how
//!   well it points where the robot is heading; acceleration and turn rate limited.

pub mod apf;

use std::collections::VecDeque;

use glam::DVec2;

use crate::map::Map;
use apf::ApfParams;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlannerParams {
    pub apf: ApfParams,
    pub max_speed: f64,
    pub max_turn_rate: f64,
    pub max_accel: f64,
    /// ω = heading_gain · heading error, rad/s per rad.
    pub heading_gain: f64,
    /// The final goal is reached within this distance, m.
    pub arrival_tolerance: f64,
    /// Intermediate waypoints are passed within this distance, m.
    pub waypoint_tolerance: f64,
    pub stuck_window_s: f64,
    pub stuck_progress: f64,
    pub oscillation_flips: usize,
    /// Clearance kept while following a boundary, m.
    pub follow_clearance: f64,
    pub escape_timeout_s: f64,
}

impl PlannerParams {
    pub const DEFAULT: PlannerParams = PlannerParams {
        apf: ApfParams::PAPER,
        max_speed: 0.45,
        max_turn_rate: 0.6,
        max_accel: 0.3,
        heading_gain: 1.2,
        arrival_tolerance: 0.3,
        waypoint_tolerance: 1.0,
        stuck_window_s: 8.0,
        stuck_progress: 0.5,
        oscillation_flips: 8,
        follow_clearance: 0.8,
        escape_timeout_s: 60.0,
    };
}

/// What the planner is doing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Mode {
    /// Following the potential field.
    Field,
    /// Following an obstacle's boundary out of a local minimum.
    Escape {
        /// +1: obstacle on the right (turning left around it), −1: on the left.
        side: f64,
        entry_distance: f64,
        since_s: f64,
        best_distance: f64,
        best_at_s: f64,
    },
    /// The last waypoint is reached.
    Arrived,
}

/// One step's result.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Command {
    pub v: f64,
    pub omega: f64,
    pub mode: Mode,
    /// The direction the planner steers to (world frame, unit or zero).
    pub direction: DVec2,
}

#[derive(Debug, Clone)]
pub struct Planner {
    pub params: PlannerParams,
    route: Vec<DVec2>,
    next: usize,
    mode: Mode,
    progress: VecDeque<(f64, f64, f64)>,
    v: f64,
    escapes: u32,
    inflation: f64,
    /// (farthest slot distance, followers' usable speed), when a formation follows.
    formation: Option<(f64, f64)>,
}

/// The robot's pose as the planner sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanPose {
    pub position: DVec2,
    pub heading: f64,
}

fn wrap(a: f64) -> f64 {
    let t = std::f64::consts::TAU;
    let w = a - t * ((a + std::f64::consts::PI) / t).floor();
    if w <= -std::f64::consts::PI {
        w + t
    } else {
        w
    }
}

impl Planner {
    /// `route`: waypoints, the last one the goal. `initial_speed`: the leader's speed now.
    pub fn new(params: PlannerParams, route: Vec<DVec2>, initial_speed: f64) -> Self {
        Self {
            params,
            route,
            next: 0,
            mode: Mode::Field,
            progress: VecDeque::new(),
            v: initial_speed,
            escapes: 0,
            inflation: 0.0,
            formation: None,
        }
    }

    /// Tells the planner how far the farthest slot is from the leader and how fast the
    /// followers can drive: the turn rate is then capped so that the farthest slot point,
    /// swung around the leader (ω·L across the leader's speed v), never needs more than
    /// that speed: ω ≤ √(v_f² − v²) / L.
    pub fn set_formation(&mut self, reach: f64, follower_speed: f64) {
        self.formation = (reach > 0.0).then_some((reach, follower_speed));
    }

    /// The turn-rate limit now.
    pub fn turn_limit(&self) -> f64 {
        let max = self.params.max_turn_rate;
        match self.formation {
            Some((reach, vf)) => max.min((vf * vf - self.v * self.v).max(0.0).sqrt() / reach),
            None => max,
        }
    }

    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// How many times the planner had to escape a local minimum.
    pub fn escapes(&self) -> u32 {
        self.escapes
    }

    pub fn goal(&self) -> Option<DVec2> {
        self.route.last().copied()
    }

    pub fn current_waypoint(&self) -> Option<DVec2> {
        self.route.get(self.next).copied()
    }

    pub fn arrived(&self) -> bool {
        self.mode == Mode::Arrived
    }

    /// One planning step. `half_width`: the formation's lateral half-width (0 for a line),
    /// added to the footprint; `speed_scale` in [0, 1] slows the leader (followers lagging).
    pub fn step(
        &mut self,
        now_s: f64,
        dt: f64,
        pose: PlanPose,
        map: &Map,
        half_width: f64,
        speed_scale: f64,
    ) -> Command {
        let p = self.params;
        let pos = pose.position;
        // Waypoints.
        while let Some(w) = self.current_waypoint() {
            let last = self.next + 1 == self.route.len();
            let tol = if last {
                p.arrival_tolerance
            } else {
                p.waypoint_tolerance
            };
            if (w - pos).length() > tol {
                break;
            }
            self.next += 1;
            self.progress.clear();
            if last {
                self.mode = Mode::Arrived;
            } else if matches!(self.mode, Mode::Escape { .. }) {
                self.mode = Mode::Field;
            }
        }
        let Some(goal) = self.current_waypoint() else {
            self.mode = Mode::Arrived;
            self.v = 0.0;
            return Command {
                v: 0.0,
                omega: 0.0,
                mode: Mode::Arrived,
                direction: DVec2::ZERO,
            };
        };
        let is_last = self.next + 1 == self.route.len();
        let to_goal = goal - pos;
        let distance = to_goal.length();

        self.inflation = half_width.max(0.0);
        let field = self.field(pos, goal, is_last, map);
        let field_dir = field.normalize_or_zero();
        let heading_err_field = wrap(field_dir.y.atan2(field_dir.x) - pose.heading);
        self.watch(now_s, distance, heading_err_field);

        let (direction, strength) = match self.mode {
            Mode::Escape {
                side,
                entry_distance,
                since_s,
                best_distance,
                best_at_s,
            } => {
                let (best_distance, best_at_s) = if distance < best_distance - 0.1 {
                    (distance, now_s)
                } else {
                    (best_distance, best_at_s)
                };
                let clear = self.way_is_clear(pos, to_goal, map);
                if distance < entry_distance - 0.5 && clear {
                    self.mode = Mode::Field;
                    self.progress.clear();
                    (field_dir, (field.length() / p.apf.k_a).min(1.0))
                } else {
                    let side = if now_s - best_at_s > p.escape_timeout_s {
                        -side
                    } else {
                        side
                    };
                    self.mode = Mode::Escape {
                        side,
                        entry_distance,
                        since_s,
                        best_distance,
                        best_at_s: if side != self.escape_side() {
                            now_s
                        } else {
                            best_at_s
                        },
                    };
                    (
                        self.boundary_direction(pos, side, map).unwrap_or(field_dir),
                        0.7,
                    )
                }
            }
            _ => (field_dir, (field.length() / p.apf.k_a).min(1.0)),
        };

        let err = if direction == DVec2::ZERO {
            0.0
        } else {
            wrap(direction.y.atan2(direction.x) - pose.heading)
        };
        let turn = self.turn_limit();
        let omega = (p.heading_gain * err).clamp(-turn, turn);
        let align = err.cos().max(0.0);
        let target = p.max_speed * strength * align * align * speed_scale.clamp(0.0, 1.0);
        self.v += (target - self.v).clamp(-p.max_accel * dt, p.max_accel * dt);
        Command {
            v: self.v,
            omega,
            mode: self.mode,
            direction,
        }
    }

    fn escape_side(&self) -> f64 {
        match self.mode {
            Mode::Escape { side, .. } => side,
            _ => 0.0,
        }
    }

    /// The footprint the field sees: the robot's, inflated to the formation's width.
    fn apf(&self) -> ApfParams {
        ApfParams {
            footprint: self.params.apf.footprint + self.inflation,
            ..self.params.apf
        }
    }

    /// The potential field's force on the formation, applied at the leader.
    fn field(&self, pos: DVec2, goal: DVec2, is_last: bool, map: &Map) -> DVec2 {
        let a = &self.apf();
        let attraction = if is_last {
            apf::attraction(pos, goal, a)
        } else {
            (goal - pos).normalize_or_zero() * a.k_a * a.attraction_saturation
        };
        let scale = if is_last {
            apf::goal_scale(pos, goal, a)
        } else {
            1.0
        };
        attraction + apf::repulsion(pos, map, a) * scale
    }

    /// Records progress and enters an escape when stuck or oscillating.
    fn watch(&mut self, now_s: f64, distance: f64, heading_err: f64) {
        if !matches!(self.mode, Mode::Field) {
            return;
        }
        self.progress.push_back((now_s, distance, heading_err));
        let window = self.params.stuck_window_s;
        while self
            .progress
            .front()
            .is_some_and(|(t, _, _)| now_s - t > window)
        {
            self.progress.pop_front();
        }
        let Some(&(t0, d0, _)) = self.progress.front() else {
            return;
        };
        let full = now_s - t0 >= window - 0.5;
        let stalled = full && d0 - distance < self.params.stuck_progress;
        let flips = self
            .progress
            .iter()
            .zip(self.progress.iter().skip(1))
            .filter(|(a, b)| a.2.abs() > 0.05 && b.2.abs() > 0.05 && a.2.signum() != b.2.signum())
            .count();
        let oscillating = flips >= self.params.oscillation_flips
            && d0 - distance < 2.0 * self.params.stuck_progress;
        if stalled || oscillating {
            self.mode = Mode::Escape {
                side: 0.0,
                entry_distance: distance,
                since_s: now_s,
                best_distance: distance,
                best_at_s: now_s,
            };
            self.escapes += 1;
            self.progress.clear();
        }
    }

    /// The tangent of the nearest boundary, keeping `follow_clearance`. On the first call
    /// of an escape (side 0) it picks the side that turns toward the goal.
    fn boundary_direction(&mut self, pos: DVec2, side: f64, map: &Map) -> Option<DVec2> {
        let p = self.params;
        let a = &self.apf();
        let n = map.nearest(pos, a.r_det * 2.0 + a.footprint)?;
        let tangent_left = n.normal.perp();
        let side = if side == 0.0 {
            let goal = self.current_waypoint().unwrap_or(pos);
            let s = if tangent_left.dot(goal - pos) >= 0.0 {
                1.0
            } else {
                -1.0
            };
            if let Mode::Escape { side, .. } = &mut self.mode {
                *side = s;
            }
            s
        } else {
            side
        };
        let clearance = n.distance - a.footprint;
        let pull = ((clearance - p.follow_clearance) / p.follow_clearance).clamp(-1.0, 1.0);
        Some((tangent_left * side - n.normal * pull).normalize_or_zero())
    }

    /// Whether a robot-wide corridor toward the goal is free for the next few metres.
    fn way_is_clear(&self, pos: DVec2, to_goal: DVec2, map: &Map) -> bool {
        let d = to_goal.length();
        if d < 1e-9 {
            return true;
        }
        let dir = to_goal / d;
        let reach = d.min(3.0);
        let w = self.apf().footprint + 0.1;
        [-w, 0.0, w]
            .iter()
            .all(|off| map.ray_cast(pos + dir.perp() * *off, dir, reach) >= reach)
    }
}
