//! The robot's configuration page: who it is and its keys, written once into a flash page
//! by the operator (`basestation robot-config`, then `probe-rs download`), read by the
//! firmware at boot. One firmware image serves every robot.
//!
//! Layout (80 bytes): `b"SWP2"`, id (u16 LE), role (0 follower, 1 leader), 0, the 32-byte
//! broadcast key, the robot's own 32-byte key (both derived from the fleet's master key,
//! which no robot holds), and an 8-byte check: the BLAKE2s MAC of the first 72 bytes under
//! the robot's key. An erased, torn or mistyped page fails the check and the robot refuses
//! to drive.

use crate::auth::{FleetKey, MasterKey};

pub const CONFIG_PAGE_LEN: usize = 80;
const MAGIC: &[u8; 4] = b"SWP2";
const DOMAIN: &[u8; 8] = b"cfgpage2";

#[derive(Clone, Copy, PartialEq, Eq)]
pub struct ConfigPage {
    pub id: u16,
    pub leader: bool,
    /// The key of broadcast frames.
    pub broadcast_key: [u8; 32],
    /// This robot's key: its handshake and unicast frames.
    pub robot_key: [u8; 32],
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
    /// Robot `id`'s page, its keys derived from the fleet's master key.
    pub fn new(id: u16, leader: bool, master: &MasterKey) -> Self {
        Self {
            id,
            leader,
            broadcast_key: master.broadcast_bytes(),
            robot_key: master.robot_bytes(id),
        }
    }

    pub fn encode(&self) -> [u8; CONFIG_PAGE_LEN] {
        let mut page = [0u8; CONFIG_PAGE_LEN];
        page[..4].copy_from_slice(MAGIC);
        page[4..6].copy_from_slice(&self.id.to_le_bytes());
        page[6] = self.leader as u8;
        page[8..40].copy_from_slice(&self.broadcast_key);
        page[40..72].copy_from_slice(&self.robot_key);
        let check = FleetKey::from_bytes(&self.robot_key).tag(DOMAIN, 0, &[&page[..72]]);
        page[72..].copy_from_slice(&check);
        page
    }

    pub fn decode(page: &[u8]) -> Option<ConfigPage> {
        if page.len() < CONFIG_PAGE_LEN || &page[..4] != MAGIC || page[6] > 1 {
            return None;
        }
        let mut broadcast_key = [0u8; 32];
        let mut robot_key = [0u8; 32];
        broadcast_key.copy_from_slice(&page[8..40]);
        robot_key.copy_from_slice(&page[40..72]);
        if !FleetKey::from_bytes(&robot_key).verify(DOMAIN, 0, &[&page[..72]], &page[72..80]) {
            return None;
        }
        Some(ConfigPage {
            id: u16::from_le_bytes([page[4], page[5]]),
            leader: page[6] == 1,
            broadcast_key,
            robot_key,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_damage() {
        let c = ConfigPage::new(7, true, &MasterKey::from_bytes(&[9; 32]));
        let mut page = c.encode();
        assert_eq!(ConfigPage::decode(&page), Some(c));
        assert_eq!(ConfigPage::decode(&[0xff; CONFIG_PAGE_LEN]), None);
        page[5] ^= 1;
        assert_eq!(ConfigPage::decode(&page), None);
    }

    #[test]
    fn a_page_holds_no_other_robots_key() {
        let m = MasterKey::from_bytes(&[9; 32]);
        let c = ConfigPage::new(7, false, &m);
        assert_eq!(c.robot_key, m.robot_bytes(7));
        assert_ne!(c.robot_key, m.robot_bytes(8));
        assert_ne!(c.broadcast_key, [9; 32], "not the master key");
    }
}
