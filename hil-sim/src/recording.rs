//! A run recorded as MCAP with the Foxglove SDK, to open in Foxglove or Lichtblick: the site
//! map and the robots as a 3D scene (obstacles, footprints, headings, followers' slot
//! points), each robot's pose, speeds and tracking error (plottable), the base station's
//! events as log messages, and the raw radio bytes every node sent (`/radio`, JSON, which
//! `basestation decode` reads). Timestamps are the simulated clock (nanoseconds from
//! the run's start). Written after the run from what the recorder kept, through a context
//! of its own, so runs recorded side by side (tests) never mix.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use base_station::geometry::Obstacle;
use foxglove::messages::{
    line_primitive, log, ArrowPrimitive, Color, CylinderPrimitive, LinePrimitive, Log, Point3,
    Pose, PoseInFrame, Quaternion, SceneEntity, SceneUpdate, SpherePrimitive, Timestamp, Vector3,
};
use foxglove::{Channel, Context, McapWriter, PartialMetadata, RawChannel, Schema};

use crate::report::Report;
use crate::world::World;

/// The frame every position is in: the site's metric frame.
pub const FRAME: &str = "site";

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
pub fn link_health(
    station: &base_station::station::BaseStation,
    now_ms: u32,
) -> Vec<(u16, LinkHealth)> {
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

/// The formation's shape when it changes: `wide`, `to_line`, `line`, `to_wide`.
#[derive(foxglove::Encode)]
struct FormationShape {
    shape: String,
}

/// What a robot's state channel carries (plottable in Foxglove's Plot panel).
#[derive(foxglove::Encode)]
struct RobotState {
    /// Forward speed, m/s.
    v: f64,
    /// Turn rate, rad/s.
    omega: f64,
    /// Distance from the follower's control point to its slot, m (−1: not a follower).
    tracking_error: f64,
    /// The formation's blend, 0 wide … 1 line.
    blend: f64,
}

/// The radio channel's topic and the JSON schema of its messages: `from` (`base`,
/// `robot:N`, `attacker`) and `hex` (the bytes it put on the air, frames with their
/// delimiters).
pub const RADIO_TOPIC: &str = "/radio";
const RADIO_SCHEMA: &str = r#"{"type":"object","properties":{"from":{"type":"string"},"hex":{"type":"string"}},"required":["from","hex"]}"#;

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
    let message = serde_json::json!({ "from": from, "hex": hex::encode(bytes) }).to_string();
    channel.log_with_meta(
        message.as_bytes(),
        PartialMetadata {
            log_time: Some(t_ns),
        },
    );
}

/// The events channel on `ctx`.
pub fn events_channel(ctx: &Arc<Context>) -> Channel<Log> {
    ctx.channel_builder(EVENTS_TOPIC).build::<Log>()
}

/// Logs one station event (its report name, and its robot if any) at `t_ns`.
pub fn log_event(channel: &Channel<Log>, event: &str, robot: Option<u16>, t_ns: u64) {
    let message = match robot {
        Some(id) => format!("{event} (robot {id})"),
        None => event.to_string(),
    };
    channel.log_with_time(
        &Log {
            timestamp: stamp(t_ns),
            level: log::Level::Info as i32,
            message,
            name: "base station".into(),
            ..Default::default()
        },
        t_ns,
    );
}

/// Messages written per topic.
pub type Counts = BTreeMap<String, u64>;

fn nanos(t_s: f64) -> u64 {
    (t_s * 1e9).round() as u64
}

/// A message's own timestamp, from nanoseconds.
pub fn stamp(t_ns: u64) -> Option<Timestamp> {
    Some(Timestamp::new(
        (t_ns / 1_000_000_000) as u32,
        (t_ns % 1_000_000_000) as u32,
    ))
}

fn point(x: f64, y: f64) -> Point3 {
    Point3 { x, y, z: 0.0 }
}

/// A pose in the plane at height `z`, turned by `heading` about the vertical.
pub fn pose(x: f64, y: f64, z: f64, heading: f64) -> Option<Pose> {
    let h = 0.5 * heading;
    Some(Pose {
        position: Some(Vector3 { x, y, z }),
        orientation: Some(Quaternion {
            x: 0.0,
            y: 0.0,
            z: h.sin(),
            w: h.cos(),
        }),
    })
}

fn color(r: f64, g: f64, b: f64) -> Option<Color> {
    Some(Color { r, g, b, a: 1.0 })
}

/// The site's obstacles: circles as 1 m cylinders, segments and polygons as lines.
fn map_entity(world: &World) -> SceneEntity {
    let grey = color(0.45, 0.45, 0.5);
    let mut e = SceneEntity {
        frame_id: FRAME.into(),
        id: "map".into(),
        ..Default::default()
    };
    for o in world.map.obstacles() {
        match o {
            Obstacle::Circle { center, radius } => e.cylinders.push(CylinderPrimitive {
                pose: pose(center.x, center.y, 0.5, 0.0),
                size: Some(Vector3 {
                    x: 2.0 * radius,
                    y: 2.0 * radius,
                    z: 1.0,
                }),
                bottom_scale: 1.0,
                top_scale: 1.0,
                color: grey,
            }),
            Obstacle::Segment { a, b } => e.lines.push(LinePrimitive {
                r#type: line_primitive::Type::LineStrip as i32,
                thickness: 0.1,
                points: vec![point(a.x, a.y), point(b.x, b.y)],
                color: grey,
                ..Default::default()
            }),
            Obstacle::Polygon { points } => e.lines.push(LinePrimitive {
                r#type: line_primitive::Type::LineLoop as i32,
                thickness: 0.1,
                points: points.iter().map(|p| point(p.x, p.y)).collect(),
                color: grey,
                ..Default::default()
            }),
        }
    }
    e
}

/// Writes the run to `path`; returns how many messages each topic got.
pub fn write_mcap(world: &World, report: &Report, path: &Path) -> Result<Counts, String> {
    let ctx: Arc<Context> = Context::new();
    let file = std::fs::File::create(path)
        .map_err(|e| format!("cannot create {}: {e}", path.display()))?;
    let mcap = McapWriter::new()
        .context(&ctx)
        .create(std::io::BufWriter::new(file))
        .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    let mut counts = Counts::new();
    let mut count = |topic: &str| *counts.entry(topic.to_string()).or_default() += 1;

    let map = ctx.channel_builder("/map").build::<SceneUpdate>();
    map.log_with_time(
        &SceneUpdate {
            entities: vec![map_entity(world)],
            ..Default::default()
        },
        0u64,
    );
    count("/map");

    let scene = ctx.channel_builder("/robots").build::<SceneUpdate>();
    // Per robot: its pose channel and its state channel.
    let channels: Vec<_> = world
        .robots
        .iter()
        .map(|r| {
            let topic = |what: &str| format!("/robot_{}/{what}", r.id);
            (
                ctx.channel_builder(topic("pose")).build::<PoseInFrame>(),
                ctx.channel_builder(topic("state")).build::<RobotState>(),
            )
        })
        .collect();
    let footprint = world
        .robots
        .first()
        .map_or(0.3, |r| r.body.params.footprint);
    for s in &world.recorder.samples {
        let t = nanos(s.t);
        let mut entities = Vec::new();
        for ((r, sample), (pose_ch, state_ch)) in world.robots.iter().zip(&s.robots).zip(&channels)
        {
            let hue = if r.role == base_station::scenario::Role::Leader {
                color(0.85, 0.3, 0.1)
            } else {
                color(0.1, 0.45, 0.85)
            };
            let mut e = SceneEntity {
                timestamp: stamp(t),
                frame_id: FRAME.into(),
                id: format!("robot_{}", r.id),
                ..Default::default()
            };
            e.cylinders.push(CylinderPrimitive {
                pose: pose(sample.x, sample.y, 0.15, sample.heading),
                size: Some(Vector3 {
                    x: 2.0 * footprint,
                    y: 2.0 * footprint,
                    z: 0.3,
                }),
                bottom_scale: 1.0,
                top_scale: 1.0,
                color: hue,
            });
            e.arrows.push(ArrowPrimitive {
                pose: pose(sample.x, sample.y, 0.35, sample.heading),
                shaft_length: footprint,
                shaft_diameter: 0.06,
                head_length: 0.15,
                head_diameter: 0.15,
                color: color(1.0, 1.0, 1.0),
            });
            if let Some((sx, sy)) = sample.slot {
                e.spheres.push(SpherePrimitive {
                    pose: pose(sx, sy, 0.05, 0.0),
                    size: Some(Vector3 {
                        x: 0.15,
                        y: 0.15,
                        z: 0.15,
                    }),
                    color: color(0.2, 0.8, 0.3),
                });
            }
            entities.push(e);
            pose_ch.log_with_time(
                &PoseInFrame {
                    timestamp: stamp(t),
                    frame_id: FRAME.into(),
                    pose: pose(sample.x, sample.y, 0.0, sample.heading),
                },
                t,
            );
            count(pose_ch.topic());
            state_ch.log_with_time(
                &RobotState {
                    v: sample.v,
                    omega: sample.omega,
                    tracking_error: sample.error.unwrap_or(-1.0),
                    blend: s.blend,
                },
                t,
            );
            count(state_ch.topic());
        }
        scene.log_with_time(
            &SceneUpdate {
                entities,
                ..Default::default()
            },
            t,
        );
        count("/robots");
    }

    // The planned route, each time the station planned one; the shape, each time it changed.
    let routes = ctx.channel_builder("/route").build::<SceneUpdate>();
    for (t_us, points) in &world.routes {
        let mut e = SceneEntity {
            timestamp: stamp(t_us * 1000),
            frame_id: FRAME.into(),
            id: "route".into(),
            ..Default::default()
        };
        e.lines.push(LinePrimitive {
            r#type: line_primitive::Type::LineStrip as i32,
            thickness: 0.05,
            points: points.iter().map(|p| point(p.x, p.y)).collect(),
            color: color(0.1, 0.5, 0.95),
            ..Default::default()
        });
        routes.log_with_time(
            &SceneUpdate {
                entities: vec![e],
                ..Default::default()
            },
            t_us * 1000,
        );
        count("/route");
    }
    let links: BTreeMap<u16, Channel<LinkHealth>> = world
        .robots
        .iter()
        .map(|r| {
            let ch = ctx.channel_builder(format!("/robot_{}/link", r.id)).build();
            (r.id, ch)
        })
        .collect();
    for (t_us, health) in &world.links {
        for (id, h) in health {
            if let Some(ch) = links.get(id) {
                ch.log_with_time(h, t_us * 1000);
                count(ch.topic());
            }
        }
    }
    let shapes = ctx.channel_builder("/formation").build::<FormationShape>();
    let mut shape = "";
    for s in &world.recorder.samples {
        if s.shape != shape {
            shape = s.shape;
            shapes.log_with_time(
                &FormationShape {
                    shape: shape.into(),
                },
                nanos(s.t),
            );
            count("/formation");
        }
    }

    let events = events_channel(&ctx);
    for e in &report.station_events {
        log_event(&events, &e.event, e.robot, nanos(e.at_s));
        count(EVENTS_TOPIC);
    }
    let radio = radio_channel(&ctx)?;
    for (t_us, from, bytes) in &world.transmitted {
        let from = match *from {
            0 => "base".to_string(),
            n if n <= world.robots.len() => format!("robot:{}", world.robots[n - 1].id),
            _ => "attacker".to_string(),
        };
        log_radio(&radio, &from, bytes, t_us * 1000);
        count(RADIO_TOPIC);
    }
    mcap.close()
        .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    Ok(counts)
}
