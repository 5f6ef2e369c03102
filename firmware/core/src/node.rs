//! The robot's radio node: authenticated frames in, commands to the controller,
//! telemetry out. The firmware's tasks and the native simulator drive the same node:
//! bytes in from the radio UART, one `tick` per control period, bytes out.

use protocol::link::{Event, Link, Timing};
use protocol::messages::{faults, LinkCounters, Message, Telemetry, WirePose};
use protocol::{units, Address, FleetKey, FrameDecoder, Reject, MAX_WIRE};

use crate::config::{RobotConfig, Role};
use crate::controller::{Controller, MotorOutput, Sensors};
use crate::follower::{LeaderSnapshot, Slots};
use crate::odometry::PoseFixSample;
use crate::{math, Pose, Twist};

/// Who this robot is. One firmware image serves all robots; this comes from the
/// configuration (flash page or scenario).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Identity {
    pub id: u16,
    pub role: Role,
    /// Incremented at every boot and kept in flash: the link session and the high half
    /// of the nonces.
    pub boot_count: u32,
    /// Fresh at every boot (noise) and unique to the board (its id): the low half of the
    /// nonces, so a repeated boot count still never repeats a nonce a recorded `Welcome`
    /// answered.
    pub entropy: u32,
}

/// How often a robot re-measures the base station's clock offset.
const RESYNC_EVERY_MS: u32 = 10_000;
/// A handshake slower than this went over a slow shared channel, ms.
const SLOW_RTT_MS: u32 = 300;
/// A follower's reports until told, after a slow handshake: once a second, periods.
const UNTOLD_REPORT_EVERY: u8 = 10;

pub struct RobotNode {
    identity: Identity,
    link: Link<1>,
    decoder: FrameDecoder,
    controller: Controller,
    /// Telemetry every this many periods (the station's `report_every`; 0: not told yet,
    /// see [`RobotNode::report_every`]), and the periods
    /// since the last report.
    report_every: u8,
    unreported: u8,
}

impl RobotNode {
    /// `broadcast_key` and `robot_key`: from the configuration page (see
    /// `protocol::auth`).
    pub fn new(
        identity: Identity,
        broadcast_key: FleetKey,
        robot_key: FleetKey,
        config: RobotConfig,
    ) -> Self {
        // Below 2³¹ in the low half: the counter never carries into the boot count.
        let nonce_base = (identity.boot_count as u64) << 32 | (identity.entropy >> 1) as u64;
        let timing = Timing {
            resync_every_ms: Some(RESYNC_EVERY_MS),
            ..Timing::default()
        };
        // Differs at every boot (the count), and with a repeated count still (the noise).
        let session = identity.entropy ^ identity.boot_count.wrapping_mul(0x9E37_79B9);
        let mut link = Link::new(
            Address::Robot(identity.id),
            broadcast_key,
            session,
            nonce_base,
            timing,
        );
        link.add_peer(Address::Base, robot_key);
        Self {
            identity,
            link,
            decoder: FrameDecoder::new(),
            controller: Controller::new(config, identity.role),
            report_every: 0,
            unreported: 0,
        }
    }

    pub fn identity(&self) -> &Identity {
        &self.identity
    }
    pub fn controller(&self) -> &Controller {
        &self.controller
    }
    pub fn link(&self) -> &Link<1> {
        &self.link
    }

    /// Bytes from the radio. Answers handshakes through `tx`.
    pub fn receive(&mut self, bytes: &[u8], now_ms: u32, tx: &mut impl FnMut(&[u8])) {
        for &b in bytes {
            let Some(frame) = self.decoder.push(b) else {
                continue;
            };
            match self.link.receive(frame, now_ms) {
                Ok(Event::Message { header, message }) => {
                    let valid_at = self.local_time(header.time_ms);
                    let sent = self.sent_at(valid_at);
                    if self.is_stale(&message, sent, now_ms) {
                        self.link.count_reject(Reject::Stale);
                        continue;
                    }
                    self.handle(message, valid_at, sent, now_ms);
                }
                Ok(Event::Challenged { from, nonce }) => {
                    let mut buf = [0u8; MAX_WIRE];
                    if let Ok(n) = self.link.answer(from, nonce, now_ms, &mut buf) {
                        tx(&buf[..n]);
                    }
                }
                Ok(Event::Linked { .. } | Event::Synced { .. } | Event::Ignored) | Err(_) => {}
            }
        }
    }

    /// When a message was sent, by the base station's clock converted to ours, at the
    /// latest the offset allows (it is good to half the handshake's round trip): a frame
    /// is as fresh as its sender's stamp, not its arrival, so a relay that delays frames
    /// makes them stale instead of invisible.
    fn sent_at(&self, valid_at: u32) -> u32 {
        let half_rtt = self
            .link
            .peer(Address::Base)
            .and_then(|p| p.rtt_ms)
            .unwrap_or(0)
            / 2;
        valid_at.wrapping_add(half_rtt)
    }

    /// A command already older than its timeout when it arrives (`sent`: see
    /// [`RobotNode::sent_at`]).
    fn is_stale(&self, message: &Message, sent: u32, now_ms: u32) -> bool {
        let timeouts = &self.controller.config().timeouts;
        let timeout = match message {
            Message::LeaderState(_) => timeouts.leader_state_ms,
            Message::VelocityCommand(_) => timeouts.command_ms,
            _ => return false,
        };
        now_ms.wrapping_sub(sent) as i32 > timeout as i32
    }

    /// The base station's clock converted to ours (the handshake measured the offset).
    fn local_time(&self, base_ms: u32) -> u32 {
        let offset = self
            .link
            .peer(Address::Base)
            .and_then(|p| p.clock_offset_ms)
            .unwrap_or(0);
        base_ms.wrapping_sub(offset as u32)
    }

    fn handle(&mut self, message: Message, valid_at: u32, sent: u32, now_ms: u32) {
        let c = &mut self.controller;
        // Malformed values are refused by the controller and flagged in telemetry.
        let _ = match message {
            Message::LeaderState(s) if self.identity.role == Role::Follower => {
                let (x, y, heading) = s.pose.to_si();
                let snapshot = LeaderSnapshot {
                    pose: Pose::new(x, y, heading),
                    v: units::from_milli_i16(s.twist.v_mm_s()),
                    omega: units::from_milli_i16(s.twist.omega_mrad_s()),
                };
                c.set_leader_state(snapshot, valid_at, s.blend as f32 / 255.0, sent)
            }
            Message::VelocityCommand(cmd) if self.identity.role == Role::Leader => {
                let twist = Twist::new(
                    units::from_milli_i16(cmd.v_mm_s),
                    units::from_milli_i16(cmd.omega_mrad_s),
                );
                c.set_command(twist, sent)
            }
            Message::FormationCommand(f) => {
                self.report_every = f.report_every.max(1);
                c.set_slots(Slots {
                    wide: f.wide.to_si(),
                    line: f.line.to_si(),
                })
            }
            Message::Detour(d) if self.identity.role == Role::Follower => c.set_detour(
                (units::mm_to_metres(d.x_mm), units::mm_to_metres(d.y_mm)),
                sent,
            ),
            Message::PoseFix(fix) => {
                let (x, y, heading) = fix.pose.to_si();
                let sample = PoseFixSample {
                    pose: Pose::new(x, y, heading),
                    sigma: units::from_mm_u16(fix.sigma_mm),
                    time_ms: valid_at,
                };
                c.apply_pose_fix(&sample, now_ms);
                Ok(())
            }
            Message::Stop(_) => {
                c.stop();
                Ok(())
            }
            Message::EmergencyStop(_) => {
                c.emergency_stop();
                Ok(())
            }
            Message::Resume(_) => {
                c.resume();
                Ok(())
            }
            _ => Ok(()),
        };
    }

    /// One control period: (re)challenge the base station if due, run the controller,
    /// send telemetry (every `report_every`-th period). Returns the motor duties.
    pub fn tick(
        &mut self,
        now_ms: u32,
        sensors: &Sensors,
        tx: &mut impl FnMut(&[u8]),
    ) -> MotorOutput {
        let mut buf = [0u8; MAX_WIRE];
        if let Some(peer) = self.link.due_challenge(now_ms) {
            if let Ok(n) = self.link.challenge(peer, now_ms, &mut buf) {
                tx(&buf[..n]);
            }
        }
        let out = self.controller.step(now_ms, sensors);
        self.unreported = self.unreported.saturating_add(1);
        if self
            .report_every()
            .is_some_and(|every| self.unreported >= every)
        {
            self.unreported = 0;
            let telemetry = Message::Telemetry(self.telemetry());
            if let Ok(n) = self.link.send(Address::Base, now_ms, &telemetry, &mut buf) {
                tx(&buf[..n]);
            }
        }
        out
    }

    /// Periods between reports, `None` while it holds them. A follower unlinked with a
    /// third challenge out unanswered sends its handshake alone: on a slow shared channel
    /// a report queued ahead of its `Hello` in the modem would stretch the round trip past
    /// the limit (one lost handshake, as on a link of its own, changes nothing).
    /// Until the station says how often, every period (the leader always), or once a
    /// second after a slow handshake: the slowest shared channels' slots carry no more.
    fn report_every(&self) -> Option<u8> {
        let base = self.link.peer(Address::Base)?;
        let follower = self.identity.role == Role::Follower;
        match (base.is_linked(), self.report_every) {
            (false, _) if follower && base.unanswered() > 2 => None,
            (_, 0) if follower && base.rtt_ms.is_some_and(|r| r > SLOW_RTT_MS) => {
                Some(UNTOLD_REPORT_EVERY)
            }
            (_, 0) => Some(1),
            (_, every) => Some(every),
        }
    }

    pub fn telemetry(&self) -> Telemetry {
        let c = &self.controller;
        let pose = c
            .pose()
            .and_then(|p| WirePose::from_si(p.x, p.y, p.heading).ok());
        let w = c.wheel_speeds();
        let stats = self.link.stats();
        let mut fault_flags = c.faults();
        if pose.is_none() {
            fault_flags |= faults::NOT_LOCALIZED;
        }
        if !self.link.peer(Address::Base).is_some_and(|p| p.is_linked()) {
            fault_flags |= faults::NOT_LINKED;
        }
        Telemetry {
            pose: pose.unwrap_or_default(),
            wheel_mm_s: [
                units::to_milli_i16(w.left).unwrap_or(0),
                units::to_milli_i16(w.right).unwrap_or(0),
            ],
            mode: c.mode(),
            tracking_error_mm: c
                .tracking_error()
                .and_then(|e| units::to_mm_u16(math::clamp(e, 0.0, 65.0)).ok())
                .unwrap_or(0),
            faults: fault_flags,
            link: LinkCounters {
                received: stats.accepted,
                rejected: stats.rejects.total(),
                lost: stats.lost,
            },
        }
    }
}
