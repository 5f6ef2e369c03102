//! Inputs that once crashed the `frame_decoder` fuzz target (fuzz/regressions/), replayed.

use protocol::link::{Link, Timing};
use protocol::{Address, FleetKey, FrameDecoder};

#[test]
fn crash_inputs_stay_fixed() {
    let dir = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../fuzz/regressions/frame_decoder"
    );
    let mut replayed = 0;
    for entry in std::fs::read_dir(dir).expect("the regressions folder is checked in") {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy();
        if name.starts_with('.') || name.ends_with(".md") {
            continue;
        }
        let data = std::fs::read(&path).unwrap();
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
                let _ = link.receive(frame, i as u32);
            }
        }
        replayed += 1;
    }
    println!("{replayed} crash inputs replayed");
}
