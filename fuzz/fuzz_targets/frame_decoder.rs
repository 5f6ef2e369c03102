//! Arbitrary bytes into the stream decoder and a linked receiver: nothing may panic, and
//! nothing random may authenticate (the body: `fuzz/bodies/frame_decoder.rs`).
#![no_main]

include!("../bodies/frame_decoder.rs");

libfuzzer_sys::fuzz_target!(|data: &[u8]| frame_decoder(data));
