//! Fixes from the site's localization, forwarded to each robot under its own key:
//! offered as they come ([`BaseStation::forward_fix`]), the one that agrees best with the
//! robot sent at its slot ([`super::fixes`], [`super::fix_check`]), their age watched.

mod check;
pub(super) mod watch;
use protocol::messages::{Message, PoseFix, WirePose};
use protocol::{units, Address};

use super::{BaseStation, StationEvent};
use crate::planner::PlanPose;
use check::Belief;
use watch::{Candidate, FixChange, FixWatch, Offer};

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
    /// held back (5 s after the last agreeing fix: `fixes::HOLD_OUTLIERS_MS`).
    Outlier,
}

/// A fix on its way to its robot: the message, and the station time it was valid at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct OutgoingFix {
    fix: PoseFix,
    valid_at_ms: u32,
}

impl BaseStation {
    /// From now on the robots' fixes come from a localization source through
    /// [`BaseStation::forward_fix`], and their age is watched (`[localization]` limits).
    pub fn watch_fixes(&mut self, now_ms: u32) {
        self.fix_watch = Some(FixWatch::new(self.cfg.fixes, self.fleet.ids(), now_ms));
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
        let robots = self.fleet.ids();
        let watch = self
            .fix_watch
            .get_or_insert_with(|| FixWatch::new(self.cfg.fixes, robots, now_ms));
        let Some(status) = self.fleet.get(robot) else {
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
    pub(super) fn send_due_fixes(&mut self, now_ms: u32) {
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

    pub(super) fn check_fixes(&mut self, now_ms: u32) {
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
                    tracing::error!("a robot has had no fix too long: the fleet stops")
                }
                FixChange::Resume => tracing::info!("every robot has fixes: the fleet goes on"),
            }
            self.events.push(StationEvent::Localization {
                change,
                at_ms: now_ms,
            });
        }
    }
}
