//! The station's tracker alone, on a scenario's movers: a scanner carried at a fixed pace
//! from the leader's start to the goal (the movers see it as a robot and steer round it
//! where they are social), every scan into a [`Tracker`], every track against the truth.
//!
//! A run of the whole fleet goes where its yielding takes it, so two trackers compared
//! there see different crowds; here the scanner's way and the crowd are the same for any
//! tracker, and what is measured is what yielding relies on: where a track says a person
//! is, and where it says they will be a second on.

use base_station::perception::tracking::{Motion, TrackView, Tracker};
use base_station::scenario::Scenario;
use glam::DVec2;
use serde::Serialize;

use crate::movers::{MoverState, Movers, RobotBody};
use crate::scanner::Scanner;

/// The scanner's pace, m/s: the leader's among people.
pub const PACE_MPS: f64 = 0.5;
/// The scan period, s (the leader's scanner's, 10 Hz).
const PERIOD_S: f64 = 0.1;
/// A track within this of a mover's footprint is that mover's, m.
const MATCH_M: f64 = 1.0;
/// Predictions are judged this far on, s.
const AHEAD_S: f64 = 1.0;
/// The scanner's footprint as the movers see it, m.
const FOOTPRINT_M: f64 = 0.3;
/// The tracks are judged against the movers within this of the scanner: where the fleet
/// decides about them, m.
const JUDGED_WITHIN_M: f64 = 8.0;

/// How well the tracks followed the movers over one run.
#[derive(Debug, Clone, Copy, Default, Serialize, PartialEq)]
pub struct TrackingFigures {
    /// Mover-samples within the scanner's reach moving faster than 0.3 m/s.
    pub samples: u64,
    /// Share of those with a moving track within 1 m of the footprint.
    pub detected_fraction: f64,
    /// Over the detected: mean distance from the track to the mover's centre, m.
    pub position_error_m: f64,
    /// Mean velocity error, m/s.
    pub velocity_error_mps: f64,
    /// Mean distance from where the track puts the mover a second on to where the mover
    /// is then, m; and the same taking the mover to stand where the track is now (what a
    /// track without a velocity would say).
    pub predicted_error_m: f64,
    pub standing_error_m: f64,
}

/// Sums of the figures, then their means.
#[derive(Default)]
struct Sums {
    samples: u64,
    detected: u64,
    /// Detected with the truth a second on (not in the run's last second).
    judged: u64,
    position: f64,
    velocity: f64,
    predicted: f64,
    standing: f64,
}

impl Sums {
    fn figures(&self) -> TrackingFigures {
        let per = |a: f64| {
            if self.detected > 0 {
                a / self.detected as f64
            } else {
                0.0
            }
        };
        TrackingFigures {
            samples: self.samples,
            detected_fraction: if self.samples > 0 {
                self.detected as f64 / self.samples as f64
            } else {
                0.0
            },
            position_error_m: per(self.position),
            velocity_error_mps: per(self.velocity),
            predicted_error_m: self.predicted / self.judged.max(1) as f64,
            standing_error_m: self.standing / self.judged.max(1) as f64,
        }
    }
}

/// One run of `scenario`'s movers (`seed`) past a scanner carried from the leader's start
/// towards the goal (or along its heading without one), for `duration_s`.
pub fn run(scenario: &Scenario, seed: u64, duration_s: f64) -> TrackingFigures {
    let site = scenario.build_site();
    let mut movers = Movers::new(scenario, &site, seed);
    let scanner = Scanner::new(scenario);
    let mut tracker = Tracker::new(scenario.yielding.personal_space_m);
    let start = scenario.leader().start;
    let from = DVec2::new(start.x, start.y);
    let way = scenario
        .route
        .goal
        .map(|g| DVec2::new(g[0], g[1]) - from)
        .filter(|d| d.length() > 1e-9)
        .unwrap_or_else(|| DVec2::from_angle(start.heading_deg.to_radians()))
        .normalize();
    let steps = (duration_s / PERIOD_S).round() as usize;
    let ahead = (AHEAD_S / PERIOD_S).round() as usize;
    // Each period's scanner position and the tracks and movers seen then.
    let mut frames: Vec<(DVec2, Vec<TrackView>, Vec<MoverState>)> = Vec::with_capacity(steps);
    for k in 0..steps {
        let t = k as f64 * PERIOD_S;
        let at = from + way * (PACE_MPS * t);
        let body = RobotBody {
            position: at,
            velocity: way * PACE_MPS,
            radius: FOOTPRINT_M,
        };
        movers.step(t, PERIOD_S, &[body], &site);
        let states: Vec<MoverState> = movers.states(t).collect();
        let hits = scanner.scan(at, &site, &states);
        let now_ms = (t * 1000.0).round() as u32;
        tracker.observe(&hits, at, now_ms);
        let tracks = tracker
            .views(now_ms)
            .filter(|v| v.motion == Motion::Moving)
            .collect();
        frames.push((at, tracks, states));
    }
    let mut sums = Sums::default();
    for (k, (at, tracks, states)) in frames.iter().enumerate() {
        let later = frames.get(k + ahead).map(|f| &f.2);
        for m in states
            .iter()
            .filter(|m| m.velocity.length() > 0.3 && m.position.distance(*at) <= JUDGED_WITHIN_M)
        {
            sums.samples += 1;
            let nearest = tracks
                .iter()
                .map(|t| (m.distance(t.position), t))
                .filter(|(d, _)| *d <= MATCH_M)
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let Some((_, t)) = nearest else { continue };
            sums.detected += 1;
            sums.position += t.position.distance(m.position);
            sums.velocity += (t.velocity - m.velocity).length();
            if let Some(then) = later.and_then(|l| l.iter().find(|o| o.index == m.index)) {
                sums.judged += 1;
                sums.predicted += t.at(AHEAD_S).distance(then.position);
                sums.standing += t.position.distance(then.position);
            }
        }
    }
    sums.figures()
}
