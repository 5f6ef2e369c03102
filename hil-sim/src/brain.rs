//! A robot's brain: the control code that runs on its MCU. The native brain is the control
//! core compiled for the host; the QEMU brain ([`crate::qemu`]) runs the real firmware
//! ELF. Both see the same radio bytes, the same sensors, the same clock.
//!
//! A step is split in two so that the world can start every robot's step before waiting
//! for any (QEMU processes then run in parallel).

use std::fmt;

use control_core::config::RobotConfig;
use control_core::controller::{MotorOutput, Sensors};
use control_core::node::{Identity, RobotNode};
use protocol::messages::RobotMode;
use protocol::{MasterKey, RejectCounts};

/// A brain that stopped working (a crashed or hung firmware).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BrainError(pub String);

impl fmt::Display for BrainError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for BrainError {}

pub trait Brain {
    /// Starts a step at `local_us` (the robot's own clock: µs since it booted): the radio
    /// bytes that arrived since the last step, then, with `sensors`, a control period.
    fn step_start(
        &mut self,
        local_us: u64,
        radio: &[u8],
        sensors: Option<&Sensors>,
    ) -> Result<(), BrainError>;
    /// Ends it: radio bytes to transmit go to `tx`; motor duties if a period ran.
    fn step_finish(&mut self, tx: &mut Vec<u8>) -> Result<Option<MotorOutput>, BrainError>;
    /// The robot's mode, for logs and plots.
    fn mode(&self) -> RobotMode;
    /// Frames the robot's radio rejected since it booted, by reason.
    fn rejects(&self) -> RejectCounts;
    /// SysTick counts of each control step, where the brain measures them (firmware).
    fn step_cycles(&self) -> Vec<u32> {
        Vec::new()
    }
    /// SysTick counts spent receiving radio frames per control period (firmware).
    fn rx_cycles(&self) -> Vec<u32> {
        Vec::new()
    }
    /// Makes the firmware fail (the harness's own tests); only firmware brains can.
    fn inject(&mut self, fault: protocol::body::FirmwareFault) -> Result<(), BrainError> {
        Err(BrainError(format!("this brain cannot inject {fault:?}")))
    }
}

/// The control core, natively.
pub struct NativeBrain {
    node: RobotNode,
    tx: Vec<u8>,
    out: Option<MotorOutput>,
}

impl NativeBrain {
    /// Robot `identity.id` with the keys its configuration page would hold.
    pub fn new(identity: Identity, master: &MasterKey, config: RobotConfig) -> Self {
        Self {
            node: RobotNode::new(
                identity,
                master.broadcast(),
                master.robot(identity.id),
                config,
            ),
            tx: Vec::new(),
            out: None,
        }
    }

    pub fn node(&self) -> &RobotNode {
        &self.node
    }
}

impl Brain for NativeBrain {
    fn step_start(
        &mut self,
        local_us: u64,
        radio: &[u8],
        sensors: Option<&Sensors>,
    ) -> Result<(), BrainError> {
        let now_ms = (local_us / 1000) as u32;
        let tx = &mut self.tx;
        self.node
            .receive(radio, now_ms, &mut |b| tx.extend_from_slice(b));
        self.out = sensors.map(|s| self.node.tick(now_ms, s, &mut |b| tx.extend_from_slice(b)));
        Ok(())
    }

    fn step_finish(&mut self, tx: &mut Vec<u8>) -> Result<Option<MotorOutput>, BrainError> {
        tx.append(&mut self.tx);
        Ok(self.out.take())
    }

    fn mode(&self) -> RobotMode {
        self.node.controller().mode()
    }

    fn rejects(&self) -> RejectCounts {
        self.node.link().stats().rejects
    }
}
