//! The lockstep link between a robot's MCU and the simulator when the body is simulated:
//! the firmware in QEMU reaches encoders, motors, sensors and its radio through it.
//! Postcard + COBS (postcard's own COBS support); not authenticated: it is a cable inside
//! the robot, not a radio (the radio's bytes ride in it unchanged, still authenticated).
//!
//! The simulator, not the wall clock, decides when time advances: every [`Step`] carries
//! the simulated time, the firmware's clock jumps to it, the radio bytes that arrived by
//! then follow in [`ToMcu::Radio`] chunks, and the firmware answers with what it
//! transmitted ([`FromMcu::Radio`]) and [`Done`] once everything due by then has run. A
//! period's bytes move in a few frames, not one by one. See `docs/firmware.md`.

use serde::{Deserialize, Serialize};

use crate::RejectCounts;

/// Largest radio chunk in one body message.
pub const MAX_RADIO_CHUNK: usize = 256;
/// Largest body message on the wire (a radio chunk, COBS overhead included).
pub const MAX_BODY_FRAME: usize = MAX_RADIO_CHUNK + 8;

/// Simulator → MCU.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ToMcu<'a> {
    /// At boot: what a real robot reads from its configuration flash page.
    Config(BodyConfig),
    /// Advance to `time_us`; the radio bytes up to `radio_rx_bytes` follow.
    Step(Step),
    /// Fault injection for the harness's own tests: make the firmware fail.
    Inject(FirmwareFault),
    /// Radio bytes received, in order (at most [`MAX_RADIO_CHUNK`]).
    Radio(&'a [u8]),
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
    /// What the board's noise source gives at this boot (the simulated board has none).
    pub entropy: u32,
    /// The configuration page's keys (`protocol::config_page`).
    pub broadcast_key: [u8; 32],
    pub robot_key: [u8; 32],
}

#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Step {
    /// The firmware's clock from now on, µs since its boot.
    pub time_us: u64,
    /// Radio bytes received since boot, once the [`ToMcu::Radio`] chunks that follow
    /// this step are counted: all processed at `time_us`, before the timers due then.
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
pub enum FromMcu<'a> {
    /// Configured, tasks running.
    Ready,
    /// Radio bytes transmitted, in order (at most [`MAX_RADIO_CHUNK`]), before the
    /// step's [`Done`].
    Radio(&'a [u8]),
    Done(Done),
}

#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Done {
    pub time_us: u64,
    /// Radio bytes transmitted since boot (the [`FromMcu::Radio`] chunks before this
    /// one included).
    pub radio_tx_bytes: u32,
    pub duty: [f32; 2],
    /// Whether a control period ran in this step.
    pub ticked: bool,
    /// SysTick counts (25 MHz virtual clock under `-icount`) the last control step took.
    pub step_cycles: u32,
    /// SysTick counts spent receiving radio bytes (deframing, verifying, decoding) in this
    /// step.
    pub rx_cycles: u32,
    /// Frames rejected since boot, by reason.
    pub rejects: RejectCounts,
}

/// Encodes a body message as COBS bytes ending in 0x00.
pub fn encode<T: Serialize>(msg: &T, out: &mut [u8]) -> Result<usize, postcard::Error> {
    postcard::to_slice_cobs(msg, out).map(|s| s.len())
}

/// Decodes one COBS frame (with or without its 0x00).
pub fn decode<'a, T: Deserialize<'a>>(frame: &'a mut [u8]) -> Result<T, postcard::Error> {
    postcard::from_bytes_cobs(frame)
}
