//! The QEMU board, `mps2-an386` (Cortex-M4F): the simulated body and the radio behind one
//! lockstep link (semihosting FIFOs), the simulator's clock as time driver, a WFI
//! executor, defmt over semihosting (QEMU's stdout), exit codes through semihosting.

mod clock;
mod executor;
mod link;
mod radio;

use core::cell::Cell;
use core::sync::atomic::Ordering;

use control_core::controller::{MotorOutput, Sensors};
use control_core::odometry::PoseFixSample;
use control_core::Pose;
use cortex_m::peripheral::syst::SystClkSource;
use critical_section::Mutex;
use embassy_executor::Spawner;
use embassy_futures::yield_now;
use protocol::body::{BodySensors, Done, FirmwareFault, FromMcu, ToMcu, MAX_RADIO_CHUNK};

use crate::robot;
use link::Link;

use defmt_semihosting as _;

pub use executor::run;

pub type RadioRx = radio::Rx;
pub type RadioTx = radio::Tx;

/// What the body link last reported, and what the motors were last told.
static SENSORS: Mutex<Cell<Option<BodySensors>>> = Mutex::new(Cell::new(None));
static DUTY: Mutex<Cell<[f32; 2]>> = Mutex::new(Cell::new([0.0; 2]));
/// When the control task's next period is due, µs.
static NEXT_TICK_US: Mutex<Cell<u64>> = Mutex::new(Cell::new(u64::MAX));

defmt::timestamp!("{=u64:us}", embassy_time::Instant::now().as_micros());

pub fn init() {
    let mut core = cortex_m::Peripherals::take().expect("first and only take");
    // SysTick free-running: it measures a control step (25 MHz, virtual under -icount).
    core.SYST.set_clock_source(SystClkSource::Core);
    core.SYST.set_reload(0x00FF_FFFF);
    core.SYST.clear_current();
    core.SYST.enable_counter();
}

/// SysTick's count now (it counts down).
pub fn cycles() -> u32 {
    cortex_m::peripheral::SYST::get_current()
}

pub fn cycles_since(start: u32) -> u32 {
    start.wrapping_sub(cycles()) & 0x00FF_FFFF
}

pub fn control_scheduled(at_us: u64) {
    critical_section::with(|cs| NEXT_TICK_US.borrow(cs).set(at_us));
}

pub fn motors_off() {
    critical_section::with(|cs| DUTY.borrow(cs).set([0.0; 2]));
}

/// The simulated body has no hardware watchdog to feed.
pub fn feed_watchdog() {}

/// The body as the control task sees it: sensors from the last step, duties to the next.
pub struct Body;

impl Body {
    pub fn sensors(&mut self) -> Sensors {
        let s = critical_section::with(|cs| SENSORS.borrow(cs).take());
        match s {
            Some(s) => Sensors {
                ticks: s.ticks,
                pose_fix: s.pose_fix.map(|(x, y, h, sigma, t)| PoseFixSample {
                    pose: Pose::new(x, y, h),
                    sigma,
                    time_ms: t,
                }),
                proximity: s.proximity,
            },
            None => Sensors::default(),
        }
    }

    pub fn drive(&mut self, out: &MotorOutput) {
        critical_section::with(|cs| DUTY.borrow(cs).set(out.duty));
    }
}

/// Moves what the transmit task wrote into the link, in chunks.
fn drain_radio(link: &mut Link) {
    let mut chunk = [0u8; MAX_RADIO_CHUNK];
    while let Ok(n) = radio::TRANSMITTED.try_read(&mut chunk) {
        link.send(&FromMcu::Radio(&chunk[..n]));
    }
}

/// The lockstep link to the simulated body: configuration at boot, then per step: `Step`
/// and the radio bytes that arrived by its time in; the clock moves to the step's time,
/// those bytes are processed, the timers due by then fire (a control period); then the
/// bytes transmitted and `Done` out.
#[embassy_executor::task]
pub async fn body_task(spawner: Spawner) {
    let mut link = Link::open();
    let mut frame: Frame = [0u8; protocol::body::MAX_BODY_FRAME + 2];
    let config = loop {
        if let Some(ToMcu::Config(c)) = link.receive(&mut frame) {
            break c;
        }
    };
    robot::configure(config);
    crate::tasks::start(spawner, radio::Rx, radio::Tx, Body);
    // The tasks start at boot time, before the first step moves the clock.
    while critical_section::with(|cs| NEXT_TICK_US.borrow(cs).get()) == u64::MAX {
        yield_now().await;
    }
    link.send(&FromMcu::Ready);
    link.flush();
    let mut received = 0u32;
    loop {
        let step = next_step(&mut link, &mut frame);
        clock::set(step.time_us);
        received = take_radio(&mut link, &mut frame, &step, received).await;
        if step.sensors.is_some() {
            critical_section::with(|cs| SENSORS.borrow(cs).set(step.sensors));
        }
        let due = critical_section::with(|cs| NEXT_TICK_US.borrow(cs).get()) <= step.time_us;
        let before = robot::CONTROL_TICKS.load(Ordering::Acquire);
        clock::wake_due();
        if due {
            while robot::CONTROL_TICKS.load(Ordering::Acquire) == before {
                yield_now().await;
            }
        }
        finish_step(&mut link, &step, due).await;
    }
}

/// A body frame's buffer.
type Frame = [u8; protocol::body::MAX_BODY_FRAME + 2];

/// The next `Step` from the harness (a fault it injects is carried out here).
fn next_step(link: &mut Link, frame: &mut Frame) -> protocol::body::Step {
    loop {
        match link.receive(frame) {
            Some(ToMcu::Step(step)) => return step,
            Some(ToMcu::Inject(FirmwareFault::Panic)) => panic!("injected by the harness"),
            Some(ToMcu::Inject(FirmwareFault::Hang)) => {
                defmt::warn!("hanging, as the harness asked");
                #[allow(clippy::empty_loop)]
                loop {}
            }
            Some(_) => {
                // Not formatted: that pulled in the body messages' defmt code, 556 B of flash.
                defmt::warn!("unexpected body message outside a step: dropped");
            }
            None => {}
        }
    }
}

/// The step's radio bytes, handed to the radio task and taken by it; the count received
/// so far.
async fn take_radio(
    link: &mut Link,
    frame: &mut Frame,
    step: &protocol::body::Step,
    mut received: u32,
) -> u32 {
    while received != step.radio_rx_bytes {
        match link.receive(frame) {
            Some(ToMcu::Radio(bytes)) => {
                radio::RECEIVED.write_all(bytes).await;
                received = received.wrapping_add(bytes.len() as u32);
            }
            _ => {
                defmt::error!("the step's radio bytes are missing");
                received = step.radio_rx_bytes;
            }
        }
    }
    while robot::RADIO_RX_BYTES.load(Ordering::Acquire) != received {
        yield_now().await;
    }
    received
}

/// Lets anything else the new time woke (the watchdog) run and the transmit task write
/// out what this step produced; then `Done`.
async fn finish_step(link: &mut Link, step: &protocol::body::Step, due: bool) {
    yield_now().await;
    loop {
        drain_radio(link);
        if crate::tasks::radio_idle() && radio::TRANSMITTED.is_empty() {
            break;
        }
        yield_now().await;
    }
    let done = Done {
        time_us: step.time_us,
        radio_tx_bytes: robot::RADIO_TX_BYTES.load(Ordering::Acquire),
        duty: critical_section::with(|cs| DUTY.borrow(cs).get()),
        ticked: due,
        step_cycles: robot::STEP_CYCLES.load(Ordering::Acquire),
        rx_cycles: robot::RX_CYCLES.swap(0, Ordering::AcqRel),
        rejects: robot::with_node(|node| node.link().stats().rejects).unwrap_or_default(),
    };
    link.send(&FromMcu::Done(done));
    link.flush();
}

/// Logs and exits QEMU with 101. Neither the message nor the location: formatting them
/// keeps every panic site's strings in flash (~7 KiB, docs/firmware.md#size); the harness
/// shows the log lines before it.
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    defmt::error!("panic");
    semihosting::process::exit(101)
}

/// No device interrupts on this board (the lockstep link is semihosting, SysTick is
/// polled): one vector instead of cortex-m-rt's generic 240 (~1 KiB of flash).
#[unsafe(link_section = ".vector_table.interrupts")]
#[unsafe(no_mangle)]
static __INTERRUPTS: [unsafe extern "C" fn(); 1] = [{
    unsafe extern "C" {
        fn DefaultHandler();
    }
    DefaultHandler
}];
