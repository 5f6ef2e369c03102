//! Inputs that once crashed the `frame_decoder` fuzz target (fuzz/regressions/), replayed
//! through the fuzz target's own body, its "nothing random authenticates" included.

include!("../../fuzz/bodies/frame_decoder.rs");

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
        frame_decoder(&std::fs::read(&path).unwrap());
        replayed += 1;
    }
    println!("{replayed} crash inputs replayed");
}
