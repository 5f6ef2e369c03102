//! Streaming frame decoder for a byte pipe (UART, serial radio, UDP datagrams).
//!
//! Bytes accumulate until a `0x00` delimiter; then the `cobs` crate decodes them in place.
//! Garbage, a truncated frame or a dropped byte damages only the frame it falls in: the
//! next delimiter resynchronises. An over-long run is discarded up to the next delimiter.

use crate::{Reject, MAX_WIRE};

/// A fixed-size decoder: no heap, `MAX_WIRE` bytes of buffer.
pub struct FrameDecoder {
    buf: [u8; MAX_WIRE],
    len: usize,
    overflowed: bool,
}

impl Default for FrameDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameDecoder {
    pub const fn new() -> Self {
        Self {
            buf: [0; MAX_WIRE],
            len: 0,
            overflowed: false,
        }
    }

    /// Feeds one byte. On a delimiter that ends a frame, returns the COBS-decoded frame
    /// (not yet authenticated) or why it was dropped. Empty frames (`00 00`) are ignored.
    pub fn push(&mut self, byte: u8) -> Option<Result<&[u8], Reject>> {
        if byte != 0 {
            if self.len < self.buf.len() {
                self.buf[self.len] = byte;
                self.len += 1;
            } else {
                self.overflowed = true;
            }
            return None;
        }
        let len = core::mem::take(&mut self.len);
        if core::mem::take(&mut self.overflowed) {
            return Some(Err(Reject::TooLong));
        }
        if len == 0 {
            return None;
        }
        match cobs::decode_in_place(&mut self.buf[..len]) {
            Ok(n) if n > 0 => Some(Ok(&self.buf[..n])),
            _ => Some(Err(Reject::BadCobs)),
        }
    }

    /// Drops a partly received frame (e.g. after a link reset).
    pub fn reset(&mut self) {
        self.len = 0;
        self.overflowed = false;
    }
}
