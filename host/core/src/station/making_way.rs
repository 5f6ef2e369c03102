//! A follower standing on the leader's way steps off it. In the line the followers stand
//! on the path the leader drove; where the leader's way turns back along it (a route
//! round a crowd that blocks the street, say), the follower behind it stands in its way.
//! The leader's ring stops it short of the follower, and the follower's ring stops it
//! short of the leader, whose place is its slot: in dense crowds (0.2 persons/m²) the
//! leader stood with a follower in front of it for up to half of its 300 s
//! (`docs/results.md#movers`). The station sees both: the follower nearest on the
//! leader's way ahead steps square off that way, to the side it stands on (or the other,
//! where the map or a robot leaves no room), and holds there until the leader is past it.

use std::collections::btree_map::{BTreeMap, Entry};

use glam::DVec2;

use super::spacing::Body;
use crate::map::Map;

/// How far along its way ahead the leader looks for a follower standing on it, m.
const AHEAD_M: f64 = 1.5;
/// The way is looked at in steps of this, m.
const STEP_M: f64 = 0.1;
/// What the leader keeps from a follower beyond both footprints when it passes, m.
const KEEP_M: f64 = 0.1;
/// What the place stepped to keeps from the map beyond the footprint, m.
const MAP_MARGIN_M: f64 = 0.05;
/// A robot slower than this stands, m/s: a follower steps off the way only where both
/// stand, the leader's ring holding it short of the follower.
const STANDING: f64 = 0.05;
/// A step off the way ends after this, whatever happens, ms.
const ASIDE_MS: u32 = 10_000;
/// It ends too once the leader is this far off (it went elsewhere), m.
const GONE_M: f64 = 3.0;

/// A follower stepping off the leader's way: the point (for its centre) it makes for.
#[derive(Debug, Clone, Copy)]
struct Aside {
    centre: DVec2,
    since_ms: u32,
}

/// One follower told to step off the way this period: the point for its control point,
/// and whether that just began.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Told {
    pub id: u16,
    pub point: DVec2,
    pub began: bool,
}

/// What [`MakingWay::step`] needs to know of the fleet this period.
#[derive(Debug, Clone, Copy)]
pub struct Fleet<'a> {
    pub leader: Body,
    /// The leader's way ahead, from where it is.
    pub ahead: &'a [DVec2],
    /// The followers following, and every robot (followers and leader).
    pub followers: &'a [Body],
    pub robots: &'a [Body],
    pub footprint: f64,
    /// How far ahead of a follower's centre its control point is, m.
    pub offset: f64,
}

/// The followers stepping off the leader's way.
#[derive(Debug, Default)]
pub struct MakingWay {
    aside: BTreeMap<u16, Aside>,
}

impl MakingWay {
    /// One period: the followers off the way stay there until the leader is past them;
    /// the one standing nearest on its way steps off it.
    pub fn step(&mut self, now_ms: u32, fleet: &Fleet, map: &Map) -> Vec<Told> {
        let leader = &fleet.leader;
        let heading = DVec2::from_angle(leader.heading);
        self.aside.retain(|id, a| {
            fleet.followers.iter().any(|f| {
                let to = f.position - leader.position;
                f.id == *id
                    && now_ms.wrapping_sub(a.since_ms) < ASIDE_MS
                    && to.dot(heading) > 0.0
                    && to.length() < GONE_M
            })
        });
        let mut began = None;
        let blocked = leader.v.abs() <= STANDING;
        if let Some((id, centre)) = off_the_way(fleet, map).filter(|_| blocked) {
            if let Entry::Vacant(e) = self.aside.entry(id) {
                e.insert(Aside {
                    centre,
                    since_ms: now_ms,
                });
                began = Some(id);
            }
        }
        self.aside
            .iter()
            .filter_map(|(id, a)| {
                let f = fleet.followers.iter().find(|f| f.id == *id)?;
                // The control point, ahead of the centre on its way to the place.
                let dir = (a.centre - f.position)
                    .try_normalize()
                    .unwrap_or(DVec2::from_angle(f.heading));
                Some(Told {
                    id: *id,
                    point: a.centre + dir * fleet.offset,
                    began: began == Some(*id),
                })
            })
            .collect()
    }
}

/// Points along `way` every [`STEP_M`] up to [`AHEAD_M`], each with the way's direction
/// there.
fn samples(way: &[DVec2]) -> Vec<(DVec2, DVec2)> {
    let mut out = Vec::new();
    let mut along = 0.0;
    for w in way.windows(2) {
        let (a, b) = (w[0], w[1]);
        let Some(dir) = (b - a).try_normalize() else {
            continue;
        };
        let len = a.distance(b);
        let mut s = 0.0;
        while s < len && along + s <= AHEAD_M {
            out.push((a + dir * s, dir));
            s += STEP_M;
        }
        along += len;
        if along > AHEAD_M {
            break;
        }
    }
    out
}

/// The follower standing nearest on the leader's way ahead (its footprint within
/// [`KEEP_M`] of the leader's there), and the centre it steps to: square off the way at
/// the nearest point, by as much as the leader needs to pass, on the side it stands on or
/// else the other, where the map and the other robots leave room.
fn off_the_way(fleet: &Fleet, map: &Map) -> Option<(u16, DVec2)> {
    let way = samples(fleet.ahead);
    let reach = 2.0 * fleet.footprint + KEEP_M;
    let (_, f) = fleet
        .followers
        .iter()
        .filter(|f| f.v.abs() <= STANDING)
        .filter_map(|f| {
            let k = way
                .iter()
                .position(|(p, _)| p.distance(f.position) < reach)?;
            Some((k, f))
        })
        .min_by_key(|(k, _)| *k)?;
    // Square off the way where it passes nearest.
    let (p, dir) = *way.iter().min_by(|a, b| {
        a.0.distance(f.position)
            .total_cmp(&b.0.distance(f.position))
    })?;
    let normal = dir.perp();
    let side = if (f.position - p).dot(normal) >= 0.0 {
        1.0
    } else {
        -1.0
    };
    let need = fleet.footprint + MAP_MARGIN_M;
    [side, -side].into_iter().find_map(|s| {
        let centre = p + normal * s * reach;
        let off_way = way.iter().all(|(q, _)| q.distance(centre) >= reach - 1e-9);
        let free_of_robots = fleet
            .robots
            .iter()
            .filter(|r| r.id != f.id)
            .all(|r| r.position.distance(centre) >= reach);
        (off_way && free_of_robots && map.clearance(centre, need) >= need).then_some((f.id, centre))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Obstacle;

    const FP: f64 = 0.3;

    fn body(id: u16, x: f64, y: f64, heading_deg: f64, v: f64) -> Body {
        Body {
            id,
            position: DVec2::new(x, y),
            heading: heading_deg.to_radians(),
            v,
        }
    }

    /// The leader at the origin facing +x, its way straight on along +x.
    fn fleet<'a>(leader: Body, followers: &'a [Body], robots: &'a [Body]) -> Fleet<'a> {
        const WAY: [DVec2; 2] = [DVec2::ZERO, DVec2::new(5.0, 0.0)];
        Fleet {
            leader,
            ahead: &WAY,
            followers,
            robots,
            footprint: FP,
            offset: 0.2,
        }
    }

    #[test]
    fn a_follower_standing_on_the_leaders_way_steps_off_it_to_its_own_side() {
        let leader = body(0, 0.0, 0.0, 0.0, 0.0);
        // Follower 1 stands 0.7 m ahead, 0.1 m left of the way, facing the leader.
        let one = body(1, 0.7, 0.1, 180.0, 0.0);
        let robots = [leader, one];
        let mut m = MakingWay::default();
        let told = m.step(0, &fleet(leader, &[one], &robots), &Map::new(Vec::new()));
        assert_eq!(told.len(), 1);
        assert!(told[0].id == 1 && told[0].began);
        // Square off the way on its left, as far as the leader needs to pass.
        let centre = m.aside[&1].centre;
        assert!(
            (centre - DVec2::new(0.7, 2.0 * FP + KEEP_M)).length() < 1e-9,
            "{centre}"
        );
        // It holds there while the leader comes by, and is let go once it is past.
        let moved = body(1, centre.x, centre.y, 90.0, 0.0);
        let driving = body(0, 0.3, 0.0, 0.0, 0.4);
        let told = m.step(
            100,
            &fleet(driving, &[moved], &[driving, moved]),
            &Map::new(Vec::new()),
        );
        assert!(told.len() == 1 && !told[0].began);
        let past = body(0, 1.0, 0.0, 0.0, 0.4);
        assert!(m
            .step(
                200,
                &fleet(past, &[moved], &[past, moved]),
                &Map::new(Vec::new())
            )
            .is_empty());
    }

    #[test]
    fn it_steps_to_the_other_side_where_a_wall_stands_and_not_while_the_leader_drives() {
        let leader = body(0, 0.0, 0.0, 0.0, 0.0);
        let one = body(1, 0.7, 0.1, 180.0, 0.0);
        let robots = [leader, one];
        let wall = Map::new(vec![Obstacle::Circle {
            center: DVec2::new(0.7, 0.9),
            radius: 0.2,
        }]);
        let mut m = MakingWay::default();
        assert_eq!(m.step(0, &fleet(leader, &[one], &robots), &wall).len(), 1);
        assert!(m.aside[&1].centre.y < 0.0);
        // A leader still driving is not held by it yet: its ring slows it first.
        let driving = body(0, 0.0, 0.0, 0.0, 0.3);
        let mut m = MakingWay::default();
        assert!(m
            .step(0, &fleet(driving, &[one], &[driving, one]), &wall)
            .is_empty());
        // Nor does a follower beside the way, with room for the leader to pass.
        let beside = body(1, 0.7, 0.8, 180.0, 0.0);
        assert!(m
            .step(0, &fleet(leader, &[beside], &[leader, beside]), &wall)
            .is_empty());
    }
}
