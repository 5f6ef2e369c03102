//! The station among what moves: what each mover is expected to do (`prediction`), the
//! leader's pace from one ranking of candidate speeds (`pace`), and the route kept aside
//! for people coming the other way down a narrow way (`oncoming`). One decision a period,
//! returned as a value ([`Decision`]); one event when the fleet's manner changes, and one
//! when it ends ([`Manner`]).

pub(crate) mod lanes;
pub(crate) mod oncoming;
pub(crate) mod pace;
pub(crate) mod prediction;

use glam::DVec2;

pub use pace::Candidate;
use pace::{Choice, Context, HELD_BELOW};
use prediction::{Mover, Prediction, MIN_RADIUS_M};

use crate::perception::tracking::TrackView;
use crate::scenario::YieldingSpec;
use crate::station::model;

/// A manner held this long is announced; a return to the route's pace, once it has held
/// this long, ends it: the ranking may try another candidate for a period or two, s.
const SETTLE_S: f64 = 0.3;
const RESUMED_AFTER_S: f64 = 1.0;
/// A step aside takes the leader's control point this far to a side of its path, and
/// this far on (a differential drive turns out of a lane on an arc): a cyclist's
/// half-width, the footprint and a margin, m.
const ASIDE_M: f64 = 1.2;
const ASIDE_AHEAD_M: f64 = 0.8;
/// Someone "comes along the lane" whose way is within this angle of the leader's
/// heading, either direction: steering out of a crosser's way stalls the fleet in it.
const ALONG_WITHIN_RAD: f64 = 0.52;
/// ... and whose way passes within this of the leader: the wide shape's half-width and a
/// cyclist's, m.
const ALONG_LANE_M: f64 = 2.5;
/// ... and who moves faster than this: someone standing in the lane is gone round, m/s.
const ALONG_MOVING_MPS: f64 = 0.5;

/// Movers round the fleet: whether they crowd its way (`line`: the wide shape gives way
/// to the line) and whether they are a crowd (`dense`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Crowd {
    pub line: bool,
    pub dense: bool,
}

/// How the fleet goes among what moves, as the operator is told.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Manner {
    /// At the route's pace, or slowed for courtesy.
    Route,
    /// Held: standing (or creeping) for someone.
    Waiting,
    /// Backing out of the way of someone who may not see it.
    SteppingBack,
    /// Stepping aside, out of the lane of someone coming along it.
    SteppingAside,
    /// Going on, hurrying if need be, out of the way of someone who would walk into it.
    ClearingWay,
}

/// What the movers decided this period.
#[derive(Debug, Clone, PartialEq)]
pub struct Decision {
    pub choice: Choice,
    /// The speed the leader makes for, m/s (negative: backing).
    pub target: f64,
    /// Movers hold the leader.
    pub held: bool,
    /// Held long enough: a way round is due, round this point and radius.
    pub avoid: Option<(DVec2, f64)>,
    /// The manner announced now, if it changed (`Some(Route)`: the last one ended).
    pub announce: Option<Manner>,
    /// Anything moved near: the leader gets going again as hard as its followers may.
    pub among_movers: bool,
    /// The followers (by id) held where they can stop: they would still move in a
    /// contact the chosen pace predicts (the station fills this in from the model's
    /// order).
    pub held_followers: Vec<u16>,
}

/// The station's movers room, from period to period.
#[derive(Debug, Clone)]
pub struct Movers {
    spec: YieldingSpec,
    prediction: Prediction,
    last: Candidate,
    held_since_s: Option<f64>,
    /// When a way round was last asked for.
    avoided_s: Option<f64>,
    /// The manner announced, and the one chosen since when.
    announced: Manner,
    current: (Manner, f64),
}

impl Movers {
    pub fn new(spec: YieldingSpec) -> Self {
        Self {
            spec,
            prediction: Prediction::default(),
            last: Candidate::Share(1.0),
            held_since_s: None,
            avoided_s: None,
            announced: Manner::Route,
            current: (Manner::Route, 0.0),
        }
    }

    pub fn spec(&self) -> &YieldingSpec {
        &self.spec
    }

    /// The movers as predicted this period (`robots`: the leader first), and whether they
    /// crowd the fleet's way (the line) and whether they are a crowd (nobody walks on for
    /// long there, and the fleet moves no more than its pace).
    pub fn observe<'a>(
        &mut self,
        now_s: f64,
        robots: &[DVec2],
        footprint: f64,
        tracks: &'a [TrackView],
    ) -> (Vec<Mover<'a>>, Crowd) {
        let movers =
            self.prediction
                .step(now_s, robots, footprint, tracks, self.spec.personal_space_m);
        let crowd = Crowd {
            line: self.prediction.crowded(now_s),
            dense: self.prediction.dense(now_s),
        };
        (movers, crowd)
    }

    /// The leader's pace this period (`ctx.pace`: the route's, m/s).
    pub fn decide(
        &mut self,
        now_s: f64,
        fleet: &model::Fleet,
        movers: &[Mover],
        ctx: &Context,
        site: &crate::geometry::map::Map,
    ) -> Decision {
        let choice = if movers.is_empty() {
            Choice {
                candidate: Candidate::Share(1.0),
                key: pace::Key::default(),
                clears: false,
                holds: Vec::new(),
            }
        } else {
            let aside = if movers.iter().any(|m| along_the_lane(m, fleet.leader.pose)) {
                self.aside_points(fleet.leader.pose)
            } else {
                Vec::new()
            };
            pace::choose(fleet, movers, (ctx, site), self.last, &aside)
        };
        tracing::trace!(now_s, chosen = ?choice.candidate, key = ?choice.key, "pace");
        self.last = choice.candidate;
        let target = choice.candidate.target(ctx);
        let held = target < HELD_BELOW * ctx.pace;
        if !held {
            self.held_since_s = None;
        } else if self.held_since_s.is_none() {
            self.held_since_s = Some(now_s);
        }
        let avoid = self.way_round_due(now_s, fleet.leader.pose.position, ctx.pace, movers);
        let manner = manner_of(&choice, target, held);
        Decision {
            choice,
            target,
            held,
            avoid,
            announce: self.announce(now_s, manner),
            among_movers: !movers.is_empty(),
            held_followers: Vec::new(),
        }
    }

    /// Where the leader's control point may step aside to, either side of its path: the
    /// point it is stepping to kept, so the step is not chased round.
    fn aside_points(&self, leader: crate::geometry::PlanPose) -> Vec<DVec2> {
        let h = DVec2::from_angle(leader.heading);
        let fresh = |side: f64| leader.position + h * ASIDE_AHEAD_M + h.perp() * side * ASIDE_M;
        match self.last {
            Candidate::Aside(p) => {
                let side = h.perp().dot(p - leader.position).signum();
                vec![p, fresh(-side)]
            }
            _ => vec![fresh(1.0), fresh(-1.0)],
        }
    }

    /// The manner to announce, if it changed and has settled.
    fn announce(&mut self, now_s: f64, manner: Manner) -> Option<Manner> {
        if manner != self.current.0 {
            self.current = (manner, now_s);
        }
        let settle = if manner == Manner::Route {
            RESUMED_AFTER_S
        } else {
            SETTLE_S
        };
        let settled = now_s - self.current.1 >= settle - 1e-9;
        (settled && manner != self.announced).then(|| {
            self.announced = manner;
            manner
        })
    }

    /// Held for `replan_after_s` by movers: the disc they stand in, once per hold.
    fn way_round_due(
        &mut self,
        now_s: f64,
        leader: DVec2,
        pace: f64,
        movers: &[Mover],
    ) -> Option<(DVec2, f64)> {
        let since = self.held_since_s?;
        if now_s - since < self.spec.replan_after_s || self.avoided_s.is_some_and(|t| t >= since) {
            return None;
        }
        self.avoided_s = Some(now_s);
        let reach = pace * self.spec.horizon_s + 2.0;
        let near: Vec<DVec2> = movers
            .iter()
            .map(|m| m.track.position)
            .filter(|p| p.distance(leader) <= reach)
            .collect();
        if near.is_empty() {
            return None;
        }
        let centre = near.iter().copied().sum::<DVec2>() / near.len() as f64;
        let radius = near.iter().map(|p| p.distance(centre)).fold(0.0, f64::max)
            + self.spec.personal_space_m
            + MIN_RADIUS_M;
        Some((centre, radius))
    }
}

/// The manner a choice shows.
fn manner_of(choice: &Choice, target: f64, held: bool) -> Manner {
    match choice.candidate {
        Candidate::Back => Manner::SteppingBack,
        Candidate::Aside(_) => Manner::SteppingAside,
        _ if held => Manner::Waiting,
        _ if choice.clears && target > 0.0 => Manner::ClearingWay,
        Candidate::Hurry => Manner::ClearingWay,
        _ => Manner::Route,
    }
}

/// Whether `m` comes along the leader's lane, from ahead or from behind.
fn along_the_lane(m: &Mover, leader: crate::geometry::PlanPose) -> bool {
    let v = m.velocity();
    let h = DVec2::from_angle(leader.heading);
    let off = (m.track.position - leader.position).dot(h.perp()).abs();
    v.length() > ALONG_MOVING_MPS
        && v.dot(h).abs() >= v.length() * ALONG_WITHIN_RAD.cos()
        && off <= ALONG_LANE_M
}
