//! The QEMU board's time driver: the simulator's clock. Time moves only when the body
//! link says so ([`advance_to`]); due timers then wake. So the firmware's clock is the
//! simulated world's clock (minus the robot's boot time), whatever QEMU's own speed.

use core::cell::{Cell, RefCell};
use core::task::Waker;

use critical_section::Mutex;
use embassy_time_queue_utils::Queue;

struct SimClock {
    now: Mutex<Cell<u64>>,
    queue: Mutex<RefCell<Queue>>,
}

impl embassy_time_driver::Driver for SimClock {
    fn now(&self) -> u64 {
        critical_section::with(|cs| self.now.borrow(cs).get())
    }

    fn schedule_wake(&self, at: u64, waker: &Waker) {
        critical_section::with(|cs| {
            if at <= self.now.borrow(cs).get() {
                // Due already: wake this one alone. Waking the queue would also run the
                // timers [`set`] made due (the control period) before the step's radio
                // bytes are processed, and without its sensors.
                waker.wake_by_ref();
            } else {
                self.queue.borrow(cs).borrow_mut().schedule_wake(at, waker);
            }
        });
    }
}

embassy_time_driver::time_driver_impl!(static CLOCK: SimClock = SimClock {
    now: Mutex::new(Cell::new(0)),
    queue: Mutex::new(RefCell::new(Queue::new())),
});

/// Moves the clock to `t` µs (never backwards) without waking timers yet: bytes that
/// arrived before `t` are processed at `t`, before anything scheduled for `t` runs.
pub fn set(t: u64) {
    critical_section::with(|cs| {
        let now = CLOCK.now.borrow(cs);
        if t > now.get() {
            now.set(t);
        }
    });
}

/// Wakes the timers due by now.
pub fn wake_due() {
    critical_section::with(|cs| {
        let now = CLOCK.now.borrow(cs).get();
        CLOCK.queue.borrow(cs).borrow_mut().next_expiration(now);
    });
}
