//! The radio protocol shared by the base station and the robots.
//!
//! A frame on the byte stream is `COBS(header ‖ payload ‖ tag) ‖ 0x00`:
//!
//! - [`frame::Header`]: protocol version and message id in one byte, sender, destination,
//!   a per-stream sequence number and the sender's clock in milliseconds;
//! - the payload: one [`messages`] struct, postcard-encoded, fixed-point SI units;
//! - a 64-bit BLAKE2s tag over the message's schema key (CRC_EXTRA-style: a schema change
//!   breaks the tag), the sender's session and the header and payload bytes, keyed by the
//!   broadcast key or by the robot's own key (both derived from the fleet's
//!   [`auth::MasterKey`]).
//!
//! [`link::Link`] adds sessions, the handshake and replay protection on top; see
//! `docs/protocol.md` for the wire format byte by byte and the threat model.
//!
//! Decoding untrusted bytes never panics and never allocates: every rejected frame has a
//! [`Reject`] reason that the receiver counts.
#![cfg_attr(not(feature = "std"), no_std)]
#![deny(unsafe_code)]

#[cfg(test)]
extern crate std;

pub mod auth;
pub mod body;
pub mod config_page;
pub mod frame;
pub mod link;
pub mod messages;
pub mod stream;
pub mod units;

pub use auth::{FleetKey, MasterKey};
pub use frame::{Address, Header};
pub use link::{Event, Link};
pub use messages::Message;
pub use stream::FrameDecoder;

/// Protocol version, carried in the top three bits of every frame's first byte.
pub const PROTOCOL_VERSION: u8 = 2;
/// Bytes of the authentication tag at the end of every frame.
pub const TAG_LEN: usize = 8;
/// Largest frame before COBS encoding (header + payload + tag).
pub const MAX_FRAME: usize = 96;
/// Largest frame on the wire: COBS adds one byte per 254 plus one, and the delimiter.
pub const MAX_WIRE: usize = MAX_FRAME + MAX_FRAME / 254 + 2;

/// Why a receiver dropped a frame. Append-only: the numbering is in telemetry and reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum Reject {
    /// The bytes between two delimiters are not valid COBS.
    BadCobs = 0,
    /// More bytes than [`MAX_WIRE`] before a delimiter.
    TooLong = 1,
    /// Too short to hold a header and a tag, or a header that does not parse.
    Truncated = 2,
    /// A protocol version this build does not speak.
    UnknownVersion = 3,
    /// A message id this build does not know.
    UnknownMessage = 4,
    /// The tag does not verify: wrong key, forged, corrupted, or a different schema.
    BadTag = 5,
    /// The sender's session is unknown here (no handshake yet).
    UnknownSession = 6,
    /// A sequence number not newer than one already accepted, or a handshake answer
    /// to a challenge this receiver did not send.
    Replay = 7,
    /// The tag verifies but the payload does not decode as the message it claims to be.
    Malformed = 8,
    /// Authentic but too old by the sender's clock (a delaying relay, or a handshake whose
    /// round trip is too long to trust the clock offset it gives).
    Stale = 9,
    /// Authentic, but broadcast where only a unicast is accepted (a robot holding the
    /// broadcast key forging a command for another).
    WrongDestination = 10,
}

impl Reject {
    /// Every reason, in wire order.
    pub const ALL: [Reject; 11] = [
        Reject::BadCobs,
        Reject::TooLong,
        Reject::Truncated,
        Reject::UnknownVersion,
        Reject::UnknownMessage,
        Reject::BadTag,
        Reject::UnknownSession,
        Reject::Replay,
        Reject::Malformed,
        Reject::Stale,
        Reject::WrongDestination,
    ];

    /// A short snake_case name for logs and reports.
    pub const fn name(self) -> &'static str {
        match self {
            Reject::BadCobs => "bad_cobs",
            Reject::TooLong => "too_long",
            Reject::Truncated => "truncated",
            Reject::UnknownVersion => "unknown_version",
            Reject::UnknownMessage => "unknown_message",
            Reject::BadTag => "bad_tag",
            Reject::UnknownSession => "unknown_session",
            Reject::Replay => "replay",
            Reject::Malformed => "malformed",
            Reject::Stale => "stale",
            Reject::WrongDestination => "wrong_destination",
        }
    }
}

impl core::error::Error for Reject {}

impl core::fmt::Display for Reject {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

/// Counts of rejected frames, one per [`Reject`] reason.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RejectCounts(pub [u32; Reject::ALL.len()]);

impl RejectCounts {
    pub fn count(&mut self, reason: Reject) {
        let slot = &mut self.0[reason as usize];
        *slot = slot.saturating_add(1);
    }

    pub fn get(&self, reason: Reject) -> u32 {
        self.0[reason as usize]
    }

    pub fn total(&self) -> u32 {
        self.0.iter().fold(0u32, |a, b| a.saturating_add(*b))
    }

    /// Adds another set of counts into this one.
    pub fn merge(&mut self, other: &RejectCounts) {
        for (a, b) in self.0.iter_mut().zip(other.0.iter()) {
            *a = a.saturating_add(*b);
        }
    }
}
