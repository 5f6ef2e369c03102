//! One robot's control step: modes, the follower law or the leader's commands, limits,
//! braking, and the two wheel PIDs. Inputs are handed in by the node (radio) and the board
//! (encoders, pose sensor); time is passed in.
//!
//! Modes (`protocol::messages::RobotMode`):
//!
//! ```text
//!            first pose fix, slots, fresh leader state
//!   Idle ───────────────────────────────────────────► Joining ◄──┐ error > 0.30 m
//!    ▲                                                  │ error < 0.10 m
//!    │ no pose / no slots / Stop                        ▼        │
//!    │                                             InFormation ──┘
//!    │                                   blend moving ▲│
//!    │                                                │▼
//!    │                                            Transforming
//!    │   leader state older than the timeout (from any driving mode)
//!    └──────────────────────────── Failsafe: brake to a stop, hold
//!                                  ── fresh state from the base station ──► Joining
//!   Leader role: Leading while commands are fresh, Failsafe when they are not.
//!   EmergencyStop: brake, latched until Resume.
//! ```
//!
//! A follower only ever follows the leader state the base station sends (the node accepts
//! it from the authenticated base station only); it never adopts anything else.

use protocol::messages::{faults, RobotMode};

use crate::config::{Limits, RobotConfig, Role};
use crate::follower::{self, LeaderSnapshot, SlotRef, Slots, Trail};
use crate::kinematics::WheelSpeeds;
use crate::odometry::{FixOutcome, Odometry, PoseFixSample};
use crate::pid::Pid;
use crate::ring::Ring;
use crate::{math, NonFinite, Pose, Twist};

/// What the board measured since the last step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Sensors {
    /// Cumulative encoder counts, left then right (they may wrap).
    pub ticks: [i32; 2],
    /// A pose fix from the localization system, if one arrived.
    pub pose_fix: Option<PoseFixSample>,
    /// Free distance to the nearest thing in front of and behind the footprint (the
    /// ultrasonic ring), m; `None` when nothing is in range.
    pub proximity: [Option<f32>; 2],
}

/// Motor duties, left then right, each in [-1, 1]. Always finite.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MotorOutput {
    pub duty: [f32; 2],
}

#[derive(Debug, Clone, Copy)]
struct LeaderInput {
    snapshot: LeaderSnapshot,
    /// When the snapshot was valid, in this robot's clock.
    valid_at_ms: u32,
    /// When it was sent, at the latest, in this robot's clock: freshness counts from here.
    sent_ms: u32,
    blend: f32,
    blend_rate: f32,
}

pub struct Controller {
    cfg: RobotConfig,
    role: Role,
    mode: RobotMode,
    odometry: Odometry,
    pids: [Pid; 2],
    slots: Option<Slots>,
    leader: Option<LeaderInput>,
    trail: Trail,
    command: Option<(Twist, u32)>,
    stop_requested: bool,
    emergency: bool,
    /// The ring's readings and what is coming at the robot.
    ring: Ring,
    last_step_ms: Option<u32>,
    commanded: Twist,
    setpoints: WheelSpeeds,
    tracking_error: Option<f32>,
    reference: Option<(f32, f32)>,
    input_faults: u16,
    faults: u16,
    /// How long each wheel has been asked to turn without turning, ms.
    stalled_ms: [u32; 2],
    /// A point to make for instead of the slot, and when the base station sent it.
    detour: Option<((f32, f32), u32)>,
}

impl Controller {
    pub fn new(cfg: RobotConfig, role: Role) -> Self {
        Self {
            cfg,
            role,
            mode: RobotMode::Idle,
            odometry: Odometry::new(),
            pids: [Pid::new(cfg.pid), Pid::new(cfg.pid)],
            slots: None,
            leader: None,
            trail: Trail::new(),
            command: None,
            stop_requested: false,
            emergency: false,
            ring: Ring::default(),
            last_step_ms: None,
            commanded: Twist::ZERO,
            setpoints: WheelSpeeds::default(),
            tracking_error: None,
            reference: None,
            input_faults: 0,
            faults: 0,
            stalled_ms: [0; 2],
            detour: None,
        }
    }

    pub fn config(&self) -> &RobotConfig {
        &self.cfg
    }
    pub fn role(&self) -> Role {
        self.role
    }
    pub fn mode(&self) -> RobotMode {
        self.mode
    }
    pub fn pose(&self) -> Option<Pose> {
        self.odometry.pose()
    }
    pub fn odometry(&self) -> &Odometry {
        &self.odometry
    }
    pub fn wheel_speeds(&self) -> WheelSpeeds {
        self.odometry.wheel_speeds()
    }
    /// The (v, ω) the wheels were last asked for.
    pub fn commanded(&self) -> Twist {
        self.commanded
    }
    pub fn wheel_setpoints(&self) -> WheelSpeeds {
        self.setpoints
    }
    /// This robot's own estimate of its distance to its slot point (followers).
    pub fn tracking_error(&self) -> Option<f32> {
        self.tracking_error
    }
    /// The slot reference point it steers its control point to (followers).
    pub fn reference_point(&self) -> Option<(f32, f32)> {
        self.reference
    }
    pub fn faults(&self) -> u16 {
        self.faults
    }
    pub fn slots(&self) -> Option<Slots> {
        self.slots
    }

    pub fn set_slots(&mut self, slots: Slots) -> Result<(), NonFinite> {
        let ok = [slots.wide.0, slots.wide.1, slots.line.0, slots.line.1]
            .iter()
            .all(|v| v.is_finite());
        if !ok {
            self.input_faults |= faults::NON_FINITE_INPUT;
            return Err(NonFinite);
        }
        self.slots = Some(slots);
        Ok(())
    }

    /// A fresh leader state, `valid_at_ms` and `sent_ms` (when the base station sent it,
    /// at the latest) in this robot's clock. Clears a `Stop`.
    pub fn set_leader_state(
        &mut self,
        snapshot: LeaderSnapshot,
        valid_at_ms: u32,
        blend: f32,
        sent_ms: u32,
    ) -> Result<(), NonFinite> {
        if !snapshot.is_finite() || !blend.is_finite() {
            self.input_faults |= faults::NON_FINITE_INPUT;
            return Err(NonFinite);
        }
        let blend = math::clamp(blend, 0.0, 1.0);
        let blend_rate = match self.leader {
            Some(prev) if valid_at_ms.wrapping_sub(prev.valid_at_ms) as i32 > 0 => {
                let dt = valid_at_ms.wrapping_sub(prev.valid_at_ms) as f32 / 1000.0;
                (blend - prev.blend) / dt
            }
            _ => 0.0,
        };
        self.trail.record(snapshot.pose.x, snapshot.pose.y);
        self.leader = Some(LeaderInput {
            snapshot,
            valid_at_ms,
            sent_ms,
            blend,
            blend_rate,
        });
        self.stop_requested = false;
        Ok(())
    }

    /// A point (site frame) to make for instead of the slot, sent (at the latest) at
    /// `sent_ms` in this robot's clock: the base station's way round what holds this
    /// follower. It lapses `DETOUR_HOLD_MS` after the last one.
    pub fn set_detour(&mut self, point: (f32, f32), sent_ms: u32) -> Result<(), NonFinite> {
        if !(point.0.is_finite() && point.1.is_finite()) {
            self.input_faults |= faults::NON_FINITE_INPUT;
            return Err(NonFinite);
        }
        self.detour = Some((point, sent_ms));
        Ok(())
    }

    /// Whether a detour holds now.
    pub fn detour(&self, now_ms: u32) -> Option<(f32, f32)> {
        self.detour
            .filter(|(_, at)| self.is_fresh(*at, now_ms, DETOUR_HOLD_MS))
            .map(|(p, _)| p)
    }

    /// A velocity command for the leader, sent (at the latest) at `sent_ms` in this
    /// robot's clock. Clears a `Stop`.
    pub fn set_command(&mut self, twist: Twist, sent_ms: u32) -> Result<(), NonFinite> {
        if !twist.is_finite() {
            self.input_faults |= faults::NON_FINITE_INPUT;
            return Err(NonFinite);
        }
        self.command = Some((twist, sent_ms));
        self.stop_requested = false;
        Ok(())
    }

    pub fn stop(&mut self) {
        self.stop_requested = true;
    }

    pub fn emergency_stop(&mut self) {
        self.emergency = true;
    }

    pub fn resume(&mut self) {
        self.emergency = false;
    }

    pub fn apply_pose_fix(&mut self, fix: &PoseFixSample, now_ms: u32) -> FixOutcome {
        let outcome = self.odometry.apply_fix(fix, now_ms, &self.cfg);
        if matches!(outcome, FixOutcome::Rejected | FixOutcome::Invalid) {
            self.input_faults |= faults::POSE_FIX_REJECTED;
        }
        outcome
    }

    /// Sent within `timeout_ms` of now (a stamp slightly ahead of our clock is fresh).
    fn is_fresh(&self, sent_ms: u32, now_ms: u32, timeout_ms: u32) -> bool {
        now_ms.wrapping_sub(sent_ms) as i32 <= timeout_ms as i32
    }

    /// One control period.
    pub fn step(&mut self, now_ms: u32, sensors: &Sensors) -> MotorOutput {
        let dt = match self.last_step_ms.replace(now_ms) {
            Some(t) => math::clamp(now_ms.wrapping_sub(t) as f32 / 1000.0, 0.0, 0.5),
            None => self.cfg.period_s(),
        };
        let measured = self.odometry.update(sensors.ticks, now_ms, &self.cfg);
        if let Some(fix) = &sensors.pose_fix {
            self.apply_pose_fix(fix, now_ms);
        }

        let mut faults = core::mem::take(&mut self.input_faults);
        if self.odometry.fix_is_stale(now_ms, &self.cfg) {
            faults |= faults::POSE_FIX_STALE;
        }
        faults |= self.watch_wheels(&measured, dt);
        let (mode, target) = self.decide(now_ms, dt, &mut faults);
        self.ring
            .observe(&sensors.proximity, self.cfg.drive.twist(measured), dt);
        let target = self.keep_distance(target, &sensors.proximity);
        if self.emergency {
            faults |= faults::EMERGENCY_STOP;
        }
        self.faults = faults;

        let was_driving = is_driving(self.mode);
        if was_driving != is_driving(mode) {
            self.pids.iter_mut().for_each(Pid::reset);
        }
        self.mode = mode;

        let wheels = self.cfg.drive.limit(self.cfg.drive.wheels(target));
        let previous = self.commanded;
        self.commanded = self.cfg.drive.twist(wheels);
        if self.commanded == Twist::ZERO && previous != Twist::ZERO {
            // Stopping: the integral held the cruise's model error, not a stop's.
            self.pids.iter_mut().for_each(Pid::reset);
        }
        self.setpoints = wheels;

        let at_rest = self.commanded == Twist::ZERO
            && math::abs(measured.left) < 0.01
            && math::abs(measured.right) < 0.01;
        if at_rest {
            self.pids.iter_mut().for_each(Pid::reset);
            return MotorOutput::default();
        }
        let duty = [
            self.pids[0].update(wheels.left, measured.left, dt),
            self.pids[1].update(wheels.right, measured.right, dt),
        ];
        if duty.iter().all(|d| d.is_finite()) {
            MotorOutput { duty }
        } else {
            self.pids.iter_mut().for_each(Pid::reset);
            MotorOutput::default()
        }
    }

    /// The mode and the (v, ω) to drive this period.
    fn decide(&mut self, now_ms: u32, dt: f32, faults: &mut u16) -> (RobotMode, Twist) {
        let brake = self.brake(dt);
        if self.emergency {
            return (RobotMode::EmergencyStop, brake);
        }
        let Some(pose) = self.odometry.pose() else {
            return (RobotMode::Idle, Twist::ZERO);
        };
        if self.stop_requested {
            return (RobotMode::Idle, brake);
        }
        match self.role {
            Role::Leader => match self.command {
                Some((cmd, at)) if self.is_fresh(at, now_ms, self.cfg.timeouts.command_ms) => {
                    (RobotMode::Leading, self.limit(cmd, dt))
                }
                _ => {
                    *faults |= faults::COMMAND_STALE;
                    (RobotMode::Failsafe, brake)
                }
            },
            Role::Follower => {
                let Some(slots) = self.slots else {
                    self.tracking_error = None;
                    return (RobotMode::Idle, brake);
                };
                let leader = match self.leader {
                    Some(l)
                        if self.is_fresh(l.sent_ms, now_ms, self.cfg.timeouts.leader_state_ms) =>
                    {
                        l
                    }
                    _ => {
                        *faults |= faults::LEADER_STATE_STALE;
                        return (RobotMode::Failsafe, brake);
                    }
                };
                match self.follow(&leader, &slots, &pose, now_ms, dt) {
                    Ok(out) => out,
                    Err(NonFinite) => {
                        *faults |= faults::NON_FINITE_INPUT;
                        (RobotMode::Failsafe, brake)
                    }
                }
            }
        }
    }

    fn follow(
        &mut self,
        leader: &LeaderInput,
        slots: &Slots,
        pose: &Pose,
        now_ms: u32,
        dt: f32,
    ) -> Result<(RobotMode, Twist), NonFinite> {
        let max_age = self.cfg.timeouts.max_prediction_ms as f32 / 1000.0;
        let age = math::clamp(
            now_ms.wrapping_sub(leader.valid_at_ms) as i32 as f32 / 1000.0,
            0.0,
            max_age,
        );
        let now_leader = leader.snapshot.predict(age);
        let blend = math::clamp(leader.blend + leader.blend_rate * age, 0.0, 1.0);
        let reference = slots.reference(&now_leader.pose, blend, &self.trail);
        let (l, phi) = follower::as_slot(&now_leader.pose, reference);
        // The slot's own motion (a shape change, the line bending along the trail), fed
        // forward: the same reference a moment later, from the predicted leader.
        const H: f32 = 0.05;
        let later = leader.snapshot.predict(age + H);
        let later_blend = math::clamp(blend + leader.blend_rate * H, 0.0, 1.0);
        let (l2, phi2) = follower::as_slot(
            &later.pose,
            slots.reference(&later.pose, later_blend, &self.trail),
        );
        let slot = SlotRef {
            l,
            phi,
            l_rate: (l2 - l) / H,
            phi_rate: math::wrap_angle(phi2 - phi) / H,
        };
        // A detour's point stands still in the world; the error stays the slot's.
        let raw = match self.detour(now_ms) {
            Some(point) => {
                follower::toward(point, pose, self.cfg.gains.d, DETOUR_GAIN, DETOUR_SPEED)
            }
            None => follower::lphi_law(&now_leader, pose, &slot, &self.cfg.gains)?,
        };
        let control_point = pose.ahead(self.cfg.gains.d);
        let error = math::hypot(control_point.0 - reference.0, control_point.1 - reference.1);
        self.reference = Some(reference);
        self.tracking_error = Some(error);

        let transforming = blend > 0.0 && blend < 1.0 || leader.blend_rate != 0.0;
        let mode = if transforming {
            RobotMode::Transforming
        } else if error < self.cfg.in_formation_below
            || (self.mode == RobotMode::InFormation && error <= self.cfg.joining_above)
        {
            RobotMode::InFormation
        } else {
            RobotMode::Joining
        };
        Ok((mode, self.limit(raw, dt)))
    }

    /// Speed and turn-rate limits, and the acceleration limit from the last command.
    fn limit(&self, t: Twist, dt: f32) -> Twist {
        limit(&self.cfg.limits, self.commanded, t, dt)
    }

    /// A wheel asked for at least 0.1 m/s that turns at less than a fifth of it for a
    /// second is stalled (blocked, or its encoder stopped counting): the flag goes into
    /// telemetry, the base station halts the fleet.
    fn watch_wheels(&mut self, measured: &WheelSpeeds, dt: f32) -> u16 {
        let asked = [self.setpoints.left, self.setpoints.right];
        let got = [measured.left, measured.right];
        let mut flags = 0;
        for i in 0..2 {
            let stuck = math::abs(asked[i]) >= 0.1 && math::abs(got[i]) < 0.2 * math::abs(asked[i]);
            self.stalled_ms[i] = if stuck {
                self.stalled_ms[i].saturating_add((dt * 1000.0) as u32)
            } else {
                0
            };
            if self.stalled_ms[i] >= STALL_MS {
                flags |= [faults::WHEEL_STALL_LEFT, faults::WHEEL_STALL_RIGHT][i];
            }
        }
        flags
    }

    /// The local safety layer: whatever the law or the base station asks, the robot does
    /// not drive into what its proximity sensors see. Speed toward an obstacle is capped
    /// at the speed it can stop from at `proximity_decel` (half its braking) before
    /// `proximity_stop`, sooner where what it sees is coming at it ([`crate::ring`]). A
    /// linear cap (1/s per metre) crawled at 0.15 m/s with 0.3 m free: a follower passing
    /// a bin beside its way fell behind its slot (docs/sim.md).
    fn keep_distance(&self, t: Twist, proximity: &[Option<f32>; 2]) -> Twist {
        let (stop, decel) = (self.cfg.proximity_stop, self.cfg.proximity_decel);
        let cap = |side: usize| self.ring.cap(side, proximity[side], stop, decel);
        let v = math::clamp(t.v, -cap(1), cap(0));
        if v == t.v || t.v == 0.0 {
            return t;
        }
        // ω is kept: turning away from the obstacle stays possible.
        Twist { v, omega: t.omega }
    }

    /// The next step of a stop: slow down at the braking rate along the same arc.
    fn brake(&self, dt: f32) -> Twist {
        let c = self.commanded;
        let step = self.cfg.limits.brake_decel * dt;
        if math::abs(c.v) <= step {
            return Twist::ZERO;
        }
        let v = c.v - step * if c.v > 0.0 { 1.0 } else { -1.0 };
        Twist {
            v,
            omega: c.omega * v / c.v,
        }
    }
}

/// A detour lapses this long after the base station's last, ms: three periods, so a lost
/// frame or two does not end it, and a station that stops sending (or is lost) does.
const DETOUR_HOLD_MS: u32 = 350;
/// A detour's point is made for at this gain (1/s) and at most this speed (m/s): a way
/// point, passed at pace (the slot runs on meanwhile), slowing only in its last 0.35 m;
/// the ring still caps the speed toward what it sees.
pub const DETOUR_GAIN: f32 = 2.0;
pub const DETOUR_SPEED: f32 = 0.7;

/// `t` within the speed and turn-rate limits, and within the acceleration limit from
/// `last`, the command `dt` before (the base station rolls a detour out with it).
pub fn limit(l: &Limits, last: Twist, t: Twist, dt: f32) -> Twist {
    let v = math::clamp(t.v, -l.max_reverse, l.max_v);
    let v = math::approach(last.v, v, l.max_accel * dt);
    Twist {
        v,
        omega: math::clamp(t.omega, -l.max_omega, l.max_omega),
    }
}

/// A wheel that does not follow its set-point this long is stalled, ms.
const STALL_MS: u32 = 1000;

fn is_driving(mode: RobotMode) -> bool {
    matches!(
        mode,
        RobotMode::Joining | RobotMode::InFormation | RobotMode::Transforming | RobotMode::Leading
    )
}
