//! Each robot's link as the base station sees it: recorded once a second in a simulated
//! run (`/robot_N/link`) and served live by `run`.

/// One robot's link as the base station sees it (`/robot_N/link`, plottable).
#[derive(foxglove::Encode, Debug, Clone, Copy, PartialEq)]
pub struct LinkHealth {
    pub linked: bool,
    /// Since the robot was last heard, ms (−1: never).
    pub last_heard_ms: i64,
    pub accepted: u32,
    pub lost: u32,
    pub rejected: u32,
}

/// Each robot's link health at the station's clock `now_ms`.
pub fn link_health(
    station: &base_station::station::BaseStation,
    now_ms: u32,
) -> Vec<(u16, LinkHealth)> {
    station
        .link()
        .peers()
        .iter()
        .filter_map(|peer| {
            let protocol::Address::Robot(id) = peer.address else {
                return None;
            };
            Some((
                id,
                LinkHealth {
                    linked: peer.is_linked(),
                    last_heard_ms: peer
                        .last_rx_ms
                        .map_or(-1, |r| now_ms.wrapping_sub(r) as i64),
                    accepted: peer.accepted,
                    lost: peer.lost,
                    rejected: peer.rejects.total(),
                },
            ))
        })
        .collect()
}
