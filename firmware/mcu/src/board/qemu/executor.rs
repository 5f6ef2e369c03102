//! An executor that sleeps with WFI when nothing is pending. QEMU treats WFE as a plain
//! yield, so the stock thread executor would spin at 100 % of a host core.

use core::sync::atomic::{AtomicBool, Ordering};

use embassy_executor::{raw, Spawner};
use static_cell::StaticCell;

static EXECUTOR: StaticCell<raw::Executor> = StaticCell::new();
static PENDING: AtomicBool = AtomicBool::new(false);

#[unsafe(export_name = "__pender")]
fn __pender(_context: *mut ()) {
    PENDING.store(true, Ordering::Release);
}

pub fn run(init: impl FnOnce(Spawner)) -> ! {
    let executor: &'static raw::Executor = EXECUTOR.init(raw::Executor::new(core::ptr::null_mut()));
    init(executor.spawner());
    loop {
        PENDING.store(false, Ordering::Release);
        // SAFETY: polled from this one thread only.
        unsafe { executor.poll() };
        cortex_m::interrupt::free(|_| {
            if !PENDING.load(Ordering::Acquire) {
                // Wakes on any interrupt, even masked; the handler runs after `free`.
                cortex_m::asm::wfi();
            }
        });
    }
}
