//! Every message that crosses the radio. Fields are positional on the wire: append new
//! messages and new enum variants only; a field change changes the message's schema key
//! and so its tag, and old peers reject it as `bad_tag` instead of misreading it.

use postcard_schema::{key::Key, Schema};
use serde::{Deserialize, Serialize};

use crate::units::{self, NonFinite};
use crate::Reject;

/// A message that can be the payload of a frame.
pub trait Payload: Serialize + for<'de> Deserialize<'de> + Schema {
    /// Message id: five bits in the frame's first byte. Append-only.
    const ID: u8;
    /// Hash of the message's path, protocol version and schema, folded into the tag.
    const SCHEMA_KEY: [u8; 8];
    /// Wraps the payload in the [`Message`] enum.
    fn into_message(self) -> Message;
}

/// A planar pose: position in millimetres, heading in 1/16384 turn.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WirePose {
    pub x_mm: i32,
    pub y_mm: i32,
    pub heading: u16,
}

impl WirePose {
    pub fn from_si(x: f32, y: f32, heading: f32) -> Result<Self, NonFinite> {
        Ok(Self {
            x_mm: units::metres_to_mm(x)?,
            y_mm: units::metres_to_mm(y)?,
            heading: units::angle_to_wire(heading)?,
        })
    }

    /// `(x, y, heading)` in metres and radians, heading in (-π, π].
    pub fn to_si(&self) -> (f32, f32, f32) {
        (
            units::mm_to_metres(self.x_mm),
            units::mm_to_metres(self.y_mm),
            units::angle_from_wire(self.heading),
        )
    }
}

/// A velocity pair in three bytes: v in mm/s and ω in mrad/s, twelve bits each (two's
/// complement, v in the low bits), saturating at ±[`WireTwist::LIMIT`]: the leader-state
/// frame's budget. JSON shows it as `{"v_mm_s", "omega_mrad_s"}`.
#[derive(Schema, Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WireTwist([u8; 3]);

impl WireTwist {
    /// The largest |v| (mm/s) and |ω| (mrad/s) carried.
    pub const LIMIT: i16 = 2047;

    pub fn new(v_mm_s: i16, omega_mrad_s: i16) -> Self {
        let bits = |x: i16| (x.clamp(-Self::LIMIT, Self::LIMIT) as u16 & 0xfff) as u32;
        let word = bits(v_mm_s) | bits(omega_mrad_s) << 12;
        Self([word as u8, (word >> 8) as u8, (word >> 16) as u8])
    }

    /// From SI units (m/s, rad/s).
    pub fn from_si(v: f32, omega: f32) -> Result<Self, NonFinite> {
        Ok(Self::new(
            units::to_milli_i16(v)?,
            units::to_milli_i16(omega)?,
        ))
    }

    fn word(&self) -> u32 {
        u32::from(self.0[0]) | u32::from(self.0[1]) << 8 | u32::from(self.0[2]) << 16
    }

    /// Twelve bits sign-extended.
    fn signed(bits: u32) -> i16 {
        ((bits as u16) << 4) as i16 >> 4
    }

    pub fn v_mm_s(&self) -> i16 {
        Self::signed(self.word() & 0xfff)
    }

    pub fn omega_mrad_s(&self) -> i16 {
        Self::signed(self.word() >> 12)
    }
}

/// Packed on the wire; as two named integers where people read it (JSON).
impl Serialize for WireTwist {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        if s.is_human_readable() {
            let mut st = s.serialize_struct("WireTwist", 2)?;
            st.serialize_field("v_mm_s", &self.v_mm_s())?;
            st.serialize_field("omega_mrad_s", &self.omega_mrad_s())?;
            st.end()
        } else {
            s.serialize_newtype_struct("WireTwist", &self.0)
        }
    }
}

impl<'de> Deserialize<'de> for WireTwist {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        struct Named {
            v_mm_s: i16,
            omega_mrad_s: i16,
        }
        #[derive(Deserialize)]
        struct Packed([u8; 3]);
        if d.is_human_readable() {
            Named::deserialize(d).map(|n| Self::new(n.v_mm_s, n.omega_mrad_s))
        } else {
            Packed::deserialize(d).map(|p| Self(p.0))
        }
    }
}

/// The leader's state, broadcast by the base station at 10 Hz. The pose is valid at the
/// frame's timestamp (the base station predicts it to its send time).
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LeaderState {
    pub pose: WirePose,
    /// The leader's v and ω.
    pub twist: WireTwist,
    /// Formation blend: 0 = wide slots, 255 = line slots, in between = transforming.
    pub blend: u8,
}

/// Base station → leader: the velocity to drive now.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct VelocityCommand {
    pub v_mm_s: i16,
    pub omega_mrad_s: i16,
}

/// Localization → a robot: where the robot was at the frame's timestamp.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PoseFix {
    pub pose: WirePose,
    /// One-sigma position uncertainty.
    pub sigma_mm: u16,
}

/// What a robot is doing. Append-only.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RobotMode {
    #[default]
    Idle,
    Joining,
    InFormation,
    Transforming,
    Failsafe,
    Leading,
    EmergencyStop,
}

/// Link health as one receiver sees it.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LinkCounters {
    pub received: u32,
    pub rejected: u32,
    /// Gaps in the sequence numbers of accepted frames.
    pub lost: u32,
}

/// Fault flags in [`Telemetry::faults`]. Append-only bits.
pub mod faults {
    pub const LEADER_STATE_STALE: u16 = 1 << 0;
    pub const COMMAND_STALE: u16 = 1 << 1;
    pub const NON_FINITE_INPUT: u16 = 1 << 2;
    pub const WHEEL_STALL_LEFT: u16 = 1 << 3;
    pub const WHEEL_STALL_RIGHT: u16 = 1 << 4;
    pub const POSE_FIX_STALE: u16 = 1 << 5;
    pub const POSE_FIX_REJECTED: u16 = 1 << 6;
    pub const EMERGENCY_STOP: u16 = 1 << 7;
    pub const NOT_LINKED: u16 = 1 << 8;
    /// No pose fix yet since boot: the telemetry's pose means nothing.
    pub const NOT_LOCALIZED: u16 = 1 << 9;
}

/// Robot → base station, 10 Hz.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Telemetry {
    pub pose: WirePose,
    /// Measured wheel speeds, left then right.
    pub wheel_mm_s: [i16; 2],
    pub mode: RobotMode,
    /// Distance from the control point to the slot reference point (followers).
    pub tracking_error_mm: u16,
    pub faults: u16,
    pub link: LinkCounters,
}

/// A slot relative to the leader: distance L and bearing φ from the leader's heading.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Slot {
    pub distance_mm: u16,
    pub bearing: u16,
}

impl Slot {
    pub fn from_si(distance: f32, bearing: f32) -> Result<Self, NonFinite> {
        Ok(Self {
            distance_mm: units::to_mm_u16(distance)?,
            bearing: units::angle_to_wire(bearing)?,
        })
    }

    /// `(L, φ)` in metres and radians.
    pub fn to_si(&self) -> (f32, f32) {
        (
            units::from_mm_u16(self.distance_mm),
            units::angle_from_wire(self.bearing),
        )
    }
}

/// Base station → one follower: its slot in the wide formation and in the line.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FormationCommand {
    /// Number of followers in the formation.
    pub followers: u16,
    /// This follower's index, 0-based (its line slot is (index + 1)·D behind).
    pub index: u16,
    pub wide: Slot,
    pub line: Slot,
    /// Send telemetry every this many control periods (0 and 1: every period): the
    /// station spreads a shared channel's air over a larger fleet.
    pub report_every: u8,
}

/// Base station → one follower: make for this point (site frame, mm) instead of the slot,
/// to go round what holds it there. Renewed every period while it lasts; a follower that
/// hears none for a while goes back to its slot.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Detour {
    pub x_mm: i32,
    pub y_mm: i32,
}

/// Keeps a link alive when there is nothing else to say.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Heartbeat {
    pub status: u8,
}

/// Brake to a stop and hold; cleared by the next valid leader state or command.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Stop {
    pub reason: u8,
}

/// Brake at once and latch until [`Resume`].
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EmergencyStop {
    pub reason: u8,
}

/// Clears a latched emergency stop.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Resume {
    pub reason: u8,
}

/// Handshake challenge: "tell me your session". Tagged with session 0.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Hello {
    pub nonce: u64,
}

/// Handshake answer, bound to the challenge's nonce. Tagged with session 0.
#[derive(Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Welcome {
    pub nonce: u64,
    /// The sender's session: every later frame of its is tagged with it.
    pub session: u32,
    /// The sender's latest broadcast sequence number: older broadcasts are replays.
    pub broadcast_seq: u32,
}

/// Where a message may be addressed: the wire table's third column.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Destination {
    /// To every robot (broadcast key) or to one (its own key).
    Any,
    /// To one node only, under its own key: a broadcast of it is refused, so the broadcast
    /// key every robot holds cannot forge it.
    Unicast,
}

macro_rules! messages {
    ($($id:literal => $name:ident, $path:literal, $dest:ident;)*) => {
        /// Any message, for dispatch after decoding.
        #[derive(Debug, Clone, Copy, PartialEq, Serialize)]
        #[cfg_attr(feature = "defmt", derive(defmt::Format))]
        pub enum Message {
            $($name($name),)*
        }

        $(
            impl Payload for $name {
                const ID: u8 = $id;
                const SCHEMA_KEY: [u8; 8] = Key::for_path::<$name>($path).to_bytes();
                fn into_message(self) -> Message {
                    Message::$name(self)
                }
            }
        )*

        impl Message {
            /// Every message id, with its name.
            pub const ALL: &'static [(u8, &'static str)] = &[$(($id, stringify!($name)),)*];

            pub fn id(&self) -> u8 {
                match self {
                    $(Message::$name(_) => $id,)*
                }
            }

            pub fn name(&self) -> &'static str {
                match self {
                    $(Message::$name(_) => stringify!($name),)*
                }
            }

            /// Where a message id may be addressed (`None`: an unknown id).
            pub fn destination(id: u8) -> Option<Destination> {
                match id {
                    $($id => Some(Destination::$dest),)*
                    _ => None,
                }
            }

            /// Every message id with its schema key: a table, not a `match` (a match
            /// built each key in code: 212 B of the robot's flash, the table 108 B).
            const SCHEMA_KEYS: &'static [(u8, [u8; 8])] =
                &[$(($id, <$name as Payload>::SCHEMA_KEY),)*];

            /// The schema key for a message id, or `None` for an unknown id.
            pub fn schema_key(id: u8) -> Option<[u8; 8]> {
                Self::SCHEMA_KEYS
                    .iter()
                    .find(|(known, _)| *known == id)
                    .map(|(_, key)| *key)
            }

            /// Decodes a payload whose id is already known to exist; the whole slice
            /// must be consumed.
            pub fn decode(id: u8, bytes: &[u8]) -> Result<Message, Reject> {
                match id {
                    $($id => {
                        let (m, rest) = postcard::take_from_bytes::<$name>(bytes)
                            .map_err(|_| Reject::Malformed)?;
                        if rest.is_empty() { Ok(Message::$name(m)) } else { Err(Reject::Malformed) }
                    })*
                    _ => Err(Reject::UnknownMessage),
                }
            }

            /// Serializes the payload into `out`, returning the bytes written.
            pub fn encode_payload(&self, out: &mut [u8]) -> Result<usize, postcard::Error> {
                match self {
                    $(Message::$name(m) => postcard::to_slice(m, out).map(|s| s.len()),)*
                }
            }
        }
    };
}

// id => message, schema path, destination. Only what every robot must hear at once may
// be broadcast; whatever drives or places one robot is unicast under that robot's key.
messages! {
    0 => LeaderState, "sweeper/v1/leader_state", Any;
    1 => VelocityCommand, "sweeper/v1/velocity_command", Unicast;
    2 => PoseFix, "sweeper/v1/pose_fix", Unicast;
    3 => Telemetry, "sweeper/v1/telemetry", Unicast;
    4 => FormationCommand, "sweeper/v1/formation_command", Unicast;
    5 => Heartbeat, "sweeper/v1/heartbeat", Any;
    6 => Stop, "sweeper/v1/stop", Any;
    7 => EmergencyStop, "sweeper/v1/emergency_stop", Any;
    8 => Resume, "sweeper/v1/resume", Any;
    9 => Hello, "sweeper/v1/hello", Unicast;
    10 => Welcome, "sweeper/v1/welcome", Unicast;
    11 => Detour, "sweeper/v1/detour", Unicast;
}

impl Message {
    /// Handshake messages are tagged with session 0: they are bound to a nonce instead.
    pub fn is_handshake(id: u8) -> bool {
        id == Hello::ID || id == Welcome::ID
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_dense_and_keys_distinct() {
        for (i, (id, _)) in Message::ALL.iter().enumerate() {
            assert_eq!(*id as usize, i);
            assert!(*id < 32, "ids must fit five bits");
        }
        for (a, _) in Message::ALL {
            for (b, _) in Message::ALL {
                if a != b {
                    assert_ne!(Message::schema_key(*a), Message::schema_key(*b));
                }
            }
        }
    }
}
