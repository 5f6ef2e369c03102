//! The watchdog: if the control loop stops ticking, the motors stop (and on hardware the
//! independent watchdog resets the MCU). Stale leader state is the control core's
//! failsafe; this guards against the loop itself dying.

use core::sync::atomic::Ordering;

use embassy_time::Timer;

use crate::{board, robot};

#[embassy_executor::task]
pub async fn watchdog_task() {
    let mut last = robot::CONTROL_TICKS.load(Ordering::Acquire);
    loop {
        Timer::after_millis(350).await;
        let now = robot::CONTROL_TICKS.load(Ordering::Acquire);
        if now == last {
            defmt::error!("control loop stalled: motors off");
            board::motors_off();
        } else {
            board::feed_watchdog();
        }
        last = now;
    }
}
