//! The leader's drive: its pace among what moves (`movers`, from one ranking over the
//! fleet's forward model), passed to guidance as a value, then its command capped short
//! of the other robots and the leader's state to every follower.

use glam::DVec2;
use protocol::messages::{Message, VelocityCommand};
use protocol::{units, Address};

use super::model::{self, Goal, LeaderStart, Path, Robot};
use super::movers::pace::Context;
use super::movers::prediction::Mover;
use super::movers::{Candidate, Decision, Manner};
use super::robots::spacing;
use super::{BaseStation, LeaderEstimate, Look, ShapeChange, StationEvent};
use crate::planner::{Pace, PlannerEvent};

/// A command shows in the leader's speed about this late: the radio's 50 ms, up to a
/// period before the robot's loop takes it, the motors' lag, s.
const COMMAND_LAG_S: f64 = 0.3;
/// Braking for someone (the pace under the speed now by this), as hard as the robot
/// allows, not at the planner's comfort, m/s.
const BRAKING_BELOW_MPS: f64 = 0.05;

impl BaseStation {
    /// The leader's pace among `movers` this period (`crowded`: whether they crowd its
    /// way), and what it announces.
    pub(super) fn pace_among_movers(
        &mut self,
        leader: &LeaderEstimate,
        look: &Look,
        movers: &[Mover],
        crowded: bool,
        (bodies, following): super::Robots<'_>,
        now_ms: u32,
    ) -> Decision {
        let (ids, followers): (Vec<u16>, Vec<(Robot, Goal)>) =
            self.model_followers(bodies, following).into_iter().unzip();
        let path = Path::new(&look.ahead);
        let now_s = now_ms as f64 / 1000.0;
        let fleet = model::Fleet {
            leader: LeaderStart {
                pose: leader.pose,
                v: leader.v,
                commanded: self.last_command.0,
                lag_s: COMMAND_LAG_S,
                accel: self.resume_accel(),
                brake: self.cfg.yield_brake.max(self.cfg.planner.max_accel),
            },
            followers: &followers,
            ahead: &path,
            behind: &look.behind,
            formation: self.guidance.formation(),
            robot: &self.cfg.robot,
            now_s,
        };
        let spec = self.movers.spec();
        let ctx = Context {
            pace: self.cfg.planner.max_speed,
            hurry: self.cfg.follower_speed,
            reverse: self.cfg.reverse_speed,
            footprint: self.guidance.formation().spec().footprint,
            horizon_s: spec.horizon_s,
            passing_share: spec.passing_share,
            crowded,
        };
        let mut decision = self.movers.decide(now_s, &fleet, movers, &ctx, &self.world);
        decision.held_followers = decision.choice.holds.iter().map(|k| ids[*k]).collect();
        if let Some(manner) = decision.announce {
            self.announce(manner, movers.len(), now_ms);
        }
        if let Some((at, radius)) = decision.avoid {
            let from = leader.pose.position;
            self.guidance.avoid(at, radius, from, now_s, &self.world);
        }
        decision
    }

    /// Each follower in the model (with its id): as estimated now, making for what it was
    /// told last period (a point), else its slot; one not following stands. One held for
    /// people makes for its slot: whether it may go on is judged by what going on would
    /// do (judged held, it would be let go the next period and held again the one after).
    fn model_followers(
        &self,
        bodies: &[spacing::Body],
        following: &[spacing::Body],
    ) -> Vec<(u16, (Robot, Goal))> {
        self.fleet
            .followers
            .iter()
            .enumerate()
            .filter_map(|(k, id)| {
                let b = bodies.iter().find(|b| b.id == *id)?;
                let following = following.iter().any(|f| f.id == *id);
                let for_people = self.people_holds.contains_key(id);
                let goal = match self.orders.get(id) {
                    Some(_) if following && for_people => Goal::Slot(k),
                    Some(point) => Goal::Point(*point),
                    None if following => Goal::Slot(k),
                    None => Goal::Hold,
                };
                Some((*id, (Robot::new(b.position, b.heading, b.v), goal)))
            })
            .collect()
    }

    /// One event when the fleet's manner among movers changes, one when it ends.
    fn announce(&mut self, manner: Manner, movers: usize, now_ms: u32) {
        let at_ms = now_ms;
        let (event, words) = match manner {
            Manner::Waiting => (StationEvent::Yielding { at_ms }, "waits for people to pass"),
            Manner::SteppingBack => (
                StationEvent::SteppingBack { at_ms },
                "steps back out of someone's way",
            ),
            Manner::SteppingAside => (
                StationEvent::SteppingAside { at_ms },
                "steps aside out of someone's lane",
            ),
            Manner::ClearingWay => (
                StationEvent::ClearingWay { at_ms },
                "goes on out of someone's way",
            ),
            Manner::Route => (StationEvent::PaceResumed { at_ms }, "goes on at its pace"),
        };
        tracing::info!(movers, "the leader {words}");
        self.events.push(event);
    }

    /// The planner's pace from the movers' `decision` and the followers' `look`: going on
    /// to clear someone's way, the leader does not wait for its followers, nor slow for a
    /// shape change.
    fn pace_of(&self, leader: &LeaderEstimate, look: &Look, d: &Decision) -> (Pace, ShapeChange) {
        let share = d.target.max(0.0) / self.cfg.planner.max_speed;
        let clearing = d.choice.clears && d.target > 0.0 || d.choice.candidate == Candidate::Hurry;
        let braking = d.target < leader.v - BRAKING_BELOW_MPS;
        let pace = Pace {
            scale: if clearing {
                share
            } else {
                look.waiting.min(share)
            },
            brake: braking.then_some(self.cfg.yield_brake),
            accel: d.among_movers.then_some(self.resume_accel()),
            held: d.held,
        };
        let change = if clearing {
            ShapeChange::Ignored
        } else {
            ShapeChange::Slows
        };
        (pace, change)
    }

    /// Drives the leader this period: its pace, guidance's command (backing where the
    /// decision says so), and what happened on the way.
    pub(super) fn drive_leader(
        &mut self,
        leader: &LeaderEstimate,
        look: &Look,
        decision: &Decision,
        bodies: &[spacing::Body],
        now_ms: u32,
    ) {
        let now_s = now_ms as f64 / 1000.0;
        let (pace, change) = self.pace_of(leader, look, decision);
        let mut drive = self
            .guidance
            .drive(now_s, leader.pose, pace, change, &self.world);
        if self.touch_up(leader.pose.position, now_ms) {
            // Not there yet: the leader goes back for what the sweep missed.
            drive.events.retain(|e| !matches!(e, PlannerEvent::Arrived));
        }
        self.report_planner(&drive.events, now_ms);
        if drive
            .events
            .iter()
            .any(|e| matches!(e, PlannerEvent::NoRoute(_)))
        {
            self.drop_lanes();
        }
        let command = match decision.choice.candidate {
            Candidate::Back => (-self.cfg.reverse_speed, 0.0),
            Candidate::Aside(point) => self.toward(leader, point),
            _ => (drive.v, drive.omega),
        };
        self.command_leader(leader, command, bodies, look.blend, now_ms);
    }

    /// Once an area's passes are all driven, the strips it missed (as the station
    /// estimates its robots' brushes) are put next on the leader's route: whether any were.
    fn touch_up(&mut self, at: DVec2, now_ms: u32) -> bool {
        let Some(sweeping) = &mut self.sweeping else {
            return false;
        };
        let planner = self.guidance.planner();
        let (passed, arrived) = (planner.passed(), planner.arrived());
        let now_s = now_ms as f64 / 1000.0;
        let next = planner.current_waypoint();
        if let Some(count) = sweeping.give_up(passed, at, next, now_s) {
            tracing::warn!(
                points = count,
                "a touch-up the fleet cannot reach: given up"
            );
            self.guidance.remove_ahead(count);
            self.events
                .push(StationEvent::SweepGivenUp { at_ms: now_ms });
            return false;
        }
        let Some(t) = sweeping.decide(passed, arrived, at, &self.world, now_s) else {
            return false;
        };
        let area = sweeping.name(t.area).to_string();
        tracing::info!(
            area,
            patches = t.patches,
            missed_m2 = t.missed_m2,
            "going back for what the sweep missed"
        );
        self.guidance.insert_ahead(&t.points);
        self.events.push(StationEvent::SweepTouchUp {
            area,
            patches: t.patches,
            at_ms: now_ms,
        });
        true
    }

    /// The leader's (v, ω) for its control point to make for `point`, as a follower's
    /// detour makes for its point.
    fn toward(&self, leader: &LeaderEstimate, point: DVec2) -> (f64, f64) {
        let p = leader.pose;
        let pose =
            control_core::Pose::new(p.position.x as f32, p.position.y as f32, p.heading as f32);
        let t = control_core::follower::toward(
            (point.x as f32, point.y as f32),
            &pose,
            self.cfg.robot.gains.d,
            control_core::controller::DETOUR_GAIN,
            control_core::controller::DETOUR_SPEED,
        );
        (t.v as f64, t.omega as f64)
    }

    /// How hard the leader speeds up among movers: as hard as its followers may, not at
    /// the planner's comfort (held again and again in a crowd, a leader creeping back to
    /// its pace took half as long again as the empty plaza).
    pub(super) fn resume_accel(&self) -> f64 {
        self.cfg.follower_accel.max(self.cfg.planner.max_accel)
    }

    /// The leader holds (the fleet is not ready, or parked): told to stand, its state to
    /// every follower.
    pub(super) fn hold_leader(&mut self, leader: &LeaderEstimate, now_ms: u32) {
        self.last_command = (0.0, 0.0);
        let hold = Message::VelocityCommand(VelocityCommand {
            v_mm_s: 0,
            omega_mrad_s: 0,
        });
        self.send(Address::Robot(self.cfg.leader), now_ms, &hold);
        self.broadcast_leader_state(leader, (0.0, 0.0), 0.0, now_ms);
    }

    /// The leader's command (`v` capped short of the other robots, `bodies`: [`spacing`]),
    /// then the leader's state to every follower.
    fn command_leader(
        &mut self,
        leader: &LeaderEstimate,
        (v, omega): (f64, f64),
        bodies: &[spacing::Body],
        blend: f64,
        now_ms: u32,
    ) {
        let body = leader.body(self.cfg.leader);
        let footprint = self.guidance.formation().spec().footprint;
        let v = spacing::cap_leader(&body, v, bodies, footprint, self.cfg.yield_brake);
        self.last_command = (v, omega);
        let command = Message::VelocityCommand(VelocityCommand {
            v_mm_s: units::to_milli_i16(v as f32).unwrap_or(0),
            omega_mrad_s: units::to_milli_i16(omega as f32).unwrap_or(0),
        });
        self.send(Address::Robot(self.cfg.leader), now_ms, &command);
        self.broadcast_leader_state(leader, (v, omega), blend, now_ms);
    }
}

/// The robots' positions for the movers' prediction: the leader first.
pub(super) fn positions(leader: DVec2, bodies: &[spacing::Body], leader_id: u16) -> Vec<DVec2> {
    std::iter::once(leader)
        .chain(
            bodies
                .iter()
                .filter(|b| b.id != leader_id)
                .map(|b| b.position),
        )
        .collect()
}
