//! The base station: it steers the leader with an artificial potential field, decides the
//! formation, broadcasts the leader's state and watches the fleet.

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
pub mod transport;
