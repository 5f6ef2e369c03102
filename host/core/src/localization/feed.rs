//! The line feed: one fix per line, for sources that already know the site frame (motion
//! capture, UWB, a ROS bridge). Comma-separated, blank lines and `#` comments ignored:
//!
//! ```text
//! ROBOT_ID,TIME_S,X_M,Y_M,HEADING_RAD,SIGMA_M
//! 2,1764486000.125,12.500,-3.250,1.5708,0.02
//! ```
//!
//! `TIME_S`: when the pose was measured, seconds since the Unix epoch (UTC); heading
//! counter-clockwise from the site's x axis; σ the one-sigma position error.

use glam::DVec2;

use super::{Fix, LineError};

/// One line: a fix, `Ok(None)` for a blank line or a comment.
pub fn parse(line: &str) -> Result<Option<Fix>, LineError> {
    let line = line.trim();
    if line.is_empty() || line.starts_with('#') {
        return Ok(None);
    }
    let fields: Vec<&str> = line.split(',').map(str::trim).collect();
    let [id, time, x, y, heading, sigma] = fields[..] else {
        return Err(LineError::Malformed(format!(
            "{} fields, expected 6 (ROBOT_ID,TIME_S,X_M,Y_M,HEADING_RAD,SIGMA_M)",
            fields.len()
        )));
    };
    let robot = id
        .parse::<u16>()
        .map_err(|_| LineError::Malformed(format!("robot id {id:?}")))?;
    let number = |name: &str, text: &str| {
        text.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| LineError::Malformed(format!("{name} {text:?}")))
    };
    let time = number("time", time)?;
    let sigma = number("sigma", sigma)?;
    if !(0.0..=1e11).contains(&time) {
        return Err(LineError::Malformed(format!("time {time} s")));
    }
    if sigma <= 0.0 {
        // No localization is perfect: a σ of 0 is not a measurement.
        return Err(LineError::Malformed(format!(
            "sigma {sigma} m: must be > 0"
        )));
    }
    Ok(Some(Fix {
        robot,
        unix_ms: (time * 1000.0).round() as u64,
        position: DVec2::new(number("x", x)?, number("y", y)?),
        heading: crate::geometry::wrap_angle(number("heading", heading)?),
        sigma,
    }))
}

/// A fix as a line of the feed (with its newline).
pub fn format(fix: &Fix) -> String {
    format!(
        "{},{:.3},{:.4},{:.4},{:.5},{:.4}\n",
        fix.robot,
        fix.unix_ms as f64 / 1000.0,
        fix.position.x,
        fix.position.y,
        fix.heading,
        fix.sigma
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fix_round_trips() {
        let fix = Fix {
            robot: 7,
            unix_ms: 1_764_486_000_125,
            position: DVec2::new(12.5, -3.25),
            heading: -1.25,
            sigma: 0.02,
        };
        assert_eq!(parse(&format(&fix)), Ok(Some(fix)));
        assert_eq!(parse("  # a comment"), Ok(None));
        assert_eq!(parse(""), Ok(None));
    }

    #[test]
    fn bad_lines_name_what_is_wrong() {
        for (line, says) in [
            ("1,2,3", "3 fields"),
            ("x,1,0,0,0,0.1", "robot id"),
            ("70000,1,0,0,0,0.1", "robot id"),
            ("1,1,NaN,0,0,0.1", "x"),
            ("1,1,0,0,inf,0.1", "heading"),
            ("1,1,0,0,0,-1", "sigma"),
            ("1,1,0,0,0,0", "must be > 0"),
            ("1,-5,0,0,0,0.1", "time"),
        ] {
            match parse(line) {
                Err(LineError::Malformed(why)) => assert!(why.contains(says), "{line}: {why}"),
                other => panic!("{line}: {other:?}"),
            }
        }
    }
}
