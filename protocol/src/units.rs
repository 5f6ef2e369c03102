//! Fixed-point units on the wire, and their checked conversions from SI floats.
//!
//! Positions are millimetres (`i32`), speeds mm/s and mrad/s (`i16`), angles binary angle
//! units of 1/16384 turn (`u16`, always < 16384, two varint bytes, 0.38 mrad). A NaN or an
//! infinity is refused with [`NonFinite`]: it never reaches the wire.

use core::f32::consts::PI;

/// Angle units per full turn.
pub const ANGLE_UNITS_PER_TURN: u16 = 16384;
const UNITS_PER_RAD: f32 = ANGLE_UNITS_PER_TURN as f32 / (2.0 * PI);

/// A value that must be finite was NaN or infinite.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NonFinite;

impl core::error::Error for NonFinite {}

impl core::fmt::Display for NonFinite {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("value is NaN or infinite")
    }
}

fn finite(x: f32) -> Result<f32, NonFinite> {
    if x.is_finite() {
        Ok(x)
    } else {
        Err(NonFinite)
    }
}

/// Rounds half away from zero; `as` saturates at the integer type's bounds.
fn round(x: f32) -> f32 {
    if x >= 0.0 {
        x + 0.5
    } else {
        x - 0.5
    }
}

/// Metres to millimetres, saturating at ±2147 km.
pub fn metres_to_mm(m: f32) -> Result<i32, NonFinite> {
    Ok(round(finite(m)? * 1000.0) as i32)
}

pub fn mm_to_metres(mm: i32) -> f32 {
    mm as f32 / 1000.0
}

/// A speed or rate to thousandths, saturating at ±32.767.
pub fn to_milli_i16(x: f32) -> Result<i16, NonFinite> {
    Ok(round(finite(x)? * 1000.0) as i16)
}

pub fn from_milli_i16(x: i16) -> f32 {
    x as f32 / 1000.0
}

/// A non-negative length to millimetres, saturating at 0 and 65.535 m.
pub fn to_mm_u16(m: f32) -> Result<u16, NonFinite> {
    Ok(round(finite(m)? * 1000.0) as u16)
}

pub fn from_mm_u16(mm: u16) -> f32 {
    mm as f32 / 1000.0
}

/// Radians (any value) to angle units in `0..16384`.
pub fn angle_to_wire(rad: f32) -> Result<u16, NonFinite> {
    // Reduce in integers: f32::rem_euclid is not in core.
    let units = round(finite(rad)? * UNITS_PER_RAD) as i64;
    Ok(units.rem_euclid(ANGLE_UNITS_PER_TURN as i64) as u16)
}

/// Angle units to radians in `(-π, π]`.
pub fn angle_from_wire(units: u16) -> f32 {
    let u = (units % ANGLE_UNITS_PER_TURN) as i32;
    let half = (ANGLE_UNITS_PER_TURN / 2) as i32;
    let signed = if u > half {
        u - ANGLE_UNITS_PER_TURN as i32
    } else {
        u
    };
    signed as f32 / UNITS_PER_RAD
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angles_wrap_into_one_turn() {
        assert_eq!(angle_to_wire(0.0), Ok(0));
        assert_eq!(angle_to_wire(2.0 * PI), Ok(0));
        assert_eq!(angle_to_wire(-PI / 2.0), Ok(12288));
        assert!((angle_from_wire(12288) + PI / 2.0).abs() < 1e-6);
        assert!((angle_from_wire(8192) - PI).abs() < 1e-6);
        assert_eq!(angle_to_wire(f32::NAN), Err(NonFinite));
    }

    #[test]
    fn conversions_saturate_and_refuse_non_finite() {
        assert_eq!(to_milli_i16(100.0), Ok(i16::MAX));
        assert_eq!(to_milli_i16(-0.0015), Ok(-2));
        assert_eq!(metres_to_mm(f32::INFINITY), Err(NonFinite));
        assert_eq!(to_mm_u16(-1.0), Ok(0));
    }
}
