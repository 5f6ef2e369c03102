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

use std::collections::BTreeMap;

use glam::DVec2;

/// The ring's outer beams, degrees off the way the robot drives (`hil-sim`'s ring): a
/// robot whose centre is within them is the ring's to keep from.
const RING_DEG: f64 = 40.0;
/// What a robot keeps from another beyond both footprints, m.
const KEEP_M: f64 = 0.05;
/// A held follower goes on where its way is this clear, m.
const CLEAR_M: f64 = 0.3;
/// What a stop allows for the station's delay: the telemetry's age and the command's
/// trip (one period each), s.
const LATENCY_S: f64 = 0.2;

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
    fn velocity(&self) -> DVec2 {
        DVec2::from_angle(self.heading) * self.v
    }
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
) -> impl Iterator<Item = (f64, f64)> + 'a {
    let dir = DVec2::from_angle(body.heading) * sign;
    let reach = 2.0 * footprint + KEEP_M;
    others
        .iter()
        .filter(|o| o.id != body.id)
        .filter_map(move |o| {
            let to = o.position - body.position;
            let along = to.dot(dir);
            let aside2 = to.length_squared() - along * along;
            let seen = along >= to.length() * RING_DEG.to_radians().cos();
            if along <= 0.0 || seen || aside2 >= reach * reach {
                return None;
            }
            let gap = (along - (reach * reach - aside2).sqrt()).max(0.0);
            Some((gap, o.velocity().dot(dir)))
        })
}

/// How far `body` can move along its heading (`sign` 1) or backward (`sign` −1) before
/// its footprint comes within `KEEP_M` of a robot its ring does not see, standing where
/// it is now.
pub fn free(body: &Body, sign: f64, others: &[Body], footprint: f64) -> f64 {
    on_way(body, sign, others, footprint)
        .map(|(gap, _)| gap)
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
        .map(|(gap, away)| speed_for(gap + yields(away, brake), brake))
        .fold(f64::INFINITY, f64::min)
}

/// The leader's commanded speed `v`, capped so that it stops short of every other robot.
pub fn cap_leader(leader: &Body, v: f64, others: &[Body], footprint: f64, brake: f64) -> f64 {
    let ahead = top_speed(leader, 1.0, others, footprint, brake);
    let behind = top_speed(leader, -1.0, others, footprint, brake);
    v.clamp(-behind, ahead)
}

/// The followers held because their way runs into another robot, by id: the way they
/// were moving (1 forward, −1 backing).
#[derive(Debug, Default)]
pub struct Spacing {
    held: BTreeMap<u16, f64>,
}

impl Spacing {
    /// One period: holds the followers whose way, at their speed, runs into another robot
    /// within their stopping distance, and lets go those whose way is clear. Returns each
    /// follower held now, the point to hold it at (`offset` ahead of its centre, where its
    /// control point is, plus what it needs to stop) and whether the hold just began.
    /// `robots`: every robot, followers included.
    pub fn step(
        &mut self,
        followers: &[Body],
        robots: &[Body],
        footprint: f64,
        offset: f64,
        brake: f64,
    ) -> Vec<(u16, DVec2, bool)> {
        let mut held = BTreeMap::new();
        let mut out = Vec::new();
        for f in followers {
            let was = self.held.get(&f.id).copied();
            let sign = was.unwrap_or(if f.v < 0.0 { -1.0 } else { 1.0 });
            let hold = match was {
                Some(_) => free(f, sign, robots, footprint) < CLEAR_M,
                None => f.v.abs() > top_speed(f, sign, robots, footprint, brake),
            };
            if !hold {
                continue;
            }
            held.insert(f.id, sign);
            let ahead = DVec2::from_angle(f.heading);
            let stop = stopping(f.v, brake) * f.v.signum();
            out.push((f.id, f.position + ahead * (offset + stop), was.is_none()));
        }
        self.held = held;
        out
    }

    /// Whether `follower` is held now.
    pub fn is_held(&self, follower: u16) -> bool {
        self.held.contains_key(&follower)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FP: f64 = 0.3;

    fn body(id: u16, x: f64, y: f64, heading_deg: f64, v: f64) -> Body {
        Body {
            id,
            position: DVec2::new(x, y),
            heading: heading_deg.to_radians(),
            v,
        }
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

    #[test]
    fn a_follower_crossing_to_another_ones_flank_is_held_until_it_moves_away() {
        let mut s = Spacing::default();
        // Follower 2 drives at 0.6 m/s past follower 1, which stands 0.7 m away at 60°:
        // 0.12 m on, their footprints would be 0.05 m apart.
        let a = 60f64.to_radians();
        let one = body(1, 0.7 * a.cos(), 0.7 * a.sin(), 180.0, 0.0);
        let two = body(2, 0.0, 0.0, 0.0, 0.6);
        let held = s.step(&[one, two], &[one, two], FP, 0.2, 0.8);
        assert_eq!(held.len(), 1);
        let (id, point, began) = held[0];
        assert!(id == 2 && began);
        // It is held at the point it can stop at, ahead of its control point.
        assert!((point.x - (0.2 + stopping(0.6, 0.8))).abs() < 1e-9 && point.y == 0.0);
        // Stopped, it stays held while follower 1 stands there...
        let two = Body { v: 0.0, ..two };
        assert_eq!(s.step(&[one, two], &[one, two], FP, 0.2, 0.8).len(), 1);
        assert!(s.is_held(2));
        // ...and goes on once follower 1 has moved off.
        let one = Body {
            position: DVec2::new(-1.0, 2.0),
            ..one
        };
        assert!(s.step(&[one, two], &[one, two], FP, 0.2, 0.8).is_empty());
        assert!(!s.is_held(2));
    }

    #[test]
    fn followers_passing_each_other_with_room_are_not_held() {
        let mut s = Spacing::default();
        // Side by side 1 m apart (0.4 m between footprints), both driving on.
        let one = body(1, 0.0, 1.0, 0.0, 0.5);
        let two = body(2, 0.0, 0.0, 0.0, 0.5);
        assert!(s.step(&[one, two], &[one, two], FP, 0.2, 0.8).is_empty());
        // One behind the other in a line, 1 m apart, at the same pace: room to stop.
        let one = body(1, 1.6, 0.0, 0.0, 0.5);
        assert!(s.step(&[one, two], &[one, two], FP, 0.2, 0.8).is_empty());
    }
}
