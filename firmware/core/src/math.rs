//! The one place maths happens: micromath, called explicitly, so host tests run the same
//! approximations as the MCU (micromath's trait methods lose to std's inherent ones when
//! std is linked).
//!
//! micromath's `sin`, `cos`, `atan2` are within 0.002 of the true value; its `sqrt`
//! (a bit trick, ~5 %) is refined here with two Newton steps (to ~2e-6), since
//! distances feed the formation law directly. See `docs/control.md` for the measured
//! effect on the law's output.

use core::f32::consts::PI;
use micromath::F32;

pub const TAU: f32 = 2.0 * PI;

pub fn sin(x: f32) -> f32 {
    F32(x).sin().0
}

pub fn cos(x: f32) -> f32 {
    F32(x).cos().0
}

/// `(sin x, cos x)`, normalised so that sin² + cos² = 1 to float precision: rotations
/// then keep lengths, and algebraically equal forms of a law stay numerically equal.
pub fn sin_cos(x: f32) -> (f32, f32) {
    let (s, c) = (sin(x), cos(x));
    let n = hypot(s, c);
    (s / n, c / n)
}

pub fn atan2(y: f32, x: f32) -> f32 {
    F32(y).atan2(F32(x)).0
}

/// Square root of a non-negative number (0 for 0, NaN for negatives).
pub fn sqrt(x: f32) -> f32 {
    if x <= 0.0 {
        return if x == 0.0 { 0.0 } else { f32::NAN };
    }
    let mut y = F32(x).sqrt().0;
    y = 0.5 * (y + x / y);
    0.5 * (y + x / y)
}

pub fn hypot(x: f32, y: f32) -> f32 {
    sqrt(x * x + y * y)
}

pub fn floor(x: f32) -> f32 {
    F32(x).floor().0
}

pub fn abs(x: f32) -> f32 {
    F32(x).abs().0
}

/// Wraps an angle into (-π, π]: one body for the robot's `f32` and the base station's
/// `f64` (they drifted apart once, the host's missing the `> π` case).
macro_rules! wrap_angle {
    ($(#[$meta:meta])* $name:ident, $t:ty, $pi:expr, $floor:expr) => {
        $(#[$meta])*
        pub fn $name(a: $t) -> $t {
            let tau = 2.0 * $pi;
            let mut w = a - tau * $floor((a + $pi) / tau);
            if w <= -$pi {
                w += tau;
            }
            if w > $pi {
                w -= tau;
            }
            w
        }
    };
}

wrap_angle!(
    /// Wraps an angle into (-π, π].
    wrap_angle,
    f32,
    PI,
    floor
);

#[cfg(feature = "std")]
wrap_angle!(
    /// [`wrap_angle`] in double precision, for the base station's planner.
    wrap_angle_f64,
    f64,
    core::f64::consts::PI,
    f64::floor
);

pub fn clamp(x: f32, lo: f32, hi: f32) -> f32 {
    if x < lo {
        lo
    } else if x > hi {
        hi
    } else {
        x
    }
}

/// Moves `from` toward `to` by at most `step`.
pub fn approach(from: f32, to: f32, step: f32) -> f32 {
    from + clamp(to - from, -step, step)
}

/// `(us / 1000) as u32`, by long division in 16-bit digits: each step is one 32-bit
/// `udiv`, where a `u64` division pulls in the 64-bit division routine (~0.9 KiB of
/// flash at opt-level "z" on the QEMU board).
pub fn micros_to_millis(us: u64) -> u32 {
    let (mut q, mut r) = (0u32, 0u32);
    for shift in [48, 32, 16, 0] {
        // r < 1000, so cur < 1000 · 2¹⁶ and its quotient fits 16 bits.
        let cur = (r << 16) | ((us >> shift) as u32 & 0xFFFF);
        q = (q << 16).wrapping_add(cur / 1000);
        r = cur % 1000;
    }
    q
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_angle_range() {
        for i in -100..100 {
            let a = i as f32 * 0.37;
            let w = wrap_angle(a);
            assert!(w > -PI && w <= PI, "{a} -> {w}");
            assert!(abs(sin(w) - sin(a)) < 5e-3);
        }
        assert!((wrap_angle(-PI) - PI).abs() < 1e-6);
    }

    #[test]
    fn refined_sqrt_is_accurate() {
        for x in [1e-6f32, 0.01, 0.5, 2.0, 12.5, 9.0, 1e4, 3.3e7] {
            let rel = (sqrt(x) - x.sqrt()).abs() / x.sqrt();
            assert!(rel < 5e-6, "{x}: {rel}");
        }
        assert_eq!(sqrt(0.0), 0.0);
        assert!(sqrt(-1.0).is_nan());
    }

    #[test]
    fn micros_to_millis_is_the_wrapping_quotient() {
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        let mut cases = std::vec![
            0,
            999,
            1000,
            1001,
            u32::MAX as u64,
            1 << 32,
            u64::MAX,
            u64::MAX - 999
        ];
        for _ in 0..10_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            cases.push(x);
            cases.push(x >> 20);
        }
        for us in cases {
            assert_eq!(micros_to_millis(us), (us / 1000) as u32, "{us}");
        }
    }
}
