//! The leader's planner, in two layers (`route`: the default), or the paper's pure APF
//! (`field`, `[planner] mode = "apf"`).
//!
//! **Route (default).** A global route over the site map ([`route`]: A\* on a clearance
//! grid, wide ways preferred, line-only passages taken when they are the way), planned at
//! the first step from where the leader is, through the waypoints in order. The APF is the
//! local layer: the attraction pulls toward a carrot `route_lookahead` ahead on the route;
//! the paper's repulsion pushes away from what is near, capped at the attraction's
//! strength and never backward along the route (the route is known to be free: a
//! repulsion that pushes the leader back out of a gap it must take is the APF's classic
//! failure). When the leader makes no progress along the route for `stuck_window_s`
//! although nothing holds it back (followers, a shape change, a turn toward the route
//! that a turn on the spot could still be making), the way is blocked by
//! something the map does not hold: the stretch ahead is marked blocked and the route is
//! planned again (a `replanned` event). No route at all: the leader holds (`NoRoute`)
//! and tries again every `stuck_window_s`.
//!
//! **Field (the paper's method, fixed).**
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
pub mod route;

use std::collections::VecDeque;

use glam::DVec2;

use crate::geometry::map::Map;
pub use crate::geometry::PlanPose;
use crate::geometry::{wrap_angle, Obstacle};
use apf::ApfParams;
use route::{NoRoute, Route, RouteParams, RoutePlanner};

/// A heading error beyond which the leader is turning toward the route rather than
/// driving along it, rad (60°).
const TURNING_AWAY: f64 = std::f64::consts::FRAC_PI_3;

/// The heading error to turn through: the shorter way round, unless the leader is already
/// turning the other way and that way is at most a quarter turn longer. A leader turning
/// on the spot swings its wide slots round at the followers' speed; reversing the turn
/// (a route planned again as a barrier comes into view) reverses them under the followers,
/// who must stop and turn round (0.46 m off on a generated barrier map).
fn keep_turning(err: f64, omega: f64) -> f64 {
    const TURNING: f64 = 0.05;
    if err.abs() <= std::f64::consts::FRAC_PI_2 || omega.abs() < TURNING || err * omega >= 0.0 {
        return err;
    }
    let other_way = err + omega.signum() * std::f64::consts::TAU;
    if other_way.abs() <= err.abs() + std::f64::consts::FRAC_PI_2 {
        other_way
    } else {
        err
    }
}

/// How the leader finds its way.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Guidance {
    /// A route on the site map, the APF as the local layer.
    Route,
    /// The paper's potential field alone, with boundary-following escapes.
    Field,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlannerParams {
    pub apf: ApfParams,
    pub max_speed: f64,
    pub max_turn_rate: f64,
    pub max_accel: f64,
    /// ω = heading_gain · heading error, rad/s per rad.
    pub heading_gain: f64,
    /// Turn rates the heading error asks for below this are not driven, and this much is
    /// taken off larger ones, rad/s: a V's rear slot L back turns a leader's correction
    /// of ω into L·ω across its path, and the few-mrad/s corrections on noisy fixes made
    /// its follower weave (docs/sim.md, "Straight legs").
    pub turn_dead_band: f64,
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
    pub guidance: Guidance,
    /// How far ahead on the route the attraction pulls, m.
    pub route_lookahead: f64,
}

impl PlannerParams {
    pub const DEFAULT: PlannerParams = PlannerParams {
        apf: ApfParams::PAPER,
        max_speed: 0.45,
        max_turn_rate: 0.6,
        max_accel: 0.3,
        heading_gain: 1.2,
        turn_dead_band: 0.04,
        arrival_tolerance: 0.3,
        waypoint_tolerance: 1.0,
        stuck_window_s: 8.0,
        stuck_progress: 0.5,
        oscillation_flips: 8,
        follow_clearance: 0.8,
        escape_timeout_s: 60.0,
        guidance: Guidance::Route,
        route_lookahead: 1.5,
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
    /// Following the planned route.
    Route,
    /// No route to the next waypoint: holding.
    NoRoute,
    /// The last waypoint is reached.
    Arrived,
}

impl Mode {
    /// As an operator reads it in a log line.
    pub fn name(&self) -> &'static str {
        match self {
            Mode::Field => "field",
            Mode::Escape { .. } => "escaping a dead end",
            Mode::Route => "route",
            Mode::NoRoute => "no route",
            Mode::Arrived => "arrived",
        }
    }
}

/// What happened in the planner, as it tells the station: each kind at most once a step.
#[derive(Debug, Clone, PartialEq)]
pub enum PlannerEvent {
    /// Stuck in a local minimum: following an obstacle's boundary (field guidance).
    Escape,
    /// The way was blocked: the route was planned again.
    Replanned,
    /// The step ended without a route to the next waypoint (said once until there is one
    /// again), and why.
    NoRoute(String),
    /// The last waypoint was reached.
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
    /// The turn rate last commanded, and how fast it may change (rad/s²).
    omega: f64,
    turn_accel: f64,
    routing: Option<Box<Routing>>,
    /// What happened since the station last took the events.
    events: Vec<PlannerEvent>,
    /// Whether the step ended without a route last time (said once).
    no_route_said: bool,
    /// The pace of the last step ([`Pace`]): how hard it brakes and speeds up, whether
    /// movers hold it (a way that only narrows is then planned again at most every
    /// [`HELD_REPLAN_S`]).
    pace: Pace,
}

/// Held by movers, the leader plans again where marks only narrow its way at most this
/// often, s (see [`Pace::held`]).
pub const HELD_REPLAN_S: f64 = 5.0;

/// How fast the leader may go this step: the station's call among its followers and
/// among what moves, passed in as a value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pace {
    /// The share of the planner's speed: under 1 slows the leader (followers lagging,
    /// people near), over 1 hurries it out of someone's way.
    pub scale: f64,
    /// Brake at up to this (m/s², above `max_accel`): stopping for someone in the way.
    pub brake: Option<f64>,
    /// Speed up at up to this (m/s², above `max_accel`): getting going among movers.
    pub accel: Option<f64>,
    /// Movers hold the leader. While they do, marks that only narrow the way ahead
    /// (people standing round it) make the route be planned again at most every
    /// [`HELD_REPLAN_S`]; marks that block it still do at once, and a hold that lasts
    /// brings its own way round (`[yielding] replan_after_s`). Planned again at every
    /// narrowing, the route of a fleet held among standing people swung from side to
    /// side and the leader turned back and forth where it stood; never planned again
    /// while held, it waited too long in denser crowds.
    pub held: bool,
}

impl From<f64> for Pace {
    /// Only a share of the speed: the planner's own acceleration, nobody holding it.
    fn from(scale: f64) -> Self {
        Self {
            scale,
            brake: None,
            accel: None,
            held: false,
        }
    }
}

/// The route layer's state.
#[derive(Debug, Clone)]
struct Routing {
    params: RouteParams,
    /// Built at the first plan, when the leader's position is known.
    planner: Option<RoutePlanner>,
    route: Option<Route>,
    /// Arc length of each remaining waypoint on the route.
    waypoint_arc: Vec<f64>,
    /// Progress along the route, m.
    s: f64,
    /// Discs found blocked (centre, radius).
    blocked: Vec<(DVec2, f64)>,
    /// Obstacles sensed since the last check against the route.
    unchecked: Vec<Obstacle>,
    /// (time, progress) while nothing held the leader back.
    progress: VecDeque<(f64, f64)>,
    /// Since when the leader has been turning toward the route, far off its heading.
    turning_since: Option<f64>,
    replans: u32,
    failure: Option<NoRoute>,
    last_attempt_s: f64,
}

impl Routing {
    /// Progress along the route from `pos` (the nearest point a little behind to a little
    /// ahead), and the waypoints passed: (arc length, how many passed, whether the last
    /// was); `None` without a route.
    fn advance(&mut self, pos: DVec2, p: &PlannerParams) -> Option<(f64, usize, bool)> {
        let route = self.route.as_ref()?;
        let s = route.project(pos, self.s - 1.0, self.s + 3.0).max(0.0);
        self.s = s;
        let (mut passed, mut arrived) = (0, false);
        while let Some(&arc) = self.waypoint_arc.first() {
            let last = self.waypoint_arc.len() == 1;
            let tol = if last {
                p.arrival_tolerance
            } else {
                p.waypoint_tolerance
            };
            // Reached, or (an intermediate one) left behind along the route: a leader that
            // went round it wider than `tol` must not be sent back for it at a replan.
            let behind = !last && s > arc + tol;
            if (route.point_at(arc) - pos).length() > tol && !behind {
                break;
            }
            self.waypoint_arc.remove(0);
            passed += 1;
            arrived = last;
        }
        Some((s, passed, arrived))
    }

    /// Whether the leader has made no progress for a window although nothing held it
    /// back. A turn toward a new route makes no progress either: a U-turn on the spot at
    /// the formation's turn limit takes longer than the window, and taken as a blockage it
    /// sent the leader back round the other way, the slots' swing reversed under the
    /// followers (0.5–0.9 m off). It is excused as long as turning round could take.
    fn stalled(
        &mut self,
        now_s: f64,
        s: f64,
        speed_scale: f64,
        turn_round_s: f64,
        p: &PlannerParams,
    ) -> bool {
        let window = p.stuck_window_s;
        let turning = self
            .turning_since
            .is_some_and(|since| now_s - since < turn_round_s);
        if speed_scale >= 0.9 && !turning {
            self.progress.push_back((now_s, s));
        } else {
            self.progress.clear();
        }
        while self
            .progress
            .front()
            .is_some_and(|(t, _)| now_s - t > window)
        {
            self.progress.pop_front();
        }
        self.progress
            .front()
            .is_some_and(|&(t0, s0)| now_s - t0 >= window - 0.5 && s - s0 < p.stuck_progress)
    }
}

/// The least distance from `obstacles` to `route` beyond arc length `from`, looking no
/// farther than `reach` (∞ when nothing is that close).
fn nearest_to_route(obstacles: &[Obstacle], route: &Route, from: f64, reach: f64) -> f64 {
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for o in obstacles {
        let [a, b] = o.bounds();
        lo = lo.min(a - reach);
        hi = hi.max(b + reach);
    }
    route
        .sample(from, route.length() - from, 0.1)
        .iter()
        .filter(|p| p.cmpge(lo).all() && p.cmple(hi).all())
        .flat_map(|p| obstacles.iter().map(|o| o.nearest(*p).distance))
        .filter(|d| *d < reach)
        .fold(f64::INFINITY, f64::min)
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
            omega: 0.0,
            turn_accel: f64::INFINITY,
            routing: None,
            events: Vec::new(),
            no_route_said: false,
            pace: Pace::from(1.0),
        }
    }

    /// Notes `event`, unless one of its kind waits already.
    fn note(&mut self, event: PlannerEvent) {
        let kind = std::mem::discriminant(&event);
        if !self
            .events
            .iter()
            .any(|e| std::mem::discriminant(e) == kind)
        {
            self.events.push(event);
        }
    }

    /// What happened since the last call, in order, each kind once.
    pub fn take_events(&mut self) -> Vec<PlannerEvent> {
        std::mem::take(&mut self.events)
    }

    /// A planner that follows a route planned on the site map with `router`'s parameters.
    pub fn routed(
        params: PlannerParams,
        route: Vec<DVec2>,
        initial_speed: f64,
        router: RouteParams,
    ) -> Self {
        let mut p = Self::new(params, route, initial_speed);
        p.mode = Mode::Route;
        p.routing = Some(Box::new(Routing {
            params: router,
            planner: None,
            route: None,
            waypoint_arc: Vec::new(),
            s: 0.0,
            blocked: Vec::new(),
            unchecked: Vec::new(),
            progress: VecDeque::new(),
            turning_since: None,
            replans: 0,
            failure: None,
            last_attempt_s: f64::NEG_INFINITY,
        }));
        p
    }

    /// The route being followed (route guidance, once planned).
    pub fn route(&self) -> Option<&Route> {
        self.routing.as_ref().and_then(|r| r.route.as_ref())
    }

    /// Obstacles the map does not hold, sensed on the way: the route avoids them from now
    /// on, and is planned again at the next step if one lies on the way ahead. The map
    /// given to later steps must hold them too (a grid built later is built from it).
    pub fn add_obstacles(&mut self, obstacles: &[Obstacle]) {
        let Some(routing) = self.routing.as_mut() else {
            return;
        };
        if let Some(planner) = routing.planner.as_mut() {
            for o in obstacles {
                planner.add_obstacle(o);
            }
        }
        routing.unchecked.extend_from_slice(obstacles);
    }

    /// Sensed obstacles that are gone again; `map`: what remains (the site and the
    /// obstacles still sensed).
    pub fn remove_obstacles(&mut self, obstacles: &[Obstacle], map: &Map) {
        let Some(routing) = self.routing.as_mut() else {
            return;
        };
        if let Some(planner) = routing.planner.as_mut() {
            planner.remove_obstacles(obstacles, map);
        }
        routing.unchecked.retain(|u| !obstacles.contains(u));
    }

    /// How far the leader has still to go along its route (route guidance, once planned;
    /// the straight way to the goal in the field mode), m, and the waypoint it makes for
    /// (1-based) of how many.
    pub fn still_to_go(&self, from: DVec2) -> Option<(f64, usize, usize)> {
        let n = self.route.len();
        let k = (self.next + 1).min(n);
        if self.arrived() {
            return Some((0.0, n, n));
        }
        let left = match self.routing.as_ref() {
            Some(r) => {
                let route = r.route.as_ref()?;
                (route.length() - r.s).max(0.0)
            }
            None => {
                let rest = self.route.get(self.next..)?;
                let mut at = from;
                rest.iter()
                    .map(|w| {
                        let d = at.distance(*w);
                        at = *w;
                        d
                    })
                    .sum()
            }
        };
        Some((left, k, n))
    }

    /// How many times the route was planned again because the way was blocked.
    pub fn replans(&self) -> u32 {
        self.routing.as_ref().map_or(0, |r| r.replans)
    }

    /// Why there is no route now, if there is none.
    pub fn no_route(&self) -> Option<&NoRoute> {
        self.routing.as_ref().and_then(|r| r.failure.as_ref())
    }

    /// The way the leader will drive next, `length` metres sampled every `step` from `pose`:
    /// the route, or straight ahead under the field.
    pub fn path_ahead(&self, pose: PlanPose, length: f64, step: f64) -> Vec<DVec2> {
        if let Some((route, s)) = self
            .routing
            .as_ref()
            .and_then(|r| r.route.as_ref().map(|x| (x, r.s)))
        {
            let mut pts = vec![pose.position];
            pts.extend(route.sample(s + step, length - step, step));
            return pts;
        }
        // Straight ahead, no farther than the goal.
        let dir = DVec2::new(pose.heading.cos(), pose.heading.sin());
        let length = self
            .goal()
            .map_or(length, |g| length.min((g - pose.position).length()));
        let n = (length / step).ceil() as usize;
        (0..=n)
            .map(|i| pose.position + dir * (i as f64 * step))
            .collect()
    }

    /// Tells the planner how far the farthest slot is from the leader and how fast the
    /// followers can drive: the turn rate is then capped so that the farthest slot point,
    /// swung around the leader (ω·L across the leader's speed v), never needs more than
    /// that speed: ω ≤ √(v_f² − v²) / L.
    /// `follower_accel` bounds the turn rate's change the same way: the farthest slot
    /// point, swung at ω, accelerates at L·dω/dt, which the followers must match.
    pub fn set_formation(&mut self, reach: f64, follower_speed: f64, follower_accel: f64) {
        self.formation = (reach > 0.0).then_some((reach, follower_speed));
        self.turn_accel = if reach > 0.0 {
            follower_accel / reach
        } else {
            f64::INFINITY
        };
    }

    /// ω toward `target` less the dead band, within the turn-rate limit and the
    /// turn-acceleration limit.
    fn turn_toward(&mut self, target: f64, dt: f64) -> f64 {
        let target = target.signum() * (target.abs() - self.params.turn_dead_band).max(0.0);
        let turn = self.turn_limit();
        let step = self.turn_accel * dt;
        self.omega = (self.omega + (target - self.omega).clamp(-step, step)).clamp(-turn, turn);
        self.omega
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

    /// Takes the next `count` points off the route (those [`Planner::insert_ahead`] put
    /// there and the leader could not reach) and plans the route again.
    pub fn remove_ahead(&mut self, count: usize) {
        let at = self.next.min(self.route.len());
        let end = (at + count).min(self.route.len());
        if end == at {
            return;
        }
        self.route.drain(at..end);
        self.progress.clear();
        if let Some(routing) = self.routing.as_mut() {
            routing.route = None;
            routing.failure = None;
        }
        if self.next >= self.route.len() {
            self.mode = Mode::Arrived;
            self.note(PlannerEvent::Arrived);
        }
    }

    /// How many of the route's points the leader has passed.
    pub fn passed(&self) -> usize {
        self.next
    }

    /// Puts `points` next on the route, before those still to come, and plans the route
    /// again; a leader that had arrived goes on.
    pub fn insert_ahead(&mut self, points: &[DVec2]) {
        if points.is_empty() {
            return;
        }
        let at = self.next.min(self.route.len());
        self.route.splice(at..at, points.iter().copied());
        self.progress.clear();
        match self.routing.as_mut() {
            Some(routing) => {
                routing.route = None;
                routing.failure = None;
                if self.mode == Mode::Arrived {
                    self.mode = Mode::Route;
                }
            }
            None if self.mode == Mode::Arrived => self.mode = Mode::Field,
            None => {}
        }
        self.events.retain(|e| !matches!(e, PlannerEvent::Arrived));
    }

    /// One planning step. `half_width`: the formation's lateral half-width (0 for a line),
    /// added to the footprint; `pace`: how fast the leader may go ([`Pace`], or just a
    /// share of its speed). What happened is noted for [`Planner::take_events`].
    pub fn step(
        &mut self,
        now_s: f64,
        dt: f64,
        pose: PlanPose,
        map: &Map,
        half_width: f64,
        pace: impl Into<Pace>,
    ) -> Command {
        self.pace = pace.into();
        let speed_scale = self.pace.scale;
        let was_arrived = self.arrived();
        let command = self.step_guided(now_s, dt, pose, map, half_width, speed_scale);
        match (self.no_route().map(ToString::to_string), self.no_route_said) {
            (Some(why), false) => {
                tracing::warn!("no route: {why}");
                self.note(PlannerEvent::NoRoute(why));
                self.no_route_said = true;
            }
            (None, true) => self.no_route_said = false,
            _ => {}
        }
        if self.arrived() && !was_arrived {
            tracing::info!("goal reached");
            self.note(PlannerEvent::Arrived);
        }
        command
    }

    /// [`Planner::step`] by the guidance in use.
    fn step_guided(
        &mut self,
        now_s: f64,
        dt: f64,
        pose: PlanPose,
        map: &Map,
        half_width: f64,
        speed_scale: f64,
    ) -> Command {
        if self.routing.is_some() {
            return self.follow_route(now_s, dt, pose, map, speed_scale);
        }
        self.follow_field(now_s, dt, pose, map, half_width, speed_scale)
    }

    /// The field layer's waypoints: passes those within their tolerance; the next one,
    /// and whether it is the last, if any remains.
    fn field_waypoint(&mut self, pos: DVec2) -> Option<(DVec2, bool)> {
        let p = self.params;
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
        let goal = self.current_waypoint()?;
        Some((goal, self.next + 1 == self.route.len()))
    }

    /// One step under the paper's field: toward the next waypoint, escaping local minima
    /// by following a boundary.
    fn follow_field(
        &mut self,
        now_s: f64,
        dt: f64,
        pose: PlanPose,
        map: &Map,
        half_width: f64,
        speed_scale: f64,
    ) -> Command {
        let pos = pose.position;
        let Some((goal, is_last)) = self.field_waypoint(pos) else {
            self.mode = Mode::Arrived;
            self.v = 0.0;
            return Command {
                v: 0.0,
                omega: 0.0,
                mode: Mode::Arrived,
                direction: DVec2::ZERO,
            };
        };
        let to_goal = goal - pos;
        let distance = to_goal.length();
        self.inflation = half_width.max(0.0);
        let field = self.field(pos, goal, is_last, map);
        let field_dir = field.normalize_or_zero();
        let heading_err_field = wrap_angle(field_dir.y.atan2(field_dir.x) - pose.heading);
        self.watch(now_s, distance, heading_err_field);
        let (direction, strength) = self.field_direction(now_s, pos, to_goal, field, map);
        let err = if direction == DVec2::ZERO {
            0.0
        } else {
            wrap_angle(direction.y.atan2(direction.x) - pose.heading)
        };
        let p = self.params;
        let omega = self.turn_toward(p.heading_gain * err, dt);
        let align = err.cos().max(0.0);
        let target = p.max_speed * strength * align * align * speed_scale.max(0.0);
        self.ramp_to(target, dt);
        Command {
            v: self.v,
            omega,
            mode: self.mode,
            direction,
        }
    }

    /// Where the field layer steers and how strongly: along the field, or round the
    /// boundary while escaping (leaving the escape when closer than on entry with the way
    /// to the goal clear, switching sides when it makes no progress).
    fn field_direction(
        &mut self,
        now_s: f64,
        pos: DVec2,
        to_goal: DVec2,
        field: DVec2,
        map: &Map,
    ) -> (DVec2, f64) {
        let p = self.params;
        let field_dir = field.normalize_or_zero();
        let along_field = (field_dir, (field.length() / p.apf.k_a).min(1.0));
        let Mode::Escape {
            side,
            entry_distance,
            since_s,
            best_distance,
            best_at_s,
        } = self.mode
        else {
            return along_field;
        };
        let distance = to_goal.length();
        let (best_distance, best_at_s) = if distance < best_distance - 0.1 {
            (distance, now_s)
        } else {
            (best_distance, best_at_s)
        };
        let clear = self.way_is_clear(pos, to_goal, map);
        if distance < entry_distance - 0.5 && clear {
            self.mode = Mode::Field;
            self.progress.clear();
            return along_field;
        }
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

    /// Plans the route from `from` if there is none yet (or retries a failed plan every
    /// `stuck_window_s`). The station calls it from its first sight of the leader, so the
    /// formation manager looks along the route before the leader moves.
    pub fn prepare(&mut self, now_s: f64, from: DVec2, map: &Map) {
        self.check_sensed(now_s, from, map);
        let window = self.params.stuck_window_s;
        let needs_plan = self.routing.as_ref().is_some_and(|r| {
            r.route.is_none() && (r.failure.is_none() || now_s - r.last_attempt_s >= window)
        });
        if needs_plan && self.mode != Mode::Arrived {
            self.plan_route(from, now_s, map);
        }
    }

    /// Plans again if something sensed since the last check lies on the way ahead (before
    /// the formation manager looks along the route, so it sees the new one).
    fn check_sensed(&mut self, now_s: f64, from: DVec2, map: &Map) {
        let Some(routing) = self.routing.as_mut() else {
            return;
        };
        if routing.unchecked.is_empty() {
            return;
        }
        // Blocking the way: plan again now. Narrowing it below what the wide formation
        // needs (the route's cost changed): plan again, at most once a second, since a
        // street with something parked in it narrows with every scan; while movers hold
        // the leader, at most every `HELD_REPLAN_S` (see [`Pace::held`]).
        let (hard, wide) = (routing.params.hard_clearance, routing.params.wide_clearance);
        let nearest = routing.route.as_ref().map_or(f64::INFINITY, |r| {
            nearest_to_route(&routing.unchecked, r, routing.s, wide)
        });
        let since = now_s - routing.last_attempt_s;
        let due = since >= 1.0;
        let due_held = since >= HELD_REPLAN_S;
        let blocked = nearest < hard;
        // Until a check is due (once a second), what was sensed waits to be checked
        // again. Held, a check due before `HELD_REPLAN_S` looks for blocking only: what
        // only narrowed the way is dropped then, and never looked at again (a mark is new
        // once).
        if blocked || due {
            routing.unchecked.clear();
        }
        if blocked || (due && nearest < wide && (!self.pace.held || due_held)) {
            tracing::info!(blocked, "something unmapped on the way: planning again");
            routing.replans += 1;
            routing.route = None;
            self.note(PlannerEvent::Replanned);
            self.plan_route(from, now_s, map);
        }
    }

    /// Plans the route from `from` through the remaining waypoints. The grid covers the
    /// waypoints, and `from` too when the leader stands outside that (or outside the grid
    /// it has).
    fn plan_route(&mut self, from: DVec2, now_s: f64, map: &Map) {
        let waypoints: Vec<DVec2> = self.route[self.next..].to_vec();
        let Some(routing) = self.routing.as_mut() else {
            return;
        };
        routing.last_attempt_s = now_s;
        if !routing.planner.as_ref().is_some_and(|p| p.covers(from)) {
            let mut points = waypoints.clone();
            let margin = 0.5 * routing.params.border;
            if routing.planner.is_some()
                || !RoutePlanner::extent(map, &points, &routing.params).covers(from, margin)
            {
                points.push(from);
            }
            routing.planner = Some(RoutePlanner::new(map, &points, routing.params));
        }
        let Some(planner) = routing.planner.as_ref() else {
            return;
        };
        let mut points = vec![from];
        let mut arcs = Vec::new();
        let mut length = 0.0;
        for w in waypoints {
            let start = *points.last().expect("starts with `from`");
            match planner.plan(start, w, &routing.blocked) {
                Ok(leg) => {
                    length += leg.length();
                    points.extend(leg.points.into_iter().skip(1));
                    arcs.push(length);
                }
                Err(_) if !routing.blocked.is_empty() => {
                    // The stuck marks are guesses (the map and what the scanner saw are
                    // the truth): when they leave no way, forget them and plan again.
                    tracing::info!(
                        marks = routing.blocked.len(),
                        "stuck marks leave no way: cleared"
                    );
                    routing.blocked.clear();
                    return self.plan_route(from, now_s, map);
                }
                Err(e) => {
                    routing.failure = Some(e);
                    routing.route = None;
                    return;
                }
            }
        }
        routing.failure = None;
        routing.route = Some(Route::new(points));
        routing.waypoint_arc = arcs;
        routing.s = 0.0;
        routing.progress.clear();
    }

    /// Slows to a stop in `mode`.
    fn hold(&mut self, mode: Mode, dt: f64) -> Command {
        self.v = (self.v - self.params.max_accel * dt).max(0.0);
        self.mode = mode;
        Command {
            v: self.v,
            omega: 0.0,
            mode,
            direction: DVec2::ZERO,
        }
    }

    /// One step along the route: waypoints, blockage, the local APF toward the carrot.
    fn follow_route(
        &mut self,
        now_s: f64,
        dt: f64,
        pose: PlanPose,
        map: &Map,
        speed_scale: f64,
    ) -> Command {
        let p = self.params;
        let pos = pose.position;
        if self.mode == Mode::Arrived {
            return self.hold(Mode::Arrived, dt);
        }
        let turn_round_s = std::f64::consts::PI / self.turn_limit().max(0.05) + 1.0;
        self.prepare(now_s, pos, map);
        let Some(routing) = self.routing.as_mut() else {
            return self.hold(Mode::NoRoute, dt);
        };
        let Some((s, passed, arrived)) = routing.advance(pos, &p) else {
            return self.hold(Mode::NoRoute, dt);
        };
        let stalled = routing.stalled(now_s, s, speed_scale, turn_round_s, &p);
        self.next += passed;
        if arrived {
            return self.hold(Mode::Arrived, dt);
        }
        if stalled {
            self.replan_blocked(s, pos, now_s, map);
            return self.hold(Mode::Route, dt);
        }
        self.drive_along(now_s, dt, pose, s, map, speed_scale)
    }

    /// The speed toward `target`, braking and speeding up within their limits.
    fn ramp_to(&mut self, target: f64, dt: f64) {
        let a = self.params.max_accel;
        let down = self.pace.brake.unwrap_or(a).max(a);
        let up = self.pace.accel.unwrap_or(a).max(a);
        self.v += (target - self.v).clamp(-down * dt, up * dt);
    }

    /// Movers (a crowd filling a street) have held the leader: the disc they stand in is
    /// marked blocked and the route planned again from `from`. A guess, as a stuck mark
    /// is: forgotten where it leaves no way (the route then stays as it was).
    pub fn avoid(&mut self, at: DVec2, radius: f64, from: DVec2, now_s: f64, map: &Map) {
        tracing::info!(
            x = at.x,
            y = at.y,
            radius,
            "movers hold the way: planning round them"
        );
        self.avoid_all(&[(at, radius)], from, now_s, map);
    }

    /// As [`Planner::avoid`], for several discs (centre, radius) at once: one plan.
    pub fn avoid_all(&mut self, discs: &[(DVec2, f64)], from: DVec2, now_s: f64, map: &Map) {
        let Some(routing) = self.routing.as_mut() else {
            return;
        };
        routing.blocked.extend_from_slice(discs);
        routing.replans += 1;
        routing.route = None;
        self.note(PlannerEvent::Replanned);
        self.plan_route(from, now_s, map);
    }

    /// The way ahead is blocked by something the map does not hold: the stretch ahead is
    /// marked blocked and the route planned again.
    fn replan_blocked(&mut self, s: f64, pos: DVec2, now_s: f64, map: &Map) {
        let Some(routing) = self.routing.as_mut() else {
            return;
        };
        let Some(route) = routing.route.as_ref() else {
            return;
        };
        let ahead = route.point_at(s + 0.8);
        tracing::info!(x = ahead.x, y = ahead.y, "route blocked: planning again");
        routing.blocked.push((ahead, 0.5));
        routing.replans += 1;
        routing.route = None;
        self.note(PlannerEvent::Replanned);
        self.plan_route(pos, now_s, map);
    }

    /// Drives toward the carrot on the route, `s` along it: the attraction, the
    /// repulsion never backward along the route and capped at the attraction, the turn
    /// and a speed that brakes for the goal.
    fn drive_along(
        &mut self,
        now_s: f64,
        dt: f64,
        pose: PlanPose,
        s: f64,
        map: &Map,
        speed_scale: f64,
    ) -> Command {
        let p = self.params;
        let pos = pose.position;
        let Some(routing) = self.routing.as_mut() else {
            return self.hold(Mode::NoRoute, dt);
        };
        let Some(route) = routing.route.as_ref() else {
            return self.hold(Mode::NoRoute, dt);
        };
        let end = route.length();
        let carrot = route.point_at(s + p.route_lookahead);
        let tangent = route.tangent_at(s);
        let to_carrot = carrot - pos;
        let attraction = to_carrot.normalize_or_zero() * p.apf.k_a;
        let mut repulsion = apf::repulsion(pos, map, &p.apf);
        let back = repulsion.dot(tangent);
        if back < 0.0 {
            repulsion -= tangent * back;
        }
        let cap = p.apf.k_a;
        if repulsion.length() > cap {
            repulsion = repulsion.normalize() * cap;
        }
        let direction = (attraction + repulsion).normalize_or_zero();
        let err = if direction == DVec2::ZERO {
            0.0
        } else {
            keep_turning(
                wrap_angle(direction.y.atan2(direction.x) - pose.heading),
                self.omega,
            )
        };
        let to_end = (end - s).max((route.point_at(end) - pos).length());
        if err.abs() < TURNING_AWAY {
            routing.turning_since = None;
        } else if routing.turning_since.is_none() {
            routing.turning_since = Some(now_s);
        }
        let omega = self.turn_toward(p.heading_gain * err, dt);
        let align = err.cos().max(0.0);
        // Brake for the goal: v ≤ √(2·a·d) with half the acceleration limit.
        let braking = (p.max_accel * to_end).sqrt();
        let target = (p.max_speed * align * align * speed_scale.max(0.0)).min(braking);
        self.ramp_to(target, dt);
        self.mode = Mode::Route;
        Command {
            v: self.v,
            omega,
            mode: Mode::Route,
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
            tracing::info!("planner: local minimum, following the boundary");
            self.note(PlannerEvent::Escape);
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

#[cfg(test)]
mod tests {
    use super::keep_turning;

    #[test]
    fn a_turn_under_way_is_kept_when_the_other_way_is_not_much_shorter() {
        // Turning left, the way now lies 171° to the right: go on left (189°).
        assert!((keep_turning(-2.99, 0.23) - (-2.99 + std::f64::consts::TAU)).abs() < 1e-12);
        // Turning left, the way 120° to the right: the left way (240°) is too long.
        assert_eq!(keep_turning(-2.1, 0.23), -2.1);
        // Within a quarter turn, or not turning, or already turning that way: as it is.
        assert_eq!(keep_turning(-1.2, 0.23), -1.2);
        assert_eq!(keep_turning(-2.99, 0.01), -2.99);
        assert_eq!(keep_turning(2.99, 0.23), 2.99);
    }
}
