//! Going round what holds a follower. A follower drives straight at its reference; when
//! an obstacle sits on that straight way close ahead, its ring holds it there, for good
//! if its reference has passed the obstacle (a follower stood 21.6 m behind a bin for
//! 230 s). The station sees the way blocked on its map, picks a point beside the obstacle
//! that the map shows free and no other robot is near, and sends it (`Detour`) every
//! period until the straight way is clear again or the follower is there; then it makes
//! for its slot again.

use std::collections::BTreeMap;

use glam::DVec2;

use crate::geometry::closest_on_segment;
use crate::geometry::map::Map;

/// A follower at least this far from its reference (by its telemetry) may be sent round,
/// m: nearer, it is keeping its slot.
const FROM_ERROR_M: f64 = 0.4;
/// How far along the straight way an obstacle holds a follower, m.
const LOOK_M: f64 = 1.5;
/// The straight way is blocked where it comes this close to a surface beyond the
/// footprint, m (the ring slows a robot inside its footprint plus 0.2 m).
const BLOCKED_WITHIN_M: f64 = 0.05;
/// And clear again (a detour ends) where it keeps this much, m.
const CLEAR_BEYOND_M: f64 = 0.15;
/// What the way to a detour point keeps from every surface beyond the footprint, m, once
/// away from where the follower stands (it may stand closer).
const WAY_MARGIN_M: f64 = 0.15;
/// What a detour point keeps beyond the footprint, m.
const POINT_MARGIN_M: f64 = 0.25;
/// What a detour keeps from other robots, centre to centre beyond two footprints, m.
const ROBOT_MARGIN_M: f64 = 0.4;
/// A detour point may be this much farther from the reference than the follower, m.
const AWAY_M: f64 = 0.5;
/// A follower whose centre is this close to its detour point has got there, m (it steers
/// its control point, 0.2 m ahead of its centre, onto the point).
const THERE_M: f64 = 0.5;
/// A detour is given up after this long (then looked at afresh), ms.
const GIVE_UP_MS: u32 = 10_000;
/// Candidate points: these bearings off the straight way, both sides, at these distances
/// (the follower slows in a point's last 0.35 m: a far one is passed at pace).
const BEARINGS_DEG: [f64; 9] = [20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0, 100.0];
const DISTANCES_M: [f64; 4] = [0.8, 1.2, 1.6, 2.0];
/// Where a follower stands close to a surface, a way may keep only what it has for this
/// long, m.
const NEAR_M: f64 = 0.3;
/// Points on a way are checked this far apart, m.
const STEP_M: f64 = 0.05;

/// What the station knows of one follower this period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Follower {
    pub id: u16,
    pub position: DVec2,
    /// Its reference point, as its control core makes it.
    pub reference: DVec2,
    /// Its distance to the reference, by its telemetry, m.
    pub error: f64,
}

#[derive(Debug, Clone, Copy)]
struct Active {
    point: DVec2,
    since_ms: u32,
}

/// The detours under way, by follower.
#[derive(Debug, Default)]
pub struct Detours {
    active: BTreeMap<u16, Active>,
}

impl Detours {
    /// One period: ends the detours that are done, starts the ones needed. Returns every
    /// follower that has one now, with its point, and whether it just began. `robots`:
    /// every robot's position, followers included.
    pub fn step(
        &mut self,
        now_ms: u32,
        map: &Map,
        footprint: f64,
        followers: &[Follower],
        robots: &[(u16, DVec2)],
    ) -> Vec<(u16, DVec2, bool)> {
        let mut out = Vec::new();
        let mut still = BTreeMap::new();
        for f in followers {
            let kept = self.active.get(&f.id).copied().filter(|a| {
                now_ms.wrapping_sub(a.since_ms) < GIVE_UP_MS
                    && f.position.distance(a.point) > THERE_M
                    && f.error >= FROM_ERROR_M
                    && blocked_within(map, f.position, f.reference, footprint + CLEAR_BEYOND_M)
            });
            let (active, new) = match kept {
                Some(a) => (a, false),
                None => {
                    let Some(point) = self.way_round(map, footprint, f, robots) else {
                        continue;
                    };
                    let a = Active {
                        point,
                        since_ms: now_ms,
                    };
                    (a, true)
                }
            };
            still.insert(f.id, active);
            out.push((f.id, active.point, new));
        }
        self.active = still;
        out
    }

    /// Whether `follower` is being sent round now.
    pub fn is_active(&self, follower: u16) -> bool {
        self.active.contains_key(&follower)
    }

    /// A point to go round by, if the follower is held and one is free.
    fn way_round(
        &self,
        map: &Map,
        footprint: f64,
        f: &Follower,
        robots: &[(u16, DVec2)],
    ) -> Option<DVec2> {
        let need = footprint + BLOCKED_WITHIN_M;
        if f.error < FROM_ERROR_M || !blocked_within(map, f.position, f.reference, need) {
            return None;
        }
        let ahead = f.reference - f.position;
        let length = ahead.length();
        if length < 1e-6 {
            return None;
        }
        let ahead = ahead / length;
        let here = map.clearance(f.position, footprint + WAY_MARGIN_M);
        let others: Vec<DVec2> = robots
            .iter()
            .filter(|(id, _)| *id != f.id)
            .map(|(_, p)| *p)
            .collect();
        let apart = 2.0 * footprint + ROBOT_MARGIN_M;
        let candidates = BEARINGS_DEG.iter().flat_map(|deg| {
            [1.0, -1.0].map(|side: f64| DVec2::from_angle(side * deg.to_radians()).rotate(ahead))
        });
        candidates
            .flat_map(|dir| DISTANCES_M.map(|d| f.position + dir * d))
            .filter(|p| {
                // Not much farther from the reference (a bin right ahead of a near
                // reference is gone round sideways), free, and reached without coming
                // closer to a surface than the follower stands now (or than the margin,
                // away from it).
                p.distance(f.reference) < length + AWAY_M
                    && map.clearance(*p, footprint + POINT_MARGIN_M) >= footprint + POINT_MARGIN_M
                    && way_keeps(map, f.position, *p, here, footprint + WAY_MARGIN_M)
                    && others.iter().all(|q| {
                        q.distance(*p) >= apart
                            && q.distance(closest_on_segment(*q, f.position, *p))
                                >= apart.min(q.distance(f.position))
                    })
            })
            .map(|p| {
                // The shortest way round, and one whose way on is clear before one that
                // would need another detour.
                let on = if blocked_within(map, p, f.reference, need) {
                    2.0 * LOOK_M
                } else {
                    0.0
                };
                (p.distance(f.position) + p.distance(f.reference) + on, p)
            })
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, p)| p)
    }
}

/// Points from `a` toward `b`, `STEP_M` apart, at most `length` along, `a` excluded.
fn way(a: DVec2, b: DVec2, length: f64) -> impl Iterator<Item = DVec2> {
    let d = b - a;
    let len = d.length().min(length);
    let dir = d.normalize_or_zero();
    let steps = (len / STEP_M).ceil() as usize;
    (1..=steps).map(move |i| a + dir * (len * i as f64 / steps as f64))
}

/// Whether the straight way from `from` toward `to`, within `LOOK_M`, comes closer than
/// `need` to a surface (where it starts aside, the follower may stand close).
fn blocked_within(map: &Map, from: DVec2, to: DVec2, need: f64) -> bool {
    let here = map.clearance(from, need);
    way(from, to, LOOK_M).any(|p| {
        let c = map.clearance(p, need);
        c < need && (c < here - 1e-3 || p.distance(from) > NEAR_M)
    })
}

/// Whether the way from `from` to `to` keeps `need` from every surface, or, near `from`,
/// at least what `from` has (`here`).
fn way_keeps(map: &Map, from: DVec2, to: DVec2, here: f64, need: f64) -> bool {
    way(from, to, f64::INFINITY).all(|p| {
        let c = map.clearance(p, need);
        c >= need || (p.distance(from) <= NEAR_M && c >= here - 1e-3)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Obstacle;

    const FP: f64 = 0.3;

    fn bin_at(x: f64, y: f64) -> Map {
        Map::new(vec![Obstacle::Circle {
            center: DVec2::new(x, y),
            radius: 0.3,
        }])
    }

    fn held(error: f64) -> Follower {
        Follower {
            id: 1,
            position: DVec2::ZERO,
            reference: DVec2::new(3.0, 0.0),
            error,
        }
    }

    fn robots(f: &Follower) -> Vec<(u16, DVec2)> {
        vec![(0, DVec2::new(6.0, 0.0)), (f.id, f.position)]
    }

    #[test]
    fn a_follower_held_by_a_bin_on_its_way_is_sent_round_on_the_free_side() {
        // The bin sits on the way, a little to the left of it.
        let map = bin_at(0.9, 0.1);
        let f = held(3.0);
        let mut d = Detours::default();
        let out = d.step(0, &map, FP, &[f], &robots(&f));
        let [(1, point, true)] = out[..] else {
            panic!("{out:?}")
        };
        assert!(point.y < -0.3, "round the right, the freer side: {point}");
        assert!(map.clearance(point, 1.0) >= FP + POINT_MARGIN_M);
        assert!(way(f.position, point, 10.0).all(|p| map.clearance(p, 1.0) >= FP + WAY_MARGIN_M));
        assert!(point.distance(f.reference) < f.position.distance(f.reference));

        // Renewed while it holds, the same point; not new.
        let out = d.step(100, &map, FP, &[f], &robots(&f));
        assert_eq!(out, vec![(1, point, false)]);

        // Past the bin, the way to the reference is clear: the detour ends.
        let past = Follower {
            position: DVec2::new(1.2, -0.8),
            ..f
        };
        assert_eq!(d.step(200, &map, FP, &[past], &robots(&past)), vec![]);
    }

    #[test]
    fn no_detour_where_the_way_is_clear_or_the_follower_keeps_its_slot() {
        let mut d = Detours::default();
        // A bin beside the way, not on it.
        let map = bin_at(1.5, 1.2);
        assert_eq!(d.step(0, &map, FP, &[held(3.0)], &[]), vec![]);
        // A bin on the way, but the follower is near its reference (keeping its slot).
        let map = bin_at(0.9, 0.0);
        let near = Follower {
            reference: DVec2::new(0.3, 0.0),
            ..held(0.3)
        };
        assert_eq!(d.step(0, &map, FP, &[near], &[]), vec![]);
    }

    #[test]
    fn a_detour_keeps_clear_of_the_other_robots() {
        let map = bin_at(0.9, 0.1);
        let f = held(3.0);
        // A neighbour stands on the freer side.
        let neighbour = DVec2::new(0.8, -1.0);
        let mut d = Detours::default();
        let out = d.step(0, &map, FP, &[f], &[(2, neighbour), (1, f.position)]);
        assert_eq!(out.len(), 1, "{out:?}");
        for (_, point, _) in &out {
            assert!(
                point.distance(neighbour) >= 2.0 * FP + ROBOT_MARGIN_M,
                "{point}"
            );
            assert!(
                neighbour.distance(closest_on_segment(neighbour, f.position, *point))
                    >= 2.0 * FP + ROBOT_MARGIN_M,
                "{point}"
            );
        }
    }

    #[test]
    fn a_detour_is_given_up_after_a_while_and_looked_at_afresh() {
        let map = bin_at(0.9, 0.1);
        let f = held(3.0);
        let mut d = Detours::default();
        assert!(d.step(0, &map, FP, &[f], &robots(&f))[0].2);
        assert!(!d.step(GIVE_UP_MS - 100, &map, FP, &[f], &robots(&f))[0].2);
        assert!(d.step(GIVE_UP_MS, &map, FP, &[f], &robots(&f))[0].2);
    }
}
