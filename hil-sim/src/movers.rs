//! What moves on the site besides the robots: people, cyclists and vehicles on their
//! paths, and crowds walking between random points of an area (`[[movers]]`,
//! `[[crowds]]`). Stepped on the world's clock, seeded, nothing read from the wall clock.
//!
//! - **Oblivious** movers keep to their path at their speed whatever is in the way (the
//!   worst case: they walk into a robot that stands).
//! - **Social** movers follow the social force model (Helbing & Molnár 1995, with the
//!   anisotropy of Helbing, Farkas & Vicsek 2000): each accelerates toward its desired
//!   velocity (relaxation time `TAU`) and is pushed off the other movers, the robots and
//!   the obstacles by forces that fall off exponentially with the gap between footprints;
//!   what lies behind it pushes it less (`LAMBDA`). People's neighbours are looked up in
//!   a grid of `CELL` cells, so a plaza of hundreds costs what their neighbourhoods do.

use base_station::geometry;
use base_station::geometry::cells::{cell_of, CellIndex};
use base_station::geometry::map::Map;
use base_station::scenario::movers::{
    Behavior, CrowdSpec, MoverKind, MoverShape, MoverSpec, Repeat,
};
use base_station::scenario::Scenario;
use glam::DVec2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Relaxation time toward the desired velocity, s.
const TAU: f64 = 0.5;
/// Strength and range of the push between movers (and from robots), m/s², m.
const A_AGENT: f64 = 2.1;
const B_AGENT: f64 = 0.3;
/// A robot pushes harder and farther: people keep further from machines.
const A_ROBOT: f64 = 10.0;
const B_ROBOT: f64 = 0.5;
/// The step aside from a robot ahead, as a share of its push.
const SIDESTEP: f64 = 0.5;
/// Bodies in contact push apart hard (Helbing, Farkas & Vicsek 2000: k / m), 1/s².
const K_BODY: f64 = 1500.0;
/// How often the movers decide their velocities, s: 10 Hz, as social-force crowd
/// simulations step (CrowdNav: 4 Hz), and about as often as a walker adjusts. They move
/// every physics step (10 ms) along them; deciding at 100 Hz cost a third of a crowd's
/// run (the paper's map with 20 pedestrians: 318 × real time; 20 Hz 488 ×, 10 Hz 610 ×).
const DECIDE_S: f64 = 0.1;
/// Strength and range of the push from obstacles, m/s², m.
const A_WALL: f64 = 5.0;
const B_WALL: f64 = 0.2;
/// How much what lies behind pushes, relative to what lies ahead.
const LAMBDA: f64 = 0.35;
/// Forces are summed over what lies within this of a mover, m.
const INTERACTION: f64 = 3.0;
/// Neighbour grid cell, m (≥ `INTERACTION`).
const CELL: f64 = 3.0;
/// A social mover walks at most this much faster than it wants to.
const MAX_SPEED_FACTOR: f64 = 1.3;
/// A path point is reached within this, m.
const REACHED: f64 = 0.25;

/// A robot as the movers see it: where it is, how it moves, its footprint's radius.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RobotBody {
    pub position: DVec2,
    pub velocity: DVec2,
    pub radius: f64,
}

/// A mover now: where it is, which way it faces, how it moves, its footprint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MoverState {
    pub index: usize,
    pub kind: MoverKind,
    pub position: DVec2,
    pub velocity: DVec2,
    /// Which way it faces (its way, for a rectangle), rad.
    pub heading: f64,
    pub shape: MoverShape,
    /// It keeps to its way whatever is in it: its way does not depend on the robots.
    pub oblivious: bool,
}

impl MoverState {
    /// The distance from `p` to its footprint (negative inside).
    pub fn distance(&self, p: DVec2) -> f64 {
        match self.shape {
            MoverShape::Circle { radius } => (p - self.position).length() - radius,
            MoverShape::Rectangle { length, width } => {
                let local = (p - self.position).rotate(DVec2::from_angle(-self.heading));
                let d = local.abs() - DVec2::new(0.5 * length, 0.5 * width);
                d.max(DVec2::ZERO).length() + d.x.max(d.y).min(0.0)
            }
        }
    }

    /// The unit vector from `p` toward the nearest point of its footprint (toward its
    /// centre where `p` is inside it or on the centre).
    pub fn toward_from(&self, p: DVec2) -> DVec2 {
        let nearest = match self.shape {
            MoverShape::Circle { .. } => self.position,
            MoverShape::Rectangle { length, width } => {
                let turn = DVec2::from_angle(-self.heading);
                let local = (p - self.position).rotate(turn);
                let half = DVec2::new(0.5 * length, 0.5 * width);
                let inside = local.abs().cmplt(half).all();
                let clamped = if inside {
                    DVec2::ZERO
                } else {
                    local.clamp(-half, half)
                };
                self.position + clamped.rotate(DVec2::from_angle(self.heading))
            }
        };
        (nearest - p).try_normalize().unwrap_or(DVec2::X)
    }

    /// Distance along the unit ray from `o` in `dir` to its footprint, if it hits.
    pub fn ray(&self, o: DVec2, dir: DVec2) -> Option<f64> {
        match self.shape {
            MoverShape::Circle { radius } => geometry::ray_circle(o, dir, self.position, radius),
            MoverShape::Rectangle { length, width } => {
                let turn = DVec2::from_angle(-self.heading);
                let (lo, ld) = ((o - self.position).rotate(turn), dir.rotate(turn));
                let half = DVec2::new(0.5 * length, 0.5 * width);
                // Slabs: where the ray is inside both pairs of sides.
                let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
                for (p, d, h) in [(lo.x, ld.x, half.x), (lo.y, ld.y, half.y)] {
                    if d.abs() < 1e-12 {
                        if p.abs() > h {
                            return None;
                        }
                        continue;
                    }
                    let (a, b) = ((-h - p) / d, (h - p) / d);
                    t0 = t0.max(a.min(b));
                    t1 = t1.min(a.max(b));
                }
                (t0 <= t1).then_some(t0)
            }
        }
    }
}

/// Where a mover is going next along its path.
#[derive(Debug, Clone)]
enum Way {
    /// A path of its own: the point it makes for and which way it goes along the path.
    Path { next: usize, forward: bool },
    /// A crowd's: a random point of the area, the crowd's random source.
    /// `until`: when it gives the goal up (something stands on it, or in the way), s.
    Wander {
        goal: DVec2,
        crowd: usize,
        until: f64,
    },
}

#[derive(Debug, Clone)]
struct Mover {
    kind: MoverKind,
    shape: MoverShape,
    behavior: Behavior,
    path: Vec<DVec2>,
    repeat: Repeat,
    speed: f64,
    start_s: f64,
    /// (path point, seconds): stops not yet made.
    pauses: Vec<(usize, f64)>,
    way: Way,
    position: DVec2,
    velocity: DVec2,
    heading: f64,
    /// Standing until then, s.
    paused_until: f64,
    /// At the end of a path walked once.
    done: bool,
}

/// A crowd's area and random source.
#[derive(Debug, Clone)]
struct Crowd {
    min: DVec2,
    max: DVec2,
    rng: ChaCha8Rng,
}

impl Crowd {
    fn point(&mut self) -> DVec2 {
        DVec2::new(
            self.rng.random_range(self.min.x..self.max.x),
            self.rng.random_range(self.min.y..self.max.y),
        )
    }

    /// Where a person of `reach` at `from` walks to next: a random point of the area. An
    /// oblivious one walks straight whatever is in the way, so theirs is one the straight
    /// way to which the site leaves room for them (a few tries; a cluttered area takes
    /// what it gets): drawn anywhere, they walked through the plaza's pillars. A social
    /// one steers round what stands (its draws are as they were).
    fn goal(&mut self, from: DVec2, reach: f64, behavior: Behavior, site: &Map) -> DVec2 {
        let mut goal = self.point();
        if behavior == Behavior::Oblivious {
            for _ in 0..GOAL_TRIES {
                if walkable(site, from, goal, reach) {
                    break;
                }
                goal = self.point();
            }
        }
        goal
    }
}

/// An oblivious person's goal is drawn at most this many times more.
const GOAL_TRIES: usize = 20;

/// Whether the straight way from `from` to `to` keeps a footprint of `reach` off the
/// site's obstacles (looked at every 0.25 m).
fn walkable(site: &Map, from: DVec2, to: DVec2, reach: f64) -> bool {
    let steps = (from.distance(to) / 0.25).ceil().max(1.0) as usize;
    (0..=steps).all(|k| site.clearance(from.lerp(to, k as f64 / steps as f64), reach) >= reach)
}

/// Everything that moves on the site.
#[derive(Debug, Clone, Default)]
pub struct Movers {
    movers: Vec<Mover>,
    crowds: Vec<Crowd>,
    /// Since the social model last decided, s.
    since_decision_s: f64,
}

fn from_spec(spec: &MoverSpec) -> Mover {
    let path = spec.points();
    let start = path.first().copied().unwrap_or_default();
    let heading = path.get(1).map_or(0.0, |p| (*p - start).to_angle());
    Mover {
        kind: spec.kind,
        shape: spec.shape(),
        behavior: spec.behavior,
        repeat: spec.repeat,
        speed: spec.speed,
        start_s: spec.start_s,
        pauses: spec.pauses.iter().map(|p| (p.at, p.for_s)).collect(),
        way: Way::Path {
            next: 1.min(path.len() - 1),
            forward: true,
        },
        position: start,
        velocity: DVec2::ZERO,
        heading,
        paused_until: f64::NEG_INFINITY,
        done: path.len() < 2,
        path,
    }
}

impl Movers {
    /// The scenario's movers, and its crowds placed at random (seeded by each crowd's
    /// seed and the run's) where the site is free and no robot starts.
    pub fn new(scenario: &Scenario, site: &Map, seed: u64) -> Self {
        let mut movers: Vec<Mover> = scenario.movers.iter().map(from_spec).collect();
        let mut crowds = Vec::new();
        let starts: Vec<DVec2> = scenario
            .robots
            .iter()
            .map(|r| DVec2::new(r.start.x, r.start.y))
            .collect();
        for (k, spec) in scenario.crowds.iter().enumerate() {
            let mut crowd = Crowd {
                min: DVec2::from(spec.area.min),
                max: DVec2::from(spec.area.max),
                rng: ChaCha8Rng::seed_from_u64(spec.seed ^ seed.rotate_left(17) ^ k as u64),
            };
            let placed = place_crowd(spec, &mut crowd, site, &starts, k);
            movers.extend(placed);
            crowds.push(crowd);
        }
        Self {
            movers,
            crowds,
            since_decision_s: 0.0,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.movers.is_empty()
    }

    /// How many there are over the run (crowds' persons included).
    pub fn len(&self) -> usize {
        self.movers.len()
    }

    /// Every mover on the site now (those not started yet are not).
    pub fn states(&self, t_s: f64) -> impl Iterator<Item = MoverState> + '_ {
        self.movers
            .iter()
            .enumerate()
            .filter(move |(_, m)| t_s >= m.start_s)
            .map(|(index, m)| MoverState {
                index,
                kind: m.kind,
                position: m.position,
                velocity: m.velocity,
                heading: m.heading,
                shape: m.shape,
                oblivious: m.behavior == Behavior::Oblivious,
            })
    }

    /// One step of `dt` ending at `t_s`: each mover on along its velocity; every
    /// [`DECIDE_S`] the social model decides the velocities anew. `robots`: each robot's
    /// position, velocity and footprint radius; `site`: the obstacles.
    pub fn step(&mut self, t_s: f64, dt: f64, robots: &[RobotBody], site: &Map) {
        self.since_decision_s += dt;
        if self.since_decision_s + 1e-9 >= DECIDE_S {
            let span = std::mem::take(&mut self.since_decision_s);
            self.decide(t_s, span, robots, site);
        }
        for m in self.movers.iter_mut().filter(|m| t_s >= m.start_s) {
            m.position += m.velocity * dt;
        }
    }

    /// Every mover's velocity for the next `span` seconds: where it wants to go, and
    /// (social ones) the push of the others, the robots and the obstacles.
    fn decide(&mut self, t_s: f64, span: f64, robots: &[RobotBody], site: &Map) {
        let grid = self.grid(t_s);
        let forces: Vec<DVec2> = (0..self.movers.len())
            .map(|i| self.social_force(i, t_s, span, &grid, robots, site))
            .collect();
        for (i, force) in forces.into_iter().enumerate() {
            if t_s < self.movers[i].start_s {
                continue;
            }
            let desired = self.desired_velocity(i, t_s, robots, site);
            let m = &mut self.movers[i];
            m.velocity = match m.behavior {
                Behavior::Oblivious => desired,
                Behavior::Social => {
                    let v = m.velocity + ((desired - m.velocity) / TAU + force) * span;
                    v.clamp_length_max(MAX_SPEED_FACTOR * m.speed)
                }
            };
            if m.velocity.length() > 0.05 {
                m.heading = m.velocity.to_angle();
            }
        }
    }

    /// The movers on the site by grid cell.
    fn grid(&self, t_s: f64) -> CellIndex {
        let on_site = self
            .movers
            .iter()
            .enumerate()
            .filter(|(_, m)| t_s >= m.start_s);
        CellIndex::new(CELL, on_site.map(|(i, m)| (cell_of(m.position, CELL), i)))
    }

    /// Where mover `i` wants to go and how fast: along its path (or to its crowd's goal),
    /// standing while it pauses or is done. Advances its way when it reaches a point.
    /// A social mover heads round the robots in its way (see [`heading_round`]).
    fn desired_velocity(&mut self, i: usize, t_s: f64, robots: &[RobotBody], site: &Map) -> DVec2 {
        let Some(target) = self.target(i, t_s, site) else {
            return DVec2::ZERO;
        };
        let m = &self.movers[i];
        let to = target - m.position;
        let speed = m.speed.min(to.length() / TAU.max(0.1) + 0.1);
        let way = match m.behavior {
            Behavior::Oblivious => to.normalize_or_zero(),
            Behavior::Social => heading_round(m.position, m.shape.reach(), target, robots),
        };
        way * speed
    }

    /// The point mover `i` makes for now, passing the points it has reached.
    fn target(&mut self, i: usize, t_s: f64, site: &Map) -> Option<DVec2> {
        let m = &mut self.movers[i];
        if m.done || t_s < m.paused_until {
            return None;
        }
        match m.way.clone() {
            Way::Wander { goal, crowd, until } => {
                if (goal - m.position).length() > REACHED && t_s < until {
                    return Some(goal);
                }
                let (from, speed) = (m.position, m.speed);
                let (reach, behavior) = (m.shape.reach(), m.behavior);
                let goal = self.crowds[crowd].goal(from, reach, behavior, site);
                let until = t_s + give_up_after(from, goal, speed);
                self.movers[i].way = Way::Wander { goal, crowd, until };
                Some(goal)
            }
            Way::Path { next, forward } => {
                let point = m.path[next];
                if (point - m.position).length() > REACHED {
                    return Some(point);
                }
                if let Some(k) = m.pauses.iter().position(|(at, _)| *at == next) {
                    let (_, for_s) = m.pauses.remove(k);
                    m.paused_until = t_s + for_s;
                }
                match advance(next, forward, m.path.len(), m.repeat) {
                    Some((next, forward)) => m.way = Way::Path { next, forward },
                    None => m.done = true,
                }
                None
            }
        }
    }

    /// The push on mover `i` from the other movers, the robots and the obstacles
    /// (social movers only; zero for the oblivious).
    fn social_force(
        &self,
        i: usize,
        t_s: f64,
        span: f64,
        grid: &CellIndex,
        robots: &[RobotBody],
        site: &Map,
    ) -> DVec2 {
        let m = &self.movers[i];
        if m.behavior == Behavior::Oblivious || t_s < m.start_s {
            return DVec2::ZERO;
        }
        let facing = DVec2::from_angle(m.heading);
        let r = m.shape.reach();
        // Bodies that overlap are pushed apart, at most by the overlap over the next
        // decision (a stiffer push would overshoot at 10 Hz).
        let body = K_BODY.min(1.0 / (span * span));
        let push = |from: DVec2, gap: f64, a: f64, b: f64| {
            let away = (m.position - from).normalize_or_zero();
            // Less from behind: (λ + (1 − λ)(1 + cos φ)/2), φ between its way and the other.
            let cos = (-away).dot(facing);
            let weight = LAMBDA + (1.0 - LAMBDA) * 0.5 * (1.0 + cos);
            away * a * (-gap / b).exp() * weight
        };
        let mut force = DVec2::ZERO;
        for j in grid.around(m.position).filter(|j| *j != i) {
            let o = &self.movers[j];
            let gap = (o.position - m.position).length() - r - o.shape.reach();
            if gap < INTERACTION {
                force += push(o.position, gap, A_AGENT, B_AGENT);
            }
            if gap < 0.0 {
                force += (m.position - o.position).normalize_or_zero() * body * -gap;
            }
        }
        for RobotBody {
            position: p,
            radius,
            ..
        } in robots
        {
            let gap = (*p - m.position).length() - r - radius;
            if gap < INTERACTION {
                // And a step to their right where the machine is ahead of them: people
                // go round a machine in their way instead of standing against it (a
                // head-on push has no side to it).
                let away = push(*p, gap, A_ROBOT, B_ROBOT);
                let ahead = (*p - m.position).normalize_or_zero().dot(facing).max(0.0);
                force += away + -facing.perp() * away.length() * SIDESTEP * ahead;
            }
            if gap < 0.0 {
                force += (m.position - *p).normalize_or_zero() * body * -gap;
            }
        }
        if let Some(wall) = site.nearest(m.position, INTERACTION) {
            let gap = wall.distance - r;
            force += wall.normal * A_WALL * (-gap / B_WALL).exp();
        }
        force
    }
}

/// The next point along a path of `len` points after `next` (reached), going `forward`;
/// `None` at the end of a path walked once.
fn advance(next: usize, forward: bool, len: usize, repeat: Repeat) -> Option<(usize, bool)> {
    let last = len - 1;
    match (repeat, forward) {
        (_, true) if next < last => Some((next + 1, true)),
        (_, false) if next > 0 => Some((next - 1, false)),
        (Repeat::Once, _) => None,
        (Repeat::Loop, _) => Some((0, true)),
        (Repeat::BackAndForth, true) => Some((last.saturating_sub(1), false)),
        (Repeat::BackAndForth, false) => Some((1.min(last), true)),
    }
}

/// The way a person heads for `goal` from `at` with robots about (Moussaïd, Helbing &
/// Theraulaz 2011: of the headings within 90° of the goal's, the one that brings them
/// nearest to it, walking on until [`LOOK_AHEAD`] or until they would come within
/// [`PASS_ROBOT`] of a robot's footprint, where it is or will be in the next
/// [`ANTICIPATE_S`] seconds). People go round a machine in their way, passing behind one
/// that drives on, instead of pressing against it.
fn heading_round(at: DVec2, reach: f64, goal: DVec2, robots: &[RobotBody]) -> DVec2 {
    let to = goal - at;
    let d_goal = to.length();
    let straight = to.normalize_or_zero();
    let look = d_goal.min(LOOK_AHEAD);
    // Where each robot is and will be over the next seconds (people see where a machine
    // is going), as discs it must be passed by.
    let near: Vec<(DVec2, f64)> = robots
        .iter()
        .flat_map(|b| {
            let r = b.radius + reach + PASS_ROBOT;
            (0..=ANTICIPATE_S as usize).map(move |k| (b.position + b.velocity * k as f64, r))
        })
        .filter(|(p, r)| p.distance(at) < look + r)
        .collect();
    if near.is_empty() || straight == DVec2::ZERO {
        return straight;
    }
    // Already closer than that: no step toward the robot.
    let free = |dir: DVec2| {
        near.iter()
            .filter_map(|(p, r)| {
                let inside = p.distance(at) < *r;
                if inside {
                    ((*p - at).dot(dir) > 0.0).then_some(0.0)
                } else {
                    geometry::ray_circle(at, dir, *p, *r)
                }
            })
            .fold(look, f64::min)
    };
    turns()
        .iter()
        .map(|turn| straight.rotate(*turn))
        .map(|dir| {
            let f = free(dir);
            ((at + dir * f).distance(goal), dir)
        })
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map_or(straight, |(_, dir)| dir)
}

/// The headings a person weighs, as turns from the goal's: every 10° within 90°.
fn turns() -> &'static [DVec2; 19] {
    static TURNS: std::sync::OnceLock<[DVec2; 19]> = std::sync::OnceLock::new();
    TURNS.get_or_init(|| {
        std::array::from_fn(|i| DVec2::from_angle((i as f64 - 9.0) * 10f64.to_radians()))
    })
}

/// How many seconds ahead a person sees where a robot goes.
const ANTICIPATE_S: f64 = 2.0;
/// How far ahead a person looks for a robot in the way, m.
const LOOK_AHEAD: f64 = 6.0;
/// What a person keeps from a robot's footprint when going round it, m (the personal
/// space the robots keep from people).
const PASS_ROBOT: f64 = 0.8;

/// A crowd's person gives a goal up after twice the time it takes to walk there, and 5 s
/// more: someone stands on it, or the way is blocked.
fn give_up_after(from: DVec2, goal: DVec2, speed: f64) -> f64 {
    2.0 * from.distance(goal) / speed.max(0.1) + 5.0
}

/// A crowd's persons, at random points of its area where the site leaves room and no
/// robot starts within 2 m, each walking to a random point, at a speed drawn for it.
fn place_crowd(
    spec: &CrowdSpec,
    crowd: &mut Crowd,
    site: &Map,
    starts: &[DVec2],
    index: usize,
) -> Vec<Mover> {
    let radius = 0.3;
    let speeds = Normal::new(spec.speed_mean, spec.speed_sd.max(1e-9)).expect("σ ≥ 0");
    let mut placed: Vec<Mover> = Vec::new();
    for _ in 0..spec.persons() {
        // A few tries for a free spot; a packed area takes what it gets.
        let mut at = crowd.point();
        for _ in 0..20 {
            let free = site.clearance(at, radius + 0.2) >= radius + 0.2
                && starts.iter().all(|s| s.distance(at) > 2.0)
                && placed
                    .iter()
                    .all(|o| o.position.distance(at) > 2.0 * radius + 0.1);
            if free {
                break;
            }
            at = crowd.point();
        }
        let speed = speeds.sample(&mut crowd.rng).clamp(0.5, 2.0);
        let goal = crowd.goal(at, radius, spec.behavior, site);
        placed.push(Mover {
            kind: MoverKind::Pedestrian,
            shape: MoverShape::Circle { radius },
            behavior: spec.behavior,
            path: vec![at],
            repeat: Repeat::Once,
            speed,
            start_s: spec.start_s,
            pauses: Vec::new(),
            way: Way::Wander {
                goal,
                crowd: index,
                until: spec.start_s + give_up_after(at, goal, speed),
            },
            position: at,
            velocity: DVec2::ZERO,
            heading: (goal - at).to_angle(),
            paused_until: f64::NEG_INFINITY,
            done: false,
        });
    }
    placed
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_are_walked_once_in_a_loop_or_back_and_forth() {
        assert_eq!(advance(1, true, 3, Repeat::Once), Some((2, true)));
        assert_eq!(advance(2, true, 3, Repeat::Once), None);
        assert_eq!(advance(2, true, 3, Repeat::Loop), Some((0, true)));
        assert_eq!(advance(2, true, 3, Repeat::BackAndForth), Some((1, false)));
        assert_eq!(advance(0, false, 3, Repeat::BackAndForth), Some((1, true)));
    }

    #[test]
    fn footprints_are_measured_and_cast_against() {
        let car = MoverState {
            index: 0,
            kind: MoverKind::Vehicle,
            position: DVec2::new(10.0, 0.0),
            velocity: DVec2::ZERO,
            heading: std::f64::consts::FRAC_PI_2,
            shape: MoverShape::Rectangle {
                length: 4.0,
                width: 2.0,
            },
            oblivious: true,
        };
        // Along y it is 4 m long, across 2 m wide.
        assert!((car.distance(DVec2::new(10.0, 3.0)) - 1.0).abs() < 1e-9);
        assert!((car.distance(DVec2::new(12.0, 0.0)) - 1.0).abs() < 1e-9);
        assert!(car.distance(DVec2::new(10.0, 0.0)) < 0.0);
        let hit = car.ray(DVec2::ZERO, DVec2::X).unwrap();
        assert!((hit - 9.0).abs() < 1e-9, "{hit}");
        assert_eq!(car.ray(DVec2::ZERO, DVec2::Y), None);
    }

    #[test]
    fn oblivious_crowds_walk_round_the_pillars_not_through_them() {
        let src = include_str!("../../scenarios/plaza-crowd.toml")
            .replace("behavior = \"social\"", "behavior = \"oblivious\"");
        let scenario = Scenario::parse(&src, "plaza-crowd.toml").expect("the shipped plaza");
        let site = scenario.build_site();
        let mut movers = Movers::new(&scenario, &site, 7);
        assert!(movers.len() > 50);
        let (mut t, dt) = (0.0, 0.02);
        for _ in 0..(120.0 / dt) as usize {
            t += dt;
            movers.step(t, dt, &[], &site);
            for m in movers.states(t) {
                // A person's footprint is 0.3 m; their way is looked at every 0.25 m.
                let gap = site.clearance(m.position, 0.25);
                assert!(gap >= 0.25, "a person at {} at {t:.2} s", m.position);
            }
        }
    }
}
