//! Sessions, handshake and replay protection between a base station and robots.

use protocol::link::{Event, Link, Timing};
use protocol::messages::*;
use protocol::{Address, FleetKey, FrameDecoder, MasterKey, Reject, MAX_WIRE};

type Base = Link<8>;
type Robot = Link<1>;

fn master() -> MasterKey {
    MasterKey::from_bytes(&[9; 32])
}

/// The broadcast key.
fn key() -> FleetKey {
    master().broadcast()
}

fn base(session: u32) -> Base {
    let mut l = Base::new(
        Address::Base,
        key(),
        session,
        (session as u64) << 32,
        Timing::default(),
    );
    l.add_peer(Address::Robot(1), master().robot(1));
    l.add_peer(Address::Robot(2), master().robot(2));
    l
}

fn robot(id: u16, boot: u32) -> Robot {
    let mut l = Robot::new(
        Address::Robot(id),
        key(),
        boot,
        (boot as u64) << 32 | 0x8000_0000,
        Timing::default(),
    );
    l.add_peer(Address::Base, master().robot(id));
    l
}

/// Delivers one wire frame to a link.
fn deliver<const N: usize>(to: &mut Link<N>, wire: &[u8], now: u32) -> Vec<Result<Event, Reject>> {
    let mut dec = FrameDecoder::new();
    let mut out = Vec::new();
    for &b in wire {
        if let Some(r) = dec.push(b) {
            out.push(to.receive(r, now));
        }
    }
    out
}

fn wire<const N: usize>(from: &mut Link<N>, to: Address, now: u32, m: Message) -> Vec<u8> {
    let mut buf = [0u8; MAX_WIRE];
    let n = from.send(to, now, &m, &mut buf).unwrap();
    buf[..n].to_vec()
}

fn leader_state(x: i32) -> Message {
    Message::LeaderState(LeaderState {
        pose: WirePose {
            x_mm: x,
            y_mm: 0,
            heading: 0,
        },
        twist: WireTwist::new(100, 0),
        blend: 0,
    })
}

/// Robot challenges base, base answers: robot learns the base's session.
fn robot_links_to<const N: usize>(r: &mut Robot, b: &mut Link<N>, now: u32) {
    let mut buf = [0u8; MAX_WIRE];
    assert_eq!(r.due_challenge(now), Some(Address::Base));
    let n = r.challenge(Address::Base, now, &mut buf).unwrap();
    let ev = deliver(b, &buf[..n], now);
    let Ok(Event::Challenged { from, nonce }) = ev[0] else {
        panic!("{ev:?}")
    };
    let n = b.answer(from, nonce, now + 10, &mut buf).unwrap();
    let ev = deliver(r, &buf[..n], now + 20);
    assert_eq!(
        ev,
        vec![Ok(Event::Linked {
            peer: Address::Base
        })]
    );
}

#[test]
fn nothing_is_accepted_before_the_handshake() {
    let mut b = base(77);
    let mut r = robot(1, 5);
    let w = wire(&mut b, Address::Broadcast, 0, leader_state(1));
    assert_eq!(deliver(&mut r, &w, 0), vec![Err(Reject::UnknownSession)]);
    robot_links_to(&mut r, &mut b, 100);
    let w = wire(&mut b, Address::Broadcast, 200, leader_state(2));
    assert!(matches!(
        deliver(&mut r, &w, 200)[0],
        Ok(Event::Message { .. })
    ));
}

#[test]
fn forged_replayed_and_reordered_frames_are_rejected() {
    let mut b = base(77);
    let mut r = robot(1, 5);
    robot_links_to(&mut r, &mut b, 0);

    let f1 = wire(&mut b, Address::Broadcast, 100, leader_state(1));
    let f2 = wire(&mut b, Address::Broadcast, 200, leader_state(2));
    let f3 = wire(&mut b, Address::Broadcast, 300, leader_state(3));
    assert!(matches!(
        deliver(&mut r, &f1, 100)[0],
        Ok(Event::Message { .. })
    ));
    assert!(matches!(
        deliver(&mut r, &f3, 300)[0],
        Ok(Event::Message { .. })
    ));
    // f2 arrives late: older than f3, refused. f1 again: a replay.
    assert_eq!(deliver(&mut r, &f2, 310), vec![Err(Reject::Replay)]);
    assert_eq!(deliver(&mut r, &f1, 320), vec![Err(Reject::Replay)]);

    // A rogue transmitter with another key, pretending to be the base station.
    let mut rogue = Base::new(
        Address::Base,
        FleetKey::from_bytes(&[1; 32]),
        77,
        0,
        Timing::default(),
    );
    rogue.add_peer(Address::Robot(1), FleetKey::from_bytes(&[1; 32]));
    let forged = wire(&mut rogue, Address::Broadcast, 400, leader_state(99));
    assert_eq!(deliver(&mut r, &forged, 400), vec![Err(Reject::BadTag)]);
    // A stolen Welcome to a challenge this robot never sent.
    let mut buf = [0u8; MAX_WIRE];
    let n = b.answer(Address::Robot(1), 12345, 500, &mut buf).unwrap();
    assert_eq!(deliver(&mut r, &buf[..n], 500), vec![Err(Reject::Replay)]);

    // The 2 skipped broadcast seqs (f2 never accepted) count as lost, rejects by reason.
    let s = r.stats();
    assert_eq!(s.rejects.get(Reject::Replay), 3);
    assert_eq!(s.rejects.get(Reject::BadTag), 1);
    assert_eq!(r.peer(Address::Base).unwrap().lost, 1);
}

#[test]
fn a_rebooted_robot_rejects_recorded_frames() {
    let mut b = base(77);
    let mut r = robot(1, 5);
    robot_links_to(&mut r, &mut b, 0);
    let recorded: Vec<_> = (0..5)
        .map(|i| wire(&mut b, Address::Broadcast, 100 * i, leader_state(i as i32)))
        .collect();

    // Reboot: a new link with the next boot count.
    let mut r = robot(1, 6);
    for f in &recorded {
        assert_eq!(deliver(&mut r, f, 1000), vec![Err(Reject::UnknownSession)]);
    }
    robot_links_to(&mut r, &mut b, 2000);
    for f in &recorded {
        assert_eq!(deliver(&mut r, f, 2100), vec![Err(Reject::Replay)]);
    }
    let fresh = wire(&mut b, Address::Broadcast, 2200, leader_state(7));
    assert!(matches!(
        deliver(&mut r, &fresh, 2200)[0],
        Ok(Event::Message { .. })
    ));
}

#[test]
fn a_restarted_base_station_is_accepted_again_without_reopening_old_frames() {
    let mut b = base(77);
    let mut r = robot(1, 5);
    robot_links_to(&mut r, &mut b, 0);
    let recorded: Vec<_> = (1..50)
        .map(|i| wire(&mut b, Address::Broadcast, 100 * i, leader_state(i as i32)))
        .collect();
    assert!(matches!(
        deliver(&mut r, &recorded[0], 100)[0],
        Ok(Event::Message { .. })
    ));

    // Restart: new session, counters from zero.
    let mut b = base(78);
    let f = wire(&mut b, Address::Broadcast, 200, leader_state(0));
    assert_eq!(deliver(&mut r, &f, 200), vec![Err(Reject::BadTag)]);
    // The robot notices the silence and challenges; no operator needed.
    assert_eq!(r.due_challenge(900), None);
    robot_links_to(&mut r, &mut b, 1100);
    let f = wire(&mut b, Address::Broadcast, 1200, leader_state(1));
    assert!(matches!(
        deliver(&mut r, &f, 1200)[0],
        Ok(Event::Message { .. })
    ));
    // The previous session's frames, some with far higher seqs, never verify again.
    for f in &recorded[1..] {
        assert_eq!(deliver(&mut r, f, 1300), vec![Err(Reject::BadTag)]);
    }
}

/// Issue 15, item 3: a recorded `Hello` replayed at 50 frames/s for 30 s is never answered
/// and never keeps the genuine robot (rebooted, so it must link again) from linking.
#[test]
fn a_replayed_hello_never_starves_the_genuine_one() {
    let mut b = base(77);
    let mut old = robot(1, 5);
    let mut buf = [0u8; MAX_WIRE];
    let n = old.challenge(Address::Base, 0, &mut buf).unwrap();
    let recorded = buf[..n].to_vec();
    assert!(matches!(
        deliver(&mut b, &recorded, 0)[0],
        Ok(Event::Challenged { .. })
    ));
    // The robot reboots; the attacker replays the recorded Hello every 20 ms.
    let mut r = robot(1, 6);
    let mut linked_at = None;
    for t in (20..30_000u32).step_by(10) {
        if t % 20 == 0 {
            let ev = deliver(&mut b, &recorded, t);
            assert_eq!(ev, vec![Err(Reject::Replay)], "never answered (at {t} ms)");
        }
        if linked_at.is_none() && r.due_challenge(t).is_some() {
            let n = r.challenge(Address::Base, t, &mut buf).unwrap();
            if let Ok(Event::Challenged { from, nonce }) = deliver(&mut b, &buf[..n], t + 5)[0] {
                let n = b.answer(from, nonce, t + 5, &mut buf).unwrap();
                if deliver(&mut r, &buf[..n], t + 10)
                    == vec![Ok(Event::Linked {
                        peer: Address::Base,
                    })]
                {
                    linked_at = Some(t);
                }
            }
        }
    }
    assert_eq!(
        linked_at,
        Some(20),
        "the genuine robot links at its first Hello"
    );
    // And a replay of the genuine robot's own newer Hello is refused too.
    let n = r.challenge(Address::Base, 31_000, &mut buf).unwrap();
    let hello = buf[..n].to_vec();
    assert!(matches!(
        deliver(&mut b, &hello, 31_000)[0],
        Ok(Event::Challenged { .. })
    ));
    assert_eq!(deliver(&mut b, &hello, 31_010), vec![Err(Reject::Replay)]);
}

/// A `Welcome` whose round trip exceeds `max_rtt_ms` gives no clock offset worth trusting
/// (a delaying relay stretches it): refused as stale.
#[test]
fn a_welcome_after_too_long_a_round_trip_is_refused() {
    let mut b = base(77);
    let mut r = robot(1, 5);
    let mut buf = [0u8; MAX_WIRE];
    let n = r.challenge(Address::Base, 0, &mut buf).unwrap();
    let Ok(Event::Challenged { from, nonce }) = deliver(&mut b, &buf[..n], 1000)[0] else {
        panic!()
    };
    let n = b.answer(from, nonce, 1000, &mut buf).unwrap();
    assert_eq!(deliver(&mut r, &buf[..n], 2001), vec![Err(Reject::Stale)]);
    assert!(!r.peer(Address::Base).unwrap().is_linked());
    robot_links_to(&mut r, &mut b, 2400);
    let base_peer = r.peer(Address::Base).unwrap();
    assert_eq!(base_peer.rtt_ms, Some(20));
}

/// A node that re-synchronises challenges its linked peer again after
/// `resync_every_ms`; the answer (same session) is `Synced`, not a new link.
#[test]
fn a_linked_peer_is_resynchronised_periodically() {
    let mut b = base(77);
    let mut r = Robot::new(
        Address::Robot(1),
        key(),
        5,
        5 << 32,
        Timing {
            resync_every_ms: Some(10_000),
            ..Timing::default()
        },
    );
    r.add_peer(Address::Base, master().robot(1));
    robot_links_to(&mut r, &mut b, 0);
    for t in (1_000..10_000).step_by(100) {
        let f = wire(&mut b, Address::Broadcast, t, leader_state(1));
        deliver(&mut r, &f, t);
        assert_eq!(r.due_challenge(t), None, "at {t} ms");
    }
    assert_eq!(r.due_challenge(10_000), Some(Address::Base));
    let mut buf = [0u8; MAX_WIRE];
    let n = r.challenge(Address::Base, 10_000, &mut buf).unwrap();
    let Ok(Event::Challenged { from, nonce }) = deliver(&mut b, &buf[..n], 10_000)[0] else {
        panic!()
    };
    let n = b.answer(from, nonce, 10_100, &mut buf).unwrap();
    assert_eq!(
        deliver(&mut r, &buf[..n], 10_060),
        vec![Ok(Event::Synced {
            peer: Address::Base
        })]
    );
    // A longer round trip (60 ms) than the link's (20 ms), 10 s later: the offset stays
    // the more exact one (see `the_shortest_round_trip_sets_the_clock_offset`).
    let peer = r.peer(Address::Base).unwrap();
    assert_eq!((peer.rtt_ms, peer.clock_offset_ms), (Some(20), Some(0)));
}

/// Within a session the clock offset comes from the shortest round trip, as NTP's clock
/// filter does; a longer one replaces it only as it ages (1 ms per second).
#[test]
fn the_shortest_round_trip_sets_the_clock_offset() {
    let mut b = base(77);
    let mut r = robot(1, 5);
    robot_links_to(&mut r, &mut b, 0); // 20 ms round trip, offset 0
    let mut resync = |r: &mut Robot, sent: u32, stamp: u32, back: u32| {
        let mut buf = [0u8; MAX_WIRE];
        let n = r.challenge(Address::Base, sent, &mut buf).unwrap();
        let Ok(Event::Challenged { from, nonce }) = deliver(&mut b, &buf[..n], sent)[0] else {
            panic!()
        };
        let n = b.answer(from, nonce, stamp, &mut buf).unwrap();
        assert_eq!(
            deliver(r, &buf[..n], back),
            vec![Ok(Event::Synced {
                peer: Address::Base
            })]
        );
        let peer = r.peer(Address::Base).unwrap();
        (peer.rtt_ms.unwrap(), peer.clock_offset_ms.unwrap())
    };
    // 200 ms round trip 20 s on: kept out (20 + 20 < 200).
    assert_eq!(resync(&mut r, 20_000, 20_150, 20_200), (20, 0));
    // 10 ms, shorter: taken at once (the stamp says our clock is 3 ms behind).
    assert_eq!(resync(&mut r, 30_000, 30_008, 30_010), (10, 3));
    // 200 ms again, 200 s after: the 10 ms estimate has aged past it.
    assert_eq!(resync(&mut r, 230_000, 230_100, 230_200), (200, 0));
}

#[test]
fn the_base_station_learns_robot_sessions_and_counts_per_robot() {
    let mut b = base(77);
    let mut r1 = robot(1, 5);
    let mut r2 = robot(2, 9);
    robot_links_to(&mut r1, &mut b, 0);
    robot_links_to(&mut r2, &mut b, 0);
    // The base challenges both robots (it knows neither session yet).
    for r in [&mut r1, &mut r2] {
        let mut buf = [0u8; MAX_WIRE];
        let peer = b.due_challenge(50).unwrap();
        let n = b.challenge(peer, 50, &mut buf).unwrap();
        let ev = deliver(r, &buf[..n], 60);
        let Ok(Event::Challenged { from, nonce }) = ev[0] else {
            panic!("{ev:?}")
        };
        let n = r.answer(from, nonce, 60, &mut buf).unwrap();
        assert!(matches!(
            deliver(&mut b, &buf[..n], 70)[0],
            Ok(Event::Linked { .. })
        ));
    }
    assert_eq!(b.due_challenge(80), None);
    let t = Message::Telemetry(Telemetry::default());
    let w1 = wire(&mut r1, Address::Base, 100, t);
    let w2 = wire(&mut r2, Address::Base, 100, t);
    assert!(matches!(
        deliver(&mut b, &w1, 100)[0],
        Ok(Event::Message { .. })
    ));
    assert!(matches!(
        deliver(&mut b, &w2, 100)[0],
        Ok(Event::Message { .. })
    ));
    assert_eq!(deliver(&mut b, &w2, 101), vec![Err(Reject::Replay)]);
    assert_eq!(
        b.peer(Address::Robot(2))
            .unwrap()
            .rejects
            .get(Reject::Replay),
        1
    );
    assert_eq!(b.peer(Address::Robot(1)).unwrap().rejects.total(), 0);
    // Robot 1 telemetry addressed to the base is not for robot 2.
    assert_eq!(deliver(&mut r2, &w1, 102), vec![Ok(Event::Ignored)]);
}

#[test]
fn a_slow_link_may_answer_an_earlier_challenge() {
    // Round trip longer than the challenge period: the answer to the first Hello arrives
    // after the second went out, and still links; a stale one does not.
    let mut b = base(77);
    let mut r = robot(1, 5);
    let mut buf = [0u8; MAX_WIRE];
    let n = r.challenge(Address::Base, 0, &mut buf).unwrap();
    let first = buf[..n].to_vec();
    let _second = r.challenge(Address::Base, 300, &mut buf).unwrap();
    let Ok(Event::Challenged { from, nonce }) = deliver(&mut b, &first, 200)[0] else {
        panic!()
    };
    let n = b.answer(from, nonce, 200, &mut buf).unwrap();
    let answer = buf[..n].to_vec();
    assert_eq!(
        deliver(&mut r, &answer, 400),
        vec![Ok(Event::Linked {
            peer: Address::Base
        })]
    );

    let mut r = robot(1, 6);
    let n = r.challenge(Address::Base, 0, &mut buf).unwrap();
    let hello = buf[..n].to_vec();
    let Ok(Event::Challenged { from, nonce }) = deliver(&mut b, &hello, 100)[0] else {
        panic!()
    };
    let n = b.answer(from, nonce, 100, &mut buf).unwrap();
    assert_eq!(
        deliver(&mut r, &buf[..n], 5000),
        vec![Err(Reject::Replay)],
        "a 5 s old challenge"
    );
}

#[test]
fn a_late_welcome_never_lowers_the_replay_floor() {
    let mut b = base(77);
    let mut r = robot(1, 5);
    robot_links_to(&mut r, &mut b, 0);
    // The robot challenges again; the answer is held back while frames flow.
    let mut buf = [0u8; MAX_WIRE];
    let n = r.challenge(Address::Base, 1000, &mut buf).unwrap();
    let Ok(Event::Challenged { from, nonce }) = deliver(&mut b, &buf[..n], 1000)[0] else {
        panic!()
    };
    let n = b.answer(from, nonce, 1010, &mut buf).unwrap();
    let held = buf[..n].to_vec();
    let first = wire(&mut b, Address::Broadcast, 1100, leader_state(1));
    assert!(matches!(
        deliver(&mut r, &first, 1100)[0],
        Ok(Event::Message { .. })
    ));
    let second = wire(&mut b, Address::Robot(1), 1200, leader_state(2));
    assert!(matches!(
        deliver(&mut r, &second, 1200)[0],
        Ok(Event::Message { .. })
    ));
    // Delivered late, within the challenge's lifetime: it re-synchronises (the same
    // session), and reopens nothing.
    assert_eq!(
        deliver(&mut r, &held, 1300),
        vec![Ok(Event::Synced {
            peer: Address::Base
        })]
    );
    assert_eq!(deliver(&mut r, &first, 1400), vec![Err(Reject::Replay)]);
    assert_eq!(deliver(&mut r, &second, 1400), vec![Err(Reject::Replay)]);
}

/// Issue 15, item 5: a robot taken apart holds the broadcast key and its own key. It
/// cannot speak as another robot to the base station, nor as the base station to another
/// robot by unicast; it can forge broadcasts (what holds and what does not:
/// docs/protocol.md).
#[test]
fn a_captured_robot_cannot_impersonate_another_robot_or_the_base_stations_unicasts() {
    let mut b = base(77);
    let mut r1 = robot(1, 5);
    let mut r2 = robot(2, 9);
    robot_links_to(&mut r1, &mut b, 0);
    robot_links_to(&mut r2, &mut b, 0);
    let mut buf = [0u8; MAX_WIRE];
    // The base station learns robot 1's session.
    let n = b.challenge(Address::Robot(1), 100, &mut buf).unwrap();
    let Ok(Event::Challenged { from, nonce }) = deliver(&mut r1, &buf[..n], 100)[0] else {
        panic!()
    };
    let n = r1.answer(from, nonce, 110, &mut buf).unwrap();
    assert!(matches!(
        deliver(&mut b, &buf[..n], 120)[0],
        Ok(Event::Linked { .. })
    ));

    // Robot 2's keys, in the attacker's hands: a link claiming to be robot 1 (its session
    // is public, it is in the Welcome) and one claiming to be the base station.
    let captured = master().robot(2);
    let mut as_robot1 = Robot::new(Address::Robot(1), key(), r1.session(), 0, Timing::default());
    as_robot1.add_peer(Address::Base, captured.clone());
    let forged = wire(
        &mut as_robot1,
        Address::Base,
        200,
        Message::Telemetry(Telemetry::default()),
    );
    assert_eq!(deliver(&mut b, &forged, 200), vec![Err(Reject::BadTag)]);

    let mut as_base = Base::new(Address::Base, key(), b.session(), 0, Timing::default());
    as_base.add_peer(Address::Robot(1), captured);
    let forged = wire(&mut as_base, Address::Robot(1), 300, leader_state(5));
    assert_eq!(deliver(&mut r1, &forged, 300), vec![Err(Reject::BadTag)]);

    // What still holds for the attacker: a broadcast, with the broadcast key every robot has.
    for _ in 0..100 {
        wire(&mut as_base, Address::Broadcast, 350, leader_state(0));
    }
    let forged = wire(&mut as_base, Address::Broadcast, 400, leader_state(6));
    assert!(matches!(
        deliver(&mut r1, &forged, 400)[0],
        Ok(Event::Message { .. })
    ));
}

/// Issue 27, finding 5: the broadcast key every robot holds cannot forge what drives or
/// places one robot. A broadcast `VelocityCommand`, `Detour`, `PoseFix`,
/// `FormationCommand`, `Hello` or `Welcome` is refused as `wrong_destination` even though
/// its tag verifies; the broadcasts a robot must hear (leader state, stop, emergency stop,
/// resume) are still taken.
#[test]
fn a_broadcast_of_a_unicast_only_message_is_refused_however_well_signed() {
    let mut b = base(77);
    let mut r1 = robot(1, 5);
    robot_links_to(&mut r1, &mut b, 0);
    // A captured robot 2 speaking as the base station with the broadcast key.
    let mut as_base = Base::new(Address::Base, key(), b.session(), 0, Timing::default());
    as_base.add_peer(Address::Robot(1), master().robot(2));
    for _ in 0..100 {
        wire(&mut as_base, Address::Broadcast, 350, leader_state(0));
    }
    let pose = WirePose::from_si(5.0, 5.0, 0.0).unwrap();
    let unicast_only = [
        Message::VelocityCommand(VelocityCommand {
            v_mm_s: 1500,
            omega_mrad_s: 0,
        }),
        Message::Detour(Detour {
            x_mm: 9000,
            y_mm: 9000,
        }),
        Message::PoseFix(PoseFix { pose, sigma_mm: 10 }),
        Message::FormationCommand(FormationCommand {
            followers: 2,
            index: 0,
            wide: Slot::default(),
            line: Slot::default(),
            report_every: 1,
        }),
        Message::Hello(Hello { nonce: u64::MAX }),
        Message::Welcome(Welcome {
            nonce: 1,
            session: 1,
            broadcast_seq: 0,
        }),
    ];
    let mut t = 400;
    for m in unicast_only {
        t += 10;
        let forged = wire(&mut as_base, Address::Broadcast, t, m);
        assert_eq!(
            deliver(&mut r1, &forged, t),
            vec![Err(Reject::WrongDestination)],
            "{}",
            m.name()
        );
    }
    for m in [
        leader_state(7),
        Message::Stop(Stop { reason: 0 }),
        Message::EmergencyStop(EmergencyStop { reason: 0 }),
        Message::Resume(Resume { reason: 0 }),
    ] {
        t += 10;
        let sent = wire(&mut as_base, Address::Broadcast, t, m);
        assert!(
            matches!(deliver(&mut r1, &sent, t)[0], Ok(Event::Message { .. })),
            "{}",
            m.name()
        );
    }
    let counts = r1.peer(Address::Base).unwrap().rejects;
    assert_eq!(counts.get(Reject::WrongDestination), 6);
}

/// Frames carry 8 bits of their sequence number: a robot that misses more of a stream than
/// they reach refuses the rest (the tag is over the whole number), falls silent, challenges
/// the base station again, and the answer's floor brings it back.
#[test]
fn a_stream_lost_beyond_the_low_bits_is_recovered_by_relinking() {
    let mut b = base(77);
    let mut r = robot(1, 5);
    robot_links_to(&mut r, &mut b, 0);
    let first = wire(&mut b, Address::Broadcast, 100, leader_state(1));
    assert!(matches!(
        deliver(&mut r, &first, 100)[0],
        Ok(Event::Message { .. })
    ));
    // 300 frames (30 s at 10 Hz) the robot never hears; the next ones it cannot place.
    for i in 0..300 {
        wire(&mut b, Address::Broadcast, 200 + i * 100, leader_state(2));
    }
    let mut now = 30_200;
    for _ in 0..15 {
        let w = wire(&mut b, Address::Broadcast, now, leader_state(3));
        assert_eq!(deliver(&mut r, &w, now + 5), vec![Err(Reject::BadTag)]);
        now += 100;
    }
    // Silent for the relink time: a challenge, answered with the broadcast floor.
    let mut buf = [0u8; MAX_WIRE];
    assert_eq!(r.due_challenge(now), Some(Address::Base));
    let n = r.challenge(Address::Base, now, &mut buf).unwrap();
    let Ok(Event::Challenged { from, nonce }) = deliver(&mut b, &buf[..n], now)[0] else {
        panic!("no challenge")
    };
    let n = b.answer(from, nonce, now + 10, &mut buf).unwrap();
    assert_eq!(
        deliver(&mut r, &buf[..n], now + 20),
        vec![Ok(Event::Synced {
            peer: Address::Base
        })]
    );
    let w = wire(&mut b, Address::Broadcast, now + 100, leader_state(4));
    assert!(matches!(
        deliver(&mut r, &w, now + 105)[0],
        Ok(Event::Message { .. })
    ));
}

/// Frames carry 12 bits (4 s) of the sender's clock, completed from the receiver's estimate
/// of it: over a day, a base station whose crystal runs 500 ppm slower or faster than the
/// robot's (ten times a real crystal's drift) is followed, frame after frame, with the whole
/// clock read right every time.
#[test]
fn a_drifting_sender_clock_is_read_whole_for_a_day() {
    for ppm in [-500i64, 500] {
        let mut b = base(77);
        let mut r = robot(1, 5);
        robot_links_to(&mut r, &mut b, 0);
        for i in 1..=43_200i64 {
            let ours = (i * 2_000) as u32; // a frame every 2 s, for 24 h
            let theirs = (i * 2_000 + i * 2_000 * ppm / 1_000_000) as u32;
            let w = wire(&mut b, Address::Broadcast, theirs, leader_state(1));
            match deliver(&mut r, &w, ours + 30).remove(0) {
                Ok(Event::Message { header, .. }) => assert_eq!(header.time_ms, theirs),
                other => panic!("{ppm} ppm, frame {i}: {other:?}"),
            }
        }
    }
}

/// Challenges nobody answers come at 300 ms, then twice as far apart each time up to
/// 4.8 s; an answer starts the count again.
#[test]
fn unanswered_challenges_back_off_to_sixteen_times_and_an_answer_resets_them() {
    let mut r = robot(1, 5);
    let mut buf = [0u8; MAX_WIRE];
    let mut sent = Vec::new();
    for t in (0..20_000).step_by(10) {
        if r.due_challenge(t).is_some() {
            r.challenge(Address::Base, t, &mut buf).unwrap();
            sent.push(t);
        }
    }
    let gaps: Vec<u32> = sent.windows(2).map(|w| w[1] - w[0]).collect();
    assert_eq!(gaps[..6], [300, 600, 1200, 2400, 4800, 4800], "{sent:?}");
    assert_eq!(
        r.peer(Address::Base).unwrap().unanswered(),
        sent.len() as u8
    );
    let mut b = base(77);
    let t = sent.last().unwrap() + 5000;
    robot_links_to(&mut r, &mut b, t);
    assert_eq!(r.peer(Address::Base).unwrap().unanswered(), 0);
}
