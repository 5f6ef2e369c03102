//! `run --mcap FILE` / `--live [ADDR]`: the run recorded as MCAP and/or served live over
//! the Foxglove WebSocket protocol, from the same log calls (the same channels as a
//! simulation's recording where the station knows them): the radio bytes both ways, the
//! base station's events, each robot's pose as its telemetry reports it and its link's
//! health once a second, and the scene a simulation's recording has (`/map`, `/route`,
//! `/tf`, `/robots` with the slots, `/robot_N/state`, `/formation`, `/tracks`,
//! `/sensed`), so one Foxglove layout serves both; a metadata record opens the file. `sim
//! --realtime --live` serves the same. Timestamps: the caller's clock (the wall clock in
//! `run`, the simulated one in `sim`).

pub mod layout;
mod stream;

use std::collections::BTreeMap;
use std::io::BufWriter;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::SystemTime;

use anyhow::Context as _;
use base_station::geometry::Obstacle;
use base_station::recording::{
    events_channel, link_health, log_event, log_radio, map_entity, pose, radio_channel,
    robot_entity, route_entity, sensed_entity, slot_marker, stamp, tracks_entity, turned,
    FormationShape, LinkHealth, RobotState, FRAME, SENSED_TOPIC, TF_TOPIC, TRACKS_TOPIC,
};
use base_station::scenario::Scenario;
use base_station::station::BaseStation;
use foxglove::messages::{
    FrameTransform, FrameTransforms, Log, PoseInFrame, SceneEntity, SceneUpdate, Vector3,
};
use foxglove::{Channel, Context, McapWriter, McapWriterHandle, RawChannel};
use stream::Stream;

pub struct LiveRecording {
    _ctx: Arc<Context>,
    /// The writer, the partial file it writes and the path it takes at the end.
    writer: Option<Writer>,
    server: Option<Stream>,
    radio: Arc<RawChannel>,
    events: Channel<Log>,
    poses: BTreeMap<u16, (Channel<PoseInFrame>, u32)>,
    links: BTreeMap<u16, Channel<LinkHealth>>,
    /// The station's clock at the last link health logged, ms.
    links_logged_ms: Option<u32>,
    events_logged: usize,
    scene: Scene,
}

/// The MCAP writer, the partial file it writes and the path it takes at the end.
type Writer = (McapWriterHandle<BufWriter<std::fs::File>>, PathBuf, PathBuf);

/// The scene channels a simulation's recording has too, fed from what the station knows.
struct Scene {
    robots: Channel<SceneUpdate>,
    frames: Channel<FrameTransforms>,
    states: BTreeMap<u16, Channel<RobotState>>,
    routes: Channel<SceneUpdate>,
    shapes: Channel<FormationShape>,
    tracks: Channel<SceneUpdate>,
    sensed: Channel<SceneUpdate>,
    /// The sensed marks last logged, and the station's clock when they were last
    /// looked at, ms.
    marks: Vec<Obstacle>,
    marks_ms: Option<u32>,
    leader: u16,
    footprint: f64,
    track_width: f64,
    bodies_drawn: bool,
    /// The route last logged (its length and last point: enough to see it change).
    route: Option<(usize, [f64; 2])>,
    shape: &'static str,
    /// The station's clock at the last scene update, ms.
    scene_ms: Option<u32>,
}

/// Scene updates at most this often, ms (the station steps at 10 Hz).
const SCENE_EVERY_MS: u32 = 100;

/// Now, ns since the Unix epoch.
pub fn now_ns() -> u64 {
    SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

impl LiveRecording {
    /// Records to `mcap` and/or serves on `live` (either may be absent; browsers' pages from
    /// `origins` and the default ones may open it), a pose channel per robot of `robots`;
    /// the file opens with a metadata record of `scenario`'s run.
    pub fn create(
        scenario: &Scenario,
        mcap: Option<&Path>,
        live: Option<SocketAddr>,
        origins: &[String],
        robots: impl IntoIterator<Item = u16>,
    ) -> anyhow::Result<Self> {
        let ctx = Context::new();
        let writer = mcap
            .map(|path| open_writer(&ctx, scenario, path))
            .transpose()?;
        let server = live
            .map(|addr| open_server(&ctx, addr, origins))
            .transpose()?;
        let radio = radio_channel(&ctx).map_err(anyhow::Error::msg)?;
        let events = events_channel(&ctx);
        let robots: Vec<u16> = robots.into_iter().collect();
        let map = ctx.channel_builder("/map").build::<SceneUpdate>();
        map.log_with_time(
            &SceneUpdate {
                entities: vec![map_entity(scenario.build_site().obstacles())],
                ..Default::default()
            },
            now_ns(),
        );
        let scene = Scene::new(&ctx, scenario, &robots);
        let links = robots
            .iter()
            .map(|id| {
                let ch = ctx
                    .channel_builder(format!("/robot_{id}/link"))
                    .build::<LinkHealth>();
                (*id, ch)
            })
            .collect();
        let poses = robots
            .into_iter()
            .map(|id| {
                let ch = ctx
                    .channel_builder(format!("/robot_{id}/pose"))
                    .build::<PoseInFrame>();
                (id, (ch, u32::MAX))
            })
            .collect();
        Ok(Self {
            _ctx: ctx,
            writer,
            server,
            radio,
            events,
            poses,
            links,
            links_logged_ms: None,
            events_logged: 0,
            scene,
        })
    }

    /// Bytes the station sent (`from` `base`) or received (`air`: any sender) at `t_ns`.
    pub fn radio(&self, from: &str, bytes: &[u8], t_ns: u64) {
        if !bytes.is_empty() {
            log_radio(&self.radio, from, bytes, t_ns);
        }
    }

    /// What the station learnt since the last call, at `t` (its clock `now_ms`): new
    /// events, new telemetry poses, and each robot's link health once a second.
    pub fn station(&mut self, station: &BaseStation, now_ms: u32, t: u64) {
        if self
            .links_logged_ms
            .is_none_or(|last| now_ms.wrapping_sub(last) >= 1000)
        {
            self.links_logged_ms = Some(now_ms);
            for (id, health) in link_health(station, now_ms) {
                if let Some(channel) = self.links.get(&id) {
                    channel.log_with_time(&health, t);
                }
            }
        }
        let leader = station.config().leader;
        for e in &station.events()[self.events_logged..] {
            let (_, name, robot) = e.describe(leader);
            log_event(&self.events, &name, robot, t);
        }
        self.events_logged = station.events().len();
        for (id, status) in station.robots() {
            let (Some(telemetry), Some((channel, seen))) =
                (status.telemetry, self.poses.get_mut(id))
            else {
                continue;
            };
            if *seen == status.received_ms {
                continue;
            }
            *seen = status.received_ms;
            let (x, y, heading) = telemetry.pose.to_si();
            channel.log_with_time(
                &PoseInFrame {
                    timestamp: stamp(t),
                    frame_id: FRAME.into(),
                    pose: pose(x as f64, y as f64, 0.0, heading as f64),
                },
                t,
            );
        }
    }

    /// The scene at the station's clock `now_ms`, at `t` (every [`SCENE_EVERY_MS`]).
    pub fn scene(&mut self, station: &BaseStation, now_ms: u32, t: u64) {
        let due = self
            .scene
            .scene_ms
            .is_none_or(|last| now_ms.wrapping_sub(last) >= SCENE_EVERY_MS);
        if due {
            self.scene.scene_ms = Some(now_ms);
            self.scene.update(station, now_ms, t);
        }
    }

    pub fn close(self) -> anyhow::Result<()> {
        if let Some(server) = self.server {
            server.stop();
        }
        let Some((writer, partial, path)) = self.writer else {
            return Ok(());
        };
        writer.close().context("cannot finish the recording")?;
        std::fs::rename(&partial, &path).with_context(|| format!("cannot write {}", path.display()))
    }
}

impl Scene {
    fn new(ctx: &Arc<Context>, scenario: &Scenario, robots: &[u16]) -> Self {
        Self {
            robots: ctx.channel_builder("/robots").build(),
            frames: ctx.channel_builder(TF_TOPIC).build(),
            states: robots
                .iter()
                .map(|id| {
                    (
                        *id,
                        ctx.channel_builder(format!("/robot_{id}/state")).build(),
                    )
                })
                .collect(),
            routes: ctx.channel_builder("/route").build(),
            shapes: ctx.channel_builder("/formation").build(),
            tracks: ctx.channel_builder(TRACKS_TOPIC).build(),
            sensed: ctx.channel_builder(SENSED_TOPIC).build(),
            marks: Vec::new(),
            marks_ms: None,
            leader: scenario
                .robots
                .iter()
                .find(|r| r.role == base_station::scenario::Role::Leader)
                .map_or(0, |r| r.id),
            footprint: scenario.robot.footprint_radius,
            track_width: scenario.robot.track_width,
            bodies_drawn: false,
            route: None,
            shape: "",
            scene_ms: None,
        }
    }

    /// Each robot's frame and state from its telemetry, the robots' bodies (once) and
    /// the slots, the route when it changed, the shape when it changed, the tracks, the
    /// sensed marks when they changed.
    fn update(&mut self, station: &BaseStation, now_ms: u32, t: u64) {
        let mut transforms = Vec::new();
        for (id, status) in station.robots() {
            let Some(telemetry) = status.telemetry else {
                continue;
            };
            let (x, y, heading) = telemetry.pose.to_si();
            transforms.push(FrameTransform {
                timestamp: stamp(t),
                parent_frame_id: FRAME.into(),
                child_frame_id: format!("robot_{id}"),
                translation: Some(Vector3 {
                    x: x as f64,
                    y: y as f64,
                    z: 0.0,
                }),
                rotation: Some(turned(heading as f64)),
            });
            let [l, r] = telemetry.wheel_mm_s.map(|w| w as f64 / 1000.0);
            if let Some(channel) = self.states.get(id) {
                let follower = *id != self.leader;
                channel.log_with_time(
                    &RobotState {
                        v: 0.5 * (l + r),
                        omega: (r - l) / self.track_width,
                        tracking_error: if follower {
                            telemetry.tracking_error_mm as f64 / 1000.0
                        } else {
                            -1.0
                        },
                        blend: station.formation().blend(),
                    },
                    t,
                );
            }
        }
        self.frames
            .log_with_time(&FrameTransforms { transforms }, t);
        let mut entities = Vec::new();
        if !self.bodies_drawn {
            self.bodies_drawn = true;
            entities.extend(
                self.states
                    .keys()
                    .map(|id| robot_entity(*id, *id == self.leader, self.footprint)),
            );
        }
        let mut slots = SceneEntity {
            timestamp: stamp(t),
            frame_id: FRAME.into(),
            id: "slots".into(),
            ..Default::default()
        };
        if let Some(l) = station.leader_estimate(now_ms) {
            for p in station.formation().slot_points(l.pose) {
                slots.spheres.push(slot_marker((p.x, p.y)));
            }
        }
        entities.push(slots);
        self.robots.log_with_time(
            &SceneUpdate {
                entities,
                ..Default::default()
            },
            t,
        );
        self.note_route(station, t);
        self.note_shape(station, t);
        self.note_sensed(station, now_ms, t);
        let tracks: Vec<_> = station.tracks(now_ms).collect();
        if !tracks.is_empty() {
            self.tracks.log_with_time(
                &SceneUpdate {
                    entities: vec![tracks_entity(t, &tracks)],
                    ..Default::default()
                },
                t,
            );
        }
    }

    /// The sensed marks, looked at once a second and logged where they changed, as in a
    /// simulation's recording (ordering thousands of them at 10 Hz would cost the loop).
    fn note_sensed(&mut self, station: &BaseStation, now_ms: u32, t: u64) {
        if self
            .marks_ms
            .is_some_and(|last| now_ms.wrapping_sub(last) < 1000)
        {
            return;
        }
        self.marks_ms = Some(now_ms);
        let marks = station.perception().in_order();
        if marks == self.marks {
            return;
        }
        self.sensed.log_with_time(
            &SceneUpdate {
                entities: vec![sensed_entity(t, &marks)],
                ..Default::default()
            },
            t,
        );
        self.marks = marks;
    }

    /// The route, when it changed: a blue line strip, as in a simulation's recording.
    fn note_route(&mut self, station: &BaseStation, t: u64) {
        let Some(route) = station.route() else {
            return;
        };
        let key = route
            .points
            .last()
            .map(|p| (route.points.len(), [p.x, p.y]));
        if key == self.route {
            return;
        }
        self.route = key;
        self.routes.log_with_time(
            &SceneUpdate {
                entities: vec![route_entity(t, &route.points)],
                ..Default::default()
            },
            t,
        );
    }

    /// The formation's shape, when it changed (`wide`, `to_line`, `line`, `to_wide`).
    fn note_shape(&mut self, station: &BaseStation, t: u64) {
        let formation = station.formation();
        let shape = formation.target().shape_name(formation.blend());
        if shape != self.shape {
            self.shape = shape;
            self.shapes.log_with_time(
                &FormationShape {
                    shape: shape.into(),
                },
                t,
            );
        }
    }
}

/// The MCAP writer on a partial file beside `path` (renamed into place when it closes: an
/// interrupted run never leaves the last recording truncated), opened with the run's
/// metadata record.
fn open_writer(ctx: &Arc<Context>, scenario: &Scenario, path: &Path) -> anyhow::Result<Writer> {
    let partial = crate::commands::partial_path(path);
    let file = std::fs::File::create(&partial)
        .with_context(|| format!("cannot create {}", partial.display()))?;
    let writer = McapWriter::new()
        .context(ctx)
        .create(BufWriter::new(file))
        .with_context(|| format!("cannot write {}", partial.display()))?;
    let metadata = base_station::recording::run_metadata(
        &scenario.name,
        None,
        "robots",
        std::time::SystemTime::now(),
    );
    writer
        .write_metadata(base_station::recording::METADATA_NAME, metadata)
        .with_context(|| format!("cannot write {}", partial.display()))?;
    Ok((writer, partial, path.to_path_buf()))
}

/// The live stream on `addr`, its URL printed for the operator.
fn open_server(ctx: &Arc<Context>, addr: SocketAddr, origins: &[String]) -> anyhow::Result<Stream> {
    let (stream, url) = stream::start(ctx, addr, origins)?;
    eprintln!("live (Foxglove WebSocket): {url}");
    Ok(stream)
}
