//! The base station: it steers the leader with an artificial potential field, decides the
//! formation, broadcasts the leader's state and watches the fleet.
//!
//! Module map, from the wire up:
//!
//! - [`station`]: the station core stepped at 10 Hz, a pipeline over rooms (fleet,
//!   gate, guidance, detours, fixes, radio); what `run` and the simulator both drive.
//! - [`planner`]: the leader's route on the map ([`planner::route`]) and the APF as its
//!   local layer ([`planner::apf`]), or the paper's pure field.
//! - [`formation`]: slots, the switch to a line and back, the pace of a change; the
//!   follower's geometry is the control core's.
//! - [`perception`]: what the leader's scans found that the map does not hold;
//!   [`tracking`]: which of it moves, and how fast.
//! - [`localization`]: fixes from the site (NMEA, the line feed); [`seal`]: who may send
//!   them (and scans): a key and a MAC per source.
//! - [`scenario`]: scenario and site files, their validation and limits, and what they
//!   lower to (station, planner, formation, robots).
//! - [`map`], [`geometry`]: obstacles behind an R-tree, distances, poses; [`cells`]:
//!   things by grid cell, for what is near a point.
//! - [`recording`]: the recording's vocabulary (topics, schemas, scene), shared by the
//!   simulator and real runs.
//! - [`transport`]: serial modem and UDP.

pub mod cells;
pub mod formation;
pub mod geometry;
pub mod localization;
pub mod map;
pub mod perception;
pub mod planner;
pub mod recording;
pub mod scenario;
pub mod seal;
pub mod station;
pub mod tracking;
pub mod transport;
