//! NMEA 0183 from a robot's GNSS/RTK receiver: position from `GGA` (or `RMC`), heading from
//! `HDT` or `THS` (a dual-antenna receiver), the position's uncertainty from `GST` when the
//! receiver sends it, else from `GGA`'s fix quality and HDOP. Framing, checksums and fields
//! by the `nmea-kit` crate (the `nmea` crate pins a `serde_with` that the Foxglove SDK's WebSocket server cannot share); a sentence without a checksum is refused.
//!
//! One [`NmeaReceiver`] per robot: a receiver's sentences carry no robot id.

use chrono::{DateTime, NaiveTime, Utc};
use nmea_kit::nmea::{ddmm_to_decimal, decimal_to_ddmm, Gga, Gst, Hdt, Rmc, Ths};
use nmea_kit::NmeaEncodable;

use super::{Fix, LineError, SiteOrigin};

/// A heading older than this (by arrival) does not go with a new position, ms.
const HEADING_FRESH_MS: u64 = 1000;
/// A `GST` older than this no longer describes the position, ms.
const GST_FRESH_MS: u64 = 2000;
/// GGA's fix quality of an RTK fixed solution.
const RTK_FIXED: u8 = 4;

/// Position error at HDOP 1 by GGA fix quality (user equivalent range error), m: what a
/// fix counts for when the receiver sends no `GST`. `None`: no position.
fn uere(quality: u8) -> Option<f64> {
    Some(match quality {
        RTK_FIXED => 0.02,
        5 => 0.3,     // RTK float
        2 | 9 => 0.7, // DGPS, SBAS
        1 | 3 => 2.5, // autonomous, PPS
        6..=8 => 5.0, // dead reckoning, manual, simulation
        _ => return None,
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

fn malformed(why: impl std::fmt::Display) -> LineError {
    LineError::Malformed(why.to_string())
}

/// `DDMM.MMMM` with its hemisphere as signed decimal degrees.
fn coordinate(ddmm: Option<f64>, hemisphere: Option<char>, negative: char) -> Option<f64> {
    let v = ddmm_to_decimal(ddmm?);
    Some(if hemisphere? == negative { -v } else { v })
}

/// `HHMMSS.sss`.
fn time_of_day(text: &str) -> Result<NaiveTime, LineError> {
    NaiveTime::parse_from_str(text, "%H%M%S%.f").map_err(|_| malformed(format!("time {text:?}")))
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
        if !line.contains('*') {
            return Err(malformed("no checksum"));
        }
        let frame = nmea_kit::parse_frame(line).map_err(|e| malformed(format!("{e:?}")))?;
        match self.sentence(frame.sentence_type, &frame.fields, now_unix_ms)? {
            Some(position) => self.fix(position, now_unix_ms).map(Some),
            None => Ok(None),
        }
    }

    /// A position sentence's (time of day, latitude, longitude, σ); a heading or `GST`
    /// sentence kept for the next position, or a sentence this receiver needs not:
    /// `None`.
    fn sentence(
        &mut self,
        kind: &str,
        fields: &[&str],
        now_unix_ms: u64,
    ) -> Result<Option<Position>, LineError> {
        match kind {
            "GGA" => {
                let gga = Gga::parse(fields).ok_or_else(|| malformed("GGA fields"))?;
                let uere = gga.quality.and_then(uere).ok_or(LineError::NoSolution)?;
                let (Some(lat), Some(lon), Some(time)) = (
                    coordinate(gga.lat, gga.ns, 'S'),
                    coordinate(gga.lon, gga.ew, 'W'),
                    gga.time,
                ) else {
                    return Err(LineError::NoSolution);
                };
                let hdop = gga.hdop.map_or(2.0, f64::from).max(0.5);
                Ok(Some((time_of_day(&time)?, lat, lon, uere * hdop)))
            }
            "RMC" => {
                let rmc = Rmc::parse(fields).ok_or_else(|| malformed("RMC fields"))?;
                let (Some('A'), Some(lat), Some(lon), Some(time)) = (
                    rmc.status,
                    coordinate(rmc.lat, rmc.ns, 'S'),
                    coordinate(rmc.lon, rmc.ew, 'W'),
                    rmc.time,
                ) else {
                    return Err(LineError::NoSolution);
                };
                Ok(Some((
                    time_of_day(&time)?,
                    lat,
                    lon,
                    uere(1).unwrap_or(2.5),
                )))
            }
            "HDT" => {
                let hdt = Hdt::parse(fields).ok_or_else(|| malformed("HDT fields"))?;
                self.heading = Some((true_heading(hdt.heading_true)?, now_unix_ms));
                Ok(None)
            }
            "THS" => {
                let ths = Ths::parse(fields).ok_or_else(|| malformed("THS fields"))?;
                // Mode A (autonomous) or D (differential) is a heading; E, M, S, V are not.
                if !matches!(ths.mode, Some('A' | 'D')) {
                    return Err(LineError::NoSolution);
                }
                self.heading = Some((true_heading(ths.heading_true)?, now_unix_ms));
                Ok(None)
            }
            "GST" => {
                let gst = Gst::parse(fields).ok_or_else(|| malformed("GST fields"))?;
                let (Some(a), Some(b)) = (gst.std_lat, gst.std_lon) else {
                    return Err(LineError::NoSolution);
                };
                let sigma = ((a as f64).powi(2) + (b as f64).powi(2)).sqrt() / 2f64.sqrt();
                self.gst = Some((sigma, now_unix_ms));
                Ok(None)
            }
            _ => Ok(None),
        }
    }

    /// A position, with the heading heard last (fresh) and `GST`'s σ when fresh, as a fix.
    fn fix(&self, (time, lat, lon, sigma): Position, now_unix_ms: u64) -> Result<Fix, LineError> {
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
            return Err(malformed(format!("position {lat}, {lon}")));
        }
        Ok(Fix {
            robot: self.robot,
            unix_ms: time_of_day_to_unix_ms(time, now_unix_ms),
            position: self.origin.to_site(lat, lon),
            heading: self.origin.heading_to_site(heading),
            sigma,
        })
    }
}

/// A position sentence's time of day, latitude and longitude (degrees) and σ (m).
type Position = (NaiveTime, f64, f64, f64);

/// A true heading field: degrees in [0, 360].
fn true_heading(field: Option<f32>) -> Result<f64, LineError> {
    let h = field.ok_or(LineError::NoSolution)? as f64;
    if h.is_finite() && (0.0..=360.0).contains(&h) {
        Ok(h)
    } else {
        Err(malformed(format!("heading {h}")))
    }
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

/// Sentences a receiver at `fix` would send: `HDT` then `GGA` (RTK fixed, HDOP from σ),
/// with checksums and line ends. For the simulated robots' receivers and for tests.
pub fn sentences(fix: &Fix, origin: &SiteOrigin) -> String {
    let (lat, lon) = origin.to_wgs84(fix.position);
    let t = DateTime::<Utc>::from_timestamp_millis(fix.unix_ms as i64).unwrap_or_default();
    let hdop = (fix.sigma / uere(RTK_FIXED).unwrap_or(0.02)).clamp(0.5, 99.0);
    let gga = Gga {
        time: Some(t.format("%H%M%S%.3f").to_string()),
        lat: Some(decimal_to_ddmm(lat.abs())),
        ns: Some(if lat >= 0.0 { 'N' } else { 'S' }),
        lon: Some(decimal_to_ddmm(lon.abs())),
        ew: Some(if lon >= 0.0 { 'E' } else { 'W' }),
        quality: Some(RTK_FIXED),
        num_sats: Some(12),
        hdop: Some(hdop as f32),
        altitude: Some(0.0),
        alt_unit: Some('M'),
        geoid_sep: Some(0.0),
        geoid_unit: Some('M'),
        dgps_age: None,
        dgps_station: None,
    };
    let hdt = Hdt {
        heading_true: Some(origin.heading_to_true(fix.heading) as f32),
    };
    [hdt.to_sentence("GP"), gga.to_sentence("GP")]
        .into_iter()
        .flatten()
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec2;

    fn with_checksum(body: &str) -> String {
        let sum = body.bytes().fold(0u8, |a, b| a ^ b);
        format!("${body}*{sum:02X}")
    }

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
        let both = sentences(&fix, &SITE);
        let [hdt, gga]: [&str; 2] = both.lines().collect::<Vec<_>>().try_into().unwrap();
        assert_eq!(rx.line(gga, NOW), Err(LineError::NoHeading));
        assert_eq!(rx.line(hdt, NOW), Ok(None));
        let got = rx.line(gga, NOW).unwrap().unwrap();
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
            "$GPHDT,12.0,T",
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
