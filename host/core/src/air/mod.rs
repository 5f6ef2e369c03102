//! A shared channel's air: how long a frame occupies it (a fixed-rate modem's bits, or
//! LoRa's time-on-air formula from the `lora-modulation` crate), and the base station's
//! schedule of it.

mod schedule;

use lora_modulation::{Bandwidth, BaseBandModulationParams, CodingRate, SpreadingFactor};

use crate::scenario::radio::{Access, Channel, Phy};
use crate::scenario::{Role, Scenario};

pub use schedule::Schedule;

/// A node on the channel: 0 is the base station, then the robots.
pub type NodeId = usize;

/// The schedule's period: the station's 10 Hz leader-state broadcast.
pub const PERIOD_US: u64 = 100_000;
/// The largest uplink frame a slot is cut for (a telemetry frame is at most 38 B).
pub const UPLINK_FRAME_BYTES: usize = 40;
/// Frames one uplink slot holds: a report and one more (a handshake, an answer), so a
/// robot's own traffic never outgrows its slot and backs up in its modem.
pub const UPLINK_FRAMES: usize = 2;
/// The downlink's frames per period: leader state, the leader's command, one more; and
/// one per ten followers (each has its slots sent once a second).
pub const DOWNLINK_FRAMES: usize = 3;
/// A downlink frame as the schedule plans it: a leader state (26 B within 1 km of the
/// site's origin); the others average no more, and the downlink takes what is left.
pub const DOWNLINK_FRAME_BYTES: usize = 26;

/// Followers report at most this seldom: 5 s between reports.
const MAX_REPORT_EVERY: u64 = 50;
/// Unscheduled, the offered load is kept at or under this share of the air: past it
/// listening first no longer keeps collisions rare.
const UNSCHEDULED_LOAD: f64 = 0.5;

/// How often the followers report (periods) so that the channel carries the fleet: with
/// the station's schedule, once per turn of their slots; unscheduled, the fewest periods
/// that keep the offered load under `UNSCHEDULED_LOAD`; every period without a shared
/// channel. The leader reports every period (its state is the followers' reference).
pub fn follower_report_every(s: &Scenario) -> u8 {
    let Ok(Some(channel)) = s.link.channel() else {
        return 1;
    };
    let every = match channel.access {
        Access::Scheduled => Schedule::of(channel, s.robots.len(), leader_node(s)).report_every(),
        Access::Csma | Access::Aloha => {
            let load = PeriodLoad::of(&Air::new(channel), s.robots.len());
            let room = UNSCHEDULED_LOAD * PERIOD_US as f64 - load.fixed_us;
            if room <= 0.0 {
                MAX_REPORT_EVERY
            } else {
                (load.reports_us / room).ceil() as u64
            }
        }
    };
    every.clamp(1, MAX_REPORT_EVERY) as u8
}

/// The leader's node on the channel (robot `i` of the scenario is node `i + 1`).
pub fn leader_node(s: &Scenario) -> Option<NodeId> {
    s.robots
        .iter()
        .position(|r| r.role == Role::Leader)
        .map(|i| i + 1)
}

/// The air a period's regular traffic takes, µs: the leader state and the leader's
/// command down and the leader's report (`fixed_us`), and one report from each follower
/// (`reports_us`, spread over `report_every` periods where they report less often).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PeriodLoad {
    pub fixed_us: f64,
    pub reports_us: f64,
}

impl PeriodLoad {
    /// For a fleet of `robots`, one of them the leader.
    pub fn of(air: &Air, robots: usize) -> Self {
        let up = air.us(UPLINK_FRAME_BYTES);
        Self {
            fixed_us: (2 * air.us(DOWNLINK_FRAME_BYTES) + up) as f64,
            reports_us: robots.saturating_sub(1) as f64 * up as f64,
        }
    }

    /// The share of the air it takes with every robot reporting every period.
    pub fn share(&self) -> f64 {
        (self.fixed_us + self.reports_us) / PERIOD_US as f64
    }
}

/// Air time of a frame.
#[derive(Debug, Clone, Copy)]
pub struct Air(Channel);

impl Air {
    pub fn new(channel: Channel) -> Self {
        Self(channel)
    }

    /// Air time of a frame of `bytes`, µs: a fixed-rate modem's coded bits and
    /// per-frame overhead, or LoRa's time-on-air formula; each plus its fixed overhead.
    pub fn us(&self, bytes: usize) -> u64 {
        match self.0.phy {
            Phy::Rate {
                air_rate_bps,
                fec,
                overhead_bytes,
                overhead_us,
            } => {
                let bits = bytes as f64 * 8.0 * fec + f64::from(overhead_bytes) * 8.0;
                (bits / f64::from(air_rate_bps) * 1e6 + overhead_us).ceil() as u64
            }
            Phy::Lora {
                spreading_factor,
                bandwidth_khz,
                overhead_us,
            } => lora_us(spreading_factor, bandwidth_khz, bytes) + overhead_us.ceil() as u64,
        }
    }
}

/// Semtech's time on air: 8-symbol preamble, explicit header, CRC, coding rate 4/5.
fn lora_us(spreading_factor: u8, bandwidth_khz: u32, bytes: usize) -> u64 {
    let sf = match spreading_factor {
        7 => SpreadingFactor::_7,
        8 => SpreadingFactor::_8,
        9 => SpreadingFactor::_9,
        10 => SpreadingFactor::_10,
        11 => SpreadingFactor::_11,
        _ => SpreadingFactor::_12,
    };
    let bw = match bandwidth_khz {
        125 => Bandwidth::_125KHz,
        250 => Bandwidth::_250KHz,
        _ => Bandwidth::_500KHz,
    };
    let params = BaseBandModulationParams::new(sf, bw, CodingRate::_4_5);
    u64::from(params.time_on_air_us(Some(8), true, bytes.min(255) as u8))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::radio::{preset, Access};

    fn channel(name: &str) -> Channel {
        let preset = preset(name).expect("a preset");
        Channel {
            preset,
            phy: preset.phy,
            access: Access::Csma,
        }
    }

    #[test]
    fn a_fixed_rate_frame_costs_its_coded_bits_and_overhead() {
        // 40 B on sik-64k: 640 coded bits + 104 overhead bits at 64 kbps, plus 0.5 ms.
        let us = Air::new(channel("sik-64k")).us(40);
        assert_eq!(us, (744.0_f64 / 64_000.0 * 1e6 + 500.0).ceil() as u64);
    }

    #[test]
    fn lora_air_time_follows_semtechs_formula() {
        let air = Air::new(channel("lora-sf7-125"));
        // 32 B at SF7/125 kHz: about 72 ms (field notes), plus 1 ms of turnaround.
        let us = air.us(32);
        assert!((70_000..75_000).contains(&us), "{us}");
        let fast = Air::new(channel("lora-sf7-500")).us(32);
        assert!((17_000..21_000).contains(&fast), "{fast}");
    }
}
