//! How often a robot standing where the fleet went would have been walked into: the
//! parked fleet a moving one is judged against (issue 51: in oblivious crowds, contacts
//! per robot-hour no higher than a parked fleet's in the same worlds). A fleet parked
//! where it starts stands at the edge of a plaza's crowd, where fewer ways cross than in
//! the middle it drives through (0.1 persons/m²: about 170 contacts per robot-hour at
//! the edge, 700–1,300 at the centre); so the parked robot is put where the moving ones
//! were. An oblivious mover's way does not depend on the robots, so one run tells where
//! they walked: each robot's position once a second is a parked robot, and every time an
//! oblivious mover's footprint came onto one over the whole run is a contact it would
//! have had.

use rustc_hash::FxHashSet;

use base_station::geometry::cells::CellIndex;

use crate::metrics::Sample;

/// A parked robot is put where each robot was once every this many samples (1 s).
const POINT_EVERY: usize = 10;
/// The points' grid: no oblivious mover reaches farther from its centre than this (half
/// a 4 m vehicle and a footprint), m.
const CELL_M: f64 = 3.0;

/// Contacts per robot-hour of robots standing, for the whole run, where the fleet's
/// robots were (`footprint`: their radius), with the oblivious movers of `samples`;
/// `None` without oblivious movers or samples.
pub fn parked_where_it_went(samples: &[Sample], footprint: f64) -> Option<f64> {
    let points: Vec<glam::DVec2> = samples
        .iter()
        .step_by(POINT_EVERY)
        .flat_map(|s| s.robots.iter().map(|r| glam::DVec2::new(r.x, r.y)))
        .collect();
    let oblivious = samples.iter().any(|s| s.movers.iter().any(|m| m.oblivious));
    if points.is_empty() || !oblivious || samples.len() < 2 {
        return None;
    }
    let index = CellIndex::of_points(CELL_M, points.iter().copied());
    let mut inside: FxHashSet<(usize, usize)> = FxHashSet::default();
    let mut now: FxHashSet<(usize, usize)> = FxHashSet::default();
    let mut entries = 0u64;
    for s in samples {
        now.clear();
        for m in s.movers.iter().filter(|m| m.oblivious) {
            for p in index.around(m.position) {
                if m.distance(points[p]) < footprint {
                    now.insert((p, m.index));
                }
            }
        }
        entries += now.difference(&inside).count() as u64;
        std::mem::swap(&mut inside, &mut now);
    }
    let span_s = samples[samples.len() - 1].t - samples[0].t;
    let hours = points.len() as f64 * span_s / 3600.0;
    (hours > 0.0).then(|| entries as f64 / hours)
}
