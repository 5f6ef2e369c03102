//! Guidance: the leader's planner and the formation manager, stepped together as a
//! pipeline of two calls that return values.
//!
//! 1. [`Guidance::look`]: with the leader's estimate and the followers' statuses, the
//!    route is planned (or kept), the formation looks along the way ahead and the way
//!    driven and sets its blend, and the planner learns how fast the followers can go (a
//!    leader waiting for a lagging follower slows, and swings its slots slower too).
//! 2. [`Guidance::drive`]: the leader's command, and what happened on the way (an
//!    escape, a replan, no route, the goal).
//!
//! The station sends what lies between (detours) and decides whether the leader may drive
//! at all (its gate); guidance holds no link and no clock of its own.

use std::collections::VecDeque;

use glam::DVec2;

use super::fleet::LeaderEstimate;
use super::StationConfig;
use crate::formation::{FollowerStatus, FormationManager, Transformation};
use crate::geometry::map::Map;
use crate::geometry::Obstacle;
use crate::planner::route::{Route, RouteParams};
use crate::planner::{Guidance as Mode, Pace, PlanPose, Planner, PlannerEvent};

/// Spacing of the paths the formation manager looks along, m.
const PATH_STEP: f64 = 0.25;
/// How much of the leader's path the station keeps, m.
const DRIVEN_KEPT: f64 = 40.0;

/// What [`Guidance::look`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct Look {
    /// The formation's blend: 0 wide … 1 line.
    pub blend: f64,
    /// The change of shape that began now.
    pub change: Option<Transformation>,
    /// The path the leader drove, from where it is now, newest first.
    pub behind: Vec<DVec2>,
    /// How much the leader waits for a lagging follower: 1 not at all … 0.2.
    pub waiting: f64,
    /// The path ahead of the leader, from where it is now.
    pub ahead: Vec<DVec2>,
}

/// Whether a shape change under way slows the leader ([`Guidance::drive`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ShapeChange {
    Slows,
    /// Not while it goes on out of someone's way (`movers`).
    Ignored,
}

/// What [`Guidance::drive`] gives: the leader's command and what happened.
#[derive(Debug, Clone, PartialEq)]
pub struct Drive {
    pub v: f64,
    pub omega: f64,
    pub events: Vec<PlannerEvent>,
}

#[derive(Debug, Clone)]
pub struct Guidance {
    planner: Planner,
    formation: FormationManager,
    /// The leader's estimated path, oldest first, points `PATH_STEP` apart.
    driven: VecDeque<DVec2>,
    /// How far the leader has driven, m.
    driven_m: f64,
    /// The speed and acceleration a follower can use to keep up, m/s, m/s².
    follower_speed: f64,
    follower_accel: f64,
    /// Followers whose tracking error exceeds this slow the leader down, m.
    wait_above: f64,
    period_s: f64,
}

impl Guidance {
    pub fn new(cfg: &StationConfig) -> Self {
        let planner = match cfg.planner.guidance {
            Mode::Field => Planner::new(cfg.planner, cfg.route.clone(), cfg.initial_speed),
            Mode::Route => Planner::routed(
                cfg.planner,
                cfg.route.clone(),
                cfg.initial_speed,
                RouteParams::for_formation(&cfg.formation),
            ),
        };
        Self {
            planner,
            formation: FormationManager::new(cfg.formation.clone()),
            driven: VecDeque::new(),
            driven_m: 0.0,
            follower_speed: cfg.follower_speed,
            follower_accel: cfg.follower_accel,
            wait_above: cfg.wait_for_followers_above,
            period_s: cfg.period_ms as f64 / 1000.0,
        }
    }

    pub fn planner(&self) -> &Planner {
        &self.planner
    }
    pub fn formation(&self) -> &FormationManager {
        &self.formation
    }
    /// Whether the leader has reached its goal.
    pub fn arrived(&self) -> bool {
        self.planner.arrived()
    }

    /// How far the leader has driven, m.
    pub fn driven_m(&self) -> f64 {
        self.driven_m
    }
    /// The route being followed, once planned.
    pub fn route(&self) -> Option<&Route> {
        self.planner.route()
    }

    /// Puts `points` next on the leader's route (the sweep going back for a strip).
    pub fn insert_ahead(&mut self, points: &[DVec2]) {
        self.planner.insert_ahead(points);
    }

    /// Takes the next `count` points off the leader's route (a touch-up given up).
    pub fn remove_ahead(&mut self, count: usize) {
        self.planner.remove_ahead(count);
    }

    /// Whether movers crowd the formation's way (the wide shape gives way to the line).
    pub fn set_crowded(&mut self, crowded: bool) {
        self.formation.set_crowded(crowded);
    }

    /// Movers have held the leader: a way round the disc (`at`, `radius`) they stand in,
    /// from `from`, if the map has one.
    pub fn avoid(&mut self, at: DVec2, radius: f64, from: DVec2, now_s: f64, world: &Map) {
        self.planner.avoid(at, radius, from, now_s, world);
    }

    /// Someone comes the other way down a narrow way: the route keeps out of the discs
    /// along their way, from `from`, if the map leaves room ([`super::movers::passing`]).
    pub fn keep_aside(&mut self, discs: &[(DVec2, f64)], from: DVec2, now_s: f64, world: &Map) {
        self.planner.avoid_all(discs, from, now_s, world);
    }

    /// Obstacles sensed on the way, and those forgotten since (`map`: what remains).
    pub fn sensed(&mut self, added: &[Obstacle], removed: &[Obstacle], map: &Map) {
        self.planner.remove_obstacles(removed, map);
        self.planner.add_obstacles(added);
    }

    fn record_leader_path(&mut self, p: DVec2) {
        if self
            .driven
            .back()
            .is_some_and(|q| (p - *q).length() < PATH_STEP)
        {
            return;
        }
        if let Some(q) = self.driven.back() {
            self.driven_m += q.distance(p);
        }
        self.driven.push_back(p);
        if self.driven.len() as f64 * PATH_STEP > DRIVEN_KEPT {
            self.driven.pop_front();
        }
    }

    /// Step 1: the route, the formation's shape, and the pace of the followers.
    pub fn look(
        &mut self,
        now_s: f64,
        leader: &LeaderEstimate,
        followers: &[Option<FollowerStatus>],
        world: &Map,
    ) -> Look {
        self.record_leader_path(leader.pose.position);
        self.planner.prepare(now_s, leader.pose.position, world);
        let spec = self.formation.spec();
        let horizon =
            spec.lookahead + self.formation.wide_reach().max(self.formation.line_reach()) + 3.0;
        let ahead = self.planner.path_ahead(leader.pose, horizon, PATH_STEP);
        let behind: Vec<DVec2> = std::iter::once(leader.pose.position)
            .chain(self.driven.iter().rev().copied())
            .collect();
        let shape = self
            .formation
            .step(now_s, leader.motion(), &ahead, &behind, followers, world);
        let waiting = self.pace(shape.blend, followers);
        Look {
            blend: shape.blend,
            change: shape.change,
            behind,
            waiting,
            ahead,
        }
    }

    /// Tells the planner how fast the followers can go; how much the leader waits.
    fn pace(&mut self, blend: f64, followers: &[Option<FollowerStatus>]) -> f64 {
        // Only the wide slots swing round the leader; the line follows its trail. Until
        // the formation is all line, the wide slots' full reach counts: half way through a
        // change a V's rear slot swings with half its reach, but moves across on its own
        // too, and a turn the half reach allowed swung it at 1.5 m/s, out of its
        // follower's reach (1.5 m off).
        let swinging = if blend >= 1.0 { 0.0 } else { 1.0 };
        // The leader waits for a follower falling behind: it slows, and it swings the
        // slots slower too (turning on the spot at 0.1 rad/s, it swung a 5-V's rear slot
        // on at 0.65 m/s from a follower going round a bin).
        let worst = followers
            .iter()
            .flatten()
            .map(|f| f.error)
            .fold(0.0, f64::max);
        let over = worst - self.wait_above;
        let waiting = if over > 0.0 {
            (1.0 - over / 0.5).max(0.2)
        } else {
            1.0
        };
        self.planner.set_formation(
            self.formation.wide_reach() * swinging,
            self.follower_speed * waiting,
            self.follower_accel,
        );
        waiting
    }

    /// Step 2: the leader's command at `pace` (the station's: its followers, what moves),
    /// slowed (`change`) by a shape change.
    pub fn drive(
        &mut self,
        now_s: f64,
        leader: PlanPose,
        pace: Pace,
        change: ShapeChange,
        world: &Map,
    ) -> Drive {
        let scale = match change {
            ShapeChange::Slows => pace.scale.min(self.formation.speed_factor(now_s)),
            ShapeChange::Ignored => pace.scale,
        };
        let half_width = self.formation.half_width();
        let pace = Pace { scale, ..pace };
        let cmd = self
            .planner
            .step(now_s, self.period_s, leader, world, half_width, pace);
        Drive {
            v: cmd.v,
            omega: cmd.omega,
            events: self.planner.take_events(),
        }
    }
}
