//! The robot node over real frames: handshake, leader state in, telemetry out.

use control_core::config::{RobotConfig, Role};
use control_core::controller::Sensors;
use control_core::node::{Identity, RobotNode};
use control_core::odometry::PoseFixSample;
use control_core::Pose;
use protocol::link::{Event, Link, Timing};
use protocol::messages::*;
use protocol::{Address, FleetKey, FrameDecoder, MAX_WIRE};

/// The broadcast key.
fn key() -> FleetKey {
    FleetKey::from_bytes(&[4; 32])
}

/// Robot 1's own key.
fn robot_key() -> FleetKey {
    FleetKey::from_bytes(&[5; 32])
}

/// A base station knowing robot 1, and robot 1, a follower, freshly booted.
fn base_and_follower() -> (Link<4>, RobotNode) {
    let mut base: Link<4> = Link::new(Address::Base, key(), 99, 1 << 50, Timing::default());
    base.add_peer(Address::Robot(1), robot_key());
    let id = Identity {
        id: 1,
        role: Role::Follower,
        boot_count: 3,
        entropy: 0x1234_5678,
    };
    let node = RobotNode::new(id, key(), robot_key(), RobotConfig::DEFAULT);
    (base, node)
}

/// Robot 1, a follower, and a base station for `periods` control periods: handshakes,
/// slots (with `report_every`) and the leader's state each period. The telemetry heard.
fn drive(report_every: u8, periods: u32) -> (RobotNode, Link<4>, Vec<Telemetry>) {
    let (mut base, mut node) = base_and_follower();
    let mut base_dec = FrameDecoder::new();
    let mut to_base: Vec<u8> = Vec::new();
    let mut to_robot: Vec<u8> = Vec::new();
    let mut telemetry = Vec::new();
    let mut buf = [0u8; MAX_WIRE];

    for i in 0..periods {
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
            report_every,
        });
        let n = base.send(Address::Robot(1), now, &slots, &mut buf).unwrap();
        to_robot.extend_from_slice(&buf[..n]);
        let state = Message::LeaderState(LeaderState {
            pose: WirePose::from_si(5.0, 0.0, 0.0).unwrap(),
            twist: WireTwist::new(0, 0),
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
    assert!(base.peer(Address::Robot(1)).unwrap().is_linked());
    (node, base, telemetry)
}

#[test]
fn follower_links_follows_and_reports() {
    let (mut node, mut base, telemetry) = drive(1, 30);
    let mut buf = [0u8; MAX_WIRE];
    assert!(node.link().peer(Address::Base).unwrap().is_linked());
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
    assert!(telemetry.len() >= 25, "{}", telemetry.len());

    // A detour from the base station reaches the controller, in metres.
    let now = 3000;
    assert_eq!(node.controller().detour(now), None);
    let detour = Message::Detour(Detour {
        x_mm: 2_500,
        y_mm: -750,
    });
    let n = base
        .send(Address::Robot(1), now, &detour, &mut buf)
        .unwrap();
    node.receive(&buf[..n], now, &mut |_| {});
    assert_eq!(node.controller().detour(now + 100), Some((2.5, -0.75)));
    assert_eq!(
        node.controller().detour(now + 400),
        None,
        "lapses unrenewed"
    );
}

/// Issue 15, item 1: a robot whose boot count repeats (power lost during the counter's
/// wrap, a replacement board) still draws fresh nonces: a `Welcome` recorded in the
/// earlier boot answers none of them, so the recorded session is never reopened and its
/// frames never accepted.
#[test]
fn a_repeated_boot_count_does_not_reopen_a_recorded_session() {
    let boot = |entropy| Identity {
        id: 1,
        role: Role::Follower,
        boot_count: 7,
        entropy,
    };
    let mut base: Link<4> = Link::new(Address::Base, key(), 99, 1 << 50, Timing::default());
    base.add_peer(Address::Robot(1), robot_key());
    let sensors = Sensors::default();

    // The earlier boot: it challenges, the base answers; the attacker records the answer
    // and the leader states that follow.
    let mut first = RobotNode::new(boot(0xAAAA_0001), key(), robot_key(), RobotConfig::DEFAULT);
    let mut hello = Vec::new();
    first.tick(0, &sensors, &mut |b| hello.extend_from_slice(b));
    let mut recorded = Vec::new();
    let mut dec = FrameDecoder::new();
    let mut buf = [0u8; MAX_WIRE];
    for b in hello {
        if let Some(frame) = dec.push(b) {
            if let Ok(Event::Challenged { from, nonce }) = base.receive(frame, 10) {
                let n = base.answer(from, nonce, 10, &mut buf).unwrap();
                recorded.extend_from_slice(&buf[..n]);
            }
        }
    }
    assert!(!recorded.is_empty(), "the base answered the first boot");
    first.receive(&recorded, 20, &mut |_| {});
    assert!(first.link().peer(Address::Base).unwrap().is_linked());
    let state = Message::LeaderState(LeaderState {
        pose: WirePose::from_si(5.0, 0.0, 0.0).unwrap(),
        twist: WireTwist::new(0, 0),
        blend: 0,
    });
    for t in [100, 200, 300] {
        let n = base.send(Address::Broadcast, t, &state, &mut buf).unwrap();
        recorded.extend_from_slice(&buf[..n]);
    }

    // The same count again, other noise: its own challenge first, then the recording.
    let mut again = RobotNode::new(boot(0x5555_0002), key(), robot_key(), RobotConfig::DEFAULT);
    again.tick(0, &sensors, &mut |_| {});
    again.receive(&recorded, 50, &mut |_| {});
    assert!(!again.link().peer(Address::Base).unwrap().is_linked());
    let rejects = again.link().stats().rejects;
    assert_eq!(
        rejects.get(protocol::Reject::Replay),
        1,
        "the recorded Welcome"
    );
    assert_eq!(
        rejects.get(protocol::Reject::UnknownSession),
        3,
        "its leader states"
    );
}

/// A node of `role` linked to a base station over real frames, placed by a first fix at
/// (2, 1.5); the clock at the end.
fn linked_node(role: Role) -> (Link<4>, RobotNode, u32) {
    let mut base: Link<4> = Link::new(Address::Base, key(), 99, 1 << 50, Timing::default());
    base.add_peer(Address::Robot(1), robot_key());
    let id = Identity {
        id: 1,
        role,
        boot_count: 3,
        entropy: 0x1234_5678,
    };
    let mut node = RobotNode::new(id, key(), robot_key(), RobotConfig::DEFAULT);
    let (mut to_base, mut to_robot) = (Vec::new(), Vec::new());
    let mut dec = FrameDecoder::new();
    let mut buf = [0u8; MAX_WIRE];
    let fix = Sensors {
        pose_fix: Some(PoseFixSample {
            pose: Pose::new(2.0, 1.5, 0.0),
            sigma: 0.02,
            time_ms: 0,
        }),
        ..Sensors::default()
    };
    for i in 0..10u32 {
        let now = i * 100;
        for b in std::mem::take(&mut to_base) {
            if let Some(frame) = dec.push(b) {
                if let Ok(Event::Challenged { from, nonce }) = base.receive(frame, now) {
                    let n = base.answer(from, nonce, now, &mut buf).unwrap();
                    to_robot.extend_from_slice(&buf[..n]);
                }
            }
        }
        if let Some(peer) = base.due_challenge(now) {
            let n = base.challenge(peer, now, &mut buf).unwrap();
            to_robot.extend_from_slice(&buf[..n]);
        }
        node.receive(&std::mem::take(&mut to_robot), now, &mut |b| {
            to_base.extend_from_slice(b)
        });
        let sensors = if i == 0 { fix } else { Sensors::default() };
        node.tick(now, &sensors, &mut |b| to_base.extend_from_slice(b));
    }
    assert!(node.link().peer(Address::Base).unwrap().is_linked());
    (base, node, 1000)
}

/// Issue 27, finding 5: a robot taken apart holds the broadcast key, and used to drive the
/// leader, send followers anywhere and move their believed pose with it. The node takes a
/// velocity command, a detour, a pose fix and slots only when they are addressed to it
/// under its own key; the same frames broadcast are refused (`wrong_destination`).
#[test]
fn commands_for_one_robot_are_taken_only_when_addressed_to_it() {
    let send = |base: &mut Link<4>, to: Address, now: u32, m: Message| {
        let mut buf = [0u8; MAX_WIRE];
        let n = base.send(to, now, &m, &mut buf).unwrap();
        buf[..n].to_vec()
    };
    // The leader: a broadcast command at 1.5 m/s moves nothing.
    let (mut base, mut leader, now) = linked_node(Role::Leader);
    let fast = Message::VelocityCommand(VelocityCommand {
        v_mm_s: 1500,
        omega_mrad_s: 0,
    });
    let forged = send(&mut base, Address::Broadcast, now, fast);
    leader.receive(&forged, now, &mut |_| {});
    leader.tick(now + 100, &Sensors::default(), &mut |_| {});
    assert_eq!(leader.controller().commanded().v, 0.0);
    let genuine = send(&mut base, Address::Robot(1), now + 100, fast);
    leader.receive(&genuine, now + 100, &mut |_| {});
    leader.tick(now + 200, &Sensors::default(), &mut |_| {});
    assert!(
        leader.controller().commanded().v > 0.0,
        "the unicast drives"
    );

    // A follower: a broadcast detour, fix and slots change nothing.
    let (mut base, mut follower, now) = linked_node(Role::Follower);
    let before = follower.controller().pose().unwrap();
    let slots_before = follower.controller().slots();
    let fix = Message::PoseFix(PoseFix {
        pose: WirePose::from_si(before.x + 0.4, before.y, before.heading).unwrap(),
        sigma_mm: 10,
    });
    let detour = Message::Detour(Detour {
        x_mm: 30_000,
        y_mm: 30_000,
    });
    let slots = Message::FormationCommand(FormationCommand {
        followers: 1,
        index: 0,
        wide: Slot::from_si(9.0, 0.0).unwrap(),
        line: Slot::from_si(9.0, 0.0).unwrap(),
        report_every: 1,
    });
    for (k, m) in [fix, detour, slots].into_iter().enumerate() {
        let t = now + 10 * k as u32;
        let forged = send(&mut base, Address::Broadcast, t, m);
        follower.receive(&forged, t, &mut |_| {});
    }
    assert_eq!(follower.controller().detour(now + 50), None);
    assert_eq!(follower.controller().pose().unwrap(), before);
    assert_eq!(follower.controller().slots(), slots_before);
    let rejects = follower.link().stats().rejects;
    assert_eq!(rejects.get(protocol::Reject::WrongDestination), 3);
    // Addressed to it, each is taken.
    for (k, m) in [fix, detour, slots].into_iter().enumerate() {
        let t = now + 100 + 10 * k as u32;
        let genuine = send(&mut base, Address::Robot(1), t, m);
        follower.receive(&genuine, t, &mut |_| {});
    }
    assert_eq!(follower.controller().detour(now + 150), Some((30.0, 30.0)));
    assert_ne!(follower.controller().pose().unwrap(), before);
    assert_ne!(follower.controller().slots(), slots_before);
}

/// The station spreads a shared channel's air: told to report every third period, the
/// follower sends a third of the telemetry frames.
#[test]
fn a_follower_reports_as_often_as_it_is_told() {
    let (_, _, every) = drive(1, 60);
    let (_, _, third) = drive(3, 60);
    assert!(every.len() >= 55, "{}", every.len());
    let expected = every.len() / 3;
    assert!(
        (expected - 1..=expected + 1).contains(&third.len()),
        "{} of {}",
        third.len(),
        every.len()
    );
}

/// Over a slow shared channel (its frames reach the base station 600 ms after it sends
/// them, as a modem waiting for its slot holds them; the first second's are lost), a
/// follower holds its reports from its third unanswered challenge until it links; linked
/// after so slow a handshake and not yet told how often, it reports once a second.
#[test]
fn over_a_slow_channel_reports_wait_for_the_link_then_come_once_a_second() {
    let (mut base, mut node) = base_and_follower();
    let mut dec = FrameDecoder::new();
    let mut held: Vec<(u32, Vec<u8>)> = Vec::new();
    let mut to_robot: Vec<u8> = Vec::new();
    let mut buf = [0u8; MAX_WIRE];
    let mut reports = Vec::new();
    let mut linked_at = None;
    for i in 0..90 {
        let now = i * 100;
        let (due, later): (Vec<_>, Vec<_>) = held.into_iter().partition(|(t, _)| *t <= now);
        held = later;
        for b in due.into_iter().flat_map(|(_, bytes)| bytes) {
            let Some(frame) = dec.push(b) else { continue };
            match base.receive(frame, now) {
                Ok(Event::Challenged { from, nonce }) => {
                    let n = base.answer(from, nonce, now, &mut buf).unwrap();
                    to_robot.extend_from_slice(&buf[..n]);
                }
                Ok(Event::Message {
                    header,
                    message: Message::Telemetry(_),
                }) => reports.push(header.time_ms),
                _ => {}
            }
        }
        if let Some(peer) = base.due_challenge(now) {
            let n = base.challenge(peer, now, &mut buf).unwrap();
            to_robot.extend_from_slice(&buf[..n]);
        }
        let bytes = std::mem::take(&mut to_robot);
        let mut sent = Vec::new();
        node.receive(&bytes, now, &mut |b| sent.extend_from_slice(b));
        let sensors = Sensors {
            ticks: [0, 0],
            pose_fix: None,
            proximity: [None, None],
        };
        node.tick(now, &sensors, &mut |b| sent.extend_from_slice(b));
        if now >= 1000 {
            held.push((now + 600, sent));
        }
        let linked = node.link().peer(Address::Base).unwrap().is_linked();
        if linked && linked_at.is_none() {
            linked_at = Some(now);
        }
    }
    let linked_at = linked_at.expect("the robot links over the slow channel");
    let rtt = node.link().peer(Address::Base).unwrap().rtt_ms.unwrap();
    assert!(rtt > 300, "{rtt}");
    assert!(
        reports.iter().all(|t| !(900..linked_at).contains(t)),
        "a report sent while it waited for the link: {reports:?}, linked at {linked_at}"
    );
    let after: Vec<u32> = reports
        .iter()
        .copied()
        .filter(|t| *t >= linked_at)
        .collect();
    let gaps: Vec<u32> = after.windows(2).map(|w| w[1] - w[0]).collect();
    assert!(
        gaps.len() >= 3 && gaps.iter().all(|g| *g == 1000),
        "{after:?}"
    );
}
