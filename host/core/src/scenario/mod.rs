//! Scenario and site files (TOML): the map, the robots, the formation, the route, the
//! gains and limits, and for simulation the link and noise models. Every field is
//! documented in `docs/scenario.md`.
//!
//! A bad file gives a [`ScenarioError`] naming the file, the line and column, and the
//! field (`map.obstacles[2].radius`): syntax and type errors from the TOML parser,
//! unknown fields, and the semantic checks of [`Scenario::validate`].

use std::fmt;
use std::path::Path;

use glam::DVec2;
use serde::{Deserialize, Serialize};

use crate::geometry::Obstacle;
use crate::planner::PlannerParams;

mod defaults;
mod locate;
mod lower;
pub mod movers;
pub mod radio;
mod reach;
pub mod sweep;
mod validate;

use locate::{line_col, locate};

/// How fast a slot point may move relative to the leader during a shape change, as a
/// fraction of the robots' top speed (it sets the change's duration,
/// `FormationSpec::transition_duration`). Back to the wide shape a follower first in line
/// moves out 1.5 m while the leader drives on: at 0.8 it had to turn nearly sideways
/// (1.6 rad/s at 0.1 m/s) and lagged its slot by 0.22 m in `sim`, 0.30–0.35 m in real time
/// (the short passage of `host/tests/operate.rs`); at 0.7 (the paper's passage: 3.5 → 4 s,
/// within issue 10's 5 s) 0.18 m and 0.21 m.
const SLOT_SPEED_OF_MAX: f64 = 0.7;

/// A scenario that could not be loaded: where, which field, why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ScenarioError {
    pub file: String,
    /// 1-based line and column, where the field could be found in the file.
    pub position: Option<(usize, usize)>,
    /// The field's path, e.g. `map.obstacles[2].radius` (empty for the whole file).
    pub field: String,
    pub message: String,
}

impl fmt::Display for ScenarioError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some((line, col)) = self.position {
            write!(f, ":{line}:{col}")?;
        }
        if !self.field.is_empty() {
            write!(f, ": field `{}`", self.field)?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for ScenarioError {}

/// Every problem found in a scenario file, in order (at least one).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ScenarioErrors(pub Vec<ScenarioError>);

impl ScenarioErrors {
    pub fn first(&self) -> &ScenarioError {
        &self.0[0]
    }
}

impl From<ScenarioError> for ScenarioErrors {
    fn from(e: ScenarioError) -> Self {
        Self(vec![e])
    }
}

impl fmt::Display for ScenarioErrors {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, e) in self.0.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            write!(f, "{e}")?;
        }
        Ok(())
    }
}

impl std::error::Error for ScenarioErrors {}

/// The largest scenario or site file read, bytes. Parsing TOML costs up to ~100 times the
/// file in memory (a 16 MiB file of polygon points took 1.7 GB), so this keeps `check` well
/// under 1 GB on any file; a city's site file of thousands of obstacles is a few hundred kB.
pub const MAX_FILE_BYTES: usize = 4 * 1024 * 1024;

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    pub name: String,
    #[serde(default)]
    pub description: String,
    #[serde(default)]
    pub map: MapSpec,
    #[serde(default)]
    pub robot: RobotSpec,
    pub robots: Vec<RobotEntry>,
    pub formation: FormationToml,
    /// Optional where the file has areas to sweep (validated).
    #[serde(default)]
    pub route: RouteSpec,
    #[serde(default)]
    pub planner: PlannerToml,
    #[serde(default)]
    pub follower: FollowerToml,
    #[serde(default)]
    pub link: LinkSpec,
    #[serde(default)]
    pub localization: LocalizationSpec,
    #[serde(default)]
    pub perception: PerceptionSpec,
    /// How the fleet yields to people and vehicles.
    #[serde(default)]
    pub yielding: YieldingSpec,
    #[serde(default)]
    pub sim: SimSpec,
    /// People, cyclists and vehicles on paths of their own (simulation only).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub movers: Vec<movers::MoverSpec>,
    /// Crowds of social pedestrians (simulation only).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub crowds: Vec<movers::CrowdSpec>,
    /// Faults and attacks the simulator injects (simulation only).
    #[serde(default)]
    pub faults: Vec<FaultSpec>,
    /// Areas to sweep, before the route's own points.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sweep: Vec<sweep::SweepSpec>,
}

/// What goes wrong. Append-only.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum FaultKind {
    /// Every frame lost, both ways, for `duration_s` (absent: for good).
    LossBurst,
    /// Frames from the base station to the robots lost.
    SilentDownlink,
    /// Frames from the robots to the base station lost.
    SilentUplink,
    /// One-way latency raised to `value` ms.
    LatencySpike,
    /// `robot` reboots: a new boot count, all its state lost.
    Reboot,
    /// The leader's controller dies: no more frames, motors off.
    LeaderDies,
    /// A transmitter with another key sends leader states, `value` frames/s.
    WrongKeyAttacker,
    /// Genuine frames recorded off the air are replayed `value` seconds later.
    ReplayAttacker,
    /// Random bytes on the air, `value` bytes/s.
    GarbageFlood,
    /// `robot`'s left wheel is blocked.
    StuckWheel,
    /// `robot`'s left motor delivers `value` (0–1) of its torque.
    WeakMotor,
    /// `robot`'s left encoder stops counting.
    EncoderDead,
    /// `robot`'s pose fixes are off by `value` metres (in x).
    PoseJump,
    /// The base station is killed and restarted (a new session, all its state lost).
    BaseRestart,
    /// Frames arrive out of order: up to `value` ms of extra random delay each.
    Reorder,
    /// Every frame arrives twice.
    Duplicate,
    /// Each byte on the air is flipped with probability `value`.
    Corruption,
    /// A relay between the base station and the robots delays every frame, both ways, by
    /// `value` seconds (authentic frames, arriving late).
    DelayRelay,
    /// Robots' `Hello` frames recorded off the air are replayed to the base station at
    /// `value` frames/s (an attempt to keep a robot from linking).
    HelloReplay,
    /// The base station's `Welcome` frames are jammed at the robot and delivered `value`
    /// seconds later (an attempt to roll a replay floor back).
    WelcomeHoldback,
    /// A robot taken apart: with the broadcast key every robot holds, an attacker
    /// broadcasts what drives or places one robot (a velocity command of 1.5 m/s, a detour
    /// 30 m off, a pose fix 4 m off), `value` frames/s.
    CapturedRobot,
}

impl FaultKind {
    /// Every kind, in the order they were added (the docs' table lists each).
    pub const ALL: [FaultKind; 21] = {
        use FaultKind as K;
        [
            K::LossBurst,
            K::SilentDownlink,
            K::SilentUplink,
            K::LatencySpike,
            K::Reboot,
            K::LeaderDies,
            K::WrongKeyAttacker,
            K::ReplayAttacker,
            K::GarbageFlood,
            K::StuckWheel,
            K::WeakMotor,
            K::EncoderDead,
            K::PoseJump,
            K::BaseRestart,
            K::Reorder,
            K::Duplicate,
            K::Corruption,
            K::DelayRelay,
            K::HelloReplay,
            K::WelcomeHoldback,
            K::CapturedRobot,
        ]
    };

    /// Its name in a site file.
    pub fn name(self) -> &'static str {
        use FaultKind as K;
        match self {
            K::LossBurst => "loss_burst",
            K::SilentDownlink => "silent_downlink",
            K::SilentUplink => "silent_uplink",
            K::LatencySpike => "latency_spike",
            K::Reboot => "reboot",
            K::LeaderDies => "leader_dies",
            K::WrongKeyAttacker => "wrong_key_attacker",
            K::ReplayAttacker => "replay_attacker",
            K::GarbageFlood => "garbage_flood",
            K::StuckWheel => "stuck_wheel",
            K::WeakMotor => "weak_motor",
            K::EncoderDead => "encoder_dead",
            K::PoseJump => "pose_jump",
            K::BaseRestart => "base_restart",
            K::Reorder => "reorder",
            K::Duplicate => "duplicate",
            K::Corruption => "corruption",
            K::DelayRelay => "delay_relay",
            K::HelloReplay => "hello_replay",
            K::WelcomeHoldback => "welcome_holdback",
            K::CapturedRobot => "captured_robot",
        }
    }
}

/// One scheduled fault. Fields beyond `at_s` and `kind` depend on the kind.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct FaultSpec {
    pub at_s: f64,
    pub kind: FaultKind,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub duration_s: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<u16>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub value: Option<f64>,
}

impl FaultSpec {
    /// Whether the fault is active at `t` seconds.
    pub fn active(&self, t: f64) -> bool {
        t >= self.at_s && self.duration_s.is_none_or(|d| t < self.at_s + d)
    }
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, Default)]
#[serde(deny_unknown_fields)]
pub struct MapSpec {
    #[serde(default)]
    pub obstacles: Vec<ObstacleSpec>,
    /// The site's edge (kerbs, fences): nothing drives outside it. Absent: the site is
    /// open around the obstacles.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bounds: Option<BoundsSpec>,
    /// Obstacles on the site that the map does not hold (simulation only): the robots meet
    /// them, the base station learns of them only through the leader's scanner.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub unmapped: Vec<ObstacleSpec>,
}

/// An axis-aligned site edge.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BoundsSpec {
    pub min: [f64; 2],
    pub max: [f64; 2],
}

#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum ObstacleKind {
    Circle,
    Segment,
    Polygon,
    Rectangle,
}

/// One obstacle. A flat table (not a tagged enum) so that an error names the exact field.
/// `circle`: `center`, `radius`; `segment`: `from`, `to`; `polygon`: `points`;
/// `rectangle`: `min`, `max`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ObstacleSpec {
    pub kind: ObstacleKind,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub center: Option<[f64; 2]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub from: Option<[f64; 2]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub to: Option<[f64; 2]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub points: Option<Vec<[f64; 2]>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min: Option<[f64; 2]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max: Option<[f64; 2]>,
}

impl ObstacleSpec {
    /// The fields each kind needs, in order.
    fn fields(kind: ObstacleKind) -> &'static [&'static str] {
        match kind {
            ObstacleKind::Circle => &["center", "radius"],
            ObstacleKind::Segment => &["from", "to"],
            ObstacleKind::Polygon => &["points"],
            ObstacleKind::Rectangle => &["min", "max"],
        }
    }

    fn present(&self) -> [(&'static str, bool); 7] {
        [
            ("center", self.center.is_some()),
            ("radius", self.radius.is_some()),
            ("from", self.from.is_some()),
            ("to", self.to.is_some()),
            ("points", self.points.is_some()),
            ("min", self.min.is_some()),
            ("max", self.max.is_some()),
        ]
    }

    /// Checks the fields against the kind; `(field, message)` on error.
    fn check(&self, at: &str) -> Result<(), (String, String)> {
        let need = Self::fields(self.kind);
        for (name, is_set) in self.present() {
            if need.contains(&name) && !is_set {
                return Err((
                    at.to_string(),
                    format!("a {:?} needs `{name}`", self.kind).to_lowercase(),
                ));
            }
            if !need.contains(&name) && is_set {
                return Err((
                    format!("{at}.{name}"),
                    format!(
                        "`{name}` does not belong to a {:?} (it takes {})",
                        self.kind,
                        need.join(", ")
                    )
                    .to_lowercase(),
                ));
            }
        }
        Ok(())
    }

    /// The obstacle; only for a spec that passed validation.
    pub fn to_obstacle(&self) -> Obstacle {
        let v = |p: Option<[f64; 2]>| {
            let p = p.unwrap_or_default();
            DVec2::new(p[0], p[1])
        };
        match self.kind {
            ObstacleKind::Circle => Obstacle::Circle {
                center: v(self.center),
                radius: self.radius.unwrap_or_default(),
            },
            ObstacleKind::Segment => Obstacle::Segment {
                a: v(self.from),
                b: v(self.to),
            },
            ObstacleKind::Polygon => Obstacle::Polygon {
                points: self
                    .points
                    .iter()
                    .flatten()
                    .map(|p| DVec2::new(p[0], p[1]))
                    .collect(),
            },
            ObstacleKind::Rectangle => Obstacle::rectangle(v(self.min), v(self.max)),
        }
    }
}

/// The robot type: body, wheels, motors, limits. Shared by every robot of the scenario.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct RobotSpec {
    pub footprint_radius: f64,
    pub track_width: f64,
    pub wheel_radius: f64,
    pub ticks_per_rev: u32,
    pub max_wheel_speed: f64,
    pub max_speed: f64,
    pub max_reverse_speed: f64,
    pub max_turn_rate: f64,
    pub max_accel: f64,
    pub brake_decel: f64,
    pub motor_time_constant_s: f64,
    pub motor_no_load_speed: f64,
    pub motor_dead_band: f64,
    /// Mass with brushes, bin and battery, kg: a contact's energy in the report.
    pub mass_kg: f64,
    /// The width the robot's brushes sweep, centred on it, m.
    pub brush_width: f64,
}

impl Default for RobotSpec {
    fn default() -> Self {
        Self {
            footprint_radius: 0.3,
            track_width: 0.4,
            wheel_radius: 0.08,
            ticks_per_rev: 2048,
            max_wheel_speed: 1.1,
            max_speed: 1.0,
            max_reverse_speed: 0.3,
            max_turn_rate: 1.5,
            max_accel: 1.0,
            brake_decel: 1.0,
            motor_time_constant_s: 0.1,
            motor_no_load_speed: 1.2,
            motor_dead_band: 0.03,
            // A 0.6 m wide sweeper with its brushes, a 40 l bin and a battery.
            mass_kg: 60.0,
            // Two side brushes reaching 5 cm beyond the 0.6 m body.
            brush_width: 0.7,
        }
    }
}

#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    Leader,
    Follower,
}

impl Role {
    /// As in scenario files and reports.
    pub fn name(self) -> &'static str {
        match self {
            Role::Leader => "leader",
            Role::Follower => "follower",
        }
    }
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RobotEntry {
    pub id: u16,
    pub role: Role,
    pub start: StartPose,
    /// Speed at the start, m/s (the paper's leader starts at 0.15).
    #[serde(default)]
    pub initial_speed: f64,
}

#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct StartPose {
    pub x: f64,
    pub y: f64,
    #[serde(default)]
    pub heading_deg: f64,
}

#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum ShapeName {
    Triangle,
    V,
    /// Rows of `per_row` abreast behind the leader, `line_spacing` apart both ways.
    Rows,
    Custom,
}

#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SlotSpec {
    pub distance: f64,
    pub angle_deg: f64,
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct FormationToml {
    pub shape: ShapeName,
    /// L_d of the triangle / V, m.
    #[serde(default = "defaults::distance")]
    pub distance: f64,
    /// φ_d of the triangle / V, degrees from the leader's heading (±).
    #[serde(default = "defaults::angle_deg")]
    pub angle_deg: f64,
    /// Custom slots, one per follower in id order.
    #[serde(default)]
    pub slots: Vec<SlotSpec>,
    /// Followers abreast in each row of the `rows` shape.
    #[serde(default = "defaults::per_row")]
    pub per_row: usize,
    /// Line spacing D, m.
    #[serde(default = "defaults::line_spacing")]
    pub line_spacing: f64,
    #[serde(default = "defaults::margin")]
    pub margin: f64,
    #[serde(default = "defaults::transition_s")]
    pub transition_s: f64,
    #[serde(default = "defaults::min_dwell_s")]
    pub min_dwell_s: f64,
    #[serde(default = "defaults::lookahead")]
    pub lookahead: f64,
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RouteSpec {
    #[serde(default)]
    pub waypoints: Vec<[f64; 2]>,
    #[serde(default)]
    pub goal: Option<[f64; 2]>,
    #[serde(default = "defaults::arrival_tolerance")]
    pub arrival_tolerance: f64,
    #[serde(default = "defaults::waypoint_tolerance")]
    pub waypoint_tolerance: f64,
}

impl Default for RouteSpec {
    fn default() -> Self {
        Self {
            waypoints: Vec::new(),
            goal: None,
            arrival_tolerance: defaults::arrival_tolerance(),
            waypoint_tolerance: defaults::waypoint_tolerance(),
        }
    }
}

impl RouteSpec {
    /// Waypoints then the goal.
    pub fn points(&self) -> Vec<DVec2> {
        self.waypoints
            .iter()
            .chain(self.goal.iter())
            .map(|p| DVec2::new(p[0], p[1]))
            .collect()
    }
}

#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum PlannerMode {
    Route,
    Apf,
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct PlannerToml {
    /// `route` (default): a route on the site map, the APF as the local layer; `apf`:
    /// the paper's potential field alone.
    pub mode: PlannerMode,
    pub k_a: f64,
    pub k_r: f64,
    pub r_det: f64,
    pub attraction_saturation: f64,
    pub max_speed: f64,
    pub max_turn_rate: f64,
    pub max_accel: f64,
    pub heading_gain: f64,
    /// Turn rates below this are not driven, rad/s.
    pub turn_dead_band: f64,
    pub follow_clearance: f64,
    /// Followers whose tracking error exceeds this slow the leader down, m.
    pub wait_for_followers_above: f64,
}

impl Default for PlannerToml {
    fn default() -> Self {
        let p = PlannerParams::DEFAULT;
        Self {
            mode: PlannerMode::Route,
            k_a: p.apf.k_a,
            k_r: p.apf.k_r,
            r_det: p.apf.r_det,
            attraction_saturation: p.apf.attraction_saturation,
            max_speed: p.max_speed,
            max_turn_rate: p.max_turn_rate,
            max_accel: p.max_accel,
            heading_gain: p.heading_gain,
            turn_dead_band: p.turn_dead_band,
            follow_clearance: p.follow_clearance,
            wait_for_followers_above: 0.3,
        }
    }
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct FollowerToml {
    pub k1: f64,
    pub k2: f64,
    pub d: f64,
    pub leader_timeout_ms: u32,
}

impl Default for FollowerToml {
    fn default() -> Self {
        Self {
            k1: 0.5,
            k2: 0.3,
            d: 0.2,
            leader_timeout_ms: 500,
        }
    }
}

/// The simulated radio.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct LinkSpec {
    pub latency_ms: f64,
    pub jitter_ms: f64,
    /// Probability that a frame is lost.
    pub loss: f64,
    /// Probability that a byte is corrupted.
    pub byte_corruption: f64,
    /// The serial line's rate; also the air's where no `radio` is named.
    pub baud: u32,
    /// A shared channel: the preset (`radio::PRESETS`); without it every transmitter has
    /// air of its own.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub radio: Option<String>,
    pub access: radio::Access,
    /// Overrides a fixed-rate preset's air rate, bit/s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub air_rate_bps: Option<u32>,
    /// Overrides a fixed-rate preset's coding (coded bits per data bit).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fec: Option<f64>,
    /// Overrides the per-frame fixed overhead (preamble, turnaround), µs.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frame_overhead_us: Option<f64>,
    /// Overrides a LoRa preset's spreading factor (7–12).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub spreading_factor: Option<u8>,
}

impl Default for LinkSpec {
    fn default() -> Self {
        Self {
            latency_ms: 50.0,
            jitter_ms: 10.0,
            loss: 0.05,
            byte_corruption: 0.0,
            baud: 115_200,
            radio: None,
            access: radio::Access::default(),
            air_rate_bps: None,
            fec: None,
            frame_overhead_us: None,
            spreading_factor: None,
        }
    }
}

/// The localization system: how the simulated one behaves (`sigma_m` … `latency_ms`),
/// and, for real operation, where the site is on the globe and how the station watches
/// the fixes it forwards.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct LocalizationSpec {
    pub sigma_m: f64,
    pub heading_sigma_deg: f64,
    pub rate_hz: f64,
    pub latency_ms: f64,
    /// The site frame on the globe, for GNSS (NMEA) sources.
    pub origin: Option<crate::localization::SiteOrigin>,
    /// At most this many fixes per robot per second go over the radio.
    pub forward_hz: f64,
    /// A robot without a fix for this long is reported `localization_lost`, s.
    pub lost_after_s: f64,
    /// A robot without a fix for this long stops the fleet until fixes are back, s
    /// (until then the robots drive on odometry).
    pub stop_after_s: f64,
}

impl Default for LocalizationSpec {
    fn default() -> Self {
        Self {
            sigma_m: 0.02,
            heading_sigma_deg: 0.5,
            rate_hz: 10.0,
            latency_ms: 20.0,
            origin: None,
            forward_hz: 10.0,
            lost_after_s: 2.0,
            stop_after_s: 10.0,
        }
    }
}

/// What the station takes from the leader's scans (`docs/scenario.md#perception`).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct PerceptionSpec {
    /// The scanner's reach: a hit farther from the leader is no hit, m.
    pub max_range_m: f64,
    /// A sensed obstacle not seen again for this long is forgotten, s.
    pub forget_after_s: f64,
}

impl Default for PerceptionSpec {
    fn default() -> Self {
        Self {
            max_range_m: 30.0,
            forget_after_s: 30.0,
        }
    }
}

/// How the fleet yields to what moves (`docs/scenario.md#yielding`).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct YieldingSpec {
    /// What the leader keeps from a person's footprint when passing, m.
    pub personal_space_m: f64,
    /// How far ahead in time the leader keeps people's personal space, under a constant
    /// velocity prediction (longer: more cautious, and slower in a crowd), s.
    pub horizon_s: f64,
    /// A leader held by movers this long takes another way, if there is one, s.
    pub replan_after_s: f64,
    /// The share of its pace at which the leader passes people whose personal space it
    /// cannot keep, in (0, 1]: 1 passes them at its pace (it still slows where it
    /// would come within about 0.5 m of them, and stops for safety).
    pub passing_share: f64,
}

impl Default for YieldingSpec {
    fn default() -> Self {
        Self {
            personal_space_m: 0.8,
            horizon_s: 1.0,
            replan_after_s: 20.0,
            passing_share: 1.0,
        }
    }
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct SimSpec {
    pub duration_s: f64,
    pub seed: u64,
    pub physics_step_ms: u32,
}

impl Default for SimSpec {
    fn default() -> Self {
        Self {
            duration_s: 240.0,
            seed: 1,
            physics_step_ms: 10,
        }
    }
}

impl Scenario {
    /// Reads, parses and validates a scenario file.
    pub fn load(path: &Path) -> Result<Scenario, ScenarioErrors> {
        let file = path.display().to_string();
        let src = std::fs::read_to_string(path).map_err(|e| ScenarioError {
            file: file.clone(),
            position: None,
            field: String::new(),
            message: format!("cannot read the file: {e}"),
        })?;
        Scenario::parse(&src, &file)
    }

    /// Parses and validates scenario text; `file` names it in errors. A syntax or type
    /// error stops the parser (only the first is known); the semantic checks list every
    /// problem.
    pub fn parse(src: &str, file: &str) -> Result<Scenario, ScenarioErrors> {
        let error =
            |field: String, position: Option<(usize, usize)>, message: String| ScenarioError {
                file: file.to_string(),
                position,
                field,
                message,
            };
        if src.len() > MAX_FILE_BYTES {
            return Err(error(
                String::new(),
                None,
                format!("over 4 MiB: a scenario or site file is at most {MAX_FILE_BYTES} bytes"),
            )
            .into());
        }
        let de = toml::Deserializer::parse(src).map_err(|e| {
            error(
                String::new(),
                e.span().map(|s| line_col(src, s.start)),
                e.message().trim().to_string(),
            )
        })?;
        let scenario: Scenario = serde_path_to_error::deserialize(de).map_err(|e| {
            let field = e.path().to_string();
            let field = if field == "." { String::new() } else { field };
            let inner = e.into_inner();
            let position = inner
                .span()
                .map(|s| line_col(src, s.start))
                .or_else(|| locate(src, &field));
            error(field, position, inner.message().trim().to_string())
        })?;
        scenario.validate().map_err(|problems| {
            ScenarioErrors(
                problems
                    .into_iter()
                    .map(|(field, message)| error(field.clone(), locate(src, &field), message))
                    .collect(),
            )
        })?;
        Ok(scenario)
    }

    pub fn leader(&self) -> &RobotEntry {
        self.robots
            .iter()
            .find(|r| r.role == Role::Leader)
            .expect("validated: one leader")
    }

    /// Followers in id order: follower k takes slot k.
    pub fn followers(&self) -> Vec<&RobotEntry> {
        let mut f: Vec<_> = self
            .robots
            .iter()
            .filter(|r| r.role == Role::Follower)
            .collect();
        f.sort_by_key(|r| r.id);
        f
    }

    /// The wide shape's name in reports.
    pub fn wide_name(&self) -> &'static str {
        match self.formation.shape {
            ShapeName::Triangle => "triangle",
            ShapeName::V => "v",
            ShapeName::Rows => "rows",
            ShapeName::Custom => "custom",
        }
    }
}

#[cfg(test)]
mod fault_kinds {
    use super::FaultKind;

    /// A kind added to the enum does not compile in [`FaultKind::name`] until it is named;
    /// named, it fails here until it is in `ALL` under the name serde reads.
    #[test]
    fn every_kind_is_listed_once_by_its_file_name() {
        let mut names = std::collections::BTreeSet::new();
        for k in FaultKind::ALL {
            assert_eq!(serde_json::to_value(k).unwrap(), k.name(), "{k:?}");
            assert!(names.insert(k.name()), "{k:?} twice");
        }
        let named = FaultKind::ALL.map(FaultKind::name);
        for k in FaultKind::ALL {
            let back: FaultKind = serde_json::from_value(k.name().into()).unwrap();
            assert!(named.contains(&back.name()));
        }
    }
}
