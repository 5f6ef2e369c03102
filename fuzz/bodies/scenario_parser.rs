// The `scenario_parser` fuzz target's body: arbitrary text into the scenario parser; it
// either loads or names the file, line and field of the problem, and never panics.
// Included by the fuzz target and by `host/core/tests/fuzz_regressions.rs`.

/// One input through the parser.
pub fn scenario_parser(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data) {
        if let Err(e) = base_station::scenario::Scenario::parse(text, "fuzz.toml") {
            assert!(e.to_string().starts_with("fuzz.toml"));
        }
    }
}
