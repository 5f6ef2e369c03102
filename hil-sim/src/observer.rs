//! What a run's judge hears on the air when the base station is another process (the
//! `robots` command): the formation's blend from the leader state, each follower's slots
//! from its formation command, each robot's mode from its telemetry, and when the shape
//! changed. The recorder measures against this as `sim` measures against the station.
//!
//! Frames are parsed without checking their tags: the observer is the harness listening to
//! its own simulated air, not a robot; the robots themselves verify everything.

use std::collections::BTreeMap;

use base_station::formation::{Reason, Target, Transformation};
use protocol::frame::{self, Address};
use protocol::messages::RobotMode;
use protocol::{FrameDecoder, Message};

use crate::metrics::{FleetView, SlotPair};
use crate::radio::NodeId;

#[derive(Default)]
pub struct AirObserver {
    decoders: BTreeMap<NodeId, FrameDecoder>,
    blend: f64,
    target: Option<Target>,
    /// Slot index → (wide, line) as (L, φ).
    slots: BTreeMap<usize, SlotPair>,
    modes: BTreeMap<u16, RobotMode>,
    transformations: Vec<Transformation>,
}

impl AirObserver {
    /// Bytes node `from` put on the air at `t_s` (0 is the base station).
    pub fn overhear(&mut self, from: NodeId, bytes: &[u8], t_s: f64) {
        let decoder = self.decoders.entry(from).or_default();
        let mut messages = Vec::new();
        for &b in bytes {
            if let Some(Ok(raw)) = decoder.push(b) {
                if let Ok((header, message)) = frame::parse_unverified(raw) {
                    messages.push((header.from, message));
                }
            }
        }
        for (sender, message) in messages {
            self.absorb(sender, message, t_s);
        }
    }

    fn absorb(&mut self, sender: Address, message: Message, t_s: f64) {
        match (sender, message) {
            (Address::Base, Message::LeaderState(s)) => {
                let blend = s.blend as f64 / 255.0;
                // The shape the station is heading to: where the blend moves, or rests.
                let target = if blend >= 1.0 || blend > self.blend {
                    Some(Target::Line)
                } else if blend <= 0.0 || blend < self.blend {
                    Some(Target::Wide)
                } else {
                    self.target
                };
                if let Some(to) = target.filter(|t| self.target.is_some_and(|o| o != *t)) {
                    self.transformations.push(Transformation {
                        to,
                        start_s: t_s,
                        reason: match to {
                            Target::Line => Reason::PassageAhead,
                            Target::Wide => Reason::PassageBehind,
                        },
                    });
                }
                self.target = target.or(self.target);
                self.blend = blend;
            }
            (Address::Base, Message::FormationCommand(f)) => {
                let (wl, wphi) = f.wide.to_si();
                let (ll, lphi) = f.line.to_si();
                self.slots.insert(
                    f.index as usize,
                    ((wl as f64, wphi as f64), (ll as f64, lphi as f64)),
                );
            }
            (Address::Robot(id), Message::Telemetry(t)) => {
                self.modes.insert(id, t.mode);
            }
            _ => {}
        }
    }

    /// The shape changes heard so far.
    pub fn transformations(&self) -> &[Transformation] {
        &self.transformations
    }
}

impl FleetView for AirObserver {
    fn blend(&self) -> f64 {
        self.blend
    }
    fn target(&self) -> Target {
        self.target.unwrap_or(Target::Wide)
    }
    fn slot(&self, k: usize) -> Option<SlotPair> {
        self.slots.get(&k).copied()
    }
    fn mode(&self, robot: u16) -> Option<RobotMode> {
        self.modes.get(&robot).copied()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::link::{Link, Timing};
    use protocol::messages::{LeaderState, WirePose};
    use protocol::MasterKey;

    fn leader_state(blend: u8) -> Message {
        Message::LeaderState(LeaderState {
            pose: WirePose::default(),
            v_mm_s: 0,
            omega_mrad_s: 0,
            blend,
        })
    }

    #[test]
    fn a_blend_that_rises_then_falls_is_two_transformations() {
        let key = MasterKey::from_bytes(&[7; 32]);
        let mut base: Link<4> = Link::new(Address::Base, key.broadcast(), 1, 1, Timing::default());
        let mut observer = AirObserver::default();
        let mut buf = [0u8; protocol::MAX_WIRE];
        for (i, blend) in [0u8, 0, 100, 255, 255, 128, 0, 0].into_iter().enumerate() {
            let n = base
                .send(
                    Address::Broadcast,
                    i as u32 * 100,
                    &leader_state(blend),
                    &mut buf,
                )
                .unwrap();
            observer.overhear(0, &buf[..n], i as f64 * 0.1);
        }
        let seen: Vec<_> = observer
            .transformations()
            .iter()
            .map(|t| (t.to, (t.start_s * 10.0).round() as u32))
            .collect();
        assert_eq!(seen, [(Target::Line, 2), (Target::Wide, 5)]);
        assert_eq!(observer.blend(), 0.0);
    }
}
