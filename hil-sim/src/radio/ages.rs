//! How fresh the leader's state is where it is used: for each robot, the age of every
//! leader-state frame when it reached the robot (from the station handing it to its
//! radio), and the longest time between two that did.

use protocol::messages::{LeaderState, Payload};
use protocol::{frame, FrameDecoder};

use super::{Arrival, NodeId};

#[derive(Debug, Clone, Default)]
pub struct LeaderStateAges {
    /// Per robot node (index node − 1): ages at arrival, µs.
    ages_us: Vec<Vec<u64>>,
    /// Per robot node: the last arrival and the longest gap, µs.
    last_us: Vec<Option<u64>>,
    gap_us: Vec<u64>,
}

impl LeaderStateAges {
    pub fn new(robots: usize) -> Self {
        Self {
            ages_us: vec![Vec::new(); robots],
            last_us: vec![None; robots],
            gap_us: vec![0; robots],
        }
    }

    /// Notes `a` if it is a leader state from the station reaching a robot at `now_us`.
    pub fn note(&mut self, a: &Arrival, now_us: u64) {
        if a.from != 0 || a.to == 0 || a.to > self.ages_us.len() || !is_leader_state(&a.bytes) {
            return;
        }
        let i = a.to - 1;
        self.ages_us[i].push(now_us.saturating_sub(a.sent_us));
        if let Some(last) = self.last_us[i] {
            self.gap_us[i] = self.gap_us[i].max(now_us - last);
        }
        self.last_us[i] = Some(now_us);
    }

    /// Robot `node`'s ages at arrival (µs) and its longest gap (µs).
    pub fn of(&self, node: NodeId) -> (&[u64], u64) {
        (&self.ages_us[node - 1], self.gap_us[node - 1])
    }
}

/// By its header's message id (the payload is not decoded).
fn is_leader_state(bytes: &[u8]) -> bool {
    let mut decoder = FrameDecoder::default();
    bytes.iter().any(|b| {
        matches!(
            decoder.push(*b),
            Some(Ok(raw)) if frame::peek_header(raw).is_ok_and(|h| h.id == LeaderState::ID)
        )
    })
}
