//! The L-φ leader-follower law (Desai and Kumar's separation-bearing control), in the
//! singularity-free form of `paper-notes.md`.
//!
//! L and φ run from the leader's reference point to the follower's control point, d
//! ahead of the follower's axle; φ is measured from the leader's heading. With
//! γ = α_i + φ − α_j,
//!
//! ```text
//! a   = L̇_d + k1 (L_d − L) + v_i cos φ
//! c   = L (φ̇_d + k2 (φ_d − φ)) − v_i sin φ + L ω_i
//! ω_j = (a sin γ + c cos γ) / d
//! v_j =  a cos γ − c sin γ
//! ```
//!
//! which makes L̇ = L̇_d + k1 (L_d − L) and φ̇ = φ̇_d + k2 (φ_d − φ) exactly (the paper's
//! law, plus feed-forward of a moving slot). The paper's form divides by cos γ; this one
//! never divides by anything but d > 0.

use crate::config::FollowerGains;
use crate::{math, NonFinite, Pose, Twist};

/// The leader's state as a follower uses it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LeaderSnapshot {
    pub pose: Pose,
    pub v: f32,
    pub omega: f32,
}

impl LeaderSnapshot {
    pub fn is_finite(&self) -> bool {
        self.pose.is_finite() && self.v.is_finite() && self.omega.is_finite()
    }

    /// The leader `dt` seconds later, driving the same arc (latency compensation).
    pub fn predict(&self, dt: f32) -> LeaderSnapshot {
        let p = self.pose;
        let dh = self.omega * dt;
        let (x, y) = if math::abs(dh) < 1e-4 {
            let (s, c) = math::sin_cos(p.heading + 0.5 * dh);
            (p.x + self.v * dt * c, p.y + self.v * dt * s)
        } else {
            let r = self.v / self.omega;
            let (s0, c0) = math::sin_cos(p.heading);
            let (s1, c1) = math::sin_cos(p.heading + dh);
            (p.x + r * (s1 - s0), p.y - r * (c1 - c0))
        };
        LeaderSnapshot {
            pose: Pose::new(x, y, math::wrap_angle(p.heading + dh)),
            ..*self
        }
    }
}

/// A slot: desired distance L_d and bearing φ_d, with their rates while the formation
/// changes shape.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SlotRef {
    pub l: f32,
    pub phi: f32,
    pub l_rate: f32,
    pub phi_rate: f32,
}

/// L, φ and γ of a follower relative to the leader.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Relative {
    pub l: f32,
    pub phi: f32,
    pub gamma: f32,
}

pub fn relative(leader: &Pose, follower: &Pose, d: f32) -> Relative {
    let (px, py) = follower.ahead(d);
    let dx = px - leader.x;
    let dy = py - leader.y;
    let phi = math::wrap_angle(math::atan2(dy, dx) - leader.heading);
    Relative {
        l: math::hypot(dx, dy),
        phi,
        gamma: math::wrap_angle(leader.heading + phi - follower.heading),
    }
}

/// A world point as (L, φ) from the leader.
pub fn as_slot(leader: &Pose, point: (f32, f32)) -> (f32, f32) {
    let dx = point.0 - leader.x;
    let dy = point.1 - leader.y;
    (
        math::hypot(dx, dy),
        math::wrap_angle(math::atan2(dy, dx) - leader.heading),
    )
}

/// The point a slot puts the follower's control point at.
pub fn slot_point(leader: &Pose, l: f32, phi: f32) -> (f32, f32) {
    let (s, c) = math::sin_cos(leader.heading + phi);
    (leader.x + l * c, leader.y + l * s)
}

/// The follower's (v, ω) from the singularity-free law, before any limit.
pub fn lphi_law(
    leader: &LeaderSnapshot,
    follower: &Pose,
    slot: &SlotRef,
    g: &FollowerGains,
) -> Result<Twist, NonFinite> {
    let finite = leader.is_finite()
        && follower.is_finite()
        && slot.l.is_finite()
        && slot.phi.is_finite()
        && slot.l_rate.is_finite()
        && slot.phi_rate.is_finite();
    // `d > 0` is false for NaN too.
    let d_ok = g.d > 0.0;
    if !finite || !d_ok {
        return Err(NonFinite);
    }
    let r = relative(&leader.pose, follower, g.d);
    let (sphi, cphi) = math::sin_cos(r.phi);
    let (sg, cg) = math::sin_cos(r.gamma);
    let a = slot.l_rate + g.k1 * (slot.l - r.l) + leader.v * cphi;
    let c = r.l * (slot.phi_rate + g.k2 * math::wrap_angle(slot.phi - r.phi)) - leader.v * sphi
        + r.l * leader.omega;
    let out = Twist {
        v: a * cg - c * sg,
        omega: (a * sg + c * cg) / g.d,
    };
    if out.is_finite() {
        Ok(out)
    } else {
        Err(NonFinite)
    }
}

/// The (v, ω) that moves the control point, `d` ahead, straight toward a point standing
/// still in the world, at `gain` times the distance and at most `speed` (a detour's point:
/// the L-φ law would close its bearing error at k2 times the distance, 0.15 m/s at
/// 0.5 m).
pub fn toward(point: (f32, f32), follower: &Pose, d: f32, gain: f32, speed: f32) -> Twist {
    let (cx, cy) = follower.ahead(d);
    let (ex, ey) = (point.0 - cx, point.1 - cy);
    let scale = gain.min(speed / math::hypot(ex, ey).max(1e-6));
    let (ux, uy) = (ex * scale, ey * scale);
    let (s, c) = math::sin_cos(follower.heading);
    Twist {
        v: ux * c + uy * s,
        omega: (uy * c - ux * s) / d,
    }
}

/// The paper's form (divides by cos γ), for comparison in tests. `None` where
/// |cos γ| < 1e-3.
pub fn lphi_law_paper(
    leader: &LeaderSnapshot,
    follower: &Pose,
    slot: &SlotRef,
    g: &FollowerGains,
) -> Option<Twist> {
    let r = relative(&leader.pose, follower, g.d);
    let (sphi, cphi) = math::sin_cos(r.phi);
    let (sg, cg) = math::sin_cos(r.gamma);
    if math::abs(cg) < 1e-3 {
        return None;
    }
    let tg = sg / cg;
    let (vi, wi, l) = (leader.v, leader.omega, r.l);
    let e_l = g.k1 * (slot.l - l);
    let e_phi = g.k2 * math::wrap_angle(slot.phi - r.phi);
    let omega = cg / g.d * (l * e_phi - vi * sphi + l * wi + e_l * tg + vi * cphi * tg);
    let v = (e_l + vi * cphi) / cg - g.d * omega * tg;
    Some(Twist { v, omega })
}

/// Trail points kept: 14.4 m of the leader's path at 0.15 m spacing (768 bytes).
pub const TRAIL_POINTS: usize = 96;
/// Least distance between two trail points, m.
pub const TRAIL_SPACING: f32 = 0.15;

/// The path the leader drove, newest last. In the line, follower k's reference is the
/// point k·D back **along this path**, not k·D behind the leader's current heading: on a
/// straight path both are the paper's `x_i − k·D·cos α_i`, but in a turn the rigid line
/// swings its tail across the inside of the corner (1.5 m at 3 m behind in a 3 m radius
/// turn), into whatever the leader went around.
#[derive(Debug, Clone, Default)]
pub struct Trail {
    points: heapless::Deque<(f32, f32), TRAIL_POINTS>,
}

impl Trail {
    pub const fn new() -> Self {
        Self {
            points: heapless::Deque::new(),
        }
    }

    /// Records where the leader was (ignores NaN and points closer than the spacing).
    pub fn record(&mut self, x: f32, y: f32) {
        if !(x.is_finite() && y.is_finite()) {
            return;
        }
        if let Some(&(lx, ly)) = self.points.back() {
            if math::hypot(x - lx, y - ly) < TRAIL_SPACING {
                return;
            }
        }
        if self.points.is_full() {
            self.points.pop_front();
        }
        let _ = self.points.push_back((x, y));
    }

    pub fn clear(&mut self) {
        self.points.clear();
    }

    /// The point `s` metres back along the path from the leader at `leader`
    /// ([`behind_along`] the recorded path).
    pub fn behind(&self, leader: &Pose, s: f32) -> (f32, f32) {
        behind_along(leader, self.points.iter().rev().copied(), s)
    }
}

/// The point `s` metres back along a path (`newest_first`) from the leader at `leader`.
/// Beyond the path it goes on straight, along the chord from the leader to the path's
/// start (stable against a wiggle at the start), or straight behind the leader when less
/// than half a metre is recorded. The robot's trail and the base station's view of it use
/// this one function.
pub fn behind_along(
    leader: &Pose,
    newest_first: impl IntoIterator<Item = (f32, f32)>,
    s: f32,
) -> (f32, f32) {
    let mut remaining = s;
    let mut cur = (leader.x, leader.y);
    for (px, py) in newest_first {
        let (dx, dy) = (px - cur.0, py - cur.1);
        let seg = math::hypot(dx, dy);
        if seg < 1e-6 {
            continue;
        }
        if seg >= remaining {
            let k = remaining / seg;
            return (cur.0 + dx * k, cur.1 + dy * k);
        }
        remaining -= seg;
        cur = (px, py);
    }
    let (cx, cy) = (cur.0 - leader.x, cur.1 - leader.y);
    let chord = math::hypot(cx, cy);
    let back = if s - remaining > 0.5 && chord > 0.25 {
        (cx / chord, cy / chord)
    } else {
        let (sh, ch) = math::sin_cos(leader.heading);
        (-ch, -sh)
    };
    (cur.0 + back.0 * remaining, cur.1 + back.1 * remaining)
}

/// A follower's two slots, and the shape between them.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Slots {
    /// (L, φ) in the wide formation (triangle / V / custom).
    pub wide: (f32, f32),
    /// (L, φ) in the line.
    pub line: (f32, f32),
}

impl Slots {
    /// The reference point at `blend` (0 = wide, 1 = line), in the world: between the wide
    /// slot point (rigid, relative to the leader's pose) and the line slot's distance back
    /// along the leader's trail.
    pub fn reference(&self, leader: &Pose, blend: f32, trail: &Trail) -> (f32, f32) {
        let b = math::clamp(blend, 0.0, 1.0);
        let (wx, wy) = slot_point(leader, self.wide.0, self.wide.1);
        if b <= 0.0 {
            return (wx, wy);
        }
        let (lx, ly) = trail.behind(leader, self.line.0);
        (wx + (lx - wx) * b, wy + (ly - wy) * b)
    }

    /// The slot at `blend` with a rigid line (leader frame only): the slot point moves on
    /// a straight line in the leader's frame, so the reference never jumps.
    pub fn at(&self, blend: f32) -> (f32, f32) {
        let b = math::clamp(blend, 0.0, 1.0);
        // The end points exactly, without an atan2 round trip.
        if b <= 0.0 {
            return self.wide;
        }
        if b >= 1.0 {
            return self.line;
        }
        let point = |(l, phi): (f32, f32)| {
            let (s, c) = math::sin_cos(phi);
            (l * c, l * s)
        };
        let (wx, wy) = point(self.wide);
        let (lx, ly) = point(self.line);
        let x = wx + (lx - wx) * b;
        let y = wy + (ly - wy) * b;
        (math::hypot(x, y), math::atan2(y, x))
    }
}
