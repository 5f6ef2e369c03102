//! What moves in the leader's scans: hits the map does not explain become clusters,
//! clusters become **tracks** with a velocity and its uncertainty, and a track is judged
//! moving or still. Perception marks what stands still (a bin, a van, a person who stopped
//! in the way) and leaves out what moves; the leader and the formation yield to what moves.
//!
//! - **Clusters**: hits closer than [`LINK_M`] to each other (single linkage); a cluster
//!   wider than a person where two or more people are predicted is split between them
//!   ([`SPLIT_ABOVE_M`]).
//! - **Association**: each track predicted to the scan's time takes the nearest cluster
//!   within its gate ([`GATE_M`] plus three sigmas of its position), nearest pairs first;
//!   a cluster nobody takes starts a track; a track not seen for [`LOST_MS`] ends.
//! - **Taken up again**: a person lost from view (behind someone else in a crowd) is kept
//!   for [`REVIVE_MS`] more; a cluster nobody takes that lies along their way (between
//!   where they were last seen and where they would be now, within [`REVIVE_GATE_M`]) is
//!   them again: the same track, still moving, not a stranger seen for the first time.
//! - **Centre**: a cluster no wider than a person is a person's near side: its centre is
//!   fitted as the circle of [`PERSON_RADIUS_M`] its hits lie on, and is noisier the less
//!   of them is seen ([`SLIVER_SIGMA_M`]); anything larger's is its centroid. The
//!   centroid of a person half hidden behind another slid over their width from scan to
//!   scan, and the velocity with it: on social plazas at 0.2 persons/m² a track's
//!   prediction a second on was no nearer the person than where the track stood
//!   (`tests/tests/tracking.rs`).
//! - **Velocity**: a constant-velocity Kalman filter per axis on the centre (white
//!   acceleration noise [`ACCEL_SIGMA`], the centre's noise as above).
//! - **Moving or still**: judged on the hits, not the centroid (a long wall's visible part
//!   slides along with the scanner; its centroid moves, its hits stay on the wall). A
//!   cluster is *novel* where most of its hits lie farther than [`NOVEL_M`] from every hit
//!   the track had [`BASELINE_MS`] ago or more: something that moves leaves the place it
//!   was, something that stands is hit where it was hit before. Twice novel with the
//!   filter's speed over [`MOVING_MPS`]: moving. Not novel for [`STILL_MS`]: still.
//! - **Marks**: a still track's hits are marked (a track that once moved and is no larger
//!   than a person is marked with the personal space round it); a moving track's are not,
//!   and the marks it left while it stood are released. A new small track is marked only
//!   once it is judged still (a person first seen walking leaves no mark); a new large
//!   one at once, as before tracking (a wall, a van across the street).
//! - **Ways**: a track keeps the way it last walked ([`TrackView::way`]); what that means
//!   once someone stops (the way they will walk on) is the station's to decide.

use std::collections::VecDeque;

use glam::DVec2;
use serde::Serialize;

use crate::geometry::cells::{cell_of, CellIndex};

/// Hits this close belong to one cluster, m.
pub const LINK_M: f64 = 0.45;
/// A track takes a cluster this far from where it was predicted, plus 3σ, m; never
/// farther than [`MAX_GATE_M`]. In a crowd people walk a metre apart: a gate of 0.8 m
/// lets tracks take their neighbours' clusters.
pub const GATE_M: f64 = 0.3;
pub const MAX_GATE_M: f64 = 1.2;
/// A track not seen for this long ends, ms.
pub const LOST_MS: u32 = 1000;
/// A person's track ended this long ago may still be taken up again, ms.
pub const REVIVE_MS: u32 = 3000;
/// By a cluster of a person's size this near their way since they were lost, m.
pub const REVIVE_GATE_M: f64 = 1.0;
/// A person's radius at the scanner's height, as the tracker takes it, m.
pub const PERSON_RADIUS_M: f64 = 0.25;
/// A cluster up to a person's breadth and this is fitted as one, m.
const FIT_SLACK_M: f64 = 0.15;
const FIT_STEPS: usize = 6;
const FIT_DAMPING: f64 = 1e-3;
/// A fitted centre's noise grows by up to this as less of the person is seen, m.
const SLIVER_SIGMA_M: f64 = 0.2;
/// The velocity's sigma of a track taken up again, m/s.
const RESUMED_SIGMA_MPS: f64 = 0.5;
/// White acceleration noise of the motion model, m/s².
pub const ACCEL_SIGMA: f64 = 1.5;
/// Noise of a centroid, m, plus a quarter of the cluster's extent.
pub const CENTROID_SIGMA_M: f64 = 0.08;
/// A hit farther than this from every earlier hit of its track is novel, m.
pub const NOVEL_M: f64 = 0.25;
/// A cluster is novel where at least this share of its hits is.
pub const NOVEL_SHARE: f64 = 0.6;
/// And not novel where at most this share is.
pub const SETTLED_SHARE: f64 = 0.25;
/// Hits are compared with the track's hits at least this long ago, ms.
pub const BASELINE_MS: u32 = 400;
/// And at most this long ago, ms.
pub const HISTORY_MS: u32 = 1200;
/// A novel cluster moves where the filter's speed is over this, m/s.
pub const MOVING_MPS: f64 = 0.3;
/// A large track not novel this long stands still, ms.
pub const STILL_MS: u32 = 500;
/// A small one must stand this long (a bin is still a bin two seconds later), ms.
pub const STOPPED_MS: u32 = 2000;
/// One that moved before, this long: a person who stopped in the way, not one held up
/// in a crowd for a few seconds (marked at 2 s, the people a crowd holds up wall a plaza
/// off for the line of robots). Until then the track stays a mover standing, which the
/// leader yields to, ms.
pub const PAUSED_MS: u32 = 6000;
/// A cluster this long or longer is marked at once, before it is judged (a wall, a van
/// across the street; people side by side in a crowd are shorter), m.
pub const LARGE_M: f64 = 2.0;
/// A track that moved and is no longer than this is a person (or a cyclist end on) and
/// gets the personal space round its marks, m.
pub const PERSON_M: f64 = 1.0;
/// Most tracks kept (the oldest unseen go first).
pub const MAX_TRACKS: usize = 512;
/// People walking side by side, or passing each other, give one cluster (their hits
/// closer than [`LINK_M`]). A cluster wider than one person (this, m) where two or more
/// tracks no larger than a person ([`PERSON_M`]) are predicted (within [`SPLIT_NEAR_M`]
/// of its hits, m), one of which moved, is split between them, each hit to the nearest;
/// hits farther than [`SPLIT_REACH_M`] from all of them are something else, m. Unsplit,
/// one track took the pair and its centroid jumped between them, and the other ended
/// and came back as a stranger the leader stopped for: on the social plazas of seeds
/// 301-332, 11 of 32 crossings at 0.2 persons/m² reached the goal; split, 25.
pub const SPLIT_ABOVE_M: f64 = 0.75;
pub const SPLIT_NEAR_M: f64 = 0.4;
pub const SPLIT_REACH_M: f64 = 0.6;

/// What a track is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Motion {
    /// Not judged yet.
    New,
    Still,
    Moving,
}

/// One axis of a constant-velocity Kalman filter: position, velocity, covariance.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Axis {
    p: f64,
    v: f64,
    /// Covariance [pp, pv, vv].
    c: [f64; 3],
}

impl Axis {
    fn new(p: f64, sigma: f64) -> Self {
        Self {
            p,
            v: 0.0,
            c: [sigma * sigma, 0.0, 1.0],
        }
    }

    fn predict(&mut self, dt: f64) {
        let q = ACCEL_SIGMA * ACCEL_SIGMA;
        let [pp, pv, vv] = self.c;
        self.p += self.v * dt;
        self.c = [
            pp + 2.0 * dt * pv + dt * dt * vv + q * dt.powi(4) / 4.0,
            pv + dt * vv + q * dt.powi(3) / 2.0,
            vv + q * dt * dt,
        ];
    }

    fn update(&mut self, z: f64, sigma: f64) {
        let [pp, pv, vv] = self.c;
        let s = pp + sigma * sigma;
        let (kp, kv) = (pp / s, pv / s);
        let y = z - self.p;
        self.p += kp * y;
        self.v += kv * y;
        self.c = [(1.0 - kp) * pp, (1.0 - kp) * pv, vv - kv * pv];
    }
}

/// Something the scans show, followed from scan to scan.
#[derive(Debug, Clone)]
pub struct Track {
    pub id: u32,
    x: Axis,
    y: Axis,
    /// The longest distance between two of its latest hits, m.
    pub extent: f64,
    pub motion: Motion,
    /// It was judged moving once (a person, a cyclist, a vehicle).
    pub moved: bool,
    /// The way it last walked, judged moving (a unit vector).
    way: Option<DVec2>,
    /// When it was first and last seen, station ms.
    pub born_ms: u32,
    pub seen_ms: u32,
    /// Its filter's time, station ms.
    at_ms: u32,
    /// Novel clusters in a row.
    novel_run: u32,
    /// Since when its clusters have not been novel, station ms.
    settled_since: Option<u32>,
    /// Its hits of the last [`HISTORY_MS`], oldest first.
    history: VecDeque<(u32, Vec<DVec2>)>,
}

/// A track as the rest of the station sees it: predicted to a time.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TrackView {
    pub id: u32,
    pub position: DVec2,
    pub velocity: DVec2,
    /// One sigma of the position and of the velocity (the larger axis), m, m/s.
    pub position_sigma: f64,
    pub velocity_sigma: f64,
    /// Half its extent: the disc its hits lie in, seen from the scanner's side, m.
    pub radius: f64,
    pub motion: Motion,
    /// Moved once and no larger than a person.
    pub person: bool,
    /// The way it last walked, judged moving (a unit vector).
    pub way: Option<DVec2>,
}

impl TrackView {
    /// Where it will be `dt` seconds on, as the filter predicts.
    pub fn at(&self, dt: f64) -> DVec2 {
        self.position + self.velocity * dt
    }
}

#[cfg(test)]
impl TrackView {
    /// A person tracked well, at `at` walking at `v`: the station's tests' mover.
    pub(crate) fn person_at(id: u32, at: (f64, f64), v: (f64, f64)) -> Self {
        Self {
            id,
            position: DVec2::new(at.0, at.1),
            velocity: DVec2::new(v.0, v.1),
            position_sigma: 0.05,
            velocity_sigma: 0.05,
            radius: 0.25,
            motion: Motion::Moving,
            person: true,
            way: Some(DVec2::new(v.0, v.1).normalize_or_zero()),
        }
    }
}

impl Track {
    fn new(id: u32, cluster: &Cluster, now_ms: u32) -> Self {
        let sigma = cluster.sigma();
        Self {
            id,
            x: Axis::new(cluster.centre.x, sigma),
            y: Axis::new(cluster.centre.y, sigma),
            extent: cluster.extent,
            motion: Motion::New,
            moved: false,
            way: None,
            born_ms: now_ms,
            seen_ms: now_ms,
            at_ms: now_ms,
            novel_run: 0,
            settled_since: None,
            history: VecDeque::from([(now_ms, cluster.hits.clone())]),
        }
    }

    /// Taken up again by `cluster` after it was lost, last seen at `seen_at`: its filter
    /// starts again there, at the mean velocity over the gap. Predicted across the gap
    /// the filter's velocity would swing past it (twice the error over the gap, as one
    /// measurement after a long gap reads: someone held up out of view would be taken to
    /// walk back).
    fn resume(&mut self, cluster: &Cluster, seen_at: DVec2, now_ms: u32) {
        let gap = now_ms.saturating_sub(self.seen_ms).max(1) as f64 / 1000.0;
        let velocity = (cluster.centre - seen_at) / gap;
        let sigma = cluster.sigma();
        for (axis, p, v) in [
            (&mut self.x, cluster.centre.x, velocity.x),
            (&mut self.y, cluster.centre.y, velocity.y),
        ] {
            *axis = Axis {
                p,
                v,
                c: [sigma * sigma, 0.0, RESUMED_SIGMA_MPS * RESUMED_SIGMA_MPS],
            };
        }
        self.at_ms = now_ms;
    }

    fn predicted(&self, now_ms: u32) -> (DVec2, f64) {
        let (mut x, mut y) = (self.x, self.y);
        let dt = now_ms.saturating_sub(self.at_ms) as f64 / 1000.0;
        x.predict(dt);
        y.predict(dt);
        (DVec2::new(x.p, y.p), x.c[0].max(y.c[0]).sqrt())
    }

    /// Its view predicted to `now_ms`.
    pub fn view(&self, now_ms: u32) -> TrackView {
        let (mut x, mut y) = (self.x, self.y);
        let dt = now_ms.saturating_sub(self.at_ms) as f64 / 1000.0;
        x.predict(dt);
        y.predict(dt);
        TrackView {
            id: self.id,
            position: DVec2::new(x.p, y.p),
            velocity: DVec2::new(x.v, y.v),
            position_sigma: x.c[0].max(y.c[0]).sqrt(),
            velocity_sigma: x.c[2].max(y.c[2]).sqrt(),
            radius: 0.5 * self.extent,
            motion: self.motion,
            person: self.is_person(),
            way: self.way,
        }
    }

    fn is_person(&self) -> bool {
        self.moved && self.extent <= PERSON_M
    }

    fn speed(&self) -> f64 {
        DVec2::new(self.x.v, self.y.v).length()
    }

    /// Takes this scan's cluster (`base`: the scan its motion is judged against, `now`:
    /// this scan's surfaces): the filter, then moving or still.
    fn take(
        &mut self,
        cluster: Cluster,
        base: Option<&Scan>,
        now: &Surface,
        now_ms: u32,
    ) -> Option<Motion> {
        let dt = now_ms.saturating_sub(self.at_ms) as f64 / 1000.0;
        let sigma = cluster.sigma();
        for (axis, z) in [
            (&mut self.x, cluster.centre.x),
            (&mut self.y, cluster.centre.y),
        ] {
            axis.predict(dt);
            axis.update(z, sigma);
        }
        self.at_ms = now_ms;
        self.seen_ms = now_ms;
        self.extent = cluster.extent;
        if self.motion == Motion::Moving && self.speed() > MOVING_MPS {
            self.way = Some(DVec2::new(self.x.v, self.y.v).normalize());
        }
        let novelty = base.and_then(|b| self.novelty(&cluster.hits, b, now));
        self.history.push_back((now_ms, cluster.hits));
        while self
            .history
            .front()
            .is_some_and(|(t, _)| now_ms.saturating_sub(*t) > HISTORY_MS)
        {
            self.history.pop_front();
        }
        self.judge(novelty, now_ms)
    }

    /// How much of the track is somewhere else than in the scan `base` (`None` when the
    /// track was not seen in it): the lesser of the share of `hits` farther than
    /// [`NOVEL_M`] from the surfaces `base` showed, and the share of the track's hits then
    /// farther than that from the surfaces `now` shows. Both must be large: a thing that
    /// moves is hit where nothing was and not where it was; the face of a van coming into
    /// the scanner's reach only gains hits, and a beam sliding along a wall as the leader
    /// drives still hits the wall.
    fn novelty(&self, hits: &[DVec2], base: &Scan, now: &Surface) -> Option<f64> {
        let (_, then) = self.history.iter().find(|(t, _)| *t == base.at_ms)?;
        if hits.is_empty() || then.is_empty() {
            return None;
        }
        let away = |from: &[DVec2], to: &Surface| {
            let far = from.iter().filter(|h| !to.near(**h, NOVEL_M)).count();
            far as f64 / from.len() as f64
        };
        Some(away(hits, &base.surface).min(away(then, now)))
    }

    /// Moving or still, from the cluster's novelty; the new motion when it changed.
    fn judge(&mut self, novelty: Option<f64>, now_ms: u32) -> Option<Motion> {
        let novelty = novelty?;
        if novelty >= NOVEL_SHARE && self.speed() > MOVING_MPS {
            self.novel_run += 1;
        } else {
            self.novel_run = 0;
        }
        if novelty <= SETTLED_SHARE {
            self.settled_since.get_or_insert(now_ms);
        } else {
            self.settled_since = None;
        }
        let before = self.motion;
        if self.novel_run >= 2 {
            self.motion = Motion::Moving;
            self.moved = true;
        } else if self.settled_since.is_some_and(|t| {
            let need = if self.moved {
                PAUSED_MS
            } else if self.extent < LARGE_M {
                STOPPED_MS
            } else {
                STILL_MS
            };
            now_ms.saturating_sub(t) + BASELINE_MS >= need
        }) {
            self.motion = Motion::Still;
        }
        (self.motion != before).then_some(self.motion)
    }
}

/// Within this of each other, consecutive hits of a scan (in bearing order from the
/// scanner) lie on one surface, m.
pub const SURFACE_LINK_M: f64 = 1.0;

/// The surfaces a scan shows: segments between consecutive hits (by bearing from where
/// it was taken) closer than [`SURFACE_LINK_M`], and lone hits, indexed by cell.
#[derive(Debug, Clone, Default)]
pub struct Surface {
    segments: Vec<(DVec2, DVec2)>,
    cells: CellIndex,
}

impl Surface {
    pub fn of(hits: &[DVec2], origin: DVec2) -> Self {
        let mut sorted: Vec<(f64, DVec2)> = hits
            .iter()
            .map(|h| ((*h - origin).to_angle(), *h))
            .collect();
        sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut segments = Vec::with_capacity(sorted.len());
        for (k, (_, h)) in sorted.iter().enumerate() {
            segments.push((*h, *h));
            let next = sorted[(k + 1) % sorted.len()].1;
            if sorted.len() > 1 && h.distance(next) <= SURFACE_LINK_M {
                segments.push((*h, next));
            }
        }
        let entries = segments.iter().enumerate().flat_map(|(i, (a, b))| {
            let (c0, c1) = (surface_cell(a.min(*b)), surface_cell(a.max(*b)));
            (c0.0..=c1.0).flat_map(move |cx| (c0.1..=c1.1).map(move |cy| ((cx, cy), i)))
        });
        let cells = CellIndex::new(SURFACE_LINK_M, entries);
        Self { segments, cells }
    }

    /// Whether `p` lies within `within` (≤ one cell) of a surface.
    pub fn near(&self, p: DVec2, within: f64) -> bool {
        self.cells.around(p).any(|i| {
            let (a, b) = self.segments[i];
            crate::geometry::closest_on_segment(p, a, b).distance(p) <= within
        })
    }
}

fn surface_cell(p: DVec2) -> (i64, i64) {
    cell_of(p, SURFACE_LINK_M)
}

/// One scan as kept for judging motion.
#[derive(Debug, Clone)]
pub struct Scan {
    at_ms: u32,
    surface: Surface,
}

/// Hits close together: one thing, or things side by side.
#[derive(Debug, Clone)]
struct Cluster {
    hits: Vec<DVec2>,
    /// Where each hit was in the scan.
    order: Vec<usize>,
    centroid: DVec2,
    /// Where the thing's centre is: a person's fitted from the arc their hits lie on
    /// ([`Cluster::fit`]); anything larger's, its centroid.
    centre: DVec2,
    /// The centre was fitted as a person's.
    fitted: bool,
    extent: f64,
}

impl Cluster {
    fn of(order: Vec<usize>, all: &[DVec2]) -> Self {
        let hits: Vec<DVec2> = order.iter().map(|i| all[*i]).collect();
        let centroid = hits.iter().copied().sum::<DVec2>() / hits.len() as f64;
        let extent = hits
            .iter()
            .flat_map(|a| hits.iter().map(move |b| a.distance(*b)))
            .fold(0.0, f64::max);
        Self {
            hits,
            order,
            centroid,
            centre: centroid,
            fitted: false,
            extent,
        }
    }

    /// The centre of a cluster no wider than a person (and [`FIT_SLACK_M`]) seen from
    /// `origin`: the centre of the circle of a person's radius ([`PERSON_RADIUS_M`]) its
    /// hits lie on nearest (Gauss-Newton from one radius behind the centroid), on the
    /// far side of the hits. A sliver of someone half hidden keeps the start.
    fn fit(&mut self, origin: DVec2) {
        let r = PERSON_RADIUS_M;
        if self.extent > 2.0 * r + FIT_SLACK_M {
            return;
        }
        let away = (self.centroid - origin).normalize_or_zero();
        let start = self.centroid + away * r;
        let mut c = start;
        for _ in 0..FIT_STEPS {
            // Normal equations of the residuals |h - c| - r, damped.
            let (mut a, mut b, mut d, mut gx, mut gy) = (FIT_DAMPING, 0.0, FIT_DAMPING, 0.0, 0.0);
            for h in &self.hits {
                let to = c - *h;
                let len = to.length();
                if len < 1e-9 {
                    continue;
                }
                let j = to / len;
                let res = len - r;
                a += j.x * j.x;
                b += j.x * j.y;
                d += j.y * j.y;
                gx += j.x * res;
                gy += j.y * res;
            }
            let det = a * d - b * b;
            let step = DVec2::new(d * gx - b * gy, a * gy - b * gx) / det;
            c -= step;
            if step.length() < 1e-4 {
                break;
            }
        }
        let behind = (c - self.centroid).dot(away) > 0.0;
        self.centre = if behind && c.distance(start) <= r {
            c
        } else {
            start
        };
        self.fitted = true;
    }

    /// The centre's noise: a centroid's hits are the near side only, and move over it; a
    /// fitted centre's is least where the whole near side is seen and grows to a
    /// person's radius for a sliver (the rest hidden, it may be either side).
    fn sigma(&self) -> f64 {
        if self.fitted {
            let seen = self.extent / (2.0 * PERSON_RADIUS_M);
            return CENTROID_SIGMA_M + SLIVER_SIGMA_M * (1.0 - seen).max(0.0);
        }
        CENTROID_SIGMA_M + 0.25 * self.extent
    }
}

/// Of `candidates` (distance, one of `a` things, one of `b`), the nearest pairs first,
/// each thing in one pair at most (ties by index).
fn nearest_pairs(
    mut candidates: Vec<(f64, usize, usize)>,
    a: usize,
    b: usize,
) -> Vec<(usize, usize)> {
    candidates.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
    let (mut a_used, mut b_used) = (vec![false; a], vec![false; b]);
    let mut pairs = Vec::new();
    for (_, i, j) in candidates {
        if !a_used[i] && !b_used[j] {
            a_used[i] = true;
            b_used[j] = true;
            pairs.push((i, j));
        }
    }
    pairs
}

/// Single-linkage clusters of `hits` ([`LINK_M`]), each hit in one.
fn clusters(hits: &[DVec2]) -> Vec<Cluster> {
    let mut parent: Vec<usize> = (0..hits.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let grid = CellIndex::of_points(LINK_M, hits.iter().copied());
    for (i, h) in hits.iter().enumerate() {
        for j in grid.around(*h) {
            if j > i && h.distance(hits[j]) <= LINK_M {
                let (a, b) = (root(&mut parent, i), root(&mut parent, j));
                parent[a.max(b)] = a.min(b);
            }
        }
    }
    let mut groups: std::collections::BTreeMap<usize, Vec<usize>> = Default::default();
    for i in 0..hits.len() {
        let r = root(&mut parent, i);
        groups.entry(r).or_default().push(i);
    }
    groups
        .into_values()
        .map(|order| Cluster::of(order, hits))
        .collect()
}

/// `cluster`'s hits, each to the nearest of `people` (predicted centres) within
/// [`SPLIT_REACH_M`], the rest clustered again on their own.
fn split(cluster: &Cluster, people: &[DVec2], all: &[DVec2]) -> Vec<Cluster> {
    let mut parts: Vec<Vec<usize>> = vec![Vec::new(); people.len()];
    let mut rest = Vec::new();
    for &i in &cluster.order {
        let nearest = people
            .iter()
            .enumerate()
            .map(|(k, at)| (all[i].distance(*at), k))
            .min_by(|a, b| a.0.total_cmp(&b.0));
        match nearest {
            Some((d, k)) if d <= SPLIT_REACH_M => parts[k].push(i),
            _ => rest.push(i),
        }
    }
    let leftover: Vec<DVec2> = rest.iter().map(|i| all[*i]).collect();
    let again = clusters(&leftover)
        .into_iter()
        .map(|c| c.order.iter().map(|j| rest[*j]).collect::<Vec<_>>());
    parts
        .into_iter()
        .chain(again)
        .filter(|order| !order.is_empty())
        .map(|order| Cluster::of(order, all))
        .collect()
}

/// Hits to mark as standing, and tracks whose marks must go.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Observation {
    /// Each hit to mark (its index in the scan, the hit, the track it belongs to and the
    /// room kept round it), in the scan's order.
    pub marks: Vec<(usize, DVec2, MarkTag)>,
    /// Tracks judged moving: the marks they left go.
    pub released: Vec<u32>,
    /// The tracks that took a cluster of this scan (seen in it).
    pub seen: Vec<u32>,
}

/// Whose a mark is and how much room it keeps beyond its cell.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkTag {
    pub track: u32,
    pub pad: f64,
    /// A mark of the way a person who stopped would walk on (the station's lanes).
    pub lane: bool,
}

/// What the tracker has done, for the operator.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct TrackCounts {
    pub started: u64,
    pub ended: u64,
    /// Ended tracks taken up again ([`REVIVE_MS`]).
    pub revived: u64,
    /// Tracks judged moving at least once.
    pub moved: u64,
}

/// The tracks of what the scans show.
#[derive(Debug, Clone, Default)]
pub struct Tracker {
    tracks: Vec<Track>,
    /// People's tracks ended within [`REVIVE_MS`], with where they were last seen.
    lost: Vec<(Track, DVec2)>,
    /// The scans of the last [`HISTORY_MS`], oldest first.
    scans: VecDeque<Scan>,
    next_id: u32,
    /// The room marks of a person who stopped keep: the personal space, m.
    person_pad: f64,
    counts: TrackCounts,
}

impl Tracker {
    /// `person_pad`: the personal space kept round a person who stopped, m.
    pub fn new(person_pad: f64) -> Self {
        Self {
            person_pad,
            ..Self::default()
        }
    }

    /// One scan at `now_ms` taken from `origin` (the leader): `hits` the map does not
    /// explain (site frame).
    pub fn observe(&mut self, hits: &[DVec2], origin: DVec2, now_ms: u32) -> Observation {
        let mut out = Observation::default();
        self.age(now_ms);
        let surface = Surface::of(hits, origin);
        let base = self
            .scans
            .iter()
            .position(|s| now_ms.saturating_sub(s.at_ms) >= BASELINE_MS);
        let mut clusters = self.split_merged(clusters(hits), hits, now_ms);
        for c in &mut clusters {
            c.fit(origin);
        }
        let mut pairs = self.associate(&clusters, now_ms);
        pairs.extend(self.revive(&clusters, &pairs, now_ms));
        let mut clusters: Vec<Option<Cluster>> = clusters.into_iter().map(Some).collect();
        for (t, c) in pairs {
            let cluster = clusters[c].take().expect("each cluster taken once");
            let had_moved = self.tracks[t].moved;
            let base = base.map(|i| &self.scans[i]);
            let changed = self.tracks[t].take(cluster.clone(), base, &surface, now_ms);
            if let Some(motion) = changed {
                let v = self.tracks[t].view(now_ms);
                tracing::debug!(
                    track = v.id,
                    ?motion,
                    x = v.position.x,
                    y = v.position.y,
                    vx = v.velocity.x,
                    vy = v.velocity.y,
                    extent = self.tracks[t].extent,
                    "track judged"
                );
            }
            if changed == Some(Motion::Moving) {
                out.released.push(self.tracks[t].id);
            }
            if self.tracks[t].moved && !had_moved {
                self.counts.moved += 1;
            }
            out.seen.push(self.tracks[t].id);
            self.mark(t, &cluster, &mut out);
        }
        for cluster in clusters.into_iter().flatten() {
            let t = self.start(&cluster, now_ms);
            self.mark(t, &cluster, &mut out);
        }
        // In the scan's order: what is marked is marked as without a tracker.
        out.marks.sort_by_key(|(i, _, _)| *i);
        self.scans.push_back(Scan {
            at_ms: now_ms,
            surface,
        });
        while self
            .scans
            .front()
            .is_some_and(|s| now_ms.saturating_sub(s.at_ms) > HISTORY_MS)
        {
            self.scans.pop_front();
        }
        out
    }

    /// Ends the tracks not seen for [`LOST_MS`]; a person's is kept [`REVIVE_MS`] more.
    pub fn age(&mut self, now_ms: u32) {
        let (kept, ended): (Vec<Track>, Vec<Track>) = std::mem::take(&mut self.tracks)
            .into_iter()
            .partition(|t| now_ms.saturating_sub(t.seen_ms) <= LOST_MS);
        self.tracks = kept;
        self.counts.ended += ended.len() as u64;
        self.lost
            .retain(|(t, _)| now_ms.saturating_sub(t.seen_ms) <= LOST_MS + REVIVE_MS);
        for t in ended.into_iter().filter(|t| t.is_person()) {
            let seen_at = t.predicted(t.seen_ms).0;
            self.lost.push((t, seen_at));
        }
        // Bounded as the tracks are: the longest lost go first.
        if self.lost.len() > MAX_TRACKS {
            let extra = self.lost.len() - MAX_TRACKS;
            self.lost.drain(..extra);
        }
    }

    /// The clusters nobody took (`pairs`: those taken) that are people lost a moment ago
    /// ([`REVIVE_GATE_M`] of their way since), nearest first: those tracks back among the
    /// tracks, each with its cluster.
    fn revive(
        &mut self,
        clusters: &[Cluster],
        pairs: &[(usize, usize)],
        now_ms: u32,
    ) -> Vec<(usize, usize)> {
        if self.lost.is_empty() {
            return Vec::new();
        }
        let taken: Vec<bool> = (0..clusters.len())
            .map(|c| pairs.iter().any(|(_, pc)| *pc == c))
            .collect();
        let mut candidates: Vec<(f64, usize, usize)> = Vec::new();
        for (l, (track, seen_at)) in self.lost.iter().enumerate() {
            let now_at = track.predicted(now_ms).0;
            for (c, cluster) in clusters.iter().enumerate() {
                if taken[c] || cluster.extent > PERSON_M {
                    continue;
                }
                let on_way = crate::geometry::closest_on_segment(cluster.centre, *seen_at, now_at);
                let d = on_way.distance(cluster.centre);
                if d <= REVIVE_GATE_M {
                    candidates.push((d, l, c));
                }
            }
        }
        let mut chosen = nearest_pairs(candidates, self.lost.len(), clusters.len());
        // Out of the lost, highest index first, so the indices still to take stay put.
        chosen.sort_by_key(|(l, _)| std::cmp::Reverse(*l));
        let mut out = Vec::with_capacity(chosen.len());
        for (l, c) in chosen {
            if self.tracks.len() >= MAX_TRACKS {
                break;
            }
            let (mut track, seen_at) = self.lost.remove(l);
            track.resume(&clusters[c], seen_at, now_ms);
            self.tracks.push(track);
            self.counts.revived += 1;
            out.push((self.tracks.len() - 1, c));
        }
        out
    }

    /// Each cluster wider than a person where two or more tracks of a person's size are
    /// predicted, one of them a person (it moved), split between them
    /// ([`SPLIT_ABOVE_M`]). Only those: a cluster where anything larger is predicted (a
    /// wall, a van, people already taken as one) stays whole, and so do patches of
    /// something standing that join as the scanner comes nearer.
    fn split_merged(&self, clusters: Vec<Cluster>, all: &[DVec2], now_ms: u32) -> Vec<Cluster> {
        if clusters.iter().all(|c| c.extent < SPLIT_ABOVE_M) {
            return clusters;
        }
        // Each track predicted once per scan, not once per wide cluster.
        let predicted: Vec<(DVec2, &Track)> = self
            .tracks
            .iter()
            .map(|t| (t.predicted(now_ms).0, t))
            .collect();
        let mut out = Vec::with_capacity(clusters.len());
        for cluster in clusters {
            let on: Vec<&(DVec2, &Track)> = if cluster.extent < SPLIT_ABOVE_M {
                Vec::new()
            } else {
                let near = |(at, _): &&(DVec2, &Track)| {
                    cluster.hits.iter().any(|h| h.distance(*at) <= SPLIT_NEAR_M)
                };
                predicted.iter().filter(near).collect()
            };
            let small = on.iter().all(|(_, t)| t.extent <= PERSON_M);
            if on.len() < 2 || !small || !on.iter().any(|(_, t)| t.moved) {
                out.push(cluster);
                continue;
            }
            let centres: Vec<DVec2> = on.iter().map(|(at, _)| *at).collect();
            out.extend(split(&cluster, &centres, all));
        }
        out
    }

    /// Nearest pairs first, each within its track's gate.
    fn associate(&self, clusters: &[Cluster], now_ms: u32) -> Vec<(usize, usize)> {
        let mut candidates: Vec<(f64, usize, usize)> = Vec::new();
        for (t, track) in self.tracks.iter().enumerate() {
            let (at, sigma) = track.predicted(now_ms);
            let gate = (GATE_M + 3.0 * sigma).min(MAX_GATE_M) + 0.5 * track.extent;
            for (c, cluster) in clusters.iter().enumerate() {
                let d = at.distance(cluster.centre);
                if d <= gate + 0.5 * cluster.extent {
                    candidates.push((d, t, c));
                }
            }
        }
        nearest_pairs(candidates, self.tracks.len(), clusters.len())
    }

    fn start(&mut self, cluster: &Cluster, now_ms: u32) -> usize {
        if self.tracks.len() >= MAX_TRACKS {
            // The one seen longest ago makes room.
            if let Some(oldest) = (0..self.tracks.len()).min_by_key(|i| self.tracks[*i].seen_ms) {
                self.tracks.swap_remove(oldest);
                self.counts.ended += 1;
            }
        }
        self.tracks.push(Track::new(self.next_id, cluster, now_ms));
        self.next_id = self.next_id.wrapping_add(1);
        self.counts.started += 1;
        self.tracks.len() - 1
    }

    /// What of track `t`'s cluster is marked.
    fn mark(&self, t: usize, cluster: &Cluster, out: &mut Observation) {
        let track = &self.tracks[t];
        let marked = match track.motion {
            Motion::Moving => false,
            Motion::Still => true,
            Motion::New => cluster.extent >= LARGE_M,
        };
        if !marked {
            return;
        }
        let pad = if track.is_person() {
            self.person_pad
        } else {
            0.0
        };
        let tag = MarkTag {
            track: track.id,
            pad,
            lane: false,
        };
        out.marks.extend(
            cluster
                .order
                .iter()
                .zip(&cluster.hits)
                .map(|(i, h)| (*i, *h, tag)),
        );
    }

    /// Every track, predicted to `now_ms`.
    pub fn views(&self, now_ms: u32) -> impl Iterator<Item = TrackView> + '_ {
        self.tracks.iter().map(move |t| t.view(now_ms))
    }

    /// The tracks judged moving, predicted to `now_ms`.
    pub fn moving(&self, now_ms: u32) -> impl Iterator<Item = TrackView> + '_ {
        self.views(now_ms).filter(|v| v.motion == Motion::Moving)
    }

    pub fn counts(&self) -> TrackCounts {
        self.counts
    }

    pub fn len(&self) -> usize {
        self.tracks.len()
    }

    pub fn is_empty(&self) -> bool {
        self.tracks.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A person's hits at `at` as a scanner at the origin sees them: the near side of a
    /// 0.25 m disc.
    fn person_at(at: DVec2) -> Vec<DVec2> {
        let toward = (-at).normalize();
        (-2..=2)
            .map(|k| at + DVec2::from_angle(toward.to_angle() + k as f64 * 0.35) * 0.25)
            .collect()
    }

    #[test]
    fn two_people_walking_side_by_side_keep_their_own_tracks() {
        // Both walk toward the scanner, 0.6 m apart, one at 1.2 m/s catching up with one
        // at 1.0 m/s from 1.4 m behind: from t = 5.3 s to 8.8 s their hits are one
        // cluster (0.9 m wide).
        let mut tracker = Tracker::new(0.8);
        for k in 0..=100 {
            let t = k as f64 * 0.1;
            let a = DVec2::new(16.0 - 1.2 * t, 0.3);
            let b = DVec2::new(14.6 - 1.0 * t, -0.3);
            let hits: Vec<DVec2> = person_at(a).into_iter().chain(person_at(b)).collect();
            tracker.observe(&hits, DVec2::ZERO, k * 100);
            if t < 2.0 {
                continue;
            }
            let views: Vec<TrackView> = tracker.views(k * 100).collect();
            assert_eq!(views.len(), 2, "t = {t:.1}: {views:?}");
            for (at, v) in [(a, -1.2), (b, -1.0)] {
                let own = views
                    .iter()
                    .min_by(|p, q| p.position.distance(at).total_cmp(&q.position.distance(at)))
                    .expect("two tracks");
                assert!(own.position.distance(at) < 0.35, "t = {t:.1}: {own:?}");
                assert!(
                    (own.velocity - DVec2::new(v, 0.0)).length() < 0.3,
                    "t = {t:.1}: {own:?}"
                );
            }
        }
        assert_eq!(
            tracker.counts().started,
            2,
            "a track ended and started again"
        );
    }

    #[test]
    fn a_person_is_tracked_at_their_centre_and_kept_through_a_gap() {
        // Walking along +y at 1.2 m/s, 6 m ahead of the scanner; out of view (behind
        // someone) from 3 s to 4.5 s.
        let mut tracker = Tracker::new(0.8);
        let centre = |t: f64| DVec2::new(6.0, -3.0 + 1.2 * t);
        for k in 0..=60 {
            let t = k as f64 * 0.1;
            let hits = if (3.0..4.5).contains(&t) {
                Vec::new()
            } else {
                person_at(centre(t))
            };
            tracker.observe(&hits, DVec2::ZERO, k * 100);
        }
        let views: Vec<TrackView> = tracker.views(6000).collect();
        assert_eq!(views.len(), 1, "{views:?}");
        let v = views[0];
        assert!(v.position.distance(centre(6.0)) < 0.1, "{v:?}");
        assert!((v.velocity - DVec2::new(0.0, 1.2)).length() < 0.3, "{v:?}");
        assert_eq!(v.motion, Motion::Moving);
        assert_eq!(tracker.counts().revived, 1);
    }
}
