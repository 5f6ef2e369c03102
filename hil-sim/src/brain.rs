//! A robot's brain: the control code that runs on its MCU. The native brain is the control
//! core compiled for the host; the QEMU brain (firmware issue) runs the real firmware ELF.
//! Both see the same radio bytes and the same body.

use std::fmt;

use control_core::config::RobotConfig;
use control_core::controller::{MotorOutput, Sensors};
use control_core::node::{Identity, RobotNode};
use protocol::messages::RobotMode;
use protocol::{FleetKey, RejectCounts};

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
    /// Radio bytes arrive (already delayed by the radio); answers go to `tx` at once.
    fn radio_rx(&mut self, bytes: &[u8], now_ms: u32, tx: &mut Vec<u8>) -> Result<(), BrainError>;
    /// One control period: sensors in; motor duties out, radio bytes appended to `tx`.
    fn tick(
        &mut self,
        now_ms: u32,
        sensors: &Sensors,
        tx: &mut Vec<u8>,
    ) -> Result<MotorOutput, BrainError>;
    /// The robot's mode, for logs and plots.
    fn mode(&self) -> RobotMode;
    /// Frames this robot's radio rejected, by reason.
    fn rejects(&self) -> RejectCounts;
}

/// The control core, natively.
pub struct NativeBrain {
    node: RobotNode,
}

impl NativeBrain {
    pub fn new(identity: Identity, key: FleetKey, config: RobotConfig) -> Self {
        Self {
            node: RobotNode::new(identity, key, config),
        }
    }

    pub fn node(&self) -> &RobotNode {
        &self.node
    }
}

impl Brain for NativeBrain {
    fn radio_rx(&mut self, bytes: &[u8], now_ms: u32, tx: &mut Vec<u8>) -> Result<(), BrainError> {
        self.node
            .receive(bytes, now_ms, &mut |b| tx.extend_from_slice(b));
        Ok(())
    }

    fn tick(
        &mut self,
        now_ms: u32,
        sensors: &Sensors,
        tx: &mut Vec<u8>,
    ) -> Result<MotorOutput, BrainError> {
        Ok(self
            .node
            .tick(now_ms, sensors, &mut |b| tx.extend_from_slice(b)))
    }

    fn mode(&self) -> RobotMode {
        self.node.controller().mode()
    }

    fn rejects(&self) -> RejectCounts {
        self.node.link().stats().rejects
    }
}
