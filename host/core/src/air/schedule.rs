//! The base station's schedule of a shared channel: the downlink opens each period (the
//! leader-state broadcast first), then the robots' uplink slots.

use super::{Air, NodeId, PERIOD_US};
use super::{DOWNLINK_FRAMES, DOWNLINK_FRAME_BYTES, UPLINK_FRAMES, UPLINK_FRAME_BYTES};
use crate::scenario::radio::Channel;

/// The base station's schedule: each period opens with the downlink, then uplink slots;
/// the leader's is the first of every period, the followers take the others in turn.
#[derive(Debug, Clone, PartialEq)]
pub struct Schedule {
    pub down_us: u64,
    /// The leader's slot: two frames (its report every period, and one more).
    pub leader_slot_us: u64,
    /// A follower's slot: two frames where every robot has a slot each period, else one
    /// (a follower taking turns reports every other turn: `report_every`).
    pub slot_us: u64,
    pub guard_us: u64,
    /// Uplink slots per period.
    pub slots: u64,
    pub leader: Option<NodeId>,
    pub followers: Vec<NodeId>,
}

impl Schedule {
    /// The schedule of `channel` for the station and nodes 1..=`robots`, `leader` among
    /// them; guards of one listening time between slots.
    pub fn of(channel: Channel, robots: usize, leader: Option<NodeId>) -> Self {
        let followers = (1..=robots).filter(|n| Some(*n) != leader).collect();
        let guard_us = channel.preset.sense_us.ceil() as u64;
        Self::new(&Air::new(channel), guard_us, leader, followers)
    }

    /// The downlink holds at least `DOWNLINK_FRAMES` frames and one per ten followers.
    /// Every robot has a slot of
    /// `UPLINK_FRAMES` each period where they fit; else the leader has one and the
    /// followers take one-frame slots in turn. What is left of the period goes to the
    /// downlink.
    fn new(air: &Air, guard_us: u64, leader: Option<NodeId>, followers: Vec<NodeId>) -> Self {
        let frames = (DOWNLINK_FRAMES + followers.len().div_ceil(10)) as u64;
        let down_min = frames * (air.us(DOWNLINK_FRAME_BYTES) + guard_us);
        let down_min = down_min.min(PERIOD_US);
        let frame = air.us(UPLINK_FRAME_BYTES);
        let wide = UPLINK_FRAMES as u64 * frame + guard_us;
        let robots = followers.len() as u64 + u64::from(leader.is_some());
        let room = PERIOD_US - down_min;
        let leader_slot_us = if leader.is_some() { wide } else { 0 };
        let (slot_us, slots) = if robots * wide <= room {
            (wide, robots)
        } else {
            let narrow = frame + guard_us;
            let followers = room.saturating_sub(leader_slot_us) / narrow;
            let slots = u64::from(leader.is_some() && leader_slot_us <= room) + followers;
            (narrow, slots.min(robots))
        };
        let first = u64::from(leader.is_some() && slots > 0);
        let used = first * leader_slot_us + (slots - first) * slot_us;
        Self {
            down_us: PERIOD_US - used,
            leader_slot_us,
            slot_us,
            guard_us,
            slots,
            leader,
            followers,
        }
    }

    /// Periods between two reports of a follower: every period where it has a two-frame
    /// slot each period, else two turns (a one-frame slot keeps room for a handshake).
    pub fn report_every(&self) -> u64 {
        match self.cycle_periods() {
            1 if self.slot_us == self.leader_slot_us || self.leader.is_none() => 1,
            u64::MAX => u64::MAX,
            c => 2 * c,
        }
    }

    /// Periods until every follower has had a slot.
    pub fn cycle_periods(&self) -> u64 {
        let per_period = self.slots.saturating_sub(u64::from(self.leader.is_some()));
        match (self.followers.len() as u64, per_period) {
            (0, _) => 1,
            (_, 0) => u64::MAX,
            (n, k) => n.div_ceil(k),
        }
    }

    /// `node`'s windows in period `p`: (start, end) of each slot it owns.
    fn windows(&self, node: NodeId, p: u64) -> Vec<(u64, u64)> {
        let base = p * PERIOD_US;
        if node == 0 {
            return vec![(base, base + self.down_us)];
        }
        let first = u64::from(self.leader.is_some());
        let per_period = self.slots.saturating_sub(first);
        let mut out = Vec::new();
        for s in 0..self.slots {
            let owner = if s < first {
                self.leader
            } else if self.followers.is_empty() {
                None
            } else {
                let g = p * per_period + (s - first);
                Some(self.followers[(g % self.followers.len() as u64) as usize])
            };
            if owner == Some(node) {
                let (start, len) = if s < first {
                    (base + self.down_us, self.leader_slot_us)
                } else {
                    let start = base + self.down_us + first * self.leader_slot_us;
                    (start + (s - first) * self.slot_us, self.slot_us)
                };
                out.push((start, start + len - self.guard_us));
            }
        }
        out
    }

    /// When `node` may start a frame of `air_us` at or after `t`; `None` if no slot of
    /// its holds such a frame.
    pub fn next_start(&self, node: NodeId, t: u64, air_us: u64) -> Option<u64> {
        let span = if node == 0 {
            self.down_us
        } else if Some(node) == self.leader {
            self.leader_slot_us - self.guard_us
        } else {
            self.slot_us - self.guard_us
        };
        if air_us > span {
            return None;
        }
        let horizon = self.cycle_periods().saturating_add(1).min(10_000);
        let p0 = t / PERIOD_US;
        (p0..p0 + horizon).find_map(|p| {
            self.windows(node, p).into_iter().find_map(|(start, end)| {
                let s = start.max(t);
                (s + air_us <= end).then_some(s)
            })
        })
    }
}
