//! The robot's shared state: the node (control core + link) and the counters the tasks
//! and the lockstep link read. Statics only.

use core::cell::RefCell;
use core::sync::atomic::{AtomicU32, Ordering};

use control_core::config::{RobotConfig, Role};
use control_core::node::{Identity, RobotNode};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_time::Instant;
use protocol::FleetKey;
use static_cell::StaticCell;

/// Who this robot is: from the configuration page (`docs/firmware.md`) on the NUCLEO,
/// from the simulated body's first message in QEMU. The wire's own type: one definition.
pub use protocol::body::BodyConfig as Config;

/// The node's storage, zeroed (`.bss`): an `Option<RobotNode>` in a static would put
/// its ~2 KiB `None` image in flash.
static NODE_CELL: StaticCell<RobotNode> = StaticCell::new();
static NODE: Mutex<CriticalSectionRawMutex, RefCell<Option<&'static mut RobotNode>>> =
    Mutex::new(RefCell::new(None));

/// Control periods run so far (the watchdog and the lockstep link watch it).
pub static CONTROL_TICKS: AtomicU32 = AtomicU32::new(0);
/// Radio bytes received and processed so far.
pub static RADIO_RX_BYTES: AtomicU32 = AtomicU32::new(0);
/// Radio bytes transmitted so far.
pub static RADIO_TX_BYTES: AtomicU32 = AtomicU32::new(0);
/// SysTick counts the last control step took.
pub static STEP_CYCLES: AtomicU32 = AtomicU32::new(0);
/// SysTick counts spent in radio receive since the lockstep link last reported.
pub static RX_CYCLES: AtomicU32 = AtomicU32::new(0);

pub fn configure(c: Config) {
    let identity = Identity {
        id: c.id,
        role: if c.leader {
            Role::Leader
        } else {
            Role::Follower
        },
        boot_count: c.boot_count,
        entropy: c.entropy,
    };
    let node = RobotNode::new(
        identity,
        FleetKey::from_bytes(&c.broadcast_key),
        FleetKey::from_bytes(&c.robot_key),
        RobotConfig::DEFAULT,
    );
    let Some(node) = NODE_CELL.try_init(node) else {
        defmt::error!("configured twice: ignored");
        return;
    };
    NODE.lock(|n| *n.borrow_mut() = Some(node));
    defmt::info!(
        "robot {} ({}) boot {}",
        c.id,
        if c.leader { "leader" } else { "follower" },
        c.boot_count
    );
}

/// Runs `f` on the node, if configured.
pub fn with_node<R>(f: impl FnOnce(&mut RobotNode) -> R) -> Option<R> {
    NODE.lock(|n| n.borrow_mut().as_mut().map(|node| f(node)))
}

/// The node's clock: milliseconds since boot, wrapping at 2³² (49 days).
pub fn millis(now: Instant) -> u32 {
    control_core::math::micros_to_millis(now.as_micros())
}

pub fn count(counter: &AtomicU32, n: usize) {
    counter.fetch_add(n as u32, Ordering::Release);
}
