//! The simulated radio: it carries the real protocol bytes, frame by frame, with air time,
//! latency, jitter, loss and byte corruption. Per (sender, receiver) pair frames arrive in
//! order, as on a serial modem link.
//!
//! Without a `[link] radio` each transmitter has air of its own at the link's baud rate (no
//! collisions); with one, every node shares one half-duplex channel ([`medium`]): frames
//! wait in their modem for the channel, collide, and are missed by a node that is sending.
//! See `docs/sim.md`.

pub mod ages;
pub mod medium;

use std::cmp::Reverse;
use std::collections::{BTreeMap, BinaryHeap, HashMap};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

pub use medium::{Medium, MediumStats};

pub use base_station::air::NodeId;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RadioParams {
    pub latency_s: f64,
    pub jitter_s: f64,
    pub loss: f64,
    pub byte_corruption: f64,
    pub baud: u32,
    /// Extra random delay per frame that may overtake earlier ones (reordering), s.
    pub reorder_s: f64,
    /// Every frame delivered twice.
    pub duplicate: bool,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RadioStats {
    /// Frame copies put on the air for their addressed receivers.
    pub frames_sent: u64,
    pub frames_delivered: u64,
    pub frames_lost: u64,
    pub bytes_corrupted: u64,
}

/// A frame copy that reached its receiver.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Arrival {
    pub to: NodeId,
    pub from: NodeId,
    /// When its sender handed it to the radio, µs.
    pub sent_us: u64,
    pub bytes: Vec<u8>,
}

/// A frame in flight: arrival time (µs), tie-break sequence, then the arrival.
type InFlight = Reverse<(u64, u64, NodeId, NodeId, u64, Vec<u8>)>;

pub struct Radio {
    params: RadioParams,
    /// One random stream per transmitter: what one node sends (an attacker's flood)
    /// does not change the loss and jitter of everyone else's frames.
    seed: u64,
    rngs: HashMap<NodeId, ChaCha8Rng>,
    queue: BinaryHeap<InFlight>,
    seq: u64,
    air_free_us: HashMap<NodeId, u64>,
    last_arrival: HashMap<(NodeId, NodeId), u64>,
    medium: Option<Medium>,
    /// Time with a frame on the air from any node, where each has air of its own.
    busy: (u64, u64),
    frames: u64,
    /// Copies addressed and delivered per (sender, receiver).
    links: BTreeMap<(NodeId, NodeId), (u64, u64)>,
    pub stats: RadioStats,
}

impl Radio {
    pub fn new(params: RadioParams, mut rng: ChaCha8Rng) -> Self {
        Self {
            params,
            seed: rng.random(),
            rngs: HashMap::new(),
            queue: BinaryHeap::new(),
            seq: 0,
            air_free_us: HashMap::new(),
            last_arrival: HashMap::new(),
            medium: None,
            busy: (0, 0),
            frames: 0,
            links: BTreeMap::new(),
            stats: RadioStats::default(),
        }
    }

    /// A radio whose nodes share `medium`.
    pub fn shared(params: RadioParams, medium: Medium, rng: ChaCha8Rng) -> Self {
        Self {
            medium: Some(medium),
            ..Self::new(params, rng)
        }
    }

    pub fn params(&self) -> &RadioParams {
        &self.params
    }

    pub fn set_params(&mut self, params: RadioParams) {
        self.params = params;
    }

    pub fn medium(&self) -> Option<&Medium> {
        self.medium.as_ref()
    }

    /// What the channel carried and lost; with air of its own for each transmitter,
    /// the frames and the time with any on the air.
    pub fn channel_stats(&self) -> MediumStats {
        match &self.medium {
            Some(m) => m.stats,
            None => MediumStats {
                frames_on_air: self.frames,
                busy_us: self.busy.1,
                ..MediumStats::default()
            },
        }
    }

    /// Copies addressed and delivered per (sender, receiver).
    pub fn links(&self) -> &BTreeMap<(NodeId, NodeId), (u64, u64)> {
        &self.links
    }

    /// Puts `bytes` (whole frames, each ending in 0x00) on the air from `from` at `now_us`.
    /// `route` names the receivers a frame is addressed to.
    pub fn transmit(
        &mut self,
        from: NodeId,
        bytes: &[u8],
        now_us: u64,
        mut route: impl FnMut(&[u8]) -> Vec<NodeId>,
    ) {
        for frame in bytes.split_inclusive(|b| *b == 0) {
            let to: Vec<NodeId> = route(frame).into_iter().filter(|t| *t != from).collect();
            for t in &to {
                self.links.entry((from, *t)).or_default().0 += 1;
            }
            self.stats.frames_sent += to.len() as u64;
            if let Some(medium) = &mut self.medium {
                if self.params.loss >= 1.0 {
                    // Silenced: nothing reaches the air.
                    self.stats.frames_lost += to.len() as u64;
                    continue;
                }
                medium.enqueue(from, frame, to, now_us);
                continue;
            }
            let air_us = (frame.len() as f64 * 10.0 / self.params.baud as f64 * 1e6) as u64;
            let start = now_us.max(*self.air_free_us.get(&from).unwrap_or(&0));
            let end = start + air_us;
            self.air_free_us.insert(from, end);
            self.busy.1 += end.saturating_sub(start.max(self.busy.0));
            self.busy.0 = self.busy.0.max(end);
            self.frames += 1;
            for to in to {
                self.launch(from, to, frame, end, now_us);
            }
        }
    }

    /// One copy off the air at `end_us`: lost, corrupted, delayed as the link's figures
    /// say, then in flight to `to`.
    fn launch(&mut self, from: NodeId, to: NodeId, frame: &[u8], end_us: u64, sent_us: u64) {
        let p = self.params;
        let seed = self.seed;
        let rng = self.rngs.entry(from).or_insert_with(|| {
            ChaCha8Rng::seed_from_u64(seed ^ (from as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15))
        });
        if rng.random::<f64>() < p.loss {
            self.stats.frames_lost += 1;
            return;
        }
        let mut copy = frame.to_vec();
        if p.byte_corruption > 0.0 {
            for b in copy.iter_mut() {
                if rng.random::<f64>() < p.byte_corruption {
                    *b ^= 1 << rng.random_range(0..8);
                    self.stats.bytes_corrupted += 1;
                }
            }
        }
        let jitter = if p.jitter_s > 0.0 {
            rng.random_range(-p.jitter_s..=p.jitter_s)
        } else {
            0.0
        };
        let delay_us = ((p.latency_s + jitter).max(0.0) * 1e6) as u64;
        let last = self.last_arrival.entry((from, to)).or_insert(0);
        let mut at = (end_us + delay_us).max(*last);
        *last = at;
        if p.reorder_s > 0.0 {
            // Past the in-order arrival: later frames may overtake this one.
            at += (rng.random_range(0.0..p.reorder_s) * 1e6) as u64;
        }
        let copies = if p.duplicate { 2 } else { 1 };
        for _ in 0..copies {
            self.seq += 1;
            self.queue
                .push(Reverse((at, self.seq, to, from, sent_us, copy.clone())));
        }
    }

    /// Frames that have arrived by `now_us`, in arrival order.
    pub fn arrivals(&mut self, now_us: u64) -> Vec<Arrival> {
        if let Some(medium) = &mut self.medium {
            for h in medium.advance(now_us) {
                self.launch(h.from, h.to, &h.bytes, h.end_us, h.queued_us);
            }
        }
        let mut out = Vec::new();
        while self
            .queue
            .peek()
            .is_some_and(|Reverse((at, ..))| *at <= now_us)
        {
            let Reverse((_, _, to, from, sent_us, bytes)) = self.queue.pop().expect("peeked");
            self.stats.frames_delivered += 1;
            self.links.entry((from, to)).or_default().1 += 1;
            out.push(Arrival {
                to,
                from,
                sent_us,
                bytes,
            });
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn latency_airtime_and_order() {
        let params = RadioParams {
            latency_s: 0.05,
            jitter_s: 0.02,
            loss: 0.0,
            byte_corruption: 0.0,
            baud: 10_000,
            reorder_s: 0.0,
            duplicate: false,
        };
        let mut r = Radio::new(params, ChaCha8Rng::seed_from_u64(1));
        // Two 10-byte frames: 10 ms of air each at 10 kbaud.
        let frames = [[1u8; 9].as_slice(), &[0], &[2u8; 9], &[0]].concat();
        r.transmit(0, &frames, 0, |_| vec![1]);
        assert!(r.arrivals(39_999).is_empty());
        let got = r.arrivals(200_000);
        assert_eq!(got.len(), 2);
        assert_eq!(got[0].bytes[0], 1);
        assert_eq!(got[1].bytes[0], 2);
        assert_eq!(r.stats.frames_delivered, 2);
    }

    #[test]
    fn loss_and_corruption_are_counted() {
        let params = RadioParams {
            latency_s: 0.0,
            jitter_s: 0.0,
            loss: 0.3,
            byte_corruption: 0.01,
            baud: 1_000_000,
            reorder_s: 0.0,
            duplicate: false,
        };
        let mut r = Radio::new(params, ChaCha8Rng::seed_from_u64(2));
        let frame = [[7u8; 39].as_slice(), &[0]].concat();
        for i in 0..1000 {
            r.transmit(0, &frame, i * 1000, |_| vec![1]);
        }
        let got = r.arrivals(u64::MAX);
        assert_eq!(r.stats.frames_sent, 1000);
        assert_eq!(got.len() as u64 + r.stats.frames_lost, 1000);
        assert!(
            (250..350).contains(&r.stats.frames_lost),
            "{}",
            r.stats.frames_lost
        );
        assert!(r.stats.bytes_corrupted > 0);
    }
}
