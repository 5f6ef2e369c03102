//! What moves on the site (simulation only): people, cyclists and vehicles on paths of
//! their own (`[[movers]]`), and crowds walking between random points of an area
//! (`[[crowds]]`). The robots meet them; the base station learns of them only through
//! the leader's scans and each robot through its ring (`docs/scenario.md#movers`).

use glam::DVec2;
use serde::{Deserialize, Serialize};

use super::BoundsSpec;

/// What a mover is.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum MoverKind {
    Pedestrian,
    Cyclist,
    Vehicle,
}

impl MoverKind {
    pub fn name(self) -> &'static str {
        match self {
            MoverKind::Pedestrian => "pedestrian",
            MoverKind::Cyclist => "cyclist",
            MoverKind::Vehicle => "vehicle",
        }
    }

    /// The footprint a mover of this kind has unless its table says otherwise.
    pub fn default_shape(self) -> MoverShape {
        match self {
            // CrowdNav's humans (radius 0.3 m).
            MoverKind::Pedestrian => MoverShape::Circle { radius: 0.3 },
            MoverKind::Cyclist => MoverShape::Rectangle {
                length: 1.8,
                width: 0.6,
            },
            MoverKind::Vehicle => MoverShape::Rectangle {
                length: 4.5,
                width: 1.9,
            },
        }
    }
}

/// How a mover reacts to the others.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "snake_case")]
pub enum Behavior {
    /// Keeps to its path whatever happens: the worst case.
    #[default]
    Oblivious,
    /// A social force model: avoids the other movers, the robots and the obstacles.
    Social,
}

/// What a mover does at its path's end.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "snake_case")]
pub enum Repeat {
    /// Walks the path once and stays at its last point.
    #[default]
    Once,
    /// From the last point on to the first, for ever.
    Loop,
    /// Back along the path, and out again, for ever.
    BackAndForth,
}

/// A mover's footprint: a circle, or a rectangle whose length lies along its way.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MoverShape {
    Circle { radius: f64 },
    Rectangle { length: f64, width: f64 },
}

impl MoverShape {
    /// The radius of the circle that holds it, m.
    pub fn reach(self) -> f64 {
        match self {
            MoverShape::Circle { radius } => radius,
            MoverShape::Rectangle { length, width } => 0.5 * length.hypot(width),
        }
    }
}

/// A stop on the way: at path point `at` (0-based), for `for_s` seconds.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PauseSpec {
    pub at: usize,
    pub for_s: f64,
}

/// One `[[movers]]` table.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MoverSpec {
    pub kind: MoverKind,
    /// A circular footprint's radius, m (default by kind: a pedestrian 0.3 m).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    /// A rectangular footprint, along and across its way, m (default by kind: a cyclist
    /// 1.8 × 0.6, a vehicle 4.5 × 1.9).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub width: Option<f64>,
    /// Points in the site frame; one point: it stands there.
    pub path: Vec<[f64; 2]>,
    #[serde(default)]
    pub repeat: Repeat,
    /// Its speed along the path, m/s.
    pub speed: f64,
    /// When it appears, s.
    #[serde(default)]
    pub start_s: f64,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pauses: Vec<PauseSpec>,
    #[serde(default)]
    pub behavior: Behavior,
}

impl MoverSpec {
    /// Its footprint: what its table gives, or its kind's.
    pub fn shape(&self) -> MoverShape {
        match (self.radius, self.length, self.width) {
            (Some(radius), None, None) => MoverShape::Circle { radius },
            (None, Some(length), Some(width)) => MoverShape::Rectangle { length, width },
            _ => self.kind.default_shape(),
        }
    }

    pub fn points(&self) -> Vec<DVec2> {
        self.path.iter().map(|p| DVec2::new(p[0], p[1])).collect()
    }
}

/// One `[[crowds]]` table: social pedestrians walking between random points of an area.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CrowdSpec {
    pub area: BoundsSpec,
    /// Persons per square metre of the area.
    pub density: f64,
    /// Their walking speeds: normal, this mean and standard deviation, kept within
    /// 0.5–2.0 m/s.
    #[serde(default = "default_speed_mean")]
    pub speed_mean: f64,
    #[serde(default = "default_speed_sd")]
    pub speed_sd: f64,
    /// Where they start and go (the scenario's seed is mixed in).
    #[serde(default)]
    pub seed: u64,
    #[serde(default = "default_crowd_behavior")]
    pub behavior: Behavior,
    #[serde(default)]
    pub start_s: f64,
}

fn default_speed_mean() -> f64 {
    1.3
}
fn default_speed_sd() -> f64 {
    0.25
}
fn default_crowd_behavior() -> Behavior {
    Behavior::Social
}

impl CrowdSpec {
    /// How many persons the crowd has.
    pub fn persons(&self) -> usize {
        let size = DVec2::from(self.area.max) - DVec2::from(self.area.min);
        (self.density * size.x.max(0.0) * size.y.max(0.0)).round() as usize
    }
}

/// Most movers of a scenario, crowds' persons included.
pub const MAX_MOVERS: usize = 2000;
/// The fastest a mover may be, m/s.
pub const MAX_MOVER_SPEED: f64 = 30.0;
/// The largest footprint's side or radius, m.
pub const MAX_MOVER_SIZE: f64 = 20.0;
/// Most points of a mover's path.
pub const MAX_PATH_POINTS: usize = 1000;
