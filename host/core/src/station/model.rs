//! The one forward model of the fleet: how the robots will move over the next seconds if
//! the leader is told to make for a speed along its path. The leader ramps to the speed
//! within its acceleration and braking limits once the commands already sent have shown
//! (the command lag); each follower drives its own firmware's law (`control_core`: the
//! L-φ law toward its reference where the formation manager puts it, or a detour's law
//! toward the point it is sent to) through the firmware's limits, at the firmware's
//! period. The leader's pace among movers rolls every candidate out with it, and the
//! spacing between robots judges a follower's swing with it: one model, the firmware's
//! own, where each room used to keep its own guess of how the followers move.

use control_core::controller::{self, DETOUR_GAIN, DETOUR_SPEED};
use control_core::follower::{self, LeaderSnapshot, SlotRef};
use control_core::{math, Pose, RobotConfig, Twist};
use glam::DVec2;

use crate::formation::FormationManager;
use crate::geometry::PlanPose;

/// The model's step: the firmware's control period, s.
pub const STEP_S: f64 = 0.1;
/// The slot's own motion is fed forward over this, as the firmware does, s.
const SLOT_RATE_S: f64 = 0.05;

/// A polyline by arc length: the leader's path ahead.
#[derive(Debug, Clone)]
pub struct Path<'a> {
    points: &'a [DVec2],
    arcs: Vec<f64>,
}

impl<'a> Path<'a> {
    pub fn new(points: &'a [DVec2]) -> Self {
        let mut arcs = Vec::with_capacity(points.len());
        let mut total = 0.0;
        for (i, p) in points.iter().enumerate() {
            if i > 0 {
                total += points[i - 1].distance(*p);
            }
            arcs.push(total);
        }
        Self { points, arcs }
    }

    /// The pose `s` along (the leader's own pose at 0; standing at the end; straight back
    /// along its heading for `s` < 0: backing).
    pub fn pose_at(&self, s: f64, start: PlanPose) -> PlanPose {
        let n = self.points.len();
        if s < 0.0 {
            let back = DVec2::from_angle(start.heading) * s;
            return PlanPose {
                position: start.position + back,
                heading: start.heading,
            };
        }
        if n < 2 || s == 0.0 {
            return start;
        }
        let i = self.arcs.partition_point(|a| *a <= s).clamp(1, n - 1);
        let (a, b) = (self.points[i - 1], self.points[i]);
        let seg = self.arcs[i] - self.arcs[i - 1];
        let f = if seg > 1e-9 {
            ((s - self.arcs[i - 1]) / seg).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let d = b - a;
        PlanPose {
            position: a.lerp(b, f),
            heading: if d.length() > 1e-9 {
                d.to_angle()
            } else {
                start.heading
            },
        }
    }

    /// The path driven by the time the leader is `s` along: the stretch ahead it covered,
    /// back to where it is now, then `behind` (from where it is now, newest first).
    pub fn behind(&self, s: f64, start: PlanPose, behind: &[DVec2]) -> Vec<DVec2> {
        let mut out = vec![self.pose_at(s, start).position];
        let covered = self.arcs.partition_point(|a| *a < s);
        out.extend(self.points[..covered.min(self.points.len())].iter().rev());
        out.extend(behind.iter().skip(1));
        out
    }
}

/// The points of `trail` up to the first `length` along it from its first, and the one
/// beyond.
pub fn prefix(trail: &[DVec2], length: f64) -> &[DVec2] {
    let mut along = 0.0;
    for (k, w) in trail.windows(2).enumerate() {
        along += w[0].distance(w[1]);
        if along > length {
            return &trail[..k + 2];
        }
    }
    trail
}

/// What a follower makes for in the model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Goal {
    /// Its slot (the formation manager's reference for slot `k`).
    Slot(usize),
    /// A point it is sent to (a detour, a step aside), driven by the detour's law.
    Point(DVec2),
    /// It is held where it stands.
    Hold,
}

/// A robot in the model: its pose and the twist it drives.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Robot {
    pub pose: Pose,
    pub twist: Twist,
}

impl Robot {
    pub fn new(position: DVec2, heading: f64, v: f64) -> Self {
        Self {
            pose: Pose::new(position.x as f32, position.y as f32, heading as f32),
            twist: Twist {
                v: v as f32,
                omega: 0.0,
            },
        }
    }

    pub fn position(&self) -> DVec2 {
        DVec2::new(self.pose.x as f64, self.pose.y as f64)
    }

    /// Its velocity in the site frame, m/s.
    pub fn velocity(&self) -> DVec2 {
        DVec2::from_angle(self.pose.heading as f64) * self.twist.v as f64
    }

    /// One step of `dt` driving `asked` through the firmware's limits.
    pub fn drive(&mut self, cfg: &RobotConfig, asked: Twist, dt: f32) {
        self.twist = controller::limit(&cfg.limits, self.twist, asked, dt);
        let (s, c) = math::sin_cos(self.pose.heading + 0.5 * self.twist.omega * dt);
        self.pose.x += self.twist.v * dt * c;
        self.pose.y += self.twist.v * dt * s;
        self.pose.heading = math::wrap_angle(self.pose.heading + self.twist.omega * dt);
    }
}

/// The leader as the model starts it, and how it may change speed.
#[derive(Debug, Clone, Copy)]
pub struct LeaderStart {
    pub pose: PlanPose,
    /// Its speed now, m/s.
    pub v: f64,
    /// The speed last commanded: it makes for that until the lag is over, m/s.
    pub commanded: f64,
    /// The commands sent show this late, s.
    pub lag_s: f64,
    pub accel: f64,
    pub brake: f64,
}

/// What the model needs of the fleet.
#[derive(Debug, Clone, Copy)]
pub struct Fleet<'a> {
    pub leader: LeaderStart,
    /// Each follower now, with what it makes for.
    pub followers: &'a [(Robot, Goal)],
    /// The path ahead from the leader, and the path it drove (newest first).
    pub ahead: &'a Path<'a>,
    pub behind: &'a [DVec2],
    pub formation: &'a FormationManager,
    pub robot: &'a RobotConfig,
    /// The station's clock now, s: a shape change under way goes on in the rollout.
    pub now_s: f64,
}

/// The fleet at one instant of a rollout: the leader first, then the followers in
/// their order.
#[derive(Debug, Clone)]
pub struct Instant {
    pub t: f64,
    pub robots: Vec<Robot>,
}

/// How the leader moves in a rollout.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Plan {
    /// Along its path, making for this speed, m/s (negative: backing straight along its
    /// heading).
    Along(f64),
    /// Off its path: its control point makes for this point, as a follower's detour does.
    Toward(DVec2),
}

/// The fleet rolled out for `horizon_s`, the leader as `plan` says; an instant per step,
/// the start left out.
pub fn rollout(fleet: &Fleet, plan: Plan, horizon_s: f64) -> Vec<Instant> {
    match plan {
        Plan::Along(target) => rollout_along(fleet, target, horizon_s),
        Plan::Toward(point) => rollout_toward(fleet, point, horizon_s),
    }
}

/// The leader making for `point` off its path, the followers after it (the line along
/// the way it drove).
fn rollout_toward(fleet: &Fleet, point: DVec2, horizon_s: f64) -> Vec<Instant> {
    let dt = STEP_S;
    let l = fleet.leader;
    let mut lead = Robot::new(l.pose.position, l.pose.heading, l.v);
    let mut driven: Vec<DVec2> = fleet.behind.to_vec();
    let mut followers: Vec<Robot> = fleet.followers.iter().map(|(r, _)| *r).collect();
    let target = (point.x as f32, point.y as f32);
    let steps = (horizon_s / dt).round() as usize;
    let mut out = Vec::with_capacity(steps);
    for k in 1..=steps {
        let t = k as f64 * dt;
        let asked = follower::toward(
            target,
            &lead.pose,
            fleet.robot.gains.d,
            DETOUR_GAIN,
            DETOUR_SPEED,
        );
        lead.drive(fleet.robot, asked, dt as f32);
        driven.insert(0, lead.position());
        let leader = LeaderSnapshot {
            pose: lead.pose,
            v: lead.twist.v,
            omega: lead.twist.omega,
        };
        let blend = fleet.formation.blend_at(fleet.now_s + t);
        for (f, (_, goal)) in followers.iter_mut().zip(fleet.followers) {
            let asked = law(fleet, &leader, &driven, blend, f, *goal);
            f.drive(fleet.robot, asked, dt as f32);
        }
        let mut robots = Vec::with_capacity(followers.len() + 1);
        robots.push(lead);
        robots.extend_from_slice(&followers);
        out.push(Instant { t, robots });
    }
    out
}

/// The leader making for `target` m/s along its path.
fn rollout_along(fleet: &Fleet, target: f64, horizon_s: f64) -> Vec<Instant> {
    let dt = STEP_S;
    let l = fleet.leader;
    let trail = prefix(fleet.behind, fleet.formation.line_reach() + 1.0);
    let (mut v, mut s) = (l.v, 0.0);
    let mut heading = l.pose.heading;
    let mut followers: Vec<Robot> = fleet.followers.iter().map(|(r, _)| *r).collect();
    let steps = (horizon_s / dt).round() as usize;
    let mut out = Vec::with_capacity(steps);
    for k in 1..=steps {
        let t = k as f64 * dt;
        let goal = if t <= l.lag_s + 1e-9 {
            l.commanded
        } else {
            target
        };
        let dv = (goal - v).clamp(-l.brake * dt, l.accel * dt);
        s += (v + 0.5 * dv) * dt;
        v += dv;
        let pose = fleet.ahead.pose_at(s, l.pose);
        let omega = math::wrap_angle((pose.heading - heading) as f32) / dt as f32;
        heading = pose.heading;
        let leader = snapshot(pose, v, omega);
        let blend = fleet.formation.blend_at(fleet.now_s + t);
        let behind = (blend > 0.0).then(|| fleet.ahead.behind(s, l.pose, trail));
        let behind = behind.as_deref().unwrap_or(&[]);
        for (f, (_, goal)) in followers.iter_mut().zip(fleet.followers) {
            let asked = law(fleet, &leader, behind, blend, f, *goal);
            f.drive(fleet.robot, asked, dt as f32);
        }
        let mut robots = Vec::with_capacity(followers.len() + 1);
        let mut lead = Robot::new(pose.position, pose.heading, v);
        lead.twist.omega = omega;
        robots.push(lead);
        robots.extend_from_slice(&followers);
        out.push(Instant { t, robots });
    }
    out
}

fn snapshot(pose: PlanPose, v: f64, omega: f32) -> LeaderSnapshot {
    LeaderSnapshot {
        pose: Pose::new(
            pose.position.x as f32,
            pose.position.y as f32,
            pose.heading as f32,
        ),
        v: v as f32,
        omega,
    }
}

/// What follower `f`'s firmware asks this step for `goal`, the leader at `leader`, the
/// shape at `blend`.
fn law(
    fleet: &Fleet,
    leader: &LeaderSnapshot,
    behind: &[DVec2],
    blend: f64,
    f: &Robot,
    goal: Goal,
) -> Twist {
    let d = fleet.robot.gains.d;
    match goal {
        Goal::Hold => Twist::ZERO,
        Goal::Point(p) => follower::toward(
            (p.x as f32, p.y as f32),
            &f.pose,
            d,
            DETOUR_GAIN,
            DETOUR_SPEED,
        ),
        Goal::Slot(k) => {
            let slot = slot_ref(fleet, leader, behind, blend, k);
            follower::lphi_law(leader, &f.pose, &slot, &fleet.robot.gains).unwrap_or(Twist::ZERO)
        }
    }
}

/// Slot `k` as (L, φ) from the leader, with its rates, as the firmware feeds them forward.
fn slot_ref(
    fleet: &Fleet,
    leader: &LeaderSnapshot,
    behind: &[DVec2],
    blend: f64,
    k: usize,
) -> SlotRef {
    let at = |l: &LeaderSnapshot| {
        let pose = PlanPose {
            position: DVec2::new(l.pose.x as f64, l.pose.y as f64),
            heading: l.pose.heading as f64,
        };
        let p = fleet.formation.reference_at(k, pose, behind, blend);
        follower::as_slot(&l.pose, (p.x as f32, p.y as f32))
    };
    let (l, phi) = at(leader);
    let h = SLOT_RATE_S as f32;
    let (l2, phi2) = at(&leader.predict(h));
    SlotRef {
        l,
        phi,
        l_rate: (l2 - l) / h,
        phi_rate: math::wrap_angle(phi2 - phi) / h,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::Scenario;

    fn paper() -> (FormationManager, RobotConfig) {
        let src = include_str!("../../../../scenarios/paper-obstacles.toml");
        let s = Scenario::parse(src, "paper-obstacles.toml").expect("the shipped scenario");
        (FormationManager::new(s.formation_spec()), s.robot_config())
    }

    /// The leader along +x from the origin, its followers in their triangle slots.
    fn fleet_rollout(v: f64, target: f64, lag_s: f64) -> Vec<Instant> {
        let (formation, robot) = paper();
        let ahead: Vec<DVec2> = (0..80).map(|k| DVec2::new(k as f64 * 0.25, 0.0)).collect();
        let path = Path::new(&ahead);
        let start = PlanPose {
            position: DVec2::ZERO,
            heading: 0.0,
        };
        let followers: Vec<(Robot, Goal)> = (0..2)
            .map(|k| {
                let slot = formation.reference(k, start, &[]);
                let centre = slot - DVec2::X * robot.gains.d as f64;
                (Robot::new(centre, 0.0, v), Goal::Slot(k))
            })
            .collect();
        let fleet = Fleet {
            leader: LeaderStart {
                pose: start,
                v,
                commanded: v,
                lag_s,
                accel: 0.5,
                brake: 0.8,
            },
            followers: &followers,
            ahead: &path,
            behind: &[DVec2::ZERO, DVec2::new(-5.0, 0.0)],
            formation: &formation,
            robot: &robot,
            now_s: 0.0,
        };
        rollout(&fleet, Plan::Along(target), 3.0)
    }

    #[test]
    fn a_fleet_at_pace_keeps_its_slots_and_brakes_within_its_limits() {
        let cruise = fleet_rollout(0.4, 0.4, 0.3);
        let last = cruise.last().expect("steps");
        assert!((last.robots[0].position().x - 1.2).abs() < 1e-6);
        // The followers keep their slots, 1.2 m on.
        for f in &last.robots[1..] {
            let x = f.position().x + 0.2;
            assert!((x - (1.2 - 3.0 * 0.866)).abs() < 0.05, "{x}");
        }
        // Told to stop: it goes on at 0.4 m/s for the lag, then brakes at 0.8 m/s² for
        // 0.5 s: 0.12 + 0.1 m.
        let stop = fleet_rollout(0.4, 0.0, 0.3);
        let last = stop.last().expect("steps");
        assert!((last.robots[0].position().x - 0.22).abs() < 1e-6);
        // Its followers stop with it, within a few centimetres of their slots.
        for f in &last.robots[1..] {
            assert!(f.twist.v.abs() < 0.02, "{:?}", f.twist);
        }
    }

    #[test]
    fn backing_goes_straight_back_along_the_heading() {
        let back = fleet_rollout(0.0, -0.24, 0.0);
        let p = back.last().expect("steps").robots[0].position();
        assert!(p.y.abs() < 1e-9 && p.x < -0.5, "{p}");
    }
}
