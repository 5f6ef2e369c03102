// The `frame_decoder` fuzz target's body: arbitrary bytes into the stream decoder and a
// linked receiver; nothing may panic, and nothing random may authenticate. Included by the
// fuzz target and by `protocol/tests/fuzz_regressions.rs`, which replays the crash inputs
// checked in under `fuzz/regressions/frame_decoder` through this same body.

/// One input through the decoder and the receiver.
pub fn frame_decoder(data: &[u8]) {
    use protocol::link::{Event, Link, Timing};
    use protocol::{Address, FleetKey, FrameDecoder};
    let mut link: Link<2> = Link::new(
        Address::Robot(1),
        FleetKey::from_bytes(&[3; 32]),
        1,
        0,
        Timing::default(),
    );
    link.add_peer(Address::Base, FleetKey::from_bytes(&[4; 32]));
    let mut dec = FrameDecoder::new();
    for (i, &b) in data.iter().enumerate() {
        if let Some(frame) = dec.push(b) {
            let r = link.receive(frame, i as u32);
            assert!(!matches!(
                r,
                Ok(Event::Message { .. }) | Ok(Event::Linked { .. }) | Ok(Event::Synced { .. })
            ));
        }
    }
}
