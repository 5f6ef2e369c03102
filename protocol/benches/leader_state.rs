//! Bytes on the wire and encode + authenticate + decode + verify time of one leader-state
//! frame: this protocol vs MAVLink 2 signed frames carrying the same information, in the
//! same run. `cargo bench -p protocol --bench leader_state`.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use mavlink::dialects::common::{
    MavFrame, MavMessage, PositionTargetTypemask, POSITION_TARGET_LOCAL_NED_DATA,
};
use mavlink::{MavHeader, MavlinkVersion, SigningConfig, SigningData};
use protocol::link::{Event, Link, Timing};
use protocol::messages::{LeaderState, Message, WirePose, WireTwist};
use protocol::{Address, FrameDecoder, MasterKey, MAX_WIRE};

const KEY: [u8; 32] = [0x5a; 32];

fn leader_state(i: u32) -> LeaderState {
    LeaderState {
        pose: WirePose::from_si(12.345 + i as f32 * 1e-3, 7.89, 0.785).unwrap(),
        twist: WireTwist::new(400, -120),
        blend: 0,
    }
}

/// A linked base station → robot pair, as in a running fleet.
fn linked_pair() -> (Link<1>, Link<1>) {
    let master = MasterKey::from_bytes(&KEY);
    let mut base = Link::new(
        Address::Base,
        master.broadcast(),
        1,
        1 << 40,
        Timing::default(),
    );
    let mut robot = Link::new(
        Address::Robot(1),
        master.broadcast(),
        2,
        2 << 40,
        Timing::default(),
    );
    base.add_peer(Address::Robot(1), master.robot(1));
    robot.add_peer(Address::Base, master.robot(1));
    let mut buf = [0u8; MAX_WIRE];
    let n = robot.challenge(Address::Base, 0, &mut buf).unwrap();
    let Some(Ok(Event::Challenged { nonce, .. })) = deliver(&mut base, &buf[..n], 0) else {
        panic!("no challenge")
    };
    let n = base.answer(Address::Robot(1), nonce, 1, &mut buf).unwrap();
    let linked = deliver(&mut robot, &buf[..n], 2);
    assert!(matches!(linked, Some(Ok(Event::Linked { .. }))));
    (base, robot)
}

fn deliver(link: &mut Link<1>, wire: &[u8], now: u32) -> Option<Result<Event, protocol::Reject>> {
    let mut dec = FrameDecoder::new();
    let mut got = None;
    for &byte in wire {
        if let Some(frame) = dec.push(byte) {
            got = Some(link.receive(frame, now));
        }
    }
    got
}

fn ours(c: &mut Criterion) {
    let (mut base, mut robot) = linked_pair();
    let mut dec = FrameDecoder::new();
    let mut buf = [0u8; MAX_WIRE];
    // An hour into a run at 10 Hz, every frame heard: the receiver completes the headers'
    // low bits from there.
    let t0 = 3_600_000;
    for i in 1..36_000 {
        let m = Message::LeaderState(leader_state(0));
        let n = base
            .send(Address::Broadcast, i * 100, &m, &mut buf)
            .unwrap();
        for &byte in &buf[..n] {
            if let Some(frame) = dec.push(byte) {
                let r = robot.receive(frame, i * 100);
                assert!(r.is_ok(), "{i}: {r:?}");
            }
        }
    }
    let m = Message::LeaderState(leader_state(0));
    let n = base.send(Address::Broadcast, t0, &m, &mut buf).unwrap();
    for &byte in &buf[..n] {
        if let Some(frame) = dec.push(byte) {
            assert!(robot.receive(frame, t0).is_ok());
        }
    }
    println!("wire bytes, this protocol, leader state: {n}");
    let mut i = 0u32;
    c.bench_function("leader_state/this_protocol", |b| {
        b.iter(|| {
            i += 1;
            let m = Message::LeaderState(leader_state(i));
            let n = base.send(Address::Broadcast, t0 + i, &m, &mut buf).unwrap();
            let mut got = None;
            for &byte in &buf[..n] {
                if let Some(frame) = dec.push(byte) {
                    got = Some(robot.receive(frame, t0 + i));
                }
            }
            assert!(matches!(got, Some(Ok(Event::Message { .. }))));
            black_box(got)
        })
    });
}

fn mavlink_message(i: u32) -> MavMessage {
    MavMessage::POSITION_TARGET_LOCAL_NED(POSITION_TARGET_LOCAL_NED_DATA {
        time_boot_ms: 3_600_000 + i,
        x: 12.345 + i as f32 * 1e-3,
        y: 7.89,
        z: 0.0,
        vx: 0.4,
        vy: 0.0,
        vz: 0.0,
        afx: 0.0,
        afy: 0.0,
        afz: 0.0,
        yaw: 0.785,
        yaw_rate: -0.12,
        // The formation blend rides in the type mask's bits, as a u16.
        type_mask: PositionTargetTypemask::from_bits_retain(0),
        coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
    })
}

fn mavlink(c: &mut Criterion) {
    let tx = SigningData::from_config(SigningConfig::new(KEY, 0, true, false));
    let rx = SigningData::from_config(SigningConfig::new(KEY, 0, true, false));
    let header = MavHeader {
        system_id: 1,
        component_id: 1,
        sequence: 0,
    };
    let mut buf = Vec::with_capacity(300);
    mavlink::write_v2_msg_signed(&mut buf, header, &mavlink_message(0), Some(&tx)).unwrap();
    println!(
        "wire bytes, MAVLink 2 signed, POSITION_TARGET_LOCAL_NED: {}",
        buf.len()
    );
    let mut i = 0u32;
    c.bench_function("leader_state/mavlink2_signed", |b| {
        b.iter(|| {
            i += 1;
            buf.clear();
            let h = MavHeader {
                sequence: i as u8,
                ..header
            };
            mavlink::write_v2_msg_signed(&mut buf, h, &mavlink_message(i), Some(&tx)).unwrap();
            let mut reader = mavlink::MavlinkReader::new(&buf[..]);
            let got = reader.read_message_signed::<MavMessage>(MavlinkVersion::V2, Some(&rx));
            assert!(got.is_ok());
            black_box(got)
        })
    });
}

criterion_group!(benches, ours, mavlink);
criterion_main!(benches);
