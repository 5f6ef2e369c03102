//! The base station's core, stepped at 10 Hz with time passed in. The `run` command drives
//! it from a serial modem or UDP and the wall clock; the simulator drives it from the
//! simulated radio and the simulated clock. Same code, same bytes.
//!
//! One step is a pipeline over rooms that each own one concern and return values
//! (`docs/basestation.md` draws it):
//!
//! - `fleet`: what the robots reported (telemetry, faults, who is fresh, where the
//!   leader is now); `radio`: bytes in and out over the authenticated link;
//! - the **gate** ([`Gate`]): whether the fleet may move at all (the operator's hold in
//!   `operator`, a robot fault, the localization watch, a lost leader, a fleet still
//!   assembling);
//! - `guidance`: the planner and the formation manager (`look`, then `drive`);
//! - `model`: the one forward model of the fleet, the firmware's own laws and limits;
//! - `movers/`: what each mover is expected to do (`prediction`), the leader's pace from
//!   one ranking (`pace`), people who stopped passed behind (`lanes`), people coming along
//!   the fleet's way passed aside (`oncoming`); `drive`: the pace and the leader's
//!   command;
//! - `robots/`: the robots among themselves (`spacing`, the leader's `way`, the
//!   `line_order`, `detour`s) and the `desk` that keeps one order per follower;
//!   `orders`: every room's proposals through it;
//! - `fixes/`: fixes from the site's localization forwarded and watched;
//!   [`crate::perception`]: what the scans found;
//! - `events`: what the operator and the report are told; `smoothing`: the turn rate
//!   the followers are told.

mod drive;
mod events;
mod fixes;
mod fleet;
mod guidance;
mod model;
mod movers;
mod operator;
mod orders;
mod radio;
mod robots;
mod smoothing;
mod story;

use glam::DVec2;
use protocol::link::{Link, Timing};
use protocol::messages::Stop;
use protocol::{Address, FrameDecoder, MasterKey, RejectCounts};

pub use events::{Severity, StationEvent, FAULT_NAMES};
use fixes::watch::FixWatch;
pub use fixes::watch::{FixChange, FixLimits};
pub use fixes::NotForwarded;
use fixes::OutgoingFix;
use fleet::Fleet;
pub use fleet::{is_following, LeaderEstimate, RobotStatus};
pub use guidance::{Drive, Guidance, Look, ShapeChange};
use movers::lanes::{self, Lanes};
use movers::oncoming::{self, Passing};
pub use movers::prediction::VEHICLE_SPACE_M;
pub use movers::Manner;
use movers::Movers;
pub use operator::OperatorCommand;
use operator::OperatorHold;
use robots::desk::Desk;
use robots::detour::Detours;
use robots::line_order::LineOrder;
use robots::spacing::{self, Spacing};
use robots::way::Blocking;
pub use smoothing::TurnRateSmoother;
pub use story::{Ending, Progress};

use crate::coverage::watch::SweepWatch;
use crate::formation::{FollowerStatus, FormationManager, FormationSpec};
use crate::geometry::map::Map;
use crate::perception::tracking::{Motion, TrackView, Tracker};
use crate::perception::{Change, Perception, PerceptionLimits};
use crate::planner::route::Route;
use crate::planner::{PlanPose, PlannerEvent, PlannerParams};

/// Every robot as estimated this period (the leader among them), and of those the
/// followers following.
type Robots<'a> = (&'a [spacing::Body], &'a [spacing::Body]);

/// What stands still is marked within this of the leader: the route is planned against
/// what the formation reaches before it has moved on (people standing farther off have
/// mostly walked on by then), m. The scanner tracks what moves much farther.
const MARK_REACH_M: f64 = 8.0;

/// A track not judged yet moves where its filter's speed is over this, m/s, and over
/// twice its sigma: a walker, not the noise of something standing.
const NEW_MOVING_MPS: f64 = 0.5;

/// A track not judged yet counts only this far from what the scans hold and the map does
/// not: hits along a parked van's side, seen from a fleet driving by, make new tracks
/// that seem to move (a kerb's walker beside a mapped wall still counts), m.
const NEW_OFF_SENSED_M: f64 = 1.5;

/// Whether a track not judged yet already moves, by its filter: person-sized, faster than
/// [`NEW_MOVING_MPS`] and twice its velocity's sigma.
fn moves(v: &TrackView) -> bool {
    let speed = v.velocity.length();
    v.radius <= 0.5 && speed > NEW_MOVING_MPS && speed > 2.0 * v.velocity_sigma
}

/// Most robots one base station serves.
pub const MAX_ROBOTS: usize = 1024;

/// Everything the station needs from the scenario or site file.
#[derive(Debug, Clone)]
pub struct StationConfig {
    pub leader: u16,
    /// In slot order at the start: follower k takes slot k (the station may hand the
    /// line's slots out anew, `order`).
    pub followers: Vec<u16>,
    pub planner: PlannerParams,
    pub formation: FormationSpec,
    pub route: Vec<DVec2>,
    pub map: Map,
    pub track_width: f64,
    pub initial_speed: f64,
    /// Followers whose reported tracking error exceeds this slow the leader down, m.
    pub wait_for_followers_above: f64,
    /// Telemetry older than this is stale, ms (a follower's: that plus its reporting
    /// interval twice over).
    pub telemetry_timeout_ms: u32,
    /// Followers send telemetry every this many periods (`air::follower_report_every`).
    pub report_every: u8,
    /// The robots share one channel (`[link] radio`): its air is scarce.
    pub shared_channel: bool,
    /// The speed a follower can use to hold its slot (a margin under its limit), m/s.
    pub follower_speed: f64,
    /// The acceleration a follower can use to keep up (a margin under its limit), m/s².
    pub follower_accel: f64,
    /// Control period, ms.
    pub period_ms: u32,
    /// How fixes from a localization source are forwarded and watched.
    pub fixes: FixLimits,
    /// What the leader's scans may claim, and how long what they found is kept.
    pub perception: PerceptionLimits,
    /// How the leader and the formation yield to what moves.
    pub yielding: crate::scenario::YieldingSpec,
    /// How hard the leader may brake for someone in its way (a margin under its limit),
    /// m/s².
    pub yield_brake: f64,
    /// How fast the leader backs out of someone's way (a margin under its limit), m/s.
    pub reverse_speed: f64,
    /// How far ahead of a follower's centre its control point is (the L-φ law's d), m.
    pub control_offset: f64,
    /// The robots' control configuration (limits, the L-φ law's gains), as their firmware
    /// has it.
    pub robot: control_core::RobotConfig,
    /// How the station treats what moves: as it should, or a baseline to measure that by.
    pub movers: MoverPolicy,
    /// The areas to sweep, when the route sweeps any.
    pub sweep: Option<crate::coverage::watch::SweepSetup>,
}

/// How the station treats what moves. Only `Heed` drives a fleet; the other two are the
/// baselines its manners are measured against, in the same worlds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum MoverPolicy {
    /// Yield, step aside, keep clear: the station's manners.
    #[default]
    Heed,
    /// Moving tracks are not acted on (what stands still is still avoided); the robots'
    /// own rings and time-to-collision stop still act.
    Ignore,
    /// The fleet assembles, then stands where it is for the whole run.
    Parked,
}

impl StationConfig {
    pub fn from_scenario(s: &crate::scenario::Scenario) -> Self {
        Self {
            leader: s.leader().id,
            followers: s.followers().iter().map(|r| r.id).collect(),
            planner: s.planner_params(),
            formation: s.formation_spec(),
            route: s.route_points(),
            map: s.build_map(),
            track_width: s.robot.track_width,
            initial_speed: s.leader().initial_speed,
            wait_for_followers_above: s.planner.wait_for_followers_above,
            telemetry_timeout_ms: s.follower.leader_timeout_ms,
            report_every: crate::air::follower_report_every(s),
            shared_channel: s.link.radio.is_some(),
            follower_speed: 0.8 * s.robot.max_speed,
            follower_accel: 0.5 * s.robot.max_accel,
            period_ms: 100,
            fixes: FixLimits::from_spec(&s.localization),
            perception: PerceptionLimits::from_scenario(s),
            yielding: s.yielding.clone(),
            yield_brake: 0.8 * s.robot.max_accel,
            reverse_speed: 0.8 * s.robot.max_reverse_speed,
            control_offset: s.follower.d,
            robot: s.robot_config(),
            movers: MoverPolicy::Heed,
            sweep: s.sweep_setup(),
        }
    }
}

/// The base station's first `Hello` nonce: its start time (ms since the Unix epoch, or
/// the simulator's clock) above 19 random bits. Robots answer only a nonce newer than the
/// last one they saw from the base station, so a restarted station must count on from
/// where the last one stopped: time does that, the random bits keep it unguessable.
pub fn nonce_base(start_ms: u64, random: u32) -> u64 {
    start_ms << 20 | (random & 0x7_FFFF) as u64
}

/// Whether the fleet may move, as far as the station itself is concerned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Gate {
    /// The leader has not been heard yet (fresh, and knowing where it is): nothing to do.
    Waiting,
    /// The leader is known and holds until every follower is linked and following.
    Assembling,
    /// The fleet is ready: the leader drives.
    Running,
    /// The leader's telemetry went stale: Stop to everyone until it is back (`ready`:
    /// whether the fleet was running).
    LeaderLost { ready: bool },
    /// A robot fault stopped the mission: Stop to everyone, for good.
    Halted,
}

pub struct BaseStation {
    cfg: StationConfig,
    link: Box<Link<MAX_ROBOTS>>,
    decoder: FrameDecoder,
    fleet: Fleet,
    guidance: Guidance,
    gate: Gate,
    /// What the leader's scanner found that the map does not hold.
    perception: Perception,
    /// What of it moves.
    tracker: Tracker,
    /// The movers predicted, and the leader's pace among them.
    movers: Movers,
    /// The people who stopped, passed behind.
    lanes: Lanes,
    /// The map and what was sensed: what the planner and the formation avoid.
    world: Map,
    outbox: Vec<u8>,
    last_slots_ms: Option<u32>,
    /// The follower whose slots the round on a shared channel refreshed last.
    slots_turn: usize,
    /// Robots whose slots go out at the next step (they just linked: what we sent them
    /// before, they refused).
    slots_due: Vec<u16>,
    events: Vec<StationEvent>,
    /// Forwarding fixes from a localization source, and watching their age.
    fix_watch: Option<FixWatch<OutgoingFix>>,
    operator: OperatorHold,
    last_command: (f64, f64),
    /// The turn rate the followers are told, calmed where it only jitters.
    broadcast_omega: TurnRateSmoother,
    /// Followers being sent round what holds them.
    detours: Detours,
    /// Followers held short of another robot.
    spacing: Spacing,
    /// Whether a follower stands in the leader's way.
    blocking: Blocking,
    /// People coming the other way down a narrow way, passed aside.
    passing: Passing,
    /// Whether the line's followers stand in slot order.
    line_order: LineOrder,
    /// One order per follower, by rank.
    desk: Desk,
    /// The points the followers were told to make for last period.
    orders: orders::Told,
    /// When the fleet set off (the gate opened), station ms.
    running_since_ms: Option<u32>,
    /// The followers held for people, and the point each makes for.
    people_holds: orders::Told,
    /// The ground swept as the station estimates it, and what it goes back for.
    sweeping: Option<SweepWatch>,
}

impl BaseStation {
    /// `session`: fresh at every start (random); `nonce_base`: see [`nonce_base`].
    /// `master`: the fleet's master key; the station derives the broadcast key and each
    /// robot's key from it (`protocol::auth`).
    pub fn new(cfg: StationConfig, master: &MasterKey, session: u32, nonce_base: u64) -> Self {
        let mut link = Box::new(Link::new(
            Address::Base,
            master.broadcast(),
            session,
            nonce_base,
            Timing {
                // A robot reporting seldom is not silent: it is on a shared channel.
                relink_after_ms: Timing::default().relink_after_ms
                    + 2 * u32::from(cfg.report_every.max(1) - 1) * cfg.period_ms,
                // A robot's answer may wait for its slot up to a report interval.
                max_rtt_ms: Timing::default().max_rtt_ms
                    + u32::from(cfg.report_every.max(1) - 1) * cfg.period_ms,
                ..Timing::default()
            },
        ));
        let fleet = Fleet::new(
            cfg.leader,
            cfg.followers.clone(),
            cfg.track_width,
            cfg.telemetry_timeout_ms,
        )
        .with_follower_timeout(
            cfg.telemetry_timeout_ms + 2 * u32::from(cfg.report_every.max(1) - 1) * cfg.period_ms,
        );
        for id in fleet.ids() {
            link.add_peer(Address::Robot(id), master.robot(id));
        }
        let sweeping = cfg.sweep.clone().map(|s| SweepWatch::new(s, &cfg.map));
        Self {
            sweeping,
            guidance: Guidance::new(&cfg),
            perception: Perception::new(cfg.perception),
            tracker: Tracker::new(cfg.yielding.personal_space_m),
            movers: Movers::new(cfg.yielding.clone()),
            lanes: Lanes::default(),
            world: cfg.map.clone(),
            cfg,
            link,
            decoder: FrameDecoder::new(),
            fleet,
            gate: Gate::Waiting,
            outbox: Vec::new(),
            last_slots_ms: None,
            slots_turn: 0,
            slots_due: Vec::new(),
            events: Vec::new(),
            fix_watch: None,
            operator: OperatorHold::default(),
            broadcast_omega: TurnRateSmoother::default(),
            last_command: (0.0, 0.0),
            detours: Detours::default(),
            spacing: Spacing::default(),
            blocking: Blocking::default(),
            passing: Passing::default(),
            line_order: LineOrder::default(),
            desk: Desk::default(),
            orders: orders::Told::new(),
            running_since_ms: None,
            people_holds: orders::Told::new(),
        }
    }

    pub fn config(&self) -> &StationConfig {
        &self.cfg
    }

    /// The ground swept as the station estimates it (with areas to sweep).
    pub fn sweeping(&self) -> Option<&SweepWatch> {
        self.sweeping.as_ref()
    }

    /// A site feed refused `refused` records in the last second (`input`: its name): an
    /// event, so that the console and the recording show it beside the run's others.
    pub fn feed_refused(&mut self, input: &str, refused: u64, now_ms: u32) {
        tracing::warn!(input, refused, "a feed refuses records in bulk");
        self.events.push(StationEvent::FeedRefused {
            input: input.to_string(),
            refused,
            at_ms: now_ms,
        });
    }

    /// The slot a follower holds now (its index among the formation's slots).
    pub fn slot_of(&self, robot: u16) -> Option<usize> {
        self.fleet.followers.iter().position(|id| *id == robot)
    }
    pub fn link(&self) -> &Link<MAX_ROBOTS> {
        &self.link
    }
    pub fn guidance(&self) -> &Guidance {
        &self.guidance
    }
    pub fn formation(&self) -> &FormationManager {
        self.guidance.formation()
    }
    /// Whether the leader has reached its goal.
    pub fn arrived(&self) -> bool {
        self.guidance.arrived()
    }
    /// The route the leader follows, once planned.
    pub fn route(&self) -> Option<&Route> {
        self.guidance.route()
    }
    pub fn robots(&self) -> &std::collections::BTreeMap<u16, RobotStatus> {
        self.fleet.robots()
    }
    pub fn events(&self) -> &[StationEvent] {
        &self.events
    }
    pub fn gate(&self) -> Gate {
        self.gate
    }
    /// The last (v, ω) sent to the leader.
    pub fn last_command(&self) -> (f64, f64) {
        self.last_command
    }
    /// Rejected frames by reason, over the whole link.
    pub fn rejects(&self) -> RejectCounts {
        self.link.stats().rejects
    }
    /// The obstacles sensed so far that the map does not hold.
    pub fn perception(&self) -> &Perception {
        &self.perception
    }
    /// The leader's pose predicted to `now_ms` from its latest telemetry.
    pub fn leader_estimate(&self, now_ms: u32) -> Option<LeaderEstimate> {
        self.fleet.leader_estimate(now_ms)
    }

    /// One scan of the leader's range scanner at `now_ms`: hit points in the site frame.
    /// Hits the map explains are ignored, and hits the leader cannot have seen (off the
    /// site, out of reach, or while the station does not know where it is); the rest
    /// become obstacles the leader avoids, and the route is planned again if they lie on
    /// it ([`crate::perception`]).
    pub fn sense(&mut self, hits: &[DVec2], now_ms: u32) {
        let estimate = self.leader_estimate(now_ms).map(|l| l.pose);
        let leader = estimate.map(|p| p.position);
        let unexplained = self.perception.screen(hits, leader, &self.cfg.map);
        let Some(PlanPose {
            position: origin,
            heading,
        }) = estimate
        else {
            return;
        };
        let fleet: Vec<DVec2> = self
            .fleet
            .positions(now_ms)
            .iter()
            .map(|(_, p)| *p)
            .chain(std::iter::once(origin))
            .collect();
        let seen = self.tracker.observe(&unexplained, origin, now_ms);
        let views: Vec<TrackView> = self
            .tracker
            .views(now_ms)
            .filter(|t| seen.seen.contains(&t.id))
            .collect();
        let round = lanes::Round {
            map: &self.cfg.map,
            leader: (origin, DVec2::from_angle(heading)),
            fleet: &fleet,
        };
        let lanes = self.lanes.step(&views, round);
        let mut change = self.perception.release(&seen.released);
        let marks: Vec<_> = seen
            .marks
            .iter()
            .map(|(_, h, t)| (*h, Some(*t)))
            .chain(lanes.into_iter().map(|(h, t)| (h, Some(t))))
            .filter(|(h, _)| h.distance(origin) <= MARK_REACH_M)
            .collect();
        let added = self.perception.mark(&marks, 0, now_ms);
        change.added = added.added;
        change.removed.extend(added.removed);
        self.apply_sensed(change);
    }

    /// What the scans show, followed: each track predicted to `now_ms`.
    pub fn tracks(&self, now_ms: u32) -> impl Iterator<Item = TrackView> + '_ {
        self.tracker.views(now_ms)
    }

    pub fn tracker(&self) -> &Tracker {
        &self.tracker
    }

    /// What perception added or forgot, into guidance and the station's map.
    fn apply_sensed(&mut self, change: Change) {
        if change.is_empty() {
            return;
        }
        tracing::debug!(
            added = change.added.len(),
            forgotten = change.removed.len(),
            "sensed obstacles the map does not hold"
        );
        for o in &change.removed {
            self.world.remove(o);
        }
        self.guidance
            .sensed(&change.added, &change.removed, &self.world);
        for o in change.added {
            self.world.insert(o);
        }
    }

    /// One 10 Hz step: the link's upkeep, the gate, then the movers and guidance, the
    /// followers' orders, and the leader's drive.
    pub fn step(&mut self, now_ms: u32) {
        self.upkeep(now_ms);
        let Some(leader) = self.pass_gate(now_ms) else {
            return;
        };
        let now_s = now_ms as f64 / 1000.0;
        let statuses = self
            .fleet
            .follower_statuses(now_ms, |id| self.detours.is_active(id));
        let tracks = self.moving_tracks(now_ms);
        // Every robot as estimated this period (the leader among them).
        let bodies = self.fleet.bodies(now_ms);
        let positions = drive::positions(leader.pose.position, &bodies, self.cfg.leader);
        if let Some(sweeping) = &mut self.sweeping {
            let estimated = bodies.iter().map(|b| (b.id, b.position, b.heading));
            sweeping.observe(estimated, now_s);
        }
        let footprint = self.guidance.formation().spec().footprint;
        let (predicted, crowd) = self.movers.observe(now_s, &positions, footprint, &tracks);
        self.guidance.set_crowded(crowd.line);
        let crowded = crowd.dense;
        let look = self.guidance.look(now_s, &leader, &statuses, &self.world);
        if let Some(change) = look.change {
            tracing::info!(
                to = change.to.shape_name(change.to.blend()),
                "formation change"
            );
            self.events.push(StationEvent::Transformation {
                to: change.to,
                at_ms: now_ms,
            });
        }
        self.keep_line_order(&look.behind, &statuses, now_ms);
        let following = self.fleet.following(&bodies, now_ms);
        let robots = (&bodies[..], &following[..]);
        // Leave only with the whole fleet: until then (or parked) the leader holds.
        let ready = self.fleet_ready(now_ms) && self.cfg.movers != MoverPolicy::Parked;
        let decision = ready
            .then(|| self.pace_among_movers(&leader, &look, &predicted, crowded, robots, now_ms));
        let held = decision.as_ref().map(|d| &d.held_followers[..]);
        let moving = (&tracks[..], crowded);
        let round = self.give_orders(leader.pose, &look, moving, robots, held, now_ms);
        let Some(decision) = decision else {
            self.hold_leader(&leader, now_ms);
            return;
        };
        self.keep_aside(leader.pose, moving, now_s);
        if let Some((at, radius)) = round {
            tracing::info!(
                x = at.x,
                y = at.y,
                "a follower stands in the leader's way: going round it"
            );
            let from = leader.pose.position;
            self.guidance.avoid(at, radius, from, now_s, &self.world);
        }
        self.drive_leader(&leader, &look, &decision, &bodies, now_ms);
    }

    /// The tracks that move, that the station acts on (none in a baseline that ignores
    /// them): those judged moving, and those not judged yet whose filter already says
    /// they move (judging takes two novel scans half a second apart, longer for two
    /// people walking side by side; someone stepping off the kerb beside the fleet reaches
    /// it in two seconds).
    fn moving_tracks(&self, now_ms: u32) -> Vec<TrackView> {
        if self.cfg.movers != MoverPolicy::Heed {
            return Vec::new();
        }
        self.tracker
            .views(now_ms)
            .filter(|v| {
                let clear = self
                    .perception
                    .obstacles()
                    .all(|o| o.nearest(v.position).distance >= NEW_OFF_SENSED_M);
                v.motion == Motion::Moving || v.motion == Motion::New && clear && moves(v)
            })
            .collect()
    }

    /// What every period needs whatever the gate says: handshakes, slots when due, the
    /// fixes due, forgotten scan marks, the localization watch.
    fn upkeep(&mut self, now_ms: u32) {
        self.challenge_due(now_ms);
        self.slots_upkeep(now_ms);
        self.send_due_fixes(now_ms);
        let forgotten = self.perception.age(now_ms);
        self.apply_sensed(forgotten);
        self.tracker.age(now_ms);
        self.check_fixes(now_ms);
    }

    /// Slots to the robots that just linked, and again to every follower each second (a
    /// slot lost is mended); on a shared channel the refresh goes round, one follower every
    /// second period: all at once they would fill the downlink behind the leader state.
    fn slots_upkeep(&mut self, now_ms: u32) {
        let mut due = std::mem::take(&mut self.slots_due);
        match self.last_slots_ms {
            Some(_) if self.cfg.shared_channel => {
                let n = 2 * self.fleet.followers.len().max(1);
                self.slots_turn = (self.slots_turn + 1) % n;
                if let Some(&id) = self.fleet.followers.get(self.slots_turn / 2) {
                    if !due.contains(&id) {
                        due.push(id);
                    }
                }
            }
            Some(t) if now_ms.wrapping_sub(t) < 1000 => {}
            _ => {
                self.send_slots(now_ms, None);
                self.last_slots_ms = Some(now_ms);
                return;
            }
        }
        if !due.is_empty() {
            self.send_slots(now_ms, Some(&due));
        }
    }

    /// The gate: the operator's hold, a fault, the localization watch, the leader's
    /// telemetry. The leader's estimate when guidance may run; `None` (having sent what
    /// the gate says) when it may not.
    fn pass_gate(&mut self, now_ms: u32) -> Option<LeaderEstimate> {
        match self.operator.this_period() {
            // Every period, not once: a robot that missed it (a lost frame) gets the next.
            Some(OperatorCommand::Resume) => {
                self.send(
                    Address::Broadcast,
                    now_ms,
                    &OperatorCommand::Resume.message(),
                );
            }
            Some(hold) => {
                self.send(Address::Broadcast, now_ms, &hold.message());
                return None;
            }
            None => {}
        }
        let localization_halt = self.fix_watch.as_ref().is_some_and(FixWatch::halted);
        if self.gate == Gate::Halted || localization_halt {
            // A robot cannot drive as told, or cannot know where it is: everyone brakes
            // and holds.
            self.broadcast(Stop { reason: 2 }, now_ms);
            return None;
        }
        let Some(leader) = self.leader_estimate(now_ms) else {
            self.leader_silent(now_ms);
            return None;
        };
        match self.gate {
            Gate::Waiting => self.gate = Gate::Assembling,
            Gate::LeaderLost { ready } => {
                self.gate = if ready {
                    Gate::Running
                } else {
                    Gate::Assembling
                };
                self.events.push(StationEvent::LeaderBack { at_ms: now_ms });
            }
            _ => {}
        }
        Some(leader)
    }

    /// No fresh telemetry from the leader: nothing yet, or it was lost.
    fn leader_silent(&mut self, now_ms: u32) {
        let ready = match self.gate {
            Gate::Waiting => return,
            Gate::LeaderLost { .. } => None,
            Gate::Running => Some(true),
            _ => Some(false),
        };
        if let Some(ready) = ready {
            self.gate = Gate::LeaderLost { ready };
            tracing::error!("no fresh telemetry from the leader: fleet stops");
            self.events.push(StationEvent::LeaderLost { at_ms: now_ms });
        }
        // Followers stop on their own when leader states stop; the leader stops when
        // commands stop. A Stop makes it explicit.
        self.broadcast(Stop { reason: 1 }, now_ms);
    }

    /// Whether the whole fleet is linked, reporting and following; the gate opens once.
    fn fleet_ready(&mut self, now_ms: u32) -> bool {
        if self.gate == Gate::Running {
            return true;
        }
        if !self.fleet.all_following(now_ms) {
            return false;
        }
        self.gate = Gate::Running;
        self.running_since_ms = Some(now_ms);
        tracing::info!("fleet ready");
        self.events.push(StationEvent::FleetReady { at_ms: now_ms });
        true
    }

    /// The line's slots handed out again in the order its followers stand on the
    /// leader's trail (`behind`), where they came out of order (`order`).
    /// `statuses`: the followers' in slot order.
    fn keep_line_order(
        &mut self,
        behind: &[DVec2],
        statuses: &[Option<FollowerStatus>],
        now_ms: u32,
    ) {
        let in_line = self.guidance.formation().blend() >= 0.5;
        let order = &self.fleet.followers;
        let Some(order) = self
            .line_order
            .step(now_ms, in_line, order, statuses, behind)
        else {
            return;
        };
        tracing::info!(
            ?order,
            "the line's followers out of order: slots handed out anew"
        );
        self.events
            .push(StationEvent::LineReordered { at_ms: now_ms });
        self.fleet.followers = order;
        self.send_slots(now_ms, None);
        self.last_slots_ms = Some(now_ms);
    }

    /// People coming the other way down a narrow way: the route keeps out of their way.
    fn keep_aside(
        &mut self,
        leader: PlanPose,
        (movers, crowded): (&[TrackView], bool),
        now_s: f64,
    ) {
        let space = oncoming::Space {
            footprint: self.guidance.formation().spec().footprint,
            personal: self.cfg.yielding.personal_space_m,
        };
        let discs = self
            .passing
            .step(leader, (movers, crowded), &self.cfg.map, space);
        if discs.is_empty() {
            return;
        }
        tracing::info!(
            discs = discs.len(),
            "someone comes the other way: the route keeps aside"
        );
        let from = leader.position;
        self.guidance.keep_aside(&discs, from, now_s, &self.world);
    }

    /// No route: the lanes of people who stopped are given up (the robots then pass in
    /// front of them, as without lanes).
    fn drop_lanes(&mut self) {
        let tracks = self.lanes.drop_all();
        if tracks.is_empty() {
            return;
        }
        tracing::info!(
            tracks = tracks.len(),
            "no way behind people who stopped: their lanes are given up"
        );
        let change = self.perception.release_lanes(&tracks);
        self.apply_sensed(change);
    }

    /// The planner's events, as the station's.
    fn report_planner(&mut self, events: &[PlannerEvent], now_ms: u32) {
        for e in events {
            let at_ms = now_ms;
            self.events.push(match e {
                PlannerEvent::Escape => StationEvent::Escape { at_ms },
                PlannerEvent::Replanned => StationEvent::Replanned { at_ms },
                PlannerEvent::NoRoute(why) => StationEvent::NoRoute {
                    at_ms,
                    why: why.clone(),
                },
                PlannerEvent::Arrived => StationEvent::Arrived { at_ms },
            });
        }
    }

    /// The operator's command, sent at once and held (a Stop or an emergency stop is
    /// repeated every period until Resume; Resume is repeated a few periods).
    pub fn operator(&mut self, command: OperatorCommand, now_ms: u32) {
        tracing::warn!(command = command.name(), "operator");
        self.events.push(StationEvent::Operator {
            command,
            at_ms: now_ms,
        });
        self.operator.set(command);
        self.send(Address::Broadcast, now_ms, &command.message());
    }

    /// Whether the localization watch halts the fleet.
    fn localization_halted(&self) -> bool {
        self.fix_watch.as_ref().is_some_and(FixWatch::halted)
    }

    /// The operator's Stop or emergency stop in force, if any.
    pub fn operator_hold(&self) -> Option<OperatorCommand> {
        self.operator.held()
    }

    /// Tells every robot to brake and hold (the operator stops the run).
    pub fn broadcast_stop(&mut self, now_ms: u32) {
        self.broadcast(Stop { reason: 0 }, now_ms);
    }
}
