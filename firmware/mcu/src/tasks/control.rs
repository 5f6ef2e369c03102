//! The 10 Hz control loop: sensors in, the node's step (wheel PIDs, the L-φ law on
//! followers, modes, telemetry), motor duties out.

use core::sync::atomic::Ordering;

use embassy_time::{Duration, Instant, Ticker};
use heapless::Vec;

use crate::board::{self, Body};
use crate::robot;

pub const PERIOD_MS: u64 = 100;

#[embassy_executor::task]
pub async fn control_task(mut body: Body) {
    let mut ticker = Ticker::every(Duration::from_millis(PERIOD_MS));
    board::control_scheduled(Instant::now().as_micros() + PERIOD_MS * 1000);
    loop {
        ticker.next().await;
        let now = Instant::now();
        let sensors = body.sensors();
        let start = board::cycles();
        let mut tx: Vec<u8, 256> = Vec::new();
        let out = robot::with_node(|node| {
            node.tick(robot::millis(now), &sensors, &mut |bytes| {
                let _ = tx.extend_from_slice(bytes);
            })
        })
        .unwrap_or_default();
        robot::STEP_CYCLES.store(board::cycles_since(start), Ordering::Release);
        body.drive(&out);
        super::radio_send(&tx).await;
        board::control_scheduled(now.as_micros() + PERIOD_MS * 1000);
        robot::count(&robot::CONTROL_TICKS, 1);
    }
}
