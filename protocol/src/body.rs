//! The wire between a robot's MCU and its body when the body is simulated: the firmware
//! in QEMU reaches encoders, motors and sensors through a second UART that the
//! simulator serves, in lockstep. Postcard + COBS (postcard's own COBS support); not
//! authenticated: it is a cable inside the robot, not a radio.
//!
//! The simulator, not the wall clock, decides when time advances: every [`Step`] carries
//! the simulated time, the firmware's clock jumps to it, and the firmware answers with
//! [`Done`] once everything due by then has run. See `docs/firmware.md`.

use serde::{Deserialize, Serialize};

/// Largest body message on the wire.
pub const MAX_BODY_FRAME: usize = 96;

/// Simulator → MCU.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ToMcu {
    /// At boot: what a real robot reads from its configuration flash page.
    Config(BodyConfig),
    /// Advance to `time_us`, after the radio bytes counted in `radio_rx_bytes`.
    Step(Step),
    /// Fault injection for the harness's own tests: make the firmware fail.
    Inject(FirmwareFault),
}

/// How a firmware under test is made to fail.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FirmwareFault {
    /// Panic (the panic handler logs and exits QEMU with 101).
    Panic,
    /// Spin forever without yielding: the executor and the lockstep link stop.
    Hang,
}

#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BodyConfig {
    pub id: u16,
    pub leader: bool,
    pub boot_count: u32,
    pub key: [u8; 32],
}

#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Step {
    /// The firmware's clock from now on, µs since its boot.
    pub time_us: u64,
    /// Radio bytes written to the radio UART so far: process them all before the time
    /// moves (the two UARTs are two sockets; this orders them).
    pub radio_rx_bytes: u32,
    /// Sensors, when a control period is due at this time.
    pub sensors: Option<BodySensors>,
}

#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BodySensors {
    pub ticks: [i32; 2],
    /// x, y (m), heading (rad), σ (m), time (ms, firmware clock).
    pub pose_fix: Option<(f32, f32, f32, f32, u32)>,
    pub proximity: [Option<f32>; 2],
}

/// MCU → simulator.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FromMcu {
    /// Configured, tasks running.
    Ready,
    Done(Done),
}

#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Done {
    pub time_us: u64,
    /// Radio bytes written to the radio UART so far.
    pub radio_tx_bytes: u32,
    pub duty: [f32; 2],
    /// Whether a control period ran in this step.
    pub ticked: bool,
    /// SysTick counts (25 MHz virtual clock under `-icount`) the last control step took.
    pub step_cycles: u32,
    /// SysTick counts spent receiving radio bytes (deframing, verifying, decoding) in this
    /// step.
    pub rx_cycles: u32,
}

/// Encodes a body message as COBS bytes ending in 0x00.
pub fn encode<T: Serialize>(msg: &T, out: &mut [u8]) -> Result<usize, postcard::Error> {
    postcard::to_slice_cobs(msg, out).map(|s| s.len())
}

/// Decodes one COBS frame (with or without its 0x00).
pub fn decode<'a, T: Deserialize<'a>>(frame: &'a mut [u8]) -> Result<T, postcard::Error> {
    postcard::from_bytes_cobs(frame)
}
