//! The robot firmware: one image for every robot. `main` initialises the board and spawns
//! the tasks; the control code is `control-core`, the radio protocol `protocol`.
//!
//! Tasks: `control_task` (10 Hz: wheel PIDs, the L-φ law on followers, telemetry),
//! `radio_rx_task` (frames in: decoder, authentication, replay window), `radio_tx_task`
//! (telemetry and handshake answers out, from a bounded queue), `watchdog_task` (stalled
//! control loop → motors off), and on the QEMU board `body_task` (the lockstep link to the
//! simulated body). Statics and bounded queues only: no heap.
#![no_std]
#![no_main]

#[cfg(all(feature = "board-qemu", feature = "board-nucleo"))]
compile_error!("select exactly one board: board-nucleo is the default; for QEMU use --no-default-features --features board-qemu");
#[cfg(not(any(feature = "board-qemu", feature = "board-nucleo")))]
compile_error!("select a board: --features board-qemu or --features board-nucleo");

#[cfg_attr(feature = "board-qemu", path = "board/qemu/mod.rs")]
#[cfg_attr(feature = "board-nucleo", path = "board/nucleo.rs")]
mod board;
mod robot;
mod tasks;

#[cfg(feature = "board-qemu")]
#[cortex_m_rt::entry]
fn main() -> ! {
    board::init();
    board::run(|spawner| {
        // The body link delivers the configuration, then starts the other tasks.
        spawner.spawn(board::body_task(spawner).unwrap());
    })
}

#[cfg(feature = "board-nucleo")]
#[embassy_executor::main]
async fn main(spawner: embassy_executor::Spawner) {
    let board = board::init();
    if let Some(config) = board.config {
        robot::configure(config);
    }
    tasks::start(spawner, board.radio_rx, board.radio_tx, board.body);
}
