//! Radio receive: bytes from the modem UART into the node (frame decoder,
//! authentication, replay window); handshake answers go straight back out.

use embassy_time::Instant;
use embedded_io_async::Read;
use heapless::Vec;

use crate::board::{self, RadioRx};
use crate::robot;

#[embassy_executor::task]
pub async fn radio_rx_task(mut rx: RadioRx) {
    let mut buf = [0u8; 64];
    loop {
        let n = match rx.read(&mut buf).await {
            Ok(n) => n,
            Err(_) => {
                defmt::warn!("radio read error");
                continue;
            }
        };
        let now_ms = robot::millis(Instant::now());
        let mut answers: Vec<u8, 256> = Vec::new();
        let started = board::cycles();
        robot::with_node(|node| {
            node.receive(&buf[..n], now_ms, &mut |bytes| {
                let _ = answers.extend_from_slice(bytes);
            })
        });
        robot::count(&robot::RX_CYCLES, board::cycles_since(started) as usize);
        super::radio_send(&answers).await;
        robot::count(&robot::RADIO_RX_BYTES, n);
    }
}
