//! Keeping to the side for people coming the other way. In a narrow way (an alley, a
//! passage between parked vans) someone walking toward the fleet passes the robots at
//! whatever offset their way has: an oblivious walker 0.6 m off the middle of a 3 m alley
//! grazes a line of robots standing in it. The scanner sees them seconds before they
//! meet, before the leader's pace holds it for them. The leader's route then keeps out
//! of their way, on the far side of the narrow way, with the personal space where the map
//! leaves room for it (as someone pushing a cart does), and each follower they are about
//! to pass steps square to their way until they are past it: a follower driving the
//! leader's path would come aside too late.

use std::collections::{BTreeMap, BTreeSet};

use glam::DVec2;

use crate::geometry::map::Map;
use crate::perception::tracking::TrackView;
use crate::planner::PlanPose;
use crate::station::robots::spacing::Body;

/// Someone slower than this is not coming along a way, m/s.
const WALKING: f64 = 0.5;
/// Their way is "the other way" within this of the leader's heading, reversed, degrees.
const ONCOMING_DEG: f64 = 30.0;
/// And they are ahead within this of the leader's heading, degrees.
const AHEAD_DEG: f64 = 30.0;
/// Nearer than this the leader cannot get aside in time any more; the yielding layer
/// holds it for them, m.
const NEAREST_M: f64 = 4.0;
/// Farther than this their way may still change: the route keeps aside once they are
/// within it, m.
const FARTHEST_M: f64 = 8.0;
/// The route leaves the leader's way this far ahead of it (it cannot step sideways), m.
const STEER_M: f64 = 2.0;
/// A way is narrow where it is less than this wide across the robot's heading (the map's
/// walls and kerbs to either side), m: wider, there is room to pass without a plan.
const NARROW_M: f64 = 5.0;
/// Over this much of its length, m.
const WAY_M: f64 = 3.0;
/// Discs along their way, this far apart, m.
const STEP_M: f64 = 0.5;
/// A follower steps aside for someone who will be abreast of it within this, s.
const SOON_S: f64 = 5.0;
/// Places to step to are tried this far apart, m.
const STEP_ASIDE_M: f64 = 0.05;
/// A step shorter than this is not worth taking, m.
const LEAST_STEP_M: f64 = 0.1;
/// What the place stepped to keeps from the map beyond the footprint, m.
const WALL_MARGIN_M: f64 = 0.1;
/// And from the other robots, beyond both footprints, m.
const ROBOT_MARGIN_M: f64 = 0.1;
/// Someone whose way runs through the leader and who reaches it sooner than this is
/// stood for (the pace): the route cannot take it aside in time, s.
const THROUGH_FROM_S: f64 = 1.5;
/// The leader keeps this much of the lane of someone coming from behind free ahead of
/// it, m.
const THROUGH_LANE_M: f64 = 6.0;
/// Someone's way runs through a follower where it comes this close to its footprint, m:
/// the track's uncertainty and a step's margin.
const THROUGH_M: f64 = 0.3;
/// A person's footprint at least, m.
const PERSON_RADIUS_M: f64 = 0.3;
/// A follower this close to its place aside is there, m.
const THERE_M: f64 = 0.1;
/// A step aside ends after this, whatever happens, ms.
const ASIDE_MS: u32 = 10_000;

/// What the fleet keeps.
#[derive(Debug, Clone, Copy)]
pub struct Space {
    pub footprint: f64,
    /// From a person's footprint, when passing, m.
    pub personal: f64,
}

/// The people already passed aside, by track, and the followers stepping aside for them.
#[derive(Debug, Default)]
pub struct Passing {
    planned: BTreeSet<u32>,
    aside: BTreeMap<u16, Aside>,
}

/// A follower stepping aside: where its centre goes, for whom, since when, and the way it
/// faced then (along the narrow way).
#[derive(Debug, Clone, Copy)]
struct Aside {
    to: DVec2,
    heading: DVec2,
    track: u32,
    since_ms: u32,
}

impl Passing {
    /// One period: for each mover newly seen coming the other way down a narrow way (on
    /// the `site`'s map: what was marked, a crowd standing, makes no alley) whose way
    /// passes the leader within the personal space, the discs (centre, radius) along that
    /// way, from them to `STEER_M` ahead of the leader, that the route should keep out of.
    /// Empty where there are none.
    pub fn step(
        &mut self,
        leader: PlanPose,
        (movers, crowded): (&[TrackView], bool),
        site: &Map,
        space: Space,
    ) -> Vec<(DVec2, f64)> {
        self.planned.retain(|id| movers.iter().any(|m| m.id == *id));
        let mut discs = Vec::new();
        for m in movers {
            if self.planned.contains(&m.id) {
                continue;
            }
            let found = match oncoming(leader, m, site, space) {
                Some(along) => {
                    // Along the narrow way, as the leader faces it: a filter's heading is
                    // off by several degrees, enough to bend the discs across an alley.
                    let way = -DVec2::from_angle(leader.heading);
                    let radius = m.radius + space.personal;
                    let steps = ((along - STEER_M) / STEP_M).floor().max(0.0) as usize;
                    (0..=steps)
                        .map(|k| (m.position + way * (k as f64 * STEP_M), radius))
                        .collect()
                }
                None if !crowded => through(leader, m, space),
                None => Vec::new(),
            };
            if !found.is_empty() {
                self.planned.insert(m.id);
                discs.extend(found);
            }
        }
        discs
    }

    /// One period: each follower whose place someone will pass within the personal space
    /// in the next `SOON_S`, coming along a narrow way (where it stands or between them:
    /// the end of the line may still be outside the alley), or whose place someone's way
    /// runs through anywhere, coming along the fleet's way from ahead or from behind
    /// (away from a crowd: in one, people steer round the robots and everyone comes
    /// along some way), steps aside, square to their way, as far as the map and the other
    /// robots let it (at least `LEAST_STEP_M`), until they are past it. Returns each
    /// follower stepping aside, the point for its control point (`offset` ahead of its
    /// centre: the point lies the step's way on) and whether the step just began.
    pub fn step_aside(
        &mut self,
        now_ms: u32,
        fleet: &Fleet,
        movers: &[TrackView],
        maps: Maps,
    ) -> Vec<(u16, DVec2, bool)> {
        let mut aside = BTreeMap::new();
        for f in fleet.followers {
            let kept = self.aside.get(&f.id).copied().filter(|a| {
                now_ms.wrapping_sub(a.since_ms) < ASIDE_MS
                    && movers
                        .iter()
                        .find(|m| m.id == a.track)
                        .is_some_and(|m| coming(f.position, a.heading, m).is_some())
            });
            let step = kept.or_else(|| {
                movers.iter().find_map(|m| {
                    let to = step_for(f, m, fleet, maps)?;
                    Some(Aside {
                        to,
                        heading: DVec2::from_angle(f.heading),
                        track: m.id,
                        since_ms: now_ms,
                    })
                })
            });
            if let Some(a) = step {
                aside.insert(f.id, a);
            }
        }
        let before = std::mem::replace(&mut self.aside, aside);
        self.aside
            .iter()
            .filter_map(|(id, a)| {
                let f = fleet.followers.iter().find(|f| f.id == *id)?;
                // There (or as good as): it holds its place, facing as it stands.
                let dir = if a.to.distance(f.position) > THERE_M {
                    (a.to - f.position).normalize()
                } else {
                    DVec2::from_angle(f.heading)
                };
                let began = !before.contains_key(id);
                Some((*id, a.to + dir * fleet.offset, began))
            })
            .collect()
    }
}

/// The maps a step aside is judged on.
#[derive(Debug, Clone, Copy)]
pub struct Maps<'a> {
    /// The site's: where a way is narrow (what was marked, a crowd standing, makes no
    /// alley).
    pub site: &'a Map,
    /// With what was sensed: where a robot may step.
    pub world: &'a Map,
}

/// What [`Passing::step_aside`] needs to know of the fleet this period.
#[derive(Debug, Clone, Copy)]
pub struct Fleet<'a> {
    pub followers: &'a [Body],
    /// Every robot, followers included.
    pub robots: &'a [Body],
    pub space: Space,
    /// How far ahead of a follower's centre its control point is, m.
    pub offset: f64,
    /// Movers crowd the fleet's way.
    pub crowded: bool,
}

/// How far `m` still walks before it is abreast of `at`, if it comes along `heading` (a
/// follower's, as it was when it stepped aside) from ahead against it, or from behind
/// with it, and gets there within `SOON_S`.
fn coming(at: DVec2, heading: DVec2, m: &TrackView) -> Option<f64> {
    let along = (m.position - at).dot(heading);
    let toward = if against(m, heading) {
        along
    } else if against(m, -heading) {
        -along
    } else {
        return None;
    };
    (toward > 0.0 && toward < m.velocity.length() * SOON_S).then_some(toward)
}

/// Where follower `f` steps to for `m`, if `m` will pass it too close down a narrow way and
/// the map and the other robots leave a step worth taking.
fn step_for(f: &Body, m: &TrackView, fleet: &Fleet, maps: Maps) -> Option<DVec2> {
    let heading = DVec2::from_angle(f.heading);
    coming(f.position, heading, m)?;
    let space = fleet.space;
    // Along the fleet's way, as the follower faces it: a filter's heading is off by
    // several degrees.
    let way = if against(m, heading) {
        -heading
    } else {
        heading
    };
    let from = f.position - m.position;
    let offset = way.perp_dot(from);
    let narrow = narrow_between(maps.site, f.position, m.position, heading);
    let want = if narrow {
        space.footprint + m.radius + space.personal
    } else if !fleet.crowded {
        space.footprint + m.radius.max(PERSON_RADIUS_M) + THROUGH_M
    } else {
        return None;
    };
    if offset.abs() >= want {
        return None;
    }
    let out = way.perp() * if offset >= 0.0 { 1.0 } else { -1.0 };
    let reach = 2.0 * space.footprint + ROBOT_MARGIN_M;
    let need = space.footprint + WALL_MARGIN_M;
    let fits = |p: DVec2| {
        maps.world.clearance(p, need) >= need
            && fleet
                .robots
                .iter()
                .filter(|r| r.id != f.id)
                .all(|r| r.position.distance(p) >= reach)
    };
    // (Less a hair, so that 0.75 m is 15 steps, not 16.)
    let steps = ((want - offset.abs()) / STEP_ASIDE_M - 1e-6).ceil() as usize;
    let reached = (1..=steps)
        .map(|k| f.position + out * (k as f64 * STEP_ASIDE_M))
        .take_while(|p| fits(*p))
        .last()?;
    (reached.distance(f.position) >= LEAST_STEP_M).then_some(reached)
}

/// Whether the way through `at` along `heading` is narrow on the `site`'s map: under
/// `NARROW_M` across at most points of the `WAY_M` around `at` (a gap between two benches
/// is no alley).
fn narrow(site: &Map, at: DVec2, heading: DVec2) -> bool {
    let side = heading.perp();
    let across = |p: DVec2| site.ray_cast(p, side, NARROW_M) + site.ray_cast(p, -side, NARROW_M);
    let half = (WAY_M / (2.0 * STEP_M)).round() as i32;
    let narrow = (-half..=half)
        .filter(|k| across(at + heading * (*k as f64 * STEP_M)) < NARROW_M)
        .count();
    narrow as i32 > half + half / 2
}

/// Whether `m` walks against `heading`, within `ONCOMING_DEG`.
fn against(m: &TrackView, heading: DVec2) -> bool {
    let speed = m.velocity.length();
    speed >= WALKING && (m.velocity / speed).dot(-heading) >= ONCOMING_DEG.to_radians().cos()
}

/// How far `m` walks before it is abreast of the leader, if it comes the other way down a
/// narrow way, ahead, and would pass within the personal space.
fn oncoming(leader: PlanPose, m: &TrackView, site: &Map, space: Space) -> Option<f64> {
    let heading = DVec2::from_angle(leader.heading);
    if !against(m, heading) {
        return None;
    }
    let way = -heading;
    let to = m.position - leader.position;
    let distance = to.length();
    let ahead = to.dot(heading) >= distance * AHEAD_DEG.to_radians().cos();
    if !(NEAREST_M..=FARTHEST_M).contains(&distance) || !ahead {
        return None;
    }
    // Their way passes the leader this far to the side.
    let back = leader.position - m.position;
    let offset = way.perp_dot(back).abs();
    if offset >= space.footprint + m.radius + space.personal {
        return None;
    }
    narrow_between(site, leader.position, m.position, heading).then(|| back.dot(way))
}

/// Discs along the way of `m`, coming along the leader's way from ahead or from behind,
/// where that way runs through the leader and they reach it in [`THROUGH_FROM_S`] to
/// `SOON_S`, from [`NEAREST_M`] off or farther: the route keeps out of their lane (from ahead, on their side of the leader
/// up to `STEER_M` before it; from behind, ahead of the leader where they ride on).
fn through(leader: PlanPose, m: &TrackView, space: Space) -> Vec<(DVec2, f64)> {
    let heading = DVec2::from_angle(leader.heading);
    let way = if against(m, heading) {
        -heading
    } else if against(m, -heading) {
        heading
    } else {
        return Vec::new();
    };
    let to_leader = (leader.position - m.position).dot(way);
    let reach_s = to_leader / m.velocity.length();
    let offset = way.perp_dot(leader.position - m.position).abs();
    let radius = m.radius.max(PERSON_RADIUS_M) + THROUGH_M;
    let far_enough = to_leader >= NEAREST_M && reach_s >= THROUGH_FROM_S;
    if !far_enough || reach_s > SOON_S || offset >= space.footprint + radius {
        return Vec::new();
    }
    let (from, to) = if way.dot(heading) < 0.0 {
        (0.0, to_leader - STEER_M)
    } else {
        (to_leader + STEER_M, to_leader + STEER_M + THROUGH_LANE_M)
    };
    let steps = ((to - from) / STEP_M).floor().max(0.0) as usize;
    (0..=steps)
        .map(|k| (m.position + way * (from + k as f64 * STEP_M), radius))
        .collect()
}

/// Whether the way from `a` to `b`, along `heading`, is narrow somewhere.
fn narrow_between(site: &Map, a: DVec2, b: DVec2, heading: DVec2) -> bool {
    let steps = (a.distance(b) / STEP_M).ceil().max(1.0) as usize;
    (0..=steps)
        .map(|k| a + (b - a) * (k as f64 / steps as f64))
        .any(|p| narrow(site, p, heading))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Obstacle;

    const SPACE: Space = Space {
        footprint: 0.3,
        personal: 0.8,
    };

    /// A 3 m alley from x = 15 to 35.
    fn alley() -> Map {
        Map::new(vec![
            Obstacle::rectangle(DVec2::new(15.0, 1.5), DVec2::new(35.0, 12.0)),
            Obstacle::rectangle(DVec2::new(15.0, -12.0), DVec2::new(35.0, -1.5)),
        ])
    }

    fn walker(id: u32, x: f64, y: f64, vx: f64, vy: f64) -> TrackView {
        TrackView {
            velocity_sigma: 0.1,
            ..TrackView::person_at(id, (x, y), (vx, vy))
        }
    }

    const LEADER: PlanPose = PlanPose {
        position: DVec2::new(12.0, 0.0),
        heading: 0.0,
    };

    #[test]
    fn someone_coming_down_the_alley_is_passed_aside_once() {
        let mut p = Passing::default();
        let w = walker(7, 19.0, 0.6, -1.2, 0.0);
        let discs = p.step(LEADER, (&[w], false), &alley(), SPACE);
        // From them to 2 m ahead of the leader, along their way, with the personal space.
        assert_eq!(discs.first(), Some(&(DVec2::new(19.0, 0.6), 1.05)));
        let last = discs.last().unwrap().0;
        assert!((last.x - 14.0).abs() <= STEP_M && last.y == 0.6, "{last}");
        // Planned once, not every period.
        assert!(p.step(LEADER, (&[w], false), &alley(), SPACE).is_empty());
    }

    #[test]
    fn nobody_is_passed_aside_in_the_open_or_going_the_same_way_or_wide_of_the_fleet() {
        let mut p = Passing::default();
        let open = Map::new(Vec::new());
        // In the open, coming at the leader but 6 s off: not yet.
        assert!(p
            .step(
                LEADER,
                (&[walker(1, 19.0, 0.6, -1.2, 0.0)], false),
                &open,
                SPACE
            )
            .is_empty());
        let alley = alley();
        let same_way = walker(2, 19.0, 0.6, 1.2, 0.0);
        let crossing = walker(3, 19.0, 0.6, 0.0, 1.2);
        let wide = walker(4, 19.0, 1.4, -1.2, 0.0);
        let near = walker(5, 15.0, 0.6, -1.2, 0.0);
        let standing = walker(6, 19.0, 0.6, -0.1, 0.0);
        let far = walker(7, 32.0, 0.6, -1.2, 0.0);
        for w in [same_way, crossing, wide, near, standing, far] {
            assert!(
                p.step(LEADER, (&[w], false), &alley, SPACE).is_empty(),
                "{}",
                w.id
            );
        }
    }

    fn both(map: &Map) -> Maps<'_> {
        Maps {
            site: map,
            world: map,
        }
    }

    fn follower(id: u16, x: f64, y: f64) -> Body {
        Body {
            id,
            position: DVec2::new(x, y),
            heading: 0.0,
            v: 0.4,
        }
    }

    #[test]
    fn a_follower_steps_to_the_far_side_of_the_alley_until_they_have_passed() {
        let mut p = Passing::default();
        let f = [follower(1, 20.0, 0.0)];
        let fleet = Fleet {
            followers: &f,
            robots: &f,
            space: SPACE,
            offset: 0.2,
            crowded: false,
        };
        let w = walker(7, 25.0, 0.6, -1.2, 0.0);
        // 0.6 m off its way, 4 s off: it steps 0.75 m to the other side (0.3 + 0.25 + 0.8
        // from their way), its control point led that way.
        let told = p.step_aside(0, &fleet, &[w], both(&alley()));
        assert_eq!(told.len(), 1);
        let (id, point, began) = told[0];
        assert!(id == 1 && began);
        assert!((point - DVec2::new(20.0, -0.95)).length() < 1e-9, "{point}");
        assert!(!p.step_aside(100, &fleet, &[w], both(&alley()))[0].2);
        // Past it: back to its slot.
        let past = walker(7, 19.0, 0.6, -1.2, 0.0);
        assert!(p
            .step_aside(200, &fleet, &[past], both(&alley()))
            .is_empty());
    }

    #[test]
    fn a_follower_steps_only_as_far_as_the_wall_and_the_robots_let_it() {
        let mut p = Passing::default();
        let w = walker(7, 25.0, 0.9, -1.2, 0.0);
        // Near the wall already: 0.05 m is not a step worth taking.
        let f = [follower(1, 20.0, -1.05)];
        let robots = f;
        let fleet = Fleet {
            followers: &f,
            robots: &robots,
            space: SPACE,
            offset: 0.2,
            crowded: false,
        };
        assert!(p.step_aside(0, &fleet, &[w], both(&alley())).is_empty());
        // A robot 0.9 m to its side: it steps 0.2 m, to 0.7 m from it.
        let f = [follower(1, 20.0, 0.0)];
        let robots = [f[0], follower(2, 20.0, -0.9)];
        let fleet = Fleet {
            followers: &f,
            robots: &robots,
            space: SPACE,
            offset: 0.2,
            crowded: false,
        };
        let (_, point, _) = p.step_aside(0, &fleet, &[w], both(&alley()))[0];
        assert!((point - DVec2::new(20.0, -0.4)).length() < 1e-9, "{point}");
        // Nobody steps aside in the open, whatever was marked there (a crowd standing
        // makes no alley).
        let mut p = Passing::default();
        let open = Map::new(Vec::new());
        let marked = Maps {
            site: &open,
            world: &alley(),
        };
        assert!(p.step_aside(0, &fleet, &[w], marked).is_empty());
        assert!(p
            .step_aside(0, &fleet, &[w], both(&Map::new(Vec::new())))
            .is_empty());
    }

    #[test]
    fn a_follower_steps_out_of_the_lane_of_someone_coming_from_behind_in_the_open() {
        let mut p = Passing::default();
        let f = [follower(1, 20.0, 0.0)];
        let fleet = Fleet {
            followers: &f,
            robots: &f,
            space: SPACE,
            offset: 0.2,
            crowded: false,
        };
        let open = Map::new(Vec::new());
        // A cyclist 12 m behind at 4 m/s, 0.2 m off its centre line: through it in 3 s.
        let cyclist = walker(8, 8.0, 0.2, 4.0, 0.0);
        let told = p.step_aside(0, &fleet, &[cyclist], both(&open));
        assert_eq!(told.len(), 1, "{told:?}");
        let (_, point, _) = told[0];
        // Square to their way, away from it, clear of their footprint.
        assert!(point.y < -0.5 && (point.x - 20.0).abs() < 0.3, "{point}");
        // In a crowd people come along every way: nobody steps aside in the open.
        let crowded = Fleet {
            crowded: true,
            ..fleet
        };
        let mut p = Passing::default();
        assert!(p
            .step_aside(0, &crowded, &[cyclist], both(&open))
            .is_empty());
    }
}
