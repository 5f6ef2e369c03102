//! Arbitrary text into the scenario parser: it either loads or names the file, line and
//! field of the problem; it never panics (the body: `fuzz/bodies/scenario_parser.rs`).
#![no_main]

include!("../bodies/scenario_parser.rs");

libfuzzer_sys::fuzz_target!(|data: &[u8]| scenario_parser(data));
