//! Frame authentication: a 64-bit BLAKE2s MAC keyed by the pre-shared fleet key.
//!
//! BLAKE2s is built from 32-bit additions, rotations and xors: fast on a Cortex-M4, no
//! tables, constant time. Its keyed mode is a MAC by design (no HMAC wrapper), and the
//! 8-byte output is a real parameter of the hash, not a truncation.

use blake2::digest::{consts::U8, KeyInit, Mac};
use blake2::Blake2sMac;
use zeroize::Zeroize;

use crate::TAG_LEN;

type Mac64 = Blake2sMac<U8>;

/// The fleet's pre-shared 256-bit key. It never travels over the air and is never printed;
/// its state is zeroed when dropped (blake2's `zeroize`).
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

    fn mac(&self, schema_key: &[u8; 8], session: u32, body: &[u8]) -> Mac64 {
        let mut mac = self.keyed.clone();
        mac.update(schema_key);
        mac.update(&session.to_le_bytes());
        mac.update(body);
        mac
    }

    /// The tag over a frame's header and payload.
    pub fn tag(&self, schema_key: &[u8; 8], session: u32, body: &[u8]) -> [u8; TAG_LEN] {
        let mut tag = [0u8; TAG_LEN];
        tag.copy_from_slice(&self.mac(schema_key, session, body).finalize().into_bytes());
        tag
    }

    /// Checks a tag in constant time.
    pub fn verify(&self, schema_key: &[u8; 8], session: u32, body: &[u8], tag: &[u8]) -> bool {
        self.mac(schema_key, session, body)
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
        let t = k.tag(&[1; 8], 5, b"body");
        assert!(k.verify(&[1; 8], 5, b"body", &t));
        assert!(!other.verify(&[1; 8], 5, b"body", &t));
        assert!(!k.verify(&[2; 8], 5, b"body", &t));
        assert!(!k.verify(&[1; 8], 6, b"body", &t));
        assert!(!k.verify(&[1; 8], 5, b"bodY", &t));
        assert!(!k.verify(&[1; 8], 5, b"body", &t[..7]));
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
