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

/// A station for `paper-passage` and its robot 1 (a follower), linked after 2 s.
fn station_and_robot_1() -> (BaseStation, Link<1>, u32) {
    let master = MasterKey::from_bytes(&[5u8; 32]);
    let mut station = BaseStation::new(StationConfig::from_scenario(&scenario()), &master, 1, 2);
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
    (station, robot, now)
}

#[test]
fn malformed_and_absurd_telemetry_does_not_stop_the_station() {
    // Robot 1 links properly, then sends the most absurd telemetry a valid frame can hold,
    // then garbage.
    let (mut station, mut robot, mut now) = station_and_robot_1();
    let mut buf = [0u8; MAX_WIRE];
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

/// Telemetry of a follower `error_mm` off its reference.
fn following(mode: RobotMode, error_mm: u16) -> Message {
    Message::Telemetry(Telemetry {
        pose: WirePose {
            x_mm: 0,
            y_mm: 0,
            heading: 0,
        },
        wheel_mm_s: [0, 0],
        mode,
        tracking_error_mm: error_mm,
        faults: 0,
        link: LinkCounters {
            received: 0,
            rejected: 0,
            lost: 0,
        },
    })
}

#[test]
fn a_follower_left_behind_is_reported_once_and_its_catching_up_too() {
    let (mut station, mut robot, mut now) = station_and_robot_1();
    let mut buf = [0u8; MAX_WIRE];
    let mut send = |station: &mut BaseStation, now: u32, m: &Message| {
        let n = robot.send(Address::Base, now, m, &mut buf).unwrap();
        station.receive(&buf[..n], now);
    };
    let named = |station: &BaseStation, name: &str| -> Vec<(u32, Option<u16>)> {
        station
            .events()
            .iter()
            .map(|e| e.describe(0))
            .filter(|(_, n, _)| n == name)
            .map(|(at, _, robot)| (at, robot))
            .collect()
    };
    // Far off before it ever joined: not left behind, still joining.
    for _ in 0..80 {
        now += 100;
        send(&mut station, now, &following(RobotMode::Joining, 5000));
    }
    assert!(named(&station, "follower_behind").is_empty());
    // Joined, then 1.5 m off: told after 5 s, once.
    now += 100;
    send(&mut station, now, &following(RobotMode::InFormation, 50));
    let off_at = now + 100;
    for _ in 0..100 {
        now += 100;
        send(&mut station, now, &following(RobotMode::Joining, 1500));
    }
    let behind = named(&station, "follower_behind");
    assert_eq!(behind, vec![(off_at + 5000, Some(1))], "{behind:?}");
    // 0.5 m off is not caught up; 0.2 m is.
    for error in [500, 500, 200, 200] {
        now += 100;
        send(&mut station, now, &following(RobotMode::Joining, error));
    }
    assert_eq!(
        named(&station, "follower_caught_up"),
        vec![(now - 100, Some(1))]
    );
    // A short excursion over a metre is not reported.
    for _ in 0..30 {
        now += 100;
        send(&mut station, now, &following(RobotMode::Transforming, 1200));
    }
    now += 100;
    send(&mut station, now, &following(RobotMode::InFormation, 80));
    assert_eq!(named(&station, "follower_behind").len(), 1);
}
