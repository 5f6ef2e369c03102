//! The leader's way blocked by its own follower. In the line the followers stand on the
//! path the leader drove; where the leader's route turns back along it (a way round
//! people in a crowd), the follower behind it stands in its way. The leader's ring holds
//! the leader short of the follower, and the follower's ring holds the follower short of
//! its slot, which is where the leader stands: in dense crowds (0.2 persons/m², seeds
//! 301–332) the leader of the worlds that missed their goal stood 19 % of its standing
//! time with a robot of its own in front of it (`docs/results.md#movers`). The planner
//! knows only that it makes no progress, and marks a disc ahead of it on its route. The
//! station knows which robot it is: held for [`HELD_S`], the leader's route goes round
//! that follower's footprint. The follower does not move: a robot stepping aside beside
//! another swings its body into it (tried and measured, ibid.).

use std::collections::BTreeMap;

use glam::DVec2;

use super::spacing::{Body, STANDING};
use crate::geometry::closest_on_segment;

/// A follower whose footprint is within this of the leader's stands in front of it, m.
const NEAR_M: f64 = 0.3;
/// Its footprint within this of the leader's way ahead, over [`AHEAD_M`] of it, is on
/// the way, m.
const ON_WAY_M: f64 = 0.1;
const AHEAD_M: f64 = 1.5;
/// The two stood like this for this long: the way goes round the follower, s.
const HELD_S: f64 = 2.0;
/// What the way keeps from the follower's footprint beyond the planner's own clearance, m.
const MARGIN_M: f64 = 0.05;

/// What [`Blocking::step`] needs of the fleet this period.
#[derive(Debug, Clone, Copy)]
pub struct Fleet<'a> {
    pub leader: Body,
    /// The leader's way ahead, from where it is.
    pub ahead: &'a [DVec2],
    /// The followers following.
    pub followers: &'a [Body],
    pub footprint: f64,
}

/// Which follower holds the leader, and since when.
#[derive(Debug, Default)]
pub struct Blocking {
    held: BTreeMap<u16, f64>,
}

impl Blocking {
    /// One period at `now_s`: the disc (centre, radius) the leader's way is to go round,
    /// once per hold, where a follower has stood in its way for [`HELD_S`].
    pub fn step(&mut self, now_s: f64, fleet: &Fleet) -> Option<(DVec2, f64)> {
        let blocking = in_the_way(fleet);
        self.held.retain(|id, _| blocking.contains(id));
        let mut due = None;
        for id in blocking {
            let since = *self.held.entry(id).or_insert(now_s);
            if now_s - since >= HELD_S && due.is_none() {
                let f = fleet.followers.iter().find(|f| f.id == id)?;
                due = Some((f.position, fleet.footprint + MARGIN_M));
                // Once per hold: it counts afresh from now.
                self.held.insert(id, now_s);
            }
        }
        due
    }
}

/// The followers standing in front of the standing leader, within its ring's view and
/// touching distance, on its way ahead.
fn in_the_way(fleet: &Fleet) -> Vec<u16> {
    let l = &fleet.leader;
    if l.v.abs() > STANDING {
        return Vec::new();
    }
    let touching = 2.0 * fleet.footprint + NEAR_M;
    let on_way = 2.0 * fleet.footprint + ON_WAY_M;
    fleet
        .followers
        .iter()
        .filter(|f| {
            let to = f.position - l.position;
            f.v.abs() <= STANDING
                && to.length() < touching
                && l.sees(1.0, f.position)
                && near_way(fleet.ahead, f.position, on_way)
        })
        .map(|f| f.id)
        .collect()
}

/// Whether `p` is within `within` of the first [`AHEAD_M`] of `way`.
fn near_way(way: &[DVec2], p: DVec2, within: f64) -> bool {
    let mut along = 0.0;
    for w in way.windows(2) {
        if p.distance(closest_on_segment(p, w[0], w[1])) < within {
            return true;
        }
        along += w[0].distance(w[1]);
        if along >= AHEAD_M {
            break;
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    const FP: f64 = 0.3;

    fn body(id: u16, x: f64, y: f64, heading_deg: f64, v: f64) -> Body {
        Body::at(id, x, y, heading_deg, v)
    }

    const WAY: [DVec2; 2] = [DVec2::ZERO, DVec2::new(5.0, 0.0)];

    fn fleet<'a>(leader: Body, followers: &'a [Body]) -> Fleet<'a> {
        Fleet {
            leader,
            ahead: &WAY,
            followers,
            footprint: FP,
        }
    }

    #[test]
    fn a_follower_standing_in_the_standing_leaders_way_is_gone_round_after_a_while() {
        let leader = body(0, 0.0, 0.0, 0.0, 0.0);
        // Follower 1 stands 0.65 m ahead, facing the leader.
        let one = [body(1, 0.65, 0.1, 180.0, 0.0)];
        let mut b = Blocking::default();
        assert_eq!(b.step(0.0, &fleet(leader, &one)), None);
        assert_eq!(b.step(1.9, &fleet(leader, &one)), None);
        let (at, r) = b.step(2.0, &fleet(leader, &one)).expect("held 2 s");
        assert!(at == one[0].position && (r - (FP + MARGIN_M)).abs() < 1e-12);
        // Once per hold: not again the next period.
        assert_eq!(b.step(2.1, &fleet(leader, &one)), None);
    }

    #[test]
    fn nobody_is_gone_round_while_either_drives_or_the_follower_is_off_the_way() {
        let mut b = Blocking::default();
        let one = [body(1, 0.65, 0.1, 180.0, 0.0)];
        let driving = body(0, 0.0, 0.0, 0.0, 0.3);
        b.step(0.0, &fleet(driving, &one));
        assert_eq!(b.step(3.0, &fleet(driving, &one)), None);
        // Beside the leader, 60° off its heading: its ring does not hold it.
        let leader = body(0, 0.0, 0.0, 0.0, 0.0);
        let beside = [body(1, 0.4, 0.7, 180.0, 0.0)];
        b.step(4.0, &fleet(leader, &beside));
        assert_eq!(b.step(7.0, &fleet(leader, &beside)), None);
        // A follower still closing in is its ring's to stop.
        let closing = [body(1, 0.65, 0.1, 180.0, 0.2)];
        b.step(8.0, &fleet(leader, &closing));
        assert_eq!(b.step(11.0, &fleet(leader, &closing)), None);
    }
}
