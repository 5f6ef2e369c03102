//! The lockstep link's transport: two host FIFOs, `lockstep.in` and `lockstep.out`, opened
//! through semihosting relative to QEMU's working directory (the harness makes one per
//! robot). One semihosting call moves a whole buffer; QEMU's CMSDK UART model moved one
//! byte per interrupt and per host syscall, which capped a run at about 10× real time.
//! Reads block: the firmware has nothing to do until the simulator's next step, and under
//! `-icount` a blocked call takes no virtual time.

use protocol::body::{self, FromMcu, ToMcu, MAX_BODY_FRAME};
use semihosting::fs::File;
use semihosting::io::{Read, Write};

/// Bytes asked of the host per read, and collected per write.
const BUFFER: usize = 512;

pub struct Link {
    input: File,
    output: File,
    inbox: [u8; BUFFER],
    start: usize,
    end: usize,
    outbox: heapless::Vec<u8, BUFFER>,
}

impl Link {
    pub fn open() -> Self {
        match (File::open(c"lockstep.in"), File::create(c"lockstep.out")) {
            (Ok(input), Ok(output)) => Self {
                input,
                output,
                inbox: [0; BUFFER],
                start: 0,
                end: 0,
                outbox: heapless::Vec::new(),
            },
            _ => {
                defmt::error!("cannot open the lockstep FIFOs in QEMU's working directory");
                semihosting::process::exit(2)
            }
        }
    }

    /// The next message, decoded in `frame`; `None` for a malformed or oversized frame
    /// (dropped and logged). Blocks until the simulator sends it.
    pub fn receive<'f>(&mut self, frame: &'f mut [u8; MAX_BODY_FRAME + 2]) -> Option<ToMcu<'f>> {
        let mut len = 0;
        let mut overflow = false;
        loop {
            if self.start == self.end {
                self.fill();
            }
            let byte = self.inbox[self.start];
            self.start += 1;
            if byte == 0 {
                break;
            }
            if len == frame.len() {
                overflow = true;
            } else {
                frame[len] = byte;
                len += 1;
            }
        }
        if overflow {
            defmt::warn!("body frame too long: dropped");
            return None;
        }
        match body::decode::<ToMcu>(&mut frame[..len]) {
            Ok(msg) => Some(msg),
            Err(_) => {
                defmt::warn!("malformed body frame: dropped");
                None
            }
        }
    }

    fn fill(&mut self) {
        match self.input.read(&mut self.inbox) {
            Ok(n) if n > 0 => (self.start, self.end) = (0, n),
            _ => {
                defmt::error!("the lockstep link closed");
                semihosting::process::exit(3)
            }
        }
    }

    /// Queues a message; [`Link::flush`] sends what is queued in one write.
    pub fn send(&mut self, msg: &FromMcu) {
        let mut buf = [0u8; MAX_BODY_FRAME];
        let Ok(n) = body::encode(msg, &mut buf) else {
            defmt::error!("body message does not encode");
            return;
        };
        if self.outbox.capacity() - self.outbox.len() < n {
            self.flush();
        }
        let _ = self.outbox.extend_from_slice(&buf[..n]);
    }

    pub fn flush(&mut self) {
        if !self.outbox.is_empty() && self.output.write_all(&self.outbox).is_err() {
            defmt::error!("the lockstep link closed");
            semihosting::process::exit(3)
        }
        self.outbox.clear();
    }
}
