//! Round trips, golden vectors, garbage on the stream.

use proptest::prelude::*;
use protocol::frame::{self, Address, Expect, Header, SEQ_BEHIND};
use protocol::messages::*;
use protocol::{FleetKey, FrameDecoder, Reject, MAX_WIRE, PROTOCOL_VERSION};

fn key() -> FleetKey {
    FleetKey::from_bytes(&[0x42; 32])
}

fn arb_address() -> impl Strategy<Value = Address> {
    prop_oneof![
        Just(Address::Base),
        any::<u16>().prop_map(Address::Robot),
        Just(Address::Broadcast)
    ]
}

fn arb_pose() -> impl Strategy<Value = WirePose> {
    (any::<i32>(), any::<i32>(), 0u16..16384).prop_map(|(x_mm, y_mm, heading)| WirePose {
        x_mm,
        y_mm,
        heading,
    })
}

fn arb_slot() -> impl Strategy<Value = Slot> {
    (any::<u16>(), 0u16..16384).prop_map(|(distance_mm, bearing)| Slot {
        distance_mm,
        bearing,
    })
}

fn arb_mode() -> impl Strategy<Value = RobotMode> {
    prop_oneof![
        Just(RobotMode::Idle),
        Just(RobotMode::Joining),
        Just(RobotMode::InFormation),
        Just(RobotMode::Transforming),
        Just(RobotMode::Failsafe),
        Just(RobotMode::Leading),
        Just(RobotMode::EmergencyStop),
    ]
}

fn arb_message() -> impl Strategy<Value = Message> {
    prop_oneof![
        (arb_pose(), any::<i16>(), any::<i16>(), any::<u8>()).prop_map(|(pose, v, w, blend)| {
            Message::LeaderState(LeaderState {
                pose,
                twist: WireTwist::new(v, w),
                blend,
            })
        }),
        (any::<i16>(), any::<i16>()).prop_map(|(v, w)| Message::VelocityCommand(VelocityCommand {
            v_mm_s: v,
            omega_mrad_s: w
        })),
        (arb_pose(), any::<u16>())
            .prop_map(|(pose, sigma_mm)| Message::PoseFix(PoseFix { pose, sigma_mm })),
        (
            arb_pose(),
            any::<[i16; 2]>(),
            arb_mode(),
            any::<u16>(),
            any::<u16>(),
            any::<[u32; 3]>()
        )
            .prop_map(|(pose, wheel_mm_s, mode, e, faults, l)| {
                Message::Telemetry(Telemetry {
                    pose,
                    wheel_mm_s,
                    mode,
                    tracking_error_mm: e,
                    faults,
                    link: LinkCounters {
                        received: l[0],
                        rejected: l[1],
                        lost: l[2],
                    },
                })
            }),
        (any::<u16>(), any::<u16>(), arb_slot(), arb_slot()).prop_map(|(n, i, wide, line)| {
            Message::FormationCommand(FormationCommand {
                followers: n,
                index: i,
                wide,
                line,
                report_every: 1,
            })
        }),
        any::<u8>().prop_map(|status| Message::Heartbeat(Heartbeat { status })),
        any::<u8>().prop_map(|reason| Message::Stop(Stop { reason })),
        any::<u8>().prop_map(|reason| Message::EmergencyStop(EmergencyStop { reason })),
        any::<u8>().prop_map(|reason| Message::Resume(Resume { reason })),
        any::<u64>().prop_map(|nonce| Message::Hello(Hello { nonce })),
        (any::<u64>(), any::<u32>(), any::<u32>()).prop_map(|(nonce, session, broadcast_seq)| {
            Message::Welcome(Welcome {
                nonce,
                session,
                broadcast_seq,
            })
        }),
        (any::<i32>(), any::<i32>())
            .prop_map(|(x_mm, y_mm)| Message::Detour(Detour { x_mm, y_mm })),
    ]
}

fn header(id: u8, from: Address, to: Address, seq: u32, time_ms: u32) -> Header {
    Header {
        version: PROTOCOL_VERSION,
        id,
        from,
        to,
        seq,
        time_ms,
    }
}

fn expect(session: u32, seq: u32, time_ms: u32) -> Expect {
    Expect {
        session,
        seq,
        time_ms,
    }
}

/// Feeds bytes to a decoder and opens every frame expecting `e`.
fn decode_all(bytes: &[u8], e: Expect) -> Vec<Result<(Header, Message), Reject>> {
    let k = key();
    let mut dec = FrameDecoder::new();
    let mut out = Vec::new();
    for &b in bytes {
        if let Some(r) = dec.push(b) {
            out.push(r.and_then(|raw| frame::open(&k, raw, |_| Ok(e))));
        }
    }
    out
}

proptest! {
    #[test]
    fn every_message_round_trips(
        m in arb_message(), from in arb_address(), to in arb_address(),
        seq in any::<u32>(), t in any::<u32>(), s in any::<u32>(),
        lost in 0u32..=223, age in 0u32..3584,
    ) {
        // The receiver expects an earlier frame (`lost` of them missed) and its estimate of
        // the sender's clock is `age` later than the stamp: the header is still whole.
        let h = header(m.id(), from, to, seq, t);
        let mut wire = [0u8; MAX_WIRE];
        let n = frame::seal(&key(), s, &h, &m, &mut wire).unwrap();
        prop_assert_eq!(wire[n - 1], 0);
        prop_assert!(!wire[..n - 1].contains(&0));
        let near = expect(s, seq.wrapping_sub(lost), t.wrapping_add(age));
        let got = decode_all(&wire[..n], near);
        prop_assert_eq!(got, vec![Ok((h, m))]);
    }

    #[test]
    fn a_header_completed_out_of_reach_never_verifies(
        seq in any::<u32>(), t in any::<u32>(), lost in 224u32..1_000_000,
        age in 3584u32..1_000_000, which in 0usize..3,
    ) {
        // Beyond the reach of the low bits, a receiver completes the header wrongly: the
        // tag, over the whole values, refuses the frame. Nothing is misread.
        let m = Message::Heartbeat(Heartbeat { status: 1 });
        let h = header(m.id(), Address::Base, Address::Broadcast, seq, t);
        let mut wire = [0u8; MAX_WIRE];
        let n = frame::seal(&key(), 3, &h, &m, &mut wire).unwrap();
        let near = match which {
            0 => expect(3, seq.wrapping_sub(lost), t),
            1 => expect(3, seq, t.wrapping_add(age)),
            _ => expect(3, seq.wrapping_add(SEQ_BEHIND + 1 + lost % 200), t),
        };
        prop_assert_eq!(decode_all(&wire[..n], near), vec![Err(Reject::BadTag)]);
    }

    #[test]
    fn a_leader_state_takes_at_most_26_bytes_on_the_wire(
        x in -1_048_575i32..=1_048_575, y in -1_048_575i32..=1_048_575,
        heading in 0u16..16384, v in any::<i16>(), w in any::<i16>(), blend in any::<u8>(),
        seq in any::<u32>(), t in any::<u32>(),
    ) {
        // Within 1,048 m of the site's origin, at any point of a run's clock.
        let m = Message::LeaderState(LeaderState {
            pose: WirePose { x_mm: x, y_mm: y, heading },
            twist: WireTwist::new(v, w),
            blend,
        });
        let h = header(m.id(), Address::Base, Address::Broadcast, seq, t);
        let mut wire = [0u8; MAX_WIRE];
        let n = frame::seal(&key(), 3, &h, &m, &mut wire).unwrap();
        let far = x.abs() >= 8192 && y.abs() >= 8192 && heading >= 128;
        prop_assert!(n <= 26 && (n == 26 || !far), "{n} bytes");
    }

    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
        for r in decode_all(&bytes, expect(1, 1, 1)) {
            // Random bytes must not forge a tag.
            prop_assert!(r.is_err());
        }
    }

    #[test]
    fn garbage_between_frames_loses_only_damaged_frames(
        msgs in proptest::collection::vec(arb_message(), 1..8),
        garbage in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..40), 8),
    ) {
        let mut stream = Vec::new();
        let mut sent = Vec::new();
        for (i, m) in msgs.iter().enumerate() {
            // Garbage ends with a delimiter so it cannot merge with the next frame.
            stream.extend_from_slice(&garbage[i]);
            stream.push(0);
            let h = header(m.id(), Address::Base, Address::Broadcast, i as u32, 7);
            let mut wire = [0u8; MAX_WIRE];
            let n = frame::seal(&key(), 9, &h, m, &mut wire).unwrap();
            stream.extend_from_slice(&wire[..n]);
            sent.push((h, *m));
        }
        let got: Vec<_> = decode_all(&stream, expect(9, 0, 7)).into_iter().filter_map(Result::ok).collect();
        prop_assert_eq!(got, sent);
    }

    #[test]
    fn a_dropped_or_flipped_byte_costs_one_frame(m in arb_message(), at in any::<prop::sample::Index>(), flip in 1u8..=255, drop in any::<bool>()) {
        let h = header(m.id(), Address::Base, Address::Robot(3), 5, 6);
        let mut wire = [0u8; MAX_WIRE];
        let n = frame::seal(&key(), 1, &h, &m, &mut wire).unwrap();
        let mut damaged = wire[..n - 1].to_vec();
        let i = at.index(damaged.len());
        if drop { damaged.remove(i); } else { damaged[i] ^= flip; }
        let mut stream = damaged;
        stream.push(0);
        stream.extend_from_slice(&wire[..n]);
        let got = decode_all(&stream, expect(1, 5, 6));
        prop_assert_eq!(got.last().cloned(), Some(Ok((h, m))));
        prop_assert!(got[..got.len() - 1].iter().all(|r| r.is_err()));
    }
}

#[test]
fn rejects_carry_reasons() {
    let k = key();
    let m = Message::Heartbeat(Heartbeat { status: 1 });
    let h = header(m.id(), Address::Base, Address::Robot(1), 1, 1);
    let mut wire = [0u8; MAX_WIRE];
    let n = frame::seal(&k, 1, &h, &m, &mut wire).unwrap();
    let mut raw = wire[..n - 1].to_vec();
    let len = cobs::decode_in_place(&mut raw).unwrap();
    let raw = &raw[..len];

    let wrong = FleetKey::from_bytes(&[1; 32]);
    assert_eq!(
        frame::open(&wrong, raw, |_| Ok(expect(1, 1, 1))),
        Err(Reject::BadTag)
    );
    assert_eq!(
        frame::open(&k, raw, |_| Ok(expect(2, 1, 1))),
        Err(Reject::BadTag)
    );
    assert_eq!(
        frame::open(&k, &raw[..5], |_| Ok(expect(1, 1, 1))),
        Err(Reject::Truncated)
    );
    let mut v = raw.to_vec();
    v[0] = ((PROTOCOL_VERSION + 1) << 5) | (v[0] & 0x1f);
    assert_eq!(
        frame::open(&k, &v, |_| Ok(expect(1, 1, 1))),
        Err(Reject::UnknownVersion)
    );
    v[0] = (PROTOCOL_VERSION << 5) | 31;
    assert_eq!(
        frame::open(&k, &v, |_| Ok(expect(1, 1, 1))),
        Err(Reject::UnknownMessage)
    );
    assert_eq!(
        frame::open(&k, raw, |_| Err(Reject::UnknownSession)),
        Err(Reject::UnknownSession)
    );

    let mut dec = FrameDecoder::new();
    let long = [1u8; MAX_WIRE + 10];
    assert!(long.iter().all(|b| dec.push(*b).is_none()));
    assert_eq!(dec.push(0), Some(Err(Reject::TooLong)));
    for b in [5u8, 1, 1] {
        assert!(dec.push(b).is_none());
    }
    assert_eq!(dec.push(0), Some(Err(Reject::BadCobs)));
}

#[test]
fn a_valid_tag_over_a_bad_payload_is_malformed() {
    // Sign a Heartbeat body with trailing junk using the Heartbeat schema key.
    let k = key();
    let mut body = vec![(PROTOCOL_VERSION << 5) | Heartbeat::ID];
    body.extend_from_slice(&[0x12, 0x10, 0x00]); // to broadcast, from base, seq 1, t 1
    body.extend_from_slice(&[1, 99]); // status 1 and a trailing byte
    let stamp = [1, 0, 0, 0, 1, 0, 0, 0]; // the whole seq and time the tag covers
    let tag = k.tag(&Heartbeat::SCHEMA_KEY, 5, &[&stamp, &body]);
    body.extend_from_slice(&tag);
    let got = frame::open(&k, &body, |_| Ok(expect(5, 1, 1)));
    assert_eq!(got, Err(Reject::Malformed));
}

/// One fixed frame per message kind, checked into `golden/frames.txt`. Any change of
/// the wire format shows in review as a change of that file; regenerate it with
/// `UPDATE_GOLDEN=1 cargo test -p protocol --test wire golden`.
#[test]
fn golden_vectors() {
    let k = FleetKey::from_bytes(&core::array::from_fn(|i| i as u8));
    let pose = WirePose {
        x_mm: 12_345,
        y_mm: -6_789,
        heading: 4096,
    };
    let slot = Slot {
        distance_mm: 3000,
        bearing: 6827,
    };
    let messages = [
        Message::LeaderState(LeaderState {
            pose,
            twist: WireTwist::new(400, -120),
            blend: 0,
        }),
        Message::VelocityCommand(VelocityCommand {
            v_mm_s: 400,
            omega_mrad_s: 60,
        }),
        Message::PoseFix(PoseFix { pose, sigma_mm: 20 }),
        Message::Telemetry(Telemetry {
            pose,
            wheel_mm_s: [390, 410],
            mode: RobotMode::InFormation,
            tracking_error_mm: 42,
            faults: 0,
            link: LinkCounters {
                received: 1000,
                rejected: 3,
                lost: 50,
            },
        }),
        Message::FormationCommand(FormationCommand {
            followers: 2,
            index: 0,
            wide: slot,
            line: Slot {
                distance_mm: 1500,
                bearing: 8192,
            },
            report_every: 1,
        }),
        Message::Heartbeat(Heartbeat { status: 0 }),
        Message::Stop(Stop { reason: 1 }),
        Message::EmergencyStop(EmergencyStop { reason: 2 }),
        Message::Resume(Resume { reason: 0 }),
        Message::Hello(Hello {
            nonce: 0x0000_0007_0000_0001,
        }),
        Message::Welcome(Welcome {
            nonce: 0x0000_0007_0000_0001,
            session: 0xdead_beef,
            broadcast_seq: 1234,
        }),
        Message::Detour(Detour {
            x_mm: 12_345,
            y_mm: -6_789,
        }),
    ];
    let mut text = String::new();
    for m in &messages {
        let to = match m {
            Message::LeaderState(_) | Message::PoseFix(_) => Address::Broadcast,
            Message::Telemetry(_) | Message::Welcome(_) => Address::Base,
            _ => Address::Robot(1),
        };
        let from = match m {
            Message::Telemetry(_) | Message::Welcome(_) => Address::Robot(1),
            _ => Address::Base,
        };
        let h = header(m.id(), from, to, 100_000, 3_600_000);
        let mut wire = [0u8; MAX_WIRE];
        let n = frame::seal(&k, 0x0102_0304, &h, m, &mut wire).unwrap();
        text.push_str(&format!("{} {}\n", m.name(), hex::encode(&wire[..n])));
    }
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/golden/frames.txt");
    if std::env::var_os("UPDATE_GOLDEN").is_some() {
        std::fs::write(path, &text).unwrap();
    }
    let expected = std::fs::read_to_string(path).expect("golden/frames.txt is checked in");
    assert_eq!(
        text, expected,
        "the wire format changed: review golden/frames.txt"
    );
}
