//! Fault and attack injection: the scenario's `[[faults]]`, applied by the world as the
//! simulated time reaches them. Radio faults change the radio; robot faults change a body
//! or a brain; attackers are an extra transmitter on the same radio.

use std::borrow::Cow;
use std::collections::VecDeque;

use base_station::scenario::{FaultKind, FaultSpec};
use control_core::controller::{MotorOutput, Sensors};
use protocol::link::{Link, Timing};
use protocol::messages::{
    Detour, Hello, LeaderState, Message, PoseFix, RobotMode, VelocityCommand, Welcome, WirePose,
    WireTwist,
};
use protocol::{Address, FleetKey, FrameDecoder, RejectCounts, MAX_WIRE};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::brain::{Brain, BrainError};
use crate::radio::RadioParams;

/// Message ids of the handshake (the attackers pick these frames by header alone).
fn is_hello(id: u8) -> bool {
    id == Message::Hello(Hello { nonce: 0 }).id()
}

fn is_welcome(id: u8) -> bool {
    id == Message::Welcome(Welcome {
        nonce: 0,
        session: 0,
        broadcast_seq: 0,
    })
    .id()
}

/// What a captured robot hears of the base station: its session, the number of its last
/// broadcast and its clock now.
pub struct Heard {
    pub session: u32,
    pub broadcast_seq: u32,
    pub base_ms: u32,
}

/// The header of one wire frame (COBS, with its delimiter), if it parses.
fn decoded_header(wire: &[u8]) -> Option<protocol::frame::WireHeader> {
    let mut decoder = FrameDecoder::new();
    for b in wire {
        if let Some(raw) = decoder.push(*b) {
            return raw
                .ok()
                .and_then(|raw| protocol::frame::peek_header(raw).ok());
        }
    }
    None
}

/// Moves the frames of `queue` (time recorded, bytes) that are `delay_s` old by `t_us`
/// into `out`, oldest first.
fn release(queue: &mut VecDeque<(u64, Vec<u8>)>, delay_s: f64, t_us: u64, out: &mut Vec<u8>) {
    let delay_us = (delay_s * 1e6) as u64;
    while let Some((_, frame)) = queue.pop_front_if(|(at, _)| *at + delay_us <= t_us) {
        out.extend_from_slice(&frame);
    }
}

/// A controller that died: no frames, motors off.
pub struct DeadBrain;

impl Brain for DeadBrain {
    fn step_start(&mut self, _: u64, _: &[u8], _: Option<&Sensors>) -> Result<(), BrainError> {
        Ok(())
    }
    fn step_finish(&mut self, _: &mut Vec<u8>) -> Result<Option<MotorOutput>, BrainError> {
        Ok(Some(MotorOutput::default()))
    }
    fn mode(&self) -> RobotMode {
        RobotMode::Idle
    }
    fn rejects(&self) -> RejectCounts {
        RejectCounts::default()
    }
}

/// What the world must do for a one-shot fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Action {
    Reboot(u16),
    KillLeader,
    RestartBase,
}

pub struct Injector {
    faults: Vec<FaultSpec>,
    fired: Vec<bool>,
    rng: ChaCha8Rng,
    rogue: Link<1>,
    recorded: VecDeque<(u64, Vec<u8>)>,
    /// The newest `Hello` heard from each robot, for the hello replayer.
    hellos: Vec<(Address, Vec<u8>)>,
    next_hello: usize,
    /// `Welcome` frames jammed at the robot, to deliver later.
    held: VecDeque<(u64, Vec<u8>)>,
    owed_garbage: f64,
    owed_forgeries: f64,
    owed_hellos: f64,
    owed_captured: f64,
    /// The captured robot's forgeries so far (their sequence numbers).
    captured_sent: u32,
}

impl Injector {
    pub fn new(faults: Vec<FaultSpec>, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xa77a_c4e5);
        let mut wrong = [0u8; 32];
        rng.fill(&mut wrong);
        // The rogue pretends to be the base station, with a key of its own.
        let rogue = Link::new(
            Address::Base,
            FleetKey::from_bytes(&wrong),
            rng.random(),
            rng.random(),
            Timing::default(),
        );
        Self {
            fired: vec![false; faults.len()],
            faults,
            rng,
            rogue,
            recorded: VecDeque::new(),
            hellos: Vec::new(),
            next_hello: 0,
            held: VecDeque::new(),
            owed_garbage: 0.0,
            owed_forgeries: 0.0,
            owed_hellos: 0.0,
            owed_captured: 0.0,
            captured_sent: 0,
        }
    }

    fn active(&self, kind: FaultKind, t_s: f64) -> Option<&FaultSpec> {
        self.faults.iter().find(|f| f.kind == kind && f.active(t_s))
    }

    /// The radio's parameters at `t_s`, from the scenario's own.
    pub fn radio(&self, base: RadioParams, t_s: f64) -> RadioParams {
        let mut p = base;
        if self.active(FaultKind::LossBurst, t_s).is_some() {
            p.loss = 1.0;
        }
        if let Some(f) = self.active(FaultKind::LatencySpike, t_s) {
            p.latency_s = f.value.unwrap_or(0.0) / 1000.0;
        }
        if let Some(f) = self.active(FaultKind::Reorder, t_s) {
            p.reorder_s = f.value.unwrap_or(0.0) / 1000.0;
        }
        if self.active(FaultKind::Duplicate, t_s).is_some() {
            p.duplicate = true;
        }
        if let Some(f) = self.active(FaultKind::Corruption, t_s) {
            p.byte_corruption = f.value.unwrap_or(0.0);
        }
        if let Some(f) = self.active(FaultKind::DelayRelay, t_s) {
            p.latency_s += f.value.unwrap_or(0.0);
        }
        p
    }

    /// The body faults of robot `id` at `t_s`.
    pub fn body(&self, id: u16, t_s: f64) -> crate::plant::BodyFaults {
        let on = |kind| {
            self.faults
                .iter()
                .find(|f| f.kind == kind && f.robot == Some(id) && f.active(t_s))
        };
        crate::plant::BodyFaults {
            stuck: [on(FaultKind::StuckWheel).is_some(), false],
            torque: [
                on(FaultKind::WeakMotor)
                    .and_then(|f| f.value)
                    .unwrap_or(1.0),
                1.0,
            ],
            encoder_dead: [on(FaultKind::EncoderDead).is_some(), false],
        }
    }

    /// How far robot `id`'s pose fixes are off in x at `t_s`, m.
    pub fn fix_offset(&self, id: u16, t_s: f64) -> f64 {
        self.faults
            .iter()
            .filter(|f| f.kind == FaultKind::PoseJump && f.robot == Some(id) && f.active(t_s))
            .filter_map(|f| f.value)
            .sum()
    }

    /// Whether frames from `from` (0: the base station) are lost at `t_s`.
    pub fn silenced(&self, from: usize, t_s: f64) -> bool {
        let kind = if from == 0 {
            FaultKind::SilentDownlink
        } else {
            FaultKind::SilentUplink
        };
        self.active(kind, t_s).is_some()
    }

    /// One-shot faults due by `t_s`.
    pub fn due(&mut self, t_s: f64) -> Vec<Action> {
        let mut out = Vec::new();
        for (f, fired) in self.faults.iter().zip(self.fired.iter_mut()) {
            if *fired || t_s < f.at_s {
                continue;
            }
            match f.kind {
                FaultKind::Reboot => {
                    *fired = true;
                    out.push(Action::Reboot(f.robot.unwrap_or(0)));
                }
                FaultKind::LeaderDies => {
                    *fired = true;
                    out.push(Action::KillLeader);
                }
                FaultKind::BaseRestart => {
                    *fired = true;
                    out.push(Action::RestartBase);
                }
                _ => {}
            }
        }
        out
    }

    /// Records what a node sent (`from` 0: the base station), for the replayers; returns
    /// what reaches the air (a `Welcome` being held back does not).
    pub fn overheard<'a>(&mut self, from: usize, t_us: u64, bytes: &'a [u8]) -> Cow<'a, [u8]> {
        let t_s = t_us as f64 / 1e6;
        let replaying = from == 0
            && self
                .faults
                .iter()
                .any(|f| f.kind == FaultKind::ReplayAttacker);
        let collecting_hellos =
            from != 0 && self.faults.iter().any(|f| f.kind == FaultKind::HelloReplay);
        let holding = from == 0 && self.active(FaultKind::WelcomeHoldback, t_s).is_some();
        if !(replaying || collecting_hellos || holding) {
            return Cow::Borrowed(bytes);
        }
        let mut on_air = Vec::with_capacity(bytes.len());
        for frame in bytes.split_inclusive(|b| *b == 0) {
            if replaying {
                self.recorded.push_back((t_us, frame.to_vec()));
            }
            let message = (collecting_hellos || holding)
                .then(|| decoded_header(frame))
                .flatten();
            match message {
                Some(h) if collecting_hellos && is_hello(h.id) => {
                    match self.hellos.iter_mut().find(|(a, _)| *a == h.from) {
                        Some(slot) => slot.1 = frame.to_vec(),
                        None => self.hellos.push((h.from, frame.to_vec())),
                    }
                }
                Some(h) if holding && is_welcome(h.id) => {
                    self.held.push_back((t_us, frame.to_vec()));
                    continue;
                }
                _ => {}
            }
            on_air.extend_from_slice(frame);
        }
        Cow::Owned(on_air)
    }

    /// A captured robot's forgeries during one step of `step_s` ending at `t_us`: sealed
    /// with the genuine broadcast key, in the base station's session (it is public, in
    /// every `Welcome`), numbered just above the genuine broadcasts and stamped with the
    /// station's clock, both as the robot hears them.
    /// `link`: the broadcast key and what the robot heard, asked only while the attack runs.
    pub fn captured(
        &mut self,
        t_us: u64,
        step_s: f64,
        link: impl FnOnce() -> (FleetKey, Heard),
    ) -> Vec<u8> {
        let mut out = Vec::new();
        let Some(f) = self.active(FaultKind::CapturedRobot, t_us as f64 / 1e6) else {
            return out;
        };
        let (key, heard) = link();
        self.owed_captured += f.value.unwrap_or(0.0) * step_s;
        let far = WirePose::from_si(30.0, 30.0, 0.0).unwrap_or_default();
        while self.owed_captured >= 1.0 {
            self.owed_captured -= 1.0;
            self.captured_sent += 1;
            let message = match self.captured_sent % 3 {
                0 => Message::VelocityCommand(VelocityCommand {
                    v_mm_s: 1500,
                    omega_mrad_s: 0,
                }),
                1 => Message::Detour(Detour {
                    x_mm: 30_000,
                    y_mm: 30_000,
                }),
                _ => Message::PoseFix(PoseFix {
                    pose: far,
                    sigma_mm: 10,
                }),
            };
            let header = protocol::Header {
                version: protocol::PROTOCOL_VERSION,
                id: message.id(),
                from: Address::Base,
                to: Address::Broadcast,
                seq: heard.broadcast_seq.wrapping_add(1),
                time_ms: heard.base_ms,
            };
            let mut buf = [0u8; MAX_WIRE];
            let session = heard.session;
            if let Ok(n) = protocol::frame::seal(&key, session, &header, &message, &mut buf) {
                out.extend_from_slice(&buf[..n]);
            }
        }
        out
    }

    /// The attacker's transmissions during one step of `step_s` ending at `t_us`.
    pub fn attack(&mut self, t_us: u64, step_s: f64) -> Vec<u8> {
        let t_s = t_us as f64 / 1e6;
        let mut out = Vec::new();
        if let Some(f) = self.active(FaultKind::GarbageFlood, t_s) {
            self.owed_garbage += f.value.unwrap_or(0.0) * step_s;
            while self.owed_garbage >= 1.0 {
                out.push(self.rng.random());
                self.owed_garbage -= 1.0;
            }
            out.push(0);
        }
        if let Some(f) = self.active(FaultKind::WrongKeyAttacker, t_s) {
            self.owed_forgeries += f.value.unwrap_or(0.0) * step_s;
            while self.owed_forgeries >= 1.0 {
                self.owed_forgeries -= 1.0;
                // "Stop where you are, the leader is 5 m to your left": a forged state.
                let forged = Message::LeaderState(LeaderState {
                    pose: WirePose::from_si(
                        self.rng.random_range(-20.0..40.0),
                        self.rng.random_range(-20.0..40.0),
                        0.0,
                    )
                    .unwrap_or_default(),
                    twist: WireTwist::new(1000, 1000),
                    blend: 0,
                });
                let mut buf = [0u8; MAX_WIRE];
                if let Ok(n) =
                    self.rogue
                        .send(Address::Broadcast, (t_us / 1000) as u32, &forged, &mut buf)
                {
                    out.extend_from_slice(&buf[..n]);
                }
            }
        }
        if let Some(f) = self.active(FaultKind::HelloReplay, t_s) {
            self.owed_hellos += f.value.unwrap_or(0.0) * step_s;
            while self.owed_hellos >= 1.0 && !self.hellos.is_empty() {
                self.owed_hellos -= 1.0;
                self.next_hello = (self.next_hello + 1) % self.hellos.len();
                out.extend_from_slice(&self.hellos[self.next_hello].1);
            }
        }
        let delay = |f: &FaultSpec| f.value.unwrap_or(0.0);
        // Held frames go out `value` s late, also after the attack window closed.
        let holdback = self
            .faults
            .iter()
            .find(|f| f.kind == FaultKind::WelcomeHoldback);
        if let Some(d) = holdback.map(delay) {
            release(&mut self.held, d, t_us, &mut out);
        }
        if let Some(d) = self.active(FaultKind::ReplayAttacker, t_s).map(delay) {
            release(&mut self.recorded, d, t_us, &mut out);
        }
        out
    }
}
