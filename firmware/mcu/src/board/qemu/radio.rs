//! The radio as the tasks see it on the QEMU board: two bounded pipes the lockstep link
//! fills and drains. `embedded_io_async::{Read, Write}`, the traits embassy-stm32's
//! `BufferedUart` gives the same tasks on the NUCLEO.

use core::convert::Infallible;

use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::pipe::Pipe;

/// Bytes buffered each way (a period's frames fit; more waits for the reader).
pub const BUFFER: usize = 512;

/// Bytes the simulated radio delivered, waiting for the receive task.
pub static RECEIVED: Pipe<CriticalSectionRawMutex, BUFFER> = Pipe::new();
/// Bytes the transmit task wrote, waiting for the lockstep link.
pub static TRANSMITTED: Pipe<CriticalSectionRawMutex, BUFFER> = Pipe::new();

pub struct Rx;
pub struct Tx;

impl embedded_io_async::ErrorType for Rx {
    type Error = Infallible;
}

impl embedded_io_async::Read for Rx {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        Ok(RECEIVED.read(buf).await)
    }
}

impl embedded_io_async::ErrorType for Tx {
    type Error = Infallible;
}

impl embedded_io_async::Write for Tx {
    async fn write(&mut self, buf: &[u8]) -> Result<usize, Infallible> {
        Ok(TRANSMITTED.write(buf).await)
    }

    async fn flush(&mut self) -> Result<(), Infallible> {
        Ok(())
    }
}
