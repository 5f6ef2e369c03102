//! The robot's tasks, the same on every board.

mod control;
mod radio;
mod watchdog;

use embassy_executor::Spawner;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::mutex::Mutex;
use embedded_io_async::Write;

use crate::board::{Body, RadioRx, RadioTx};
use crate::robot;

/// The radio's transmit side, shared by the tasks that answer and report.
static RADIO_TX: Mutex<CriticalSectionRawMutex, Option<RadioTx>> = Mutex::new(None);

/// Sends bytes over the radio and counts them.
pub async fn radio_send(bytes: &[u8]) {
    if bytes.is_empty() {
        return;
    }
    let mut tx = RADIO_TX.lock().await;
    if let Some(tx) = tx.as_mut() {
        if tx.write_all(bytes).await.is_ok() {
            robot::count(&robot::RADIO_TX_BYTES, bytes.len());
        } else {
            defmt::warn!("radio write failed");
        }
    }
}

/// Spawns the tasks once the node is configured.
pub fn start(spawner: Spawner, rx: RadioRx, tx: RadioTx, body: Body) {
    if let Ok(mut slot) = RADIO_TX.try_lock() {
        *slot = Some(tx);
    }
    spawner.spawn(radio::radio_rx_task(rx).unwrap());
    spawner.spawn(control::control_task(body).unwrap());
    spawner.spawn(watchdog::watchdog_task().unwrap());
}
