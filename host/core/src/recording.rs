//! The recording's vocabulary, shared by a simulation's recording (`hil-sim`) and a real
//! run's (`basestation run --mcap` / `--live`), so that one Foxglove layout serves both
//! and `decode` reads either: the site frame, the topics and their schemas, the scene's
//! entities, and how a message is stamped.
//!
//! Topics: `/radio` (the bytes every node put on the air, JSON `from` + `hex`), `/events`
//! (the station's events as log lines), `/tf` (each robot's frame in the site frame),
//! `/robot_N/link` ([`LinkHealth`] once a second), `/tracks` (what the station tracks:
//! [`tracks_entity`]), and the scene and per-robot channels a recording writes with the
//! entities and messages below (a simulation adds `/movers`, the movers' truth).

use std::sync::Arc;

use foxglove::messages::{
    line_primitive, log, ArrowPrimitive, Color, CylinderPrimitive, LinePrimitive, Log, Point3,
    Pose, Quaternion, SceneEntity, Timestamp, Vector3,
};
use foxglove::{Channel, Context, PartialMetadata, RawChannel, Schema};

use crate::geometry::Obstacle;
use crate::perception::tracking::{Motion, TrackView};

/// The recording's metadata record (`run`): what ran, which build, since when.
pub const METADATA_NAME: &str = "run";

/// The metadata of a recording of `scenario` (seed, firmware where simulated): the
/// program's version and git revision, and the start in UTC (RFC 3339).
pub fn run_metadata(
    scenario: &str,
    seed: Option<u64>,
    firmware: &str,
    started: std::time::SystemTime,
) -> std::collections::BTreeMap<String, String> {
    let since = started
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap_or_default();
    let utc = chrono::DateTime::from_timestamp(since.as_secs() as i64, since.subsec_nanos())
        .map_or_else(|| "unknown".into(), |t| t.to_rfc3339());
    let mut m = std::collections::BTreeMap::new();
    m.insert("scenario".into(), scenario.into());
    m.insert("seed".into(), seed.map_or("none".into(), |s| s.to_string()));
    m.insert("firmware".into(), firmware.into());
    m.insert("version".into(), env!("CARGO_PKG_VERSION").into());
    m.insert("git_revision".into(), GIT_REVISION.into());
    m.insert("started_utc".into(), utc);
    m
}

/// The source revision this build was made from (`unknown` outside a git checkout).
pub const GIT_REVISION: &str = env!("SWEEPER_GIT_REVISION");

/// The frame every position is in: the site's metric frame.
pub const FRAME: &str = "site";

/// The formation's shape when it changes: `wide`, `to_line`, `line`, `to_wide`.
#[derive(foxglove::Encode)]
pub struct FormationShape {
    pub shape: String,
}

/// What a robot's state channel carries (plottable in Foxglove's Plot panel).
#[derive(foxglove::Encode)]
pub struct RobotState {
    /// Forward speed, m/s.
    pub v: f64,
    /// Turn rate, rad/s.
    pub omega: f64,
    /// Distance from the follower's control point to its slot, m (−1: not a follower).
    pub tracking_error: f64,
    /// The formation's blend, 0 wide … 1 line.
    pub blend: f64,
}

/// The radio channel's topic and the JSON schema of its messages: `from` (`base`,
/// `robot:N`, `attacker`) and `hex` (the bytes it put on the air, frames with their
/// delimiters).
pub const RADIO_TOPIC: &str = "/radio";
pub const RADIO_SCHEMA: &str = r#"{"type":"object","properties":{"from":{"type":"string"},"hex":{"type":"string"}},"required":["from","hex"]}"#;

/// The base station's events, as log messages.
pub const EVENTS_TOPIC: &str = "/events";

/// The radio channel (raw JSON messages) on `ctx`.
pub fn radio_channel(ctx: &Arc<Context>) -> Result<Arc<RawChannel>, String> {
    ctx.channel_builder(RADIO_TOPIC)
        .message_encoding("json")
        .schema(Schema::new(
            "RadioBytes",
            "jsonschema",
            RADIO_SCHEMA.as_bytes(),
        ))
        .build_raw()
        .map_err(|e| format!("the radio channel: {e}"))
}

/// Logs what `from` put on the air at `t_ns`.
pub fn log_radio(channel: &RawChannel, from: &str, bytes: &[u8], t_ns: u64) {
    // Written directly (no JSON value in between: this is the busiest channel); `from`
    // is a sender's name, never anything that needs escaping.
    let mut message = Vec::with_capacity(24 + from.len() + 2 * bytes.len());
    message.extend_from_slice(br#"{"from":""#);
    message.extend_from_slice(from.as_bytes());
    message.extend_from_slice(br#"","hex":""#);
    let start = message.len();
    message.resize(start + 2 * bytes.len(), 0);
    let _ = hex::encode_to_slice(bytes, &mut message[start..]);
    message.extend_from_slice(br#""}"#);
    channel.log_with_meta(
        &message,
        PartialMetadata {
            log_time: Some(t_ns),
        },
    );
}

/// The events channel on `ctx`.
pub fn events_channel(ctx: &Arc<Context>) -> Channel<Log> {
    ctx.channel_builder(EVENTS_TOPIC).build::<Log>()
}

/// Logs one station event (its report name, and its robot if any) at `t_ns`, at its
/// severity (Foxglove's log panel filters by it).
pub fn log_event(channel: &Channel<Log>, event: &str, robot: Option<u16>, t_ns: u64) {
    let message = match robot {
        Some(id) => format!("{event} (robot {id})"),
        None => event.to_string(),
    };
    channel.log_with_time(
        &Log {
            timestamp: stamp(t_ns),
            level: match crate::station::Severity::of(event) {
                crate::station::Severity::Info => log::Level::Info,
                crate::station::Severity::Warning => log::Level::Warning,
                crate::station::Severity::Error => log::Level::Error,
            } as i32,
            message,
            name: "base station".into(),
            ..Default::default()
        },
        t_ns,
    );
}

/// A message's own timestamp, from nanoseconds.
pub fn stamp(t_ns: u64) -> Option<Timestamp> {
    Some(Timestamp::new(
        (t_ns / 1_000_000_000) as u32,
        (t_ns % 1_000_000_000) as u32,
    ))
}

pub fn point(x: f64, y: f64) -> Point3 {
    Point3 { x, y, z: 0.0 }
}

/// A pose in the plane at height `z`, turned by `heading` about the vertical.
pub fn pose(x: f64, y: f64, z: f64, heading: f64) -> Option<Pose> {
    Some(Pose {
        position: Some(Vector3 { x, y, z }),
        orientation: Some(turned(heading)),
    })
}

/// A turn by `heading` about the vertical.
pub fn turned(heading: f64) -> Quaternion {
    let h = 0.5 * heading;
    Quaternion {
        x: 0.0,
        y: 0.0,
        z: h.sin(),
        w: h.cos(),
    }
}

pub fn color(r: f64, g: f64, b: f64) -> Option<Color> {
    Some(Color { r, g, b, a: 1.0 })
}

/// The site's obstacles: circles as 1 m cylinders, segments and polygons as lines; grey.
pub fn map_entity(obstacles: &[Obstacle]) -> SceneEntity {
    obstacles_entity("map", color(0.45, 0.45, 0.5), 1.0, obstacles)
}

/// The station's sensed marks (`/sensed`): what its scans hold that the site map does not
/// (a van, a bin, a person who stopped, with the room they are owed, and the lane they
/// will walk on), which the route keeps out of; 0.3 m amber discs.
pub const SENSED_TOPIC: &str = "/sensed";

/// The marks in the scene at `t_ns`, as [`SENSED_TOPIC`] shows them.
pub fn sensed_entity(t_ns: u64, marks: &[Obstacle]) -> SceneEntity {
    SceneEntity {
        timestamp: stamp(t_ns),
        ..obstacles_entity("sensed", color(0.95, 0.65, 0.1), 0.3, marks)
    }
}

/// `obstacles` as scene entity `id`: circles as cylinders `height` tall, segments and
/// polygons as lines.
fn obstacles_entity(
    id: &str,
    hue: Option<Color>,
    height: f64,
    obstacles: &[Obstacle],
) -> SceneEntity {
    let mut e = SceneEntity {
        frame_id: FRAME.into(),
        id: id.into(),
        ..Default::default()
    };
    for o in obstacles {
        match o {
            Obstacle::Circle { center, radius } => e.cylinders.push(CylinderPrimitive {
                pose: pose(center.x, center.y, 0.5 * height, 0.0),
                size: Some(Vector3 {
                    x: 2.0 * radius,
                    y: 2.0 * radius,
                    z: height,
                }),
                bottom_scale: 1.0,
                top_scale: 1.0,
                color: hue,
            }),
            Obstacle::Segment { a, b } => e.lines.push(LinePrimitive {
                r#type: line_primitive::Type::LineStrip as i32,
                thickness: 0.1,
                points: vec![point(a.x, a.y), point(b.x, b.y)],
                color: hue,
                ..Default::default()
            }),
            Obstacle::Polygon { points } => e.lines.push(LinePrimitive {
                r#type: line_primitive::Type::LineLoop as i32,
                thickness: 0.1,
                points: points.iter().map(|p| point(p.x, p.y)).collect(),
                color: hue,
                ..Default::default()
            }),
        }
    }
    e
}

/// A follower's slot point in the scene: a small green sphere.
pub fn slot_marker((x, y): (f64, f64)) -> foxglove::messages::SpherePrimitive {
    foxglove::messages::SpherePrimitive {
        pose: pose(x, y, 0.05, 0.0),
        size: Some(Vector3 {
            x: 0.15,
            y: 0.15,
            z: 0.15,
        }),
        color: color(0.2, 0.8, 0.3),
    }
}

/// A route the station planned, at `t_ns`: a blue line strip (`/route`).
pub fn route_entity(t_ns: u64, points: &[glam::DVec2]) -> SceneEntity {
    SceneEntity {
        timestamp: stamp(t_ns),
        frame_id: FRAME.into(),
        id: "route".into(),
        lines: vec![LinePrimitive {
            r#type: line_primitive::Type::LineStrip as i32,
            thickness: 0.05,
            points: points.iter().map(|p| point(p.x, p.y)).collect(),
            color: color(0.1, 0.5, 0.95),
            ..Default::default()
        }],
        ..Default::default()
    }
}

/// What the station tracks (a scene update per sample while it tracks anything).
pub const TRACKS_TOPIC: &str = "/tracks";

/// The station's tracks in the scene: each a disc of its radius grown by one sigma
/// (moving orange, still grey, not judged yet yellow) and, moving, an arrow of where it
/// will be in a second.
pub fn tracks_entity(t_ns: u64, tracks: &[TrackView]) -> SceneEntity {
    let mut e = SceneEntity {
        timestamp: stamp(t_ns),
        frame_id: FRAME.into(),
        id: "tracks".into(),
        ..Default::default()
    };
    for t in tracks {
        let hue = match t.motion {
            Motion::Moving => color(1.0, 0.55, 0.0),
            Motion::Still => color(0.55, 0.55, 0.55),
            Motion::New => color(0.95, 0.85, 0.2),
        };
        let across = 2.0 * (t.radius + t.position_sigma).max(0.1);
        e.cylinders.push(CylinderPrimitive {
            pose: pose(t.position.x, t.position.y, 0.05, 0.0),
            size: Some(Vector3 {
                x: across,
                y: across,
                z: 0.1,
            }),
            bottom_scale: 1.0,
            top_scale: 1.0,
            color: hue.map(|c| Color { a: 0.6, ..c }),
        });
        let speed = t.velocity.length();
        if t.motion == Motion::Moving && speed > 0.05 {
            e.arrows.push(ArrowPrimitive {
                pose: pose(
                    t.position.x,
                    t.position.y,
                    0.15,
                    t.velocity.y.atan2(t.velocity.x),
                ),
                shaft_length: speed,
                shaft_diameter: 0.05,
                head_length: 0.15,
                head_diameter: 0.15,
                color: hue,
            });
        }
    }
    e
}

/// Each robot's frame in the site frame, every sample.
pub const TF_TOPIC: &str = "/tf";

/// A robot's body in its own frame (`robot_N`), drawn once and moved by `/tf`: its
/// footprint (leader orange, followers blue) and a heading arrow.
pub fn robot_entity(id: u16, leads: bool, footprint: f64) -> SceneEntity {
    let hue = if leads {
        color(0.85, 0.3, 0.1)
    } else {
        color(0.1, 0.45, 0.85)
    };
    SceneEntity {
        frame_id: format!("robot_{id}"),
        id: format!("robot_{id}"),
        frame_locked: true,
        cylinders: vec![CylinderPrimitive {
            pose: pose(0.0, 0.0, 0.15, 0.0),
            size: Some(Vector3 {
                x: 2.0 * footprint,
                y: 2.0 * footprint,
                z: 0.3,
            }),
            bottom_scale: 1.0,
            top_scale: 1.0,
            color: hue,
        }],
        arrows: vec![ArrowPrimitive {
            pose: pose(0.0, 0.0, 0.35, 0.0),
            shaft_length: footprint,
            shaft_diameter: 0.06,
            head_length: 0.15,
            head_diameter: 0.15,
            color: color(1.0, 1.0, 1.0),
        }],
        ..Default::default()
    }
}

/// One robot's link as the base station sees it (`/robot_N/link`, plottable).
#[derive(foxglove::Encode, Debug, Clone, Copy, PartialEq)]
pub struct LinkHealth {
    pub linked: bool,
    /// Since the robot was last heard, ms (−1: never).
    pub last_heard_ms: i64,
    pub accepted: u32,
    pub lost: u32,
    pub rejected: u32,
}

/// Each robot's link health at the station's clock `now_ms`.
pub fn link_health(station: &crate::station::BaseStation, now_ms: u32) -> Vec<(u16, LinkHealth)> {
    station
        .link()
        .peers()
        .iter()
        .filter_map(|peer| {
            let protocol::Address::Robot(id) = peer.address else {
                return None;
            };
            Some((
                id,
                LinkHealth {
                    linked: peer.is_linked(),
                    last_heard_ms: peer
                        .last_rx_ms
                        .map_or(-1, |r| now_ms.wrapping_sub(r) as i64),
                    accepted: peer.accepted,
                    lost: peer.lost,
                    rejected: peer.rejects.total(),
                },
            ))
        })
        .collect()
}
