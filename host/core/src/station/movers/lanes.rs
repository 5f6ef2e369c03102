//! Passing behind someone who stopped. A person who stopped mid-way on their own (in the
//! open, away from the robots and from anyone else moving) will walk on the way they
//! were walking: [`LANE_M`] of it is marked ahead of them, so the route passes behind
//! them, as a driver passes behind a pedestrian. Someone who stops near the robots is
//! most likely letting them by, someone held up in a crowd walks on with it, and someone
//! who stops by a wall or a kerb has arrived: no lane for them. The tracker says which
//! way a track last walked; what that means is decided here. Lanes are given up where
//! they leave no route.

use std::collections::HashMap;

use glam::DVec2;

use crate::geometry::map::Map;
use crate::perception::tracking::{MarkTag, Motion, TrackView, MOVING_MPS};

/// How far of their way on is marked ahead of them, how much round it, in steps of this:
/// a stride and a half beyond a walker who sets off, m.
pub const LANE_M: f64 = 3.0;
pub const LANE_PAD_M: f64 = 0.3;
const LANE_STEP_M: f64 = 0.2;
/// Only for someone who stopped this far from every robot: one who stops nearer is most
/// likely letting the robots by, m.
const WAITING_M: f64 = 5.0;
/// Nor for one who stopped this near someone else moving: held up in a crowd, their way
/// on is the crowd's, and lanes of the held-up would wall a plaza off, m.
const HELD_UP_M: f64 = 3.0;
/// Nor for one who stopped within this of a wall or a kerb: they have arrived, m.
const OPEN_M: f64 = 2.0;
/// Someone who stops ahead of the leader within the fleet's breadth and this is in its
/// way, however near: one letting the robots by stops beside their way, m.
const IN_THE_WAY_M: f64 = 1.0;

/// What the station decided of a person who stopped.
#[derive(Debug, Clone, Copy)]
struct Stopped {
    /// They stopped on their own: their way on is marked.
    alone: bool,
    /// Given up: the robots found no way behind them.
    dropped: bool,
}

/// The people who stopped, by track.
#[derive(Debug, Default)]
pub struct Lanes {
    stopped: HashMap<u32, Stopped>,
}

/// What was round the tracks this scan.
#[derive(Debug, Clone, Copy)]
pub struct Round<'a> {
    pub map: &'a Map,
    /// Where the leader is and which way it faces (a unit vector).
    pub leader: (DVec2, DVec2),
    /// Every robot's position.
    pub fleet: &'a [DVec2],
}

impl Lanes {
    /// One scan: each track that stopped walking is judged once; the lane marks of those
    /// who stand still on their own.
    pub fn step(&mut self, tracks: &[TrackView], round: Round) -> Vec<(DVec2, MarkTag)> {
        self.stopped
            .retain(|id, _| tracks.iter().any(|t| t.id == *id));
        let moving: Vec<(u32, DVec2)> = tracks
            .iter()
            .filter(|t| t.motion == Motion::Moving)
            .map(|t| (t.id, t.position))
            .collect();
        let mut marks = Vec::new();
        for t in tracks {
            if t.motion == Motion::Moving && t.velocity.length() > MOVING_MPS {
                self.stopped.remove(&t.id);
                continue;
            }
            let Some(way) = t.way else {
                continue;
            };
            let s = *self.stopped.entry(t.id).or_insert_with(|| Stopped {
                alone: alone(round, &moving, t.id, t.position),
                dropped: false,
            });
            if t.motion == Motion::Still && t.person && s.alone && !s.dropped {
                marks.extend(lane(t, way));
            }
        }
        marks
    }

    /// Gives up the lanes marked now (no way behind the people who stopped): their tracks.
    pub fn drop_all(&mut self) -> Vec<u32> {
        let mut ids = Vec::new();
        for (id, s) in &mut self.stopped {
            if s.alone && !s.dropped {
                s.dropped = true;
                ids.push(*id);
            }
        }
        ids.sort_unstable();
        ids
    }
}

/// The marks of `t`'s way on.
fn lane(t: &TrackView, way: DVec2) -> impl Iterator<Item = (DVec2, MarkTag)> + '_ {
    let tag = MarkTag {
        track: t.id,
        pad: LANE_PAD_M,
        lane: true,
    };
    let steps = (LANE_M / LANE_STEP_M).round() as usize;
    (1..=steps).map(move |k| (t.position + way * (k as f64 * LANE_STEP_M), tag))
}

/// Whether track `id`, stopping at `at`, stopped mid-way for reasons of its own: in the
/// open ([`OPEN_M`]), far from every robot ([`WAITING_M`]) unless in the leader's way,
/// and far from anyone else moving ([`HELD_UP_M`]).
fn alone(round: Round, moving: &[(u32, DVec2)], id: u32, at: DVec2) -> bool {
    round.map.clearance(at, OPEN_M) >= OPEN_M
        && (round.fleet.iter().all(|r| r.distance(at) > WAITING_M) || in_the_way(round, at))
        && moving
            .iter()
            .all(|(other, p)| *other == id || p.distance(at) > HELD_UP_M)
}

/// Whether `at` lies ahead of the leader within the fleet's breadth (and
/// [`IN_THE_WAY_M`] more): someone who stops there is not letting the robots by.
fn in_the_way(round: Round, at: DVec2) -> bool {
    let (origin, ahead) = round.leader;
    let side = |p: DVec2| (p - origin).perp_dot(ahead).abs();
    let breadth = round.fleet.iter().map(|r| side(*r)).fold(0.0, f64::max);
    (at - origin).dot(ahead) > 0.0 && side(at) <= breadth + IN_THE_WAY_M
}

#[cfg(test)]
mod tests {
    use std::f64::consts::FRAC_PI_2;

    use super::*;
    use crate::geometry::Obstacle;
    use crate::perception::tracking::Tracker;

    fn person_at(at: DVec2) -> Vec<DVec2> {
        let toward = (-at).normalize();
        (-2..=2)
            .map(|k| at + DVec2::from_angle(toward.to_angle() + k as f64 * 0.35) * 0.25)
            .collect()
    }

    /// Someone walks 2.5 s along -y at 1.2 m/s to (10, 0) and stands there 8 s, scanned
    /// at 10 Hz by the leader at the origin facing `heading`, a robot at `fleet`: the
    /// lanes, and the lane marks of the last scan.
    fn lane_after_a_stop(map: &Map, heading: f64, fleet: DVec2) -> (Lanes, Vec<DVec2>) {
        let mut tracker = Tracker::new(0.8);
        let mut lanes = Lanes::default();
        let mut last = Vec::new();
        let round = Round {
            map,
            leader: (DVec2::ZERO, DVec2::from_angle(heading)),
            fleet: &[fleet],
        };
        for k in 0..=105 {
            let t = k as f64 * 0.1;
            let at = DVec2::new(10.0, (3.0 - 1.2 * t).max(0.0));
            tracker.observe(&person_at(at), DVec2::ZERO, k * 100);
            let views: Vec<TrackView> = tracker.views(k * 100).collect();
            last = lanes.step(&views, round);
        }
        (lanes, last.iter().map(|m| m.0).collect())
    }

    #[test]
    fn a_person_who_stops_in_the_open_leaves_their_way_on_marked() {
        let open = Map::new(vec![]);
        let (mut lanes, lane) = lane_after_a_stop(&open, 0.0, DVec2::ZERO);
        assert!(!lane.is_empty(), "no lane marked");
        // Ahead of them on the way they walked, up to LANE_M.
        let on_the_way = |p: &DVec2| (p.x - 10.0).abs() < 0.3 && p.y < 0.0 && p.y > -LANE_M - 0.1;
        assert!(lane.iter().all(on_the_way), "{lane:?}");
        // Given up (no route behind them), it is not marked again while they stand.
        assert_eq!(lanes.drop_all().len(), 1);
        assert!(lanes.drop_all().is_empty());
    }

    #[test]
    fn no_lane_for_a_person_who_stops_by_a_wall_or_near_the_robots() {
        let wall = Obstacle::Circle {
            center: DVec2::new(11.5, 0.0),
            radius: 0.5,
        };
        let (_, lane) = lane_after_a_stop(&Map::new(vec![wall]), 0.0, DVec2::ZERO);
        assert!(lane.is_empty(), "arrived by a wall: {lane:?}");
        // A robot 2.2 m from them, the leader facing past them: letting the robots by.
        let near = DVec2::new(8.0, -1.0);
        let (_, lane) = lane_after_a_stop(&Map::new(vec![]), FRAC_PI_2, near);
        assert!(lane.is_empty(), "stopped for the robots: {lane:?}");
    }

    #[test]
    fn a_person_who_stops_in_the_leaders_way_is_passed_behind_however_near() {
        let near = DVec2::new(8.0, -1.0);
        let (_, lane) = lane_after_a_stop(&Map::new(vec![]), 0.0, near);
        assert!(!lane.is_empty(), "stopped ahead of the leader: no lane");
    }
}
