//! Arbitrary text into the scenario parser: it either loads or names the file, line and
//! field of the problem; it never panics.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        if let Err(e) = base_station::scenario::Scenario::parse(text, "fuzz.toml") {
            assert!(e.to_string().starts_with("fuzz.toml"));
        }
    }
});
