//! Keeping the robots apart. A robot's ring sees ±40° ahead and behind it, so two robots
//! side by side, or one driving past another's flank, can touch with neither ring seeing
//! the other: in dense crowds a follower crossing the line to its slot clipped a follower
//! standing square to its side (`docs/results.md#movers`). The station knows where every
//! robot is. It caps the leader's speed toward another robot as the ring caps it toward an
//! echo, and holds a follower whose way runs into another robot (a `Detour` to the point
//! it can stop at) until that way is clear again.
//!
//! The robots are discs of one footprint, and a robot's centre moves along its heading:
//! a robot turning on the spot never comes closer to another.
//!
//! Where a follower is sent aside or let go, how its body will swing getting there is
//! rolled out with the firmware's own control code ([`swing`]).

use std::collections::{BTreeMap, BTreeSet};

use control_core::follower::LeaderSnapshot;
use control_core::RobotConfig;
use glam::DVec2;

use crate::geometry::map::Map;

mod swing;
use swing::{sets_off_clear, steps_clear};

/// The ring's outer beams, degrees off the way the robot drives (`hil-sim`'s ring): a
/// robot whose centre is within them is the ring's to keep from.
const RING_DEG: f64 = 40.0;
/// What a robot keeps from another beyond both footprints, m.
const KEEP_M: f64 = 0.05;
/// A held follower goes on where its way is this clear, m.
const CLEAR_M: f64 = 0.3;
/// A follower held this long has the follower standing in its way step aside, ms.
const ROOM_AFTER_MS: u32 = 1500;
/// How far beyond the held one's way it steps, m.
const ROOM_M: f64 = 0.1;
/// What the place it steps to keeps from the map beyond its footprint, m.
const ROOM_MAP_M: f64 = 0.05;
/// A robot slower than this stands, m/s.
pub(super) const STANDING: f64 = 0.05;
/// A standing follower whose slot is farther than this sets off for it, m.
const SET_OFF_M: f64 = 0.1;
/// What a stop allows for the station's delay: the telemetry's age and the command's
/// trip (one period each), s.
const LATENCY_S: f64 = 0.2;
/// A follower turning on the spot faces its slot within this, degrees.
const FACING_DEG: f64 = 20.0;
/// A follower turns to face a slot at least this far from its control point, m (a nearer
/// one is where it stands: the way there swings round as it turns).
const TURN_FROM_M: f64 = 0.5;

/// One robot as the station estimates it now.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Body {
    pub id: u16,
    pub position: DVec2,
    pub heading: f64,
    /// Forward speed, m/s (negative backing).
    pub v: f64,
}

impl Body {
    /// A body at (`x`, `y`) facing `heading_deg`, for the tests.
    #[cfg(test)]
    pub(super) fn at(id: u16, x: f64, y: f64, heading_deg: f64, v: f64) -> Self {
        Self {
            id,
            position: DVec2::new(x, y),
            heading: heading_deg.to_radians(),
            v,
        }
    }

    fn velocity(&self) -> DVec2 {
        DVec2::from_angle(self.heading) * self.v
    }

    /// Its control point, `offset` ahead of its centre.
    fn control(&self, offset: f64) -> DVec2 {
        self.position + DVec2::from_angle(self.heading) * offset
    }

    /// Whether `p` is within its ring's beams ahead (`sign` 1) or behind (−1).
    pub(super) fn sees(&self, sign: f64, p: DVec2) -> bool {
        let to = p - self.position;
        to.dot(DVec2::from_angle(self.heading) * sign) >= to.length() * RING_DEG.to_radians().cos()
    }
}

/// The slot (for its control point) of follower `id`, if it has one.
fn slot_of(slots: &[(u16, DVec2)], id: u16) -> Option<DVec2> {
    slots.iter().find(|(f, _)| *f == id).map(|(_, slot)| *slot)
}

/// What lies on `body`'s way along its heading (`sign` 1) or backward (`sign` −1) where
/// its ring does not look: for each other robot beyond `RING_DEG` off that way that it
/// would come within `KEEP_M` of, how far its centre can move first
/// (0 where it is within that already and the move closes in), and how fast that robot
/// moves away along the way (negative coming at it).
fn on_way<'a>(
    body: &'a Body,
    sign: f64,
    others: &'a [Body],
    footprint: f64,
) -> impl Iterator<Item = (&'a Body, f64, f64)> + 'a {
    let dir = DVec2::from_angle(body.heading) * sign;
    let reach = 2.0 * footprint + KEEP_M;
    others
        .iter()
        .filter(|o| o.id != body.id)
        .filter_map(move |o| {
            let to = o.position - body.position;
            let along = to.dot(dir);
            let aside2 = to.length_squared() - along * along;
            if along <= 0.0 || body.sees(sign, o.position) || aside2 >= reach * reach {
                return None;
            }
            let gap = (along - (reach * reach - aside2).sqrt()).max(0.0);
            Some((o, gap, o.velocity().dot(dir)))
        })
}

/// How far `body` can move along its heading (`sign` 1) or backward (`sign` −1) before
/// its footprint comes within `KEEP_M` of a robot its ring does not see, standing where
/// it is now.
pub fn free(body: &Body, sign: f64, others: &[Body], footprint: f64) -> f64 {
    on_way(body, sign, others, footprint)
        .map(|(_, gap, _)| gap)
        .fold(f64::INFINITY, f64::min)
}

/// How far a robot moving away at `speed` still goes if it brakes now at `brake`: room
/// the one behind it may count on (none from one coming at it).
fn yields(speed: f64, brake: f64) -> f64 {
    if speed > 0.0 {
        speed * speed / (2.0 * brake)
    } else {
        0.0
    }
}

/// The distance a robot at `speed` needs to stop at `brake`, with the station's delay.
fn stopping(speed: f64, brake: f64) -> f64 {
    speed.abs() * LATENCY_S + speed * speed / (2.0 * brake)
}

/// The fastest a robot may drive with `free` metres before it, to stop in time at
/// `brake`: the speed whose stopping distance is `free`.
fn speed_for(free: f64, brake: f64) -> f64 {
    brake * (-LATENCY_S + (LATENCY_S * LATENCY_S + 2.0 * free.max(0.0) / brake).sqrt())
}

/// The fastest `body` may drive along its heading (`sign` 1) or backward (−1) and still
/// stop short of every robot on that way, each braking too.
fn top_speed(body: &Body, sign: f64, others: &[Body], footprint: f64, brake: f64) -> f64 {
    on_way(body, sign, others, footprint)
        .map(|(_, gap, away)| speed_for(gap + yields(away, brake), brake))
        .fold(f64::INFINITY, f64::min)
}

/// How long two robots' courses are held against each other beyond the time to stop, s.
const COURSE_S: f64 = 0.2;

/// Whether `body` and another robot, both moving and neither seeing the other with its
/// ring, close on each other so that, keeping their velocities until `body` could stop
/// (and [`COURSE_S`] more), they come within `KEEP_M` of touching, `body`'s own motion
/// being part of the closing: two followers tracking slots that swing with the leader
/// converge flank to flank, each moving clear of where the other was. A robot standing
/// is judged by [`free`]; one the other sees is its ring's.
fn converging(body: &Body, others: &[Body], footprint: f64, brake: f64) -> bool {
    let unseen = |a: &Body, b: &Body| a.v.abs() > STANDING && !a.sees(a.v.signum(), b.position);
    if body.v.abs() <= STANDING {
        return false;
    }
    let reach = 2.0 * footprint + KEEP_M;
    let horizon = LATENCY_S + body.v.abs() / brake + COURSE_S;
    let own = body.velocity();
    others
        .iter()
        .filter(|o| o.id != body.id && unseen(body, o) && unseen(o, body))
        .any(|o| {
            let (r, w) = (o.position - body.position, o.velocity() - own);
            let t = (-r.dot(w) / w.length_squared().max(1e-12)).clamp(0.0, horizon);
            r.dot(w) < 0.0 && own.dot(r) > 0.0 && (r + w * t).length() < reach
        })
}

/// The leader's commanded speed `v`, capped so that it stops short of every other robot.
pub fn cap_leader(leader: &Body, v: f64, others: &[Body], footprint: f64, brake: f64) -> f64 {
    let ahead = top_speed(leader, 1.0, others, footprint, brake);
    let behind = top_speed(leader, -1.0, others, footprint, brake);
    v.clamp(-behind, ahead)
}

/// What the station tells a follower to do for another robot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Order {
    /// Stop: its way runs into a robot its ring cannot see.
    Hold,
    /// Step aside: it stands beside the way of a follower held for it.
    MakeRoom,
}

/// One follower told something this period: the point to make for, and whether the order
/// just began.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Told {
    pub id: u16,
    pub order: Order,
    pub point: DVec2,
    pub began: bool,
}

/// A follower held: the way it was moving (1 forward, −1 backing) and since when; for one
/// held before it set off, the way to its goal (its slot, or the point it is sent to;
/// radians); the point it makes for, fixed when the hold began (recomputed from where
/// it is each period, the point runs ahead of a moving follower by its stopping distance
/// and it never stops).
#[derive(Debug, Clone, Copy)]
struct Held {
    sign: f64,
    since_ms: u32,
    to_slot: Option<f64>,
    point: DVec2,
    /// Where its control point makes for to turn on the spot to face its slot, fixed when
    /// the turn began ([`turn`]).
    turn: Option<DVec2>,
}

/// The followers held because their way runs into another robot, and those stepping aside
/// for them.
#[derive(Debug, Default)]
pub struct Spacing {
    held: BTreeMap<u16, Held>,
    making_room: BTreeSet<u16>,
    /// The followers held off a slot the leader stands on.
    off_slot: BTreeSet<u16>,
}

impl Spacing {
    /// One period. Holds the followers whose way, at their speed, runs into another robot
    /// within their stopping distance, and lets go those whose way is clear; a follower
    /// standing in the way of one held for `ROOM_AFTER_MS` steps aside (else the two wait
    /// for each other for good: the held one for the way, the other, behind it in the
    /// line, for its ring to see it go). Holds come first in the list. Points are for the
    /// control point, `fleet.offset` ahead of the centre. `map`: what the robots must keep
    /// from.
    ///
    /// A follower standing is judged on the way to its slot (`slots`: each one's, for its
    /// control point), or to the point it is sent to instead (`fleet.sent`), where it
    /// will set off: judged on its heading, it would be held only once it moved, a
    /// period and the station's delay late, turning into the flank of one standing
    /// beside it.
    pub fn step(
        &mut self,
        now_ms: u32,
        fleet: &Fleet,
        slots: &[(u16, DVec2)],
        map: &Map,
    ) -> Vec<Told> {
        let mut held = BTreeMap::new();
        let mut out = Vec::new();
        for f in fleet.followers {
            let was = self.held.get(&f.id).copied();
            if let Some((h, told)) = hold_one(f, was, fleet, slots, now_ms) {
                held.insert(f.id, h);
                out.push(told);
            }
        }
        let (making_room, room) = self.make_room(&held, fleet, map, now_ms);
        out.extend(room);
        self.held = held;
        self.making_room = making_room;
        out
    }

    /// The followers standing in the way of one held for [`ROOM_AFTER_MS`], each told to
    /// step aside (the two would otherwise wait for each other for good).
    fn make_room(
        &self,
        held: &BTreeMap<u16, Held>,
        fleet: &Fleet,
        map: &Map,
        now_ms: u32,
    ) -> (BTreeSet<u16>, Vec<Told>) {
        let mut making_room = BTreeSet::new();
        let mut out = Vec::new();
        for (id, h) in held {
            if now_ms.wrapping_sub(h.since_ms) < ROOM_AFTER_MS {
                continue;
            }
            let Some(f) = fleet.followers.iter().find(|f| f.id == *id) else {
                continue;
            };
            let way = h.to_slot.map_or(*f, |heading| Body { heading, ..*f });
            let Some((other, point)) = room_for(&way, h.sign, fleet, map) else {
                continue;
            };
            if held.contains_key(&other) || !making_room.insert(other) {
                continue;
            }
            out.push(Told {
                id: other,
                order: Order::MakeRoom,
                point,
                began: !self.making_room.contains(&other),
            });
        }
        (making_room, out)
    }

    /// One period: the followers whose slot (`slots`: each one's, for its control point)
    /// lies where its footprint would come within [`KEEP_M`] of the leader's, held where
    /// they can stop until it does not. Where the leader's route turns back along the
    /// line, the slot on the path it drove can fall on the leader itself, and a follower
    /// closing on it at its pace would touch the leader's flank.
    pub fn hold_off_slots(
        &mut self,
        fleet: &Fleet,
        leader: &Body,
        slots: &[(u16, DVec2)],
    ) -> Vec<Told> {
        let reach = 2.0 * fleet.footprint + KEEP_M;
        let mut held = BTreeSet::new();
        let mut out = Vec::new();
        for f in fleet.followers {
            let Some(slot) = slot_of(slots, f.id) else {
                continue;
            };
            let centre = slot - DVec2::from_angle(f.heading) * fleet.offset;
            if centre.distance(leader.position) >= reach {
                continue;
            }
            held.insert(f.id);
            out.push(Told {
                id: f.id,
                order: Order::Hold,
                point: hold_point(f, fleet),
                began: !self.off_slot.contains(&f.id),
            });
        }
        self.off_slot = held;
        out
    }
}

/// Whether follower `f` (held last period: `was`) is held this period, and where: its
/// way, at its speed, runs into another robot within its stopping distance, or, standing,
/// its way to its goal (its slot, or the point it is sent to) does not swing clear.
/// Standing, it turns to face its goal where that swings clear, and goes once it does
/// with the way clear; held while moving, it is judged on its heading.
fn hold_one(
    f: &Body,
    was: Option<Held>,
    fleet: &Fleet,
    slots: &[(u16, DVec2)],
    now_ms: u32,
) -> Option<(Held, Told)> {
    let standing = f.v.abs() <= STANDING;
    let to_slot = match was {
        // The slot moves on with the leader: judged on the way to it as it was when the
        // hold began, two followers side by side held each other for good.
        Some(h) if h.to_slot.is_some() && standing => way_to_goal(f, slots, fleet),
        Some(h) => h.to_slot,
        None if standing => way_to_goal(f, slots, fleet),
        None => None,
    };
    // Toward its slot it sets off forward, whatever its speed's sign standing.
    let sign = match (was, to_slot) {
        (_, Some(_)) => 1.0,
        (Some(h), None) => h.sign,
        (None, None) if f.v < 0.0 => -1.0,
        (None, None) => 1.0,
    };
    let way = to_slot.map_or(*f, |heading| Body { heading, ..*f });
    let hold = converging(f, fleet.robots, fleet.footprint, fleet.brake)
        || if was.is_some() || to_slot.is_some() {
            free(&way, sign, fleet.robots, fleet.footprint) < CLEAR_M
                || to_slot.is_some() && !fleet.sets_off_to_goal_clear(f, slots)
        } else {
            f.v.abs() > top_speed(f, sign, fleet.robots, fleet.footprint, fleet.brake)
        };
    let stop_at = was.map_or_else(|| hold_point(f, fleet), |h| h.point);
    let turning = was.and_then(|h| h.turn);
    let turn = match was {
        Some(h) if hold && h.to_slot.is_none() && (standing || turning.is_some()) => {
            turn(f, turning, slots, fleet)
        }
        _ => Turn::Stay,
    };
    // Once it has turned, it is held where it stands now.
    let here = f.control(fleet.offset);
    let (point, turning, stop_at) = match turn {
        Turn::Go => return None,
        Turn::To(point) => (point, Some(point), here),
        Turn::Stay if hold && turning.is_some() => (here, None, here),
        Turn::Stay if hold => (stop_at, None, stop_at),
        Turn::Stay => return None,
    };
    let h = Held {
        sign,
        since_ms: was.map_or(now_ms, |h| h.since_ms),
        to_slot,
        point: stop_at,
        turn: turning,
    };
    let told = Told {
        id: f.id,
        order: Order::Hold,
        point,
        began: was.is_none(),
    };
    Some((h, told))
}

/// The way from a follower's control point to its goal (radians; the point it is sent
/// to, else its slot), if it has one and is not there already.
fn way_to_goal(f: &Body, slots: &[(u16, DVec2)], fleet: &Fleet) -> Option<f64> {
    let to = fleet.goal(slots, f.id)? - f.control(fleet.offset);
    (to.length() > SET_OFF_M).then(|| to.to_angle())
}

/// What a follower held while it moved does once it stands.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Turn {
    /// It faces its slot and the way there is clear: it goes.
    Go,
    /// It turns on the spot to face its slot: its control point makes for this point.
    To(DVec2),
    /// It stays as it stands.
    Stay,
}

/// A follower held while it moved stands with another robot at its flank, on its heading
/// but not on its way to its slot. Judged on its heading it is held for good; judged on
/// the way to its slot it is let go, and the law drives it on along its heading while it
/// turns, into that flank; two followers so held, each on the other's way, wait for each
/// other for good. It turns on the spot first, where that swings clear, and goes once it
/// faces its slot with the way clear.
/// `turning`: the point of a turn under way.
fn turn(f: &Body, turning: Option<DVec2>, slots: &[(u16, DVec2)], fleet: &Fleet) -> Turn {
    let Some(slot) = fleet.goal(slots, f.id) else {
        return Turn::Stay;
    };
    let control = f.control(fleet.offset);
    if slot.distance(control) < TURN_FROM_M {
        return Turn::Stay;
    }
    let way = (slot - control).to_angle();
    let facing = crate::geometry::wrap_angle(way - f.heading).abs() <= FACING_DEG.to_radians();
    let along = Body { heading: way, ..*f };
    if facing
        && free(&along, 1.0, fleet.robots, fleet.footprint) >= CLEAR_M
        && fleet.sets_off_to_goal_clear(f, slots)
    {
        return Turn::Go;
    }
    if let Some(point) = turning {
        return if facing { Turn::Stay } else { Turn::To(point) };
    }
    let point = f.position + DVec2::from_angle(way) * fleet.offset;
    if facing || !steps_clear(f, point, fleet) {
        return Turn::Stay;
    }
    Turn::To(point)
}

/// Where a held follower's control point makes for: the point it can stop at.
fn hold_point(f: &Body, fleet: &Fleet) -> DVec2 {
    stop_point(f, fleet.offset, fleet.brake)
}

/// The point `f`'s control point (`offset` ahead of its centre) can stop at, braking at
/// `brake` after the station's delay.
pub fn stop_point(f: &Body, offset: f64, brake: f64) -> DVec2 {
    let stop = stopping(f.v, brake) * f.v.signum();
    f.position + DVec2::from_angle(f.heading) * (offset + stop)
}

/// What [`Spacing::step`] needs to know of the fleet this period.
#[derive(Debug, Clone, Copy)]
pub struct Fleet<'a> {
    /// The followers following (not idle, stopped or failsafe).
    pub followers: &'a [Body],
    /// Every robot, followers included.
    pub robots: &'a [Body],
    pub footprint: f64,
    /// How far ahead of a follower's centre its control point is, m.
    pub offset: f64,
    /// How hard a robot may brake, m/s².
    pub brake: f64,
    /// The followers' control configuration (limits, the L-φ law's gains).
    pub robot: RobotConfig,
    /// The leader as the followers' law takes it, if known.
    pub leader: Option<LeaderSnapshot>,
    /// The points (for the control point) followers are sent to this period instead of
    /// their slots: a way round an obstacle, a step aside for someone passing.
    pub sent: &'a [(u16, DVec2)],
}

impl Fleet<'_> {
    /// Where follower `id`'s control point makes for: the point it is sent to, else its
    /// slot (`slots`).
    fn goal(&self, slots: &[(u16, DVec2)], id: u16) -> Option<DVec2> {
        slot_of(self.sent, id).or_else(|| slot_of(slots, id))
    }

    /// Whether standing follower `f` swings clear of the robots beside it setting off for
    /// its goal, as its firmware drives there: a detour's law toward a point it is sent to,
    /// else the L-φ law toward its slot: judged on its slot while it is sent round a bin,
    /// a follower let go backs toward the detour point, turning, into the flank of one
    /// standing beside it.
    fn sets_off_to_goal_clear(&self, f: &Body, slots: &[(u16, DVec2)]) -> bool {
        match slot_of(self.sent, f.id) {
            Some(point) => steps_clear(f, point, self),
            None => sets_off_clear(f, slots, self),
        }
    }
}

/// The follower standing nearest on `held`'s way, and the point (for its control point)
/// that takes it `ROOM_M` beyond that way, if that point is free of the map and the other
/// robots.
fn room_for(held: &Body, sign: f64, fleet: &Fleet, map: &Map) -> Option<(u16, DVec2)> {
    let (other, _, _) =
        on_way(held, sign, fleet.robots, fleet.footprint).min_by(|a, b| a.1.total_cmp(&b.1))?;
    if other.v.abs() > STANDING || !fleet.followers.iter().any(|f| f.id == other.id) {
        return None;
    }
    let dir = DVec2::from_angle(held.heading) * sign;
    let to = other.position - held.position;
    let aside = to - dir * to.dot(dir);
    let out = aside.try_normalize()?;
    let reach = 2.0 * fleet.footprint + KEEP_M;
    let centre = other.position + out * ((reach - aside.length()).max(0.0) + ROOM_M);
    let need = fleet.footprint + ROOM_MAP_M;
    let free_of_robots = fleet
        .robots
        .iter()
        .filter(|r| r.id != other.id)
        .all(|r| r.position.distance(centre) >= reach);
    let point = centre + out * fleet.offset;
    (free_of_robots && map.clearance(centre, need) >= need && steps_clear(other, point, fleet))
        .then_some((other.id, point))
}

#[cfg(test)]
mod tests {
    use super::*;
    use control_core::Pose;

    const FP: f64 = 0.3;

    fn body(id: u16, x: f64, y: f64, heading_deg: f64, v: f64) -> Body {
        Body::at(id, x, y, heading_deg, v)
    }

    #[test]
    fn free_is_the_way_to_a_robot_the_ring_cannot_see_and_unbounded_away() {
        let me = body(1, 0.0, 0.0, 0.0, 0.5);
        // 0.5 m ahead and 0.5 m aside: 45° off, beyond the ring's beams.
        let ahead = body(2, 0.5, 0.5, 0.0, 0.0);
        let reach = 2.0 * FP + KEEP_M;
        let gap = 0.5 - (reach * reach - 0.25f64).sqrt();
        assert!((free(&me, 1.0, &[me, ahead], FP) - gap).abs() < 1e-9);
        assert_eq!(free(&me, -1.0, &[ahead], FP), f64::INFINITY);
        // Straight ahead is the ring's to see.
        let seen = body(2, 0.7, 0.0, 0.0, 0.0);
        assert_eq!(free(&me, 1.0, &[seen], FP), f64::INFINITY);
        // Square to its side, 0.6 m apart and 0.05 m ahead: touching distance, closing.
        let flank = body(2, 0.05, 0.6, 0.0, 0.0);
        assert_eq!(free(&me, 1.0, &[flank], FP), 0.0);
        // The same, a little behind: moving on opens the gap.
        let behind = body(2, -0.05, 0.6, 0.0, 0.0);
        assert_eq!(free(&me, 1.0, &[behind], FP), f64::INFINITY);
    }

    #[test]
    fn the_leader_slows_for_a_robot_at_its_flank_that_its_ring_cannot_see() {
        let leader = body(0, 0.0, 0.0, 0.0, 0.3);
        // 65° off its heading, 0.05 m beyond both footprints: the ring's beams end at 40°.
        let f = body(
            1,
            0.65 * 65f64.to_radians().cos(),
            0.65 * 65f64.to_radians().sin(),
            90.0,
            0.0,
        );
        assert!(cap_leader(&leader, 0.3, &[f], FP, 0.8).abs() < 1e-9);
        // Backing away from it is not held.
        assert!((cap_leader(&leader, -0.2, &[f], FP, 0.8) + 0.2).abs() < 1e-9);
        // At 45°, 0.6 m ahead and aside: it may go at the speed it can stop from in the
        // 0.35 m free.
        let far = body(1, 0.6, 0.6, 0.0, 0.0);
        let v = cap_leader(&leader, 2.0, &[far], FP, 0.8);
        assert!((stopping(v, 0.8) - 0.35).abs() < 1e-9, "{v}");
        // And not at all for a robot straight ahead: that is its ring's.
        let ahead = body(1, 0.7, 0.0, 0.0, 0.0);
        assert_eq!(cap_leader(&leader, 2.0, &[ahead], FP, 0.8), 2.0);
    }

    fn fleet<'a>(bodies: &'a [Body]) -> Fleet<'a> {
        Fleet {
            followers: bodies,
            robots: bodies,
            footprint: FP,
            offset: 0.2,
            brake: 0.8,
            robot: RobotConfig::DEFAULT,
            leader: None,
            sent: &[],
        }
    }

    fn open() -> Map {
        Map::new(Vec::new())
    }

    #[test]
    fn a_follower_crossing_to_another_ones_flank_is_held_until_it_moves_away() {
        let mut s = Spacing::default();
        // Follower 2 drives at 0.6 m/s past follower 1, which stands 0.7 m away at 60°:
        // 0.12 m on, their footprints would be 0.05 m apart.
        let a = 60f64.to_radians();
        let one = body(1, 0.7 * a.cos(), 0.7 * a.sin(), 180.0, 0.0);
        let two = body(2, 0.0, 0.0, 0.0, 0.6);
        let told = s.step(0, &fleet(&[one, two]), &[], &open());
        assert_eq!(told.len(), 1);
        let t = told[0];
        assert!(t.id == 2 && t.order == Order::Hold && t.began);
        // It is held at the point it can stop at, ahead of its control point.
        let x = 0.2 + stopping(0.6, 0.8);
        assert!((t.point.x - x).abs() < 1e-9 && t.point.y == 0.0);
        // Further on, it stays held while follower 1 stands there, at the same point...
        let two = Body {
            position: DVec2::new(0.1, 0.0),
            v: 0.2,
            ..two
        };
        let told = s.step(100, &fleet(&[one, two]), &[], &open());
        assert!(told.len() == 1 && !told[0].began && s.held.contains_key(&2));
        assert!((told[0].point.x - x).abs() < 1e-9, "the point moved on");
        // ...and goes on once follower 1 has moved off.
        let one = Body {
            position: DVec2::new(-1.0, 2.0),
            ..one
        };
        assert!(s.step(200, &fleet(&[one, two]), &[], &open()).is_empty());
        assert!(!s.held.contains_key(&2));
    }

    #[test]
    fn a_follower_standing_in_the_way_of_one_held_steps_aside_after_a_while() {
        let mut s = Spacing::default();
        let a = 60f64.to_radians();
        let one = body(1, 0.7 * a.cos(), 0.7 * a.sin(), -90.0, 0.0);
        let two = body(2, 0.0, 0.0, 0.0, 0.6);
        s.step(0, &fleet(&[one, two]), &[], &open());
        let two = Body { v: 0.0, ..two };
        assert_eq!(s.step(1000, &fleet(&[one, two]), &[], &open()).len(), 1);
        // Held 1.5 s: follower 1 is sent beyond follower 2's way, square to it.
        let told = s.step(1500, &fleet(&[one, two]), &[], &open());
        assert_eq!(told.len(), 2);
        let room = told[1];
        assert!(room.id == 1 && room.order == Order::MakeRoom && room.began);
        let centre = room.point - (room.point - one.position).normalize() * 0.2;
        let reach = 2.0 * FP + KEEP_M;
        assert!((centre.x - one.position.x).abs() < 1e-9);
        assert!((centre.y - (reach + ROOM_M)).abs() < 1e-9, "{centre}");
        // Not where a wall stands: they wait.
        let mut s = Spacing::default();
        let wall = Map::new(vec![crate::geometry::Obstacle::Circle {
            center: DVec2::new(one.position.x, 1.1),
            radius: 0.2,
        }]);
        let two = Body { v: 0.6, ..two };
        s.step(0, &fleet(&[one, two]), &[], &wall);
        let two = Body { v: 0.0, ..two };
        assert_eq!(s.step(1500, &fleet(&[one, two]), &[], &wall).len(), 1);
    }

    #[test]
    fn a_follower_steps_aside_only_where_its_body_swings_clear() {
        // plaza-0.2-social-seed1033 at 241.5 s: follower 1 is held, its way to its slot
        // (-2.2 m, +1.0 m) running into follower 2, who stands 0.59 m off (footprints
        // 0.04 m apart) facing 117°. Its control point to be sent aside, behind it and
        // to its right, follower 2 would back and swing its flank into follower 1.
        let one = body(1, 0.0, 0.0, 129.5, 0.0);
        let slot = [(1, DVec2::new(-2.2, 1.0))];
        let facing = |deg| body(2, -0.525, -0.27, deg, 0.0);
        let sent = |two: Body| {
            let mut s = Spacing::default();
            s.step(0, &fleet(&[one, two]), &slot, &open());
            s.step(1500, &fleet(&[one, two]), &slot, &open())
                .iter()
                .any(|t| t.id == 2 && t.order == Order::MakeRoom)
        };
        assert!(!sent(facing(117.0)));
        // Facing the way it is sent (away from follower 1's way), it drives out clear.
        assert!(sent(facing(-115.0)));
    }

    #[test]
    fn a_standing_follower_sets_off_only_where_its_own_law_swings_it_clear() {
        // plaza-0.2-social-seed1053: follower 2 stands facing −112°, its slot 1.3 m away
        // 19° to its left; follower 1 stands 0.75 m off 41° to its left, just beyond its
        // ring's beams; the leader drives on at 0.09 m/s, 1.9 m off.
        fn with(bodies: &[Body]) -> Fleet<'_> {
            Fleet {
                leader: Some(LeaderSnapshot {
                    pose: Pose::new(20.652, 16.104, -0.073),
                    v: 0.09,
                    omega: 0.0,
                }),
                ..fleet(bodies)
            }
        }
        let two = Body::at(2, 18.750, 16.523, -112.2, 0.0);
        let one = Body::at(1, 18.993, 15.817, 12.9, 0.0);
        let slot = [(2, DVec2::new(18.606, 15.265))];
        // Judged as a straight line, the way to its slot is clear: follower 1 is within
        // 40° of it, the ring's to see…
        let way = way_to_goal(&two, &slot, &fleet(&[one, two])).unwrap();
        assert!(
            free(
                &Body {
                    heading: way,
                    ..two
                },
                1.0,
                &[one, two],
                FP
            ) >= CLEAR_M
        );
        // …but driving its law it turns left as it goes, toward follower 1: it is held.
        let bodies = [one, two];
        assert!(!sets_off_clear(&two, &slot, &with(&bodies)));
        let told = Spacing::default().step(0, &with(&bodies), &slot, &open());
        assert!(told.iter().any(|t| t.id == 2 && t.order == Order::Hold));
        // With follower 1 a metre off, it sets off.
        let far = Body::at(1, 19.3, 15.8, 12.9, 0.0);
        assert!(sets_off_clear(&two, &slot, &with(&[far, two])));
    }

    #[test]
    fn two_followers_held_for_each_other_turn_to_their_slots_and_go() {
        // plaza-0.2-social-seed1005 at 100 s: follower 1, held while it drove at −73°,
        // has follower 2 at its flank on that heading, though not on its way to its slot
        // (−19°); follower 2's way to its slot runs past follower 1's flank. Each was held
        // for the other, for good.
        let slots = [(1, DVec2::new(16.58, 11.21)), (2, DVec2::new(15.23, 11.26))];
        let two = body(2, 13.965, 11.668, 136.5, 0.0);
        let driving = body(1, 14.425, 12.110, -72.8, 0.1);
        let mut s = Spacing::default();
        let told = s.step(0, &fleet(&[driving, two]), &slots, &open());
        assert_eq!(told.len(), 2, "{told:?}");
        // Standing, follower 1 turns on the spot: its control point is sent 0.2 m from
        // its centre on the way to its slot.
        let one = Body { v: 0.0, ..driving };
        let told = s.step(100, &fleet(&[one, two]), &slots, &open());
        let t = told.iter().find(|t| t.id == 1).unwrap();
        let control = one.position + DVec2::from_angle(one.heading) * 0.2;
        let way = (slots[0].1 - control).to_angle();
        assert!(
            t.point
                .distance(one.position + DVec2::from_angle(way) * 0.2)
                < 1e-9
        );
        // Facing its slot, with the way there clear, it goes.
        let turned = Body {
            heading: way,
            ..one
        };
        let told = s.step(200, &fleet(&[turned, two]), &slots, &open());
        assert!(told.iter().all(|t| t.id != 1), "{told:?}");
    }

    #[test]
    fn a_standing_follower_is_held_before_it_sets_off_past_another_ones_flank() {
        let mut s = Spacing::default();
        // Follower 2 stands facing away (heading −158°, as on plaza-0.3-social-seed402);
        // its slot lies along -x, and follower 1 stands 0.65 m off at 114°: turning to
        // its slot and driving, it would graze follower 1's flank.
        let one = body(1, -0.26, 0.59, 6.0, 0.0);
        let two = body(2, 0.0, 0.0, -158.0, 0.0);
        let slot = [(2, DVec2::new(-2.2, 0.5))];
        // Judged on its heading, nothing holds it (it stands, its way is clear).
        assert!(s.step(0, &fleet(&[one, two]), &[], &open()).is_empty());
        let told = s.step(100, &fleet(&[one, two]), &slot, &open());
        assert_eq!(told.len(), 1);
        let t = told[0];
        assert!(t.id == 2 && t.order == Order::Hold && t.began);
        // Held where it stands: its own control point.
        let control = two.position + DVec2::from_angle(two.heading) * 0.2;
        assert!(t.point.distance(control) < 1e-9);
        // Standing with a hair of backward speed, it is judged toward its slot too, and
        // stays held while that way is not clear.
        let creeping = Body { v: -0.01, ..two };
        let mut s = Spacing::default();
        assert_eq!(s.step(0, &fleet(&[one, creeping]), &slot, &open()).len(), 1);
        let told = s.step(100, &fleet(&[one, creeping]), &slot, &open());
        assert!(told.len() == 1 && !told[0].began, "let go and held again");
        // A slot the other way is clear to set off for.
        let mut s = Spacing::default();
        let away = [(2, DVec2::new(2.2, -0.5))];
        assert!(s.step(0, &fleet(&[one, two]), &away, &open()).is_empty());
    }

    #[test]
    fn a_follower_held_before_it_sets_off_goes_once_its_slot_has_moved_clear() {
        let mut s = Spacing::default();
        // As above: follower 2's way to its slot passes follower 1's flank.
        let one = body(1, -0.26, 0.59, 6.0, 0.0);
        let two = body(2, 0.0, 0.0, -158.0, 0.0);
        let slot = [(2, DVec2::new(-2.2, 0.5))];
        assert_eq!(s.step(0, &fleet(&[one, two]), &slot, &open()).len(), 1);
        assert_eq!(s.step(100, &fleet(&[one, two]), &slot, &open()).len(), 1);
        // The leader drove on and the slot swung to the other side: that way is clear.
        let moved = [(2, DVec2::new(0.5, -2.2))];
        assert!(s.step(200, &fleet(&[one, two]), &moved, &open()).is_empty());
        assert!(!s.held.contains_key(&2));
    }

    #[test]
    fn a_follower_is_held_off_a_slot_the_leader_stands_on() {
        let mut s = Spacing::default();
        let leader = body(0, 0.0, 0.0, 90.0, 0.0);
        // Follower 1 drives at the leader's flank, 1.2 m off, toward a slot 0.4 m from
        // the leader's centre (its control point 0.2 m ahead of its centre).
        let one = body(1, 1.2, 0.0, 180.0, 0.4);
        let bodies = [leader, one];
        let on_leader = [(1, DVec2::new(0.2, 0.0))];
        let told = s.hold_off_slots(&fleet(&bodies[1..]), &leader, &on_leader);
        assert_eq!(told.len(), 1);
        let t = told[0];
        assert!(t.id == 1 && t.order == Order::Hold && t.began);
        let x = 1.2 - 0.2 - stopping(0.4, 0.8);
        assert!((t.point.x - x).abs() < 1e-9 && t.point.y.abs() < 1e-9);
        // Still there next period: not a new hold.
        assert!(!s.hold_off_slots(&fleet(&bodies[1..]), &leader, &on_leader)[0].began);
        // A slot with room beside the leader is the follower's to make for.
        let beside = [(1, DVec2::new(0.6, 0.0))];
        assert!(s
            .hold_off_slots(&fleet(&bodies[1..]), &leader, &beside)
            .is_empty());
    }

    #[test]
    fn followers_converging_flank_to_flank_are_held() {
        // plaza-0.3-social-seed1324 at 203.5 s: follower 1 backs (heading 110°) and
        // follower 2 drives on (heading −95°), each tracking a slot that swings with the
        // leader. Each moves clear of where the other is (69° and 68° off their ways,
        // beyond both rings' beams), but they close on each other, and touched 1 s later.
        // Follower 2, the faster, would come within touching distance before it could
        // stop: it is held.
        let one = body(1, 24.594, 5.128, 110.0, -0.2);
        let two = body(2, 25.29, 5.33, -94.5, 0.285);
        assert!(free(&one, -1.0, &[two], FP).is_infinite());
        assert!(free(&two, 1.0, &[one], FP).is_infinite());
        let mut s = Spacing::default();
        let told = s.step(0, &fleet(&[one, two]), &[], &open());
        let held: Vec<u16> = told.iter().map(|t| t.id).collect();
        assert_eq!(held, vec![2], "{told:?}");
        // Follower 2 alone, driving away from a follower that stands: not held.
        let still = Body { v: 0.0, ..one };
        let away = Body {
            heading: 85f64.to_radians(),
            ..two
        };
        let mut s = Spacing::default();
        assert!(s.step(0, &fleet(&[still, away]), &[], &open()).is_empty());
    }

    #[test]
    fn followers_passing_each_other_with_room_are_not_held() {
        let mut s = Spacing::default();
        // Side by side 1 m apart (0.4 m between footprints), both driving on.
        let one = body(1, 0.0, 1.0, 0.0, 0.5);
        let two = body(2, 0.0, 0.0, 0.0, 0.5);
        assert!(s.step(0, &fleet(&[one, two]), &[], &open()).is_empty());
        // One behind the other in a line, 1 m apart: the ring's to keep.
        let one = body(1, 1.6, 0.0, 0.0, 0.5);
        assert!(s.step(100, &fleet(&[one, two]), &[], &open()).is_empty());
    }

    #[test]
    fn a_follower_sent_round_something_is_let_go_only_where_its_way_there_is_clear() {
        // plaza-0.3-social-seed1615 (a variant of 2026-12-06): follower 2 stands facing
        // west with follower 1 at its flank, 0.61 m apart, and is sent round a bin to a
        // point 0.8 m south of it.
        let two = Body::at(2, 13.04, 13.27, 170.2, 0.0);
        let one = Body::at(1, 13.274, 13.836, -174.8, 0.0);
        let slots = [(2, DVec2::new(11.0, 13.4))];
        let bodies = [one, two];
        // The leader 1 m on from the slot, facing west, standing.
        let led = Fleet {
            leader: Some(LeaderSnapshot {
                pose: Pose::new(10.0, 13.4, std::f32::consts::PI),
                v: 0.0,
                omega: 0.0,
            }),
            ..fleet(&bodies)
        };
        // Setting off west for its slot swings it clear …
        assert!(led.sets_off_to_goal_clear(&two, &slots));
        // … but its firmware drives the detour: it backs east, turning, into 1's flank.
        let sent = [(2, DVec2::new(13.06, 12.47))];
        let sent_round = Fleet { sent: &sent, ..led };
        assert!(!sent_round.sets_off_to_goal_clear(&two, &slots));
        let way = way_to_goal(&two, &slots, &sent_round).unwrap();
        assert!(
            (way.to_degrees() + 75.0).abs() < 10.0,
            "{}",
            way.to_degrees()
        );
    }
}
