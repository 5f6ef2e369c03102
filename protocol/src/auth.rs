//! Frame authentication: a 64-bit BLAKE2s MAC keyed by a pre-shared key.
//!
//! BLAKE2s is built from 32-bit additions, rotations and xors: fast on a Cortex-M4, no
//! tables, constant time. Its keyed mode is a MAC by design (no HMAC wrapper), and the
//! 8-byte output is a real parameter of the hash, not a truncation.
//!
//! Keys: the fleet's [`MasterKey`] stays with the base station and the provisioning tool.
//! From it come the **broadcast key** (frames to [`Address::Broadcast`], which every robot
//! holds) and one **robot key** per robot (the handshake and every unicast frame between
//! the base station and that robot, both ways). A robot holds the broadcast key and its
//! own key only: taken apart, it can forge broadcasts, not another robot's frames nor the
//! base station's unicasts to another robot.
//!
//! [`Address::Broadcast`]: crate::Address::Broadcast

use blake2::digest::{
    consts::{U32, U8},
    KeyInit, Mac,
};
use blake2::Blake2sMac;
use zeroize::Zeroize;

use crate::TAG_LEN;

type Mac64 = Blake2sMac<U8>;

/// A 256-bit frame key. It never travels over the air and is never printed; on std hosts
/// its state is zeroed when dropped (blake2's `zeroize`, with the `std` feature).
#[derive(Clone)]
pub struct FleetKey {
    /// The MAC with the key block already absorbed; cloned for every frame.
    keyed: Mac64,
}

/// A fleet key that is not 64 hexadecimal digits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BadKey;

impl core::error::Error for BadKey {}

impl core::fmt::Display for BadKey {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("a fleet key is 64 hexadecimal digits (32 bytes)")
    }
}

impl FleetKey {
    pub fn from_bytes(bytes: &[u8; 32]) -> Self {
        Self {
            keyed: <Mac64 as KeyInit>::new_from_slice(bytes).expect("32 bytes is a valid key"),
        }
    }

    /// Parses 64 hexadecimal digits (surrounding whitespace allowed).
    pub fn from_hex(text: &str) -> Result<Self, BadKey> {
        let mut bytes = key_bytes_from_hex(text)?;
        let key = Self::from_bytes(&bytes);
        bytes.zeroize();
        Ok(key)
    }

    fn mac(&self, schema_key: &[u8; 8], session: u32, parts: &[&[u8]]) -> Mac64 {
        let mut mac = self.keyed.clone();
        mac.update(schema_key);
        mac.update(&session.to_le_bytes());
        for part in parts {
            mac.update(part);
        }
        mac
    }

    /// The tag over a frame's parts (what the receiver knows of the frame besides its
    /// bytes, then the bytes), in order.
    pub fn tag(&self, schema_key: &[u8; 8], session: u32, parts: &[&[u8]]) -> [u8; TAG_LEN] {
        let mut tag = [0u8; TAG_LEN];
        tag.copy_from_slice(&self.mac(schema_key, session, parts).finalize().into_bytes());
        tag
    }

    /// Checks a tag in constant time.
    pub fn verify(&self, schema_key: &[u8; 8], session: u32, parts: &[&[u8]], tag: &[u8]) -> bool {
        self.mac(schema_key, session, parts)
            .verify_slice(tag)
            .is_ok()
    }
}

impl core::fmt::Debug for FleetKey {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("FleetKey(<secret>)")
    }
}

/// The 32 bytes of a key written as 64 hexadecimal digits (surrounding whitespace
/// allowed). Zero them when done.
pub fn key_bytes_from_hex(text: &str) -> Result<[u8; 32], BadKey> {
    let text = text.trim().as_bytes();
    if text.len() != 64 {
        return Err(BadKey);
    }
    let mut bytes = [0u8; 32];
    for (i, pair) in text.chunks_exact(2).enumerate() {
        match (hex_digit(pair[0]), hex_digit(pair[1])) {
            (Some(hi), Some(lo)) => bytes[i] = hi << 4 | lo,
            _ => {
                bytes.zeroize();
                return Err(BadKey);
            }
        }
    }
    Ok(bytes)
}

/// The fleet's master key: only the base station and the provisioning tool hold it. Zeroed
/// when dropped.
pub struct MasterKey([u8; 32]);

impl MasterKey {
    pub fn from_bytes(bytes: &[u8; 32]) -> Self {
        Self(*bytes)
    }

    /// Parses 64 hexadecimal digits (surrounding whitespace allowed).
    pub fn from_hex(text: &str) -> Result<Self, BadKey> {
        key_bytes_from_hex(text).map(Self)
    }

    /// The key of frames to [`crate::Address::Broadcast`], held by every robot.
    pub fn broadcast_bytes(&self) -> [u8; 32] {
        self.derive(b"sweeper/v1/broadcast", &[])
    }

    /// Robot `id`'s own key: its handshake and unicast frames, both ways.
    pub fn robot_bytes(&self, id: u16) -> [u8; 32] {
        self.derive(b"sweeper/v1/robot", &id.to_le_bytes())
    }

    /// The key of one localization or scan source of the site (`basestation feed-key`):
    /// the MAC of its datagrams to the base station. Not a robot's: a source that is taken
    /// apart can speak as itself only.
    pub fn source_bytes(&self, name: &str) -> [u8; 32] {
        self.derive(b"sweeper/v1/source", name.as_bytes())
    }

    pub fn broadcast(&self) -> FleetKey {
        let mut bytes = self.broadcast_bytes();
        let key = FleetKey::from_bytes(&bytes);
        bytes.zeroize();
        key
    }

    pub fn robot(&self, id: u16) -> FleetKey {
        let mut bytes = self.robot_bytes(id);
        let key = FleetKey::from_bytes(&bytes);
        bytes.zeroize();
        key
    }

    /// BLAKE2s keyed by the master key over a label (a PRF: one key per label).
    fn derive(&self, label: &[u8], context: &[u8]) -> [u8; 32] {
        let mut mac =
            <Blake2sMac<U32> as KeyInit>::new_from_slice(&self.0).expect("32 bytes is a valid key");
        mac.update(label);
        mac.update(context);
        let mut out = [0u8; 32];
        out.copy_from_slice(&mac.finalize().into_bytes());
        out
    }
}

impl Drop for MasterKey {
    fn drop(&mut self) {
        self.0.zeroize();
    }
}

impl core::fmt::Debug for MasterKey {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("MasterKey(<secret>)")
    }
}

fn hex_digit(c: u8) -> Option<u8> {
    match c {
        b'0'..=b'9' => Some(c - b'0'),
        b'a'..=b'f' => Some(c - b'a' + 10),
        b'A'..=b'F' => Some(c - b'A' + 10),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tag_depends_on_key_schema_session_and_body() {
        let k = FleetKey::from_bytes(&[7; 32]);
        let other = FleetKey::from_bytes(&[8; 32]);
        let t = k.tag(&[1; 8], 5, &[b"seq", b"body"]);
        assert!(k.verify(&[1; 8], 5, &[b"seq", b"body"], &t));
        assert!(!other.verify(&[1; 8], 5, &[b"seq", b"body"], &t));
        assert!(!k.verify(&[2; 8], 5, &[b"seq", b"body"], &t));
        assert!(!k.verify(&[1; 8], 6, &[b"seq", b"body"], &t));
        assert!(!k.verify(&[1; 8], 5, &[b"seQ", b"body"], &t));
        assert!(!k.verify(&[1; 8], 5, &[b"seq", b"bodY"], &t));
        assert!(!k.verify(&[1; 8], 5, &[b"seq", b"body"], &t[..7]));
    }

    #[test]
    fn derived_keys_differ_per_purpose_and_robot() {
        let m = MasterKey::from_bytes(&[5; 32]);
        let keys = [
            m.broadcast_bytes(),
            m.robot_bytes(0),
            m.robot_bytes(1),
            m.source_bytes("fixes"),
            m.source_bytes("scan"),
            [5; 32],
        ];
        for (i, a) in keys.iter().enumerate() {
            for b in &keys[i + 1..] {
                assert_ne!(a, b);
            }
        }
        assert_eq!(
            m.robot_bytes(1),
            MasterKey::from_bytes(&[5; 32]).robot_bytes(1)
        );
        assert_ne!(
            m.robot_bytes(1),
            MasterKey::from_bytes(&[6; 32]).robot_bytes(1)
        );
    }

    #[test]
    fn hex_keys() {
        let hex = "00112233445566778899aabbccddeeff00112233445566778899AABBCCDDEEFF\n";
        assert!(FleetKey::from_hex(hex).is_ok());
        assert_eq!(FleetKey::from_hex("abc").err(), Some(BadKey));
        assert_eq!(
            FleetKey::from_hex(&hex.replace('0', "g")).err(),
            Some(BadKey)
        );
        assert_eq!(
            std::format!("{:?}", FleetKey::from_hex(hex).unwrap()),
            "FleetKey(<secret>)"
        );
    }
}
