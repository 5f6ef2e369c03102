//! The robot's radio node: authenticated frames in, commands to the controller,
//! telemetry out. The firmware's tasks and the native simulator drive the same node:
//! bytes in from the radio UART, one `tick` per control period, bytes out.

use protocol::link::{Event, Link, Timing};
use protocol::messages::{faults, LinkCounters, Message, Telemetry, WirePose};
use protocol::{units, Address, FleetKey, FrameDecoder, MAX_WIRE};

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
    /// Incremented at every boot and kept in flash: the link session and nonce base.
    pub boot_count: u32,
}

pub struct RobotNode {
    identity: Identity,
    link: Link<1>,
    decoder: FrameDecoder,
    controller: Controller,
}

impl RobotNode {
    pub fn new(identity: Identity, key: FleetKey, config: RobotConfig) -> Self {
        let mut link = Link::new(
            Address::Robot(identity.id),
            key,
            identity.boot_count,
            (identity.boot_count as u64) << 32,
            Timing::default(),
        );
        link.add_peer(Address::Base);
        Self {
            identity,
            link,
            decoder: FrameDecoder::new(),
            controller: Controller::new(config, identity.role),
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
                    self.handle(message, valid_at, now_ms);
                }
                Ok(Event::Challenged { from, nonce }) => {
                    let mut buf = [0u8; MAX_WIRE];
                    if let Ok(n) = self.link.answer(from, nonce, now_ms, &mut buf) {
                        tx(&buf[..n]);
                    }
                }
                Ok(Event::Linked { .. } | Event::Ignored) | Err(_) => {}
            }
        }
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

    fn handle(&mut self, message: Message, valid_at: u32, now_ms: u32) {
        let c = &mut self.controller;
        // Malformed values are refused by the controller and flagged in telemetry.
        let _ = match message {
            Message::LeaderState(s) if self.identity.role == Role::Follower => {
                let (x, y, heading) = s.pose.to_si();
                let snapshot = LeaderSnapshot {
                    pose: Pose::new(x, y, heading),
                    v: units::from_milli_i16(s.v_mm_s),
                    omega: units::from_milli_i16(s.omega_mrad_s),
                };
                c.set_leader_state(snapshot, valid_at, s.blend as f32 / 255.0, now_ms)
            }
            Message::VelocityCommand(cmd) if self.identity.role == Role::Leader => {
                let twist = Twist::new(
                    units::from_milli_i16(cmd.v_mm_s),
                    units::from_milli_i16(cmd.omega_mrad_s),
                );
                c.set_command(twist, now_ms)
            }
            Message::FormationCommand(f) => c.set_slots(Slots {
                wide: f.wide.to_si(),
                line: f.line.to_si(),
            }),
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
    /// send telemetry. Returns the motor duties.
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
        let telemetry = Message::Telemetry(self.telemetry());
        if let Ok(n) = self.link.send(Address::Base, now_ms, &telemetry, &mut buf) {
            tx(&buf[..n]);
        }
        out
    }

    pub fn telemetry(&self) -> Telemetry {
        let c = &self.controller;
        let pose = c
            .pose()
            .and_then(|p| WirePose::from_si(p.x, p.y, p.heading).ok())
            .unwrap_or_default();
        let w = c.wheel_speeds();
        let stats = self.link.stats();
        let mut fault_flags = c.faults();
        if !self.link.peer(Address::Base).is_some_and(|p| p.is_linked()) {
            fault_flags |= faults::NOT_LINKED;
        }
        Telemetry {
            pose,
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
