//! The leader steps back out of the way of someone who does not see it. Away from a
//! crowd, the leader stands for a stranger crossing its way; but one seen late, at the
//! kerb a couple of metres off, can still walk into the leader standing where it braked
//! (fresh seeds 701–732: `crossing-oblivious-seed729`, walked into 1.1 s after it stood,
//! 0.13 m too far on; `standing-person-oblivious-seed707`, `movers-unmapped-seed719`, the
//! same). Where standing lets such a mover touch one of the robots within [`AHEAD_S`],
//! and backing along the leader's heading keeps every mover clear of them, the leader
//! backs at its reverse pace, and the followers with it (their slots are rigid to it):
//! the station checks the way behind against the site and the other robots (`spacing`),
//! and the rings guard it too.

use glam::DVec2;

use super::yielding::MIN_RADIUS_M;
use crate::geometry::map::Map;
use crate::perception::tracking::TrackView;

/// How far ahead a walker's way is judged, s.
pub const AHEAD_S: f64 = 2.5;
/// The rollout's step, s.
const STEP_S: f64 = 0.1;
/// Nobody is to come this close to the leader's footprint (their track's disc), m.
const CLEAR_M: f64 = 0.15;
/// The way behind the leader keeps this from the site beyond its footprint, m.
const SITE_MARGIN_M: f64 = 0.1;

/// The leader as the rollout needs it.
#[derive(Debug, Clone, Copy)]
pub struct Leader<'a> {
    pub position: DVec2,
    /// Where the followers are (they back with it).
    pub followers: &'a [DVec2],
    pub heading: f64,
    /// Its speed now (negative backing), m/s.
    pub v: f64,
    pub footprint: f64,
    /// How fast it backs, and how hard it changes speed, m/s, m/s².
    pub reverse: f64,
    pub accel: f64,
}

impl Leader<'_> {
    /// How far it has moved along its heading `t` seconds on, backing from its speed now
    /// (`back`) or braking to a stand.
    fn along(&self, t: f64, back: bool) -> f64 {
        let target = if back { -self.reverse } else { 0.0 };
        let (mut v, mut s, mut left) = (self.v, 0.0, t);
        while left > 1e-9 {
            let dt = left.min(STEP_S);
            let dv = (target - v).clamp(-self.accel * dt, self.accel * dt);
            s += (v + 0.5 * dv) * dt;
            v += dv;
            left -= dt;
        }
        s
    }

    /// The least gap between a robot's footprint and `m`'s disc over [`AHEAD_S`]: their
    /// footprint on their predicted way, `grown` by their position's uncertainty.
    fn least_gap(&self, m: &TrackView, back: bool, grown: bool) -> f64 {
        let sigma = if grown { m.position_sigma } else { 0.0 };
        let radius = m.radius.max(MIN_RADIUS_M) + sigma + self.footprint;
        let heading = DVec2::from_angle(self.heading);
        let robots = || std::iter::once(&self.position).chain(self.followers);
        let steps = (AHEAD_S / STEP_S).round() as usize;
        (1..=steps)
            .map(|k| {
                let t = k as f64 * STEP_S;
                let moved = heading * self.along(t, back);
                let at = m.at(t);
                robots()
                    .map(|r| (*r + moved).distance(at) - radius)
                    .fold(f64::INFINITY, f64::min)
            })
            .fold(f64::INFINITY, f64::min)
    }
}

/// Whether the leader should back now: standing lets one of `wary` (movers that may not
/// see the robots) touch a robot within [`AHEAD_S`], and backing keeps their footprint
/// clear of every robot, brings nobody else within [`CLEAR_M`] whom standing keeps
/// farther, and the site leaves the leader room behind.
pub fn should_back(leader: &Leader, movers: &[TrackView], wary: &[bool], site: &Map) -> bool {
    let mut threat = false;
    for (m, w) in movers.iter().zip(wary) {
        let stand = leader.least_gap(m, false, true);
        let threatens = *w && stand < CLEAR_M;
        // Backing must keep whoever threatens clear of the footprint on their predicted
        // way (touched while backing, the robot would be the one moving), and bring
        // nobody nearer than standing would, nor within reach.
        let clear = if threatens {
            leader.least_gap(m, true, false) >= 0.0
        } else {
            leader.least_gap(m, true, true) >= CLEAR_M.min(stand)
        };
        if !clear {
            return false;
        }
        threat |= threatens;
    }
    threat && way_behind_free(leader, site)
}

/// Whether the site leaves the leader's footprint room over the way it would back.
fn way_behind_free(leader: &Leader, site: &Map) -> bool {
    let reach = leader.reverse * AHEAD_S;
    let back = -DVec2::from_angle(leader.heading);
    let need = leader.footprint + SITE_MARGIN_M;
    (1..=4).all(|k| {
        let p = leader.position + back * (reach * k as f64 / 4.0);
        site.clearance(p, need) >= need
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn leader(v: f64) -> Leader<'static> {
        Leader {
            position: DVec2::ZERO,
            followers: &[],
            heading: 0.0,
            v,
            footprint: 0.3,
            reverse: 0.24,
            accel: 0.8,
        }
    }

    fn walker(at: (f64, f64), v: (f64, f64)) -> TrackView {
        TrackView::person_at(1, at, v)
    }

    fn open() -> Map {
        Map::new(Vec::new())
    }

    #[test]
    fn the_leader_backs_out_of_the_way_of_a_walker_who_does_not_see_it() {
        // Crossing from the right 0.4 m ahead of its centre, 3 m off, at 1.5 m/s: they
        // reach its line in 2 s, the leader's front within their reach.
        let crossing = walker((0.4, -3.0), (0.0, 1.5));
        assert!(should_back(&leader(0.0), &[crossing], &[true], &open()));
        // Someone known to steer round the robots is left to do so.
        assert!(!should_back(&leader(0.0), &[crossing], &[false], &open()));
        // Crossing 1.5 m ahead: standing clears them already.
        let ahead = walker((1.5, -3.0), (0.0, 1.5));
        assert!(!should_back(&leader(0.0), &[ahead], &[true], &open()));
        // Crossing right through its centre: backing 0.4 m would not clear them, so it
        // does not move (it is walked into standing).
        let through = walker((0.0, -3.0), (0.0, 1.5));
        assert!(!should_back(&leader(0.0), &[through], &[true], &open()));
    }

    #[test]
    fn the_leader_does_not_back_into_someone_or_into_the_site() {
        let crossing = walker((0.4, -3.0), (0.0, 1.5));
        // Someone standing just behind it.
        let behind = walker((-0.9, 0.0), (0.0, 0.0));
        let movers = [crossing, behind];
        assert!(!should_back(&leader(0.0), &movers, &[true, false], &open()));
        // A wall 0.5 m behind it.
        let wall = Map::new(vec![crate::geometry::Obstacle::Segment {
            a: DVec2::new(-0.5, -3.0),
            b: DVec2::new(-0.5, 3.0),
        }]);
        assert!(!should_back(&leader(0.0), &[crossing], &[true], &wall));
        // Someone standing just behind a follower, which backs with it.
        let behind_follower = walker((-2.4, 1.2), (0.0, 0.0));
        let followers = [DVec2::new(-1.5, 1.2)];
        let with = Leader {
            followers: &followers,
            ..leader(0.0)
        };
        let movers = [crossing, behind_follower];
        assert!(!should_back(&with, &movers, &[true, false], &open()));
        assert!(should_back(&with, &[crossing], &[true], &open()));
    }
}
