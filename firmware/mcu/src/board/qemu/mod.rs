//! The QEMU board, `mps2-an386` (Cortex-M4F): the radio on UART0, the simulated body on
//! UART1 (lockstep link), the simulator's clock as time driver, a WFI executor, defmt over
//! semihosting (QEMU's stdout), exit codes through semihosting.

mod clock;
mod executor;
mod uart;

use core::cell::Cell;
use core::sync::atomic::Ordering;

use control_core::controller::{MotorOutput, Sensors};
use control_core::odometry::PoseFixSample;
use control_core::Pose;
use cortex_m::peripheral::syst::SystClkSource;
use critical_section::Mutex;
use embassy_executor::Spawner;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::pipe::Pipe;
use embedded_io_async::{Read, Write};
use heapless::Vec;
use protocol::body::{self, BodySensors, Done, FirmwareFault, FromMcu, ToMcu, MAX_BODY_FRAME};

use crate::robot::{self, Config};

use defmt_semihosting as _;

pub use executor::run;

pub type RadioRx = uart::Rx;
pub type RadioTx = uart::Tx;

static RADIO_PIPE: Pipe<CriticalSectionRawMutex, { uart::RX_BUFFER }> = Pipe::new();
static BODY_PIPE: Pipe<CriticalSectionRawMutex, { uart::RX_BUFFER }> = Pipe::new();
static RADIO_UART: uart::Port = uart::Port::new(0x4000_4000, &RADIO_PIPE);
static BODY_UART: uart::Port = uart::Port::new(0x4000_5000, &BODY_PIPE);

/// What the body link last reported, and what the motors were last told.
static SENSORS: Mutex<Cell<Option<BodySensors>>> = Mutex::new(Cell::new(None));
static DUTY: Mutex<Cell<[f32; 2]>> = Mutex::new(Cell::new([0.0; 2]));
/// When the control task's next period is due, µs.
static NEXT_TICK_US: Mutex<Cell<u64>> = Mutex::new(Cell::new(u64::MAX));
/// Radio bytes the current step lets through (those that arrived before its time).
static RADIO_ALLOWED: Mutex<Cell<u32>> = Mutex::new(Cell::new(0));
static RADIO_GATE: embassy_sync::signal::Signal<CriticalSectionRawMutex, ()> =
    embassy_sync::signal::Signal::new();

/// How many radio bytes may be processed now; waits for the next step when none.
pub async fn radio_allowance() -> usize {
    loop {
        let allowed = critical_section::with(|cs| RADIO_ALLOWED.borrow(cs).get());
        let left = allowed.wrapping_sub(robot::RADIO_RX_BYTES.load(Ordering::Acquire));
        if left > 0 && left < u32::MAX / 2 {
            return left as usize;
        }
        RADIO_GATE.wait().await;
    }
}

defmt::timestamp!("{=u64:us}", embassy_time::Instant::now().as_micros());

pub struct Board {
    radio: (uart::Rx, uart::Tx),
    body: (uart::Rx, uart::Tx),
}

#[derive(Clone, Copy)]
struct Irq(u16);

// SAFETY: mps2-an386 external interrupt numbers.
unsafe impl cortex_m::interrupt::InterruptNumber for Irq {
    fn number(self) -> u16 {
        self.0
    }
}

const UART0_RX: u16 = 0;
const UART1_RX: u16 = 2;

pub fn init() -> Board {
    let mut core = cortex_m::Peripherals::take().expect("first and only take");
    // SysTick free-running: it measures a control step (25 MHz, virtual under -icount).
    core.SYST.set_clock_source(SystClkSource::Core);
    core.SYST.set_reload(0x00FF_FFFF);
    core.SYST.clear_current();
    core.SYST.enable_counter();
    RADIO_UART.enable();
    BODY_UART.enable();
    // SAFETY: the handlers below only touch their UART and its pipe.
    unsafe {
        cortex_m::peripheral::NVIC::unmask(Irq(UART0_RX));
        cortex_m::peripheral::NVIC::unmask(Irq(UART1_RX));
    }
    Board {
        radio: (uart::Rx(&RADIO_UART), uart::Tx(&RADIO_UART)),
        body: (uart::Rx(&BODY_UART), uart::Tx(&BODY_UART)),
    }
}

#[cortex_m_rt::exception]
unsafe fn DefaultHandler(irqn: i16) {
    match irqn as u16 {
        UART0_RX => RADIO_UART.on_rx_interrupt(),
        UART1_RX => BODY_UART.on_rx_interrupt(),
        _ => {}
    }
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

async fn read_frame(
    rx: &mut uart::Rx,
    frame: &mut Vec<u8, { MAX_BODY_FRAME + 2 }>,
) -> Option<ToMcu> {
    frame.clear();
    let mut byte = [0u8];
    loop {
        let _ = rx.read(&mut byte).await;
        if frame.push(byte[0]).is_err() {
            defmt::warn!("body frame too long: dropped");
            frame.clear();
            continue;
        }
        if byte[0] == 0 {
            return match body::decode::<ToMcu>(frame) {
                Ok(msg) => Some(msg),
                Err(_) => {
                    defmt::warn!("malformed body frame: dropped");
                    None
                }
            };
        }
    }
}

async fn send(tx: &mut uart::Tx, msg: &FromMcu) {
    let mut buf = [0u8; MAX_BODY_FRAME];
    if let Ok(n) = body::encode(msg, &mut buf) {
        let _ = tx.write_all(&buf[..n]).await;
    }
}

/// The lockstep link to the simulated body: configuration at boot, then one `Step` in,
/// one `Done` out. The clock moves to the step's time, the radio bytes that came before it
/// are processed, then the timers due by then fire (a control period), then `Done`.
#[embassy_executor::task]
pub async fn body_task(spawner: Spawner, board: Board) {
    let Board { radio, body } = board;
    let (mut rx, mut tx) = body;
    let mut frame = Vec::new();
    loop {
        if let Some(ToMcu::Config(c)) = read_frame(&mut rx, &mut frame).await {
            robot::configure(Config {
                id: c.id,
                leader: c.leader,
                boot_count: c.boot_count,
                key: c.key,
            });
            break;
        }
    }
    crate::tasks::start(spawner, radio.0, radio.1, Body);
    send(&mut tx, &FromMcu::Ready).await;
    loop {
        let step = match read_frame(&mut rx, &mut frame).await {
            Some(ToMcu::Step(step)) => step,
            Some(ToMcu::Inject(FirmwareFault::Panic)) => panic!("injected by the harness"),
            Some(ToMcu::Inject(FirmwareFault::Hang)) => {
                defmt::warn!("hanging, as the harness asked");
                #[allow(clippy::empty_loop)]
                loop {}
            }
            _ => continue,
        };
        clock::set(step.time_us);
        critical_section::with(|cs| RADIO_ALLOWED.borrow(cs).set(step.radio_rx_bytes));
        RADIO_GATE.signal(());
        while robot::RADIO_RX_BYTES.load(Ordering::Acquire) < step.radio_rx_bytes {
            embassy_futures::yield_now().await;
        }
        if step.sensors.is_some() {
            critical_section::with(|cs| SENSORS.borrow(cs).set(step.sensors));
        }
        let due = critical_section::with(|cs| NEXT_TICK_US.borrow(cs).get()) <= step.time_us;
        let before = robot::CONTROL_TICKS.load(Ordering::Acquire);
        clock::wake_due();
        if due {
            while robot::CONTROL_TICKS.load(Ordering::Acquire) == before {
                embassy_futures::yield_now().await;
            }
        }
        // Let anything else the new time woke (the watchdog) run, and the transmit task
        // write out what this step produced.
        embassy_futures::yield_now().await;
        while !crate::tasks::radio_idle() {
            embassy_futures::yield_now().await;
        }
        let done = Done {
            time_us: step.time_us,
            radio_tx_bytes: robot::RADIO_TX_BYTES.load(Ordering::Acquire),
            duty: critical_section::with(|cs| DUTY.borrow(cs).get()),
            ticked: due,
            step_cycles: robot::STEP_CYCLES.load(Ordering::Acquire),
            rx_cycles: robot::RX_CYCLES.swap(0, Ordering::AcqRel),
        };
        send(&mut tx, &FromMcu::Done(done)).await;
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    defmt::error!("panic: {}", defmt::Display2Format(info));
    semihosting::process::exit(101)
}
