//! Yielding to what moves: the leader's pace among people, cyclists and vehicles.
//!
//! Each period, for a few speeds from the planner's full pace down to a standstill, the
//! formation is rolled out along the leader's path: the leader along the path ahead, each
//! follower's reference where the formation manager puts it (wide slots rigid to the
//! leader's pose, line slots along the path it drove), each follower closing on its
//! reference; every moving track along its estimated velocity, its disc grown by its
//! position's and (for a while) its velocity's uncertainty.
//!
//! Each speed is judged, mover by mover, against the fleet standing still:
//!
//! - **Safe** ([`safe`]): moving touches nobody, i.e. nobody comes within [`TOUCH_M`] of a
//!   robot over the next [`NEAR_S`] whom standing would leave more room. And whoever is
//!   about to touch a robot within [`IMMINENT_S`] is stopped for, moving or not, when
//!   the robots cannot count on them to steer round ([`Yielding::wary`]: not known yet,
//!   or walking at the fleet standing as if they did not see it). Away from a crowd,
//!   moving must not bring the robots within [`TOUCH_M`] of such a mover over
//!   [`CROSSING_S`] either, where standing would not: someone crossing from the kerb
//!   reaches the leader's line in 2-3 s, and a leader that judged only the next second
//!   stopped in their way.
//! - **No intrusion** ([`intrudes`]): moving brings nobody within [`CLEAR_M`] over the
//!   next [`IMMINENT_S`] where standing would leave them more room.
//! - **Room kept** ([`owes`]): moving brings nobody within the personal space
//!   (`personal_space_m`, from a person's footprint) or [`VEHICLE_SPACE_M`] (from
//!   anything larger) over `[yielding] horizon_s`, where standing would leave more.
//!
//! The leader takes the fastest safe speed that keeps the room; passes people whose room
//! it cannot keep no faster than `[yielding] passing_share` (its full pace by default:
//! 0.8 until 2026-12-04 took 1.49 × the empty time through 0.1 persons/m², 1 takes
//! 1.30 ×); crosses those it cannot keep clear of (a crowd all round) no faster than
//! [`SLOW_SHARE`]; else it stands. Courtesy slows it, only safety stops it. The other
//! way round, with the room over a 4 s horizon as a condition to move (until
//! 2026-12-03), some constant-velocity prediction always crossed the fleet's way in a
//! crowd of 0.1 persons/m², and the leader stood for 170 of 300 s among people who steer
//! round robots and would have made room.
//!
//! Why this and not ORCA or a velocity obstacle on the leader's heading: the leader leads
//! a formation, and a swerve of the leader swings every slot; a path kept and a pace
//! chosen keep the formation whole and make the robots predictable to the people round
//! them (they slow and wait; they do not dodge). A standstill is the slowest pace; away
//! from a crowd, held, it may back out of the way of someone who does not see it
//! (`stepping_back`), never toward anyone it knows of. Chosen 2026-12-03, measured in
//! `docs/sim.md#movers`.
//!
//! Held for `replan_after_s` by movers (a crowd filling a street), the leader asks the
//! planner for another way round where they stand.
//!
//! **Going on out of someone's way.** Away from a crowd, where no pace is safe and the
//! mean way of someone the robots cannot count on runs through a robot standing, the
//! leader goes on if that keeps every mean way [`TOUCH_M`] off the robots (then,
//! committed, while it keeps them [`KEEP_CLEARING_M`] off): at its pace, or hurrying at
//! up to `hurry`, not slowed for a shape change. A leader that went round someone
//! standing in the street was crossing their way when they set off again, braked, and
//! stood in it: they walked into it, where its pace would have taken it clear
//! (`standing-person-oblivious-seed1806`, 2026-12-06). It hurries before no pace is safe
//! where its pace would take it into such a mean way and hurrying clears it
//! ([`Yielding::hurry_clears`]), and, once going on, keeps at it while that still clears
//! them ([`Yielding::keep_clearing`]), judged with the commands already sent taking
//! [`COMMAND_LAG_S`] to show (2026-12-07).

use std::collections::HashMap;

use glam::DVec2;

use super::stepping_back;
use crate::formation::FormationManager;
use crate::geometry::map::Map;
use crate::geometry::PlanPose;
use crate::perception::tracking::TrackView;
use crate::scenario::YieldingSpec;

/// What is kept from anything that moves and is larger than a person, m.
pub const VEHICLE_SPACE_M: f64 = 1.0;
/// This many moving within [`CROWD_NEAR_M`] of the leader crowd the way.
const CROWD_COUNT: usize = 2;
const CROWD_NEAR_M: f64 = 6.0;
/// The way is clear again once nobody has crowded it for this long, s.
const CROWD_CLEAR_S: f64 = 8.0;
/// The speeds tried, as shares of the planner's full pace.
const SHARES: [f64; 6] = [1.0, 0.8, 0.6, 0.4, 0.2, 0.0];
/// The rollout's step, s.
const STEP_S: f64 = 0.25;
/// A track's velocity uncertainty grows its disc for at most this much, m.
const VELOCITY_GROWTH_MAX_M: f64 = 0.2;
/// A track's disc is at least this: a person's footprint, m.
pub(super) const MIN_RADIUS_M: f64 = 0.3;
/// Nobody is to come within [`TOUCH_M`] of a robot over this: the leader brakes from
/// full speed in about half a second, s.
const NEAR_S: f64 = 1.0;
/// Away from a crowd, moving must not bring the robots within [`TOUCH_M`] of a mover
/// they cannot count on over this, where standing would not: one crossing the street
/// from the kerb (`crossing-oblivious-seed406`: seen 4 m off, they walked into the
/// leader standing 0.14 m too far on), s. In a crowd someone's way always crosses the
/// fleet's within a few seconds: applied there, 0.2 persons/m² social crowds reached
/// the goal in 18 of 32 worlds instead of 25.
const CROSSING_S: f64 = 2.5;
/// What comes within this, a robot must be able to stop for: its braking and a period
/// of the loop, s.
const IMMINENT_S: f64 = 0.75;
/// A mover seen for less than this is not known yet: the robots stop for it, s.
const KNOWN_S: f64 = 1.5;
/// A mover that walks at the fleet standing this long does not see it, s.
const AIMING_S: f64 = 0.5;
/// A moving robot keeps this from a mover's disc: the disc is already grown by the
/// track's uncertainty (0.15-0.2 m for a person in view), so about the 0.5 m of the
/// intrusion measure from their footprint, m.
const CLEAR_M: f64 = 0.3;
/// A pace that keeps this much less room than standing would owes the mover its room;
/// one that keeps about as much (they come by anyway) does not, m.
const NO_WORSE_M: f64 = 0.05;
/// Moving brings nobody this close to a robot's footprint (the track's uncertainty on
/// top), m.
const TOUCH_M: f64 = 0.15;
/// Going on to clear someone's way, the leader keeps going while every mean way keeps
/// this far off the robots (it set off where they kept [`TOUCH_M`]). Kept on to where
/// they kept none, it was still braking out of it when a walker crossing diagonally
/// touched it; breaking off at once, it stood in the way again
/// (`crossing-oblivious-seed1812`, `standing-person-oblivious-seed1811`), m.
const KEEP_CLEARING_M: f64 = 0.075;
/// A command shows in the leader's speed about this late: the radio's 50 ms, up to a
/// period before the robot's loop takes it, the motors' lag. Going on to clear someone's
/// way is judged with it: judged from the speed now, the leader hurrying seemed to gain
/// room it did not, and broke off in the walker's way (`movers-unmapped-seed2208`: the
/// speed estimate rose 0.3 s behind the commands), s.
const COMMAND_LAG_S: f64 = 0.3;
/// Where it cannot keep clear of them either (a crowd all round), no faster than this.
const SLOW_SHARE: f64 = 0.4;
/// Speeding up again needs this much more room than keeping a pace, m.
const RESUME_MARGIN_M: f64 = 0.1;
/// The leader is held when the share it may use is under this.
const HELD_BELOW: f64 = 0.05;

/// What yielding decided this period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Yield {
    /// The share of the planner's pace the leader may use, in [0, 1].
    pub share: f64,
    /// Movers hold the leader (it just began: `began`).
    pub held: bool,
    pub began: bool,
    /// Held long enough: a way round is due, round this point and radius.
    pub avoid: Option<(DVec2, f64)>,
    /// Held, and someone who may not see it would walk into it standing: it backs out
    /// of their way (`stepping_back`).
    pub back: bool,
    /// No pace is safe, and going on at `share` (over 1 where only hurrying does) is
    /// what clears someone who would walk into the robots standing (see the module's
    /// doc): not slowed for a shape change either. It just began: `clearing_began`.
    pub clearing: bool,
    pub clearing_began: bool,
}

/// What the rollout needs of the fleet now.
pub struct Fleet<'a> {
    pub leader: PlanPose,
    /// The leader's speed now, m/s.
    pub v: f64,
    /// The speed last commanded to the leader, m/s: its wheels reach it about
    /// [`COMMAND_LAG_S`] on.
    pub commanded: f64,
    pub max_speed: f64,
    /// How fast it may go to get out of the way of someone who would walk into it, m/s.
    pub hurry: f64,
    pub max_accel: f64,
    /// How hard it brakes for someone in its way, m/s².
    pub brake: f64,
    pub footprint: f64,
    /// The path ahead from the leader's position, and the path it drove (from its
    /// position back).
    pub ahead: &'a [DVec2],
    pub behind: &'a [DVec2],
    /// Each follower's position (None: not known), in slot order.
    pub followers: &'a [Option<DVec2>],
    pub follower_speed: f64,
    /// How fast the leader backs, m/s.
    pub reverse: f64,
    /// What the leader must keep from: the site and what was sensed.
    pub site: &'a Map,
}

impl Fleet<'_> {
    /// Hurrying as a share of the planner's pace (over 1 where it is faster).
    fn hurry_share(&self) -> f64 {
        self.hurry / self.max_speed
    }
}

/// The leader's pace among movers.
#[derive(Debug, Clone)]
pub struct Yielding {
    spec: YieldingSpec,
    /// The share given last period.
    last: f64,
    held_since_s: Option<f64>,
    /// When a way round was last asked for.
    avoided_s: Option<f64>,
    /// When movers last crowded the way.
    crowded_s: Option<f64>,
    /// What is known of each track's manners, by track id.
    manners: HashMap<u32, Manners>,
    /// Whether it went on last period to clear someone's way.
    clearing: bool,
}

/// Whether a mover has shown it sees the robots.
#[derive(Debug, Clone, Copy)]
struct Manners {
    /// When the track was first yielded to, s.
    first_s: f64,
    /// Since when it has kept walking at the fleet standing (its predicted way touching a
    /// robot), s.
    aiming_since_s: Option<f64>,
}

impl Yielding {
    pub fn new(spec: YieldingSpec) -> Self {
        Self {
            spec,
            last: 1.0,
            held_since_s: None,
            avoided_s: None,
            crowded_s: None,
            manners: HashMap::new(),
            clearing: false,
        }
    }

    /// Whether movers crowd the formation's way: `CROWD_COUNT` moving within
    /// `CROWD_NEAR_M` of the leader, until none have for `CROWD_CLEAR_S`. The wide
    /// shape then gives way to the line: three robots abreast cross a crowd as a 4 m
    /// wall, in a line as one robot's width.
    pub fn crowded(&mut self, now_s: f64, leader: DVec2, movers: &[TrackView]) -> bool {
        let near = movers
            .iter()
            .filter(|m| m.position.distance(leader) <= CROWD_NEAR_M)
            .count();
        if near >= CROWD_COUNT {
            self.crowded_s = Some(now_s);
        }
        self.in_crowd(now_s)
    }

    /// Whether movers crowded the way within the last [`CROWD_CLEAR_S`].
    fn in_crowd(&self, now_s: f64) -> bool {
        self.crowded_s.is_some_and(|t| now_s - t <= CROWD_CLEAR_S)
    }

    /// One period at `now_s`: the share of its pace the leader may use.
    pub fn decide(
        &mut self,
        now_s: f64,
        fleet: &Fleet<'_>,
        formation: &FormationManager,
        movers: &[TrackView],
    ) -> Yield {
        let ((share, clearing), wary) = if movers.is_empty() {
            // Nobody moves: what was known of anyone's manners is stale (someone who
            // stood for a while sets off as a stranger).
            self.manners.clear();
            ((1.0, false), Vec::new())
        } else {
            let wary = self.wary(now_s, fleet, movers);
            (self.choose(now_s, fleet, formation, movers, &wary), wary)
        };
        self.last = share;
        let clearing_began = clearing && !self.clearing;
        self.clearing = clearing;
        let held = share < HELD_BELOW;
        // Away from a crowd only: in one, someone is always behind.
        let back = held && !self.in_crowd(now_s) && self.backs(fleet, movers, &wary);
        let began = held && self.held_since_s.is_none();
        if !held {
            self.held_since_s = None;
        } else if began {
            self.held_since_s = Some(now_s);
        }
        let avoid = self.way_round_due(now_s, fleet, movers);
        Yield {
            share,
            held,
            began,
            avoid,
            back,
            clearing,
            clearing_began,
        }
    }

    /// Whether the leader, held, backs out of the way of one of `movers` (`wary`: whom
    /// the robots cannot count on to steer round them).
    fn backs(&self, fleet: &Fleet<'_>, movers: &[TrackView], wary: &[bool]) -> bool {
        let followers: Vec<DVec2> = fleet.followers.iter().flatten().copied().collect();
        let leader = stepping_back::Leader {
            position: fleet.leader.position,
            followers: &followers,
            heading: fleet.leader.heading,
            v: fleet.v,
            footprint: fleet.footprint,
            reverse: fleet.reverse,
            accel: fleet.brake,
        };
        stepping_back::should_back(&leader, movers, wary, fleet.site)
    }

    /// The fastest safe share, no faster than its courtesy allows (see the module's doc):
    /// any pace where it keeps everyone's room, `passing_share` where it cannot,
    /// [`SLOW_SHARE`] where it would intrude; else, where no pace is safe, one that
    /// clears someone who would walk into it standing (and `true`: see the module's
    /// doc), or a standstill.
    fn choose(
        &mut self,
        now_s: f64,
        fleet: &Fleet<'_>,
        formation: &FormationManager,
        movers: &[TrackView],
        wary: &[bool],
    ) -> (f64, bool) {
        let standing = rollout(fleet, formation, movers, 0.0, &self.spec);
        // In a crowd, someone's way always crosses the fleet's within a few seconds.
        let lone = !self.in_crowd(now_s);
        if self.clearing && lone {
            if let Some(share) = self.keep_clearing(fleet, formation, movers, &standing) {
                return (share, true);
            }
        }
        // The unsafe pace that keeps the most room, where nothing is safe.
        let mut going_on: Option<(f64, f64)> = None;
        // The shares come fastest first: the first one within its cap is the answer.
        for share in SHARES.into_iter().filter(|s| *s > 0.0) {
            let gaps = rollout(fleet, formation, movers, share, &self.spec);
            let extra = if share > self.last + 1e-9 {
                RESUME_MARGIN_M
            } else {
                0.0
            };
            let each = || gaps.iter().zip(&standing);
            if !each()
                .zip(wary)
                .all(|((g, s), w)| safe(g, s, *w, lone, extra))
            {
                let kept = room(&gaps);
                if going_on.is_none_or(|(_, best)| kept > best) {
                    going_on = Some((share, kept));
                }
                continue;
            }
            let cap = if each().any(|(g, s)| intrudes(g, s, extra)) {
                SLOW_SHARE
            } else if each().any(|(g, s)| owes(g, s, extra)) {
                self.spec.passing_share
            } else {
                1.0
            };
            if share <= cap + 1e-9 {
                let late = lone
                    && room_of_wary(&gaps, wary) < TOUCH_M
                    && room_of_wary(&standing, wary) < 0.0;
                if late && self.hurry_clears(fleet, formation, movers, TOUCH_M) {
                    return (fleet.hurry_share(), true);
                }
                return (share, false);
            }
        }
        // Nothing is safe. Away from a crowd, someone who would walk into the robots
        // standing may still be cleared by going on: at a pace the planner keeps, else
        // hurrying. (In crowds of 0.3 persons/m² it went on among new tracks, and 87
        // worlds of 128 reached the goal instead of 93.)
        let standing_room = room_of_wary(&standing, wary);
        if !lone || standing_room >= 0.0 {
            return (0.0, false);
        }
        // Once going on, it keeps going while that still keeps their ways half as far off.
        let need = if self.clearing {
            KEEP_CLEARING_M
        } else {
            TOUCH_M
        };
        let spec = &self.spec;
        if let Some((share, _)) =
            going_on.filter(|(share, _)| clears(fleet, formation, movers, *share, spec) >= need)
        {
            return (share, true);
        }
        if self.hurry_clears(fleet, formation, movers, need) {
            return (fleet.hurry_share(), true);
        }
        (0.0, false)
    }

    /// Going on to clear someone's way, the share it keeps going at: the one it went at
    /// last period, else its pace, else hurrying, the first that keeps every mean way
    /// [`KEEP_CLEARING_M`] off the robots; none once standing would leave nobody's way
    /// through a robot (done) or none does (it breaks off). A pace merely no worse than
    /// standing is not enough here: judged so, the leader dropped its hurry a period in,
    /// went on at its pace into the walker's way, and was braking in it when they
    /// reached it (`movers-unmapped-seed2163`, `2208`: contacts while moving).
    fn keep_clearing(
        &self,
        fleet: &Fleet<'_>,
        formation: &FormationManager,
        movers: &[TrackView],
        standing: &[Gaps],
    ) -> Option<f64> {
        if room(standing) >= 0.0 {
            return None;
        }
        let hurry = fleet.hurry_share().max(1.0);
        [self.last, 1.0, hurry]
            .into_iter()
            .filter(|share| *share > 0.0)
            .find(|share| clears(fleet, formation, movers, *share, &self.spec) >= KEEP_CLEARING_M)
    }

    /// Whether hurrying is faster than its pace and keeps every mean way `need` off the
    /// robots. Away from a crowd, where the pace it may take keeps someone it cannot
    /// count on within touch of their way and standing would leave it through a robot,
    /// the leader hurries across at once where this holds for [`TOUCH_M`]: waiting until
    /// no pace is safe, it drove at its pace into a walker's way that hurrying would
    /// have kept 0.6 m clear, and was too late to hurry then
    /// (`movers-unmapped-seed2208`: a contact while moving).
    fn hurry_clears(
        &self,
        fleet: &Fleet<'_>,
        formation: &FormationManager,
        movers: &[TrackView],
        need: f64,
    ) -> bool {
        let hurry = fleet.hurry_share();
        hurry > 1.0 && clears(fleet, formation, movers, hurry, &self.spec) >= need
    }

    /// Which movers the robots stop for when they are about to touch one, even if
    /// standing is no better: those not yet seen long enough to know ([`KNOWN_S`]), and
    /// those that kept walking at the fleet standing for [`AIMING_S`] (they do not see
    /// it). The rest have shown they steer round the robots; a robot that stopped for
    /// everyone walking its way would never cross a crowd.
    fn wary(&mut self, now_s: f64, fleet: &Fleet<'_>, movers: &[TrackView]) -> Vec<bool> {
        self.manners
            .retain(|id, _| movers.iter().any(|m| m.id == *id));
        let robots: Vec<DVec2> = std::iter::once(fleet.leader.position)
            .chain(fleet.followers.iter().flatten().copied())
            .collect();
        movers
            .iter()
            .map(|m| {
                let manners = self.manners.entry(m.id).or_insert(Manners {
                    first_s: now_s,
                    aiming_since_s: None,
                });
                if aims(m, &robots, fleet.footprint) {
                    manners.aiming_since_s.get_or_insert(now_s);
                } else {
                    manners.aiming_since_s = None;
                }
                now_s - manners.first_s < KNOWN_S
                    || manners
                        .aiming_since_s
                        .is_some_and(|t| now_s - t >= AIMING_S)
            })
            .collect()
    }

    /// Held for `replan_after_s` by movers: the disc they stand in, once per hold.
    fn way_round_due(
        &mut self,
        now_s: f64,
        fleet: &Fleet<'_>,
        movers: &[TrackView],
    ) -> Option<(DVec2, f64)> {
        let since = self.held_since_s?;
        if now_s - since < self.spec.replan_after_s || self.avoided_s.is_some_and(|t| t >= since) {
            return None;
        }
        self.avoided_s = Some(now_s);
        let reach = fleet.max_speed * self.spec.horizon_s + 2.0;
        let near: Vec<DVec2> = movers
            .iter()
            .map(|m| m.position)
            .filter(|p| p.distance(fleet.leader.position) <= reach)
            .collect();
        if near.is_empty() {
            return None;
        }
        let centre = near.iter().copied().sum::<DVec2>() / near.len() as f64;
        let radius = near.iter().map(|p| p.distance(centre)).fold(0.0, f64::max)
            + self.spec.personal_space_m
            + MIN_RADIUS_M;
        Some((centre, radius))
    }
}

/// The least gap between a mover and any robot over the next [`IMMINENT_S`], over the
/// next [`NEAR_S`], over `horizon_s` and over [`CROSSING_S`], and the room the mover is
/// owed.
#[derive(Debug, Clone, Copy)]
struct Gaps {
    imminent: f64,
    near: f64,
    ahead: f64,
    crossing: f64,
    owed: f64,
    /// The least gap over [`CROSSING_S`] to the mover's footprint on its mean way (its
    /// disc not grown by the track's uncertainty).
    bare: f64,
}

/// Each mover's [`Gaps`], the leader making for `share` of its full pace.
fn rollout(
    fleet: &Fleet<'_>,
    formation: &FormationManager,
    movers: &[TrackView],
    share: f64,
    spec: &YieldingSpec,
) -> Vec<Gaps> {
    rollout_from(fleet, formation, movers, share, spec, 0.0)
}

/// [`rollout`], the speed commanded last taking `lag_s` to show: until then the leader
/// makes for that, not for `share`.
fn rollout_from(
    fleet: &Fleet<'_>,
    formation: &FormationManager,
    movers: &[TrackView],
    share: f64,
    spec: &YieldingSpec,
    lag_s: f64,
) -> Vec<Gaps> {
    let path = Path::new(fleet.ahead);
    // The line's last slot is at most this far back along the trail: the rest of it
    // (the whole way driven) need not be copied at every step.
    let trail = prefix(fleet.behind, formation.line_reach() + 1.0);
    let target = share * fleet.max_speed;
    let (mut v, mut s) = (fleet.v, 0.0);
    let mut positions: Vec<Option<DVec2>> = fleet.followers.to_vec();
    let mut gaps: Vec<Gaps> = movers
        .iter()
        .map(|m| Gaps {
            imminent: f64::INFINITY,
            near: f64::INFINITY,
            ahead: f64::INFINITY,
            crossing: f64::INFINITY,
            owed: owed(m, spec.personal_space_m),
            bare: f64::INFINITY,
        })
        .collect();
    let steps = (spec.horizon_s.max(CROSSING_S) / STEP_S).ceil() as usize;
    for k in 1..=steps {
        let t = k as f64 * STEP_S;
        let goal = if t <= lag_s + 1e-9 {
            fleet.commanded
        } else {
            target
        };
        let dv = (goal - v).clamp(-fleet.brake * STEP_S, fleet.max_accel * STEP_S);
        s += (v + 0.5 * dv) * STEP_S;
        v += dv;
        let pose = path.pose_at(s, fleet.leader);
        let behind = path.behind(s, fleet.leader, trail);
        let mut robots = vec![pose.position];
        for (k, p) in positions.iter_mut().enumerate() {
            let Some(at) = p else { continue };
            let reference = formation.reference(k, pose, &behind);
            let to = reference - *at;
            let reach = fleet.follower_speed * STEP_S;
            *at += if to.length() <= reach {
                to
            } else {
                to.normalize() * reach
            };
            robots.push(*at);
        }
        for (m, g) in movers.iter().zip(gaps.iter_mut()) {
            let (centre, radius) = disc(m, t);
            let least = robots
                .iter()
                .map(|r| r.distance(centre) - radius - fleet.footprint)
                .fold(f64::INFINITY, f64::min);
            if t <= IMMINENT_S + 1e-9 {
                g.imminent = g.imminent.min(least);
            }
            if t <= NEAR_S + 1e-9 {
                g.near = g.near.min(least);
            }
            if t <= spec.horizon_s + 1e-9 {
                g.ahead = g.ahead.min(least);
            }
            if t <= CROSSING_S + 1e-9 {
                g.crossing = g.crossing.min(least);
                let grown = radius - m.radius.max(MIN_RADIUS_M);
                g.bare = g.bare.min(least + grown);
            }
        }
    }
    gaps
}

/// Whether a pace is safe for one mover (`g`; `s` with the fleet standing; `wary`: see
/// [`Yielding::wary`]): the robots touch nobody by moving (nobody comes within
/// [`TOUCH_M`] over [`NEAR_S`] whom standing would leave more room), and they stop for
/// whoever they cannot count on to steer round them and is about to touch them; and,
/// `lone` (no crowd round the leader), they do not move into the way of one of those over
/// [`CROSSING_S`].
fn safe(g: &Gaps, s: &Gaps, wary: bool, lone: bool, extra: f64) -> bool {
    let touch = g.near < TOUCH_M + extra;
    let worse = g.near < s.near - NO_WORSE_M;
    let stop_for = wary && g.imminent < TOUCH_M + extra;
    let late = lone && wary && g.crossing < TOUCH_M + extra && g.crossing < s.crossing - NO_WORSE_M;
    (!touch || (!worse && !stop_for)) && !late
}

/// The room going on at `share` leaves everyone's mean way ([`room`]), the commands
/// already sent taking [`COMMAND_LAG_S`] to show.
fn clears(
    fleet: &Fleet<'_>,
    formation: &FormationManager,
    movers: &[TrackView],
    share: f64,
    spec: &YieldingSpec,
) -> f64 {
    room(&rollout_from(
        fleet,
        formation,
        movers,
        share,
        spec,
        COMMAND_LAG_S,
    ))
}

/// The least room a pace leaves anyone on their mean way over [`CROSSING_S`], m
/// (negative: their way runs through a robot).
fn room(gaps: &[Gaps]) -> f64 {
    gaps.iter().map(|g| g.bare).fold(f64::INFINITY, f64::min)
}

/// The same, for those the robots cannot count on to steer round them (`wary`).
fn room_of_wary(gaps: &[Gaps], wary: &[bool]) -> f64 {
    gaps.iter()
        .zip(wary)
        .filter(|(_, w)| **w)
        .map(|(g, _)| g.bare)
        .fold(f64::INFINITY, f64::min)
}

/// Whether a pace brings the robots within [`CLEAR_M`] of a mover over [`IMMINENT_S`]
/// where standing would leave them more room.
fn intrudes(g: &Gaps, s: &Gaps, extra: f64) -> bool {
    g.imminent < CLEAR_M + extra && g.imminent < s.imminent - NO_WORSE_M
}

/// Whether a pace brings the robots within the room a mover is owed over `horizon_s`
/// where standing would leave them more.
fn owes(g: &Gaps, s: &Gaps, extra: f64) -> bool {
    g.ahead < g.owed + extra && g.ahead < s.ahead - NO_WORSE_M
}

/// Whether `m` walks at one of `robots` standing: its mean way over [`NEAR_S`] comes
/// within [`TOUCH_M`] of one's footprint. Not its disc grown by its uncertainty: a track
/// the scanner lost grows round the robots without anyone walking at them.
fn aims(m: &TrackView, robots: &[DVec2], footprint: f64) -> bool {
    let reach = m.radius.max(MIN_RADIUS_M) + footprint + TOUCH_M;
    let steps = (NEAR_S / STEP_S).ceil() as usize;
    (1..=steps).any(|k| {
        let at = m.at(k as f64 * STEP_S);
        robots.iter().any(|r| r.distance(at) < reach)
    })
}

/// The points of `trail` up to the first `length` along it from its first, and the
/// one beyond.
fn prefix(trail: &[DVec2], length: f64) -> &[DVec2] {
    let mut along = 0.0;
    for (k, w) in trail.windows(2).enumerate() {
        along += w[0].distance(w[1]);
        if along > length {
            return &trail[..k + 2];
        }
    }
    trail
}

/// The room a mover is owed: the personal space for a person, more for anything larger.
fn owed(m: &TrackView, personal_space: f64) -> f64 {
    if m.person {
        personal_space
    } else {
        VEHICLE_SPACE_M
    }
}

/// A mover `t` seconds on: its centre (the tracker fits a person's from their near side),
/// and its radius grown by its uncertainty.
fn disc(m: &TrackView, t: f64) -> (DVec2, f64) {
    let radius = m.radius.max(MIN_RADIUS_M)
        + m.position_sigma
        + (m.velocity_sigma * t).min(VELOCITY_GROWTH_MAX_M);
    (m.at(t), radius)
}

/// A polyline by arc length.
struct Path<'a> {
    points: &'a [DVec2],
    arcs: Vec<f64>,
}

impl<'a> Path<'a> {
    fn new(points: &'a [DVec2]) -> Self {
        let mut arcs = Vec::with_capacity(points.len());
        let mut total = 0.0;
        for (i, p) in points.iter().enumerate() {
            if i > 0 {
                total += points[i - 1].distance(*p);
            }
            arcs.push(total);
        }
        Self { points, arcs }
    }

    /// The pose `s` along (the leader's own pose at 0; standing at the end).
    fn pose_at(&self, s: f64, start: PlanPose) -> PlanPose {
        let n = self.points.len();
        if n < 2 || s <= 0.0 {
            return start;
        }
        let i = self.arcs.partition_point(|a| *a <= s).clamp(1, n - 1);
        let (a, b) = (self.points[i - 1], self.points[i]);
        let seg = self.arcs[i] - self.arcs[i - 1];
        let f = if seg > 1e-9 {
            ((s - self.arcs[i - 1]) / seg).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let d = b - a;
        PlanPose {
            position: a.lerp(b, f),
            heading: if d.length() > 1e-9 {
                d.to_angle()
            } else {
                start.heading
            },
        }
    }

    /// The path driven by the time the leader is `s` along: the stretch ahead it covered,
    /// back to where it is now, then `behind`.
    fn behind(&self, s: f64, start: PlanPose, behind: &[DVec2]) -> Vec<DVec2> {
        let mut out = vec![self.pose_at(s, start).position];
        let covered = self.arcs.partition_point(|a| *a < s);
        out.extend(self.points[..covered.min(self.points.len())].iter().rev());
        out.extend(behind.iter().skip(1));
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::Scenario;

    fn formation() -> FormationManager {
        let src = include_str!("../../../../../scenarios/paper-obstacles.toml");
        let s = Scenario::parse(src, "paper-obstacles.toml").expect("the shipped scenario");
        FormationManager::new(s.formation_spec())
    }

    fn person(id: u32, at: (f64, f64), v: (f64, f64)) -> TrackView {
        TrackView::person_at(id, at, v)
    }

    /// The leader at the origin driving along +x at full pace, its followers unknown.
    fn decide(y: &mut Yielding, now_s: f64, movers: &[TrackView]) -> f64 {
        let ahead: Vec<DVec2> = (0..40).map(|k| DVec2::new(k as f64 * 0.25, 0.0)).collect();
        let behind = [DVec2::ZERO, DVec2::new(-5.0, 0.0)];
        let fleet = Fleet {
            leader: PlanPose {
                position: DVec2::ZERO,
                heading: 0.0,
            },
            v: 0.45,
            commanded: 0.45,
            max_speed: 0.45,
            hurry: 0.8,
            max_accel: 0.3,
            brake: 0.8,
            footprint: 0.3,
            ahead: &ahead,
            behind: &behind,
            followers: &[None, None],
            follower_speed: 0.6,
            reverse: 0.24,
            site: &Map::new(Vec::new()),
        };
        y.decide(now_s, &fleet, &formation(), movers).share
    }

    /// Someone 1.4 m to the leader's left walking straight at where it stands.
    fn at_the_leader(id: u32) -> TrackView {
        person(id, (0.0, 1.4), (0.0, -1.3))
    }

    #[test]
    fn the_leader_stops_for_someone_it_does_not_know_yet() {
        let mut y = Yielding::new(YieldingSpec::default());
        assert_eq!(decide(&mut y, 0.0, &[at_the_leader(1)]), 0.0);
    }

    #[test]
    fn the_leader_goes_on_past_someone_who_has_steered_round_it_so_far() {
        let mut y = Yielding::new(YieldingSpec::default());
        let far = person(1, (0.0, 6.0), (1.3, 0.0));
        assert_eq!(decide(&mut y, 0.0, &[far]), 1.0);
        // Known for 2 s, and now walking its way: standing would leave them no more room.
        assert!(decide(&mut y, 2.0, &[at_the_leader(1)]) > 0.0);
        // Still walking at the leader half a second on: they do not see it.
        assert_eq!(decide(&mut y, 2.5, &[at_the_leader(1)]), 0.0);
    }

    #[test]
    fn someone_who_stood_sets_off_as_a_stranger() {
        let mut y = Yielding::new(YieldingSpec::default());
        let far = person(1, (0.0, 6.0), (1.3, 0.0));
        assert_eq!(decide(&mut y, 0.0, &[far]), 1.0);
        // They stood (a still track is no mover) while nobody else moved ...
        assert_eq!(decide(&mut y, 2.0, &[]), 1.0);
        // ... and set off at the leader: nothing is known of them any more.
        assert_eq!(decide(&mut y, 2.1, &[at_the_leader(1)]), 0.0);
    }

    #[test]
    fn the_leader_stands_off_the_way_of_a_lone_stranger_crossing_from_the_kerb() {
        // Seen at the kerb 2.6 m to the left, 1 m on, walking across at 1.3 m/s: they
        // cross the leader's line in 2 s, where the leader at full pace would be.
        let crossing = person(1, (1.0, 2.6), (0.0, -1.3));
        let mut y = Yielding::new(YieldingSpec::default());
        let share = decide(&mut y, 0.0, &[crossing]);
        assert!(share < SLOW_SHARE, "went on at {share}");
        // In a crowd someone always crosses within a few seconds: the leader goes on
        // (it still stops for whoever is about to touch it).
        let mut y = Yielding::new(YieldingSpec::default());
        let others = [person(2, (-3.0, 3.0), (1.0, 0.0)), crossing];
        assert!(y.crowded(0.0, DVec2::ZERO, &others));
        assert_eq!(decide(&mut y, 0.0, &others), 1.0);
    }

    #[test]
    fn the_leader_goes_on_out_of_the_way_of_a_stranger_who_would_walk_into_it_standing() {
        // Someone setting off 1.2 m to the right and 0.4 m behind, walking across at
        // 1.2 m/s: about to come within touch whatever the leader does, their way runs
        // through it standing, and keeps clear of it at its pace.
        let setting_off = person(1, (-0.4, -1.2), (0.0, 1.2));
        let mut y = Yielding::new(YieldingSpec::default());
        assert_eq!(decide(&mut y, 0.0, &[setting_off]), 1.0);
        // Coming at where it goes on as well: it stands (and is walked into, not moving).
        let ahead = person(1, (0.3, -1.2), (0.0, 1.2));
        let mut y = Yielding::new(YieldingSpec::default());
        assert_eq!(decide(&mut y, 0.0, &[ahead]), 0.0);
    }

    #[test]
    fn the_leader_hurries_across_the_way_of_a_stranger_it_would_drive_into_at_its_pace() {
        // Seen 3.5 m to the right and 0.6 m on, walking across at 1.3 m/s: standing, their
        // way runs through the leader; at its pace it drives into it; hurrying clears it
        // (`movers-unmapped-seed2208`).
        let hurry = 0.8 / 0.45;
        let crossing = |dt: f64| person(1, (0.6, -3.5 + 1.3 * dt), (0.0, 1.3));
        let mut y = Yielding::new(YieldingSpec::default());
        assert_eq!(decide(&mut y, 0.0, &[crossing(0.0)]), hurry);
        // Still hurrying a period on, once they are known as well.
        assert_eq!(decide(&mut y, 0.1, &[crossing(0.1)]), hurry);
        assert_eq!(decide(&mut y, 2.0, &[crossing(0.2)]), hurry);
    }

    #[test]
    fn the_leader_passes_someone_whose_room_it_cannot_keep_at_the_passing_share() {
        let spec = YieldingSpec {
            passing_share: 0.6,
            ..YieldingSpec::default()
        };
        let mut y = Yielding::new(spec.clone());
        // Someone standing 0.9 m beside the way just ahead: the leader passes within
        // their personal space, not within touch (1.05 m: their centre).
        let beside = person(1, (0.8, 1.05), (0.0, 0.0));
        assert_eq!(decide(&mut y, 0.0, &[beside]), 0.6);
        // Nobody near: full pace.
        let far = person(1, (0.8, 4.0), (0.0, 0.0));
        assert_eq!(decide(&mut y, 0.1, &[far]), 1.0);
        // Passing at its pace where the operator chose so: still no nearer than touch.
        let mut y = Yielding::new(YieldingSpec {
            passing_share: 1.0,
            ..spec
        });
        assert_eq!(decide(&mut y, 0.0, &[beside]), 1.0);
        let in_the_way = person(1, (1.0, 0.3), (0.0, 0.0));
        assert!(decide(&mut y, 0.1, &[in_the_way]) <= SLOW_SHARE);
    }
}
