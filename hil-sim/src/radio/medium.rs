//! One shared, half-duplex channel: every node hears every other (no range model, so no
//! capture); a frame occupies the channel for its air time; two frames that overlap at a
//! receiver are both lost there, and a node sending misses what it would have heard.
//! Who may send when is the access scheme's: ALOHA, listen-before-talk (CSMA) or the base
//! station's schedule. Time in µs; events in time order, ties by node, so a run is the
//! same whatever the machine.

use std::collections::VecDeque;

use base_station::air::{Air, Schedule};
use base_station::scenario::radio::{Access, Channel};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::NodeId;

/// A robot's modem holds this many frames; a new one pushes the oldest out.
const QUEUE_FRAMES: usize = 8;
/// The station's (it answers every robot's handshake at once).
const STATION_QUEUE_FRAMES: usize = 64;

/// What the medium did, for the report.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MediumStats {
    pub frames_on_air: u64,
    /// Copies lost at a receiver to another frame on the air at the same time.
    pub collisions: u64,
    /// Copies a receiver missed because it was sending.
    pub half_duplex: u64,
    /// Frames a full modem queue pushed out.
    pub queue_drops: u64,
    /// Frames longer than any slot of their sender's.
    pub unsendable: u64,
    /// Time with at least one frame on the air.
    pub busy_us: u64,
}

/// A frame waiting in its sender's modem.
struct Pending {
    bytes: Vec<u8>,
    to: Vec<NodeId>,
    queued_us: u64,
}

/// A frame on the air.
struct OnAir {
    from: NodeId,
    start: u64,
    end: u64,
    frame: Pending,
    resolved: bool,
}

/// A copy that reached its receiver through the medium.
pub struct Heard {
    pub from: NodeId,
    pub to: NodeId,
    pub bytes: Vec<u8>,
    pub queued_us: u64,
    pub end_us: u64,
}

#[derive(Default)]
struct Mac {
    queue: VecDeque<Pending>,
    next_try: u64,
}

pub struct Medium {
    air: Air,
    /// A frame handed over at a step reaches its modem at a random instant within the
    /// step: the firmware's tick falls anywhere in it (a simulator's step is no clock
    /// every robot shares).
    spread_us: u64,
    access: Access,
    sense_us: u64,
    backoff_slots: u32,
    schedule: Schedule,
    macs: Vec<Mac>,
    rng: ChaCha8Rng,
    on_air: Vec<OnAir>,
    busy_until: u64,
    pub stats: MediumStats,
}

impl Medium {
    /// A channel for the station (node 0) and `robots` robots; the schedule serves
    /// `leader` every period.
    pub fn new(
        channel: Channel,
        robots: usize,
        leader: Option<NodeId>,
        spread_us: u64,
        seed: u64,
    ) -> Self {
        let air = Air::new(channel);
        let sense_us = channel.preset.sense_us.ceil() as u64;
        Self {
            air,
            spread_us,
            access: channel.access,
            sense_us,
            backoff_slots: channel.preset.backoff_slots.max(1),
            schedule: Schedule::of(channel, robots, leader),
            macs: (0..=robots).map(|_| Mac::default()).collect(),
            rng: ChaCha8Rng::seed_from_u64(seed),
            on_air: Vec::new(),
            busy_until: 0,
            stats: MediumStats::default(),
        }
    }

    pub fn schedule(&self) -> &Schedule {
        &self.schedule
    }

    /// Hands a frame to `from`'s modem at `now_us`.
    pub fn enqueue(&mut self, from: NodeId, bytes: &[u8], to: Vec<NodeId>, now_us: u64) {
        if from >= self.macs.len() {
            self.macs.resize_with(from + 1, Mac::default);
        }
        let mut at = now_us + self.rng.random_range(0..self.spread_us.max(1));
        if self.access == Access::Csma {
            // Unslotted CSMA-CA: a random backoff before the first listen.
            at += self.sense_us * self.rng.random_range(0..self.backoff_slots) as u64;
        }
        let mac = &mut self.macs[from];
        if mac.queue.is_empty() {
            mac.next_try = mac.next_try.max(at);
        }
        // The schedule opens each period with the broadcast (the leader state): it goes
        // ahead of the unicast frames waiting.
        let pos = match self.access {
            Access::Scheduled if to.len() > 1 => mac
                .queue
                .iter()
                .position(|p| p.to.len() <= 1)
                .unwrap_or(mac.queue.len()),
            _ => mac.queue.len(),
        };
        mac.queue.insert(
            pos,
            Pending {
                bytes: bytes.to_vec(),
                to,
                queued_us: now_us,
            },
        );
        let room = if from == 0 {
            STATION_QUEUE_FRAMES
        } else {
            QUEUE_FRAMES
        };
        if mac.queue.len() > room {
            mac.queue.pop_front();
            self.stats.queue_drops += 1;
        }
    }

    /// Runs the channel up to `until_us`; the copies heard by then, in the order their
    /// frames ended.
    pub fn advance(&mut self, until_us: u64) -> Vec<Heard> {
        while let Some((node, t)) = self.next_attempt() {
            if t > until_us {
                break;
            }
            self.attempt(node, t);
        }
        self.resolve(until_us)
    }

    /// The node that tries first (ties: the lowest id) and when.
    fn next_attempt(&self) -> Option<(NodeId, u64)> {
        self.macs
            .iter()
            .enumerate()
            .filter(|(_, m)| !m.queue.is_empty())
            .map(|(n, m)| (n, m.next_try))
            .min_by_key(|(n, t)| (*t, *n))
    }

    fn attempt(&mut self, node: NodeId, t: u64) {
        let len = self.macs[node].queue.front().expect("queued").bytes.len();
        let air_us = self.air.us(len);
        match self.access {
            Access::Aloha => self.start(node, t, air_us),
            Access::Csma => match self.sensed_busy_until(node, t) {
                Some(end) => {
                    let slots = self.rng.random_range(0..self.backoff_slots) as u64;
                    self.macs[node].next_try = end + self.sense_us * (1 + slots);
                }
                None => self.start(node, t, air_us),
            },
            Access::Scheduled => match self.schedule.next_start(node, t, air_us) {
                Some(s) if s == t => self.start(node, t, air_us),
                Some(s) => self.macs[node].next_try = s,
                None => {
                    self.macs[node].queue.pop_front();
                    self.stats.unsendable += 1;
                }
            },
        }
    }

    /// The end of the frames `node` hears at `t` (one that began under `sense_us` ago is
    /// not heard yet).
    fn sensed_busy_until(&self, node: NodeId, t: u64) -> Option<u64> {
        self.on_air
            .iter()
            .filter(|f| f.from != node && f.start + self.sense_us <= t && t < f.end)
            .map(|f| f.end)
            .max()
    }

    fn start(&mut self, node: NodeId, t: u64, air_us: u64) {
        let frame = self.macs[node].queue.pop_front().expect("queued");
        let end = t + air_us;
        self.macs[node].next_try = end;
        self.stats.frames_on_air += 1;
        self.stats.busy_us += end.saturating_sub(t.max(self.busy_until));
        self.busy_until = self.busy_until.max(end);
        self.on_air.push(OnAir {
            from: node,
            start: t,
            end,
            frame,
            resolved: false,
        });
    }

    /// Frames that ended by `until_us`: who heard each; then forgets what no frame still
    /// on the air overlaps.
    fn resolve(&mut self, until_us: u64) -> Vec<Heard> {
        let mut done: Vec<usize> = (0..self.on_air.len())
            .filter(|i| !self.on_air[*i].resolved && self.on_air[*i].end <= until_us)
            .collect();
        done.sort_by_key(|i| (self.on_air[*i].end, self.on_air[*i].from));
        let mut heard = Vec::new();
        for i in done {
            let f = &self.on_air[i];
            for &to in &f.frame.to {
                match self.fate(i, to) {
                    Fate::Heard => heard.push(Heard {
                        from: f.from,
                        to,
                        bytes: f.frame.bytes.clone(),
                        queued_us: f.frame.queued_us,
                        end_us: f.end,
                    }),
                    Fate::Collided => self.stats.collisions += 1,
                    Fate::Sending => self.stats.half_duplex += 1,
                }
            }
            self.on_air[i].resolved = true;
        }
        let keep_from = self
            .on_air
            .iter()
            .filter(|f| !f.resolved)
            .map(|f| f.start)
            .min()
            .unwrap_or(u64::MAX);
        self.on_air.retain(|f| !f.resolved || f.end > keep_from);
        heard
    }

    fn fate(&self, i: usize, to: NodeId) -> Fate {
        let f = &self.on_air[i];
        let overlapping = self
            .on_air
            .iter()
            .enumerate()
            .filter(|(j, g)| *j != i && g.start < f.end && f.start < g.end);
        let mut fate = Fate::Heard;
        for (_, g) in overlapping {
            if g.from == to {
                return Fate::Sending;
            }
            if g.from != f.from {
                fate = Fate::Collided;
            }
        }
        fate
    }
}

enum Fate {
    Heard,
    Collided,
    Sending,
}

#[cfg(test)]
mod tests {
    use super::*;
    use base_station::air::PERIOD_US;
    use base_station::scenario::radio::preset;

    fn channel(name: &str, access: Access) -> Channel {
        let preset = preset(name).expect("a preset");
        Channel {
            preset,
            phy: preset.phy,
            access,
        }
    }

    #[test]
    fn overlapping_frames_collide_and_a_sender_hears_nothing() {
        let mut m = Medium::new(channel("sik-64k", Access::Aloha), 2, Some(1), 1, 1);
        m.enqueue(1, &[1; 30], vec![0, 2], 0);
        m.enqueue(2, &[2; 30], vec![0, 1], 1_000);
        let heard = m.advance(1_000_000);
        assert!(
            heard.is_empty(),
            "both lost at the station, each sender deaf"
        );
        assert_eq!(m.stats.collisions, 2);
        assert_eq!(m.stats.half_duplex, 2);
        m.enqueue(1, &[1; 30], vec![0, 2], 2_000_000);
        let heard = m.advance(3_000_000);
        assert_eq!(heard.len(), 2, "alone on the air");
    }

    /// Hands each (time, node, length, receivers) to the medium at its time, in order.
    fn feed(m: &mut Medium, mut frames: Vec<(u64, NodeId, usize, Vec<NodeId>)>) -> Vec<Heard> {
        frames.sort_by_key(|f| (f.0, f.1));
        let mut heard = Vec::new();
        for (t, node, len, to) in frames {
            heard.extend(m.advance(t));
            m.enqueue(node, &vec![9; len], to, t);
        }
        heard.extend(m.advance(u64::MAX / 2));
        heard
    }

    /// Every robot sends one frame a period at a random time; the station one at the
    /// period's start.
    fn traffic(robots: usize, periods: u64) -> Vec<(u64, NodeId, usize, Vec<NodeId>)> {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut out = Vec::new();
        for p in 0..periods {
            out.push((p * PERIOD_US, 0, 31, (1..=robots).collect()));
            for node in 1..=robots {
                out.push((
                    p * PERIOD_US + rng.random_range(0..PERIOD_US),
                    node,
                    38,
                    vec![0],
                ));
            }
        }
        out
    }

    #[test]
    fn listening_first_avoids_most_collisions() {
        let lost = |access| {
            let mut m = Medium::new(channel("sik-64k", access), 5, Some(1), 1, 7);
            feed(&mut m, traffic(5, 300));
            m.stats.collisions
        };
        let (aloha, csma) = (lost(Access::Aloha), lost(Access::Csma));
        assert!(csma * 3 < aloha, "csma {csma}, aloha {aloha}");
    }

    #[test]
    fn the_schedule_never_collides() {
        let mut m = Medium::new(channel("sik-64k", Access::Scheduled), 15, Some(1), 1, 7);
        let s = m.schedule().clone();
        assert!(s.slots >= 2 && s.cycle_periods() > 1, "{s:?}");
        let heard = feed(&mut m, traffic(15, 100));
        assert_eq!(m.stats.collisions + m.stats.half_duplex, 0);
        assert_eq!(heard.iter().filter(|h| h.from == 0).count(), 100 * 15);
        // The leader has a slot every period.
        assert_eq!(heard.iter().filter(|h| h.from == 1).count(), 100);
    }
}
