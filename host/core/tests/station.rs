//! The base station keeps serving the fleet whatever one robot sends it.

use base_station::scenario::Scenario;
use base_station::station::{BaseStation, StationConfig};
use protocol::link::{Event, Link, Timing};
use protocol::messages::*;
use protocol::{Address, FrameDecoder, MasterKey, MAX_WIRE};

fn scenario() -> Scenario {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../scenarios/paper-passage.toml"
    );
    Scenario::load(std::path::Path::new(path)).unwrap()
}

#[test]
fn malformed_and_absurd_telemetry_does_not_stop_the_station() {
    let master = MasterKey::from_bytes(&[5u8; 32]);
    let mut station = BaseStation::new(StationConfig::from_scenario(&scenario()), &master, 1, 2);
    // Robot 1 links properly, then sends the most absurd telemetry a valid frame can hold,
    // then garbage.
    let mut robot: Link<1> = Link::new(
        Address::Robot(1),
        master.broadcast(),
        9,
        9 << 32,
        Timing::default(),
    );
    robot.add_peer(Address::Base, master.robot(1));
    let mut buf = [0u8; MAX_WIRE];
    let mut dec = FrameDecoder::new();
    let mut now = 0;
    for _ in 0..20 {
        now += 100;
        station.step(now);
        let out = station.take_outbox();
        for &b in &out {
            if let Some(frame) = dec.push(b) {
                if let Ok(Event::Challenged { from, nonce }) = robot.receive(frame, now) {
                    let n = robot.answer(from, nonce, now, &mut buf).unwrap();
                    station.receive(&buf[..n], now);
                }
            }
        }
        let n = robot.challenge(Address::Base, now, &mut buf).unwrap();
        station.receive(&buf[..n], now);
    }
    assert!(station.link().peer(Address::Robot(1)).unwrap().is_linked());
    let absurd = Message::Telemetry(Telemetry {
        pose: WirePose {
            x_mm: i32::MAX,
            y_mm: i32::MIN,
            heading: u16::MAX,
        },
        wheel_mm_s: [i16::MIN, i16::MAX],
        mode: RobotMode::EmergencyStop,
        tracking_error_mm: u16::MAX,
        faults: u16::MAX,
        link: LinkCounters {
            received: u32::MAX,
            rejected: u32::MAX,
            lost: u32::MAX,
        },
    });
    for i in 0..50u32 {
        now += 100;
        let n = robot.send(Address::Base, now, &absurd, &mut buf).unwrap();
        station.receive(&buf[..n], now);
        let garbage: Vec<u8> = (0..200u32)
            .map(|j| (j.wrapping_mul(2654435761).wrapping_add(i) >> 7) as u8)
            .collect();
        station.receive(&garbage, now);
        station.step(now);
        assert!(
            !station.take_outbox().is_empty(),
            "the station keeps transmitting"
        );
    }
    assert!(station.rejects().total() > 0, "garbage counted");
}
