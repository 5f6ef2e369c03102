//! What the station expects of each mover over the next seconds: where it will be (its
//! track's constant-velocity prediction, its disc grown by the track's uncertainty), how
//! much room it is owed, and for how long the robots may count on it to steer round them
//! (its manners, learned from how it has walked so far). And whether movers crowd the
//! fleet's way. The tracker says what moves and how fast; what that means for the fleet
//! is decided here.

use std::collections::HashMap;

use glam::DVec2;

use crate::perception::tracking::TrackView;

/// What is kept from anything that moves and is larger than a person, m.
pub const VEHICLE_SPACE_M: f64 = 1.0;
/// A track's disc is at least this: a person's footprint, m.
pub const MIN_RADIUS_M: f64 = 0.3;
/// A track's velocity uncertainty grows its disc by at most this: beyond it the track
/// would fill the street, m.
const VELOCITY_GROWTH_MAX_M: f64 = 0.2;
/// Someone who has shown they steer round the robots is counted on to do so beyond this:
/// a person sidesteps a robot in about a second, s.
pub const TRUSTED_S: f64 = 1.0;
/// Someone the robots cannot count on is predicted walking straight on for this long:
/// one crossing from the kerb reaches the fleet's line in 2–3 s, s.
pub const UNTRUSTED_S: f64 = 2.5;
/// A mover seen near the robots for less than this is not known yet, s.
const KNOWN_S: f64 = 1.5;
/// Near the robots: within this of one. How someone walks near the robots is what tells
/// whether they see them; the scanner tracks people much farther off, m.
const NEAR_M: f64 = 8.0;
/// A mover that walks at the fleet standing this long does not see it, s.
const AIMING_S: f64 = 0.5;
/// A mover "walks at" a robot whose footprint its mean way comes within this of, m.
const AIMING_WITHIN_M: f64 = 0.15;
/// This many moving within [`CROWD_NEAR_M`] of the leader crowd the way: three robots
/// abreast would cross them as a 4 m wall.
const CROWD_COUNT: usize = 2;
/// This many make a crowd (0.035 persons/m²), where someone's way always crosses the
/// fleet's within seconds; a street's two or three people walking by are not one.
const DENSE_COUNT: usize = 4;
const CROWD_NEAR_M: f64 = 6.0;
/// The way is clear again once nobody has crowded it for this long: people in a crowd
/// come in waves, s.
const CROWD_CLEAR_S: f64 = 8.0;

/// One mover as the pace judges it.
#[derive(Debug, Clone, Copy)]
pub struct Mover<'a> {
    pub track: &'a TrackView,
    /// How long the robots may not count on it to steer round them, s: it walks on as
    /// tracked for this long.
    pub trust_after_s: f64,
    /// Whether it may not see the robots (not known yet, or walking at them).
    pub wary: bool,
    /// The room it is owed beyond its footprint, m.
    pub owed: f64,
}

impl Mover<'_> {
    /// Its disc `t` seconds on: its centre, and its radius grown by the track's
    /// uncertainty.
    pub fn disc(&self, t: f64) -> (DVec2, f64) {
        let m = self.track;
        let radius = m.radius.max(MIN_RADIUS_M)
            + m.position_sigma
            + (m.velocity_sigma * t).min(VELOCITY_GROWTH_MAX_M);
        (m.at(t), radius)
    }

    pub fn velocity(&self) -> DVec2 {
        self.track.velocity
    }
}

/// Whether a mover has shown it sees the robots.
#[derive(Debug, Clone, Copy)]
struct Manners {
    /// When the track was first seen moving, s.
    first_s: f64,
    /// Since when it has kept walking at the fleet standing, s.
    aiming_since_s: Option<f64>,
}

/// The station's expectations of the movers, kept from period to period.
#[derive(Debug, Clone, Default)]
pub struct Prediction {
    manners: HashMap<u32, Manners>,
    /// When movers last crowded the way, and when they were last a crowd.
    crowded_s: Option<f64>,
    dense_s: Option<f64>,
}

impl Prediction {
    /// One period at `now_s`: each of `movers` judged (`robots`: every robot's position,
    /// the leader first; `footprint`: theirs).
    pub fn step<'a>(
        &mut self,
        now_s: f64,
        robots: &[DVec2],
        footprint: f64,
        movers: &'a [TrackView],
        personal_space: f64,
    ) -> Vec<Mover<'a>> {
        if movers.is_empty() {
            // Someone who stood for a while sets off as a stranger.
            self.manners.clear();
        }
        self.manners
            .retain(|id, _| movers.iter().any(|m| m.id == *id));
        if let Some(leader) = robots.first() {
            let near = movers
                .iter()
                .filter(|m| m.position.distance(*leader) <= CROWD_NEAR_M)
                .count();
            if near >= CROWD_COUNT {
                self.crowded_s = Some(now_s);
            }
            if near >= DENSE_COUNT {
                self.dense_s = Some(now_s);
            }
        }
        let dense = self.dense(now_s);
        movers
            .iter()
            .map(|m| {
                let wary = self.wary(now_s, m, robots, footprint);
                Mover {
                    track: m,
                    // In a crowd someone's way always crosses the fleet's within a few
                    // seconds: walking on for long is expected of nobody there.
                    trust_after_s: if wary && !dense {
                        UNTRUSTED_S
                    } else {
                        TRUSTED_S
                    },
                    wary,
                    owed: if m.person {
                        personal_space
                    } else {
                        VEHICLE_SPACE_M
                    },
                }
            })
            .collect()
    }

    /// Whether movers crowded the way within the last [`CROWD_CLEAR_S`]: three robots
    /// abreast cross a crowd as a 4 m wall, in a line as one robot's width.
    pub fn crowded(&self, now_s: f64) -> bool {
        self.crowded_s.is_some_and(|t| now_s - t <= CROWD_CLEAR_S)
    }

    /// Whether the fleet was among a crowd within the last [`CROWD_CLEAR_S`].
    pub fn dense(&self, now_s: f64) -> bool {
        self.dense_s.is_some_and(|t| now_s - t <= CROWD_CLEAR_S)
    }

    /// Whether the robots cannot count on `m` to steer round them: not seen near them
    /// long enough to know ([`KNOWN_S`]), or walking at the fleet standing for
    /// [`AIMING_S`].
    fn wary(&mut self, now_s: f64, m: &TrackView, robots: &[DVec2], footprint: f64) -> bool {
        let near = robots.iter().any(|r| r.distance(m.position) <= NEAR_M);
        if !near && !self.manners.contains_key(&m.id) {
            return true;
        }
        let manners = self.manners.entry(m.id).or_insert(Manners {
            first_s: now_s,
            aiming_since_s: None,
        });
        if aims(m, robots, footprint) {
            manners.aiming_since_s.get_or_insert(now_s);
        } else {
            manners.aiming_since_s = None;
        }
        now_s - manners.first_s < KNOWN_S
            || manners
                .aiming_since_s
                .is_some_and(|t| now_s - t >= AIMING_S)
    }
}

/// Whether `m` walks at one of `robots` standing: its mean way over [`TRUSTED_S`] comes
/// within [`AIMING_WITHIN_M`] of one's footprint. Not its disc grown by its uncertainty: a
/// track the scanner lost grows round the robots without anyone walking at them.
fn aims(m: &TrackView, robots: &[DVec2], footprint: f64) -> bool {
    let reach = m.radius.max(MIN_RADIUS_M) + footprint + AIMING_WITHIN_M;
    (1..=4).any(|k| {
        let at = m.at(k as f64 * TRUSTED_S / 4.0);
        robots.iter().any(|r| r.distance(at) < reach)
    })
}
