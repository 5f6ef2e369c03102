//! The leader's pace among what moves, from one ranking. The planner fixes the path; this
//! room chooses only the speed along it (path–velocity decomposition, as Nav2's DWB
//! chooses among sampled trajectories with critics). Each period a few candidate speeds
//! within the leader's limits ([`Candidate`]: backing off, standing, creeping, slower
//! shares of its pace, its pace, hurrying) are each rolled out once, with the command
//! lag, by the fleet's one forward model (`station::model`: the firmware's own law and
//! limits for every follower), against every mover's predicted disc
//! (`movers::prediction`), and ranked by one ordered key ([`Key`]):
//!
//! 1. the site: backing must keep the leader off what is mapped (ahead, the route is
//!    known free);
//! 2. **strikes**: possible contacts (each mover's disc grown by its track's
//!    uncertainty) where a robot would drive into someone: its velocity toward them over
//!    0.1 m/s and larger than theirs toward it, at any instant of the contact (ISO 3691-4:
//!    a driverless vehicle must not strike a person); summed by the robot's closing
//!    speed, so that where none escapes them the slowest wins;
//! 3. **likely contacts while moving**: contacts on each mover's mean way (their
//!    footprint on their track's prediction meeting a robot's) with a robot moving in them, that moving
//!    makes worse than standing would, summed by the robot's top speed in them (passive
//!    safety: be at rest when a contact cannot be escaped; ISO/TS 15066: what cannot be
//!    escaped is judged by its power);
//! 4. **likely contacts** at all: someone who would walk into the fleet standing is
//!    cleared by going on, hurrying or backing, where that avoids them;
//! 5. **possible contacts while moving**, as 3 on the grown discs, summed by how deep
//!    into the touching distance they come (going on clears someone's way sooner);
//! 6. **intrusion**: passing within about 0.5 m of someone's footprint faster than
//!    [`SLOW_SHARE`] of the pace where standing would leave them more room;
//! 7. **room owed**: passing within someone's personal space faster than
//!    `[yielding] passing_share` where standing would leave them more;
//! 8. then speed, up to the route's pace (hurrying only ever wins on the terms above).
//!
//! Someone the robots can count on to steer round them is predicted only as far as they
//! cannot (`Mover::trust_after_s`); a contact "moving makes worse" is any contact for
//! someone who may not see the robots.
//!
//! Hysteresis against flapping: a candidate faster than the one chosen last must keep
//! [`RESUME_MARGIN_M`] more room, and the one chosen last may keep [`KEEP_MARGIN_M`] less.

use glam::DVec2;

use super::prediction::{Mover, MIN_RADIUS_M};
use crate::geometry::map::Map;
use crate::station::model::{self, Instant};

/// Predicted this close to a robot's footprint (beyond the mover's grown disc), a mover
/// touches it, m.
const TOUCH_M: f64 = 0.15;
/// On a mover's mean way, this close to a robot's footprint they touch it: half the
/// grown disc's margin, what the tracker's centre is off by for a person in view, m.
const LIKELY_M: f64 = 0.075;
/// A moving robot keeps this from a mover's grown disc over [`IMMINENT_S`]: about the
/// 0.5 m of the intrusion measure from their footprint, m.
const CLEAR_M: f64 = 0.3;
/// What comes within this, a robot must be able to stop for: its braking and a period,
/// s.
const IMMINENT_S: f64 = 0.75;
/// A pace that keeps this much less room than standing makes it worse; one that keeps
/// about as much (they come by anyway) does not, m.
const NO_WORSE_M: f64 = 0.05;
/// A robot closing on someone faster than this drives into them, m/s (the report's line).
const STRIKE_MPS: f64 = 0.1;
/// A robot slower than this stands, m/s.
const STANDING_MPS: f64 = 0.05;
/// Speeding up needs this much more room than keeping a pace, m.
const RESUME_MARGIN_M: f64 = 0.1;
/// The pace chosen last may keep this much less room: committed to clearing someone's
/// way, a leader that broke off at the first doubt stood in it, m.
const KEEP_MARGIN_M: f64 = 0.075;
/// Intruding, no faster than this share of the pace: a person within half a metre has
/// time to step aside from a robot at a walking child's speed.
const SLOW_SHARE: f64 = 0.4;
/// What backing keeps from the site beyond the footprint, m.
const SITE_MARGIN_M: f64 = 0.1;
/// The leader is held when its speed is under this share of its pace.
pub const HELD_BELOW: f64 = 0.05;

/// A speed the leader may be told to make for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Candidate {
    /// Back straight along its heading at its reverse speed, out of someone's way.
    Back,
    Stand,
    /// A share of the route's pace (0.2 creeps).
    Share(f64),
    /// Faster than the route's pace, to clear someone's way.
    Hurry,
    /// Off its path, its control point making for this point to one side of it: out of
    /// the lane of someone coming along it.
    Aside(DVec2),
}

impl Candidate {
    /// The speed it makes for, m/s.
    pub fn target(self, c: &Context) -> f64 {
        match self {
            Candidate::Back => -c.reverse,
            Candidate::Stand => 0.0,
            Candidate::Share(s) => s * c.pace,
            Candidate::Hurry => c.hurry,
            Candidate::Aside(_) => 0.0,
        }
    }

    /// How the forward model moves the leader for it.
    pub fn plan(self, c: &Context) -> model::Plan {
        match self {
            Candidate::Aside(point) => model::Plan::Toward(point),
            _ => model::Plan::Along(self.target(c)),
        }
    }

    /// Whether it moves the leader more than its pace would, to clear someone's way.
    fn extra_motion(self) -> bool {
        matches!(self, Candidate::Hurry | Candidate::Aside(_))
    }

    /// Every candidate for this period: backing, hurrying and stepping aside (to the
    /// points `aside`) only away from a crowd (in one someone is always behind, and
    /// moving more than its pace among people just seen costs goals).
    fn all(crowded: bool, hurry_faster: bool, aside: &[DVec2]) -> Vec<Candidate> {
        let mut out = vec![Candidate::Stand];
        out.extend([0.2, 0.4, 0.6, 0.8, 1.0].map(Candidate::Share));
        if !crowded {
            out.push(Candidate::Back);
            if hurry_faster {
                out.push(Candidate::Hurry);
            }
            out.extend(aside.iter().map(|p| Candidate::Aside(*p)));
        }
        out
    }
}

/// The leader's speeds, m/s.
#[derive(Debug, Clone, Copy)]
pub struct Context {
    /// The route's pace.
    pub pace: f64,
    /// How fast it may go to clear someone's way.
    pub hurry: f64,
    /// How fast it backs.
    pub reverse: f64,
    pub footprint: f64,
    /// Beyond the personal space, the room owed is judged over this, s.
    pub horizon_s: f64,
    /// Passing someone whose room it cannot keep, no faster than this share.
    pub passing_share: f64,
    pub crowded: bool,
}

/// The ordered key a candidate is ranked by: lower is better, field by field. Speeds
/// are in mm/s.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord)]
pub struct Key {
    pub site: bool,
    /// Possible strikes (the grown disc), by the robot's closing speed.
    pub strikes: u32,
    /// Likely contacts (the mean way) with a robot moving in them, by its top speed.
    pub likely_moving: u32,
    /// Likely contacts at all.
    pub likely: u32,
    /// Possible contacts (the grown disc) with a robot moving in them, by how deep into
    /// the touching distance they come: the surer, the worse.
    pub possible_moving: u32,
    pub intrusions: u32,
    pub owed: u32,
    /// Minus the speed up to the pace.
    pub slower: i64,
    /// Hurrying or stepping aside: moving more than its pace, where that and its pace
    /// rank the same.
    pub extra_motion: bool,
}

/// A predicted contact, judged as the report judges one, over all its instants.
#[derive(Debug, Clone, Copy)]
struct Touch {
    /// The robot's top velocity toward the mover, and its top speed, m/s.
    own: f64,
    speed: f64,
    /// The robot drives into them at some instant: its velocity toward them over
    /// [`STRIKE_MPS`] and larger than theirs toward it.
    strike: bool,
    /// Which robot (0 the leader, then the followers in the model's order): the one
    /// moving fastest in the contact.
    robot: usize,
    /// How deep into the touching distance it comes at worst, m.
    depth: f64,
}

impl Touch {
    fn moving(&self) -> bool {
        self.speed > STANDING_MPS
    }

    /// The worse of two instants of one contact: a robot that starts to move while
    /// someone is against it moves in the contact.
    fn worst(self, other: Touch) -> Touch {
        Touch {
            own: self.own.max(other.own),
            speed: self.speed.max(other.speed),
            strike: self.strike || other.strike,
            robot: if other.speed > self.speed {
                other.robot
            } else {
                self.robot
            },
            depth: self.depth.max(other.depth),
        }
    }
}

/// Speeds in the key, mm/s.
fn mm(v: f64) -> u32 {
    (v.max(0.0) * 1000.0).round() as u32
}

/// One mover's contact with the fleet over a rollout, for one of its two discs.
#[derive(Debug, Clone, Copy)]
struct Contact {
    touch: Option<Touch>,
    /// The least gap until they are counted on to steer round, m.
    least: f64,
}

impl Contact {
    const NONE: Contact = Contact {
        touch: None,
        least: f64::INFINITY,
    };

    fn see(&mut self, gap: f64, within: f64, now: impl FnOnce() -> Touch) {
        self.least = self.least.min(gap);
        if gap < within {
            let now = Touch {
                depth: within - gap,
                ..now()
            };
            self.touch = Some(self.touch.map_or(now, |t| t.worst(now)));
        }
    }

    /// Its top speed in a contact that moving makes worse than standing's `stand` (any
    /// contact for someone who may not see the robots), mm/s.
    fn moving_worse(&self, stand: &Contact, wary: bool) -> Option<u32> {
        self.moving_touch(stand, wary).map(|t| mm(t.speed))
    }

    /// How deep into the touching distance that contact comes, mm.
    fn moving_depth(&self, stand: &Contact, wary: bool) -> Option<u32> {
        self.moving_touch(stand, wary).map(|t| mm(t.depth))
    }

    /// That contact.
    fn moving_touch(&self, stand: &Contact, wary: bool) -> Option<Touch> {
        let t = self.touch.filter(Touch::moving)?;
        let worse = self.least < stand.least - NO_WORSE_M;
        (wary || stand.touch.is_none() || worse).then_some(t)
    }
}

/// One mover against one rollout: its likely contact (its mean way: its footprint on
/// its track's prediction), its possible contact (its disc grown by the track's
/// uncertainty), and the least gaps (grown) over [`IMMINENT_S`] and over the horizon
/// for the room owed.
#[derive(Debug, Clone, Copy)]
struct Gaps {
    likely: Contact,
    possible: Contact,
    imminent: f64,
    ahead: f64,
}

/// Each mover's [`Gaps`] over `instants`: a possible contact within [`TOUCH_M`] of a
/// footprint, a likely one within [`LIKELY_M`] on the mean way; `extra` more for both
/// (the hysteresis).
fn gaps(instants: &[Instant], movers: &[Mover], c: &Context, extra: f64) -> Vec<Gaps> {
    movers
        .iter()
        .map(|m| {
            let mut g = Gaps {
                likely: Contact::NONE,
                possible: Contact::NONE,
                imminent: f64::INFINITY,
                ahead: f64::INFINITY,
            };
            let bare = m.track.radius.max(MIN_RADIUS_M);
            for i in instants {
                let (centre, radius) = m.disc(i.t);
                let (k, reach) = i
                    .robots
                    .iter()
                    .enumerate()
                    .map(|(k, r)| (k, r.position().distance(centre) - c.footprint))
                    .fold((0, f64::INFINITY), |a, b| if b.1 < a.1 { b } else { a });
                let gap = reach - radius;
                if i.t <= IMMINENT_S + 1e-9 {
                    g.imminent = g.imminent.min(gap);
                }
                if i.t <= c.horizon_s + 1e-9 {
                    g.ahead = g.ahead.min(gap);
                }
                if i.t > m.trust_after_s + 1e-9 {
                    continue;
                }
                let now = || judge(&i.robots[k], k, m, centre);
                g.possible.see(gap, TOUCH_M + extra, now);
                g.likely.see(reach - bare, LIKELY_M + extra, now);
            }
            g
        })
        .collect()
}

/// A predicted touch of robot `r` (the `k`th of the rollout) and mover `m` (its centre
/// then).
fn judge(r: &model::Robot, k: usize, m: &Mover, centre: DVec2) -> Touch {
    let towards = (centre - r.position()).normalize_or_zero();
    let own = r.velocity().dot(towards);
    let theirs = -m.velocity().dot(towards);
    Touch {
        own,
        speed: r.twist.v.abs() as f64,
        strike: own > STRIKE_MPS && own > theirs,
        robot: k,
        depth: 0.0,
    }
}

/// The key of a candidate whose rollout gave `g`, against standing's `stand`.
fn key(
    candidate: Candidate,
    g: &[Gaps],
    stand: &[Gaps],
    movers: &[Mover],
    c: &Context,
    extra: f64,
) -> Key {
    let target = candidate.target(c);
    let each = || g.iter().zip(stand).zip(movers);
    let worse = |a: f64, b: f64| a < b - NO_WORSE_M;
    let count = |f: &dyn Fn(&Gaps, &Gaps, &Mover) -> bool| {
        each().filter(|((g, s), m)| f(g, s, m)).count() as u32
    };
    // Unavoidable, a contact is judged by its speed (ISO/TS 15066 limits its power).
    let sum = |f: &dyn Fn(&Gaps, &Gaps, &Mover) -> Option<u32>| {
        each().filter_map(|((g, s), m)| f(g, s, m)).sum::<u32>()
    };
    Key {
        site: false,
        strikes: sum(&|g, _, _| g.possible.touch.filter(|t| t.strike).map(|t| mm(t.own))),
        likely_moving: sum(&|g, s, m| g.likely.moving_worse(&s.likely, m.wary)),
        likely: count(&|g, _, _| g.likely.touch.is_some()),
        possible_moving: sum(&|g, s, m| g.possible.moving_depth(&s.possible, m.wary)),
        intrusions: count(&|g, s, _| {
            target > SLOW_SHARE * c.pace + 1e-9
                && g.imminent < CLEAR_M + extra
                && worse(g.imminent, s.imminent)
        }),
        owed: count(&|g, s, m| {
            target > c.passing_share * c.pace + 1e-9
                && g.ahead < m.owed + extra
                && worse(g.ahead, s.ahead)
        }),
        slower: -(target.min(c.pace) * 1000.0).round() as i64,
        extra_motion: candidate.extra_motion(),
    }
}

/// What the ranking chose.
#[derive(Debug, Clone, PartialEq)]
pub struct Choice {
    pub candidate: Candidate,
    pub key: Key,
    /// It avoids a touch that standing would have: it goes on (or backs) to clear
    /// someone's way.
    pub clears: bool,
    /// The followers (their index in the model) that would still move in a contact it
    /// predicts, likely or possible: they are held where they can stop, at rest if
    /// someone comes into them (a shape change or their slot may carry them into
    /// someone's way while the leader stands).
    pub holds: Vec<usize>,
}

/// Ranks every candidate for this period and returns the best. `fleet`: the model's
/// fleet; `last`: the candidate chosen last period; `site`: what backing must keep off.
pub fn choose(
    fleet: &model::Fleet,
    movers: &[Mover],
    (c, site): (&Context, &Map),
    last: Candidate,
    aside: &[DVec2],
) -> Choice {
    let near: Vec<Mover> = movers
        .iter()
        .filter(|m| within_reach(fleet, m, c))
        .copied()
        .collect();
    if near.is_empty() {
        // Nobody can come into any term of the key: every candidate ranks by speed alone.
        return Choice {
            candidate: Candidate::Share(1.0),
            key: Key::default(),
            clears: false,
            holds: Vec::new(),
        };
    }
    let movers = &near[..];
    let horizon = movers
        .iter()
        .map(|m| m.trust_after_s)
        .fold(c.horizon_s.max(IMMINENT_S), f64::max);
    let last_target = last.target(c);
    let roll = |cand: Candidate| model::rollout(fleet, cand.plan(c), horizon);
    let standing = roll(Candidate::Stand);
    let extra_of = |cand: Candidate| {
        let t = cand.target(c);
        if cand == last {
            -KEEP_MARGIN_M
        } else if t > last_target + 1e-9 && t > 0.0 {
            RESUME_MARGIN_M
        } else {
            0.0
        }
    };
    let stand_gaps = gaps(&standing, movers, c, extra_of(Candidate::Stand));
    let stand_key = key(Candidate::Stand, &stand_gaps, &stand_gaps, movers, c, 0.0);
    tracing::trace!(?stand_key, "pace candidate Stand");
    let mut best = (Candidate::Stand, stand_key, stand_gaps.clone());
    let hurry_faster = c.hurry > c.pace + 1e-9;
    for cand in Candidate::all(c.crowded, hurry_faster, aside) {
        if cand == Candidate::Stand {
            continue;
        }
        let extra = extra_of(cand);
        let instants = roll(cand);
        let g = gaps(&instants, movers, c, extra);
        let mut k = key(cand, &g, &stand_gaps, movers, c, extra);
        let off_path = matches!(cand, Candidate::Back | Candidate::Aside(_));
        k.site = off_path && !clear_of_site(&instants, c, site);
        tracing::trace!(?cand, ?k, "pace candidate");
        if k < best.1 {
            best = (cand, k, g);
        }
    }
    let (candidate, key, g) = best;
    Choice {
        candidate,
        key,
        clears: key.likely < stand_key.likely,
        holds: holds(&g, movers),
    }
}

/// The followers still moving in a contact a rollout predicts (`g`): likely with anyone,
/// possible with someone who may not see them.
fn holds(g: &[Gaps], movers: &[Mover]) -> Vec<usize> {
    let mut out: Vec<usize> = g
        .iter()
        .zip(movers)
        .filter_map(|(g, m)| {
            let likely = g.likely.touch.filter(Touch::moving);
            let possible = g.possible.touch.filter(|t| m.wary && t.moving());
            likely.or(possible)
        })
        .filter(|t| t.robot > 0)
        .map(|t| t.robot - 1)
        .collect();
    out.sort_unstable();
    out.dedup();
    out
}

/// Whether `m` may come into any term of the key over the rollouts: within what it and
/// the fastest robot may cover over the horizon, its grown disc, the footprint, the room
/// it is owed and the hysteresis of a robot. Beyond it, it changes no candidate's key.
fn within_reach(fleet: &model::Fleet, m: &Mover, c: &Context) -> bool {
    let horizon = m.trust_after_s.max(c.horizon_s).max(IMMINENT_S);
    let fastest = c.hurry.max(c.pace).max(c.reverse) + 0.5;
    let room = m.owed.max(CLEAR_M).max(TOUCH_M) + RESUME_MARGIN_M;
    let (_, disc) = m.disc(horizon);
    let reach = (m.velocity().length() + fastest) * horizon + disc + c.footprint + room + 1.0;
    let robots = std::iter::once(fleet.leader.pose.position)
        .chain(fleet.followers.iter().map(|(r, _)| r.position()));
    robots
        .into_iter()
        .any(|r| r.distance(m.track.position) <= reach)
}

/// Whether the leader keeps [`SITE_MARGIN_M`] from the site all along a rollout.
fn clear_of_site(instants: &[Instant], c: &Context, site: &Map) -> bool {
    let need = c.footprint + SITE_MARGIN_M;
    instants
        .iter()
        .all(|i| site.clearance(i.robots[0].position(), need) >= need)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_key_puts_safety_before_courtesy_before_speed() {
        let base = Key {
            slower: -450,
            ..Key::default()
        };
        let slow = Key {
            slower: -90,
            ..base
        };
        assert!(base < slow);
        let with = |f: fn(&mut Key)| {
            let mut k = base;
            f(&mut k);
            k
        };
        assert!(with(|k| k.intrusions = 1) > slow);
        assert!(
            with(|k| k.possible_moving = 1)
                > Key {
                    intrusions: 3,
                    ..slow
                }
        );
        assert!(
            with(|k| k.likely = 1)
                > Key {
                    possible_moving: 900,
                    ..slow
                }
        );
        assert!(with(|k| k.likely_moving = 1) > Key { likely: 2, ..slow });
        assert!(
            with(|k| k.strikes = 1)
                > Key {
                    likely_moving: 900,
                    ..slow
                }
        );
        assert!(
            with(|k| k.site = true)
                > Key {
                    strikes: 900,
                    ..slow
                }
        );
        assert!(with(|k| k.extra_motion = true) > base);
    }
}
