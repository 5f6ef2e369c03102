//! Where the robots are, from the site's localization system: NMEA 0183 from a GNSS/RTK
//! receiver on each robot ([`nmea`]), or a line feed from motion capture, UWB or a ROS
//! bridge ([`feed`]). Both give [`Fix`]es in the site frame, which the station forwards to
//! each robot as an authenticated `PoseFix` ([`crate::station::BaseStation::forward_fix`]).
//!
//! Input is never trusted: a line that is not a fix is counted by [`LineError`] and dropped.

pub mod feed;
pub mod nmea;
mod site;

use glam::DVec2;
use serde::Serialize;

pub use site::SiteOrigin;

/// One robot's pose at one instant, in the site frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fix {
    pub robot: u16,
    /// When the pose was measured, ms since the Unix epoch (UTC).
    pub unix_ms: u64,
    pub position: DVec2,
    /// Counter-clockwise from the site's x axis, rad.
    pub heading: f64,
    /// One-sigma position uncertainty, m.
    pub sigma: f64,
}

/// Why an input line gave no fix.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LineError {
    /// Not a line of the format: what is wrong with it.
    Malformed(String),
    /// The receiver says it has no position (NMEA fix quality 0, RMC status V).
    NoSolution,
    /// A position without a recent heading (NMEA `HDT`/`THS`).
    NoHeading,
}

impl LineError {
    pub fn name(&self) -> &'static str {
        match self {
            LineError::Malformed(_) => "malformed",
            LineError::NoSolution => "no_solution",
            LineError::NoHeading => "no_heading",
        }
    }
}

impl std::fmt::Display for LineError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LineError::Malformed(why) => write!(f, "malformed: {why}"),
            LineError::NoSolution => write!(f, "the receiver has no position"),
            LineError::NoHeading => write!(f, "a position without a recent heading"),
        }
    }
}

/// What a localization source delivered: fixes, and the lines that were not.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct InputCounts {
    pub fixes: u64,
    pub malformed: u64,
    pub no_solution: u64,
    pub no_heading: u64,
    /// Fixes of a robot that is not in the fleet.
    pub unknown_robot: u64,
    /// Fixes too old, or from the future, by the station's clock.
    pub out_of_time: u64,
    /// Fixes not forwarded: a fix that agreed better with the robot took the slot (each
    /// robot gets at most `forward_hz` a second).
    pub rate_limited: u64,
    /// Fixes far from where the robot knows it is, held back while fixes it agrees with
    /// keep coming.
    pub outliers: u64,
}

impl InputCounts {
    pub fn count(&mut self, error: &LineError) {
        match error {
            LineError::Malformed(_) => self.malformed += 1,
            LineError::NoSolution => self.no_solution += 1,
            LineError::NoHeading => self.no_heading += 1,
        }
    }
}
