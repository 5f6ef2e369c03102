//! Follower orders: every room that may want a follower somewhere other than its slot
//! proposes ([`desk::Proposal`]), the desk keeps one per follower by rank, and only that
//! is sent. Detours and steps aside come first: the spacing between robots judges a
//! follower on its way to where those send it.

use std::collections::BTreeMap;

use glam::DVec2;

use super::fleet::{is_following, position};
use super::movers::oncoming;
use super::robots::desk::{self, Kind, Proposal};
use super::robots::{detour, spacing, way};
use super::{BaseStation, Look, Robots, StationEvent};
use crate::perception::tracking::TrackView;
use crate::planner::PlanPose;

impl BaseStation {
    /// Every follower's order this period, from every room, through the desk; sent.
    /// `tracks`: what moves, and whether it crowds the fleet's way. `held`: the followers
    /// the leader's pace holds for people, while the fleet runs
    /// (`None`: it does not yet; only then may a follower be backed off the leader).
    /// The disc the leader's way is to go round, where a follower has stood in it.
    pub(super) fn give_orders(
        &mut self,
        leader: PlanPose,
        look: &Look,
        (tracks, crowded): (&[TrackView], bool),
        robots: Robots<'_>,
        held: Option<&[u16]>,
        now_ms: u32,
    ) -> Option<(DVec2, f64)> {
        let (bodies, following) = robots;
        let (mut proposals, slots) = self.detours(leader, &look.behind, now_ms);
        let aside = self.step_aside(following, bodies, (tracks, crowded), now_ms);
        let mut avoid = None;
        if let Some(held) = held {
            // One stepping out of someone's way is not held in it.
            let held: Vec<u16> = held
                .iter()
                .copied()
                .filter(|id| !aside.iter().any(|p| p.robot == *id))
                .collect();
            proposals.extend(self.hold_for_people(&held, following));
            let (backs, round) = self.back_off(look, robots, now_ms);
            proposals.extend(backs);
            avoid = round;
        }
        proposals.extend(aside);
        let sent: Vec<(u16, DVec2)> = desk::best(&proposals)
            .into_values()
            .map(|p| (p.robot, p.point))
            .collect();
        proposals.extend(self.hold_apart(following, bodies, &slots, &sent, now_ms));
        let orders = self.desk.decide(&proposals);
        for o in &orders {
            if o.began {
                self.note_order(o.robot, o.kind, o.point, now_ms);
            }
            self.send_detour(o.robot, o.point, now_ms);
        }
        self.orders = orders.iter().map(|o| (o.robot, o.point)).collect();
        avoid
    }

    /// The followers the leader's pace holds for people, each where its control point was
    /// when the hold began: it brakes as hard as its firmware allows and stands (a point
    /// it could just stop at would have it creep on into them at the end of its stop).
    fn hold_for_people(&mut self, held: &[u16], following: &[spacing::Body]) -> Vec<Proposal> {
        let offset = self.cfg.control_offset;
        let before = std::mem::take(&mut self.people_holds);
        for f in following.iter().filter(|f| held.contains(&f.id)) {
            let point = before
                .get(&f.id)
                .copied()
                .unwrap_or_else(|| f.position + DVec2::from_angle(f.heading) * offset);
            self.people_holds.insert(f.id, point);
        }
        self.people_holds
            .iter()
            .map(|(robot, point)| Proposal {
                robot: *robot,
                kind: Kind::Hold,
                point: *point,
            })
            .collect()
    }

    /// What a new order is logged and recorded as.
    fn note_order(&mut self, robot: u16, kind: Kind, point: DVec2, now_ms: u32) {
        let at_ms = now_ms;
        let (event, words) = match kind {
            Kind::Hold => (
                StationEvent::FollowerGivesWay { robot, at_ms },
                "follower held short of another robot",
            ),
            Kind::MakeRoom => (
                StationEvent::FollowerGivesWay { robot, at_ms },
                "follower steps aside for another",
            ),
            Kind::BackOff => (
                StationEvent::FollowerGivesWay { robot, at_ms },
                "a follower in the leader's way backs away from it",
            ),
            Kind::StepAside => (
                StationEvent::FollowerStepsAside { robot, at_ms },
                "follower steps aside for someone passing",
            ),
            Kind::Detour => (
                StationEvent::FollowerDetour { robot, at_ms },
                "follower sent round an obstacle",
            ),
        };
        tracing::info!(robot, x = point.x, y = point.y, "{words}");
        self.events.push(event);
    }

    /// Followers held on their way sent round what holds them ([`detour`]); and each
    /// following follower's slot (its reference now).
    fn detours(
        &mut self,
        leader: PlanPose,
        behind: &[DVec2],
        now_ms: u32,
    ) -> (Vec<Proposal>, Vec<(u16, DVec2)>) {
        let mut followers = Vec::new();
        for (k, id) in self.fleet.followers.iter().enumerate() {
            let Some(t) = self.fleet.telemetry(*id, now_ms) else {
                continue;
            };
            if !is_following(t.mode) {
                continue;
            }
            followers.push(detour::Follower {
                id: *id,
                position: position(&t),
                reference: self.guidance.formation().reference(k, leader, behind),
                error: t.tracking_error_mm as f64 / 1000.0,
            });
        }
        let robots = self.fleet.positions(now_ms);
        let footprint = self.guidance.formation().spec().footprint;
        let detours = self
            .detours
            .step(now_ms, &self.world, footprint, &followers, &robots);
        let proposals = detours
            .into_iter()
            .map(|(robot, point, _)| Proposal {
                robot,
                kind: Kind::Detour,
                point,
            })
            .collect();
        let slots = followers.iter().map(|f| (f.id, f.reference)).collect();
        (proposals, slots)
    }

    /// The followers (`following`: those following; `robots`: every robot) stepping aside
    /// for someone in `movers` coming along a narrow way ([`oncoming`]).
    fn step_aside(
        &mut self,
        following: &[spacing::Body],
        robots: &[spacing::Body],
        (movers, crowded): (&[TrackView], bool),
        now_ms: u32,
    ) -> Vec<Proposal> {
        let fleet = oncoming::Fleet {
            followers: following,
            robots,
            space: oncoming::Space {
                footprint: self.guidance.formation().spec().footprint,
                personal: self.cfg.yielding.personal_space_m,
            },
            offset: self.cfg.control_offset,
            crowded,
        };
        let maps = oncoming::Maps {
            site: &self.cfg.map,
            world: &self.world,
        };
        let stepping = self.passing.step_aside(now_ms, &fleet, movers, maps);
        stepping
            .into_iter()
            .map(|(robot, point, _)| Proposal {
                robot,
                kind: Kind::StepAside,
                point,
            })
            .collect()
    }

    /// Where a follower has stood in the standing leader's way for a while, it backs off
    /// it, and the leader's way goes round it ([`way`]): the backs, and the disc.
    fn back_off(
        &mut self,
        look: &Look,
        (bodies, following): Robots<'_>,
        now_ms: u32,
    ) -> (Vec<Proposal>, Option<(DVec2, f64)>) {
        let Some(leader) = bodies.iter().find(|b| b.id == self.cfg.leader).copied() else {
            return (Vec::new(), None);
        };
        let people: Vec<TrackView> = self.tracker.views(now_ms).collect();
        let fleet = way::Fleet {
            leader,
            ahead: &look.ahead,
            followers: following,
            robots: bodies,
            footprint: self.guidance.formation().spec().footprint,
            offset: self.cfg.control_offset,
            site: &self.cfg.map,
            people: &people,
        };
        let blocked = self.blocking.step(now_ms as f64 / 1000.0, &fleet);
        let backs = blocked
            .backs
            .into_iter()
            .map(|(robot, point, _)| Proposal {
                robot,
                kind: Kind::BackOff,
                point,
            })
            .collect();
        (backs, blocked.avoid)
    }

    /// The followers (as for `step_aside`) held short of another robot or off a slot
    /// (`slots`: each follower's) the leader stands on, and those stepping aside for
    /// them (`spacing`). `sent`: the points some are sent to this period instead of their
    /// slots, which they set off for when let go.
    fn hold_apart(
        &mut self,
        following: &[spacing::Body],
        robots: &[spacing::Body],
        slots: &[(u16, DVec2)],
        sent: &[(u16, DVec2)],
        now_ms: u32,
    ) -> Vec<Proposal> {
        let fleet = spacing::Fleet {
            followers: following,
            robots,
            footprint: self.guidance.formation().spec().footprint,
            offset: self.cfg.control_offset,
            brake: self.cfg.yield_brake,
            robot: self.cfg.robot,
            leader: leader_snapshot(robots, self.cfg.leader, self.told_twist()),
            sent,
        };
        let mut told = self.spacing.step(now_ms, &fleet, slots, &self.world);
        if let Some(leader) = robots.iter().find(|b| b.id == self.cfg.leader) {
            told.extend(self.spacing.hold_off_slots(&fleet, leader, slots));
        }
        told.into_iter()
            .map(|t| Proposal {
                robot: t.id,
                kind: match t.order {
                    spacing::Order::Hold => Kind::Hold,
                    spacing::Order::MakeRoom => Kind::MakeRoom,
                },
                point: t.point,
            })
            .collect()
    }

    /// The leader's twist as the followers were last told it: the speed it was commanded
    /// (every command is broadcast as it is sent) and the smoothed turn rate.
    fn told_twist(&self) -> (f64, f64) {
        (self.last_command.0, self.broadcast_omega.omega())
    }
}

/// The leader as its followers' law takes it: where it is, and the twist they were last
/// told it drives.
fn leader_snapshot(
    robots: &[spacing::Body],
    leader: u16,
    twist: (f64, f64),
) -> Option<control_core::follower::LeaderSnapshot> {
    let l = robots.iter().find(|b| b.id == leader)?;
    Some(control_core::follower::LeaderSnapshot {
        pose: control_core::Pose::new(l.position.x as f32, l.position.y as f32, l.heading as f32),
        v: twist.0 as f32,
        omega: twist.1 as f32,
    })
}

/// The points followers were told to make for, by follower.
pub(super) type Told = BTreeMap<u16, DVec2>;
