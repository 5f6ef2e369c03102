//! Inputs that once crashed the `scenario_parser` fuzz target (fuzz/regressions/),
//! replayed through the fuzz target's own body.

include!("../../../fuzz/bodies/scenario_parser.rs");

#[test]
fn crash_inputs_stay_fixed() {
    let dir = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fuzz/regressions/scenario_parser"
    );
    for entry in std::fs::read_dir(dir).expect("the regressions folder is checked in") {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy();
        if name.starts_with('.') || name.ends_with(".md") {
            continue;
        }
        scenario_parser(&std::fs::read(&path).unwrap());
    }
}
