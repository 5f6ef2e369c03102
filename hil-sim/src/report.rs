//! The run's report: a public interface. `schema_version` 2 keeps every schema-1 key and
//! adds per-follower join times, percentiles and transformation errors, and a reason per
//! transformation; 3 adds what the robots did among the movers (`movers`). Every key is
//! documented in `docs/sim.md`. 4 judges each mover contact as the safety standards do
//! (`movers.drove_into`, `walked_into_standing`, `walked_into_braking`, and per contact the
//! robot's speed, the closing speed and the robot's energy), floors
//! `min_person_clearance_m` at 0 (the overlap is `deepest_person_overlap_m`), adds
//! `min_vehicle_clearance_m`, and leaves the tracking errors null where nothing was
//! detected. 5 adds `coverage` where the scenario has areas to sweep. 6 adds
//! `link.channel`: the channel's use and losses, each robot's delivery and leader-state age.

use std::collections::BTreeMap;

use base_station::formation::{Target, Transformation};
use base_station::planner::route::Route;
use base_station::scenario::{Role, Scenario};
use glam::DVec2;
use serde::Serialize;

use crate::metrics::{Recorder, Sample, SAMPLE_PERIOD_US};

pub const SCHEMA_VERSION: u32 = 6;

/// A follower has joined at its first sample under this error, m.
pub const JOINED_BELOW_M: f64 = 0.1;

/// A shape change as the report shows it.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct TransformationReport {
    pub to: String,
    pub start_s: f64,
    /// From the start until the slots reached the new shape and every follower is back
    /// under 0.1 m; null if that never happened.
    pub duration_s: Option<f64>,
    /// From the start until the slots reached the new shape (later than the nominal
    /// change where the station slowed it for its followers); null if the next change
    /// cut it short.
    pub shaped_s: Option<f64>,
    /// Why: `passage_ahead` (into the line), `passage_behind` (back to the wide shape).
    pub reason: String,
}

#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct RobotReport {
    pub id: u16,
    pub role: String,
    pub avg_speed_mps: f64,
    pub avg_abs_omega_radps: f64,
    /// Followers: max error from their own join to the end of the run (everything:
    /// obstacles, transformations); over the whole run if they never joined.
    pub max_tracking_error_m: Option<f64>,
    /// Followers: max error after their join outside transformations and away from
    /// obstacles (the paper's "stable phases").
    pub stable_max_tracking_error_m: Option<f64>,
    /// Followers: the first sample under 0.1 m; null if never.
    pub joined_at_s: Option<f64>,
    /// Followers: 95th percentile of the error after their join.
    pub p95_tracking_error_m: Option<f64>,
    /// Followers: share of the samples after their join with the error under 0.1 m.
    pub time_within_0_1m_fraction: Option<f64>,
    /// Followers: max error after their join while the formation changes shape (and 3 s
    /// after); null without a transformation after the join.
    pub max_tracking_error_transforming_m: Option<f64>,
    /// Mean |ω| on straight legs (see [`straight_legs`]); followers after their join. Null
    /// when the run had no straight leg.
    pub straight_avg_abs_omega_radps: Option<f64>,
    /// Followers: mean |ω| after their join where their own reference point runs straight
    /// (see [`slot_straight_legs`]); null where it never did.
    pub slot_straight_avg_abs_omega_radps: Option<f64>,
    /// Followers: the time that mean is over, s.
    pub slot_straight_time_s: Option<f64>,
}

#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct LinkReport {
    pub frames_sent: u64,
    pub frames_delivered: u64,
    pub frames_rejected: u64,
    /// Rejected frames by reason, over every receiver.
    pub rejects_by_reason: BTreeMap<String, u64>,
    /// The channel: its use, its losses, each robot's delivery and leader-state age
    /// (schema 6).
    pub channel: ChannelReport,
}

/// The radio channel over the run (schema 6).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ChannelReport {
    /// The `[link] radio` preset, or `own_air` (each transmitter has air of its own).
    pub radio: String,
    /// `csma`, `aloha` or `scheduled`; null with `own_air`.
    pub access: Option<String>,
    /// Share of the run with at least one frame on the air.
    pub utilisation: f64,
    pub frames_on_air: u64,
    /// Frame copies lost at a receiver to another frame on the air at the same time.
    pub collisions: u64,
    /// Copies a receiver missed because it was sending.
    pub half_duplex_losses: u64,
    /// Frames a full modem queue (8 frames) pushed out.
    pub queue_drops: u64,
    /// Frames longer than any slot their sender has.
    pub unsendable: u64,
    /// With `scheduled` access.
    pub schedule: Option<ScheduleReport>,
    pub robots: Vec<RobotLinkReport>,
}

/// The base station's schedule of the channel (schema 6).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ScheduleReport {
    pub period_ms: f64,
    pub downlink_ms: f64,
    pub leader_slot_ms: f64,
    /// A follower's slot.
    pub slot_ms: f64,
    pub uplink_slots_per_period: u64,
    /// Periods between two slots of a follower (the leader has one every period).
    pub follower_every_periods: Option<u64>,
}

/// One robot's link over the run (schema 6).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct RobotLinkReport {
    pub id: u16,
    /// Delivered share of the frame copies it sent to the station.
    pub uplink_delivery: Option<f64>,
    /// Delivered share of the frame copies addressed to it (broadcasts included).
    pub downlink_delivery: Option<f64>,
    /// Age of the leader-state frames that reached it, from the station handing each to
    /// its radio, ms.
    pub leader_state_age_ms_p50: Option<f64>,
    pub leader_state_age_ms_p99: Option<f64>,
    /// The longest time between two leader states reaching it, ms.
    pub leader_state_gap_ms_max: Option<f64>,
}

/// Something the base station noticed, for the report.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct StationEventReport {
    pub at_s: f64,
    pub event: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub robot: Option<u16>,
}

#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Report {
    pub schema_version: u32,
    pub scenario: String,
    pub seed: u64,
    pub firmware: String,
    pub sim_time_s: f64,
    pub wall_time_s: f64,
    /// A real-time run's start on the Unix clock, ms (`robots`: the same clock as `run`'s
    /// summary, to line the two up); absent from a simulation, whose report depends on
    /// nothing but its scenario and seed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub started_unix_ms: Option<u64>,
    /// A baseline run (`sim --baseline`): `parked` or `ignore_movers`; absent from a run
    /// with the station's manners (schema 4).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub baseline: Option<String>,
    pub goal_reached: bool,
    pub time_to_goal_s: Option<f64>,
    /// How the run ended (schema 4): `goal_reached`, `time_up`, `leader_lost`, `halted`,
    /// `localization_lost`, `no_route`, `stopped`, `never_linked`, or `external` (the
    /// station was another process: its summary says why).
    pub ending: String,
    /// Why, in one line: the same line as the summary, the figure and the console.
    pub why: String,
    pub collisions: u32,
    pub min_obstacle_clearance_m: f64,
    pub min_robot_separation_m: f64,
    /// The first sample with every follower under 0.1 m at once.
    pub convergence_time_s: Option<f64>,
    /// Time the samples spent on straight legs (what `straight_avg_abs_omega_radps` averages).
    pub straight_leg_time_s: f64,
    pub robots: Vec<RobotReport>,
    pub transformations: Vec<TransformationReport>,
    pub link: LinkReport,
    /// What the base station noticed (links, formation changes, a lost leader, …).
    pub station_events: Vec<StationEventReport>,
    /// What the robots did among the people, cyclists and vehicles on the site.
    pub movers: MoversReport,
    /// What the brushes swept (schema 5; only with `[[sweep]]` areas).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coverage: Option<crate::swept::SweepReport>,
}

/// The robots among the movers (schema 3).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct MoversReport {
    /// Movers on the site over the run (crowds' persons included).
    pub count: usize,
    /// Contacts with a mover while the robot moved (faster than 0.05 m/s), whoever's
    /// doing: `drove_into` + `walked_into_braking`.
    pub contacts_moving: u32,
    /// Contacts of a mover with a robot that stood: `walked_into_standing`.
    pub contacts_standing: u32,
    /// Contacts where the robot's velocity toward the mover was over 0.1 m/s and larger
    /// than the mover's toward the robot: the robot struck them (schema 4).
    pub drove_into: u32,
    /// Contacts where the mover walked (rode, drove) into a robot standing, and into one
    /// still moving but not closing as fast as they did (schema 4).
    pub walked_into_standing: u32,
    pub walked_into_braking: u32,
    /// The least gap between a robot's footprint and a person's (pedestrian or cyclist),
    /// m, 0 at a contact; null without persons.
    pub min_person_clearance_m: Option<f64>,
    /// How deep a robot's footprint and a person's overlapped at worst, m; null without
    /// persons (schema 4).
    pub deepest_person_overlap_m: Option<f64>,
    /// The least gap between a robot's footprint and a vehicle's, m, 0 at a contact;
    /// null without vehicles (schema 4).
    pub min_vehicle_clearance_m: Option<f64>,
    /// Time a moving robot was within 0.5 m of a person's footprint, s.
    pub intrusion_s: f64,
    /// The same, robot by robot (the run's order, as in `contacts[].robot`), s.
    pub intrusion_by_robot_s: Vec<f64>,
    /// Time the leader stood with a person within 1.5 m of its footprint, s.
    pub freezing_s: f64,
    /// The same scenario and seed with nobody on the site: its time to goal (null: not
    /// run, or the goal not reached).
    pub time_to_goal_empty_s: Option<f64>,
    /// Contacts with movers per robot-hour of the run (schema 4).
    pub contacts_per_robot_hour: f64,
    /// The same for robots standing, for the whole run, where this run's robots were
    /// (once a second), walked into by the movers who keep to their way whatever is in
    /// it: the parked fleet this one is judged against (`exposure.rs`); null without such
    /// movers (schema 4).
    pub parked_contacts_per_robot_hour: Option<f64>,
    /// The first 100 contacts, one by one.
    pub contacts: Vec<crate::metrics::MoverContact>,
    /// How well the station's tracks matched the movers (null without movers).
    pub tracking: Option<TrackingReport>,
}

/// The station's tracks against the truth, over the samples (10 Hz), for the movers
/// within the leader's scanner's reach.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct TrackingReport {
    /// Mover-samples within reach, moving faster than 0.3 m/s.
    pub moving_samples: u64,
    /// Share of those with a moving track within 1 m of its footprint (null: none in
    /// reach).
    pub detected_fraction: Option<f64>,
    /// Over the detected: mean distance from the track to the mover's centre, m, and
    /// mean velocity error, m/s (null: none detected).
    pub mean_position_error_m: Option<f64>,
    pub mean_velocity_error_mps: Option<f64>,
    /// Share of the detected whose velocity error is within two of the track's sigmas
    /// (null: none detected).
    pub velocity_within_2_sigma_fraction: Option<f64>,
    /// Moving tracks with no mover within 1 m of them, per moving track-sample (null: no
    /// moving track).
    pub false_moving_fraction: Option<f64>,
}

fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

/// The tracks are judged against the movers within this of the leader: where the
/// fleet's decisions about them are made, m.
const TRACKING_REACH_M: f64 = 8.0;

impl TrackingReport {
    pub fn of(rec: &Recorder, leader: Option<usize>) -> Option<Self> {
        let leader = leader?;
        let (mut n, mut found, mut pos, mut vel, mut within) = (0u64, 0u64, 0.0, 0.0, 0u64);
        let (mut tracks, mut false_moving) = (0u64, 0u64);
        for s in rec.samples.iter().filter(|s| !s.movers.is_empty()) {
            let l = glam::DVec2::new(s.robots[leader].x, s.robots[leader].y);
            let moving: Vec<_> = s
                .tracks
                .iter()
                .filter(|t| t.motion == base_station::perception::tracking::Motion::Moving)
                .collect();
            for m in s
                .movers
                .iter()
                .filter(|m| m.velocity.length() > 0.3 && m.position.distance(l) <= TRACKING_REACH_M)
            {
                n += 1;
                let near = moving
                    .iter()
                    .map(|t| (m.distance(t.position), t))
                    .filter(|(d, _)| *d <= 1.0)
                    .min_by(|a, b| a.0.total_cmp(&b.0));
                if let Some((_, t)) = near {
                    found += 1;
                    pos += t.position.distance(m.position);
                    let e = (t.velocity - m.velocity).length();
                    vel += e;
                    within += (e <= 2.0 * t.velocity_sigma * std::f64::consts::SQRT_2) as u64;
                }
            }
            for t in &moving {
                tracks += 1;
                false_moving += s.movers.iter().all(|m| m.distance(t.position) > 1.0) as u64;
            }
        }
        let per = |a: f64, b: u64| (b > 0).then(|| a / b as f64);
        (n > 0 || tracks > 0).then(|| Self {
            moving_samples: n,
            detected_fraction: per(found as f64, n),
            mean_position_error_m: per(pos, found),
            mean_velocity_error_mps: per(vel, found),
            velocity_within_2_sigma_fraction: per(within as f64, found),
            false_moving_fraction: per(false_moving as f64, tracks),
        })
    }
}

impl MoversReport {
    /// The measures of a run (`time_to_goal_empty_s` is filled by whoever ran the empty
    /// site); `robots`: how many, over `sim_time_s`.
    pub fn of(rec: &Recorder, count: usize, robots: usize, sim_time_s: f64) -> Self {
        let m = &rec.movers;
        let contacts = m.drove_into + m.walked_into_standing + m.walked_into_braking;
        let hours = robots as f64 * sim_time_s / 3600.0;
        Self {
            count,
            contacts_moving: m.contacts_moving,
            contacts_standing: m.contacts_standing,
            drove_into: m.drove_into,
            walked_into_standing: m.walked_into_standing,
            walked_into_braking: m.walked_into_braking,
            min_person_clearance_m: finite(m.min_person_clearance_m),
            deepest_person_overlap_m: finite(m.min_person_clearance_m)
                .map(|_| m.deepest_person_overlap_m),
            min_vehicle_clearance_m: finite(m.min_vehicle_clearance_m),
            intrusion_s: m.intrusion_s,
            intrusion_by_robot_s: m.intrusion_by_robot_s.clone(),
            freezing_s: m.freezing_s,
            time_to_goal_empty_s: None,
            contacts_per_robot_hour: if hours > 0.0 {
                contacts as f64 / hours
            } else {
                0.0
            },
            parked_contacts_per_robot_hour: crate::exposure::parked_where_it_went(
                &rec.samples,
                rec.footprint(),
            ),
            contacts: m.contacts.clone(),
            tracking: None,
        }
    }

    /// Time to goal over the empty site's, if both reached it.
    pub fn slowdown(&self, time_to_goal_s: Option<f64>) -> Option<f64> {
        Some(time_to_goal_s? / self.time_to_goal_empty_s?)
    }
}

impl Report {
    /// The station events of one name (`follower_detour`, `replanned`, …), in order.
    pub fn events_named<'a>(
        &'a self,
        name: &'a str,
    ) -> impl Iterator<Item = &'a StationEventReport> + 'a {
        self.station_events.iter().filter(move |e| e.event == name)
    }
}

/// Follower errors of a sample (all followers), if every one is known.
fn errors(s: &Sample) -> Vec<f64> {
    s.robots.iter().filter_map(|r| r.error).collect()
}

/// The transformations, with their durations measured on the samples.
pub fn transformations(
    rec: &Recorder,
    done: &[Transformation],
    wide_name: &str,
    transition_s: f64,
) -> Vec<TransformationReport> {
    done.iter()
        .map(|tr| {
            let shaped = tr.end_s.unwrap_or(tr.start_s + transition_s);
            let back = rec
                .samples
                .iter()
                .find(|s| s.t >= shaped - 1e-9 && errors(s).iter().all(|e| *e < JOINED_BELOW_M))
                .map(|s| s.t - tr.start_s);
            TransformationReport {
                to: match tr.to {
                    Target::Line => "line".to_string(),
                    Target::Wide => wide_name.to_string(),
                },
                start_s: tr.start_s,
                duration_s: back,
                shaped_s: tr.end_s.map(|end| end - tr.start_s),
                reason: tr.reason.name().to_string(),
            }
        })
        .collect()
}

fn max(values: impl Iterator<Item = f64>) -> Option<f64> {
    values.fold(None, |m, e| Some(m.map_or(e, |m: f64| m.max(e))))
}

/// The `q` quantile (nearest rank) of `values`.
pub(crate) fn quantile(mut values: Vec<f64>, q: f64) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    let rank = ((q * values.len() as f64).ceil() as usize).clamp(1, values.len());
    Some(values[rank - 1])
}

/// A straight leg: the leader's path from the formation's length + 1 m behind it to 1 m
/// ahead of it (where it drives next) keeps within this of the chord, m.
pub const STRAIGHT_WITHIN_M: f64 = 0.05;
/// The least speed of the leader on a straight leg, m/s.
const STRAIGHT_MIN_SPEED: f64 = 0.1;

/// Which samples are on a straight leg: the leader's driven path over the whole formation's
/// length behind it and 1 m ahead is straight (within [`STRAIGHT_WITHIN_M`]), the leader
/// moves, and the shape is settled (not changing) over that stretch. Where the leader
/// itself wiggles, the stretch is still straight: its wiggles count against it.
pub fn straight_legs(samples: &[Sample], leader: usize, reach: f64) -> Vec<bool> {
    let path = samples
        .iter()
        .map(|s| Some(DVec2::new(s.robots[leader].x, s.robots[leader].y)))
        .collect();
    straight_along(samples, path, reach + 1.0, 1.0, |s| {
        s.robots[leader].v >= STRAIGHT_MIN_SPEED
    })
}

/// Which samples have follower `i`'s reference point on a straight stretch of its own
/// path: [`SLOT_LEG_M`] back and ahead of it within [`STRAIGHT_WITHIN_M`] of the chord,
/// moving, the shape settled. A big formation's rear slots run straight long before the
/// leader's path is straight over the formation's whole length (a 7-follower line on a
/// gently curving street: 0.7 s of the leader's legs in 100 s).
pub fn slot_straight_legs(samples: &[Sample], i: usize) -> Vec<bool> {
    let path = samples
        .iter()
        .map(|s| s.robots[i].slot.map(|(x, y)| DVec2::new(x, y)))
        .collect();
    straight_along(samples, path, SLOT_LEG_M, SLOT_LEG_M, |s| {
        s.robots[i].v >= STRAIGHT_MIN_SPEED
    })
}

/// How far back and ahead along a follower's reference path it must run straight, m.
pub const SLOT_LEG_M: f64 = 1.5;

/// Samples where `path` (one point per sample, `None` where there is none) runs straight
/// from `behind` metres back to `ahead` metres on, `moving` holds, and the shape is
/// settled over that stretch.
fn straight_along(
    samples: &[Sample],
    path: Vec<Option<DVec2>>,
    behind: f64,
    ahead: f64,
    moving: impl Fn(&Sample) -> bool,
) -> Vec<bool> {
    let known: Vec<usize> = (0..path.len()).filter(|i| path[*i].is_some()).collect();
    let mut on = vec![false; samples.len()];
    // Stretches of consecutive samples with a point; a gap starts a new path.
    for run in known.chunk_by(|a, b| b - a == 1) {
        let Route { points, arc } = Route::new(run.iter().map(|i| path[*i].unwrap()).collect());
        let (mut from, mut to) = (0, 0);
        for (k, &i) in run.iter().enumerate() {
            while arc[from] < arc[k] - behind {
                from += 1;
            }
            while to + 1 < arc.len() && arc[to] < arc[k] + ahead {
                to += 1;
            }
            let long_enough = arc[k] - arc[from] >= behind - 0.2 && arc[to] - arc[k] >= ahead - 0.2;
            if !long_enough || !moving(&samples[i]) {
                continue;
            }
            let settled = run[from..=to]
                .iter()
                .all(|j| matches!(samples[*j].shape, "wide" | "line"));
            let (a, b) = (points[from], points[to]);
            let chord = (b - a).normalize_or_zero();
            on[i] = settled
                && points[from..=to]
                    .iter()
                    .all(|p| (*p - a).perp_dot(chord).abs() <= STRAIGHT_WITHIN_M);
        }
    }
    on
}

fn mean(values: impl Iterator<Item = f64>) -> Option<f64> {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    (n > 0).then(|| sum / n as f64)
}

/// What the run measured, besides the link and the station's events.
pub struct RunFacts<'a> {
    pub scenario: &'a Scenario,
    /// Each robot's id and role, in the samples' order.
    pub roles: &'a [(u16, Role)],
    pub seed: u64,
    pub firmware: &'a str,
    pub sim_time_s: f64,
    pub wall_time_s: f64,
    pub time_to_goal_s: Option<f64>,
    /// Movers on the site over the run.
    pub movers: usize,
}

pub fn build_report(
    rec: &Recorder,
    facts: &RunFacts<'_>,
    transformations: Vec<TransformationReport>,
    link: LinkReport,
) -> Report {
    let scenario = facts.scenario;
    let convergence = rec
        .samples
        .iter()
        .find(|s| {
            let e = errors(s);
            !e.is_empty() && e.iter().all(|e| *e < JOINED_BELOW_M)
        })
        .map(|s| s.t);
    let judge = Judge::new(rec, facts, &transformations);
    let straight_leg_time_s =
        judge.straight.iter().filter(|s| **s).count() as f64 * SAMPLE_PERIOD_US as f64 / 1e6;
    let robots = facts
        .roles
        .iter()
        .enumerate()
        .map(|(i, (id, role))| judge.robot(i, *id, *role))
        .collect();
    Report {
        schema_version: SCHEMA_VERSION,
        scenario: scenario.name.clone(),
        seed: facts.seed,
        firmware: facts.firmware.to_string(),
        sim_time_s: facts.sim_time_s,
        wall_time_s: facts.wall_time_s,
        started_unix_ms: None,
        baseline: None,
        goal_reached: facts.time_to_goal_s.is_some(),
        ending: String::new(),
        why: String::new(),
        time_to_goal_s: facts.time_to_goal_s,
        collisions: rec.contacts + rec.movers.contacts_moving + rec.movers.contacts_standing,
        min_obstacle_clearance_m: rec.min_clearance,
        min_robot_separation_m: rec.min_separation,
        convergence_time_s: convergence,
        straight_leg_time_s,
        robots,
        transformations,
        link,
        station_events: Vec::new(),
        movers: MoversReport {
            tracking: TrackingReport::of(
                rec,
                facts.roles.iter().position(|(_, r)| *r == Role::Leader),
            ),
            ..MoversReport::of(rec, facts.movers, facts.roles.len(), facts.sim_time_s)
        },
        coverage: rec.sweeping.as_ref().map(|s| s.report()),
    }
}

/// What each robot's figures are judged against: the samples, the leader's straight legs,
/// the shape changes' busy windows, and how long the fleet was moving.
struct Judge<'a> {
    rec: &'a Recorder,
    /// Per sample: on one of the leader's straight legs.
    straight: Vec<bool>,
    /// (from, to), s: a shape change from its start until the slots are shaped and the
    /// followers back (or the blend's end if they never came back), plus 3 s.
    busy: Vec<(f64, f64)>,
    moving_until: f64,
}

impl<'a> Judge<'a> {
    fn new(
        rec: &'a Recorder,
        facts: &RunFacts<'_>,
        transformations: &[TransformationReport],
    ) -> Self {
        let spec = facts.scenario.formation_spec();
        let transition = spec.transition_duration();
        let busy = transformations
            .iter()
            .map(|t| {
                let shaped = t.shaped_s.unwrap_or(transition);
                let end = t.start_s + shaped.max(t.duration_s.unwrap_or(0.0));
                (t.start_s, end + 3.0)
            })
            .collect();
        let reach = spec
            .wide_slots()
            .into_iter()
            .chain(spec.line_slots())
            .map(|(l, _)| l)
            .fold(0.0, f64::max);
        let straight = match facts.roles.iter().position(|(_, r)| *r == Role::Leader) {
            Some(leader) => straight_legs(&rec.samples, leader, reach),
            None => vec![false; rec.samples.len()],
        };
        Self {
            rec,
            straight,
            busy,
            moving_until: facts.time_to_goal_s.unwrap_or(facts.sim_time_s),
        }
    }

    fn in_busy(&self, t: f64) -> bool {
        self.busy.iter().any(|(a, b)| t >= *a && t <= *b)
    }

    /// Robot `i`'s mean |ω| on the leader's straight legs from `since` on.
    fn straight_omega(&self, i: usize, since: f64) -> Option<f64> {
        mean(
            self.rec
                .samples
                .iter()
                .zip(&self.straight)
                .filter(|(s, on)| **on && s.t >= since)
                .map(|(s, _)| s.robots[i].omega.abs()),
        )
    }

    /// Robot `i`'s report: its speeds while the fleet moved, and a follower's errors.
    fn robot(&self, i: usize, id: u16, role: Role) -> RobotReport {
        let moving: Vec<_> = self
            .rec
            .samples
            .iter()
            .filter(|s| s.t <= self.moving_until)
            .map(|s| &s.robots[i])
            .collect();
        let n = moving.len().max(1) as f64;
        let report = RobotReport {
            id,
            role: role.name().into(),
            avg_speed_mps: moving.iter().map(|r| r.v.abs()).sum::<f64>() / n,
            avg_abs_omega_radps: moving.iter().map(|r| r.omega.abs()).sum::<f64>() / n,
            max_tracking_error_m: None,
            stable_max_tracking_error_m: None,
            joined_at_s: None,
            p95_tracking_error_m: None,
            time_within_0_1m_fraction: None,
            max_tracking_error_transforming_m: None,
            straight_avg_abs_omega_radps: None,
            slot_straight_avg_abs_omega_radps: None,
            slot_straight_time_s: None,
        };
        if role != Role::Follower {
            return RobotReport {
                straight_avg_abs_omega_radps: self.straight_omega(i, 0.0),
                ..report
            };
        }
        self.follower(i, report)
    }

    /// A follower's figures: when it joined, its tracking errors after, its turning
    /// where its own reference runs straight.
    fn follower(&self, i: usize, mut report: RobotReport) -> RobotReport {
        let samples = &self.rec.samples;
        let errors: Vec<(&Sample, f64)> = samples
            .iter()
            .filter_map(|s| s.robots[i].error.map(|e| (s, e)))
            .collect();
        let joined = errors
            .iter()
            .find(|(_, e)| *e < JOINED_BELOW_M)
            .map(|(s, _)| s.t);
        let after: Vec<(&Sample, f64)> = errors
            .iter()
            .filter(|(s, _)| joined.is_some_and(|j| s.t >= j))
            .copied()
            .collect();
        report.joined_at_s = joined;
        report.straight_avg_abs_omega_radps = joined.and_then(|j| self.straight_omega(i, j));
        if let Some(j) = joined {
            let own: Vec<f64> = samples
                .iter()
                .zip(slot_straight_legs(samples, i))
                .filter(|(s, on)| *on && s.t >= j)
                .map(|(s, _)| s.robots[i].omega.abs())
                .collect();
            report.slot_straight_time_s = Some(own.len() as f64 * SAMPLE_PERIOD_US as f64 / 1e6);
            report.slot_straight_avg_abs_omega_radps = mean(own.into_iter());
        }
        report.max_tracking_error_m = if joined.is_some() {
            max(after.iter().map(|(_, e)| *e))
        } else {
            max(errors.iter().map(|(_, e)| *e))
        };
        report.stable_max_tracking_error_m = max(after
            .iter()
            .filter(|(s, _)| !s.near_obstacle && !self.in_busy(s.t))
            .map(|(_, e)| *e));
        report.p95_tracking_error_m = quantile(after.iter().map(|(_, e)| *e).collect(), 0.95);
        report.time_within_0_1m_fraction = (!after.is_empty()).then(|| {
            after.iter().filter(|(_, e)| *e < JOINED_BELOW_M).count() as f64 / after.len() as f64
        });
        report.max_tracking_error_transforming_m = max(after
            .iter()
            .filter(|(s, _)| self.in_busy(s.t))
            .map(|(_, e)| *e));
        report
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use base_station::formation::Reason;

    /// The leader at 0.4 m/s along `path(t)`, one sample per 0.1 s.
    fn samples(
        path: impl Fn(f64) -> (f64, f64),
        shape: impl Fn(f64) -> &'static str,
    ) -> Vec<Sample> {
        (0..400)
            .map(|k| {
                let t = k as f64 * 0.1;
                let (x, y) = path(t);
                Sample {
                    t,
                    robots: vec![crate::metrics::RobotSample {
                        x,
                        y,
                        heading: 0.0,
                        v: 0.4,
                        omega: 0.0,
                        slot: None,
                        error: None,
                        mode: None,
                    }],
                    blend: 0.0,
                    shape: shape(t),
                    near_obstacle: false,
                    movers: Vec::new(),
                    tracks: Vec::new(),
                }
            })
            .collect()
    }

    /// A change the station slowed: it lasts until its slots arrived (`end_s`), not its
    /// nominal duration, though a follower is back under 0.1 m before.
    #[test]
    fn a_slowed_change_lasts_until_its_slots_arrived() {
        let paper = include_str!("../../scenarios/paper-passage.toml");
        let mut rec = Recorder::new(&Scenario::parse(paper, "paper-passage").unwrap());
        rec.samples = samples(|t| (0.4 * t, 0.0), |_| "wide");
        for s in &mut rec.samples {
            s.robots[0].error = Some(if (2.0..4.0).contains(&s.t) { 0.2 } else { 0.05 });
        }
        let change = |end_s| Transformation {
            to: Target::Line,
            start_s: 1.0,
            end_s,
            reason: Reason::PassageAhead,
        };
        let nominal = transformations(&rec, &[change(None)], "v", 4.0);
        assert_eq!(nominal[0].shaped_s, None);
        assert!((nominal[0].duration_s.unwrap() - 4.0).abs() < 1e-9);
        let slowed = transformations(&rec, &[change(Some(11.0))], "v", 4.0);
        assert_eq!(slowed[0].shaped_s, Some(10.0));
        assert!((slowed[0].duration_s.unwrap() - 10.0).abs() < 1e-9);
    }

    #[test]
    fn straight_legs_are_straight_settled_stretches_of_the_leaders_path() {
        let wide = |_| "wide";
        // A straight line: straight once the formation's length (3 m + 1 m) lies behind,
        // until 1 m before the end.
        let line = straight_legs(&samples(|t| (0.4 * t, 0.0), wide), 0, 3.0);
        assert!(!line[5] && line[150] && !line[399]);
        // A 5 m circle: never (its sagitta over 5 m is 0.6 m).
        let r = 5.0;
        let circle = straight_legs(
            &samples(
                |t| (r * (0.4 * t / r).sin(), r * (1.0 - (0.4 * t / r).cos())),
                wide,
            ),
            0,
            3.0,
        );
        assert!(circle.iter().all(|s| !s));
        // A wiggle of ±2 cm still counts (the leader's own wiggles count against it; the
        // chord's ends wiggle too), ±10 cm does not; nor does a stretch in which the shape
        // changes.
        let wiggle = |a: f64| move |t: f64| (0.4 * t, a * (t * 3.0).sin());
        assert!(straight_legs(&samples(wiggle(0.02), wide), 0, 3.0)[150]);
        assert!(!straight_legs(&samples(wiggle(0.1), wide), 0, 3.0)[150]);
        let changing = straight_legs(
            &samples(
                |t| (0.4 * t, 0.0),
                |t| {
                    if (14.0..16.0).contains(&t) {
                        "to_line"
                    } else {
                        "wide"
                    }
                },
            ),
            0,
            3.0,
        );
        assert!(!changing[150] && changing[300]);
    }

    /// A follower's own legs: where its reference runs straight 1.5 m back and ahead, on a
    /// path the leader's straight legs never cover whole (a 12 m formation on a 20 m
    /// radius arc that straightens out at t = 20 s); none where it has no reference.
    #[test]
    fn a_followers_own_legs_follow_its_reference() {
        let bend = |t: f64| {
            let s = 0.4 * t;
            if s < 8.0 {
                (20.0 * (s / 20.0).sin(), 20.0 * (1.0 - (s / 20.0).cos()))
            } else {
                let (a, c) = ((8.0f64 / 20.0).sin(), (8.0f64 / 20.0).cos());
                (20.0 * a + (s - 8.0) * c, 20.0 * (1.0 - c) + (s - 8.0) * a)
            }
        };
        let mut run = samples(bend, |_| "line");
        for (k, s) in run.iter_mut().enumerate() {
            let (x, y) = (s.robots[0].x, s.robots[0].y);
            s.robots[0].slot = (k >= 10).then_some((x, y));
        }
        let own = slot_straight_legs(&run, 0);
        // On the arc (sagitta over 3 m: 5.6 cm), no; well past the bend, yes; before the
        // reference existed, no.
        assert!(!own[100] && own[300] && !own[5]);
        // The leader's legs over a 12 m formation need 13 m of straight behind: never
        // within these 8 m.
        assert!(straight_legs(&run, 0, 12.0).iter().all(|on| !on));
    }

    #[test]
    fn quantile_is_nearest_rank() {
        let v: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(quantile(v.clone(), 0.95), Some(95.0));
        assert_eq!(quantile(v, 1.0), Some(100.0));
        assert_eq!(quantile(vec![3.0], 0.95), Some(3.0));
        assert_eq!(quantile(Vec::new(), 0.95), None);
    }
}
