//! Pose from encoder ticks, corrected by the localization system's pose fixes.
//!
//! Between fixes the pose is dead-reckoned from the wheels (midpoint integration). A fix
//! is compared with the odometry pose *at the fix's time* (a short history absorbs the
//! fix's latency) and the difference is blended in with a fixed gain (a complementary
//! filter), applied to the current pose and the history alike. A fix farther than the gate
//! is an outlier and dropped; only 5 s of consistent outliers (the odometry really is
//! off, or the localization re-anchored) re-localizes.
//!
//! When fixes stop, the robot goes on with odometry alone and raises `POSE_FIX_STALE`
//! after [`Timeouts::pose_fix_ms`](crate::config::Timeouts): its error then grows with the
//! distance driven (wheel slip, tick quantisation, track width error), no faster.

use heapless::Deque;

use crate::config::RobotConfig;
use crate::kinematics::WheelSpeeds;
use crate::{math, Pose};

/// Odometry poses kept to match late fixes: 1.6 s at 10 Hz.
const HISTORY: usize = 16;
/// Consecutive outliers that make the odometry give way to the fixes: 5 s at 10 Hz. A
/// jump shorter than that is ignored (odometry drifts little in 5 s); a lasting one means
/// the localization system re-anchored, and every robot must follow it.
const RELOCALIZE_AFTER: u8 = 50;
/// A fix with this σ counts half as much as a perfect one: the blending gain is
/// `fix_gain / (1 + (σ / FIX_SIGMA_REF)²)`, so a vaguer fix pulls less (m).
const FIX_SIGMA_REF: f32 = 0.1;
/// A fix whose heading is farther than this from the odometry's is an outlier too, rad
/// (20°: a localization's heading is good to a degree or two).
const HEADING_GATE: f32 = 0.35;

/// A pose fix, time already in this robot's clock.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PoseFixSample {
    pub pose: Pose,
    /// One-sigma position uncertainty, m.
    pub sigma: f32,
    pub time_ms: u32,
}

/// What a fix did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FixOutcome {
    /// The first fix: the pose is now known.
    Initialized,
    Applied,
    /// An outlier, dropped.
    Rejected,
    /// Enough consistent outliers: the pose was reset to the fixes.
    Relocalized,
    /// NaN, infinite or negative sigma: ignored.
    Invalid,
}

#[derive(Debug, Clone)]
pub struct Odometry {
    pose: Option<Pose>,
    last_ticks: Option<[i32; 2]>,
    last_update_ms: u32,
    history: Deque<(u32, Pose), HISTORY>,
    last_fix_ms: Option<u32>,
    outliers_in_row: u8,
    speeds: WheelSpeeds,
    pub fixes_applied: u32,
    pub fixes_rejected: u32,
}

impl Default for Odometry {
    fn default() -> Self {
        Self::new()
    }
}

impl Odometry {
    pub const fn new() -> Self {
        Self {
            pose: None,
            last_ticks: None,
            last_update_ms: 0,
            history: Deque::new(),
            last_fix_ms: None,
            outliers_in_row: 0,
            speeds: WheelSpeeds {
                left: 0.0,
                right: 0.0,
            },
            fixes_applied: 0,
            fixes_rejected: 0,
        }
    }

    /// The pose estimate, once a first fix has placed the robot.
    pub fn pose(&self) -> Option<Pose> {
        self.pose
    }

    /// Wheel rim speeds measured over the last update, m/s.
    pub fn wheel_speeds(&self) -> WheelSpeeds {
        self.speeds
    }

    pub fn fix_is_stale(&self, now_ms: u32, cfg: &RobotConfig) -> bool {
        self.last_fix_ms
            .is_none_or(|t| now_ms.wrapping_sub(t) > cfg.timeouts.pose_fix_ms)
    }

    /// Integrates the cumulative encoder counts (they may wrap).
    pub fn update(&mut self, ticks: [i32; 2], now_ms: u32, cfg: &RobotConfig) -> WheelSpeeds {
        let Some(last) = self.last_ticks.replace(ticks) else {
            self.last_update_ms = now_ms;
            return self.speeds;
        };
        let dt = now_ms.wrapping_sub(self.last_update_ms) as f32 / 1000.0;
        self.last_update_ms = now_ms;
        let per_tick = cfg.metres_per_tick();
        let dl = ticks[0].wrapping_sub(last[0]) as f32 * per_tick;
        let dr = ticks[1].wrapping_sub(last[1]) as f32 * per_tick;
        if dt > 0.0 {
            self.speeds = WheelSpeeds {
                left: dl / dt,
                right: dr / dt,
            };
        }
        if let Some(p) = self.pose.as_mut() {
            let ds = 0.5 * (dl + dr);
            let dtheta = (dr - dl) / cfg.drive.track_width;
            let (s, c) = math::sin_cos(p.heading + 0.5 * dtheta);
            p.x += ds * c;
            p.y += ds * s;
            p.heading = math::wrap_angle(p.heading + dtheta);
            if self.history.is_full() {
                self.history.pop_front();
            }
            let _ = self.history.push_back((now_ms, *p));
        }
        self.speeds
    }

    /// The odometry pose at `t` (the newest entry not after `t`, else the oldest).
    fn pose_at(&self, t: u32, now_ms: u32) -> Option<Pose> {
        let age = now_ms.wrapping_sub(t);
        self.history
            .iter()
            .rev()
            .find(|(ht, _)| now_ms.wrapping_sub(*ht) >= age)
            .or_else(|| self.history.front())
            .map(|(_, p)| *p)
            .or(self.pose)
    }

    /// Blends a pose fix in.
    pub fn apply_fix(&mut self, fix: &PoseFixSample, now_ms: u32, cfg: &RobotConfig) -> FixOutcome {
        // σ = 0 claims a perfect fix: no localization system can, so it is not one.
        if !fix.pose.is_finite() || !fix.sigma.is_finite() || fix.sigma <= 0.0 {
            return FixOutcome::Invalid;
        }
        let Some(current) = self.pose else {
            self.pose = Some(Pose {
                heading: math::wrap_angle(fix.pose.heading),
                ..fix.pose
            });
            self.history.clear();
            self.last_fix_ms = Some(now_ms);
            self.fixes_applied += 1;
            return FixOutcome::Initialized;
        };
        let then = self.pose_at(fix.time_ms, now_ms).unwrap_or(current);
        let ix = fix.pose.x - then.x;
        let iy = fix.pose.y - then.y;
        let ih = math::wrap_angle(fix.pose.heading - then.heading);
        if math::hypot(ix, iy) > cfg.fix_gate + 3.0 * fix.sigma || math::abs(ih) > HEADING_GATE {
            self.fixes_rejected += 1;
            self.outliers_in_row = self.outliers_in_row.saturating_add(1);
            if self.outliers_in_row < RELOCALIZE_AFTER {
                return FixOutcome::Rejected;
            }
            self.shift(ix, iy, ih);
            self.outliers_in_row = 0;
            self.last_fix_ms = Some(now_ms);
            return FixOutcome::Relocalized;
        }
        self.outliers_in_row = 0;
        let r = fix.sigma / FIX_SIGMA_REF;
        let w = cfg.fix_gain / (1.0 + r * r);
        self.shift(w * ix, w * iy, w * ih);
        self.last_fix_ms = Some(now_ms);
        self.fixes_applied += 1;
        FixOutcome::Applied
    }

    /// Moves the pose and its history by one correction.
    fn shift(&mut self, dx: f32, dy: f32, dh: f32) {
        let apply = |p: &mut Pose| {
            p.x += dx;
            p.y += dy;
            p.heading = math::wrap_angle(p.heading + dh);
        };
        if let Some(p) = self.pose.as_mut() {
            apply(p);
        }
        for (_, p) in self.history.iter_mut() {
            apply(p);
        }
    }
}
