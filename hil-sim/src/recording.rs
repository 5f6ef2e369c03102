//! A run recorded as MCAP with the Foxglove SDK, to open in Foxglove or Lichtblick: the site
//! map and the robots as a 3D scene (obstacles, footprints, headings, followers' slot
//! points), the movers (`/movers`, the truth), what the station tracks (`/tracks`) and the
//! marks it keeps of what its scans found unmapped (`/sensed`), each robot's pose, speeds
//! and tracking error (plottable), the base station's events as log messages, and the raw
//! radio bytes every node sent (`/radio`, JSON, which `basestation decode` reads), and
//! where areas are swept the ground swept so far (`/coverage`, a grid every 30 s).
//! Timestamps are the simulated clock (nanoseconds from the run's start). Written while
//! the run goes on ([`Recording`]: `sim` hands it what is new every few simulated seconds;
//! encoding and compression run on a thread of its own) or after it ([`write_mcap`]),
//! through a context of its own, so runs recorded side by side (tests) never mix.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::{mpsc, Arc};

use foxglove::messages::{
    packed_element_field::NumericType, CubePrimitive, CylinderPrimitive, FrameTransform,
    FrameTransforms, Grid, Log, PackedElementField, Pose, PoseInFrame, Quaternion, SceneEntity,
    SceneUpdate, Vector2, Vector3,
};
use foxglove::{Channel, Context, McapWriteOptions, McapWriter, RawChannel};

use base_station::geometry::Obstacle;
use glam::DVec2;

use crate::metrics::Sample;
use crate::movers::MoverState;
use crate::report::Report;
use crate::world::World;
use base_station::scenario::movers::MoverShape;

pub use base_station::recording::*;

/// The movers as they are (a simulation's truth), a scene update per sample.
pub const MOVERS_TOPIC: &str = "/movers";

/// The movers in the scene: persons as 1.7 m cylinders, cyclists and vehicles as boxes
/// turned along their way; purple.
fn movers_entity(t_ns: u64, movers: &[MoverState]) -> SceneEntity {
    let hue = color(0.55, 0.3, 0.75);
    let mut e = SceneEntity {
        timestamp: stamp(t_ns),
        frame_id: FRAME.into(),
        id: "movers".into(),
        ..Default::default()
    };
    for m in movers {
        let (x, y) = (m.position.x, m.position.y);
        match m.shape {
            MoverShape::Circle { radius } => e.cylinders.push(CylinderPrimitive {
                pose: pose(x, y, 0.85, 0.0),
                size: Some(Vector3 {
                    x: 2.0 * radius,
                    y: 2.0 * radius,
                    z: 1.7,
                }),
                bottom_scale: 1.0,
                top_scale: 1.0,
                color: hue,
            }),
            MoverShape::Rectangle { length, width } => e.cubes.push(CubePrimitive {
                pose: pose(x, y, 0.75, m.heading),
                size: Some(Vector3 {
                    x: length,
                    y: width,
                    z: 1.5,
                }),
                color: hue,
            }),
        }
    }
    e
}

/// Messages written per topic.
pub type Counts = BTreeMap<String, u64>;

fn nanos(t_s: f64) -> u64 {
    (t_s * 1e9).round() as u64
}

/// Writes the run to `path` after it ran; returns how many messages each topic got.
pub fn write_mcap(world: &World, report: &Report, path: &Path) -> Result<Counts, String> {
    Recording::create(world, path)?.finish(world, report)
}

/// What the run recorded since the last handover, on its way to the writer's thread: one
/// batch per handover, so one wake-up of the writer (a handover per record kind cost the
/// simulation 6 % of its time, mostly in waking the writer).
struct Batch {
    samples: Vec<Sample>,
    radio: Transmissions,
    routes: Vec<(u64, Vec<DVec2>)>,
    links: Vec<(u64, Vec<(u16, LinkHealth)>)>,
    sensed: Vec<(u64, Vec<Obstacle>)>,
    events: Vec<(String, Option<u16>, f64)>,
    /// The ground swept so far (`/coverage`), when a snapshot is due.
    coverage: Option<(u64, Grid)>,
}

/// The coverage layer is snapshot at most this often, µs of simulated time (an image of
/// the whole grid each: a 1,200 m² plaza is 480 kB before compression).
const COVERAGE_EVERY_US: u64 = 30_000_000;
/// The coverage layer's topic.
pub const COVERAGE_TOPIC: &str = "/coverage";

/// The ground swept as a Foxglove grid (RGBA cells in the site frame), if the run sweeps.
fn coverage_grid(world: &World) -> Option<Grid> {
    let grid = world.recorder.sweeping.as_ref()?.grid();
    let (origin, nx, _) = grid.shape();
    let cell = base_station::coverage::grid::CELL;
    let channel = |name: &str, offset: u32| PackedElementField {
        name: name.into(),
        offset,
        r#type: NumericType::Uint8 as i32,
    };
    Some(Grid {
        timestamp: stamp(world.t_us * 1000),
        frame_id: FRAME.into(),
        pose: Some(Pose {
            position: Some(Vector3 {
                x: origin.x,
                y: origin.y,
                z: -0.01,
            }),
            orientation: Some(Quaternion {
                w: 1.0,
                ..Default::default()
            }),
        }),
        column_count: nx as u32,
        cell_size: Some(Vector2 { x: cell, y: cell }),
        row_stride: 4 * nx as u32,
        cell_stride: 4,
        fields: vec![
            channel("red", 0),
            channel("green", 1),
            channel("blue", 2),
            channel("alpha", 3),
        ],
        data: grid.rgba().into(),
    })
}

/// Transmissions handed over at once, their bytes in one buffer: allocated by the
/// simulation and freed by the writer, so few allocations (one each, 144,000 an hour,
/// cost the simulation a quarter of its time in the allocator and the kernel).
#[derive(Default)]
struct Transmissions {
    /// When (µs), by which node, and where its bytes end in `bytes`.
    sent: Vec<(u64, usize, usize)>,
    bytes: Vec<u8>,
}

/// Batches in flight to the writer at most; a simulation faster than its writer waits.
const BATCHES_IN_FLIGHT: usize = 16;

/// A recording written while the run goes on, on a thread of its own: the simulation
/// hands over what is new ([`Recording::feed`], every [`Recording::FEED_EVERY_US`] of
/// simulated time) and goes on while it is encoded and compressed beside it.
pub struct Recording {
    batches: Option<mpsc::SyncSender<Batch>>,
    writer: Option<std::thread::JoinHandle<Result<Counts, String>>>,
    /// The file, as messages name it.
    shown: String,
    /// How much of each of the world's records was handed over.
    fed: Fed,
}

/// How many of each of the world's records were handed over.
#[derive(Debug, Clone, Copy, Default)]
struct Fed {
    samples: usize,
    radio: usize,
    routes: usize,
    links: usize,
    sensed: usize,
    /// When the last coverage snapshot was taken, µs.
    coverage_us: Option<u64>,
}

impl Fed {
    fn all(world: &World) -> Self {
        Self {
            samples: world.recorder.samples.len(),
            radio: world.transmitted.len(),
            routes: world.routes.len(),
            links: world.links.len(),
            sensed: world.sensed.len(),
            coverage_us: None,
        }
    }
}

impl Recording {
    /// How often a run hands over what is new, µs of simulated time: seldom enough that
    /// waking the writer costs the simulation nothing to speak of (every simulated second
    /// cost it 2–3 %), often enough that a batch stays small (about 200 kB).
    pub const FEED_EVERY_US: u64 = 5_000_000;

    /// Opens `path`, writes the site map and starts the writer.
    pub fn create(world: &World, path: &Path) -> Result<Self, String> {
        let ctx: Arc<Context> = Context::new();
        let file = std::fs::File::create(path)
            .map_err(|e| format!("cannot create {}: {e}", path.display()))?;
        // zstd's fastest level: the writer must keep up with a simulation at thousands
        // of times real time (an hour's file: 23.2 MB at both levels). Compressed on the
        // writer's own thread: zstd's worker threads (one per core by default) took the
        // simulation's core.
        let options = McapWriteOptions::default()
            .compression_level(1)
            .compression_threads(0);
        let mcap = McapWriter::with_options(options)
            .context(&ctx)
            .create(std::io::BufWriter::new(file))
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        let metadata = run_metadata(
            &world.scenario.name,
            Some(world.options.seed),
            world.options.firmware.name(),
            std::time::SystemTime::now(),
        );
        mcap.write_metadata(METADATA_NAME, metadata)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        let mut writer = Writer::new(&ctx, world)?;
        let map = ctx.channel_builder("/map").build::<SceneUpdate>();
        map.log_with_time(
            &SceneUpdate {
                entities: vec![map_entity(world.map.obstacles())],
                ..Default::default()
            },
            0u64,
        );
        writer.count("/map");
        let (batches, inbox) = mpsc::sync_channel(BATCHES_IN_FLIGHT);
        let shown = path.display().to_string();
        let named = shown.clone();
        let thread = std::thread::Builder::new()
            .name("mcap writer".into())
            .spawn(move || {
                // The channels live as long as their context.
                let _ctx = ctx;
                for batch in inbox {
                    writer.write(batch);
                }
                mcap.close()
                    .map_err(|e| format!("cannot write {named}: {e}"))?;
                Ok(writer.counts)
            })
            .map_err(|e| format!("cannot start the recording's writer: {e}"))?;
        Ok(Self {
            batches: Some(batches),
            writer: Some(thread),
            shown,
            fed: Fed::default(),
        })
    }

    /// What the world recorded since the last handover.
    fn batch(&mut self, world: &World) -> Batch {
        let fed = self.fed;
        let new = &world.transmitted[fed.radio..];
        let mut batch = Batch {
            samples: world.recorder.samples[fed.samples..].to_vec(),
            radio: Transmissions {
                sent: Vec::with_capacity(new.len()),
                bytes: Vec::with_capacity(new.iter().map(|(.., b)| b.len()).sum()),
            },
            routes: world.routes[fed.routes..].to_vec(),
            links: world.links[fed.links..].to_vec(),
            sensed: world.sensed[fed.sensed..].to_vec(),
            events: Vec::new(),
            coverage: None,
        };
        let due = fed
            .coverage_us
            .is_none_or(|t| world.t_us.saturating_sub(t) >= COVERAGE_EVERY_US);
        let mut coverage_us = fed.coverage_us;
        if due {
            batch.coverage = coverage_grid(world).map(|g| (world.t_us * 1000, g));
            coverage_us = Some(world.t_us);
        }
        for (t_us, from, bytes) in new {
            batch.radio.bytes.extend_from_slice(bytes);
            batch
                .radio
                .sent
                .push((*t_us, *from, batch.radio.bytes.len()));
        }
        self.fed = Fed {
            coverage_us,
            ..Fed::all(world)
        };
        batch
    }

    fn send(&self, batch: Batch) {
        // A writer that stopped says why at `finish`.
        if let Some(batches) = &self.batches {
            let _ = batches.send(batch);
        }
    }

    /// Hands over what the world recorded since the last call.
    pub fn feed(&mut self, world: &World) {
        let batch = self.batch(world);
        self.send(batch);
    }

    /// Hands over the rest and the station's events, and waits for the file to be
    /// written; returns how many messages each topic got.
    pub fn finish(mut self, world: &World, report: &Report) -> Result<Counts, String> {
        // The last snapshot is the run's end, whenever the one before was taken.
        self.fed.coverage_us = None;
        let mut batch = self.batch(world);
        batch.events = report
            .station_events
            .iter()
            .map(|e| (e.event.clone(), e.robot, e.at_s))
            .collect();
        self.send(batch);
        self.batches = None;
        let writer = self.writer.take().expect("finished once");
        writer
            .join()
            .map_err(|_| format!("the writer of {} stopped unexpectedly", self.shown))?
    }
}

/// Adds `n` messages to `topic`'s count (a new key only the first time: this runs per
/// message).
fn count(counts: &mut Counts, topic: &str, n: u64) {
    match counts.get_mut(topic) {
        Some(c) => *c += n,
        None => {
            counts.insert(topic.to_string(), n);
        }
    }
}

/// The radio channel's name of each node that transmits, by node number: the base
/// station, then the robots (`robot:ID`); any other node is the attacker.
fn sender_names(world: &World) -> Vec<String> {
    std::iter::once("base".to_string())
        .chain(world.robots.iter().map(|r| format!("robot:{}", r.id)))
        .collect()
}

/// The writer's channels and what it wrote, on its own thread.
struct Writer {
    scene: Channel<SceneUpdate>,
    frames: Channel<FrameTransforms>,
    /// The last sample's transforms and poses, one per robot, rewritten at each sample.
    tf: FrameTransforms,
    poses: Vec<PoseInFrame>,
    /// Per robot: its id, whether it leads, its pose and state channels.
    robots: Vec<(u16, bool, Channel<PoseInFrame>, Channel<RobotState>)>,
    footprint: f64,
    routes: Channel<SceneUpdate>,
    links: BTreeMap<u16, Channel<LinkHealth>>,
    shapes: Channel<FormationShape>,
    shape: &'static str,
    movers: Channel<SceneUpdate>,
    tracks: Channel<SceneUpdate>,
    sensed: Channel<SceneUpdate>,
    events: Channel<Log>,
    coverage: Channel<Grid>,
    radio: Arc<RawChannel>,
    senders: Vec<String>,
    counts: Counts,
}

impl Writer {
    fn new(ctx: &Arc<Context>, world: &World) -> Result<Self, String> {
        let robots = world
            .robots
            .iter()
            .map(|r| {
                let topic = |what: &str| format!("/robot_{}/{what}", r.id);
                (
                    r.id,
                    r.role == base_station::scenario::Role::Leader,
                    ctx.channel_builder(topic("pose")).build::<PoseInFrame>(),
                    ctx.channel_builder(topic("state")).build::<RobotState>(),
                )
            })
            .collect();
        let links = world
            .robots
            .iter()
            .map(|r| {
                let ch = ctx.channel_builder(format!("/robot_{}/link", r.id)).build();
                (r.id, ch)
            })
            .collect();
        let tf = FrameTransforms {
            transforms: world
                .robots
                .iter()
                .map(|r| FrameTransform {
                    parent_frame_id: FRAME.into(),
                    child_frame_id: format!("robot_{}", r.id),
                    ..Default::default()
                })
                .collect(),
        };
        let poses = world
            .robots
            .iter()
            .map(|_| PoseInFrame {
                frame_id: FRAME.into(),
                ..Default::default()
            })
            .collect();
        Ok(Self {
            scene: ctx.channel_builder("/robots").build::<SceneUpdate>(),
            frames: ctx.channel_builder(TF_TOPIC).build::<FrameTransforms>(),
            tf,
            poses,
            robots,
            footprint: world
                .robots
                .first()
                .map_or(0.3, |r| r.body.params.footprint),
            routes: ctx.channel_builder("/route").build::<SceneUpdate>(),
            movers: ctx.channel_builder(MOVERS_TOPIC).build::<SceneUpdate>(),
            tracks: ctx.channel_builder(TRACKS_TOPIC).build::<SceneUpdate>(),
            sensed: ctx.channel_builder(SENSED_TOPIC).build::<SceneUpdate>(),
            links,
            shapes: ctx.channel_builder("/formation").build::<FormationShape>(),
            shape: "",
            events: events_channel(ctx),
            coverage: ctx.channel_builder(COVERAGE_TOPIC).build::<Grid>(),
            radio: radio_channel(ctx)?,
            senders: sender_names(world),
            counts: Counts::new(),
        })
    }

    fn count(&mut self, topic: &str) {
        count(&mut self.counts, topic, 1);
    }

    fn write(&mut self, batch: Batch) {
        batch.samples.iter().for_each(|s| self.sample(s));
        let radio = batch.radio;
        count(&mut self.counts, RADIO_TOPIC, radio.sent.len() as u64);
        let mut start = 0;
        for (t_us, from, end) in radio.sent {
            let from = self.senders.get(from).map_or("attacker", String::as_str);
            log_radio(&self.radio, from, &radio.bytes[start..end], t_us * 1000);
            start = end;
        }
        batch.routes.iter().for_each(|(t, r)| self.route(*t, r));
        for (t_us, marks) in &batch.sensed {
            let t = t_us * 1000;
            let update = SceneUpdate {
                entities: vec![sensed_entity(t, marks)],
                ..Default::default()
            };
            self.sensed.log_with_time(&update, t);
            self.count(SENSED_TOPIC);
        }
        for (t_us, health) in batch.links {
            for (id, h) in health {
                if let Some(ch) = self.links.get(&id) {
                    ch.log_with_time(&h, t_us * 1000);
                    count(&mut self.counts, ch.topic(), 1);
                }
            }
        }
        if let Some((t, grid)) = batch.coverage {
            self.coverage.log_with_time(&grid, t);
            self.count(COVERAGE_TOPIC);
        }
        for (event, robot, at_s) in batch.events {
            log_event(&self.events, &event, robot, nanos(at_s));
            self.count(EVENTS_TOPIC);
        }
    }

    /// One sample: each robot's frame (`/tf`), the followers' slot points (`/robots`; the
    /// robots' bodies there once, at the first sample, locked to their frames), each
    /// robot's pose and state, the shape if it changed.
    fn sample(&mut self, s: &Sample) {
        let t = nanos(s.t);
        let mut entities = Vec::new();
        // The robots' bodies go into the scene once, with its first update.
        if !self.counts.contains_key("/robots") {
            entities.extend(
                self.robots
                    .iter()
                    .map(|(id, leads, ..)| robot_entity(*id, *leads, self.footprint)),
            );
        }
        let mut slots = SceneEntity {
            timestamp: stamp(t),
            frame_id: FRAME.into(),
            id: "slots".into(),
            ..Default::default()
        };
        // The transforms and poses are written into messages kept from the last sample:
        // their frame names stay, and nothing is allocated at 10 Hz per robot.
        let robots = self.robots.iter().zip(&s.robots);
        for (((_, _, pose_ch, state_ch), sample), (transform, pose_msg)) in
            robots.zip(self.tf.transforms.iter_mut().zip(&mut self.poses))
        {
            transform.timestamp = stamp(t);
            transform.translation = Some(Vector3 {
                x: sample.x,
                y: sample.y,
                z: 0.0,
            });
            transform.rotation = Some(turned(sample.heading));
            if let Some(slot) = sample.slot {
                slots.spheres.push(slot_marker(slot));
            }
            pose_msg.timestamp = stamp(t);
            pose_msg.pose = pose(sample.x, sample.y, 0.0, sample.heading);
            pose_ch.log_with_time(pose_msg, t);
            state_ch.log_with_time(
                &RobotState {
                    v: sample.v,
                    omega: sample.omega,
                    tracking_error: sample.error.unwrap_or(-1.0),
                    blend: s.blend,
                },
                t,
            );
        }
        for (_, _, pose_ch, state_ch) in &self.robots {
            for topic in [pose_ch.topic(), state_ch.topic()] {
                count(&mut self.counts, topic, 1);
            }
        }
        self.frames.log_with_time(&self.tf, t);
        self.count(TF_TOPIC);
        entities.push(slots);
        self.scene.log_with_time(
            &SceneUpdate {
                entities,
                ..Default::default()
            },
            t,
        );
        self.count("/robots");
        self.note_shape(s.shape, t);
        self.note_movers(s, t);
    }

    /// The movers (the truth) and the station's tracks, while there are any.
    fn note_movers(&mut self, s: &Sample, t: u64) {
        let scene = |e: SceneEntity| SceneUpdate {
            entities: vec![e],
            ..Default::default()
        };
        if !s.movers.is_empty() {
            self.movers
                .log_with_time(&scene(movers_entity(t, &s.movers)), t);
            self.count(MOVERS_TOPIC);
        }
        if !s.tracks.is_empty() {
            self.tracks
                .log_with_time(&scene(tracks_entity(t, &s.tracks)), t);
            self.count(TRACKS_TOPIC);
        }
    }

    /// The formation's shape, when it changed.
    fn note_shape(&mut self, shape: &'static str, t: u64) {
        if shape == self.shape {
            return;
        }
        self.shape = shape;
        self.shapes.log_with_time(
            &FormationShape {
                shape: shape.into(),
            },
            t,
        );
        self.count("/formation");
    }

    /// A route the station planned at `t_us`: a blue line strip.
    fn route(&mut self, t_us: u64, points: &[DVec2]) {
        self.routes.log_with_time(
            &SceneUpdate {
                entities: vec![route_entity(t_us * 1000, points)],
                ..Default::default()
            },
            t_us * 1000,
        );
        self.count("/route");
    }
}
