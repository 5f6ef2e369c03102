//! The robot node over real frames: handshake, leader state in, telemetry out.

use control_core::config::{RobotConfig, Role};
use control_core::controller::Sensors;
use control_core::node::{Identity, RobotNode};
use control_core::odometry::PoseFixSample;
use control_core::Pose;
use protocol::link::{Event, Link, Timing};
use protocol::messages::*;
use protocol::{Address, FleetKey, FrameDecoder, MAX_WIRE};

fn key() -> FleetKey {
    FleetKey::from_bytes(&[4; 32])
}

#[test]
fn follower_links_follows_and_reports() {
    let mut base: Link<4> = Link::new(Address::Base, key(), 99, 1 << 50, Timing::default());
    base.add_peer(Address::Robot(1));
    let id = Identity {
        id: 1,
        role: Role::Follower,
        boot_count: 3,
        entropy: 0x1234_5678,
    };
    let mut node = RobotNode::new(id, key(), RobotConfig::DEFAULT);
    let mut base_dec = FrameDecoder::new();
    let mut to_base: Vec<u8> = Vec::new();
    let mut to_robot: Vec<u8> = Vec::new();
    let mut telemetry = Vec::new();
    let mut buf = [0u8; MAX_WIRE];

    for i in 0..30u32 {
        let now = i * 100;
        // Base: answer challenges, challenge the robot, slots and leader state.
        for b in std::mem::take(&mut to_base) {
            if let Some(frame) = base_dec.push(b) {
                match base.receive(frame, now) {
                    Ok(Event::Challenged { from, nonce }) => {
                        let n = base.answer(from, nonce, now, &mut buf).unwrap();
                        to_robot.extend_from_slice(&buf[..n]);
                    }
                    Ok(Event::Message {
                        message: Message::Telemetry(t),
                        ..
                    }) => telemetry.push(t),
                    _ => {}
                }
            }
        }
        if let Some(peer) = base.due_challenge(now) {
            let n = base.challenge(peer, now, &mut buf).unwrap();
            to_robot.extend_from_slice(&buf[..n]);
        }
        let slots = Message::FormationCommand(FormationCommand {
            followers: 2,
            index: 0,
            wide: Slot::from_si(3.0, 2.618).unwrap(),
            line: Slot::from_si(1.5, std::f32::consts::PI).unwrap(),
        });
        let n = base.send(Address::Robot(1), now, &slots, &mut buf).unwrap();
        to_robot.extend_from_slice(&buf[..n]);
        let state = Message::LeaderState(LeaderState {
            pose: WirePose::from_si(5.0, 0.0, 0.0).unwrap(),
            v_mm_s: 0,
            omega_mrad_s: 0,
            blend: 0,
        });
        let n = base
            .send(Address::Broadcast, now, &state, &mut buf)
            .unwrap();
        to_robot.extend_from_slice(&buf[..n]);

        let bytes = std::mem::take(&mut to_robot);
        node.receive(&bytes, now, &mut |b| to_base.extend_from_slice(b));
        let sensors = Sensors {
            ticks: [0, 0],
            pose_fix: Some(PoseFixSample {
                pose: Pose::new(2.0, 1.5, 0.0),
                sigma: 0.02,
                time_ms: now,
            }),
            proximity: [None, None],
        };
        node.tick(now, &sensors, &mut |b| to_base.extend_from_slice(b));
    }
    assert!(node.link().peer(Address::Base).unwrap().is_linked());
    assert!(base.peer(Address::Robot(1)).unwrap().is_linked());
    let last = telemetry
        .last()
        .expect("telemetry reached the base station");
    assert_eq!(last.faults & faults::NOT_LINKED, 0);
    assert!(matches!(
        last.mode,
        RobotMode::Joining | RobotMode::InFormation
    ));
    assert!(last.tracking_error_mm > 0);
    // Only the two frames sent before the handshake: their session was unknown.
    let rejects = node.link().stats().rejects;
    assert_eq!(last.link.rejected, 2);
    assert_eq!(rejects.get(protocol::Reject::UnknownSession), 2);
}
