//! NUCLEO-F411RE (STM32F411RE, Cortex-M4F; its ST-LINK speaks to probe-rs). It runs on the
//! internal 16 MHz oscillator, embassy's default: a period's work takes about 2 ms of its
//! 100 ms there, and the PLL's setup to the rated 100 MHz would cost 384 B of flash.
//!
//! Pin map (Arduino header names in brackets):
//!
//! | function | pins | peripheral |
//! | --- | --- | --- |
//! | radio modem UART, 115200 8N1 | TX PA9 [D8], RX PA10 [D2] | USART1 |
//! | left motor PWM (20 kHz) / direction | PA0 [A0] / PB0 [A3] | TIM2 CH1, GPIO |
//! | right motor PWM (20 kHz) / direction | PA1 [A1] / PA4 [A2] | TIM2 CH2, GPIO |
//! | left encoder A / B | PA6 [D12] / PA7 [D11] | TIM3 encoder mode |
//! | right encoder A / B | PB6 [D10] / PB7 [CN7-21] | TIM4 encoder mode |
//!
//! Configuration page: flash sector 6 (0x0804_0000, written with `probe-rs download`);
//! boot counter: flash sector 7 (0x0806_0000), one word appended per boot (provisioned with
//! its first word; an empty or unwritable log keeps the robot from linking).

use core::cell::RefCell;

use control_core::controller::{MotorOutput, Sensors};
use embassy_stm32::flash::Flash;
use embassy_stm32::gpio::{Level, Output, OutputType, Speed};
use embassy_stm32::peripherals::{IWDG, TIM2, TIM3, TIM4};
use embassy_stm32::timer::low_level::{CountingMode, OutputCompareMode, Timer};
use embassy_stm32::timer::qei::{Config as QeiConfig, Qei};
use embassy_stm32::timer::simple_pwm::PwmPin;
use embassy_stm32::timer::{Ch1, Ch2, Channel};
use embassy_stm32::usart::{self, BufferedUart};
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::Peri;
use embassy_stm32::{bind_interrupts, peripherals};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use protocol::config_page::{ConfigPage, CONFIG_PAGE_LEN};
use static_cell::StaticCell;

use crate::robot::Config;

use {defmt_rtt as _, panic_probe as _};

bind_interrupts!(struct Irqs {
    USART1 => usart::BufferedInterruptHandler<peripherals::USART1>;
});

pub type RadioRx = usart::BufferedUartRx<'static>;
pub type RadioTx = usart::BufferedUartTx<'static>;

const CONFIG_OFFSET: u32 = 0x4_0000;
const BOOT_LOG_OFFSET: u32 = 0x6_0000;
const BOOT_LOG_LEN: u32 = 0x2_0000;

static WATCHDOG: Mutex<
    CriticalSectionRawMutex,
    RefCell<Option<IndependentWatchdog<'static, IWDG>>>,
> = Mutex::new(RefCell::new(None));

pub struct Board {
    pub radio_rx: RadioRx,
    pub radio_tx: RadioTx,
    pub body: Body,
    pub config: Option<Config>,
}

/// Increments the boot counter: a log of words in sector 7, the newest one last,
/// provisioned with a first word (`robot-config`). Fails closed (`None`: the robot does
/// not link) when the new count does not read back, and when the log is empty: never
/// provisioned, or a wrap's erase was cut by a power loss; counting again from 1 would
/// repeat sessions.
fn next_boot_count(flash: &mut Flash<'_, embassy_stm32::flash::Blocking>) -> Option<u32> {
    // Read through the memory map: written words first, then erased ones (append-only).
    let base = (embassy_stm32::flash::FLASH_BASE as u32 + BOOT_LOG_OFFSET) as *const u32;
    let words = (BOOT_LOG_LEN / 4) as usize;
    // SAFETY: sector 7 is mapped flash, only ever written by this function.
    let log = unsafe { core::slice::from_raw_parts(base, words) };
    let used = log.partition_point(|w| *w != u32::MAX);
    let mut slot = used as u32 * 4;
    let last = used.checked_sub(1).map(|i| log[i]);
    let Some(last) = last else {
        defmt::error!("boot counter empty (not provisioned, or its erase was cut): not linking");
        return None;
    };
    let next = last.checked_add(1).filter(|n| *n != u32::MAX)?;
    if slot >= BOOT_LOG_LEN {
        // Power lost from here to the write leaves the log empty: fail closed next boot.
        flash
            .blocking_erase(BOOT_LOG_OFFSET, BOOT_LOG_OFFSET + BOOT_LOG_LEN)
            .ok()?;
        slot = 0;
    }
    let written = flash.blocking_write(BOOT_LOG_OFFSET + slot, &next.to_le_bytes());
    // SAFETY: as above; read back after the write.
    let stored = unsafe { core::ptr::read_volatile(base.add(slot as usize / 4)) };
    if written.is_err() || stored != next {
        defmt::error!("boot counter did not persist: not linking");
        return None;
    }
    Some(next)
}

/// Fresh at every power-up, unique to the chip: SRAM's power-up state (cell noise; kept
/// across a warm reset, where it is stirred on) mixed with the 96-bit unique id. The F411
/// has no RNG; the nonces need uniqueness, not secrecy.
fn boot_entropy() -> u32 {
    #[unsafe(link_section = ".uninit.entropy")]
    static mut POOL: core::mem::MaybeUninit<[u32; 64]> = core::mem::MaybeUninit::uninit();
    let mix = |x: u32, v: u32| (x ^ v).wrapping_mul(0x9E37_79B1).rotate_left(13);
    let mut x = embassy_stm32::uid::uid().chunks_exact(4).fold(0, |x, w| {
        mix(x, u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
    });
    // SAFETY: read before anything else touches the pool (once, at boot); volatile: the
    // compiler must not assume what an uninitialised section holds.
    let pool = core::ptr::addr_of_mut!(POOL).cast::<u32>();
    for i in 0..64 {
        unsafe {
            x = mix(x, core::ptr::read_volatile(pool.add(i)));
            core::ptr::write_volatile(pool.add(i), x);
        }
    }
    x
}

pub fn init() -> Board {
    let p = embassy_stm32::init(Default::default());

    let mut flash = Flash::new_blocking(p.FLASH);
    let entropy = boot_entropy();
    // SAFETY: sector 6 is mapped flash, written only at provisioning.
    let page = unsafe {
        &*((embassy_stm32::flash::FLASH_BASE as u32 + CONFIG_OFFSET)
            as *const [u8; CONFIG_PAGE_LEN])
    };
    let config = ConfigPage::decode(page).and_then(|c| {
        Some(Config {
            id: c.id,
            leader: c.leader,
            boot_count: next_boot_count(&mut flash)?,
            entropy,
            broadcast_key: c.broadcast_key,
            robot_key: c.robot_key,
        })
    });
    if config.is_none() {
        defmt::error!("no valid configuration page at 0x0804_0000: the robot will not drive");
    }

    static TX_BUF: StaticCell<[u8; 512]> = StaticCell::new();
    static RX_BUF: StaticCell<[u8; 512]> = StaticCell::new();
    let uart = BufferedUart::new(
        p.USART1,
        p.PA10,
        p.PA9,
        TX_BUF.init([0; 512]),
        RX_BUF.init([0; 512]),
        Irqs,
        usart::Config::default(),
    )
    .expect("USART1 at 115200 8N1");
    let (radio_tx, radio_rx) = uart.split();

    let pwm = MotorPwm::new(
        p.TIM2,
        PwmPin::new(p.PA0, OutputType::PushPull),
        PwmPin::new(p.PA1, OutputType::PushPull),
    );
    let left = Qei::new(p.TIM3, p.PA6, p.PA7, QeiConfig::default());
    let right = Qei::new(p.TIM4, p.PB6, p.PB7, QeiConfig::default());

    let mut wdg = IndependentWatchdog::new(p.IWDG, 500_000);
    wdg.unleash();
    WATCHDOG.lock(|w| *w.borrow_mut() = Some(wdg));

    let mut core = cortex_m::Peripherals::take().expect("first and only take");
    core.DCB.enable_trace();
    core.DWT.enable_cycle_counter();

    Board {
        radio_rx,
        radio_tx,
        body: Body {
            left,
            right,
            last: [0; 2],
            ticks: [0; 2],
            pwm,
            dir: [
                Output::new(p.PB0, Level::Low, Speed::Low),
                Output::new(p.PA4, Level::Low, Speed::Low),
            ],
        },
        config,
    }
}

/// The robot's body: encoders in, motor PWM and direction out.
pub struct Body {
    left: Qei<'static, TIM3>,
    right: Qei<'static, TIM4>,
    last: [u16; 2],
    ticks: [i32; 2],
    pwm: MotorPwm,
    dir: [Output<'static>; 2],
}

/// The motors' PWM frequency, Hz.
const PWM_HZ: u32 = 20_000;

/// TIM2's channels 1 and 2 as the motors' PWM, edge-aligned at [`PWM_HZ`]. Set up from the
/// timer's clock with one 32-bit division: embassy-stm32's `SimplePwm` computes its
/// prescaler with a 64-bit one, whose routine alone is 864 B of flash (docs/firmware.md).
pub struct MotorPwm {
    timer: Timer<'static, TIM2>,
    /// Timer clocks per PWM period.
    period: u32,
    // Kept: dropping a pin takes it off the timer.
    _pins: (PwmPin<'static, TIM2, Ch1>, PwmPin<'static, TIM2, Ch2>),
}

impl MotorPwm {
    fn new(
        tim: Peri<'static, TIM2>,
        left: PwmPin<'static, TIM2, Ch1>,
        right: PwmPin<'static, TIM2, Ch2>,
    ) -> Self {
        let timer = Timer::new(tim);
        // 800 clocks at the 16 MHz of the default clock tree, 5,000 at 100 MHz: no
        // prescaler needed.
        let period = embassy_stm32::rcc::frequency::<TIM2>().0 / PWM_HZ;
        timer.set_counting_mode(CountingMode::EdgeAlignedUp);
        timer.regs_core().psc().write_value(0);
        timer.set_max_compare_value(period - 1);
        for channel in [Channel::Ch1, Channel::Ch2] {
            timer.set_output_compare_mode(channel, OutputCompareMode::PwmMode1);
            timer.set_output_compare_preload(channel, true);
            timer.set_compare_value(channel, 0);
            timer.enable_channel(channel, true);
        }
        timer.set_autoreload_preload(true);
        timer.generate_update_event();
        timer.start();
        Self {
            timer,
            period,
            _pins: (left, right),
        }
    }

    /// Duty of `channel` in thousandths (at most 1000).
    fn set(&mut self, channel: Channel, permille: u32) {
        let compare = permille.min(1000) * self.period / 1000;
        self.timer.set_compare_value(channel, compare);
    }
}

impl Body {
    pub fn sensors(&mut self) -> Sensors {
        let now = [self.left.count(), self.right.count()];
        for ((ticks, now), last) in self.ticks.iter_mut().zip(now).zip(self.last) {
            // 16-bit timers: extend through the wrapping difference.
            *ticks = ticks.wrapping_add(now.wrapping_sub(last) as i16 as i32);
        }
        self.last = now;
        Sensors {
            ticks: self.ticks,
            pose_fix: None,
            proximity: [None, None],
        }
    }

    pub fn drive(&mut self, out: &MotorOutput) {
        for (i, duty) in out.duty.iter().enumerate() {
            let level = if *duty < 0.0 { Level::High } else { Level::Low };
            self.dir[i].set_level(level);
            let permille = (duty.abs().min(1.0) * 1000.0) as u32;
            let channel = [Channel::Ch1, Channel::Ch2][i];
            self.pwm.set(channel, permille);
        }
    }
}

pub fn cycles() -> u32 {
    cortex_m::peripheral::DWT::cycle_count()
}

pub fn cycles_since(start: u32) -> u32 {
    cycles().wrapping_sub(start)
}

/// The real clock needs no lockstep bookkeeping.
pub fn control_scheduled(_at_us: u64) {}

/// Stops feeding the independent watchdog: the MCU resets within 0.5 s, its PWM pins go
/// high-impedance and the motor drivers' pull-downs stop the motors.
pub fn motors_off() {
    defmt::error!("control loop stalled: waiting for the watchdog reset");
}

pub fn feed_watchdog() {
    WATCHDOG.lock(|w| {
        if let Some(w) = w.borrow_mut().as_mut() {
            w.pet();
        }
    });
}
