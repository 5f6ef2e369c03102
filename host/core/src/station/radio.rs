//! What the station hears and says over the authenticated link: frames in (telemetry to
//! the fleet room, handshakes answered at once), and out (challenges, slots, the orders
//! the desk gave, the leader's state), each sealed into the outbox the driver sends.

use glam::DVec2;
use protocol::link::Event;
use protocol::messages::{
    Detour, FormationCommand, LeaderState, Message, Slot, Stop, WirePose, WireTwist,
};
use protocol::{units, Address, Reject, MAX_WIRE};

use super::fleet::LeaderEstimate;
use super::{BaseStation, Gate, StationEvent};

impl BaseStation {
    /// Bytes to transmit, oldest first.
    pub fn take_outbox(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.outbox)
    }

    /// Counts a frame the byte decoder could not even deframe.
    pub fn count_reject(&mut self, reason: Reject) {
        self.link.count_reject(reason);
    }

    pub(super) fn send(&mut self, to: Address, now_ms: u32, message: &Message) {
        let mut buf = [0u8; MAX_WIRE];
        match self.link.send(to, now_ms, message, &mut buf) {
            Ok(n) => self.outbox.extend_from_slice(&buf[..n]),
            Err(e) => tracing::warn!(%to, "cannot send {}: {e}", message.name()),
        }
    }

    /// A Stop to every robot.
    pub(super) fn broadcast(&mut self, stop: Stop, now_ms: u32) {
        self.send(Address::Broadcast, now_ms, &Message::Stop(stop));
    }

    /// Bytes from the radio.
    pub fn receive(&mut self, bytes: &[u8], now_ms: u32) {
        for &b in bytes {
            let Some(frame) = self.decoder.push(b) else {
                continue;
            };
            match self.link.receive(frame, now_ms) {
                Ok(Event::Message { header, message }) => {
                    if let (Address::Robot(id), Message::Telemetry(t)) = (header.from, message) {
                        let offset = self
                            .link
                            .peer(header.from)
                            .and_then(|p| p.clock_offset_ms)
                            .unwrap_or(0);
                        // Robot clock → ours; never later than now.
                        let at = header.time_ms.wrapping_sub(offset as u32);
                        let pose_at = if (now_ms.wrapping_sub(at) as i32) < 0 {
                            now_ms
                        } else {
                            at
                        };
                        self.check_told(id, pose_at);
                        let heard = self.fleet.hear(id, t, pose_at, now_ms);
                        self.events.extend(heard.events);
                        if heard.halts {
                            self.gate = Gate::Halted;
                        }
                    }
                }
                Ok(Event::Challenged { from, nonce }) => {
                    let mut buf = [0u8; MAX_WIRE];
                    if let Ok(n) = self.link.answer(from, nonce, now_ms, &mut buf) {
                        self.outbox.extend_from_slice(&buf[..n]);
                        // The robot verifies our frames from this answer on: its slots go
                        // out at the next step (sent before, they were refused). On a
                        // shared channel the round of refreshes brings them: a robot
                        // challenging again and again would fill the downlink.
                        if let (Address::Robot(id), false) = (from, self.cfg.shared_channel) {
                            self.slots_due_for(id);
                        }
                    }
                }
                Ok(Event::Linked { peer }) => {
                    if let Address::Robot(robot) = peer {
                        tracing::info!(robot, "linked");
                        self.events.push(StationEvent::Linked {
                            robot,
                            at_ms: now_ms,
                        });
                        self.slots_due_for(robot);
                    }
                }
                Ok(Event::Synced { .. } | Event::Ignored) => {}
                Err(reason) => tracing::debug!(%reason, "frame rejected"),
            }
        }
    }

    /// On a shared channel a follower's slots go round slowly: one whose reports come
    /// closer together than half the interval it was told (by its own stamps: a modem
    /// holding them evens out their arrival) has not had its `FormationCommand` since it
    /// linked, and gets its slots at the next step.
    fn check_told(&mut self, id: u16, pose_at_ms: u32) {
        if !self.cfg.shared_channel || !self.fleet.followers.contains(&id) {
            return;
        }
        let told_ms = u32::from(self.cfg.report_every) * self.cfg.period_ms;
        let too_often = self
            .fleet
            .get(id)
            .filter(|s| s.telemetry.is_some())
            .is_some_and(|s| pose_at_ms.wrapping_sub(s.pose_at_ms) < told_ms / 2);
        if too_often {
            self.slots_due_for(id);
        }
    }

    /// Challenges to the robots whose link needs one.
    /// On a shared channel one a period: a fleet challenged at once would fill the
    /// downlink for seconds, and the answers to robots' own challenges wait behind.
    pub(super) fn challenge_due(&mut self, now_ms: u32) {
        let mut buf = [0u8; MAX_WIRE];
        while let Some(peer) = self.link.due_challenge(now_ms) {
            match self.link.challenge(peer, now_ms, &mut buf) {
                Ok(n) => self.outbox.extend_from_slice(&buf[..n]),
                Err(_) => break,
            }
            if self.cfg.shared_channel {
                break;
            }
        }
    }

    /// Slots for robot `id` at the next step: on a shared channel its own alone (the
    /// air is scarce), else every follower's (a slot lost before is mended at once).
    fn slots_due_for(&mut self, id: u16) {
        if !self.cfg.shared_channel {
            self.last_slots_ms = None;
        } else if !self.slots_due.contains(&id) {
            self.slots_due.push(id);
        }
    }

    /// Each follower's two slots (`only`: these followers').
    pub(super) fn send_slots(&mut self, now_ms: u32, only: Option<&[u16]>) {
        let n = self.fleet.followers.len();
        for (k, id) in self.fleet.followers.clone().into_iter().enumerate() {
            if only.is_some_and(|o| !o.contains(&id)) {
                continue;
            }
            let slot =
                |(l, phi): (f64, f64)| Slot::from_si(l as f32, phi as f32).unwrap_or_default();
            let formation = self.guidance.formation();
            let cmd = Message::FormationCommand(FormationCommand {
                followers: n.min(u16::MAX as usize) as u16,
                index: k.min(u16::MAX as usize) as u16,
                wide: slot(formation.wide_slots()[k]),
                line: slot(formation.line_slots()[k]),
                report_every: self.cfg.report_every,
            });
            self.send(Address::Robot(id), now_ms, &cmd);
        }
    }

    /// The pose is the leader's (measured, predicted to now); the velocity is the one it
    /// was just told to drive. The followers then start to speed up or turn when the
    /// leader does, not a motor lag later: their own lag matches the leader's. The turn
    /// rate is smoothed where it only jitters ([`super::TurnRateSmoother`]).
    pub(super) fn broadcast_leader_state(
        &mut self,
        leader: &LeaderEstimate,
        twist: (f64, f64),
        blend: f64,
        now_ms: u32,
    ) {
        let p = leader.pose;
        let twist = (twist.0, self.broadcast_omega.step(twist.1));
        if let Ok(pose) =
            WirePose::from_si(p.position.x as f32, p.position.y as f32, p.heading as f32)
        {
            let state = Message::LeaderState(LeaderState {
                pose,
                twist: WireTwist::from_si(twist.0 as f32, twist.1 as f32).unwrap_or_default(),
                blend: (blend.clamp(0.0, 1.0) * 255.0).round() as u8,
            });
            self.send(Address::Broadcast, now_ms, &state);
        }
    }

    /// Tells a follower to make for `point` instead of its slot, this period.
    pub(super) fn send_detour(&mut self, robot: u16, point: DVec2, now_ms: u32) {
        let (Ok(x_mm), Ok(y_mm)) = (
            units::metres_to_mm(point.x as f32),
            units::metres_to_mm(point.y as f32),
        ) else {
            return;
        };
        self.send(
            Address::Robot(robot),
            now_ms,
            &Message::Detour(Detour { x_mm, y_mm }),
        );
    }
}
