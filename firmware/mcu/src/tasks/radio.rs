//! Radio receive: bytes from the modem UART into the node (frame decoder,
//! authentication, replay window); handshake answers go straight back out.
//!
//! The board may gate how many bytes are processed (the QEMU board's lockstep link lets
//! through exactly the bytes that arrived before the current simulated time).

use embassy_time::Instant;
use embedded_io_async::Read;
use heapless::Vec;

use crate::board::{self, RadioRx};
use crate::robot;

#[embassy_executor::task]
pub async fn radio_rx_task(mut rx: RadioRx) {
    let mut buf = [0u8; 64];
    let (mut start, mut end) = (0usize, 0usize);
    loop {
        if start == end {
            start = 0;
            end = match rx.read(&mut buf).await {
                Ok(n) => n,
                Err(_) => {
                    defmt::warn!("radio read error");
                    0
                }
            };
            continue;
        }
        let allowed = board::radio_allowance().await;
        let n = (end - start).min(allowed);
        let now_ms = Instant::now().as_millis() as u32;
        let mut answers: Vec<u8, 256> = Vec::new();
        let started = board::cycles();
        robot::with_node(|node| {
            node.receive(&buf[start..start + n], now_ms, &mut |bytes| {
                let _ = answers.extend_from_slice(bytes);
            })
        });
        robot::count(&robot::RX_CYCLES, board::cycles_since(started) as usize);
        start += n;
        super::radio_send(&answers).await;
        robot::count(&robot::RADIO_RX_BYTES, n);
    }
}
