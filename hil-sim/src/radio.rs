//! The simulated radio: it carries the real protocol bytes, frame by frame, with air time
//! (baud rate), latency, jitter, loss and byte corruption. Per (sender, receiver) pair
//! frames arrive in order, as on a serial modem link.
//!
//! Each transmitter has its own air time; the channel itself is not shared (no collisions):
//! see `docs/sim.md`.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A node on the radio: 0 is the base station, then the robots.
pub type NodeId = usize;

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

/// A frame in flight: arrival time (µs), tie-break sequence, receiver, bytes.
type InFlight = Reverse<(u64, u64, NodeId, Vec<u8>)>;

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
            stats: RadioStats::default(),
        }
    }

    pub fn params(&self) -> &RadioParams {
        &self.params
    }

    pub fn set_params(&mut self, params: RadioParams) {
        self.params = params;
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
        let p = self.params;
        let seed = self.seed;
        let rng = self.rngs.entry(from).or_insert_with(|| {
            ChaCha8Rng::seed_from_u64(seed ^ (from as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15))
        });
        for frame in bytes.split_inclusive(|b| *b == 0) {
            let air_us = (frame.len() as f64 * 10.0 / p.baud as f64 * 1e6) as u64;
            let start = now_us.max(*self.air_free_us.get(&from).unwrap_or(&0));
            let end = start + air_us;
            self.air_free_us.insert(from, end);
            for to in route(frame) {
                if to == from {
                    continue;
                }
                self.stats.frames_sent += 1;
                if rng.random::<f64>() < p.loss {
                    self.stats.frames_lost += 1;
                    continue;
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
                let mut at = (end + delay_us).max(*last);
                *last = at;
                if p.reorder_s > 0.0 {
                    // Past the in-order arrival: later frames may overtake this one.
                    at += (rng.random_range(0.0..p.reorder_s) * 1e6) as u64;
                }
                let copies = if p.duplicate { 2 } else { 1 };
                for _ in 0..copies {
                    self.seq += 1;
                    self.queue.push(Reverse((at, self.seq, to, copy.clone())));
                }
            }
        }
    }

    /// Frames that have arrived by `now_us`, in arrival order.
    pub fn arrivals(&mut self, now_us: u64) -> Vec<(NodeId, Vec<u8>)> {
        let mut out = Vec::new();
        while self
            .queue
            .peek()
            .is_some_and(|Reverse((at, ..))| *at <= now_us)
        {
            let Reverse((_, _, to, bytes)) = self.queue.pop().expect("peeked");
            self.stats.frames_delivered += 1;
            out.push((to, bytes));
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
        assert_eq!(got[0].1[0], 1);
        assert_eq!(got[1].1[0], 2);
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
