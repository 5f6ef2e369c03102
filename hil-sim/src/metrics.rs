//! What a run measured: samples at 10 Hz for the figure, the trace and the report; contacts
//! and clearances at every physics step. Knows bodies, not the world that moves them.
//!
//! Definitions (also in `docs/sim.md`): tracking error = distance from a follower's
//! control point to its reference point, computed from the **true** leader: the wide slot
//! point rigid to the leader's pose, the line slot point its distance back along the path
//! the leader **drove** (recorded here at every physics step), blended by the station's
//! blend at the sample's instant. Clearance = footprint to obstacle surface. Robot separation = footprint
//! to footprint.

use rustc_hash::FxHashSet;

use base_station::formation::{back_along, Target};
use base_station::geometry::map::Map;
use base_station::scenario::{Role, Scenario};
use base_station::station::BaseStation;
use glam::DVec2;
use protocol::messages::RobotMode;
use serde::Serialize;

use crate::movers::MoverState;
use crate::plant::Body;
use base_station::perception::tracking::TrackView;
use base_station::scenario::movers::MoverKind;

/// Samples for the figure, the trace and the report: 10 Hz.
pub const SAMPLE_PERIOD_US: u64 = 100_000;

/// A robot as the recorder sees it: who it is and its body (the world's robots implement
/// it, so the recorder reads them where they are, at every physics step).
pub trait Tracked {
    fn id(&self) -> u16;
    fn role(&self) -> Role;
    fn body(&self) -> &Body;
}

/// A slot's (L, φ) in the wide formation, and in the line.
pub type SlotPair = ((f64, f64), (f64, f64));

/// What the recorder needs from whoever runs the formation: the shape at an instant and
/// each slot, and what each robot last said of its mode. The base station in `sim`; in
/// `robots`, whose station is another process, what was heard on the air.
pub trait FleetView {
    /// 0 = wide, 1 = line, at `t_us` on the world's clock: where the transition under way
    /// has the blend then (the followers extrapolate to it too), not where it was at the
    /// station's last step.
    fn blend(&self, t_us: u64) -> f64;
    fn target(&self) -> Target;
    /// A follower's slot's (L, φ), wide and line, as the station last handed it out.
    fn slot(&self, robot: u16) -> Option<SlotPair>;
    fn mode(&self, robot: u16) -> Option<RobotMode>;
    /// What the station tracks at `t_us` (none where the station is not in this process).
    fn tracks(&self, _t_us: u64) -> Vec<TrackView> {
        Vec::new()
    }
}

/// The base station in the world, whose clock started at `epoch_us` of the world's.
pub struct StationView<'a> {
    pub station: &'a BaseStation,
    pub epoch_us: u64,
}

impl FleetView for StationView<'_> {
    fn blend(&self, t_us: u64) -> f64 {
        let station_s = t_us.saturating_sub(self.epoch_us) as f64 / 1e6;
        self.station.formation().blend_at(station_s)
    }
    fn target(&self) -> Target {
        self.station.formation().target()
    }
    fn slot(&self, robot: u16) -> Option<SlotPair> {
        let k = self.station.slot_of(robot)?;
        let f = self.station.formation();
        Some((*f.wide_slots().get(k)?, *f.line_slots().get(k)?))
    }
    fn mode(&self, robot: u16) -> Option<RobotMode> {
        self.station
            .robots()
            .get(&robot)
            .and_then(|s| s.telemetry)
            .map(|t| t.mode)
    }
    fn tracks(&self, t_us: u64) -> Vec<TrackView> {
        let now_ms = (t_us.saturating_sub(self.epoch_us) / 1000) as u32;
        self.station.tracks(now_ms).collect()
    }
}

/// One robot at one sample.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct RobotSample {
    pub x: f64,
    pub y: f64,
    pub heading: f64,
    pub v: f64,
    pub omega: f64,
    /// Followers: the reference point their control point should be at.
    pub slot: Option<(f64, f64)>,
    /// Followers: distance from the control point to the reference point.
    pub error: Option<f64>,
    /// The robot's mode as its last telemetry to the base station said.
    pub mode: Option<&'static str>,
}

#[derive(Debug, Clone, Serialize)]
pub struct Sample {
    pub t: f64,
    pub robots: Vec<RobotSample>,
    /// 0 = wide, 1 = line.
    pub blend: f64,
    /// The shape the formation is in or heading to ("wide", "line", "to_line", "to_wide").
    pub shape: &'static str,
    /// Some robot has an obstacle within R_det.
    pub near_obstacle: bool,
    /// The movers on the site (the truth).
    #[serde(skip)]
    pub movers: Vec<MoverState>,
    /// What the station tracked (what it believed).
    #[serde(skip)]
    pub tracks: Vec<TrackView>,
}

/// The leader's driven path, newest last, points at least `SPACING` apart.
#[derive(Debug, Clone, Default)]
pub struct DrivenPath {
    points: Vec<DVec2>,
}

impl DrivenPath {
    const SPACING: f64 = 0.02;

    pub fn record(&mut self, p: DVec2) {
        if self
            .points
            .last()
            .is_none_or(|q| (p - *q).length() >= Self::SPACING)
        {
            self.points.push(p);
        }
    }

    /// The point `s` metres back along the path from `leader` (its current position).
    /// Before the path began, straight on along the chord from the leader to the path's
    /// start, as the control core extends its trail (`control_core::follower::Trail`),
    /// or back along `heading` while the path is shorter than half a metre (back along
    /// `heading` always would swing that stretch sideways once the leader turned).
    pub fn behind(&self, leader: DVec2, heading: f64, s: f64) -> DVec2 {
        back_along(leader, heading, self.points.iter().rev().copied(), s)
    }
}

#[derive(Debug, Clone)]
pub struct Recorder {
    footprint: f64,
    /// A robot's mass, kg (a contact's energy).
    mass: f64,
    d: f64,
    r_det: f64,
    pub samples: Vec<Sample>,
    pub min_clearance: f64,
    pub min_separation: f64,
    pub contacts: u32,
    touching: FxHashSet<(usize, usize)>,
    /// The true leader's path: the line's reference.
    path: DrivenPath,
    /// What the robots did among the movers.
    pub movers: MoverMeasures,
    /// The last physics step observed, µs.
    last_us: Option<u64>,
    /// What the brushes swept, when the scenario has areas to sweep.
    pub sweeping: Option<crate::swept::Sweeping>,
}

/// A robot moving slower than this stands, m/s.
const STANDING: f64 = 0.05;
/// A robot closing on a person faster than this (and faster than they close on it) drives
/// into them: the standards' line between a vehicle striking someone and being struck, m/s.
const DRIVING_INTO: f64 = 0.1;
/// A moving robot within this of a person's footprint intrudes on their personal space, m.
const INTRUSION_WITHIN: f64 = 0.5;
/// The leader standing with a person within this of its footprint is freezing, m.
const FREEZING_WITHIN: f64 = 1.5;

/// A robot at one physics step, as the mover measures need it.
#[derive(Debug, Clone, Copy)]
pub struct RobotNow {
    pub position: DVec2,
    pub footprint: f64,
    pub heading: f64,
    /// Forward speed, m/s (negative backing).
    pub v: f64,
    pub leads: bool,
}

impl RobotNow {
    fn velocity(&self) -> DVec2 {
        DVec2::from_angle(self.heading) * self.v
    }
}

/// What the robots did among the movers.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct MoverMeasures {
    /// Contacts with a mover while the robot moved (faster than 0.05 m/s), whoever's doing.
    pub contacts_moving: u32,
    /// Contacts of a mover with a robot that stood (walked into).
    pub contacts_standing: u32,
    /// Contacts by who did what ([`ContactClass`]).
    pub drove_into: u32,
    pub walked_into_standing: u32,
    pub walked_into_braking: u32,
    /// The least gap between a robot's footprint and a person's (pedestrian or
    /// cyclist), m, 0 at a contact; ∞ without persons.
    pub min_person_clearance_m: f64,
    /// How deep a robot's footprint and a person's overlapped at worst, m (0: never).
    pub deepest_person_overlap_m: f64,
    /// The least gap between a robot's footprint and a vehicle's, m; ∞ without vehicles.
    pub min_vehicle_clearance_m: f64,
    /// Time a moving robot was within 0.5 m of a person's footprint, s.
    pub intrusion_s: f64,
    /// The same, robot by robot (in the run's order); they overlap where two robots
    /// intrude at once, s.
    pub intrusion_by_robot_s: Vec<f64>,
    /// Time the leader stood with a person within 1.5 m of its footprint, s.
    pub freezing_s: f64,
    /// The first [`MAX_CONTACTS_LISTED`] contacts, in order.
    pub contacts: Vec<MoverContact>,
    /// Who touched whom: (robot, mover).
    #[serde(skip)]
    touching: FxHashSet<(usize, usize)>,
}

/// Most mover contacts listed one by one.
pub const MAX_CONTACTS_LISTED: usize = 100;

/// Who did what at a contact, as the safety standards judge it (ISO 3691-4: a driverless
/// vehicle must not strike a person; passive safety: be at rest, or not closing, when a
/// contact happens).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ContactClass {
    /// The robot's own velocity toward the mover was over 0.1 m/s and larger than the
    /// mover's toward the robot.
    DroveInto,
    /// The robot stood (0.05 m/s or slower).
    WalkedIntoStanding,
    /// The robot moved, but the closing was the mover's doing.
    WalkedIntoBraking,
}

impl ContactClass {
    /// `robot_toward`, `mover_toward`: each one's velocity along the line between them,
    /// toward the other, m/s; `speed`: the robot's speed, m/s.
    pub fn of(robot_toward: f64, mover_toward: f64, speed: f64) -> Self {
        if robot_toward > DRIVING_INTO && robot_toward > mover_toward {
            ContactClass::DroveInto
        } else if speed <= STANDING {
            ContactClass::WalkedIntoStanding
        } else {
            ContactClass::WalkedIntoBraking
        }
    }
}

/// One contact of a robot with a mover.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MoverContact {
    pub at_s: f64,
    /// The robot's index in the run (its order in the scenario).
    pub robot: usize,
    /// The mover's index (`[[movers]]` first, then each crowd's persons).
    pub mover: usize,
    pub kind: MoverKind,
    /// Whether the robot moved (faster than 0.05 m/s).
    pub robot_moving: bool,
    pub class: ContactClass,
    /// The robot's speed, m/s.
    pub robot_speed_mps: f64,
    /// How fast the two closed on each other, m/s.
    pub closing_speed_mps: f64,
    /// The robot's kinetic energy, ½·`[robot] mass_kg`·speed², J.
    pub robot_energy_j: f64,
}

impl MoverMeasures {
    fn new() -> Self {
        Self {
            min_person_clearance_m: f64::INFINITY,
            min_vehicle_clearance_m: f64::INFINITY,
            ..Self::default()
        }
    }

    /// One physics step of `dt`; `mass`: a robot's, kg.
    fn observe(
        &mut self,
        t_s: f64,
        robots: &[RobotNow],
        movers: &[MoverState],
        dt: f64,
        mass: f64,
    ) {
        let (mut intruding, mut freezing) = (false, false);
        self.intrusion_by_robot_s.resize(robots.len(), 0.0);
        for (i, r) in robots.iter().enumerate() {
            let moving = r.v.abs() > STANDING;
            let mut intrudes = false;
            for m in movers {
                let gap = m.distance(r.position) - r.footprint;
                if m.kind == MoverKind::Vehicle {
                    self.min_vehicle_clearance_m = self.min_vehicle_clearance_m.min(gap.max(0.0));
                } else {
                    self.min_person_clearance_m = self.min_person_clearance_m.min(gap.max(0.0));
                    self.deepest_person_overlap_m = self.deepest_person_overlap_m.max(-gap);
                    intrudes |= moving && gap < INTRUSION_WITHIN;
                    freezing |= r.leads && !moving && gap < FREEZING_WITHIN;
                }
                let pair = (i, m.index);
                if gap >= 0.0 {
                    // Nearly always apart, and nobody touching: skip the lookup.
                    if !self.touching.is_empty() {
                        self.touching.remove(&pair);
                    }
                } else if self.touching.insert(pair) {
                    self.count(contact(t_s, i, r, m, mass));
                }
            }
            if intrudes {
                self.intrusion_by_robot_s[i] += dt;
            }
            intruding |= intrudes;
        }
        self.intrusion_s += if intruding { dt } else { 0.0 };
        self.freezing_s += if freezing { dt } else { 0.0 };
    }

    /// A new contact, counted and listed.
    fn count(&mut self, c: MoverContact) {
        if c.robot_moving {
            self.contacts_moving += 1;
        } else {
            self.contacts_standing += 1;
        }
        match c.class {
            ContactClass::DroveInto => self.drove_into += 1,
            ContactClass::WalkedIntoStanding => self.walked_into_standing += 1,
            ContactClass::WalkedIntoBraking => self.walked_into_braking += 1,
        }
        if self.contacts.len() < MAX_CONTACTS_LISTED {
            self.contacts.push(c);
        }
    }
}

/// Robot `i` (`r`) and mover `m` at the instant they touch, judged.
fn contact(t_s: f64, i: usize, r: &RobotNow, m: &MoverState, mass: f64) -> MoverContact {
    let towards = m.toward_from(r.position);
    let (own, theirs) = (r.velocity(), m.velocity);
    let robot_toward = own.dot(towards);
    let mover_toward = -theirs.dot(towards);
    let speed = r.v.abs();
    MoverContact {
        at_s: t_s,
        robot: i,
        mover: m.index,
        kind: m.kind,
        robot_moving: speed > STANDING,
        class: ContactClass::of(robot_toward, mover_toward, speed),
        robot_speed_mps: speed,
        closing_speed_mps: (robot_toward + mover_toward).max(0.0),
        robot_energy_j: 0.5 * mass * speed * speed,
    }
}

const OBSTACLE: usize = usize::MAX;

fn mode_name(m: RobotMode) -> &'static str {
    use RobotMode as M;
    match m {
        M::Idle => "idle",
        M::Joining => "joining",
        M::InFormation => "in_formation",
        M::Transforming => "transforming",
        M::Leading => "leading",
        M::Failsafe => "failsafe",
        M::EmergencyStop => "emergency_stop",
    }
}

impl Recorder {
    pub fn new(s: &Scenario) -> Self {
        Self {
            footprint: s.robot.footprint_radius,
            mass: s.robot.mass_kg,
            d: s.follower.d,
            r_det: s.planner.r_det,
            samples: Vec::new(),
            min_clearance: f64::INFINITY,
            min_separation: f64::INFINITY,
            contacts: 0,
            touching: FxHashSet::default(),
            path: DrivenPath::default(),
            movers: MoverMeasures::new(),
            last_us: None,
            sweeping: None,
        }
    }

    /// The robots' footprint radius, m.
    pub fn footprint(&self) -> f64 {
        self.footprint
    }

    fn contact(&mut self, pair: (usize, usize), now: bool) {
        if now {
            if self.touching.insert(pair) {
                self.contacts += 1;
            }
        } else {
            self.touching.remove(&pair);
        }
    }

    /// The brushes after a physics step, when the run sweeps.
    fn observe_sweep<R: Tracked>(
        &mut self,
        t_us: u64,
        dt: f64,
        robots: &[R],
        movers: &[MoverState],
    ) {
        let Some(sweeping) = &mut self.sweeping else {
            return;
        };
        let brushes = robots.iter().map(|r| {
            let b = r.body();
            crate::swept::Brush {
                id: r.id(),
                leads: r.role() == Role::Leader,
                position: DVec2::new(b.x, b.y),
                heading: b.heading,
                v: b.twist().0,
            }
        });
        sweeping.observe(t_us as f64 / 1e6, dt, brushes, movers);
    }

    /// Called after every physics step. `map`: everything a robot can touch, besides the
    /// `movers`.
    pub fn observe<R: Tracked>(
        &mut self,
        t_us: u64,
        robots: &[R],
        map: &Map,
        movers: &[MoverState],
        view: &dyn FleetView,
    ) {
        let dt = self
            .last_us
            .map_or(0.0, |l| t_us.saturating_sub(l) as f64 / 1e6);
        self.last_us = Some(t_us);
        self.observe_sweep(t_us, dt, robots, movers);
        if !movers.is_empty() {
            let bodies: Vec<RobotNow> = robots
                .iter()
                .map(|r| {
                    let b = r.body();
                    RobotNow {
                        position: DVec2::new(b.x, b.y),
                        footprint: self.footprint,
                        heading: b.heading,
                        v: b.twist().0,
                        leads: r.role() == Role::Leader,
                    }
                })
                .collect();
            let t_s = t_us as f64 / 1e6;
            self.movers.observe(t_s, &bodies, movers, dt, self.mass);
        }
        let fp = self.footprint;
        let reach = self.r_det + fp;
        let mut near = false;
        for (i, r) in robots.iter().enumerate() {
            let p = DVec2::new(r.body().x, r.body().y);
            let Some(surface) = map.nearest(p, reach) else {
                self.contact((i, OBSTACLE), false);
                continue;
            };
            let clearance = surface.distance - fp;
            near |= clearance < self.r_det;
            self.min_clearance = self.min_clearance.min(clearance);
            self.contact((i, OBSTACLE), clearance < 0.0);
        }
        // Robot pairs: a sort along x bounds the work (fleets here are small or spread).
        let mut order: Vec<usize> = (0..robots.len()).collect();
        order.sort_by(|a, b| robots[*a].body().x.total_cmp(&robots[*b].body().x));
        for (k, &i) in order.iter().enumerate() {
            for &j in &order[k + 1..] {
                let (a, b) = (robots[i].body(), robots[j].body());
                if b.x - a.x > 2.0 * fp + 1.0 {
                    break;
                }
                let gap = ((a.x - b.x).powi(2) + (a.y - b.y).powi(2)).sqrt() - 2.0 * fp;
                self.min_separation = self.min_separation.min(gap);
                self.contact((i.min(j), i.max(j)), gap < 0.0);
            }
        }
        let leader = robots
            .iter()
            .find(|r| r.role() == Role::Leader)
            .map(|r| r.body());
        if let Some(l) = leader {
            self.path.record(DVec2::new(l.x, l.y));
        }
        if !t_us.is_multiple_of(SAMPLE_PERIOD_US) {
            return;
        }
        self.sample(t_us, robots, leader, view, near);
        if let Some(last) = self.samples.last_mut() {
            last.movers = movers.to_vec();
            last.tracks = view.tracks(t_us);
        }
    }

    fn sample<R: Tracked>(
        &mut self,
        t_us: u64,
        robots: &[R],
        leader: Option<&Body>,
        view: &dyn FleetView,
        near_obstacle: bool,
    ) {
        let blend = view.blend(t_us);
        let reference = |id: u16| -> Option<DVec2> {
            let l = leader?;
            let pos = DVec2::new(l.x, l.y);
            let ((wl, wphi), (ll, _)) = view.slot(id)?;
            let a = l.heading + wphi;
            let wide = pos + DVec2::new(a.cos(), a.sin()) * wl;
            if blend <= 0.0 {
                return Some(wide);
            }
            let line = self.path.behind(pos, l.heading, ll);
            Some(wide.lerp(line, blend.min(1.0)))
        };
        let robots = robots
            .iter()
            .map(|r| {
                let (v, omega) = r.body().twist();
                let slot = (r.role() == Role::Follower)
                    .then(|| reference(r.id()))
                    .flatten();
                let error = slot.map(|s| {
                    let (cx, cy) = r.body().ahead(self.d);
                    (DVec2::new(cx, cy) - s).length()
                });
                let mode = view.mode(r.id()).map(mode_name);
                RobotSample {
                    x: r.body().x,
                    y: r.body().y,
                    heading: r.body().heading,
                    v,
                    omega,
                    slot: slot.map(|s| (s.x, s.y)),
                    error,
                    mode,
                }
            })
            .collect();
        let shape = view.target().shape_name(blend);
        self.samples.push(Sample {
            t: t_us as f64 / 1e6,
            robots,
            blend,
            shape,
            near_obstacle,
            movers: Vec::new(),
            tracks: Vec::new(),
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use base_station::scenario::movers::MoverShape;

    fn person(index: usize, x: f64, y: f64) -> MoverState {
        MoverState {
            index,
            kind: MoverKind::Pedestrian,
            position: DVec2::new(x, y),
            velocity: DVec2::new(1.0, 0.0),
            heading: 0.0,
            shape: MoverShape::Circle { radius: 0.25 },
            oblivious: true,
        }
    }

    fn robot(x: f64, y: f64, heading_deg: f64, v: f64, leads: bool) -> RobotNow {
        RobotNow {
            position: DVec2::new(x, y),
            footprint: 0.3,
            heading: heading_deg.to_radians(),
            v,
            leads,
        }
    }

    /// A contact is the robot's doing where it closes faster than 0.1 m/s and faster than
    /// the person; else they walked into it, standing or moving; its energy from its mass.
    #[test]
    fn contacts_are_judged_by_who_closed_on_whom() {
        let fp = 0.3;
        // A person 0.5 m ahead (touching: 0.25 + 0.3 > 0.5), walking across at 1 m/s.
        let crossing = [person(0, 0.5, 0.0)];
        let cases = [
            // Driving at them at 0.5 m/s: the robot's doing.
            (robot(0.0, 0.0, 0.0, 0.5, false), ContactClass::DroveInto),
            // Standing: walked into.
            (
                robot(0.0, 0.0, 0.0, 0.0, false),
                ContactClass::WalkedIntoStanding,
            ),
            // Creeping at 0.08 m/s: moving, but not driving into them.
            (
                robot(0.0, 0.0, 0.0, 0.08, false),
                ContactClass::WalkedIntoBraking,
            ),
            // Driving away from them at 0.5 m/s (they are behind it).
            (
                robot(0.0, 0.0, 180.0, 0.5, false),
                ContactClass::WalkedIntoBraking,
            ),
        ];
        for (r, class) in cases {
            let mut m = MoverMeasures::new();
            m.observe(0.0, &[r], &crossing, 0.01, 60.0);
            assert_eq!(m.contacts.len(), 1);
            let c = &m.contacts[0];
            assert_eq!(c.class, class, "{r:?}");
            assert!((c.robot_energy_j - 30.0 * r.v * r.v).abs() < 1e-9);
        }
        // A person walking at the robot faster than it drives at them: walked into.
        let mut at_it = person(0, 0.5, 0.0);
        at_it.velocity = DVec2::new(-1.3, 0.0);
        let mut m = MoverMeasures::new();
        m.observe(
            0.0,
            &[robot(0.0, 0.0, 0.0, 0.5, false)],
            &[at_it],
            0.01,
            60.0,
        );
        let c = &m.contacts[0];
        assert_eq!(c.class, ContactClass::WalkedIntoBraking);
        assert!((c.closing_speed_mps - 1.8).abs() < 1e-9);
        assert_eq!((m.drove_into, m.walked_into_braking), (0, 1));
        assert_eq!(m.min_person_clearance_m, 0.0);
        assert!((m.deepest_person_overlap_m - (0.25 + fp - 0.5)).abs() < 1e-9);
    }

    /// Intrusion is counted once for the fleet and robot by robot; a standing robot
    /// does not intrude.
    #[test]
    fn intrusion_is_counted_for_the_fleet_and_robot_by_robot() {
        let mut m = MoverMeasures::new();
        // Robot 0 moves with a person 0.3 m off its footprint; robot 1 moves far from
        // anyone; robot 2 stands with a person 0.1 m off.
        let robots = [
            robot(0.0, 0.0, 0.0, 0.3, true),
            robot(10.0, 0.0, 0.0, 0.3, false),
            robot(0.0, 5.0, 0.0, 0.0, false),
        ];
        let movers = [person(0, 0.85, 0.0), person(1, 0.0, 5.65)];
        for k in 0..10 {
            m.observe(k as f64 * 0.1, &robots, &movers, 0.1, 60.0);
        }
        assert!((m.intrusion_s - 1.0).abs() < 1e-9);
        assert_eq!(m.intrusion_by_robot_s.len(), 3);
        assert!((m.intrusion_by_robot_s[0] - 1.0).abs() < 1e-9);
        assert_eq!(m.intrusion_by_robot_s[1], 0.0);
        assert_eq!(m.intrusion_by_robot_s[2], 0.0);
        // Now robot 2 moves as well: the fleet's time counts once, each robot's its own.
        let both = [
            robots[0],
            robots[1],
            RobotNow {
                v: 0.2,
                ..robots[2]
            },
        ];
        for k in 0..5 {
            m.observe(1.0 + k as f64 * 0.1, &both, &movers, 0.1, 60.0);
        }
        assert!((m.intrusion_s - 1.5).abs() < 1e-9);
        assert!((m.intrusion_by_robot_s[0] - 1.5).abs() < 1e-9);
        assert!((m.intrusion_by_robot_s[2] - 0.5).abs() < 1e-9);
    }

    /// Past the path's start the reference goes on along the chord from the leader to
    /// the start, not back along the heading the leader has now.
    #[test]
    fn behind_the_start_runs_on_along_the_chord() {
        let mut path = DrivenPath::default();
        for k in 0..=500 {
            path.record(DVec2::new(k as f64 * 0.02, 0.0));
        }
        // Turned right a little since: the chord still points back down the street.
        let leader = DVec2::new(10.0 + 0.8, -0.6);
        path.record(leader);
        let p = path.behind(leader, -0.64, 14.0);
        let chord = (DVec2::ZERO - leader).normalize();
        // 1 m back to (10, 0), 10 m along the path, 3 m on past its start.
        let expected = chord * 3.0;
        assert!((p - expected).length() < 0.01, "{p} vs {expected}");
        assert!(p.y.abs() < 0.2, "{p}: swung off the street");
        // Along the path itself.
        let q = path.behind(leader, -0.64, 3.0);
        assert!((q - DVec2::new(8.0, 0.0)).length() < 0.01, "{q}");
    }
}
