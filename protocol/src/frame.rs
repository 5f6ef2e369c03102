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

/// The envelope in front of every payload.
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

/// The addressing part of the header, postcard-encoded after the first byte.
#[derive(Serialize, Deserialize)]
struct Route {
    from: Address,
    to: Address,
    seq: u32,
    time_ms: u32,
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

/// Writes header and payload into `raw`, returning their length.
fn write_body(header: &Header, message: &Message, raw: &mut [u8]) -> Result<usize, EncodeError> {
    let (first, rest) = raw.split_first_mut().ok_or(EncodeError::TooLarge)?;
    *first = (PROTOCOL_VERSION << 5) | (message.id() & 0x1f);
    let route = Route {
        from: header.from,
        to: header.to,
        seq: header.seq,
        time_ms: header.time_ms,
    };
    let n = postcard::to_slice(&route, rest)
        .map_err(|_| EncodeError::TooLarge)?
        .len();
    let m = message
        .encode_payload(&mut rest[n..])
        .map_err(|_| EncodeError::TooLarge)?;
    Ok(1 + n + m)
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
    let tag = key.tag(&schema_key, session, &raw[..body_len]);
    raw[body_len..body_len + TAG_LEN].copy_from_slice(&tag);
    let n = cobs::try_encode(&raw[..body_len + TAG_LEN], out)
        .map_err(|_| EncodeError::BufferTooSmall)?;
    *out.get_mut(n).ok_or(EncodeError::BufferTooSmall)? = 0;
    Ok(n + 1)
}

/// Reads the header of a COBS-decoded frame without checking its tag. For routing and
/// diagnostics only: nothing in it is trusted until [`open`] verifies the tag.
pub fn peek_header(raw: &[u8]) -> Result<Header, Reject> {
    split(raw).map(|(header, _)| header)
}

/// The header and the payload bytes of a COBS-decoded frame (tag unchecked).
fn split(raw: &[u8]) -> Result<(Header, &[u8]), Reject> {
    if raw.len() < 1 + 4 + TAG_LEN {
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
    let body = &raw[1..raw.len() - TAG_LEN];
    let (route, payload) =
        postcard::take_from_bytes::<Route>(body).map_err(|_| Reject::Truncated)?;
    let header = Header {
        version,
        id,
        from: route.from,
        to: route.to,
        seq: route.seq,
        time_ms: route.time_ms,
    };
    Ok((header, payload))
}

/// Decodes a COBS-decoded frame **without** checking its tag: for capture analysis
/// (`basestation decode` without the key). Never act on what it returns.
pub fn parse_unverified(raw: &[u8]) -> Result<(Header, Message), Reject> {
    let (header, payload) = split(raw)?;
    Ok((header, Message::decode(header.id, payload)?))
}

/// Verifies and decodes a COBS-decoded frame. `session_of` gives the sender's session
/// (handshake messages use 0 and skip it) or the reason to refuse the sender.
pub fn open(
    key: &FleetKey,
    raw: &[u8],
    session_of: impl FnOnce(&Header) -> Result<u32, Reject>,
) -> Result<(Header, Message), Reject> {
    let (header, payload) = split(raw)?;
    let body = &raw[..raw.len() - TAG_LEN];
    let tag = &raw[raw.len() - TAG_LEN..];
    let session = if Message::is_handshake(header.id) {
        0
    } else {
        session_of(&header)?
    };
    let schema_key = Message::schema_key(header.id).ok_or(Reject::UnknownMessage)?;
    if !key.verify(&schema_key, session, body, tag) {
        return Err(Reject::BadTag);
    }
    let message = Message::decode(header.id, payload)?;
    Ok((header, message))
}
