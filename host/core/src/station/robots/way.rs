//! The leader's way blocked by its own follower. In the line the followers stand on the
//! path the leader drove; where the leader's route turns back along it (a way round
//! people in a crowd), the follower behind it stands in its way. The leader's ring (or,
//! for a follower beside its ring's view, the station's cap) holds the leader short of
//! the follower, and the follower's ring holds the follower short of its slot, which is
//! where the leader stands: in dense crowds the leader stood for long with a robot of
//! its own in front of it. The planner knows only that it makes no progress, and marks
//! a disc ahead of it on its route. The station knows which robot it is: held for
//! [`HELD_S`], the leader's route goes round that follower's footprint. The follower does
//! not step aside: a robot stepping aside beside another swings its body into it. But in
//! a crowd a way round one follower often runs into the other or into people, and the
//! robots stand packed. Held for [`BACK_AFTER_S`], the
//! follower in the way backs straight away from the leader by [`BACK_M`] (a straight
//! back swings nothing), where that way is clear of the site, the other robots and
//! everyone tracked.

use std::collections::BTreeMap;

use glam::DVec2;

use super::spacing::{self, Body, STANDING};
use crate::geometry::closest_on_segment;
use crate::geometry::map::Map;
use crate::perception::tracking::TrackView;

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
/// A follower that has stood in the leader's way this long backs away from it (a way
/// round it has been asked for twice), s.
const BACK_AFTER_S: f64 = 4.5;
/// How far its centre backs, m.
const BACK_M: f64 = 0.5;
/// A back ends after this, s.
const BACK_FOR_S: f64 = 3.0;
/// What the way back keeps beyond the footprints from the site and the other robots, m.
const BACK_MARGIN_M: f64 = 0.1;
/// A tracked person's disc, where they are and a second on, counts at least this and at
/// most [`PERSON_MAX_M`] in radius, m.
const PERSON_M: f64 = 0.3;
/// A group the tracker holds as one spans metres; the follower's ring, looking behind it,
/// stops it short of anyone there, m.
const PERSON_MAX_M: f64 = 0.5;
/// And from a person's disc: backing is moving, and a moving robot within 0.5 m of a
/// person's footprint intrudes on them (`docs/sim.md`), m.
const PERSON_ROOM_M: f64 = 0.5;
/// Points of the way back are checked this far apart, m.
const STEP_M: f64 = 0.05;

/// What [`Blocking::step`] needs of the fleet this period.
#[derive(Debug, Clone, Copy)]
pub struct Fleet<'a> {
    pub leader: Body,
    /// The leader's way ahead, from where it is.
    pub ahead: &'a [DVec2],
    /// The followers following.
    pub followers: &'a [Body],
    /// Every robot, the leader and the followers among them.
    pub robots: &'a [Body],
    pub footprint: f64,
    /// How far ahead of a follower's centre its control point is, m.
    pub offset: f64,
    /// The site as mapped (what was sensed is tracked, in `people`).
    pub site: &'a Map,
    /// What the station tracks, moving or not.
    pub people: &'a [TrackView],
}

/// Which followers hold the leader, and the followers backing away from it.
#[derive(Debug, Default)]
pub struct Blocking {
    held: BTreeMap<u16, Held>,
    backing: BTreeMap<u16, Back>,
}

/// A follower standing in the leader's way: since when it counts toward the next way
/// round it, and toward backing off it (each counts afresh once it was due), s.
#[derive(Debug, Clone, Copy)]
struct Held {
    round_from_s: f64,
    back_from_s: f64,
}

/// A follower backing away from the leader: where its control point makes for, since when.
#[derive(Debug, Clone, Copy)]
struct Back {
    point: DVec2,
    since_s: f64,
}

/// What [`Blocking::step`] decided this period.
#[derive(Debug, Default, PartialEq)]
pub struct Blocked {
    /// The disc (centre, radius) the leader's way is to go round.
    pub avoid: Option<(DVec2, f64)>,
    /// The followers backing away from the leader, with the point each makes for, and
    /// whether that just began.
    pub backs: Vec<(u16, DVec2, bool)>,
}

impl Blocking {
    /// One period at `now_s`: the disc the leader's way is to go round, once per hold,
    /// where a follower has stood in its way for [`HELD_S`]; and the follower that has
    /// stood there for [`BACK_AFTER_S`] backing away from it.
    pub fn step(&mut self, now_s: f64, fleet: &Fleet) -> Blocked {
        let blocking = in_the_way(fleet);
        self.held.retain(|id, _| blocking.contains(id));
        self.backing.retain(|_, b| now_s - b.since_s < BACK_FOR_S);
        let mut out = Blocked::default();
        for id in blocking {
            let Some(f) = fleet.followers.iter().find(|f| f.id == id) else {
                continue;
            };
            let held = self.held.entry(id).or_insert(Held {
                round_from_s: now_s,
                back_from_s: now_s,
            });
            if now_s - held.round_from_s >= HELD_S && out.avoid.is_none() {
                out.avoid = Some((f.position, fleet.footprint + MARGIN_M));
                // Once per hold: it counts afresh from now.
                held.round_from_s = now_s;
            }
            if now_s - held.back_from_s < BACK_AFTER_S || self.backing.contains_key(&id) {
                continue;
            }
            let Some((who, point)) = self.way_made(f, fleet) else {
                continue;
            };
            if who == id {
                if let Some(h) = self.held.get_mut(&id) {
                    h.back_from_s = now_s;
                }
            }
            self.backing.insert(
                who,
                Back {
                    point,
                    since_s: now_s,
                },
            );
            out.backs.push((who, point, true));
        }
        for (id, b) in &self.backing {
            if !out.backs.iter().any(|(i, _, _)| i == id) {
                out.backs.push((*id, b.point, false));
            }
        }
        out
    }

    /// Who moves to make way for follower `f` standing in the leader's way, and the point
    /// its control point makes for: `f` backing off the leader; where another follower
    /// not backing yet stands in that way, that one moving off `f` first (a line packed
    /// behind a leader that turned back).
    fn way_made(&self, f: &Body, fleet: &Fleet) -> Option<(u16, DVec2)> {
        match way_off(f, fleet.leader.position, fleet) {
            Ok(point) => Some((f.id, point)),
            Err(Some(other)) if other != fleet.leader.id && !self.backing.contains_key(&other) => {
                let o = fleet.followers.iter().find(|o| o.id == other)?;
                way_off(o, f.position, fleet)
                    .ok()
                    .map(|point| (other, point))
            }
            Err(_) => None,
        }
    }
}

/// Follower `f`'s way off straight along its heading (forward or back, whichever leads
/// away from `from`) by [`BACK_M`]: the point its control point makes for, if that way
/// keeps [`BACK_MARGIN_M`] from the site, the other robots (or comes no nearer one than
/// now) and everyone tracked; else the robot in the way, if a robot is.
fn way_off(f: &Body, from: DVec2, fleet: &Fleet) -> Result<DVec2, Option<u16>> {
    let heading = DVec2::from_angle(f.heading);
    let sign = if heading.dot(from - f.position) > 0.0 {
        -1.0
    } else {
        1.0
    };
    let fp = fleet.footprint;
    let steps = (BACK_M / STEP_M).ceil() as usize;
    for k in 1..=steps {
        let at = f.position + heading * (sign * k as f64 * STEP_M);
        // Nearer than that already, it must not come nearer.
        if let Some(r) = fleet.robots.iter().find(|r| {
            let least = (2.0 * fp + BACK_MARGIN_M).min(r.position.distance(f.position));
            r.id != f.id && r.position.distance(at) < least - 1e-6
        }) {
            return Err(Some(r.id));
        }
        let site = fleet.site.clearance(at, fp + BACK_MARGIN_M) >= fp + BACK_MARGIN_M;
        let people = fleet.people.iter().all(|m| {
            let reach = m.radius.clamp(PERSON_M, PERSON_MAX_M) + fp + PERSON_ROOM_M;
            m.position.distance(at) >= reach && m.at(1.0).distance(at) >= reach
        });
        if !site || !people {
            return Err(None);
        }
    }
    Ok(f.position + heading * (fleet.offset + sign * BACK_M))
}

/// The followers standing in front of the standing leader, within touching distance, on
/// its way ahead, and holding it: within its ring's view, or beside it where the station
/// stops it short of them ([`spacing::free`]): its route turning back past its line, a
/// leader facing 47° off a follower is held by the station for it.
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
                && holds(l, f, fleet.footprint)
                && near_way(fleet.ahead, f.position, on_way)
        })
        .map(|f| f.id)
        .collect()
}

/// Whether follower `f` holds the leader `l` going forward: its ring sees `f`, or its
/// footprint would come within the robots' keeping distance of `f`'s before it moved
/// [`NEAR_M`].
fn holds(l: &Body, f: &Body, footprint: f64) -> bool {
    l.sees(1.0, f.position) || spacing::free(l, 1.0, std::slice::from_ref(f), footprint) < NEAR_M
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

    fn fleet<'a>(leader: Body, followers: &'a [Body], site: &'a Map) -> Fleet<'a> {
        Fleet {
            leader,
            ahead: &WAY,
            followers,
            robots: followers,
            footprint: FP,
            offset: 0.2,
            site,
            people: &[],
        }
    }

    fn open() -> Map {
        Map::new(Vec::new())
    }

    #[test]
    fn a_follower_standing_in_the_standing_leaders_way_is_gone_round_after_a_while() {
        let site = open();
        let leader = body(0, 0.0, 0.0, 0.0, 0.0);
        // Follower 1 stands 0.65 m ahead, facing the leader.
        let one = [body(1, 0.65, 0.1, 180.0, 0.0)];
        let mut b = Blocking::default();
        assert_eq!(b.step(0.0, &fleet(leader, &one, &site)).avoid, None);
        assert_eq!(b.step(1.9, &fleet(leader, &one, &site)).avoid, None);
        let (at, r) = b
            .step(2.0, &fleet(leader, &one, &site))
            .avoid
            .expect("held 2 s");
        assert!(at == one[0].position && (r - (FP + MARGIN_M)).abs() < 1e-12);
        // Once per hold: not again the next period.
        assert_eq!(b.step(2.1, &fleet(leader, &one, &site)).avoid, None);
    }

    #[test]
    fn a_follower_beside_the_rings_view_that_the_station_stops_the_leader_for_is_gone_round() {
        let site = open();
        let leader = body(0, 0.0, 0.0, 0.0, 0.0);
        // 0.64 m off, 47° left of the leader's heading: out of its ring's view, but its
        // footprint would touch the follower's within 0.3 m (seed 1755's jam).
        let one = [body(1, 0.436, 0.468, 78.0, 0.0)];
        assert!(!leader.sees(1.0, one[0].position));
        let mut b = Blocking::default();
        b.step(0.0, &fleet(leader, &one, &site));
        let (at, _) = b
            .step(2.0, &fleet(leader, &one, &site))
            .avoid
            .expect("held 2 s by the station's cap");
        assert_eq!(at, one[0].position);
    }

    #[test]
    fn nobody_is_gone_round_while_either_drives_or_the_follower_is_off_the_way() {
        let site = open();
        let mut b = Blocking::default();
        let one = [body(1, 0.65, 0.1, 180.0, 0.0)];
        let driving = body(0, 0.0, 0.0, 0.0, 0.3);
        b.step(0.0, &fleet(driving, &one, &site));
        assert_eq!(
            b.step(3.0, &fleet(driving, &one, &site)),
            Blocked::default()
        );
        // Beside the leader, 60° off its heading: its ring does not hold it.
        let leader = body(0, 0.0, 0.0, 0.0, 0.0);
        let beside = [body(1, 0.4, 0.7, 180.0, 0.0)];
        b.step(4.0, &fleet(leader, &beside, &site));
        assert_eq!(
            b.step(7.0, &fleet(leader, &beside, &site)),
            Blocked::default()
        );
        // A follower still closing in is its ring's to stop.
        let closing = [body(1, 0.65, 0.1, 180.0, 0.2)];
        b.step(8.0, &fleet(leader, &closing, &site));
        assert_eq!(
            b.step(11.0, &fleet(leader, &closing, &site)),
            Blocked::default()
        );
    }

    #[test]
    fn a_follower_in_the_leaders_way_too_long_backs_straight_away_where_that_is_clear() {
        let site = open();
        let leader = body(0, 0.0, 0.0, 0.0, 0.0);
        // Facing the leader, 0.65 m ahead of it: backing takes it east.
        let one = [body(1, 0.65, 0.0, 180.0, 0.0)];
        let mut b = Blocking::default();
        for k in 0..45 {
            let told = b.step(k as f64 * 0.1, &fleet(leader, &one, &site));
            assert!(told.backs.is_empty(), "backed after {k} periods");
        }
        let told = b.step(4.5, &fleet(leader, &one, &site));
        let (id, point, began) = told.backs[0];
        assert!(id == 1 && began);
        // Its centre goes 0.5 m east, to 1.15 m; its control point (0.2 m ahead of it,
        // west) to 0.95 m.
        assert!(point.distance(DVec2::new(0.95, 0.0)) < 1e-9, "{point}");
        // Told every period until it ends.
        let told = b.step(4.6, &fleet(leader, &one, &site));
        assert_eq!(told.backs, vec![(1, point, false)]);
        assert!(b.step(7.6, &fleet(leader, &one, &site)).backs.is_empty());
        // With someone standing behind it, it does not back.
        let mut b = Blocking::default();
        let behind = [TrackView::person_at(7, (1.5, 0.1), (0.0, 0.0))];
        let with = Fleet {
            people: &behind,
            ..fleet(leader, &one, &site)
        };
        b.step(0.0, &with);
        assert!(b.step(4.5, &with).backs.is_empty());
    }

    #[test]
    fn a_follower_packed_behind_the_one_in_the_leaders_way_moves_off_first() {
        let site = open();
        let leader = body(0, 0.0, 0.0, 0.0, 0.0);
        // Follower 1 faces the leader; follower 2 stands right behind it, facing it too.
        let two = [
            body(1, 0.65, 0.0, 180.0, 0.0),
            body(2, 1.35, 0.0, 180.0, 0.0),
        ];
        let mut b = Blocking::default();
        b.step(0.0, &fleet(leader, &two, &site));
        let told = b.step(4.5, &fleet(leader, &two, &site));
        // Follower 2 backs 0.5 m east, off follower 1's way back.
        assert_eq!(told.backs.len(), 1);
        let (id, point, began) = told.backs[0];
        assert!(id == 2 && began);
        assert!(point.distance(DVec2::new(1.65, 0.0)) < 1e-9, "{point}");
        // Once it has, follower 1 backs too.
        let moved = [two[0], body(2, 1.85, 0.0, 180.0, 0.0)];
        let told = b.step(4.6, &fleet(leader, &moved, &site));
        assert!(told.backs.iter().any(|(id, _, began)| *id == 1 && *began));
    }
}
