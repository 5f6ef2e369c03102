//! The simulated world: the real base station, the simulated radio, and each robot's body
//! around its brain, stepped on one simulated clock. Deterministic under a seed; no sleeping
//! unless `realtime`.

use std::collections::{HashMap, VecDeque};
use std::time::{Duration, Instant};

use base_station::geometry::map::Map;
use base_station::geometry::Obstacle;
use base_station::scenario::{Role, Scenario};
use base_station::station::{nonce_base, BaseStation, MoverPolicy, StationConfig};
use control_core::config::{self, RobotConfig};
use control_core::controller::{MotorOutput, Sensors};
use control_core::node::Identity;
use control_core::odometry::PoseFixSample;
use control_core::Pose;
use glam::DVec2;
use protocol::body::BodyConfig;
use protocol::frame::{self, Address};
use protocol::MasterKey;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use crate::brain::{Brain, BrainError, NativeBrain};
use crate::faults::{Action, DeadBrain, Heard, Injector};
use crate::metrics::{FleetView, Recorder, StationView, Tracked};
use crate::movers::{MoverState, Movers, RobotBody};
use crate::observer::AirObserver;
use crate::plant::{Body, BodyParams};
use crate::radio::ages::LeaderStateAges;
use crate::radio::{Medium, NodeId, Radio, RadioParams};
use crate::ring;
use crate::scanner::Scanner;

/// Which control code runs in the robots.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Firmware {
    /// The control core compiled for the host.
    Native,
    /// The real firmware ELF, one QEMU per robot.
    Qemu,
}

impl Firmware {
    pub fn name(self) -> &'static str {
        match self {
            Firmware::Native => "native",
            Firmware::Qemu => "qemu",
        }
    }
}

/// Who runs the base station.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BaseSide {
    /// The real base station code, in the world, on the simulated clock.
    Simulated,
    /// Another process (`basestation run`): its bytes come in through
    /// [`World::base_transmit`], what reaches it leaves through [`World::take_base_inbox`].
    External,
}

/// How robots learn where they are.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FixPath {
    /// Each robot's own receiver hands its fixes to its controller.
    Onboard,
    /// Fixes are published (taken with [`World::take_published_fixes`]) for the base
    /// station to forward over the radio, as a site's localization system would.
    Published,
}

#[derive(Debug, Clone)]
pub struct SimOptions {
    pub seed: u64,
    pub firmware: Firmware,
    pub realtime: bool,
    pub base: BaseSide,
    pub fixes: FixPath,
    /// The fleet's key; the seed's simulation key when absent.
    pub key: Option<std::sync::Arc<MasterKey>>,
    /// Keep running this long after the goal is reached (followers settle), s.
    pub settle_s: f64,
    /// A firmware brain that takes longer than this (wall clock) for a step has hung.
    pub step_timeout: std::time::Duration,
    /// How the simulated base station treats what moves (a baseline, or its manners).
    pub movers: MoverPolicy,
}

impl SimOptions {
    pub fn new(seed: u64) -> Self {
        Self {
            seed,
            firmware: Firmware::Native,
            realtime: false,
            base: BaseSide::Simulated,
            fixes: FixPath::Onboard,
            key: None,
            settle_s: 5.0,
            step_timeout: crate::qemu::STEP_TIMEOUT,
            movers: MoverPolicy::Heed,
        }
    }
}

impl SimOptions {
    /// The fleet key the robots (and a simulated base station) hold.
    pub fn fleet_key(&self) -> std::sync::Arc<MasterKey> {
        self.key
            .clone()
            .unwrap_or_else(|| std::sync::Arc::new(sim_key(self.seed)))
    }
}

/// The simulated station's configuration: the scenario's, treating movers as asked.
fn station_config(scenario: &Scenario, options: &SimOptions) -> StationConfig {
    StationConfig {
        movers: options.movers,
        ..StationConfig::from_scenario(scenario)
    }
}

/// The simulation's fleet key: derived from the seed. Simulation only; real runs take
/// the key from a file.
pub fn sim_key_bytes(seed: u64) -> [u8; 32] {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed_f1ee_7000_0001);
    let mut key = [0u8; 32];
    rng.fill(&mut key);
    key
}

/// The simulated world's wall clock at t = 0, ms since the Unix epoch (1 January 2026:
/// any fixed instant will do, so that a run depends on nothing but its seed).
const SIM_EPOCH_MS: u64 = 1_767_225_600_000;

/// The simulated fleet's master key, from the seed.
pub fn sim_key(seed: u64) -> MasterKey {
    MasterKey::from_bytes(&sim_key_bytes(seed))
}

/// What a robot's noise source gives at one boot: from the seed, the id and the boot.
fn boot_entropy(seed: u64, id: u16, boot_count: u32) -> u32 {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ (id as u64) << 32 ^ boot_count as u64);
    rng.random()
}

/// A robot's controller at boot: native, or its firmware in a fresh QEMU.
fn boot_brain(
    options: &SimOptions,
    elf: &std::path::Path,
    cfg: RobotConfig,
    id: u16,
    role: Role,
    boot_count: u32,
) -> Result<Box<dyn Brain>, BrainError> {
    let entropy = boot_entropy(options.seed, id, boot_count);
    let key = options.fleet_key();
    Ok(match options.firmware {
        Firmware::Native => {
            let identity = Identity {
                id,
                role: match role {
                    Role::Leader => config::Role::Leader,
                    Role::Follower => config::Role::Follower,
                },
                boot_count,
                entropy,
            };
            Box::new(NativeBrain::new(identity, &key, cfg))
        }
        Firmware::Qemu => Box::new(crate::qemu::QemuBrain::spawn(
            elf,
            BodyConfig {
                id,
                leader: role == Role::Leader,
                boot_count,
                entropy,
                broadcast_key: key.broadcast_bytes(),
                robot_key: key.robot_bytes(id),
            },
            options.step_timeout,
        )?),
    })
}

pub struct SimRobot {
    pub id: u16,
    pub role: Role,
    pub body: Body,
    pub brain: Box<dyn Brain>,
    /// This robot's control ticks happen at `phase_us` past each 100 ms.
    phase_us: u64,
    duty: MotorOutput,
    fixes: VecDeque<(u64, PoseFixSample)>,
    /// Radio bytes that arrived since this robot's last step.
    inbox: Vec<u8>,
    pub boot_count: u32,
}

impl Tracked for SimRobot {
    fn id(&self) -> u16 {
        self.id
    }
    fn role(&self) -> Role {
        self.role
    }
    fn body(&self) -> &Body {
        &self.body
    }
}

pub struct World {
    /// The points the leader drives to, in order (the sweep's, then the route's).
    route_points: Vec<DVec2>,
    pub scenario: Scenario,
    pub map: Map,
    pub station: BaseStation,
    pub radio: Radio,
    /// The leader state's age at each robot it reached.
    pub leader_state_ages: LeaderStateAges,
    pub robots: Vec<SimRobot>,
    node_of: HashMap<u16, NodeId>,
    loc_rng: ChaCha8Rng,
    pub recorder: Recorder,
    /// What each node put on the air, as sent: (µs, node: 0 the base station, 1.. the
    /// robots, then the attacker, bytes). For the recording's radio channel.
    pub transmitted: Vec<(u64, NodeId, Vec<u8>)>,
    pub options: SimOptions,
    pub t_us: u64,
    goal_at_us: Option<u64>,
    /// Asked to end early (`sim --realtime` interrupted): the run ends after this step.
    pub stop_requested: bool,
    injector: Injector,
    radio_params: RadioParams,
    scanner: Scanner,
    /// When the current base station started (a restart begins a new clock).
    base_epoch_us: u64,
    robot_cfg: RobotConfig,
    elf: std::path::PathBuf,
    /// The base station when it is another process; `None`: `station` runs here.
    pub external: Option<External>,
    /// People, cyclists and vehicles on the site.
    pub movers: Movers,
    /// Where they are now (after the last step): what the sensors and the recorder see.
    pub mover_states: Vec<MoverState>,
    /// Each route the station planned, when it was first seen (µs): for the recording.
    pub routes: Vec<(u64, Vec<DVec2>)>,
    /// Each robot's link health as the station saw it, once a second (µs): for the recording.
    pub links: Vec<(u64, Vec<(u16, base_station::recording::LinkHealth)>)>,
    /// The station's sensed marks, once a second where they changed (µs): for the
    /// recording.
    pub sensed: Vec<(u64, Vec<Obstacle>)>,
}

const PERIOD_US: u64 = 100_000;

/// What the world keeps for a base station that is another process (`basestation
/// robots`): what it said, as heard on the air (for the recorder), what reached it and
/// what it is to be sent (fixes, scans), and how far along its route the true leader is
/// (arrival is judged without its planner).
pub struct External {
    pub observer: AirObserver,
    /// Bytes that reached it, not yet taken.
    inbox: Vec<u8>,
    /// Published fixes not yet taken: (robot, fix stamped with the world's clock, ms).
    fixes: Vec<(u16, PoseFixSample)>,
    /// The leader's latest scan (hits on what the map does not hold), not yet taken.
    scan: Vec<DVec2>,
    /// The next route point the true leader has to pass.
    next_route_point: usize,
}

impl World {
    pub fn new(scenario: Scenario, options: SimOptions) -> Result<Self, BrainError> {
        // The draws from the seed in a fixed order: the station's session and nonce, the
        // radio's seed, each robot's phase, the localization's seed.
        let mut master = ChaCha8Rng::seed_from_u64(options.seed);
        let key = options.fleet_key();
        let station = BaseStation::new(
            station_config(&scenario, &options),
            &key,
            master.random(),
            nonce_base(SIM_EPOCH_MS, master.random()),
        );
        let radio = Self::radio_of(&scenario, &mut master);
        let cfg = scenario.robot_config();
        if options.firmware == Firmware::Qemu && cfg != RobotConfig::DEFAULT {
            return Err(BrainError(
                "--firmware qemu: the firmware image carries the default robot parameters; \
                 this scenario changes [robot] or [follower] values"
                    .into(),
            ));
        }
        let elf = crate::qemu::firmware_elf();
        let (robots, node_of) = Self::robots_of(&scenario, &options, &elf, cfg, &mut master)?;
        let map = scenario.build_site();
        let movers = Movers::new(&scenario, &map, options.seed);
        let mover_states = movers.states(0.0).collect();
        let scanner = Scanner::new(&scenario);
        let mut recorder = Recorder::new(&scenario);
        recorder.sweeping = crate::swept::Sweeping::new(&scenario, &map);
        let route_points = scenario.route_points();
        let radio_params = *radio.params();
        let injector = Injector::new(scenario.faults.clone(), options.seed);
        Ok(Self {
            route_points,
            injector,
            radio_params,
            scanner,
            base_epoch_us: 0,
            robot_cfg: cfg,
            elf,
            loc_rng: ChaCha8Rng::seed_from_u64(master.random()),
            external: (options.base == BaseSide::External).then(|| External {
                observer: AirObserver::new(scenario.formation_spec().transition_duration()),
                inbox: Vec::new(),
                fixes: Vec::new(),
                scan: Vec::new(),
                next_route_point: 0,
            }),
            routes: Vec::new(),
            links: Vec::new(),
            sensed: Vec::new(),
            movers,
            mover_states,
            map,
            station,
            leader_state_ages: LeaderStateAges::new(robots.len()),
            radio,
            robots,
            node_of,
            recorder,
            transmitted: Vec::new(),
            scenario,
            options,
            t_us: 0,
            goal_at_us: None,
            stop_requested: false,
        })
    }

    /// The simulated radio with the scenario's `[link]`, seeded from `master`: air of its
    /// own for each transmitter, or one shared channel (robot `i` is node `i + 1`).
    fn radio_of(scenario: &Scenario, master: &mut ChaCha8Rng) -> Radio {
        let l = &scenario.link;
        let params = RadioParams {
            latency_s: l.latency_ms / 1000.0,
            jitter_s: l.jitter_ms / 1000.0,
            loss: l.loss,
            byte_corruption: l.byte_corruption,
            baud: l.baud,
            reorder_s: 0.0,
            duplicate: false,
        };
        let rng = ChaCha8Rng::seed_from_u64(master.random());
        match l.channel().expect("validated") {
            None => Radio::new(params, rng),
            Some(channel) => {
                let n = scenario.robots.len();
                let step_us = u64::from(scenario.sim.physics_step_ms) * 1000;
                let leader = base_station::air::leader_node(scenario);
                let medium = Medium::new(channel, n, leader, step_us, master.random());
                Radio::shared(params, medium, rng)
            }
        }
    }

    /// The scenario's robots at their starts, each booted, its control phase drawn from
    /// `master`; and each robot's radio node.
    fn robots_of(
        scenario: &Scenario,
        options: &SimOptions,
        elf: &std::path::Path,
        cfg: RobotConfig,
        master: &mut ChaCha8Rng,
    ) -> Result<(Vec<SimRobot>, HashMap<u16, NodeId>), BrainError> {
        let r = &scenario.robot;
        let params = BodyParams {
            footprint: r.footprint_radius,
            track_width: r.track_width,
            wheel_radius: r.wheel_radius,
            ticks_per_rev: r.ticks_per_rev,
            tau: r.motor_time_constant_s,
            no_load_speed: r.motor_no_load_speed,
            dead_band: r.motor_dead_band,
        };
        let mut node_of = HashMap::new();
        let robots = scenario
            .robots
            .iter()
            .enumerate()
            .map(|(i, e)| -> Result<SimRobot, BrainError> {
                node_of.insert(e.id, i + 1);
                let mut body = Body::new(
                    params,
                    e.start.x,
                    e.start.y,
                    e.start.heading_deg.to_radians(),
                );
                body.wheel = [e.initial_speed; 2];
                let brain = boot_brain(options, elf, cfg, e.id, e.role, 1)?;
                Ok(SimRobot {
                    id: e.id,
                    role: e.role,
                    body,
                    brain,
                    // Robots are not synchronised: spread their ticks over the period.
                    phase_us: (master.random_range(0..100) * 1000) as u64,
                    duty: MotorOutput::default(),
                    fixes: VecDeque::new(),
                    inbox: Vec::new(),
                    boot_count: 1,
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok((robots, node_of))
    }

    /// The addressed receivers of a frame (unparseable: everyone, who will reject it).
    fn route(node_of: &HashMap<u16, NodeId>, robots: usize, frame: &[u8]) -> Vec<NodeId> {
        let mut copy = frame.to_vec();
        let body = copy
            .strip_suffix(&[0])
            .map(<[u8]>::len)
            .unwrap_or(copy.len());
        let header = cobs::decode_in_place(&mut copy[..body])
            .ok()
            .and_then(|n| frame::peek_header(&copy[..n]).ok());
        match header.map(|h| h.to) {
            Some(Address::Base) => vec![0],
            Some(Address::Robot(id)) => node_of.get(&id).copied().into_iter().collect(),
            _ => (0..=robots).collect(),
        }
    }

    fn transmit(&mut self, from: NodeId, bytes: &[u8]) {
        if bytes.is_empty() {
            return;
        }
        let t_s = self.t_us as f64 / 1e6;
        let on_air = self.injector.overheard(from, self.t_us, bytes);
        let bytes = &on_air[..];
        if !bytes.is_empty() {
            self.transmitted.push((self.t_us, from, bytes.to_vec()));
            if let Some(external) = &mut self.external {
                external.observer.overhear(from, bytes, t_s);
            }
        }
        let silenced = self.injector.silenced(from, t_s);
        let params = *self.radio.params();
        if silenced {
            self.radio.set_params(RadioParams {
                loss: 1.0,
                ..params
            });
        }
        let node_of = &self.node_of;
        let n = self.robots.len();
        self.radio
            .transmit(from, bytes, self.t_us, |f| Self::route(node_of, n, f));
        self.radio.set_params(params);
    }

    /// Applies the faults due at the current time.
    fn inject(&mut self, step_us: u64) -> Result<(), BrainError> {
        let t_s = self.t_us as f64 / 1e6;
        let params = self.injector.radio(self.radio_params, t_s);
        self.radio.set_params(params);
        for r in &mut self.robots {
            r.body.faults = self.injector.body(r.id, t_s);
        }
        for action in self.injector.due(t_s) {
            match action {
                Action::Reboot(id) => self.reboot(id)?,
                Action::RestartBase => {
                    tracing::info!("fault: the base station restarts");
                    let mut rng = ChaCha8Rng::seed_from_u64(self.options.seed ^ self.t_us);
                    self.station = BaseStation::new(
                        station_config(&self.scenario, &self.options),
                        &self.options.fleet_key(),
                        rng.random(),
                        nonce_base(SIM_EPOCH_MS + self.t_us / 1000, rng.random()),
                    );
                    // Its clock starts again at 0 too.
                    self.base_epoch_us = self.t_us;
                }
                Action::KillLeader => {
                    if let Some(r) = self.robots.iter_mut().find(|r| r.role == Role::Leader) {
                        tracing::info!("fault: the leader's controller dies");
                        r.brain = Box::new(DeadBrain);
                    }
                }
            }
        }
        let mut attack = self.injector.attack(self.t_us, step_us as f64 / 1e6);
        let (options, station, base_ms) = (&self.options, &self.station, self.base_ms());
        attack.extend(self.injector.captured(self.t_us, step_us as f64 / 1e6, || {
            let link = station.link();
            let heard = Heard {
                session: link.session(),
                broadcast_seq: link.broadcast_seq(),
                base_ms,
            };
            (options.fleet_key().broadcast(), heard)
        }));
        if !attack.is_empty() {
            let attacker = self.robots.len() + 1;
            self.transmit(attacker, &attack);
        }
        Ok(())
    }

    /// Robot `id` reboots: a fresh brain with the next boot count and its clock from zero
    /// (its first control period 100 ms from now); the body rolls on.
    fn reboot(&mut self, id: u16) -> Result<(), BrainError> {
        let now = self.t_us;
        let Some(r) = self.robots.iter_mut().find(|r| r.id == id) else {
            return Ok(());
        };
        r.boot_count += 1;
        r.phase_us = now;
        // Fixes stamped before the boot: a booting robot is not listening.
        r.fixes.clear();
        tracing::info!(robot = id, boot = r.boot_count, "fault: reboot");
        r.brain = boot_brain(
            &self.options,
            &self.elf,
            self.robot_cfg,
            id,
            r.role,
            r.boot_count,
        )?;
        r.duty = MotorOutput::default();
        r.inbox.clear();
        Ok(())
    }

    /// Runs to the goal (plus settling) or the scenario's duration.
    pub fn run(&mut self) -> Result<(), BrainError> {
        self.run_with(|_| {})
    }

    /// [`World::run`], calling `each_step` after every physics step (progress, a live
    /// console's view and commands).
    pub fn run_with(&mut self, mut each_step: impl FnMut(&mut World)) -> Result<(), BrainError> {
        let end_us = (self.scenario.sim.duration_s * 1e6) as u64;
        let step_us = self.scenario.sim.physics_step_ms as u64 * 1000;
        let wall = Instant::now();
        while self.t_us < end_us {
            self.step(step_us)?;
            each_step(self);
            if self.stop_requested {
                break;
            }
            if let Some(goal) = self.goal_at_us {
                if self.t_us >= goal + (self.options.settle_s * 1e6) as u64 {
                    break;
                }
            }
            if self.options.realtime {
                let ahead = Duration::from_micros(self.t_us).saturating_sub(wall.elapsed());
                std::thread::sleep(ahead);
            }
        }
        Ok(())
    }

    /// One physics step of `step_us`, in its phases: faults and attacks, the radio's
    /// arrivals, localization, the leader's scan and the base station, the robots'
    /// control, the bodies, and what the recorder sees.
    pub fn step(&mut self, step_us: u64) -> Result<(), BrainError> {
        self.inject(step_us)?;
        self.deliver_arrivals();
        self.localize(step_us);
        if self.t_us.is_multiple_of(PERIOD_US) {
            self.scan_and_station();
        }
        self.control(step_us)?;
        self.move_bodies(step_us);
        self.move_movers(step_us);
        self.observe();
        Ok(())
    }

    /// The movers walk (or drive) on, around the robots where they are social.
    fn move_movers(&mut self, step_us: u64) {
        if self.movers.is_empty() {
            return;
        }
        let robots: Vec<RobotBody> = self
            .robots
            .iter()
            .map(|r| {
                let (v, _) = r.body.twist();
                RobotBody {
                    position: DVec2::new(r.body.x, r.body.y),
                    velocity: DVec2::from_angle(r.body.heading) * v,
                    radius: r.body.params.footprint,
                }
            })
            .collect();
        let t_s = self.t_us as f64 / 1e6;
        self.movers
            .step(t_s, step_us as f64 / 1e6, &robots, &self.map);
        self.mover_states = self.movers.states(t_s).collect();
    }

    /// Radio arrivals: the base station takes its bytes at once; each robot gets its own
    /// at its next step (this one, if it is booted).
    fn deliver_arrivals(&mut self) {
        let base_ms = self.base_ms();
        for a in self.radio.arrivals(self.t_us) {
            self.leader_state_ages.note(&a, self.t_us);
            match (a.to, &mut self.external) {
                (0, Some(external)) => external.inbox.extend_from_slice(&a.bytes),
                (0, None) => self.station.receive(&a.bytes, base_ms),
                (to, _) => self.robots[to - 1].inbox.extend_from_slice(&a.bytes),
            }
        }
    }

    /// Localization: a fix of every robot each period, delivered after its latency (to the
    /// robot's own receiver, or published for an external station to forward).
    fn localize(&mut self, step_us: u64) {
        let t = self.t_us;
        let loc = &self.scenario.localization;
        let fix_every = (1e6 / loc.rate_hz) as u64;
        if t % fix_every >= step_us {
            return;
        }
        let pos = Normal::new(0.0, loc.sigma_m.max(1e-12)).expect("σ ≥ 0");
        let head = Normal::new(0.0, loc.heading_sigma_deg.to_radians().max(1e-12)).expect("σ ≥ 0");
        let arrive = t + (loc.latency_ms * 1000.0) as u64;
        let t_s = t as f64 / 1e6;
        let now_ms = (t / 1000) as u32;
        for r in &mut self.robots {
            let jump = self.injector.fix_offset(r.id, t_s);
            let sample = PoseFixSample {
                pose: Pose::new(
                    (r.body.x + jump + pos.sample(&mut self.loc_rng)) as f32,
                    (r.body.y + pos.sample(&mut self.loc_rng)) as f32,
                    (r.body.heading + head.sample(&mut self.loc_rng)) as f32,
                ),
                sigma: loc.sigma_m as f32,
                time_ms: now_ms,
            };
            match (self.options.fixes, &mut self.external) {
                (FixPath::Onboard, _) => r.fixes.push_back((arrive, sample)),
                (FixPath::Published, Some(external)) => external.fixes.push((r.id, sample)),
                (FixPath::Published, None) => {}
            }
        }
    }

    /// At 10 Hz the leader scans: for the external station to take, or into ours, which
    /// then steps and transmits.
    fn scan_and_station(&mut self) {
        let (t, base_ms) = (self.t_us, self.base_ms());
        let hits = self
            .leader_position()
            .map(|at| self.scanner.scan(at, &self.map, &self.mover_states))
            .unwrap_or_default();
        if let Some(external) = &mut self.external {
            external.scan = hits;
            return;
        }
        if !hits.is_empty() {
            self.station.sense(&hits, base_ms);
        }
        self.station.step(base_ms);
        let out = self.station.take_outbox();
        self.transmit(0, &out);
        if let Some(route) = self.station.route() {
            if self.routes.last().is_none_or(|(_, r)| *r != route.points) {
                self.routes.push((t, route.points.clone()));
            }
        }
        if t.is_multiple_of(1_000_000) {
            self.links.push((
                t,
                base_station::recording::link_health(&self.station, base_ms),
            ));
            self.note_sensed(t);
        }
    }

    /// The station's sensed marks at `t`, if they changed since the last ones noted.
    fn note_sensed(&mut self, t: u64) {
        let marks = self.station.perception().in_order();
        if self
            .sensed
            .last()
            .map_or(!marks.is_empty(), |(_, m)| *m != marks)
        {
            self.sensed.push((t, marks));
        }
    }

    /// Robots: each boots at its phase and runs a control period every 100 ms of its own
    /// clock after that. The radio bytes that reached it are handed over in the physics
    /// step they arrive in (a step without sensors between periods), as the firmware's
    /// radio task takes them as they come (handed over at the next period, a handshake
    /// answered just after one would measure its round trip a period too long, and the
    /// robot's clock offset would come out up to half a period off what it is behind a
    /// real transport).
    fn control(&mut self, step_us: u64) -> Result<(), BrainError> {
        let t = self.t_us;
        let due: Vec<bool> = self
            .robots
            .iter()
            .map(|r| t >= r.phase_us + PERIOD_US && (t - r.phase_us) % PERIOD_US < step_us)
            .collect();
        let hearing: Vec<bool> = self
            .robots
            .iter()
            .map(|r| t >= r.phase_us && !r.inbox.is_empty())
            .collect();
        let neighbours = due.iter().any(|d| *d).then(|| {
            ring::Neighbours::new(
                self.robots
                    .iter()
                    .map(|r| DVec2::new(r.body.x, r.body.y))
                    .collect(),
            )
        });
        let mut stepping = Vec::new();
        for i in (0..self.robots.len()).filter(|i| due[*i] || hearing[*i]) {
            let sensors = due[i].then(|| {
                let neighbours = neighbours.as_ref().expect("built when due");
                self.sensors(i, neighbours)
            });
            let r = &mut self.robots[i];
            let inbox = std::mem::take(&mut r.inbox);
            r.brain
                .step_start(t - r.phase_us, &inbox, sensors.as_ref())?;
            stepping.push(i);
        }
        for i in stepping {
            let mut tx = Vec::new();
            if let Some(out) = self.robots[i].brain.step_finish(&mut tx)? {
                self.robots[i].duty = out;
            }
            self.transmit(i + 1, &tx);
        }
        Ok(())
    }

    /// What robot `i`'s board reads this period: encoders, the newest fix that has
    /// arrived, the ring.
    fn sensors(&mut self, i: usize, neighbours: &ring::Neighbours) -> Sensors {
        let t = self.t_us;
        let body = &self.robots[i].body;
        let proximity = ring::sense(
            i,
            body.heading,
            body.params.footprint,
            &self.map,
            neighbours,
            &self.mover_states,
        );
        let r = &mut self.robots[i];
        let mut newest = None;
        while r.fixes.front().is_some_and(|(at, _)| *at <= t) {
            newest = r.fixes.pop_front().map(|f| f.1);
        }
        let phase_ms = (r.phase_us / 1000) as u32;
        Sensors {
            ticks: r.body.ticks(),
            pose_fix: newest.map(|f| PoseFixSample {
                time_ms: f.time_ms.wrapping_sub(phase_ms),
                ..f
            }),
            proximity,
        }
    }

    /// The bodies move under their motors' duties.
    fn move_bodies(&mut self, step_us: u64) {
        let dt = step_us as f64 / 1e6;
        for r in &mut self.robots {
            r.body.step(&r.duty, dt);
        }
        self.t_us += step_us;
    }

    /// Whether the goal is reached, and what the recorder sees now.
    fn observe(&mut self) {
        if self.goal_at_us.is_none() && self.arrived() {
            self.goal_at_us = Some(self.t_us);
        }
        let station = StationView {
            station: &self.station,
            epoch_us: self.base_epoch_us,
        };
        let view: &dyn FleetView = match &self.external {
            Some(external) => &external.observer,
            None => &station,
        };
        self.recorder
            .observe(self.t_us, &self.robots, &self.map, &self.mover_states, view);
    }

    /// Whether the leader has arrived: the station's planner says so, or, with an
    /// external station, the true leader has passed every route point in order.
    fn arrived(&mut self) -> bool {
        let Some(at) = self.leader_position() else {
            return self.external.is_none() && self.station.arrived();
        };
        let Some(external) = &mut self.external else {
            return self.station.arrived();
        };
        let route = &self.route_points;
        while let Some(p) = route.get(external.next_route_point) {
            let last = external.next_route_point + 1 == route.len();
            let tol = if last {
                self.scenario.route.arrival_tolerance
            } else {
                self.scenario.route.waypoint_tolerance
            };
            if (*p - at).length() > tol {
                break;
            }
            external.next_route_point += 1;
        }
        !route.is_empty() && external.next_route_point == route.len()
    }

    /// An external base station's bytes, put on the air now.
    pub fn base_transmit(&mut self, bytes: &[u8]) {
        self.transmit(0, bytes);
    }

    /// What reached an external base station over the air since the last call.
    pub fn take_base_inbox(&mut self) -> Vec<u8> {
        self.external
            .as_mut()
            .map(|e| std::mem::take(&mut e.inbox))
            .unwrap_or_default()
    }

    /// The leader's latest scan (site frame), once; empty when it saw nothing unmapped.
    pub fn take_scan(&mut self) -> Vec<DVec2> {
        self.external
            .as_mut()
            .map(|e| std::mem::take(&mut e.scan))
            .unwrap_or_default()
    }

    /// Fixes published since the last call: (robot, fix stamped with the world's clock).
    pub fn take_published_fixes(&mut self) -> Vec<(u16, PoseFixSample)> {
        self.external
            .as_mut()
            .map(|e| std::mem::take(&mut e.fixes))
            .unwrap_or_default()
    }

    /// The current base station's clock now, ms.
    pub fn base_ms(&self) -> u32 {
        ((self.t_us - self.base_epoch_us) / 1000) as u32
    }

    /// When the current base station started, s of simulated time.
    pub fn base_epoch_s(&self) -> f64 {
        self.base_epoch_us as f64 / 1e6
    }

    pub fn goal_time_s(&self) -> Option<f64> {
        self.goal_at_us.map(|t| t as f64 / 1e6)
    }

    pub fn leader_position(&self) -> Option<DVec2> {
        self.robots
            .iter()
            .find(|r| r.role == Role::Leader)
            .map(|r| DVec2::new(r.body.x, r.body.y))
    }
}
