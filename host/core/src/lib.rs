//! The base station: it steers the leader with an artificial potential field, decides the
//! formation, broadcasts the leader's state and watches the fleet.
//!
//! Module map, from the wire up (folders are parts, files are rooms):
//!
//! - [`station`]: the station core stepped at 10 Hz, a pipeline over rooms: the fleet,
//!   the gate and the operator, guidance, the radio; `station/movers/` (the leader's pace
//!   among what moves, the way kept aside for people coming the other way),
//!   `station/robots/` (the robots among themselves: spacing, the leader's way, the
//!   line's order, detours), `station/fixes/` (the site's localization forwarded and
//!   watched). What `run` and the simulator both drive.
//! - [`planner`]: the leader's route on the map ([`planner::route`]) and the APF as its
//!   local layer ([`planner::apf`]), or the paper's pure field.
//! - [`coverage`]: areas swept: the coverage route (boustrophedon passes), the formation's
//!   swath, the ground a run swept.
//! - [`formation`]: slots, the switch to a line and back, the pace of a change; the
//!   follower's geometry is the control core's.
//! - [`perception`]: from the leader's scans to what the map does not hold, and
//!   ([`perception::tracking`]) to tracks: which of it moves, and how fast.
//! - [`localization`]: fixes from the site (NMEA, the line feed); [`seal`]: who may send
//!   them (and scans): a key and a MAC per source.
//! - [`scenario`]: the scenario and site file, its validation and limits, and what it
//!   lowers to (station, planner, formation, robots).
//! - [`geometry`]: obstacles, distances, poses; [`geometry::map`] behind an R-tree;
//!   [`geometry::cells`]: things by grid cell, for what is near a point.
//! - [`recording`]: the recording's vocabulary (topics, schemas, scene), shared by the
//!   simulator and real runs.
//! - [`transport`]: serial modem and UDP.

pub mod air;
pub mod coverage;
pub mod formation;
pub mod geometry;
pub mod localization;
pub mod perception;
pub mod planner;
pub mod recording;
pub mod scenario;
pub mod seal;
pub mod station;
pub mod transport;
