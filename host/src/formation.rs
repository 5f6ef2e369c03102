//! The formation manager: slots for N followers, and the switch to a line before a
//! passage narrower than the formation, back to the wide shape after it.
//!
//! - **Slots** (L, φ from the leader's heading): a V (the paper's triangle for two
//!   followers: follower k at rank ⌈k/2⌉·L_d, alternately left and right at ±φ), a line
//!   (follower k at k·D behind: the paper's formula with the index fixed, `paper-notes.md`),
//!   or a custom list.
//! - **Passage ahead**: at points every 0.25 m along the leader's heading up to `lookahead`,
//!   rays to the left and right measure the free width. Narrower than the wide formation
//!   (its lateral extent plus footprints) plus `margin` → transform to the line.
//! - **Back to wide** when nothing narrow lies ahead of the leader *and* every follower's
//!   own position is in the open (hysteresis: `margin + 0.5 m`), and the line has been held
//!   for `min_dwell_s`. So the shape does not flap at the boundary.
//! - **Smooth**: the blend (0 wide … 1 line) follows a smoothstep over `transition_s`, so
//!   the followers' slot points never jump.

use glam::DVec2;

use crate::map::Map;
use crate::planner::PlanPose;

/// The shape outside passages.
#[derive(Debug, Clone, PartialEq)]
pub enum WideShape {
    /// Followers alternately left and right, at ±angle, rank by rank (triangle for two).
    V { distance: f64, angle: f64 },
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
    pub transition_s: f64,
    pub min_dwell_s: f64,
    pub lookahead: f64,
    pub footprint: f64,
}

/// Which shape the formation is in or heading to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    Wide,
    Line,
}

/// A change of shape, for the record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transformation {
    pub to: Target,
    pub start_s: f64,
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
            WideShape::Custom(slots) => slots.clone(),
        }
    }

    pub fn line_slots(&self) -> Vec<(f64, f64)> {
        (1..=self.followers)
            .map(|k| (k as f64 * self.line_spacing, std::f64::consts::PI))
            .collect()
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
    wide: Vec<(f64, f64)>,
    line: Vec<(f64, f64)>,
    target: Target,
    blend: f64,
    from_blend: f64,
    transition_start: Option<f64>,
    line_since: Option<f64>,
    events: Vec<Transformation>,
}

fn smoothstep(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

impl FormationManager {
    pub fn new(spec: FormationSpec) -> Self {
        Self {
            wide: spec.wide_slots(),
            line: spec.line_slots(),
            spec,
            target: Target::Wide,
            blend: 0.0,
            from_blend: 0.0,
            transition_start: None,
            line_since: None,
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

    /// Follower k's slot (L, φ) at the current blend, on the straight segment between its
    /// two slot points in the leader's frame (what the followers compute too).
    pub fn slot(&self, k: usize) -> (f64, f64) {
        let point = |(l, phi): (f64, f64)| DVec2::new(l * phi.cos(), l * phi.sin());
        let p = point(self.wide[k]).lerp(point(self.line[k]), self.blend);
        (p.length(), p.y.atan2(p.x))
    }

    /// The slot points in the world for a leader pose.
    pub fn slot_points(&self, leader: PlanPose) -> Vec<DVec2> {
        (0..self.spec.followers)
            .map(|k| {
                let (l, phi) = self.slot(k);
                let a = leader.heading + phi;
                leader.position + DVec2::new(a.cos(), a.sin()) * l
            })
            .collect()
    }

    /// Free width across `dir` at `p`, looking at most `reach` to each side.
    fn width(&self, map: &Map, p: DVec2, dir: DVec2, reach: f64) -> f64 {
        let n = dir.perp();
        map.ray_cast(p, n, reach) + map.ray_cast(p, -n, reach)
    }

    fn narrow_ahead(&self, map: &Map, leader: PlanPose, need: f64) -> bool {
        let dir = DVec2::new(leader.heading.cos(), leader.heading.sin());
        let steps = (self.spec.lookahead / 0.25).ceil() as usize;
        (0..=steps).any(|i| {
            let p = leader.position + dir * (i as f64 * 0.25);
            self.width(map, p, dir, need) < need
        })
    }

    /// One step. `followers`: their positions where known. `force_line`: the planner
    /// wants the narrow shape (following a boundary out of a trap).
    pub fn step(
        &mut self,
        now_s: f64,
        leader: PlanPose,
        followers: &[DVec2],
        map: &Map,
        force_line: bool,
    ) -> f64 {
        let wide = self.spec.wide_width();
        let need_in = wide + self.spec.margin;
        let need_out = need_in + 0.5;
        match self.target {
            Target::Wide => {
                if force_line || self.narrow_ahead(map, leader, need_in) {
                    self.switch(Target::Line, now_s);
                }
            }
            Target::Line => {
                if self.blend >= 1.0 && self.line_since.is_none() {
                    self.line_since = Some(now_s);
                }
                let dwelt = self
                    .line_since
                    .is_some_and(|t| now_s - t >= self.spec.min_dwell_s);
                let dir = DVec2::new(leader.heading.cos(), leader.heading.sin());
                let open = !force_line
                    && !self.narrow_ahead(map, leader, need_out)
                    && followers
                        .iter()
                        .all(|f| self.width(map, *f, dir, need_out) >= need_out);
                if dwelt && open {
                    self.switch(Target::Wide, now_s);
                }
            }
        }
        if let Some(t0) = self.transition_start {
            let end = match self.target {
                Target::Wide => 0.0,
                Target::Line => 1.0,
            };
            let s = smoothstep((now_s - t0) / self.spec.transition_s);
            self.blend = self.from_blend + (end - self.from_blend) * s;
            if s >= 1.0 {
                self.transition_start = None;
            }
        }
        self.blend
    }

    fn switch(&mut self, to: Target, now_s: f64) {
        self.target = to;
        self.from_blend = self.blend;
        self.transition_start = Some(now_s);
        self.line_since = None;
        self.events.push(Transformation { to, start_s: now_s });
    }
}
