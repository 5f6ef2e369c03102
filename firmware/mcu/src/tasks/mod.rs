//! The robot's tasks, the same on every board.

mod control;
mod radio;
mod watchdog;

use core::sync::atomic::{AtomicU32, Ordering};

use embassy_executor::Spawner;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
use embedded_io_async::Write;
use heapless::Vec;

use crate::board::{Body, RadioRx, RadioTx};
use crate::robot;

/// Largest chunk queued for the radio (a few frames).
const CHUNK: usize = 128;

/// Frames waiting for the radio: telemetry from the control task, handshake answers from
/// the receive task. Bounded: a full queue makes the producer wait, nothing is dropped.
static RADIO_OUT: Channel<CriticalSectionRawMutex, Vec<u8, CHUNK>, 6> = Channel::new();
/// Chunks queued and not yet written.
static RADIO_PENDING: AtomicU32 = AtomicU32::new(0);

/// Queues bytes for the radio.
pub async fn radio_send(bytes: &[u8]) {
    for chunk in bytes.chunks(CHUNK) {
        let Ok(v) = Vec::from_slice(chunk) else {
            continue;
        };
        RADIO_PENDING.fetch_add(1, Ordering::AcqRel);
        RADIO_OUT.send(v).await;
    }
}

/// True when everything queued has been written to the radio (the lockstep link waits
/// for it).
#[cfg(feature = "board-qemu")]
pub fn radio_idle() -> bool {
    RADIO_PENDING.load(Ordering::Acquire) == 0
}

/// Telemetry and answers out: drains the queue into the radio UART.
#[embassy_executor::task]
async fn radio_tx_task(mut tx: RadioTx) {
    loop {
        let chunk = RADIO_OUT.receive().await;
        if tx.write_all(&chunk).await.is_ok() {
            robot::count(&robot::RADIO_TX_BYTES, chunk.len());
        } else {
            defmt::warn!("radio write failed");
        }
        RADIO_PENDING.fetch_sub(1, Ordering::AcqRel);
    }
}

/// Spawns the tasks once the node is configured.
pub fn start(spawner: Spawner, rx: RadioRx, tx: RadioTx, body: Body) {
    spawner.spawn(radio_tx_task(tx).unwrap());
    spawner.spawn(radio::radio_rx_task(rx).unwrap());
    spawner.spawn(control::control_task(body).unwrap());
    spawner.spawn(watchdog::watchdog_task().unwrap());
}
