//! The site's feeds: who may speak on them ([`gate`]), the localization fixes and NMEA
//! ([`localization`]) and the leader's scans ([`scan`]), read for `run` and published by
//! `robots`.

pub mod gate;
pub mod localization;
pub mod scan;
