//! The radios a fleet shares one channel on: presets for the modems people use, each
//! overridable field by field in `[link]` (`docs/sim.md#a-shared-channel`). The figures
//! and their sources are in the docs; `crate::air` turns them into air time.

use serde::{Deserialize, Serialize};

use super::LinkSpec;

/// How nodes take the shared channel.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Access {
    /// Listen before talk: a node defers while it hears the channel busy, then backs off
    /// a random number of slots (what an unscheduled modem does).
    #[default]
    Csma,
    /// Send when there is something to send (pure ALOHA).
    Aloha,
    /// The base station's schedule: the downlink opens each 100 ms period, then the
    /// robots' uplink slots (the leader's every period, the followers' in turn).
    Scheduled,
}

impl Access {
    pub fn name(self) -> &'static str {
        match self {
            Access::Csma => "csma",
            Access::Aloha => "aloha",
            Access::Scheduled => "scheduled",
        }
    }
}

/// A modem's physical layer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Phy {
    /// A fixed-rate modem (FSK, 802.11 DSSS): `fec` coded bits per data bit, a
    /// per-frame `overhead_bytes` (preamble, sync, header, CRC) at the raw rate and a
    /// fixed `overhead_us` (PLCP preamble, turnaround).
    Rate {
        air_rate_bps: u32,
        fec: f64,
        overhead_bytes: u32,
        overhead_us: f64,
    },
    /// LoRa: Semtech's time-on-air formula (8-symbol preamble, explicit header, CRC,
    /// coding rate 4/5), plus `overhead_us` of turnaround.
    Lora {
        spreading_factor: u8,
        bandwidth_khz: u32,
        overhead_us: f64,
    },
}

/// A radio people build such fleets with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Preset {
    pub name: &'static str,
    pub what: &'static str,
    pub phy: Phy,
    /// The largest frame the modem sends in one piece, bytes.
    pub max_frame_bytes: u32,
    /// Carrier sensing: how long a node listens before it may send, µs (also the width
    /// of one backoff slot).
    pub sense_us: f64,
    /// Backoff window, slots.
    pub backoff_slots: u32,
}

/// The presets `[link] radio` names.
pub const PRESETS: &[Preset] = &[
    Preset {
        name: "sik-64k",
        what: "SiK-class FSK modem (HopeRF/RFD900) at its default 64 kbps air rate, Golay ECC",
        phy: Phy::Rate {
            air_rate_bps: 64_000,
            fec: 2.0,
            overhead_bytes: 13,
            overhead_us: 500.0,
        },
        max_frame_bytes: 252,
        sense_us: 1_000.0,
        backoff_slots: 16,
    },
    Preset {
        name: "multipoint-250k",
        what: "RFD900x multipoint firmware at 250 kbps air rate, Golay ECC",
        phy: Phy::Rate {
            air_rate_bps: 250_000,
            fec: 2.0,
            overhead_bytes: 13,
            overhead_us: 500.0,
        },
        max_frame_bytes: 252,
        sense_us: 500.0,
        backoff_slots: 16,
    },
    Preset {
        name: "lora-sf7-125",
        what: "LoRa SF7, 125 kHz, CR 4/5",
        phy: Phy::Lora {
            spreading_factor: 7,
            bandwidth_khz: 125,
            overhead_us: 1_000.0,
        },
        max_frame_bytes: 255,
        sense_us: 2_048.0,
        backoff_slots: 16,
    },
    Preset {
        name: "lora-sf7-250",
        what: "LoRa SF7, 250 kHz, CR 4/5",
        phy: Phy::Lora {
            spreading_factor: 7,
            bandwidth_khz: 250,
            overhead_us: 1_000.0,
        },
        max_frame_bytes: 255,
        sense_us: 1_024.0,
        backoff_slots: 16,
    },
    Preset {
        name: "lora-sf7-500",
        what: "LoRa SF7, 500 kHz, CR 4/5",
        phy: Phy::Lora {
            spreading_factor: 7,
            bandwidth_khz: 500,
            overhead_us: 1_000.0,
        },
        max_frame_bytes: 255,
        sense_us: 512.0,
        backoff_slots: 16,
    },
    Preset {
        name: "esp-now",
        what: "ESP-NOW broadcast: 802.11 at 1 Mbps, long preamble, vendor action frame",
        phy: Phy::Rate {
            air_rate_bps: 1_000_000,
            fec: 1.0,
            overhead_bytes: 47,
            overhead_us: 242.0,
        },
        max_frame_bytes: 250,
        sense_us: 20.0,
        backoff_slots: 32,
    },
];

/// The preset called `name`.
pub fn preset(name: &str) -> Option<&'static Preset> {
    PRESETS.iter().find(|p| p.name == name)
}

/// The presets' names, for messages.
pub fn preset_names() -> String {
    PRESETS
        .iter()
        .map(|p| format!("\"{}\"", p.name))
        .collect::<Vec<_>>()
        .join(", ")
}

/// One shared channel, as the file resolves it: the preset with its fields overridden.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Channel {
    pub preset: &'static Preset,
    pub phy: Phy,
    pub access: Access,
}

impl LinkSpec {
    /// The shared channel `[link]` describes (`None`: every transmitter has air of its
    /// own), or why not (field, message).
    pub fn channel(&self) -> Result<Option<Channel>, (&'static str, String)> {
        let Some(name) = &self.radio else {
            return match self.overrides().first() {
                Some(field) => Err((field, "needs `radio` (a preset) to override".into())),
                None => Ok(None),
            };
        };
        let preset = preset(name).ok_or_else(|| {
            (
                "link.radio",
                format!(
                    "unknown radio \"{name}\"; the presets are {}",
                    preset_names()
                ),
            )
        })?;
        let phy = self.overridden(preset.phy)?;
        Ok(Some(Channel {
            preset,
            phy,
            access: self.access,
        }))
    }

    fn overrides(&self) -> Vec<&'static str> {
        [
            (self.air_rate_bps.is_some(), "link.air_rate_bps"),
            (self.fec.is_some(), "link.fec"),
            (self.frame_overhead_us.is_some(), "link.frame_overhead_us"),
            (self.spreading_factor.is_some(), "link.spreading_factor"),
        ]
        .into_iter()
        .filter_map(|(set, field)| set.then_some(field))
        .collect()
    }

    fn overridden(&self, phy: Phy) -> Result<Phy, (&'static str, String)> {
        if self
            .frame_overhead_us
            .is_some_and(|v| !(v.is_finite() && v >= 0.0))
        {
            return Err((
                "link.frame_overhead_us",
                "must be a finite number ≥ 0".into(),
            ));
        }
        match phy {
            Phy::Rate {
                air_rate_bps,
                fec,
                overhead_bytes,
                overhead_us,
            } => {
                if self.spreading_factor.is_some() {
                    return Err(("link.spreading_factor", "only a LoRa radio has one".into()));
                }
                let air_rate_bps = self.air_rate_bps.unwrap_or(air_rate_bps);
                let fec = self.fec.unwrap_or(fec);
                if air_rate_bps == 0 {
                    return Err(("link.air_rate_bps", "must be > 0".into()));
                }
                if !(fec.is_finite() && (1.0..=4.0).contains(&fec)) {
                    return Err(("link.fec", "must be in [1, 4] coded bits per bit".into()));
                }
                Ok(Phy::Rate {
                    air_rate_bps,
                    fec,
                    overhead_bytes,
                    overhead_us: self.frame_overhead_us.unwrap_or(overhead_us),
                })
            }
            Phy::Lora {
                spreading_factor,
                bandwidth_khz,
                overhead_us,
            } => {
                if self.air_rate_bps.is_some() || self.fec.is_some() {
                    let field = if self.fec.is_some() {
                        "link.fec"
                    } else {
                        "link.air_rate_bps"
                    };
                    return Err((
                        field,
                        "a LoRa radio's rate follows its spreading factor".into(),
                    ));
                }
                let spreading_factor = self.spreading_factor.unwrap_or(spreading_factor);
                if !(7..=12).contains(&spreading_factor) {
                    return Err(("link.spreading_factor", "must be 7 to 12".into()));
                }
                Ok(Phy::Lora {
                    spreading_factor,
                    bandwidth_khz,
                    overhead_us: self.frame_overhead_us.unwrap_or(overhead_us),
                })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_preset_resolves_with_its_fields_overridden() {
        let t = LinkSpec {
            radio: Some("sik-64k".into()),
            air_rate_bps: Some(128_000),
            ..Default::default()
        };
        let c = t.channel().unwrap().unwrap();
        let Phy::Rate {
            air_rate_bps, fec, ..
        } = c.phy
        else {
            panic!("a fixed-rate radio");
        };
        assert_eq!((air_rate_bps, fec), (128_000, 2.0));
    }

    #[test]
    fn bad_channels_name_their_field() {
        let unknown = LinkSpec {
            radio: Some("wifi".into()),
            ..Default::default()
        };
        let (field, msg) = unknown.channel().unwrap_err();
        assert_eq!(field, "link.radio");
        assert!(msg.contains("sik-64k") && msg.contains("esp-now"), "{msg}");
        let orphan = LinkSpec {
            fec: Some(2.0),
            ..Default::default()
        };
        assert_eq!(orphan.channel().unwrap_err().0, "link.fec");
        let lora_rate = LinkSpec {
            radio: Some("lora-sf7-125".into()),
            air_rate_bps: Some(9_600),
            ..Default::default()
        };
        assert_eq!(lora_rate.channel().unwrap_err().0, "link.air_rate_bps");
        assert_eq!(LinkSpec::default().channel(), Ok(None));
    }
}
