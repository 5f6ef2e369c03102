//! What the robots reported: each robot's latest telemetry, when it came and when its pose
//! was valid, whether a follower has joined or been left behind, and the faults it raised.
//! From it: which robots are fresh, where the leader is now, how the followers stand.

use std::collections::BTreeMap;

use glam::DVec2;
use protocol::messages::{faults, RobotMode, Telemetry};
use protocol::units;

use super::events::{fault_name, StationEvent, REPORTED_FAULTS};
use super::robots::spacing::Body;
use crate::formation::{FollowerStatus, LeaderMotion};
use crate::planner::PlanPose;

/// A follower this close to its reference has joined the formation, mm (as the report
/// counts joining).
const JOINED_BELOW_MM: u16 = 100;
/// A joined follower this far from its reference for `BEHIND_FOR_MS` is left behind (held
/// behind an obstacle its ring will not let it pass, say): the operator is told, mm.
const BEHIND_ABOVE_MM: u16 = 1000;
const BEHIND_FOR_MS: u32 = 5000;
/// It has caught up again under this, mm (where it counts as joining again, as well).
const CAUGHT_UP_BELOW_MM: u16 = 300;

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

/// A follower in this mode is following its slot (not idle, stopped or failsafe).
pub fn is_following(mode: RobotMode) -> bool {
    matches!(
        mode,
        RobotMode::Joining | RobotMode::InFormation | RobotMode::Transforming
    )
}

/// Where a robot's telemetry says it is, m.
pub fn position(t: &Telemetry) -> DVec2 {
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

/// The leader (or any robot) as the station estimates it now.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeaderEstimate {
    pub pose: PlanPose,
    pub v: f64,
    pub omega: f64,
}

impl LeaderEstimate {
    /// As [`super::robots::spacing`] takes it: robot `id`.
    pub fn body(&self, id: u16) -> Body {
        Body {
            id,
            position: self.pose.position,
            heading: self.pose.heading,
            v: self.v,
        }
    }

    /// As the formation manager takes it.
    pub fn motion(&self) -> LeaderMotion {
        LeaderMotion {
            pose: self.pose,
            v: self.v,
            omega: self.omega,
        }
    }
}

/// What one telemetry frame changed.
#[derive(Debug, Default)]
pub struct Heard {
    pub events: Vec<StationEvent>,
    /// A fault that stops the fleet was raised.
    pub halts: bool,
}

/// The fleet as its telemetry tells it.
#[derive(Debug, Clone)]
pub struct Fleet {
    pub leader: u16,
    /// In slot order: follower k takes slot k (handed out anew where the line came out
    /// of order).
    pub followers: Vec<u16>,
    robots: BTreeMap<u16, RobotStatus>,
    track_width: f64,
    /// Telemetry older than this is stale, ms.
    timeout_ms: u32,
    /// A follower's (it may report less often than the leader).
    follower_timeout_ms: u32,
}

impl Fleet {
    pub fn new(leader: u16, followers: Vec<u16>, track_width: f64, timeout_ms: u32) -> Self {
        let robots = std::iter::once(leader)
            .chain(followers.iter().copied())
            .map(|id| (id, RobotStatus::default()))
            .collect();
        Self {
            leader,
            followers,
            robots,
            track_width,
            timeout_ms,
            follower_timeout_ms: timeout_ms,
        }
    }

    /// Followers' telemetry stale after `ms` instead.
    pub fn with_follower_timeout(mut self, ms: u32) -> Self {
        self.follower_timeout_ms = ms;
        self
    }

    pub fn robots(&self) -> &BTreeMap<u16, RobotStatus> {
        &self.robots
    }

    pub fn ids(&self) -> impl Iterator<Item = u16> + '_ {
        self.robots.keys().copied()
    }

    pub fn get(&self, id: u16) -> Option<&RobotStatus> {
        self.robots.get(&id)
    }

    /// Telemetry `t` of robot `id` arrived at `now_ms`, its pose valid at `pose_at_ms`
    /// (station clock): the faults it newly raises, a follower left behind or caught up.
    pub fn hear(&mut self, id: u16, t: Telemetry, pose_at_ms: u32, now_ms: u32) -> Heard {
        let mut heard = Heard::default();
        let Some(status) = self.robots.get_mut(&id) else {
            return heard;
        };
        let before = status.telemetry.map_or(0, |p| p.faults);
        for (bit, halts) in REPORTED_FAULTS {
            if t.faults & bit != 0 && before & bit == 0 {
                let fault = fault_name(bit);
                // A halting fault stops the mission: an error; the rest a warning.
                if halts {
                    tracing::error!(robot = id, fault, "robot fault: the fleet stops");
                } else {
                    tracing::warn!(robot = id, fault, "robot fault");
                }
                heard.events.push(StationEvent::RobotFault {
                    robot: id,
                    fault,
                    at_ms: now_ms,
                    halts,
                });
                heard.halts |= halts;
            }
        }
        status.telemetry = Some(t);
        status.joined |= matches!(t.mode, RobotMode::InFormation | RobotMode::Transforming)
            && t.tracking_error_mm < JOINED_BELOW_MM;
        if let Some(event) = status.watch_behind(id, &t, now_ms) {
            heard.events.push(event);
        }
        status.received_ms = now_ms;
        status.pose_at_ms = pose_at_ms;
        heard
    }

    /// A robot's status if its telemetry is recent and its pose means something (a robot
    /// that has had no fix since boot does not know where it is).
    pub fn fresh(&self, id: u16, now_ms: u32) -> Option<&RobotStatus> {
        self.robots.get(&id).filter(|s| {
            s.telemetry
                .is_some_and(|t| t.faults & faults::NOT_LOCALIZED == 0)
                && now_ms.wrapping_sub(s.received_ms) <= self.timeout_of(id)
        })
    }

    fn timeout_of(&self, id: u16) -> u32 {
        if id == self.leader {
            self.timeout_ms
        } else {
            self.follower_timeout_ms
        }
    }

    /// A robot's fresh telemetry.
    pub fn telemetry(&self, id: u16, now_ms: u32) -> Option<Telemetry> {
        self.fresh(id, now_ms)?.telemetry
    }

    /// Every robot with fresh telemetry and where it is.
    pub fn positions(&self, now_ms: u32) -> Vec<(u16, DVec2)> {
        self.ids()
            .filter_map(|id| Some((id, position(&self.telemetry(id, now_ms)?))))
            .collect()
    }

    /// Of `bodies`, the followers following (not idle, stopped or failsafe), in order.
    pub fn following(&self, bodies: &[Body], now_ms: u32) -> Vec<Body> {
        bodies
            .iter()
            .filter(|b| {
                self.followers.contains(&b.id)
                    && self
                        .telemetry(b.id, now_ms)
                        .is_some_and(|t| is_following(t.mode))
            })
            .copied()
            .collect()
    }

    /// Whether every follower is linked, reporting and following (not idle, failsafe).
    pub fn all_following(&self, now_ms: u32) -> bool {
        self.followers.iter().all(|id| {
            self.telemetry(*id, now_ms)
                .is_some_and(|t| is_following(t.mode))
        })
    }

    /// Each follower's (slot order) fresh position, tracking error and whether it has
    /// joined; `detouring`: whether the station is sending it round something.
    pub fn follower_statuses(
        &self,
        now_ms: u32,
        detouring: impl Fn(u16) -> bool,
    ) -> Vec<Option<FollowerStatus>> {
        self.followers
            .iter()
            .map(|id| {
                let status = self.fresh(*id, now_ms)?;
                let t = status.telemetry?;
                Some(FollowerStatus {
                    position: position(&t),
                    error: t.tracking_error_mm as f64 / 1000.0,
                    joined: status.joined,
                    detouring: detouring(*id),
                })
            })
            .collect()
    }

    /// The leader's pose predicted to `now_ms` from its latest telemetry.
    pub fn leader_estimate(&self, now_ms: u32) -> Option<LeaderEstimate> {
        self.estimate(self.leader, now_ms)
    }

    /// Every robot with fresh telemetry, as [`Fleet::estimate`] makes it.
    pub fn bodies(&self, now_ms: u32) -> Vec<Body> {
        self.ids()
            .filter_map(|id| Some(self.estimate(id, now_ms)?.body(id)))
            .collect()
    }

    /// A robot's pose predicted to `now_ms` from its latest telemetry, as a follower
    /// predicts the leader's.
    pub fn estimate(&self, id: u16, now_ms: u32) -> Option<LeaderEstimate> {
        let s = self.fresh(id, now_ms)?;
        let t = s.telemetry?;
        let (x, y, heading) = t.pose.to_si();
        let vl = units::from_milli_i16(t.wheel_mm_s[0]) as f64;
        let vr = units::from_milli_i16(t.wheel_mm_s[1]) as f64;
        let v = 0.5 * (vl + vr);
        let omega = (vr - vl) / self.track_width;
        let age = (now_ms.wrapping_sub(s.pose_at_ms) as f64 / 1000.0).clamp(0.0, 0.5);
        // As a follower predicts the leader's state to now.
        let motion = LeaderMotion {
            pose: PlanPose {
                position: DVec2::new(x as f64, y as f64),
                heading: heading as f64,
            },
            v,
            omega,
        };
        Some(LeaderEstimate {
            pose: motion.after(age),
            v,
            omega,
        })
    }
}
