//! The CMSDK APB UART of the mps2 boards, without a PAC: receive interrupt → a bounded
//! pipe; transmit polls the TX-full flag (QEMU's chardev never overruns). Implements
//! `embedded_io_async::{Read, Write}`, the traits embassy-stm32's `BufferedUart` gives the
//! tasks on the real board.

use core::convert::Infallible;
use core::ptr::{read_volatile, write_volatile};

use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::pipe::Pipe;

const DATA: usize = 0x00;
const STATE: usize = 0x04;
const CTRL: usize = 0x08;
const INTCLEAR: usize = 0x0C;
const BAUDDIV: usize = 0x10;

const STATE_TX_FULL: u32 = 1 << 0;
const STATE_RX_FULL: u32 = 1 << 1;
const CTRL_TX_EN: u32 = 1 << 0;
const CTRL_RX_EN: u32 = 1 << 1;
const CTRL_RX_INT_EN: u32 = 1 << 3;

/// Bytes buffered between the interrupt and the reading task.
pub const RX_BUFFER: usize = 1024;

pub struct Port {
    base: usize,
    rx: &'static Pipe<CriticalSectionRawMutex, RX_BUFFER>,
}

fn reg(base: usize, off: usize) -> *mut u32 {
    (base + off) as *mut u32
}

impl Port {
    pub const fn new(base: usize, rx: &'static Pipe<CriticalSectionRawMutex, RX_BUFFER>) -> Self {
        Self { base, rx }
    }

    /// Enables transmit, receive and the receive interrupt.
    pub fn enable(&self) {
        // SAFETY: the UART's registers on mps2-an386; nothing else owns this UART.
        unsafe {
            write_volatile(reg(self.base, BAUDDIV), 16);
            write_volatile(
                reg(self.base, CTRL),
                CTRL_TX_EN | CTRL_RX_EN | CTRL_RX_INT_EN,
            );
        }
    }

    /// The receive interrupt: move bytes into the pipe while it has room. A full pipe
    /// leaves the byte in the UART (QEMU then holds the sender back): nothing is lost.
    pub fn on_rx_interrupt(&self) {
        // SAFETY: registers as above; called from this UART's interrupt only.
        unsafe {
            while read_volatile(reg(self.base, STATE)) & STATE_RX_FULL != 0
                && self.rx.free_capacity() > 0
            {
                let byte = read_volatile(reg(self.base, DATA)) as u8;
                let _ = self.rx.try_write(&[byte]);
            }
            write_volatile(reg(self.base, INTCLEAR), 1 << 1);
        }
    }

    /// Picks up bytes the interrupt left in the UART while the pipe was full.
    fn drain(&self) {
        critical_section::with(|_| self.on_rx_interrupt());
    }

    pub fn write_byte(&self, byte: u8) {
        // SAFETY: registers as above.
        unsafe {
            while read_volatile(reg(self.base, STATE)) & STATE_TX_FULL != 0 {}
            write_volatile(reg(self.base, DATA), byte as u32);
        }
    }
}

pub struct Rx(pub &'static Port);
pub struct Tx(pub &'static Port);

impl embedded_io_async::ErrorType for Rx {
    type Error = Infallible;
}

impl embedded_io_async::Read for Rx {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        let n = self.0.rx.read(buf).await;
        self.0.drain();
        Ok(n)
    }
}

impl embedded_io_async::ErrorType for Tx {
    type Error = Infallible;
}

impl embedded_io_async::Write for Tx {
    async fn write(&mut self, buf: &[u8]) -> Result<usize, Infallible> {
        for &b in buf {
            self.0.write_byte(b);
        }
        Ok(buf.len())
    }

    async fn flush(&mut self) -> Result<(), Infallible> {
        Ok(())
    }
}
