//! One frame: header, payload, tag, COBS-encoded and delimited by `0x00`.

use postcard_schema::Schema;
use serde::{Deserialize, Serialize};

use crate::auth::FleetKey;
use crate::messages::Message;
use crate::{Reject, MAX_FRAME, PROTOCOL_VERSION, TAG_LEN};

/// Who sent a frame, or whom it is for. Append-only.
#[derive(
    Serialize, Deserialize, Schema, Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord,
)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Address {
    /// The base station.
    Base,
    /// A robot by its fleet id.
    Robot(u16),
    /// Every robot (a destination only).
    Broadcast,
}

/// As an operator reads it: `base`, `robot 2`, `broadcast`.
impl core::fmt::Display for Address {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Address::Base => f.write_str("base"),
            Address::Robot(id) => write!(f, "robot {id}"),
            Address::Broadcast => f.write_str("broadcast"),
        }
    }
}

/// The envelope in front of every payload, as sender and receiver know it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Header {
    /// Protocol version, three bits.
    pub version: u8,
    /// Message id, five bits.
    pub id: u8,
    pub from: Address,
    pub to: Address,
    /// Per (sender, destination stream) counter: broadcasts and each unicast peer count
    /// separately, so a receiver sees every number of its streams and can count loss.
    pub seq: u32,
    /// The sender's clock, milliseconds since its boot.
    pub time_ms: u32,
}

/// Low bits of [`Header::seq`] on the wire.
pub const SEQ_BITS: u32 = 8;
/// Low bits of [`Header::time_ms`] on the wire: 4.096 s, far beyond any frame's freshness.
pub const TIME_BITS: u32 = 12;
/// A receiver takes a frame's sequence number as at most this far behind the next it
/// expects (an older one is a replay whatever it resolves to); the rest of the span is
/// ahead: 223 frames may be lost in a row.
pub const SEQ_BEHIND: u32 = 32;
/// A receiver takes a frame's clock as at most this far behind its estimate of the
/// sender's clock, ms; the rest of the span (512 ms) covers a sender's clock ahead of it.
pub const TIME_BEHIND_MS: u32 = 3584;

/// The header as the wire carries it. Handshake frames carry whole values; every other
/// frame the low [`SEQ_BITS`] of its sequence number and [`TIME_BITS`] of its clock, which
/// the receiver completes from what it expects ([`WireHeader::resolve`]). The tag covers
/// the whole values, so a wrong completion fails it: nothing is ever misread.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WireHeader {
    pub version: u8,
    pub id: u8,
    pub from: Address,
    pub to: Address,
    /// Whole on handshake frames, its low [`SEQ_BITS`] otherwise.
    pub seq: u32,
    /// Whole on handshake frames, its low [`TIME_BITS`] otherwise.
    pub time_ms: u32,
    /// True when `seq` and `time_ms` are whole (a handshake frame).
    pub whole: bool,
}

/// What a receiver expects of a sender's next frame, to complete its header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Expect {
    /// The sender's session.
    pub session: u32,
    /// The next sequence number of the frame's stream (the last accepted plus one).
    pub seq: u32,
    /// The sender's clock now, as the receiver estimates it.
    pub time_ms: u32,
}

/// The value with these low `bits` in the span that starts `behind` before `near`.
pub fn complete(low: u32, bits: u32, near: u32, behind: u32) -> u32 {
    let mask = (1u32 << bits) - 1;
    let start = near.wrapping_sub(behind);
    start.wrapping_add(low.wrapping_sub(start) & mask)
}

impl WireHeader {
    /// The whole header: as carried when whole, else completed near what is expected (the
    /// stream's next number, the sender's clock now).
    pub fn resolve(&self, seq: u32, time_ms: u32) -> Header {
        self.with(self.seq_near(seq), self.time_near(time_ms))
    }

    /// The header with `seq` and `time_ms` as carried (low bits unless whole): for showing
    /// an unverified frame, never for acting on it.
    pub fn carried(&self) -> Header {
        self.with(self.seq, self.time_ms)
    }

    /// The whole sequence number, completed near the stream's next one unless carried whole.
    pub fn seq_near(&self, next: u32) -> u32 {
        if self.whole {
            self.seq
        } else {
            complete(self.seq, SEQ_BITS, next, SEQ_BEHIND)
        }
    }

    /// The sender's whole clock, completed near an estimate of it unless carried whole.
    pub fn time_near(&self, estimate_ms: u32) -> u32 {
        if self.whole {
            self.time_ms
        } else {
            complete(self.time_ms, TIME_BITS, estimate_ms, TIME_BEHIND_MS)
        }
    }

    fn with(&self, seq: u32, time_ms: u32) -> Header {
        Header {
            version: self.version,
            id: self.id,
            from: self.from,
            to: self.to,
            seq,
            time_ms,
        }
    }
}

/// An address's kind in the header's two-bit fields; a robot's id follows the word.
fn kind(a: Address) -> u32 {
    match a {
        Address::Base => 0,
        Address::Robot(_) => 1,
        Address::Broadcast => 2,
    }
}

/// Why a frame could not be built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EncodeError {
    /// Header + payload + tag exceed [`MAX_FRAME`].
    TooLarge,
    /// The output buffer is smaller than the encoded frame.
    BufferTooSmall,
    /// A unicast to an address that is not one of the link's peers.
    UnknownPeer,
}

impl core::error::Error for EncodeError {}

impl core::fmt::Display for EncodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            EncodeError::TooLarge => "frame larger than MAX_FRAME",
            EncodeError::BufferTooSmall => "output buffer too small",
            EncodeError::UnknownPeer => "destination is not a peer of this link",
        })
    }
}

/// Appends `value`, postcard-encoded, at `raw[*n..]`.
fn put<T: Serialize>(value: &T, raw: &mut [u8], n: &mut usize) -> Result<(), EncodeError> {
    let rest = raw.get_mut(*n..).ok_or(EncodeError::TooLarge)?;
    *n += postcard::to_slice(value, rest)
        .map_err(|_| EncodeError::TooLarge)?
        .len();
    Ok(())
}

/// Writes header and payload into `raw`, returning their length: the version and id
/// byte, a 24-bit little-endian word (destination kind, sender kind, the sequence
/// number's and the clock's low bits), the robot ids named by the kinds, on handshake
/// frames the high bits of sequence number and clock, then the payload.
fn write_body(header: &Header, message: &Message, raw: &mut [u8]) -> Result<usize, EncodeError> {
    let seq_low = header.seq & ((1 << SEQ_BITS) - 1);
    let time_low = header.time_ms & ((1 << TIME_BITS) - 1);
    let word = kind(header.to) | kind(header.from) << 2 | seq_low << 4 | time_low << 12;
    let first = [
        (PROTOCOL_VERSION << 5) | (message.id() & 0x1f),
        word as u8,
        (word >> 8) as u8,
        (word >> 16) as u8,
    ];
    raw.get_mut(..4)
        .ok_or(EncodeError::TooLarge)?
        .copy_from_slice(&first);
    let mut n = 4;
    for address in [header.from, header.to] {
        if let Address::Robot(id) = address {
            put(&id, raw, &mut n)?;
        }
    }
    if Message::is_handshake(message.id()) {
        put(&(header.seq >> SEQ_BITS), raw, &mut n)?;
        put(&(header.time_ms >> TIME_BITS), raw, &mut n)?;
    }
    let rest = raw.get_mut(n..).ok_or(EncodeError::TooLarge)?;
    let m = message
        .encode_payload(rest)
        .map_err(|_| EncodeError::TooLarge)?;
    Ok(n + m)
}

/// What the MAC covers besides a frame's bytes: its whole sequence number and clock.
fn stamp(header: &Header) -> [u8; 8] {
    let mut stamp = [0u8; 8];
    stamp[..4].copy_from_slice(&header.seq.to_le_bytes());
    stamp[4..].copy_from_slice(&header.time_ms.to_le_bytes());
    stamp
}

/// Builds a frame and writes it to `out` as COBS bytes followed by the `0x00` delimiter.
/// The header's version and id are taken from the protocol and the message.
pub fn seal(
    key: &FleetKey,
    session: u32,
    header: &Header,
    message: &Message,
    out: &mut [u8],
) -> Result<usize, EncodeError> {
    let mut raw = [0u8; MAX_FRAME];
    let body_len = write_body(header, message, &mut raw[..MAX_FRAME - TAG_LEN])?;
    let schema_key = Message::schema_key(message.id()).ok_or(EncodeError::TooLarge)?;
    let session = if Message::is_handshake(message.id()) {
        0
    } else {
        session
    };
    let tag = key.tag(&schema_key, session, &[&stamp(header), &raw[..body_len]]);
    raw[body_len..body_len + TAG_LEN].copy_from_slice(&tag);
    let n = cobs::try_encode(&raw[..body_len + TAG_LEN], out)
        .map_err(|_| EncodeError::BufferTooSmall)?;
    *out.get_mut(n).ok_or(EncodeError::BufferTooSmall)? = 0;
    Ok(n + 1)
}

/// Reads the header of a COBS-decoded frame without checking its tag. For routing and
/// diagnostics only: nothing in it is trusted until [`open`] verifies the tag.
pub fn peek_header(raw: &[u8]) -> Result<WireHeader, Reject> {
    split(raw).map(|(header, _)| header)
}

/// Takes one postcard value off the front of `bytes`.
fn take<'a, T: Deserialize<'a>>(bytes: &'a [u8]) -> Result<(T, &'a [u8]), Reject> {
    postcard::take_from_bytes(bytes).map_err(|_| Reject::Truncated)
}

/// The address of a header kind, taking a robot's id off `rest`.
fn address_of(kind: u32, rest: &mut &[u8]) -> Result<Address, Reject> {
    Ok(match kind {
        0 => Address::Base,
        1 => {
            let (id, tail) = take(rest)?;
            *rest = tail;
            Address::Robot(id)
        }
        2 => Address::Broadcast,
        _ => return Err(Reject::Truncated),
    })
}

/// `high` above `bits` low bits, if it fits in 32 bits.
fn join(high: u32, low: u32, bits: u32) -> Result<u32, Reject> {
    if high > u32::MAX >> bits {
        return Err(Reject::Truncated);
    }
    Ok(high << bits | low)
}

/// The header and the payload bytes of a COBS-decoded frame (tag unchecked).
fn split(raw: &[u8]) -> Result<(WireHeader, &[u8]), Reject> {
    if raw.len() < 4 + TAG_LEN {
        return Err(Reject::Truncated);
    }
    let version = raw[0] >> 5;
    let id = raw[0] & 0x1f;
    if version != PROTOCOL_VERSION {
        return Err(Reject::UnknownVersion);
    }
    if Message::schema_key(id).is_none() {
        return Err(Reject::UnknownMessage);
    }
    let word = u32::from(raw[1]) | u32::from(raw[2]) << 8 | u32::from(raw[3]) << 16;
    let mut rest = &raw[4..raw.len() - TAG_LEN];
    let from = address_of(word >> 2 & 3, &mut rest)?;
    let to = address_of(word & 3, &mut rest)?;
    let mut seq = word >> 4 & ((1 << SEQ_BITS) - 1);
    let mut time_ms = word >> 12;
    let whole = Message::is_handshake(id);
    if whole {
        let (seq_high, tail) = take::<u32>(rest)?;
        let (time_high, tail) = take::<u32>(tail)?;
        seq = join(seq_high, seq, SEQ_BITS)?;
        time_ms = join(time_high, time_ms, TIME_BITS)?;
        rest = tail;
    }
    let header = WireHeader {
        version,
        id,
        from,
        to,
        seq,
        time_ms,
        whole,
    };
    Ok((header, rest))
}

/// Decodes a COBS-decoded frame **without** checking its tag: for capture analysis
/// (`basestation decode` without the key). Never act on what it returns.
pub fn parse_unverified(raw: &[u8]) -> Result<(WireHeader, Message), Reject> {
    let (header, payload) = split(raw)?;
    Ok((header, Message::decode(header.id, payload)?))
}

/// Verifies and decodes a COBS-decoded frame. `expect` gives what the receiver expects
/// of the sender (its session, the stream's next sequence number, its clock now) or the
/// reason to refuse it; handshake frames carry whole values and skip it (session 0).
pub fn open(
    key: &FleetKey,
    raw: &[u8],
    expect: impl FnOnce(&WireHeader) -> Result<Expect, Reject>,
) -> Result<(Header, Message), Reject> {
    let (wire, payload) = split(raw)?;
    let body = &raw[..raw.len() - TAG_LEN];
    let tag = &raw[raw.len() - TAG_LEN..];
    let (session, header) = if wire.whole {
        (0, wire.carried())
    } else {
        let e = expect(&wire)?;
        (e.session, wire.resolve(e.seq, e.time_ms))
    };
    let schema_key = Message::schema_key(wire.id).ok_or(Reject::UnknownMessage)?;
    if !key.verify(&schema_key, session, &[&stamp(&header), body], tag) {
        return Err(Reject::BadTag);
    }
    let message = Message::decode(wire.id, payload)?;
    Ok((header, message))
}
