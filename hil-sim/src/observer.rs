//! What a run's judge hears on the air when the base station is another process (the
//! `robots` command): the formation's blend from the leader state, each follower's slots
//! from its formation command, each robot's mode from its telemetry, and when the shape
//! changed. The recorder measures against this as `sim` measures against the station.
//!
//! A transition's blend follows a known curve ([`smoothstep`] over the transition's
//! duration) from where it was when the station switched: from the first leader state that
//! moved, the observer recovers when the switch was, and so the blend at any instant, as
//! the station has it.
//!
//! A leader state is timed by the station's own stamp in its header, not by when it was
//! heard: behind a real transport it arrives 0–100 ms late, by the pseudo-terminal, the
//! world's 10 ms step and the station's scheduling, and timed on arrival the recovered
//! switch came late by as much (the followers, which time it by the station's clock, then
//! looked up to 0.08 m off in a shape change). The station's clock is mapped to the
//! world's by the least apparent latency of its recent frames (a minimum filter, as a
//! clock filter keeps the shortest round trip).
//!
//! Frames are parsed without checking their tags: the observer is the harness listening to
//! its own simulated air, not a robot; the robots themselves verify everything.

use std::collections::{BTreeMap, VecDeque};

use base_station::formation::{smoothstep, transition_blend, Reason, Target, Transformation};
use protocol::frame::{self, Address, WireHeader};
use protocol::messages::RobotMode;
use protocol::{FrameDecoder, Message};

use crate::metrics::{FleetView, SlotPair};
use crate::radio::NodeId;

pub struct AirObserver {
    decoders: BTreeMap<NodeId, FrameDecoder>,
    /// The transition's duration, s.
    duration: f64,
    /// The last blend heard.
    heard: f64,
    /// The transition under way or last done: from which blend, to what, started when
    /// (world clock, s).
    transition: Option<(f64, Target, f64)>,
    /// Robot → its slot (wide, line) as (L, φ), as last told.
    slots: BTreeMap<u16, SlotPair>,
    modes: BTreeMap<u16, RobotMode>,
    transformations: Vec<Transformation>,
    /// The base station's recent frames' apparent latency (heard − stamped), s: the
    /// least is the offset of its clock to the world's.
    latencies: VecDeque<f64>,
    /// The station's last stamp, whole, and when it was heard (world clock, s): frames carry
    /// their clock's low bits, completed from it.
    last_stamp: Option<(u32, f64)>,
}

/// How many of the station's frames the clock mapping looks back on (5 s at 10 Hz and a
/// frame or two more per period): long enough to hold an undelayed frame, short enough to
/// follow a drift of the two clocks.
const LATENCY_WINDOW: usize = 100;

/// The x in [0, 1] where [`smoothstep`] reaches `y` (it rises monotonically).
fn inverse_smoothstep(y: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..50 {
        let mid = 0.5 * (lo + hi);
        if smoothstep(mid) < y {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

impl AirObserver {
    /// `transition_s`: the formation's transition duration (the scenario's).
    pub fn new(transition_s: f64) -> Self {
        Self {
            decoders: BTreeMap::new(),
            duration: transition_s,
            heard: 0.0,
            transition: None,
            slots: BTreeMap::new(),
            modes: BTreeMap::new(),
            transformations: Vec::new(),
            latencies: VecDeque::new(),
            last_stamp: None,
        }
    }

    /// Bytes node `from` put on the air at `t_s` (0 is the base station).
    pub fn overhear(&mut self, from: NodeId, bytes: &[u8], t_s: f64) {
        let decoder = self.decoders.entry(from).or_default();
        let mut messages = Vec::new();
        for &b in bytes {
            if let Some(Ok(raw)) = decoder.push(b) {
                if let Ok((header, message)) = frame::parse_unverified(raw) {
                    messages.push((header.from, header.to, header, message));
                }
            }
        }
        for (sender, to, header, message) in messages {
            let t_s = match sender {
                Address::Base => {
                    let stamp_ms = self.whole_stamp(&header, t_s);
                    self.station_time(stamp_ms, t_s)
                }
                _ => t_s,
            };
            self.absorb(sender, to, message, t_s);
        }
    }

    /// The station's whole clock on a frame heard at `heard_s`: carried on a handshake
    /// frame, else completed from the last one heard (the first from the world's clock; a
    /// wrong guess there shifts every stamp alike, which the latency offset absorbs).
    fn whole_stamp(&mut self, header: &WireHeader, heard_s: f64) -> u32 {
        let near = match self.last_stamp {
            Some((stamp, at)) => stamp.wrapping_add(((heard_s - at) * 1000.0) as u32),
            None => (heard_s * 1000.0) as u32,
        };
        let whole = header.time_near(near);
        self.last_stamp = Some((whole, heard_s));
        whole
    }

    /// When the station stamped a frame heard at `heard_s`, on the world's clock.
    fn station_time(&mut self, stamp_ms: u32, heard_s: f64) -> f64 {
        let stamp_s = stamp_ms as f64 / 1000.0;
        if self.latencies.len() == LATENCY_WINDOW {
            self.latencies.pop_front();
        }
        self.latencies.push_back(heard_s - stamp_s);
        let offset = self.latencies.iter().copied().fold(f64::INFINITY, f64::min);
        stamp_s + offset
    }

    fn absorb(&mut self, sender: Address, to: Address, message: Message, t_s: f64) {
        match (sender, message) {
            (Address::Base, Message::LeaderState(s)) => {
                let blend = s.blend as f64 / 255.0;
                let moving = if blend > self.heard {
                    Some(Target::Line)
                } else if blend < self.heard {
                    Some(Target::Wide)
                } else {
                    None
                };
                let current = self.transition.map(|t| t.1);
                if let Some(to) = moving.filter(|to| current != Some(*to)) {
                    // The first step of a new transition: when did the station switch?
                    let done = ((blend - self.heard) / (to.blend() - self.heard)).clamp(0.0, 1.0);
                    let start_s = t_s - inverse_smoothstep(done) * self.duration;
                    self.transition = Some((self.heard, to, start_s));
                    self.transformations.push(Transformation {
                        to,
                        start_s,
                        end_s: None,
                        reason: match to {
                            Target::Line => Reason::PassageAhead,
                            Target::Wide => Reason::PassageBehind,
                        },
                    });
                }
                // Each state of the transition tells its start again; the 8-bit blend tells it
                // best mid-way, where the curve is steep. The station may slow a change down
                // (`FormationManager::step`), so the start fitted later on is where the curve
                // at full pace would have started: the record keeps the first half's.
                if let Some((from, to, start_s)) = &mut self.transition {
                    let done = (blend - *from) / (to.blend() - *from);
                    let last = self.transformations.last_mut();
                    if (0.1..=0.9).contains(&done) {
                        *start_s = t_s - inverse_smoothstep(done) * self.duration;
                        if let Some(last) = last.filter(|_| done <= 0.5) {
                            last.start_s = *start_s;
                        }
                    } else if done >= 1.0 {
                        if let Some(last) = last.filter(|l| l.end_s.is_none()) {
                            last.end_s = Some(t_s);
                        }
                    }
                }
                self.heard = blend;
            }
            (Address::Base, Message::FormationCommand(f)) => {
                let Address::Robot(robot) = to else {
                    return;
                };
                let (wl, wphi) = f.wide.to_si();
                let (ll, lphi) = f.line.to_si();
                self.slots
                    .insert(robot, ((wl as f64, wphi as f64), (ll as f64, lphi as f64)));
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
    fn blend(&self, t_us: u64) -> f64 {
        match self.transition {
            Some((from, to, start_s)) => {
                transition_blend(from, to, t_us as f64 / 1e6 - start_s, self.duration)
            }
            None => self.heard,
        }
    }
    fn target(&self) -> Target {
        self.transition.map_or(Target::Wide, |t| t.1)
    }
    fn slot(&self, robot: u16) -> Option<SlotPair> {
        self.slots.get(&robot).copied()
    }
    fn mode(&self, robot: u16) -> Option<RobotMode> {
        self.modes.get(&robot).copied()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::link::{Link, Timing};
    use protocol::messages::{LeaderState, WirePose, WireTwist};
    use protocol::MasterKey;

    fn leader_state(blend: u8) -> Message {
        Message::LeaderState(LeaderState {
            pose: WirePose::default(),
            twist: WireTwist::default(),
            blend,
        })
    }

    /// A station's transitions (3.5 s, switching to the line at 0.25 s and back at 2.0 s,
    /// mid-way), broadcast at 10 Hz and heard up to 90 ms late: the observer has the
    /// station's blend at any instant.
    #[test]
    fn the_blend_between_leader_states_is_the_stations() {
        let key = MasterKey::from_bytes(&[7; 32]);
        let mut base: Link<4> = Link::new(Address::Base, key.broadcast(), 1, 1, Timing::default());
        let mut observer = AirObserver::new(3.5);
        let station = |t: f64| {
            let up = smoothstep((t - 0.25) / 3.5);
            if t < 2.0 {
                up
            } else {
                let from = smoothstep((2.0 - 0.25) / 3.5);
                from * (1.0 - smoothstep((t - 2.0) / 3.5))
            }
        };
        let mut buf = [0u8; protocol::MAX_WIRE];
        for i in 0..60 {
            let t = i as f64 * 0.1;
            let blend = (station(t) * 255.0).round() as u8;
            let n = base
                .send(Address::Broadcast, i * 100, &leader_state(blend), &mut buf)
                .unwrap();
            // Heard 0–90 ms late, as behind a pseudo-terminal and a busy scheduler.
            let late = [0.0, 0.03, 0.09, 0.01, 0.06][i as usize % 5];
            observer.overhear(0, &buf[..n], t + late);
            // Between this state and the next, as the station has it (to the wire's 1/255);
            // except right after a switch, which the air tells only with the next state.
            let between = t + 0.05;
            let got = observer.blend((between * 1e6) as u64);
            if i >= 4 && i != 20 {
                assert!(
                    (got - station(between)).abs() < 0.01,
                    "{between}: {got} vs {}",
                    station(between)
                );
            }
        }
        let seen = observer.transformations();
        assert_eq!(seen.len(), 2);
        for (t, (to, start)) in seen.iter().zip([(Target::Line, 0.25), (Target::Wide, 2.0)]) {
            assert_eq!(t.to, to);
            assert!((t.start_s - start).abs() < 0.02, "{t:?}");
        }
    }
}
