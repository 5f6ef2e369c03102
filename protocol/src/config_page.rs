//! The robot's configuration page: who it is and the fleet key, written once into a flash
//! page by the operator (`basestation robot-config`, then `probe-rs download`), read by the
//! firmware at boot. One firmware image serves every robot.
//!
//! Layout (48 bytes): `b"SWP1"`, id (u16 LE), role (0 follower, 1 leader), 0, the 32-byte
//! fleet key, and an 8-byte check: the BLAKE2s MAC of the first 40 bytes under that key.
//! An erased, torn or mistyped page fails the check and the robot refuses to drive.

use crate::auth::FleetKey;

pub const CONFIG_PAGE_LEN: usize = 48;
const MAGIC: &[u8; 4] = b"SWP1";
const DOMAIN: &[u8; 8] = b"cfgpage1";

#[derive(Clone, Copy, PartialEq, Eq)]
pub struct ConfigPage {
    pub id: u16,
    pub leader: bool,
    pub key: [u8; 32],
}

impl core::fmt::Debug for ConfigPage {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("ConfigPage")
            .field("id", &self.id)
            .field("leader", &self.leader)
            .finish_non_exhaustive()
    }
}

impl ConfigPage {
    pub fn encode(&self) -> [u8; CONFIG_PAGE_LEN] {
        let mut page = [0u8; CONFIG_PAGE_LEN];
        page[..4].copy_from_slice(MAGIC);
        page[4..6].copy_from_slice(&self.id.to_le_bytes());
        page[6] = self.leader as u8;
        page[8..40].copy_from_slice(&self.key);
        let check = FleetKey::from_bytes(&self.key).tag(DOMAIN, 0, &page[..40]);
        page[40..].copy_from_slice(&check);
        page
    }

    pub fn decode(page: &[u8]) -> Option<ConfigPage> {
        if page.len() < CONFIG_PAGE_LEN || &page[..4] != MAGIC || page[6] > 1 {
            return None;
        }
        let mut key = [0u8; 32];
        key.copy_from_slice(&page[8..40]);
        if !FleetKey::from_bytes(&key).verify(DOMAIN, 0, &page[..40], &page[40..48]) {
            return None;
        }
        Some(ConfigPage {
            id: u16::from_le_bytes([page[4], page[5]]),
            leader: page[6] == 1,
            key,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_damage() {
        let c = ConfigPage {
            id: 7,
            leader: true,
            key: [9; 32],
        };
        let mut page = c.encode();
        assert_eq!(ConfigPage::decode(&page), Some(c));
        assert_eq!(ConfigPage::decode(&[0xff; CONFIG_PAGE_LEN]), None);
        page[5] ^= 1;
        assert_eq!(ConfigPage::decode(&page), None);
    }
}
