//! NMEA 0183 from a robot's GNSS/RTK receiver: position from `GGA` (or `RMC`), heading from
//! `HDT` or `THS` (a dual-antenna receiver), the position's uncertainty from `GST` when the
//! receiver sends it, else from `GGA`'s fix quality and HDOP. Parsed with the `nmea` crate
//! (checksums checked); `THS`, which it does not know, is read here after the same check.
//!
//! One [`NmeaReceiver`] per robot: a receiver's sentences carry no robot id.

use chrono::{DateTime, NaiveTime, Utc};
use nmea::sentences::FixType;
use nmea::ParseResult;

use super::{Fix, LineError, SiteOrigin};

/// A heading older than this (by arrival) does not go with a new position, ms.
const HEADING_FRESH_MS: u64 = 1000;
/// A `GST` older than this no longer describes the position, ms.
const GST_FRESH_MS: u64 = 2000;

/// Position error at HDOP 1 by fix quality (user equivalent range error), m: what a fix
/// counts for when the receiver sends no `GST`.
fn uere(fix: FixType) -> Option<f64> {
    Some(match fix {
        FixType::Rtk => 0.02,
        FixType::FloatRtk => 0.3,
        FixType::DGps => 0.7,
        FixType::Gps | FixType::Pps => 2.5,
        FixType::Estimated | FixType::Manual | FixType::Simulation => 5.0,
        FixType::Invalid => return None,
    })
}

pub struct NmeaReceiver {
    robot: u16,
    origin: SiteOrigin,
    /// (true heading, degrees; arrival, Unix ms).
    heading: Option<(f64, u64)>,
    /// (σ from GST, m; arrival, Unix ms).
    gst: Option<(f64, u64)>,
}

impl NmeaReceiver {
    pub fn new(robot: u16, origin: SiteOrigin) -> Self {
        Self {
            robot,
            origin,
            heading: None,
            gst: None,
        }
    }

    /// One sentence, received at `now_unix_ms`. A position with a fresh heading is a fix;
    /// heading and `GST` sentences are kept for the next position (`Ok(None)`).
    pub fn line(&mut self, line: &str, now_unix_ms: u64) -> Result<Option<Fix>, LineError> {
        let line = line.trim();
        if line.is_empty() {
            return Ok(None);
        }
        if line.starts_with('$') && line.get(3..6) == Some("THS") {
            self.heading = Some((parse_ths(line)?, now_unix_ms));
            return Ok(None);
        }
        let malformed = |e: nmea::Error| LineError::Malformed(e.to_string());
        let (time, lat, lon, sigma) = match nmea::parse_str(line) {
            Ok(ParseResult::GGA(gga)) => {
                let fix = gga.fix_type.unwrap_or(FixType::Invalid);
                let Some(uere) = uere(fix) else {
                    return Err(LineError::NoSolution);
                };
                let (Some(lat), Some(lon), Some(time)) =
                    (gga.latitude, gga.longitude, gga.fix_time)
                else {
                    return Err(LineError::NoSolution);
                };
                let hdop = gga.hdop.map_or(2.0, f64::from).max(0.5);
                (time, lat, lon, uere * hdop)
            }
            Ok(ParseResult::RMC(rmc)) => {
                use nmea::sentences::rmc::RmcStatusOfFix as S;
                let (Some(lat), Some(lon), Some(time), S::Autonomous | S::Differential) =
                    (rmc.lat, rmc.lon, rmc.fix_time, rmc.status_of_fix)
                else {
                    return Err(LineError::NoSolution);
                };
                (time, lat, lon, uere(FixType::Gps).unwrap_or(2.5))
            }
            Ok(ParseResult::HDT(hdt)) => {
                let heading = hdt.heading.ok_or(LineError::NoSolution)?;
                self.heading = Some((heading as f64, now_unix_ms));
                return Ok(None);
            }
            Ok(ParseResult::GST(gst)) => {
                let (Some(a), Some(b)) = (gst.lat_sd, gst.long_sd) else {
                    return Err(LineError::NoSolution);
                };
                let sigma = ((a as f64).powi(2) + (b as f64).powi(2)).sqrt() / 2f64.sqrt();
                self.gst = Some((sigma, now_unix_ms));
                return Ok(None);
            }
            Ok(_) => return Ok(None), // a sentence this receiver needs not
            Err(e) => return Err(malformed(e)),
        };
        let Some((heading, _)) = self
            .heading
            .filter(|(_, at)| now_unix_ms.saturating_sub(*at) <= HEADING_FRESH_MS)
        else {
            return Err(LineError::NoHeading);
        };
        let sigma = self
            .gst
            .filter(|(_, at)| now_unix_ms.saturating_sub(*at) <= GST_FRESH_MS)
            .map_or(sigma, |(s, _)| s);
        if !(lat.is_finite() && lon.is_finite() && lat.abs() <= 90.0 && lon.abs() <= 180.0) {
            return Err(LineError::Malformed(format!("position {lat}, {lon}")));
        }
        Ok(Some(Fix {
            robot: self.robot,
            unix_ms: time_of_day_to_unix_ms(time, now_unix_ms),
            position: self.origin.to_site(lat, lon),
            heading: self.origin.heading_to_site(heading),
            sigma,
        }))
    }
}

/// `$xxTHS,heading,mode*hh`: true heading from a dual-antenna receiver (the `nmea` crate
/// does not know it); mode `A` (autonomous) or `D` (differential) is a heading, anything
/// else is not.
fn parse_ths(line: &str) -> Result<f64, LineError> {
    let malformed = |why: &str| LineError::Malformed(format!("THS: {why}"));
    let (body, sum) = line[1..]
        .split_once('*')
        .ok_or_else(|| malformed("no checksum"))?;
    let sum = u8::from_str_radix(sum, 16).map_err(|_| malformed("checksum not hex"))?;
    if body.bytes().fold(0u8, |a, b| a ^ b) != sum {
        return Err(malformed("checksum mismatch"));
    }
    let mut fields = body.split(',').skip(1);
    let heading = fields.next().unwrap_or("");
    match fields.next() {
        Some("A" | "D") => {}
        _ => return Err(LineError::NoSolution),
    }
    heading
        .parse::<f64>()
        .ok()
        .filter(|h| h.is_finite() && (0.0..=360.0).contains(h))
        .ok_or_else(|| LineError::Malformed(format!("THS heading {heading:?}")))
}

/// A UTC time of day on the day (yesterday, today or tomorrow) that puts it nearest `now`.
fn time_of_day_to_unix_ms(time: NaiveTime, now_unix_ms: u64) -> u64 {
    let now = DateTime::<Utc>::from_timestamp_millis(now_unix_ms as i64).unwrap_or_default();
    let today = now.date_naive();
    [today.pred_opt(), Some(today), today.succ_opt()]
        .into_iter()
        .flatten()
        .map(|d| d.and_time(time).and_utc().timestamp_millis())
        .min_by_key(|t| (t - now_unix_ms as i64).abs())
        .unwrap_or(now_unix_ms as i64)
        .max(0) as u64
}

/// Sentences a receiver at `fix` would send: `GGA` (RTK fixed) and `HDT`, with checksums.
/// For the simulated robots' receivers and for tests.
pub fn sentences(fix: &Fix, origin: &SiteOrigin) -> [String; 2] {
    let (lat, lon) = origin.to_wgs84(fix.position);
    let t = DateTime::<Utc>::from_timestamp_millis(fix.unix_ms as i64).unwrap_or_default();
    let time = t.format("%H%M%S%.3f");
    let angle = |deg: f64, width: usize| {
        let d = deg.abs().trunc();
        let m = (deg.abs() - d) * 60.0;
        format!("{:0width$}{m:011.8}", d as u32)
    };
    let hdop = (fix.sigma / uere(FixType::Rtk).unwrap_or(0.02)).clamp(0.5, 99.0);
    let gga = format!(
        "GPGGA,{time},{},{},{},{},4,12,{hdop:.1},0.0,M,0.0,M,,",
        angle(lat, 2),
        if lat >= 0.0 { 'N' } else { 'S' },
        angle(lon, 3),
        if lon >= 0.0 { 'E' } else { 'W' },
    );
    let hdt = format!("GPHDT,{:.2},T", origin.heading_to_true(fix.heading));
    [with_checksum(&gga), with_checksum(&hdt)]
}

fn with_checksum(body: &str) -> String {
    let sum = body.bytes().fold(0u8, |a, b| a ^ b);
    format!("${body}*{sum:02X}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec2;

    const SITE: SiteOrigin = SiteOrigin {
        lat_deg: 47.3769,
        lon_deg: 8.5417,
        x_axis_bearing_deg: 60.0,
    };
    /// 2026-11-30 07:00:00 UTC.
    const NOW: u64 = 1_764_486_000_000;

    #[test]
    fn a_fix_round_trips_through_gga_and_hdt() {
        let fix = Fix {
            robot: 2,
            unix_ms: NOW - 150,
            position: DVec2::new(31.25, -7.5),
            heading: 2.0,
            sigma: 0.02,
        };
        let mut rx = NmeaReceiver::new(2, SITE);
        let [gga, hdt] = sentences(&fix, &SITE);
        assert_eq!(rx.line(&gga, NOW), Err(LineError::NoHeading));
        assert_eq!(rx.line(&hdt, NOW), Ok(None));
        let got = rx.line(&gga, NOW).unwrap().unwrap();
        assert_eq!(got.robot, 2);
        assert_eq!(got.unix_ms, fix.unix_ms);
        assert!((got.position - fix.position).length() < 0.005, "{got:?}");
        assert!((got.heading - fix.heading).abs() < 1e-3);
        assert!((got.sigma - 0.02).abs() < 0.011, "{}", got.sigma);
    }

    #[test]
    fn ths_gst_and_a_fix_just_before_midnight() {
        let mut rx = NmeaReceiver::new(1, SITE);
        // 23:59:59.900 yesterday, received 00:00:00.100 today.
        let midnight = 1_764_460_800_000;
        let ths = with_checksum("GNTHS,60.00,A");
        let gst = with_checksum("GPGST,235959.90,0.5,0.03,0.02,45.0,0.04,0.03,0.05");
        let gga = with_checksum("GPGGA,235959.90,4722.6140,N,00832.5020,E,4,12,0.8,0.0,M,0.0,M,,");
        for line in [&ths, &gst] {
            assert_eq!(rx.line(line, midnight + 100), Ok(None));
        }
        let fix = rx.line(&gga, midnight + 100).unwrap().unwrap();
        assert_eq!(fix.unix_ms, midnight - 100);
        assert!(fix.heading.abs() < 1e-9, "heading along x: {}", fix.heading);
        assert!(
            (fix.sigma - 0.0354).abs() < 1e-3,
            "σ from GST: {}",
            fix.sigma
        );
    }

    #[test]
    fn bad_sentences_are_errors_not_panics() {
        let mut rx = NmeaReceiver::new(1, SITE);
        let cases = [
            "$GPGGA,1,2,3*00",
            "GPGGA,,,,",
            "$GPHDT,12.0,T*FF",
            "\u{0}\u{ff}garbage",
            &with_checksum("GNTHS,400,A"),
            &"$GPGGA,".repeat(100),
        ];
        for line in cases {
            assert!(
                matches!(rx.line(line, NOW), Err(LineError::Malformed(_))),
                "{line:?}"
            );
        }
        let no_fix = with_checksum("GPGGA,120000.00,4722.6140,N,00832.5020,E,0,00,99.9,,M,,M,,");
        assert_eq!(rx.line(&no_fix, NOW), Err(LineError::NoSolution));
        assert_eq!(
            rx.line(&with_checksum("GNTHS,12.0,V"), NOW),
            Err(LineError::NoSolution)
        );
    }
}
