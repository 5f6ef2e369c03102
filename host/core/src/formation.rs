//! The formation manager: slots for N followers, and the switch to a line before a
//! passage narrower than the formation, back to the wide shape after it.
//!
//! - **Slots** (L, φ from the leader's heading): a V (the paper's triangle for two
//!   followers: follower k at rank ⌈k/2⌉·L_d, alternately left and right at ±φ), a line
//!   (follower k at k·D behind: the paper's formula with the index fixed, `paper-notes.md`),
//!   or a custom list.
//! - **From the width of the way, nothing else**: at points every 0.25 m along the path
//!   the leader will drive (the planned route; straight ahead under the pure field) and
//!   along the path it drove, the clearance (distance to the nearest obstacle surface)
//!   says whether the formation, symmetric about the leader's path, fits: half of its
//!   lateral extent (footprints included) plus half of `margin` on every side. The same
//!   measure the route planner prefers its way by, so the two agree.
//! - **Into the line** when the way narrows within `lookahead` ahead.
//! - **Back to the wide shape** once the way is wide (hysteresis: 0.3 m more) along the path
//!   behind for the formation's length plus `EXIT_MARGIN` (every follower is out: dwell in
//!   space), at every follower, and ahead for `lookahead` + the formation's length +
//!   `REOPEN_AHEAD` (a short wide stretch between two pinches is not worth two changes),
//!   and the line has been held for `min_dwell_s` (dwell in time). So a narrow section
//!   costs one change into the line and one back, whatever the planner does meanwhile.
//! - While the slots move into the line, the leader slows to `TRANSFORM_SPEED` of its
//!   speed: the rear slot points move forward up to 1.9 m relative to the leader, and the
//!   followers' speed is bounded. Back to the wide shape it keeps its pace (the slots
//!   fall back: see `speed_factor`).
//! - **Smooth**: the blend (0 wide … 1 line) follows a smoothstep over `transition_s`, so
//!   the followers' slot points never jump; longer when a slot moves far, so that none
//!   moves faster than a follower can drive relative to the leader (`transition_duration`).
//! - **At the followers' pace**: the smoothstep's progress slows where a reference point
//!   (between the wide slot and the point its line distance back along the leader's path)
//!   would move faster than the robots' top speed in the world, the leader's motion and
//!   the path's bends included (`pace`), and stands still while a follower that has joined
//!   falls behind with its way to its reference clear (`lag_pace`); a follower held behind
//!   an obstacle is not waited for.

use control_core::follower::{self, LeaderSnapshot};
use control_core::Pose;
use glam::DVec2;

use crate::geometry::map::Map;
use crate::geometry::PlanPose;

/// The shape outside passages.
#[derive(Debug, Clone, PartialEq)]
pub enum WideShape {
    /// Followers alternately left and right, at ±angle, rank by rank (triangle for two).
    V { distance: f64, angle: f64 },
    /// Rows of `per_row` abreast behind the leader, centred on its path, `spacing` apart
    /// across and between rows (the last row holds what is left): a large fleet's rear
    /// stays close behind, where a V's spreads out.
    Rows { per_row: usize, spacing: f64 },
    /// Explicit (L, φ) per follower.
    Custom(Vec<(f64, f64)>),
}

#[derive(Debug, Clone, PartialEq)]
pub struct FormationSpec {
    pub wide: WideShape,
    pub followers: usize,
    /// Spacing D of the line, m.
    pub line_spacing: f64,
    /// Extra free width demanded beside the formation, m.
    pub margin: f64,
    /// The shortest shape change, s; longer when a slot moves far (see `transition_duration()`).
    pub transition_s: f64,
    pub min_dwell_s: f64,
    pub lookahead: f64,
    pub footprint: f64,
    /// The speed a follower can use to reach a moving slot, m/s.
    pub slot_speed: f64,
    /// The robots' top speed, m/s (a shape change's slot points stay under
    /// `PACE_SPEED_OF_TOP` of it in the world: `FormationManager::step`).
    pub top_speed: f64,
}

/// Which shape the formation is in or heading to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    Wide,
    Line,
}

impl Target {
    /// The shape's name at `blend` on the way to this target: `wide`, `to_line`, `line`
    /// or `to_wide` (the recordings' `/formation`, the trace's `shape`).
    pub fn shape_name(self, blend: f64) -> &'static str {
        match (self, blend) {
            (Target::Line, b) if b >= 1.0 => "line",
            (Target::Line, _) => "to_line",
            (Target::Wide, b) if b <= 0.0 => "wide",
            (Target::Wide, _) => "to_wide",
        }
    }

    /// The blend this shape rests at: 0 wide, 1 line.
    pub fn blend(self) -> f64 {
        match self {
            Target::Wide => 0.0,
            Target::Line => 1.0,
        }
    }
}

/// Why the shape changed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reason {
    /// The way ahead is narrower than the wide formation.
    PassageAhead,
    /// The narrow stretch is behind the whole formation and the way ahead is wide.
    PassageBehind,
    /// People (or vehicles) move about the formation's way: the narrow shape crosses them.
    MoversAhead,
    /// Nobody moves about the way any more (and it is wide).
    MoversGone,
}

impl Reason {
    pub fn name(self) -> &'static str {
        match self {
            Reason::PassageAhead => "passage_ahead",
            Reason::PassageBehind => "passage_behind",
            Reason::MoversAhead => "movers_ahead",
            Reason::MoversGone => "movers_gone",
        }
    }
}

/// What one step of the formation manager gives.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShapeStep {
    /// 0 wide … 1 line.
    pub blend: f64,
    /// The change of shape that began this step.
    pub change: Option<Transformation>,
}

/// A change of shape, for the record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transformation {
    pub to: Target,
    pub start_s: f64,
    /// When the slots reached the new shape (none yet: under way, or cut short by the
    /// next change).
    pub end_s: Option<f64>,
    pub reason: Reason,
}

impl FormationSpec {
    pub fn wide_slots(&self) -> Vec<(f64, f64)> {
        match &self.wide {
            WideShape::V { distance, angle } => (0..self.followers)
                .map(|k| {
                    let rank = (k / 2 + 1) as f64;
                    let side = if k % 2 == 0 { 1.0 } else { -1.0 };
                    (rank * distance, side * angle)
                })
                .collect(),
            WideShape::Rows { per_row, spacing } => {
                let per_row = (*per_row).max(1);
                (0..self.followers)
                    .map(|k| {
                        let row = k / per_row;
                        let abreast = per_row.min(self.followers - row * per_row);
                        let across = ((k % per_row) as f64 - 0.5 * (abreast - 1) as f64) * spacing;
                        let back = -((row + 1) as f64) * spacing;
                        (back.hypot(across), across.atan2(back))
                    })
                    .collect()
            }
            WideShape::Custom(slots) => slots.clone(),
        }
    }

    pub fn line_slots(&self) -> Vec<(f64, f64)> {
        (1..=self.followers)
            .map(|k| (k as f64 * self.line_spacing, std::f64::consts::PI))
            .collect()
    }

    /// How long a shape change takes: `transition_s`, or longer so that no slot point
    /// moves faster than `slot_speed` (a smoothstep peaks at 1.5× its mean rate): a
    /// 7-follower V's rear slots move 6 m into the line.
    pub fn transition_duration(&self) -> f64 {
        let point = |(l, phi): (f64, f64)| DVec2::new(l * phi.cos(), l * phi.sin());
        let far = self
            .wide_slots()
            .into_iter()
            .zip(self.line_slots())
            .map(|(w, l)| (point(w) - point(l)).length())
            .fold(0.0, f64::max);
        self.transition_s.max(1.5 * far / self.slot_speed.max(1e-3))
    }

    /// Lateral extent of the wide formation including footprints, m.
    pub fn wide_width(&self) -> f64 {
        let lateral = |slots: Vec<(f64, f64)>| {
            let ys = slots.iter().map(|(l, phi)| l * phi.sin());
            let hi = ys.clone().fold(0.0, f64::max);
            let lo = ys.fold(0.0, f64::min);
            hi - lo
        };
        lateral(self.wide_slots()) + 2.0 * self.footprint
    }
}

#[derive(Debug, Clone)]
pub struct FormationManager {
    spec: FormationSpec,
    /// The duration of a shape change, s.
    duration: f64,
    wide: Vec<(f64, f64)>,
    line: Vec<(f64, f64)>,
    target: Target,
    blend: f64,
    from_blend: f64,
    transition: Option<Transition>,
    line_since: Option<f64>,
    events: Vec<Transformation>,
    /// Movers crowd the way: the line, until they are gone.
    crowded: bool,
}

/// A shape change under way: how far along its smoothstep (0 … 1), and how fast it goes
/// on from the last step.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Transition {
    progress: f64,
    /// Progress per second from `at_s` on.
    rate: f64,
    /// The pace the followers allowed at the last step (`lag_pace`, slewed).
    waiting: f64,
    /// The last step, s.
    at_s: f64,
}

impl Transition {
    /// Its progress at `now_s`, going on at the last step's rate.
    fn progress_at(&self, now_s: f64) -> f64 {
        (self.progress + self.rate * (now_s - self.at_s)).min(1.0)
    }
}

/// The leader's speed factor while the slots move.
pub const TRANSFORM_SPEED: f64 = 0.4;
/// Slow time after the slots reached the new shape, s.
const SETTLE_S: f64 = 1.5;
/// How far past the narrow stretch every follower must be before the wide shape returns, m.
const EXIT_MARGIN: f64 = 1.0;
/// Extra free width asked before the wide shape returns, m.
const HYSTERESIS: f64 = 0.3;
/// Clearance beyond its footprint a follower needs at its wide slot, m.
const SLOT_MARGIN: f64 = 0.1;
/// Spacing of the points checked along a follower's way between its slots, m.
const WAY_STEP: f64 = 0.25;
/// How far ahead a shape change's pace looks, s (the station's period).
const PACE_HORIZON_S: f64 = 0.1;
/// The fastest a shape change moves a slot point in the world, as a fraction of the
/// robots' top speed.
const PACE_SPEED_OF_TOP: f64 = 1.0;
/// A shape change slows for a follower this far off its reference, m …
const LAG_FROM_M: f64 = 0.15;
/// … and stands still for one this much further off, m.
const LAG_SPAN_M: f64 = 0.15;
/// How fast the pace the followers allow may change, per second (from full pace to a
/// stop in 0.5 s: a slot slows as a follower can).
const PACE_SLEW_PER_S: f64 = 2.0;
/// Clearance beyond its footprint a follower's way to its reference needs for it to be
/// waited for, m: its ultrasonic ring slows it for echoes up to 0.2 m beside it.
const LAG_WAY_MARGIN: f64 = 0.25;
/// The paces a shape change may go at, fastest first (fractions of its nominal rate).
const PACES: [f64; 6] = [1.0, 0.8, 0.6, 0.4, 0.2, 0.0];

/// The leader's pose as the control core takes it.
fn core_pose(p: PlanPose) -> Pose {
    Pose::new(p.position.x as f32, p.position.y as f32, p.heading as f32)
}

fn point((x, y): (f32, f32)) -> DVec2 {
    DVec2::new(x as f64, y as f64)
}

/// Where slot (L, φ) is with the leader at `leader`: rigid to its pose, as the follower's
/// control core puts it.
fn slot_point(leader: PlanPose, (l, phi): (f64, f64)) -> DVec2 {
    point(follower::slot_point(
        &core_pose(leader),
        l as f32,
        phi as f32,
    ))
}

/// The point `s` back along the path the leader drove (`newest_first`) from the leader at
/// `leader` heading `heading`, as the follower's control core has it
/// ([`follower::behind_along`]: before the path began, on along the chord from the
/// leader to the path's start, or back along the heading while less than half a metre is
/// recorded).
pub fn back_along(
    leader: DVec2,
    heading: f64,
    newest_first: impl IntoIterator<Item = DVec2>,
    s: f64,
) -> DVec2 {
    let at = Pose::new(leader.x as f32, leader.y as f32, heading as f32);
    let path = newest_first.into_iter().map(|p| (p.x as f32, p.y as f32));
    point(follower::behind_along(&at, path, s as f32))
}

/// The two ends a follower's reference point moves between, as its control core makes
/// them: its wide slot point with the leader at `leader`, and the point its line distance
/// back along the path the leader drove (`behind`: newest first, from `behind[0]`, where
/// the leader was before it drove on by `advance`). At blend b the reference is
/// `wide.lerp(line, b)`.
fn reference_ends(
    leader: PlanPose,
    wide: (f64, f64),
    line: (f64, f64),
    behind: &[DVec2],
    advance: f64,
) -> (DVec2, DVec2) {
    let from = behind.first().copied().unwrap_or(leader.position);
    let l = back_along(
        from,
        leader.heading,
        behind.iter().copied(),
        (line.0 - advance).max(0.0),
    );
    (slot_point(leader, wide), l)
}

/// Points from `from` to `to` at most `WAY_STEP` apart, both ends included: where a
/// follower crossing between them would be.
fn way_points(from: DVec2, to: DVec2) -> impl Iterator<Item = DVec2> {
    let steps = ((to - from).length() / WAY_STEP).ceil().max(1.0) as usize;
    (0..=steps).map(move |i| from.lerp(to, i as f64 / steps as f64))
}

/// The point `s` along `path` from its first point, if the path is that long.
fn along(path: &[DVec2], s: f64) -> Option<DVec2> {
    let mut left = s;
    for w in path.windows(2) {
        let len = (w[1] - w[0]).length();
        if len >= left && len > 1e-9 {
            return Some(w[0].lerp(w[1], left / len));
        }
        left -= len;
    }
    None
}

/// What the station last heard from a follower: where it is, how far off its reference
/// it said it was (m), and whether it has joined the formation yet.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FollowerStatus {
    pub position: DVec2,
    pub error: f64,
    pub joined: bool,
    /// Being sent round an obstacle by the station (`Detour`): on its way, though not
    /// the straight one.
    pub detouring: bool,
}

/// The leader's pose and how it drives: forward speed `v` (m/s), turn rate `omega` (rad/s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeaderMotion {
    pub pose: PlanPose,
    pub v: f64,
    pub omega: f64,
}

impl LeaderMotion {
    /// Where the leader is `t` seconds on, driving the same arc: the followers' own
    /// prediction ([`LeaderSnapshot::predict`]).
    pub fn after(&self, t: f64) -> PlanPose {
        let snapshot = LeaderSnapshot {
            pose: core_pose(self.pose),
            v: self.v as f32,
            omega: self.omega as f32,
        };
        let p = snapshot.predict(t as f32).pose;
        PlanPose {
            position: point((p.x, p.y)),
            heading: p.heading as f64,
        }
    }
}

/// How far ahead in time the wide slots are checked along the leader's arc, s: a follower
/// slows behind a bin its slot is about to cross (its ultrasonic ring looks ahead), so
/// the check at the leader's pose alone came when the follower was already held.
const SLOT_HORIZON_S: f64 = 2.0;
/// The wide shape returns only with this much wide way ahead beyond the lookahead and
/// the formation's length, m.
const REOPEN_AHEAD: f64 = 2.0;

/// The blend `elapsed_s` into a change of shape lasting `duration_s`, from blend `from`
/// to the shape `to`.
pub fn transition_blend(from: f64, to: Target, elapsed_s: f64, duration_s: f64) -> f64 {
    from + (to.blend() - from) * smoothstep(elapsed_s / duration_s)
}

/// How a transition moves the blend: from 0 to 1 as x does, flat at both ends.
pub fn smoothstep(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

impl FormationManager {
    pub fn new(spec: FormationSpec) -> Self {
        Self {
            duration: spec.transition_duration(),
            wide: spec.wide_slots(),
            line: spec.line_slots(),
            spec,
            target: Target::Wide,
            blend: 0.0,
            from_blend: 0.0,
            transition: None,
            line_since: None,
            crowded: false,
            events: Vec::new(),
        }
    }

    pub fn spec(&self) -> &FormationSpec {
        &self.spec
    }
    pub fn wide_slots(&self) -> &[(f64, f64)] {
        &self.wide
    }
    pub fn line_slots(&self) -> &[(f64, f64)] {
        &self.line
    }
    /// 0 = wide, 1 = line.
    pub fn blend(&self) -> f64 {
        self.blend
    }
    pub fn target(&self) -> Target {
        self.target
    }
    pub fn transformations(&self) -> &[Transformation] {
        &self.events
    }

    /// Follower k's reference point at the current blend, as its control core makes it,
    /// with the leader at `leader` (`behind`: the leader's driven path from it, newest
    /// first).
    pub fn reference(&self, k: usize, leader: PlanPose, behind: &[DVec2]) -> DVec2 {
        self.reference_at(k, leader, behind, self.blend)
    }

    /// [`FormationManager::reference`] at `blend`.
    pub fn reference_at(&self, k: usize, leader: PlanPose, behind: &[DVec2], blend: f64) -> DVec2 {
        let (w, l) = reference_ends(leader, self.wide[k], self.line[k], behind, 0.0);
        w.lerp(l, blend)
    }

    /// Follower k's slot (L, φ) at the current blend, on the straight segment between its
    /// two slot points in the leader's frame (what the followers compute too).
    pub fn slot(&self, k: usize) -> (f64, f64) {
        let point = |(l, phi): (f64, f64)| DVec2::new(l * phi.cos(), l * phi.sin());
        let p = point(self.wide[k]).lerp(point(self.line[k]), self.blend);
        (p.length(), p.y.atan2(p.x))
    }

    /// The formation's lateral half-width at the current blend (slot centres, without
    /// footprints), m.
    pub fn half_width(&self) -> f64 {
        (0..self.spec.followers)
            .map(|k| {
                let (l, phi) = self.slot(k);
                (l * phi.sin()).abs()
            })
            .fold(0.0, f64::max)
    }

    /// The distance of the farthest wide slot from the leader, m.
    pub fn wide_reach(&self) -> f64 {
        self.wide.iter().map(|s| s.0).fold(0.0, f64::max)
    }

    /// The distance of the last line slot from the leader, m.
    pub fn line_reach(&self) -> f64 {
        self.line.iter().map(|s| s.0).fold(0.0, f64::max)
    }

    /// The slot points in the world for a leader pose.
    pub fn slot_points(&self, leader: PlanPose) -> Vec<DVec2> {
        (0..self.spec.followers)
            .map(|k| slot_point(leader, self.slot(k)))
            .collect()
    }

    /// Whether the formation, centred on a path through `p`, lacks `need` of free width:
    /// an obstacle closer than `need / 2`. A point inside or touching an obstacle is not a
    /// passage (that obstacle is in the way: the planner's business).
    fn is_narrow(&self, map: &Map, p: DVec2, need: f64) -> bool {
        let c = map.clearance(p, 0.5 * need);
        c >= self.spec.footprint && c < 0.5 * need
    }

    /// Whether any point of `path` (its first point first), within `length` along it, is
    /// narrow for `need`.
    fn narrow_along(&self, map: &Map, path: &[DVec2], length: f64, need: f64) -> bool {
        let mut travelled = 0.0;
        for w in path.windows(2) {
            let d = w[1] - w[0];
            let len = d.length();
            if len < 1e-9 {
                continue;
            }
            if self.is_narrow(map, w[0], need) {
                return true;
            }
            travelled += len;
            if travelled > length {
                break;
            }
        }
        false
    }

    /// The leader's speed factor: slower while the slots move into the line and for
    /// `SETTLE_S` after, while the followers close the last gap to their new slots. Into
    /// the line the rear slots move forward relative to the leader, so their followers
    /// must outrun it. Back to the wide shape the slots fall back and out to the sides: a
    /// slowed leader would make a slot retreat in the world, which a differential-drive
    /// follower can only follow by turning round (`paper-passage` seed 5: 1.5 rad/s at
    /// 0.02 m/s, a 5.9 s change; at full speed 3.5 s), so the leader keeps its pace.
    pub fn speed_factor(&self, now_s: f64) -> f64 {
        let settling = self.events.last().is_some_and(|e| {
            e.to == Target::Line && e.end_s.is_none_or(|end| now_s < end + SETTLE_S)
        });
        if settling {
            TRANSFORM_SPEED
        } else {
            1.0
        }
    }

    /// Whether, with the leader at `leader`, a wide slot point lies within `need` of an
    /// obstacle: the follower there would touch it. The width of the way along the path
    /// does not tell this: in a turn a V swings its rear slots out beyond it, over what
    /// stands beside the leader's way (a 5-follower V's follower 9 m back pressed on a bin
    /// its slot had swept into, up to 12 m off, and the leader, pacing on it, crawled).
    /// Checked along the leader's arc as it drives now, `SLOT_HORIZON_S` ahead (a short
    /// stretch, which the leader does drive), not along the route ahead: the route's
    /// corners swing a rigid V further than the leader's rounded turns do (checked along
    /// the route, the 2-follower dense bin fields changed shape where no slot ever met a
    /// bin). At the leader's pose alone the check came when a rear follower was already
    /// held behind the bin its slot was crossing.
    pub fn wide_slot_blocked(&self, map: &Map, leader: LeaderMotion, need: f64) -> bool {
        const STEPS: usize = 4;
        (0..=STEPS).any(|k| {
            let pose = leader.after(SLOT_HORIZON_S * k as f64 / STEPS as f64);
            self.wide.iter().any(|slot| {
                let p = slot_point(pose, *slot);
                map.clearance(p, need) < need
            })
        })
    }

    /// Whether each follower's way from its line slot (on the path behind) to its wide slot
    /// (at the leader's pose) is clear by `need`. Back to the wide shape the followers
    /// cross that way sideways, 4.5 m for a 5-follower V's last: one met a bin on it and
    /// was held behind it (1.3 m off) while its slot went on.
    pub fn widening_clear(&self, map: &Map, leader: PlanPose, behind: &[DVec2], need: f64) -> bool {
        self.wide.iter().zip(&self.line).all(|(wide, (ll, _))| {
            let wide = slot_point(leader, *wide);
            let Some(line) = along(behind, *ll) else {
                return true;
            };
            way_points(line, wide).all(|p| map.clearance(p, need) >= need)
        })
    }

    /// The clearance a follower needs at its wide slot not to touch: its footprint and a
    /// tenth of a metre.
    pub fn slot_need(&self) -> f64 {
        self.spec.footprint + SLOT_MARGIN
    }

    /// One step. `leader`: its pose; `ahead`: the path the leader will drive, from the
    /// leader on; `behind`: the path it drove, newest first (both sampled finely,
    /// ≤ 0.25 m); `followers`: their positions where known. The blend now, and the shape
    /// change this step began, if any.
    pub fn step(
        &mut self,
        now_s: f64,
        leader: LeaderMotion,
        ahead: &[DVec2],
        behind: &[DVec2],
        followers: &[Option<FollowerStatus>],
        map: &Map,
    ) -> ShapeStep {
        let changes = self.events.len();
        self.decide(now_s, leader, ahead, behind, followers, map);
        self.advance(now_s, leader, behind, followers, map);
        ShapeStep {
            blend: self.blend,
            change: self.events[changes..].last().copied(),
        }
    }

    /// Whether to change shape now: into the line before a narrow way, back out of it
    /// once the way is wide again everywhere the formation is or goes.
    fn decide(
        &mut self,
        now_s: f64,
        leader: LeaderMotion,
        ahead: &[DVec2],
        behind: &[DVec2],
        followers: &[Option<FollowerStatus>],
        map: &Map,
    ) {
        let need_in = self.spec.wide_width() + self.spec.margin;
        let need_out = need_in + HYSTERESIS;
        let length = self.wide_reach().max(self.line_reach());
        match self.target {
            Target::Wide => {
                if self.narrow_along(map, ahead, self.spec.lookahead, need_in)
                    || self.wide_slot_blocked(map, leader, self.slot_need())
                {
                    self.switch(Target::Line, now_s, Reason::PassageAhead);
                } else if self.crowded {
                    self.switch(Target::Line, now_s, Reason::MoversAhead);
                }
            }
            Target::Line => {
                if self.blend >= 1.0 && self.line_since.is_none() {
                    self.line_since = Some(now_s);
                }
                let dwelt = self
                    .line_since
                    .is_some_and(|t| now_s - t >= self.spec.min_dwell_s);
                let open = dwelt
                    && !self.crowded
                    && !self.narrow_along(
                        map,
                        ahead,
                        self.spec.lookahead + length + REOPEN_AHEAD,
                        need_out,
                    )
                    && !self.narrow_along(map, behind, length + EXIT_MARGIN, need_out)
                    && !self.wide_slot_blocked(map, leader, self.slot_need() + HYSTERESIS)
                    && self.widening_clear(map, leader.pose, behind, self.slot_need())
                    && !followers
                        .iter()
                        .flatten()
                        .any(|f| self.is_narrow(map, f.position, need_out));
                if open {
                    let movers = self
                        .events
                        .last()
                        .is_some_and(|e| e.reason == Reason::MoversAhead);
                    let why = if movers {
                        Reason::MoversGone
                    } else {
                        Reason::PassageBehind
                    };
                    self.switch(Target::Wide, now_s, why);
                }
            }
        }
    }

    /// The change under way moves on, at the pace the followers and the world allow.
    fn advance(
        &mut self,
        now_s: f64,
        leader: LeaderMotion,
        behind: &[DVec2],
        followers: &[Option<FollowerStatus>],
        map: &Map,
    ) {
        if let Some(t) = self.transition {
            let progress = t.progress_at(now_s);
            self.blend = self.blend_of(progress);
            if progress >= 1.0 {
                self.transition = None;
                if let Some(e) = self.events.last_mut() {
                    e.end_s = Some(now_s);
                }
            } else {
                // The followers' pace changes gently: a slot that stopped at once left a
                // follower driving at it at 0.57 m/s 0.39 m beyond it.
                let slew = PACE_SLEW_PER_S * (now_s - t.at_s);
                let lag = self.lag_pace(leader.pose, behind, followers, map);
                let waiting = lag.clamp(t.waiting - slew, t.waiting + slew);
                let pace = self.pace(progress, leader, behind).min(waiting);
                self.transition = Some(Transition {
                    progress,
                    rate: pace / self.duration,
                    waiting,
                    at_s: now_s,
                });
            }
        }
    }

    /// The blend at `progress` along the change under way.
    fn blend_of(&self, progress: f64) -> f64 {
        transition_blend(self.from_blend, self.target, progress, 1.0)
    }

    /// The pace of the change under way from `progress` on, as a fraction of its nominal
    /// rate: the fastest at which no follower's reference point moves faster than
    /// `PACE_SPEED_OF_TOP` of the top speed in the world (or, if the leader's own motion
    /// already carries one faster, the pace that carries it least fast). The duration
    /// bounds the slots' speed relative to the leader; this adds the leader's motion and
    /// the trail's bends. A 5-follower V's last slot, between the wide point and the point
    /// 7.5 m back along a bent trail, moved at 1.1–1.4 m/s, and its follower fell 0.5–1.7 m
    /// behind.
    fn pace(&self, progress: f64, leader: LeaderMotion, behind: &[DVec2]) -> f64 {
        let h = PACE_HORIZON_S;
        let next_pose = leader.after(h);
        let advance = leader.v * h;
        let b0 = self.blend_of(progress);
        // Per follower: its reference now, and the ends it moves between 0.1 s on.
        let moves: Vec<(DVec2, (DVec2, DVec2))> = self
            .wide
            .iter()
            .zip(&self.line)
            .map(|(wide, line)| {
                let (w, l) = reference_ends(leader.pose, *wide, *line, behind, 0.0);
                let next = reference_ends(next_pose, *wide, *line, behind, advance);
                (w.lerp(l, b0), next)
            })
            .collect();
        let speed_at = |pace: f64| {
            let b1 = self.blend_of(progress + pace * h / self.duration);
            moves
                .iter()
                .map(|(now, (w, l))| (w.lerp(*l, b1) - *now).length() / h)
                .fold(0.0, f64::max)
        };
        let mut best = (f64::INFINITY, 0.0);
        for pace in PACES {
            let speed = speed_at(pace);
            if speed <= PACE_SPEED_OF_TOP * self.spec.top_speed {
                return pace;
            }
            if speed < best.0 {
                best = (speed, pace);
            }
        }
        best.1
    }

    /// The pace the followers allow: slower as the one furthest off its reference falls
    /// behind (`LAG_FROM_M` on; still at `LAG_FROM_M + LAG_SPAN_M`), among those that have
    /// joined and whose straight way to it is clear. One still joining is not waited for
    /// (a 7-follower line starting as the V was asked for was held toward the V's slots,
    /// 0.12 m from a street's wall). One held behind a bin its reference has passed is not
    /// waited for: only the change can take its reference off the bin's far side (waited
    /// for, a 5-follower V's last stood behind a bin while the leader crept on to the goal).
    /// One the station is sending round it is waited for: it is on its way.
    fn lag_pace(
        &self,
        leader: PlanPose,
        behind: &[DVec2],
        followers: &[Option<FollowerStatus>],
        map: &Map,
    ) -> f64 {
        let need = self.spec.footprint + LAG_WAY_MARGIN;
        let worst = followers
            .iter()
            .take(self.wide.len())
            .enumerate()
            .filter_map(|(k, f)| {
                let f = (*f).filter(|f| f.joined && f.error > LAG_FROM_M)?;
                let to = self.reference(k, leader, behind);
                // From the first step beyond where it stands: it may stand close to a bin.
                let clear = f.detouring
                    || way_points(f.position, to)
                        .skip(1)
                        .all(|p| map.clearance(p, need) >= need);
                clear.then_some(f.error)
            })
            .fold(0.0, f64::max);
        (1.0 - (worst - LAG_FROM_M) / LAG_SPAN_M).clamp(0.0, 1.0)
    }

    /// The blend at `now_s` (station clock) as the transition under way makes it: what the
    /// followers extrapolate to between leader states ([`FormationManager::blend`] is its
    /// value at the last step).
    pub fn blend_at(&self, now_s: f64) -> f64 {
        let Some(t) = self.transition else {
            return self.blend;
        };
        self.blend_of(t.progress_at(now_s))
    }

    /// Whether movers crowd the formation's way (the station's tracks say): the wide
    /// shape gives way to the line while they do.
    pub fn set_crowded(&mut self, crowded: bool) {
        self.crowded = crowded;
    }

    fn switch(&mut self, to: Target, now_s: f64, reason: Reason) {
        self.target = to;
        self.from_blend = self.blend;
        self.transition = Some(Transition {
            progress: 0.0,
            rate: 1.0 / self.duration,
            waiting: 1.0,
            at_s: now_s,
        });
        self.line_since = None;
        self.events.push(Transformation {
            to,
            start_s: now_s,
            end_s: None,
            reason,
        });
    }
}
