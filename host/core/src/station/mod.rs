//! The base station's core: radio link, fleet status, planner and formation manager,
//! stepped at 10 Hz with time passed in. The `run` command drives it from a serial
//! modem or UDP and the wall clock; the simulator drives it from the simulated radio and
//! the simulated clock. Same code, same bytes.

mod detour;
mod events;
mod fix_check;
mod fixes;
mod smoothing;

use std::collections::BTreeMap;

use glam::DVec2;
use protocol::link::{Event, Link, Timing};
use protocol::messages::{
    faults, Detour, EmergencyStop, FormationCommand, LeaderState, Message, PoseFix, Resume,
    RobotMode, Slot, Stop, Telemetry, VelocityCommand, WirePose,
};
use protocol::{units, Address, FrameDecoder, MasterKey, Reject, RejectCounts, MAX_WIRE};

use detour::Detours;
pub use events::StationEvent;
use events::REPORTED_FAULTS;
use fix_check::Belief;
use fixes::{Candidate, FixWatch, Offer};
pub use fixes::{FixChange, FixLimits};
pub use smoothing::TurnRateSmoother;

use crate::formation::{FollowerStatus, FormationManager, FormationSpec};
use crate::map::Map;
use crate::perception::{Change, Perception, PerceptionLimits};
use crate::planner::route::RouteParams;
use crate::planner::{Guidance, PlanPose, Planner, PlannerParams};

/// Most robots one base station serves.
pub const MAX_ROBOTS: usize = 1024;

/// Everything the station needs from the scenario or site file.
#[derive(Debug, Clone)]
pub struct StationConfig {
    pub leader: u16,
    /// In slot order: follower k takes slot k.
    pub followers: Vec<u16>,
    pub planner: PlannerParams,
    pub formation: FormationSpec,
    pub route: Vec<DVec2>,
    pub map: Map,
    pub track_width: f64,
    pub initial_speed: f64,
    /// Followers whose reported tracking error exceeds this slow the leader down, m.
    pub wait_for_followers_above: f64,
    /// Telemetry older than this is stale, ms.
    pub telemetry_timeout_ms: u32,
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
}

/// What the station knows of one robot.
#[derive(Debug, Clone, Default)]
pub struct RobotStatus {
    pub telemetry: Option<Telemetry>,
    /// Station clock when the telemetry arrived.
    pub received_ms: u32,
    /// Station clock at which the telemetry's pose was valid.
    pub pose_at_ms: u32,
    /// Whether it has been within `JOINED_BELOW_MM` of its reference since it linked.
    pub joined: bool,
    /// Since when a joined follower has been farther than `BEHIND_ABOVE_MM` from its
    /// reference (station clock, ms), and whether the operator was told.
    pub behind_since_ms: Option<u32>,
    pub behind: bool,
}

/// A follower this close to its reference has joined the formation, mm (as the report
/// counts joining).
const JOINED_BELOW_MM: u16 = 100;
/// A joined follower this far from its reference for `BEHIND_FOR_MS` is left behind (held
/// behind an obstacle its ring will not let it pass, say): the operator is told, mm.
const BEHIND_ABOVE_MM: u16 = 1000;
const BEHIND_FOR_MS: u32 = 5000;
/// It has caught up again under this, mm (where it counts as joining again, as well).
const CAUGHT_UP_BELOW_MM: u16 = 300;

/// A follower in this mode is following its slot (not idle, stopped or failsafe).
fn is_following(mode: RobotMode) -> bool {
    matches!(
        mode,
        RobotMode::Joining | RobotMode::InFormation | RobotMode::Transforming
    )
}

/// Where a robot's telemetry says it is, m.
fn position(t: &Telemetry) -> DVec2 {
    let (x, y, _) = t.pose.to_si();
    DVec2::new(x as f64, y as f64)
}

impl RobotStatus {
    /// Whether a joined follower has now been left behind, or has caught up again.
    fn watch_behind(&mut self, robot: u16, t: &Telemetry, now_ms: u32) -> Option<StationEvent> {
        if !(self.joined && is_following(t.mode)) {
            return None;
        }
        if t.tracking_error_mm < CAUGHT_UP_BELOW_MM {
            self.behind_since_ms = None;
            if std::mem::take(&mut self.behind) {
                tracing::info!(robot, "follower caught up");
                return Some(StationEvent::FollowerCaughtUp {
                    robot,
                    at_ms: now_ms,
                });
            }
        } else if t.tracking_error_mm > BEHIND_ABOVE_MM {
            let since = *self.behind_since_ms.get_or_insert(now_ms);
            if !self.behind && now_ms.wrapping_sub(since) >= BEHIND_FOR_MS {
                self.behind = true;
                tracing::warn!(
                    robot,
                    error_mm = t.tracking_error_mm,
                    "follower left behind"
                );
                return Some(StationEvent::FollowerBehind {
                    robot,
                    at_ms: now_ms,
                });
            }
        } else if !self.behind {
            self.behind_since_ms = None;
        }
        None
    }
}

/// What the operator tells the fleet (the console's buttons).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OperatorCommand {
    /// The formation halts: every robot brakes and holds; Resume goes on.
    Stop,
    /// Every robot latches stopped (its motors held at zero) until Resume.
    EmergencyStop,
    /// Clears a Stop or an emergency stop: the mission goes on.
    Resume,
}

impl OperatorCommand {
    pub fn name(self) -> &'static str {
        match self {
            OperatorCommand::Stop => "stop",
            OperatorCommand::EmergencyStop => "emergency_stop",
            OperatorCommand::Resume => "resume",
        }
    }

    /// The frame that carries it to every robot.
    fn message(self) -> Message {
        let reason = OPERATOR_REASON;
        match self {
            OperatorCommand::Stop => Message::Stop(Stop { reason }),
            OperatorCommand::EmergencyStop => Message::EmergencyStop(EmergencyStop { reason }),
            OperatorCommand::Resume => Message::Resume(Resume { reason }),
        }
    }
}

/// The `reason` of the frames an operator's command sends.
const OPERATOR_REASON: u8 = 3;

/// A Resume is sent this many periods running: one lost frame must not leave a robot
/// latched.
const RESUME_REPEATS: u8 = 5;

/// Why a fix was not sent to its robot.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NotForwarded {
    UnknownRobot,
    /// A fix that agrees better with the robot waits for the same slot (at most
    /// `[localization] forward_hz` fixes a second go out).
    RateLimited,
    /// The robot has no link yet (it would reject the frame).
    NotLinked,
    /// A pose the wire cannot carry, or a σ that is not a localization's (0, over 65 m).
    OutOfRange,
    /// Far from where the robot knows it is, while fixes that agree with it keep coming:
    /// held back ([`fixes::HOLD_OUTLIERS_MS`]).
    Outlier,
}

/// A fix on its way to its robot: the message, and the station time it was valid at.
#[derive(Debug, Clone, Copy, PartialEq)]
struct OutgoingFix {
    fix: PoseFix,
    valid_at_ms: u32,
}

/// The leader as the station estimates it now.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeaderEstimate {
    pub pose: PlanPose,
    pub v: f64,
    pub omega: f64,
}

impl LeaderEstimate {
    /// As the formation manager takes it.
    pub fn motion(&self) -> crate::formation::LeaderMotion {
        crate::formation::LeaderMotion {
            pose: self.pose,
            v: self.v,
            omega: self.omega,
        }
    }
}

pub struct BaseStation {
    cfg: StationConfig,
    link: Box<Link<MAX_ROBOTS>>,
    decoder: FrameDecoder,
    planner: Planner,
    formation: FormationManager,
    /// What the leader's scanner found that the map does not hold.
    perception: Perception,
    /// The map and what was sensed: what the planner and the formation avoid.
    world: Map,
    robots: BTreeMap<u16, RobotStatus>,
    outbox: Vec<u8>,
    last_slots_ms: Option<u32>,
    events: Vec<StationEvent>,
    leader_seen: bool,
    leader_lost: bool,
    ready: bool,
    /// A robot fault stopped the mission: Stop to all, no more commands.
    halted: bool,
    /// Forwarding fixes from a localization source, and watching their age.
    fix_watch: Option<FixWatch<OutgoingFix>>,
    /// The operator's Stop or emergency stop, held (and repeated every period) until Resume.
    operator_hold: Option<OperatorCommand>,
    /// Resumes still to send.
    resumes_left: u8,
    escapes_seen: u32,
    replans_seen: u32,
    no_route_seen: bool,
    last_command: (f64, f64),
    /// The leader's estimated path, oldest first, points `PATH_STEP` apart.
    driven: std::collections::VecDeque<DVec2>,
    /// The turn rate the followers are told, calmed where it only jitters.
    broadcast_omega: TurnRateSmoother,
    /// Followers being sent round what holds them.
    detours: Detours,
}

/// Spacing of the paths the formation manager looks along, m.
const PATH_STEP: f64 = 0.25;
/// How much of the leader's path the station keeps, m.
const DRIVEN_KEPT: f64 = 40.0;

impl StationConfig {
    pub fn from_scenario(s: &crate::scenario::Scenario) -> Self {
        Self {
            leader: s.leader().id,
            followers: s.followers().iter().map(|r| r.id).collect(),
            planner: s.planner_params(),
            formation: s.formation_spec(),
            route: s.route.points(),
            map: s.build_map(),
            track_width: s.robot.track_width,
            initial_speed: s.leader().initial_speed,
            wait_for_followers_above: s.planner.wait_for_followers_above,
            telemetry_timeout_ms: s.follower.leader_timeout_ms,
            follower_speed: 0.8 * s.robot.max_speed,
            follower_accel: 0.5 * s.robot.max_accel,
            period_ms: 100,
            fixes: FixLimits::from_spec(&s.localization),
            perception: PerceptionLimits::from_scenario(s),
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
            Timing::default(),
        ));
        let mut robots = BTreeMap::new();
        for id in std::iter::once(cfg.leader).chain(cfg.followers.iter().copied()) {
            link.add_peer(Address::Robot(id), master.robot(id));
            robots.insert(id, RobotStatus::default());
        }
        let planner = match cfg.planner.guidance {
            Guidance::Field => Planner::new(cfg.planner, cfg.route.clone(), cfg.initial_speed),
            Guidance::Route => Planner::routed(
                cfg.planner,
                cfg.route.clone(),
                cfg.initial_speed,
                RouteParams::for_formation(&cfg.formation),
            ),
        };
        let formation = FormationManager::new(cfg.formation.clone());
        let world = cfg.map.clone();
        let perception = cfg.perception;
        Self {
            cfg,
            perception: Perception::new(perception),
            world,
            link,
            decoder: FrameDecoder::new(),
            planner,
            formation,
            robots,
            outbox: Vec::new(),
            last_slots_ms: None,
            events: Vec::new(),
            leader_seen: false,
            leader_lost: false,
            ready: false,
            halted: false,
            fix_watch: None,
            operator_hold: None,
            resumes_left: 0,
            escapes_seen: 0,
            replans_seen: 0,
            no_route_seen: false,
            driven: std::collections::VecDeque::new(),
            broadcast_omega: TurnRateSmoother::default(),
            last_command: (0.0, 0.0),
            detours: Detours::default(),
        }
    }

    /// From now on the robots' fixes come from a localization source through
    /// [`BaseStation::forward_fix`], and their age is watched (`[localization]` limits).
    pub fn watch_fixes(&mut self, now_ms: u32) {
        self.fix_watch = Some(FixWatch::new(
            self.cfg.fixes,
            self.robots.keys().copied(),
            now_ms,
        ));
    }

    /// A fix of `robot` from the localization source, valid at `valid_at_ms` (station
    /// clock): it goes to the robot as an authenticated `PoseFix` at the robot's next
    /// forwarding slot ([`BaseStation::step`]) unless a fix that agrees better with the
    /// robot comes for the same slot. `Err` when it will not go, and why.
    pub fn forward_fix(
        &mut self,
        robot: u16,
        pose: PlanPose,
        sigma: f64,
        valid_at_ms: u32,
        now_ms: u32,
    ) -> Result<(), NotForwarded> {
        let robots = self.robots.keys().copied();
        let watch = self
            .fix_watch
            .get_or_insert_with(|| FixWatch::new(self.cfg.fixes, robots, now_ms));
        let Some(status) = self.robots.get(&robot) else {
            return Err(NotForwarded::UnknownRobot);
        };
        if !self
            .link
            .peer(Address::Robot(robot))
            .is_some_and(|p| p.is_linked())
        {
            return Err(NotForwarded::NotLinked);
        }
        let sigma_mm = units::to_mm_u16(sigma as f32).map_err(|_| NotForwarded::OutOfRange)?;
        let pose_on_wire = WirePose::from_si(
            pose.position.x as f32,
            pose.position.y as f32,
            pose.heading as f32,
        )
        .map_err(|_| NotForwarded::OutOfRange)?;
        if sigma <= 0.0 || sigma_mm == 0 {
            return Err(NotForwarded::OutOfRange);
        }
        let (disagreement, outlier) = status.telemetry.map_or((0.0, false), |telemetry| {
            Belief {
                telemetry,
                at_ms: status.pose_at_ms,
                track_width: self.cfg.track_width,
            }
            .judge(pose.position, pose.heading, sigma, valid_at_ms)
        });
        let fix = OutgoingFix {
            fix: PoseFix {
                pose: pose_on_wire,
                sigma_mm,
            },
            valid_at_ms,
        };
        let candidate = Candidate {
            fix,
            disagreement,
            outlier,
        };
        match watch.offer(robot, candidate, now_ms) {
            Offer::Waiting => Ok(()),
            Offer::Outdone => Err(NotForwarded::RateLimited),
            Offer::HeldOutlier => Err(NotForwarded::Outlier),
            Offer::Unknown => Err(NotForwarded::UnknownRobot),
        }
    }

    /// The fixes whose robots' slots have come, sent.
    fn send_due_fixes(&mut self, now_ms: u32) {
        let Some(watch) = &mut self.fix_watch else {
            return;
        };
        for (robot, out) in watch.due(now_ms) {
            // The frame's stamp is when the pose was valid: the robot matches it against
            // its odometry history of that instant.
            self.send(
                Address::Robot(robot),
                out.valid_at_ms,
                &Message::PoseFix(out.fix),
            );
        }
    }

    /// One scan of the leader's range scanner at `now_ms`: hit points in the site frame.
    /// Hits the map explains are ignored, and hits the leader cannot have seen (off the
    /// site, out of reach, or while the station does not know where it is); the rest
    /// become obstacles the leader avoids, and the route is planned again if they lie on
    /// it ([`crate::perception`]).
    pub fn sense(&mut self, hits: &[DVec2], now_ms: u32) {
        let leader = self.leader_estimate(now_ms).map(|l| l.pose.position);
        let change = self
            .perception
            .absorb(hits, leader, &self.cfg.map, 0, now_ms);
        self.apply_sensed(change);
    }

    /// What perception added or forgot, into the planner and the station's map.
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
        self.planner.remove_obstacles(&change.removed, &self.world);
        self.planner.add_obstacles(&change.added);
        for o in change.added {
            self.world.insert(o);
        }
    }

    /// The obstacles sensed so far that the map does not hold.
    pub fn perception(&self) -> &Perception {
        &self.perception
    }

    pub fn config(&self) -> &StationConfig {
        &self.cfg
    }
    pub fn link(&self) -> &Link<MAX_ROBOTS> {
        &self.link
    }
    pub fn planner(&self) -> &Planner {
        &self.planner
    }
    pub fn formation(&self) -> &FormationManager {
        &self.formation
    }
    pub fn robots(&self) -> &BTreeMap<u16, RobotStatus> {
        &self.robots
    }
    pub fn events(&self) -> &[StationEvent] {
        &self.events
    }
    /// The last (v, ω) sent to the leader.
    pub fn last_command(&self) -> (f64, f64) {
        self.last_command
    }

    /// Rejected frames by reason, over the whole link.
    pub fn rejects(&self) -> RejectCounts {
        self.link.stats().rejects
    }

    /// Bytes to transmit, oldest first.
    pub fn take_outbox(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.outbox)
    }

    fn send(&mut self, to: Address, now_ms: u32, message: &Message) {
        let mut buf = [0u8; MAX_WIRE];
        match self.link.send(to, now_ms, message, &mut buf) {
            Ok(n) => self.outbox.extend_from_slice(&buf[..n]),
            Err(e) => tracing::warn!(?to, "cannot send {}: {e}", message.name()),
        }
    }

    /// Bytes from the radio.
    pub fn receive(&mut self, bytes: &[u8], now_ms: u32) {
        for &b in bytes {
            let Some(frame) = self.decoder.push(b) else {
                continue;
            };
            match self.link.receive(frame, now_ms) {
                Ok(Event::Message { header, message }) => {
                    if let (Address::Robot(id), Message::Telemetry(t)) = (header.from, message) {
                        let offset = self
                            .link
                            .peer(header.from)
                            .and_then(|p| p.clock_offset_ms)
                            .unwrap_or(0);
                        if let Some(status) = self.robots.get_mut(&id) {
                            let before = status.telemetry.map_or(0, |p| p.faults);
                            for (bit, fault, halts) in REPORTED_FAULTS {
                                if t.faults & bit != 0 && before & bit == 0 {
                                    tracing::warn!(robot = id, fault, "robot fault");
                                    self.events.push(StationEvent::RobotFault {
                                        robot: id,
                                        fault,
                                        at_ms: now_ms,
                                        halts,
                                    });
                                    self.halted |= halts;
                                }
                            }
                            status.telemetry = Some(t);
                            status.joined |=
                                matches!(t.mode, RobotMode::InFormation | RobotMode::Transforming)
                                    && t.tracking_error_mm < JOINED_BELOW_MM;
                            if let Some(event) = status.watch_behind(id, &t, now_ms) {
                                self.events.push(event);
                            }
                            status.received_ms = now_ms;
                            // Robot clock → ours; never later than now.
                            let at = header.time_ms.wrapping_sub(offset as u32);
                            status.pose_at_ms = if (now_ms.wrapping_sub(at) as i32) < 0 {
                                now_ms
                            } else {
                                at
                            };
                        }
                    }
                }
                Ok(Event::Challenged { from, nonce }) => {
                    let mut buf = [0u8; MAX_WIRE];
                    if let Ok(n) = self.link.answer(from, nonce, now_ms, &mut buf) {
                        self.outbox.extend_from_slice(&buf[..n]);
                        // The robot verifies our frames from this answer on: its slots go
                        // out at the next step (sent before, they were refused).
                        self.last_slots_ms = None;
                    }
                }
                Ok(Event::Linked { peer }) => {
                    if let Address::Robot(robot) = peer {
                        tracing::info!(robot, "linked");
                        self.events.push(StationEvent::Linked {
                            robot,
                            at_ms: now_ms,
                        });
                        self.last_slots_ms = None;
                    }
                }
                Ok(Event::Synced { .. } | Event::Ignored) => {}
                Err(reason) => tracing::debug!(%reason, "frame rejected"),
            }
        }
    }

    /// A robot's status if its telemetry is recent and its pose means something (a robot
    /// that has had no fix since boot does not know where it is).
    fn fresh(&self, id: u16, now_ms: u32) -> Option<&RobotStatus> {
        self.robots.get(&id).filter(|s| {
            s.telemetry
                .is_some_and(|t| t.faults & faults::NOT_LOCALIZED == 0)
                && now_ms.wrapping_sub(s.received_ms) <= self.cfg.telemetry_timeout_ms
        })
    }

    /// The leader's pose predicted to `now_ms` from its latest telemetry.
    pub fn leader_estimate(&self, now_ms: u32) -> Option<LeaderEstimate> {
        let s = self.fresh(self.cfg.leader, now_ms)?;
        let t = s.telemetry?;
        let (x, y, heading) = t.pose.to_si();
        let vl = units::from_milli_i16(t.wheel_mm_s[0]) as f64;
        let vr = units::from_milli_i16(t.wheel_mm_s[1]) as f64;
        let v = 0.5 * (vl + vr);
        let omega = (vr - vl) / self.cfg.track_width;
        let age = (now_ms.wrapping_sub(s.pose_at_ms) as f64 / 1000.0).clamp(0.0, 0.5);
        let h0 = heading as f64;
        let h1 = h0 + omega * age;
        let mid = 0.5 * (h0 + h1);
        let pos = DVec2::new(x as f64, y as f64) + DVec2::new(mid.cos(), mid.sin()) * v * age;
        Some(LeaderEstimate {
            pose: PlanPose {
                position: pos,
                heading: h1,
            },
            v,
            omega,
        })
    }

    fn record_leader_path(&mut self, p: DVec2) {
        if self
            .driven
            .back()
            .is_some_and(|q| (p - *q).length() < PATH_STEP)
        {
            return;
        }
        self.driven.push_back(p);
        if self.driven.len() as f64 * PATH_STEP > DRIVEN_KEPT {
            self.driven.pop_front();
        }
    }

    /// Each follower's (slot order) fresh position, tracking error and whether it has joined.
    fn follower_statuses(&self, now_ms: u32) -> Vec<Option<FollowerStatus>> {
        self.cfg
            .followers
            .iter()
            .map(|id| {
                let status = self.fresh(*id, now_ms)?;
                let t = status.telemetry?;
                Some(FollowerStatus {
                    position: position(&t),
                    error: t.tracking_error_mm as f64 / 1000.0,
                    joined: status.joined,
                    detouring: self.detours.is_active(*id),
                })
            })
            .collect()
    }

    /// One 10 Hz step: handshakes, planning, commands and leader state out.
    pub fn step(&mut self, now_ms: u32) {
        let mut buf = [0u8; MAX_WIRE];
        while let Some(peer) = self.link.due_challenge(now_ms) {
            match self.link.challenge(peer, now_ms, &mut buf) {
                Ok(n) => self.outbox.extend_from_slice(&buf[..n]),
                Err(_) => break,
            }
        }
        let due_slots = self
            .last_slots_ms
            .is_none_or(|t| now_ms.wrapping_sub(t) >= 1000);
        if due_slots {
            self.send_slots(now_ms);
            self.last_slots_ms = Some(now_ms);
        }

        self.send_due_fixes(now_ms);
        let forgotten = self.perception.age(now_ms);
        self.apply_sensed(forgotten);
        self.check_fixes(now_ms);
        if let Some(hold) = self.operator_hold {
            // Every period, not once: a robot that missed it (a lost frame) gets the next.
            self.send(Address::Broadcast, now_ms, &hold.message());
            return;
        }
        if self.resumes_left > 0 {
            self.resumes_left -= 1;
            self.send(
                Address::Broadcast,
                now_ms,
                &OperatorCommand::Resume.message(),
            );
        }
        if self.halted || self.fix_watch.as_ref().is_some_and(FixWatch::halted) {
            // A robot cannot drive as told, or cannot know where it is: everyone brakes
            // and holds.
            self.send(
                Address::Broadcast,
                now_ms,
                &Message::Stop(Stop { reason: 2 }),
            );
            return;
        }
        let Some(leader) = self.leader_estimate(now_ms) else {
            if !self.leader_seen {
                return;
            }
            if !self.leader_lost {
                self.leader_lost = true;
                tracing::warn!("no fresh telemetry from the leader: fleet stops");
                self.events.push(StationEvent::LeaderLost { at_ms: now_ms });
            }
            // Followers stop on their own when leader states stop; the leader stops when
            // commands stop. A Stop makes it explicit.
            self.send(
                Address::Broadcast,
                now_ms,
                &Message::Stop(Stop { reason: 1 }),
            );
            return;
        };
        self.leader_seen = true;
        if self.leader_lost {
            self.leader_lost = false;
            self.events.push(StationEvent::LeaderBack { at_ms: now_ms });
        }

        let now_s = now_ms as f64 / 1000.0;
        self.record_leader_path(leader.pose.position);
        self.planner
            .prepare(now_s, leader.pose.position, &self.world);
        let spec = self.formation.spec();
        let horizon =
            spec.lookahead + self.formation.wide_reach().max(self.formation.line_reach()) + 3.0;
        let ahead = self.planner.path_ahead(leader.pose, horizon, PATH_STEP);
        let behind: Vec<DVec2> = std::iter::once(leader.pose.position)
            .chain(self.driven.iter().rev().copied())
            .collect();
        let statuses = self.follower_statuses(now_ms);
        let before = self.formation.transformations().len();
        let blend = self.formation.step(
            now_s,
            leader.motion(),
            &ahead,
            &behind,
            &statuses,
            &self.world,
        );
        if self.formation.transformations().len() > before {
            let to = self.formation.target();
            tracing::info!(?to, "formation change");
            self.events
                .push(StationEvent::Transformation { to, at_ms: now_ms });
        }

        self.send_detours(leader.pose, &behind, now_ms);

        let half_width = self.formation.half_width();
        // Only the wide slots swing round the leader; the line follows its trail. Until
        // the formation is all line, the wide slots' full reach counts: half way through a
        // change a V's rear slot swings with half its reach, but moves across on its own
        // too, and a turn the half reach allowed swung it at 1.5 m/s, out of its
        // follower's reach (1.5 m off).
        let swinging = if blend >= 1.0 { 0.0 } else { 1.0 };
        // The leader waits for a follower falling behind: it slows, and it swings the
        // slots slower too (turning on the spot at 0.1 rad/s, it swung a 5-V's rear slot
        // on at 0.65 m/s from a follower going round a bin).
        let worst = statuses
            .iter()
            .flatten()
            .map(|f| f.error)
            .fold(0.0, f64::max);
        let over = worst - self.cfg.wait_for_followers_above;
        let waiting = if over > 0.0 {
            (1.0 - over / 0.5).max(0.2)
        } else {
            1.0
        };
        self.planner.set_formation(
            self.formation.wide_reach() * swinging,
            self.cfg.follower_speed * waiting,
            self.cfg.follower_accel,
        );
        if !self.ready {
            // Leave only with the whole fleet: every follower linked, reporting and
            // following (not idle, not failsafe). Until then the leader holds.
            let following = self.cfg.followers.iter().all(|id| {
                self.fresh(*id, now_ms)
                    .and_then(|s| s.telemetry)
                    .is_some_and(|t| is_following(t.mode))
            });
            if !following {
                self.last_command = (0.0, 0.0);
                let hold = Message::VelocityCommand(VelocityCommand {
                    v_mm_s: 0,
                    omega_mrad_s: 0,
                });
                self.send(Address::Robot(self.cfg.leader), now_ms, &hold);
                self.broadcast_leader_state(&leader, (0.0, 0.0), 0.0, now_ms);
                return;
            }
            self.ready = true;
            tracing::info!("fleet ready");
            self.events.push(StationEvent::FleetReady { at_ms: now_ms });
        }
        let speed_scale = waiting.min(self.formation.speed_factor(now_s));
        let was_arrived = self.planner.arrived();
        let cmd = self.planner.step(
            now_s,
            self.cfg.period_ms as f64 / 1000.0,
            leader.pose,
            &self.world,
            half_width,
            speed_scale,
        );
        if self.planner.escapes() > self.escapes_seen {
            self.escapes_seen = self.planner.escapes();
            tracing::info!("planner: local minimum, following the boundary");
            self.events.push(StationEvent::Escape { at_ms: now_ms });
        }
        if self.planner.replans() > self.replans_seen {
            self.replans_seen = self.planner.replans();
            self.events.push(StationEvent::Replanned { at_ms: now_ms });
        }
        match (self.planner.no_route(), self.no_route_seen) {
            (Some(why), false) => {
                tracing::warn!("no route: {why}");
                self.events.push(StationEvent::NoRoute {
                    at_ms: now_ms,
                    why: why.to_string(),
                });
                self.no_route_seen = true;
            }
            (None, true) => self.no_route_seen = false,
            _ => {}
        }
        if self.planner.arrived() && !was_arrived {
            tracing::info!("goal reached");
            self.events.push(StationEvent::Arrived { at_ms: now_ms });
        }
        self.last_command = (cmd.v, cmd.omega);
        let command = Message::VelocityCommand(VelocityCommand {
            v_mm_s: units::to_milli_i16(cmd.v as f32).unwrap_or(0),
            omega_mrad_s: units::to_milli_i16(cmd.omega as f32).unwrap_or(0),
        });
        self.send(Address::Robot(self.cfg.leader), now_ms, &command);

        self.broadcast_leader_state(&leader, (cmd.v, cmd.omega), blend, now_ms);
    }

    /// The pose is the leader's (measured, predicted to now); the velocity is the one it
    /// was just told to drive. The followers then start to speed up or turn when the
    /// leader does, not a motor lag later: their own lag matches the leader's. The turn
    /// rate is smoothed where it only jitters ([`TurnRateSmoother`]).
    fn broadcast_leader_state(
        &mut self,
        leader: &LeaderEstimate,
        twist: (f64, f64),
        blend: f64,
        now_ms: u32,
    ) {
        let p = leader.pose;
        let twist = (twist.0, self.broadcast_omega.step(twist.1));
        if let Ok(pose) =
            WirePose::from_si(p.position.x as f32, p.position.y as f32, p.heading as f32)
        {
            let state = Message::LeaderState(LeaderState {
                pose,
                v_mm_s: units::to_milli_i16(twist.0 as f32).unwrap_or(0),
                omega_mrad_s: units::to_milli_i16(twist.1 as f32).unwrap_or(0),
                blend: (blend.clamp(0.0, 1.0) * 255.0).round() as u8,
            });
            self.send(Address::Broadcast, now_ms, &state);
        }
    }

    /// Detours for the followers held on their way ([`detour`]), sent every period.
    fn send_detours(&mut self, leader: PlanPose, behind: &[DVec2], now_ms: u32) {
        let mut followers = Vec::new();
        for (k, id) in self.cfg.followers.iter().enumerate() {
            let Some(t) = self.fresh(*id, now_ms).and_then(|s| s.telemetry) else {
                continue;
            };
            if !is_following(t.mode) {
                continue;
            }
            followers.push(detour::Follower {
                id: *id,
                position: position(&t),
                reference: self.formation.reference(k, leader, behind),
                error: t.tracking_error_mm as f64 / 1000.0,
            });
        }
        let robots: Vec<(u16, DVec2)> = self
            .robots
            .keys()
            .filter_map(|id| {
                let t = self.fresh(*id, now_ms)?.telemetry?;
                Some((*id, position(&t)))
            })
            .collect();
        let footprint = self.formation.spec().footprint;
        let detours = self
            .detours
            .step(now_ms, &self.world, footprint, &followers, &robots);
        for (robot, point, new) in detours {
            if new {
                tracing::info!(
                    robot,
                    x = point.x,
                    y = point.y,
                    "follower sent round an obstacle"
                );
                self.events.push(StationEvent::FollowerDetour {
                    robot,
                    at_ms: now_ms,
                });
            }
            let (Ok(x_mm), Ok(y_mm)) = (
                units::metres_to_mm(point.x as f32),
                units::metres_to_mm(point.y as f32),
            ) else {
                continue;
            };
            self.send(
                Address::Robot(robot),
                now_ms,
                &Message::Detour(Detour { x_mm, y_mm }),
            );
        }
    }

    fn send_slots(&mut self, now_ms: u32) {
        let n = self.cfg.followers.len();
        for (k, id) in self.cfg.followers.clone().into_iter().enumerate() {
            let slot =
                |(l, phi): (f64, f64)| Slot::from_si(l as f32, phi as f32).unwrap_or_default();
            let cmd = Message::FormationCommand(FormationCommand {
                followers: n.min(u16::MAX as usize) as u16,
                index: k.min(u16::MAX as usize) as u16,
                wide: slot(self.formation.wide_slots()[k]),
                line: slot(self.formation.line_slots()[k]),
            });
            self.send(Address::Robot(id), now_ms, &cmd);
        }
    }

    fn check_fixes(&mut self, now_ms: u32) {
        let Some(watch) = &mut self.fix_watch else {
            return;
        };
        let mut changes = Vec::new();
        watch.check(now_ms, &mut changes);
        for change in changes {
            match change {
                FixChange::Lost(robot) => {
                    tracing::warn!(robot, "no fixes from the localization source");
                }
                FixChange::Back(robot) => tracing::info!(robot, "fixes back"),
                FixChange::Halt => {
                    tracing::warn!("a robot has had no fix too long: the fleet stops")
                }
                FixChange::Resume => tracing::info!("every robot has fixes: the fleet goes on"),
            }
            self.events.push(StationEvent::Localization {
                change,
                at_ms: now_ms,
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
        match command {
            OperatorCommand::Resume => {
                self.operator_hold = None;
                self.resumes_left = RESUME_REPEATS;
            }
            hold => {
                self.operator_hold = Some(hold);
                self.resumes_left = 0;
            }
        }
        self.send(Address::Broadcast, now_ms, &command.message());
    }

    /// The operator's Stop or emergency stop in force, if any.
    pub fn operator_hold(&self) -> Option<OperatorCommand> {
        self.operator_hold
    }

    /// Tells every robot to brake and hold (the operator stops the run).
    pub fn broadcast_stop(&mut self, now_ms: u32) {
        self.send(
            Address::Broadcast,
            now_ms,
            &Message::Stop(Stop { reason: 0 }),
        );
    }

    /// Counts a frame the byte decoder could not even deframe.
    pub fn count_reject(&mut self, reason: Reject) {
        self.link.count_reject(reason);
    }
}
