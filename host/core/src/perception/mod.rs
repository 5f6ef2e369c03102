//! What the leader's range scanner sees that the site map does not hold (a parked van, a
//! skip, a bin moved into the street): scan hits become small obstacles the planner
//! avoids and routes round.
//!
//! A hit within `EXPLAINED` of a mapped surface is the map's own obstacle and ignored;
//! the others go to the tracker ([`crate::perception::tracking`]), which says which stand still. Those
//! are kept one per `CELL`-sized cell, as discs of radius `CELL / 2` centred on the first
//! hit of that cell ("marks"), grown by the personal space where a person stopped; a mark
//! belongs to its track, and goes when the track moves on.
//!
//! What a scan may claim is bounded, so no scan (nor a forged one) can stop a mission for
//! good or blind the station to what is really there:
//!
//! - a hit farther from the leader than the scanner reaches (`[perception] max_range_m`),
//!   or outside the site's bounds (plus [`BOUNDS_MARGIN`]), is no hit (`out_of_range`);
//!   while the station does not know where the leader is, no hit is taken;
//! - a mark not seen again for `[perception] forget_after_s` is forgotten: a van that
//!   drove off, a wall that was never there;
//! - past [`MAX_SENSED`] marks (or a source's share of them, [`SOURCE_SHARE`]) the mark
//!   seen longest ago makes room for the new one: the newest observations always count.
//!
//! Where the station has no simulated scanner (`basestation run`), the scans come in as a
//! line feed ([`parse_scan_line`]) from whatever processes the leader's lidar.

pub mod tracking;
use std::collections::{BTreeSet, HashMap};

use glam::DVec2;
use serde::Serialize;

use crate::geometry::map::Map;
use crate::geometry::Obstacle;
use crate::perception::tracking::MarkTag;

/// Side of the cells hits are merged in, m.
pub const CELL: f64 = 0.2;
/// A hit closer than this to a mapped surface is that surface, m.
pub const EXPLAINED: f64 = 0.15;
/// Most sensed obstacles kept.
pub const MAX_SENSED: usize = 8192;
/// The share of [`MAX_SENSED`] one source may hold.
pub const SOURCE_SHARE: usize = MAX_SENSED / 2;
/// A hit this far outside the site's bounds is off the site, m.
pub const BOUNDS_MARGIN: f64 = 1.0;

/// What bounds the scans, from the scenario's `[perception]` and the site's bounds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PerceptionLimits {
    /// Farthest a hit may lie from the leader, m.
    pub max_range: f64,
    /// A mark not seen again for this long is forgotten, ms.
    pub forget_after_ms: u32,
    /// The site's bounds (min, max), when the site file gives them.
    pub bounds: Option<(DVec2, DVec2)>,
}

impl PerceptionLimits {
    pub fn from_scenario(s: &crate::scenario::Scenario) -> Self {
        Self {
            max_range: s.perception.max_range_m,
            forget_after_ms: (s.perception.forget_after_s * 1000.0).round() as u32,
            bounds: s
                .map
                .bounds
                .map(|b| (DVec2::from(b.min), DVec2::from(b.max))),
        }
    }

    /// Whether a hit at `hit` is one the leader at `leader` can have seen on this site.
    fn plausible(&self, hit: DVec2, leader: DVec2) -> bool {
        let on_site = self.bounds.is_none_or(|(lo, hi)| {
            let m = DVec2::splat(BOUNDS_MARGIN);
            hit.cmpge(lo - m).all() && hit.cmple(hi + m).all()
        });
        hit.is_finite() && on_site && hit.distance(leader) <= self.max_range
    }
}

/// What the scans brought, by what became of their hits.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct PerceptionCounts {
    /// Hits off the site or out of the scanner's reach (or before the leader was known).
    pub out_of_range: u64,
    /// Marks forgotten, not seen again.
    pub forgotten: u64,
    /// Marks that made room for newer ones.
    pub evicted: u64,
    /// Marks of things that stood and moved on.
    pub released: u64,
}

#[derive(Debug, Clone)]
struct Mark {
    obstacle: Obstacle,
    last_seen_ms: u32,
    source: u8,
    /// The track whose hit it was, if a tracker judged it.
    track: Option<u32>,
    /// A person's way on, not a hit.
    lane: bool,
}

/// What a scan or the passing of time changed.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Change {
    pub added: Vec<Obstacle>,
    pub removed: Vec<Obstacle>,
}

impl Change {
    pub fn is_empty(&self) -> bool {
        self.added.is_empty() && self.removed.is_empty()
    }
}

#[derive(Debug, Clone)]
pub struct Perception {
    limits: PerceptionLimits,
    marks: HashMap<Cell, Mark>,
    /// Each source's marks by when they were last seen.
    by_age: HashMap<u8, Ages>,
    counts: PerceptionCounts,
}

/// A cell of the merging grid.
type Cell = (i64, i64);
/// One source's marks by when they were last seen (station ms), oldest first.
type Ages = BTreeSet<(u32, Cell)>;

fn cell_of(hit: DVec2) -> Cell {
    ((hit.x / CELL).floor() as i64, (hit.y / CELL).floor() as i64)
}

impl Perception {
    pub fn new(limits: PerceptionLimits) -> Self {
        Self {
            limits,
            marks: HashMap::new(),
            by_age: HashMap::new(),
            counts: PerceptionCounts::default(),
        }
    }

    /// Takes one scan of source `source` (its hits in the site frame), taken with the
    /// leader at `leader` (`None`: not known, nothing is taken) at `now_ms`, and marks
    /// every hit the map does not explain (no tracker: everything seen stands).
    pub fn absorb(
        &mut self,
        hits: &[DVec2],
        leader: Option<DVec2>,
        known: &Map,
        source: u8,
        now_ms: u32,
    ) -> Change {
        let unexplained = self.screen(hits, leader, known);
        let marks: Vec<(DVec2, Option<MarkTag>)> =
            unexplained.into_iter().map(|h| (h, None)).collect();
        self.mark(&marks, source, now_ms)
    }

    /// The hits of a scan taken with the leader at `leader` that the leader can have
    /// seen and the map does not explain (the rest counted).
    pub fn screen(&mut self, hits: &[DVec2], leader: Option<DVec2>, known: &Map) -> Vec<DVec2> {
        let Some(leader) = leader else {
            self.counts.out_of_range += hits.len() as u64;
            return Vec::new();
        };
        let mut kept = Vec::with_capacity(hits.len());
        for &hit in hits {
            if !self.limits.plausible(hit, leader) {
                self.counts.out_of_range += 1;
            } else if known.clearance(hit, EXPLAINED) >= EXPLAINED {
                kept.push(hit);
            }
        }
        kept
    }

    /// Marks each hit of `marks` (one per cell: a hit in a marked cell renews it), of
    /// `source`, at `now_ms`; a tag says whose it is and the room it keeps.
    pub fn mark(&mut self, marks: &[(DVec2, Option<MarkTag>)], source: u8, now_ms: u32) -> Change {
        let mut change = Change::default();
        for &(hit, tag) in marks {
            let cell = cell_of(hit);
            if let Some(mark) = self.marks.get_mut(&cell) {
                if let Some(ages) = self.by_age.get_mut(&mark.source) {
                    ages.remove(&(mark.last_seen_ms, cell));
                    ages.insert((now_ms, cell));
                }
                mark.last_seen_ms = now_ms;
                continue;
            }
            let mine = self.by_age.get(&source).map_or(0, BTreeSet::len);
            if self.marks.len() >= MAX_SENSED || mine >= SOURCE_SHARE {
                let only = (mine >= SOURCE_SHARE).then_some(source);
                if let Some(old) = self.evict(only) {
                    self.counts.evicted += 1;
                    change.removed.push(old);
                }
            }
            let obstacle = Obstacle::Circle {
                center: hit,
                radius: 0.5 * CELL + tag.map_or(0.0, |t| t.pad),
            };
            self.marks.insert(
                cell,
                Mark {
                    obstacle: obstacle.clone(),
                    last_seen_ms: now_ms,
                    source,
                    track: tag.map(|t| t.track),
                    lane: tag.is_some_and(|t| t.lane),
                },
            );
            self.by_age
                .entry(source)
                .or_default()
                .insert((now_ms, cell));
            change.added.push(obstacle);
        }
        change
    }

    /// Forgets the marks of `tracks`: they moved on.
    pub fn release(&mut self, tracks: &[u32]) -> Change {
        self.release_where(tracks, |_| true)
    }

    /// Forgets the lane marks of `tracks` (their hits stay marked).
    pub fn release_lanes(&mut self, tracks: &[u32]) -> Change {
        self.release_where(tracks, |m| m.lane)
    }

    fn release_where(&mut self, tracks: &[u32], which: impl Fn(&Mark) -> bool) -> Change {
        if tracks.is_empty() {
            return Change::default();
        }
        let mut cells: Vec<Cell> = self
            .marks
            .iter()
            .filter(|(_, m)| m.track.is_some_and(|t| tracks.contains(&t)) && which(m))
            .map(|(c, _)| *c)
            .collect();
        cells.sort_unstable();
        let removed: Vec<Obstacle> = cells.into_iter().filter_map(|c| self.remove(c)).collect();
        self.counts.released += removed.len() as u64;
        Change {
            added: Vec::new(),
            removed,
        }
    }

    /// Forgets the mark seen longest ago (of `source` only, when given).
    fn evict(&mut self, source: Option<u8>) -> Option<Obstacle> {
        let (_, cell) = self
            .by_age
            .iter()
            .filter(|(s, _)| source.is_none_or(|only| **s == only))
            .filter_map(|(_, ages)| ages.first().copied())
            .min()?;
        self.remove(cell)
    }

    fn remove(&mut self, cell: Cell) -> Option<Obstacle> {
        let mark = self.marks.remove(&cell)?;
        if let Some(ages) = self.by_age.get_mut(&mark.source) {
            ages.remove(&(mark.last_seen_ms, cell));
        }
        Some(mark.obstacle)
    }

    /// Forgets the marks not seen again for `forget_after` by `now_ms`.
    pub fn age(&mut self, now_ms: u32) -> Change {
        let limit = self.limits.forget_after_ms;
        let mut stale: Vec<Cell> = self
            .by_age
            .values()
            .flat_map(|ages| {
                ages.iter()
                    .take_while(|(seen, _)| now_ms.saturating_sub(*seen) > limit)
                    .map(|(_, cell)| *cell)
            })
            .collect();
        stale.sort_unstable();
        let removed: Vec<Obstacle> = stale.into_iter().filter_map(|c| self.remove(c)).collect();
        self.counts.forgotten += removed.len() as u64;
        Change {
            added: Vec::new(),
            removed,
        }
    }

    /// Everything sensed and not forgotten, in no particular order.
    pub fn obstacles(&self) -> impl Iterator<Item = &Obstacle> + '_ {
        self.marks.values().map(|m| &m.obstacle)
    }

    /// Everything sensed and not forgotten, by cell (row by row): the same marks in the
    /// same order in every process, for a recording (the marks are kept hashed).
    pub fn in_order(&self) -> Vec<Obstacle> {
        let mut cells: Vec<(&Cell, &Mark)> = self.marks.iter().collect();
        cells.sort_unstable_by_key(|(c, _)| (c.1, c.0));
        cells.into_iter().map(|(_, m)| m.obstacle.clone()).collect()
    }

    pub fn len(&self) -> usize {
        self.marks.len()
    }

    pub fn is_empty(&self) -> bool {
        self.marks.is_empty()
    }

    pub fn counts(&self) -> PerceptionCounts {
        self.counts
    }
}

/// Most hits one line of the scan feed may carry (a 0.25° lidar's full turn).
pub const MAX_HITS_PER_LINE: usize = 1440;

/// One line of the scan feed: `TIME_S,X_M,Y_M[,X_M,Y_M…]`, one scan's hits on obstacle
/// surfaces in the site frame, `TIME_S` when it was taken (seconds since the Unix epoch).
/// Blank lines and `#` comments are `Ok(None)`; what is wrong is said, field by field.
pub fn parse_scan_line(line: &str) -> Result<Option<(f64, Vec<DVec2>)>, String> {
    let line = line.trim();
    if line.is_empty() || line.starts_with('#') {
        return Ok(None);
    }
    let fields: Vec<&str> = line.split(',').map(str::trim).collect();
    if fields.len() < 3 || fields.len().is_multiple_of(2) {
        return Err(format!(
            "{} fields, expected TIME_S then X_M,Y_M pairs",
            fields.len()
        ));
    }
    if (fields.len() - 1) / 2 > MAX_HITS_PER_LINE {
        return Err(format!(
            "{} hits, at most {MAX_HITS_PER_LINE} a line",
            (fields.len() - 1) / 2
        ));
    }
    let number = |i: usize| {
        fields[i]
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("field {}: {:?} is not a number", i + 1, fields[i]))
    };
    let time = number(0)?;
    if !(0.0..=1e11).contains(&time) {
        return Err(format!("time {time} is not seconds since 1970"));
    }
    let hits = (1..fields.len())
        .step_by(2)
        .map(|i| Ok(DVec2::new(number(i)?, number(i + 1)?)))
        .collect::<Result<Vec<_>, String>>()?;
    Ok(Some((time, hits)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scan_lines_parse_and_bad_ones_say_why() {
        assert_eq!(
            parse_scan_line("1764486000.5, 1.0,2.0, -3.5,4").unwrap(),
            Some((
                1764486000.5,
                vec![DVec2::new(1.0, 2.0), DVec2::new(-3.5, 4.0)]
            ))
        );
        assert_eq!(parse_scan_line("  # a comment").unwrap(), None);
        assert_eq!(parse_scan_line("").unwrap(), None);
        for (bad, why) in [
            ("1764486000.5,1.0", "2 fields"),
            ("1764486000.5,1.0,2.0,3.0", "4 fields"),
            ("1764486000.5,1.0,north", "field 3"),
            ("1764486000.5,inf,2.0", "field 2"),
            ("-5,1.0,2.0", "seconds since 1970"),
        ] {
            let e = parse_scan_line(bad).unwrap_err();
            assert!(e.contains(why), "{bad}: {e}");
        }
        let long = format!("1.0{}", ",0.0,0.0".repeat(MAX_HITS_PER_LINE + 1));
        assert!(parse_scan_line(&long).unwrap_err().contains("at most"));
    }

    const LIMITS: PerceptionLimits = PerceptionLimits {
        max_range: 10.0,
        forget_after_ms: 30_000,
        bounds: Some((DVec2::new(-5.0, -5.0), DVec2::new(20.0, 20.0))),
    };

    #[test]
    fn mapped_surfaces_are_ignored_and_new_ones_kept_once_per_cell() {
        let known = Map::new(vec![Obstacle::Circle {
            center: DVec2::new(5.0, 0.0),
            radius: 1.0,
        }]);
        let mut p = Perception::new(LIMITS);
        let leader = Some(DVec2::ZERO);
        let added = p.absorb(
            &[
                DVec2::new(4.0, 0.0),   // on the mapped bin
                DVec2::new(0.0, 3.01),  // new
                DVec2::new(0.05, 3.05), // same cell
                DVec2::new(0.0, 3.5),   // next cell
                DVec2::new(f64::NAN, 0.0),
            ],
            leader,
            &known,
            0,
            0,
        );
        assert_eq!(added.added.len(), 2);
        assert_eq!(p.len(), 2);
        assert!(p
            .absorb(&[DVec2::new(0.0, 3.02)], leader, &known, 0, 100)
            .is_empty());
    }

    /// Issue 27, finding 3: one datagram of hits far away, off the site or before the
    /// leader is known (a hit at 1e300 made the start "inside an obstacle") adds nothing.
    #[test]
    fn hits_the_scanner_cannot_have_seen_are_no_hits() {
        let known = Map::new(Vec::new());
        let mut p = Perception::new(LIMITS);
        let far = [
            DVec2::new(15.0, 15.0),   // on the site, 21 m from the leader
            DVec2::new(-8.0, 0.0),    // off the site
            DVec2::new(1e300, 1e300), // nowhere
        ];
        assert!(p.absorb(&far, Some(DVec2::ZERO), &known, 0, 0).is_empty());
        let near = [DVec2::new(2.0, 2.0)];
        assert!(p.absorb(&near, None, &known, 0, 0).is_empty());
        assert_eq!(p.counts().out_of_range, 4);
        assert_eq!(
            p.absorb(&near, Some(DVec2::ZERO), &known, 0, 0).added.len(),
            1
        );
    }

    /// A person who stopped: their hits and the lane of their way on. Giving the lane up
    /// releases the lane marks alone; their hits stay marked until they move on.
    #[test]
    fn a_lane_is_released_alone_and_the_person_with_it_when_they_move() {
        let mut p = Perception::new(LIMITS);
        let tag = |lane| {
            Some(MarkTag {
                track: 7,
                pad: 0.3,
                lane,
            })
        };
        let person = (DVec2::new(3.0, 0.0), tag(false));
        let lane: Vec<_> = (1..=5)
            .map(|k| (DVec2::new(3.0, -0.4 * k as f64), tag(true)))
            .collect();
        let mut marks = vec![person];
        marks.extend(lane);
        assert_eq!(p.mark(&marks, 0, 0).added.len(), 6);
        assert!(p.release_lanes(&[8]).is_empty(), "another track's lanes");
        assert_eq!(p.release_lanes(&[7]).removed.len(), 5);
        assert_eq!(p.len(), 1, "the person stays marked");
        assert_eq!(p.release(&[7]).removed.len(), 1);
        assert_eq!(p.len(), 0);
    }

    /// The marks in order are the same whatever order they were seen in (the store is
    /// hashed, and hashers differ from process to process).
    #[test]
    fn marks_in_order_do_not_depend_on_the_order_seen() {
        let known = Map::new(Vec::new());
        let hits: Vec<DVec2> = (0..30)
            .map(|k| DVec2::new(-3.0 + 0.2 * (k % 10) as f64, 1.0 + 0.4 * (k / 10) as f64))
            .collect();
        let mut reversed = hits.clone();
        reversed.reverse();
        let mut a = Perception::new(LIMITS);
        let mut b = Perception::new(LIMITS);
        a.absorb(&hits, Some(DVec2::ZERO), &known, 0, 0);
        b.absorb(&reversed, Some(DVec2::ZERO), &known, 0, 0);
        let order = a.in_order();
        assert_eq!(order.len(), 30);
        assert_eq!(order, b.in_order());
        let first = order[0].bounds()[0];
        assert!(first.y < 1.0 && first.x < -2.9, "{first}");
    }

    /// Issue 27, finding 3: a wall of hits (here a real one seen once) is forgotten when
    /// it is not seen again; what is seen again stays.
    #[test]
    fn marks_not_seen_again_are_forgotten() {
        let known = Map::new(Vec::new());
        let mut p = Perception::new(LIMITS);
        let wall: Vec<DVec2> = (0..40)
            .map(|k| DVec2::new(-3.0 + 0.2 * k as f64, 5.0))
            .collect();
        let van = [DVec2::new(3.0, -2.0)];
        p.absorb(&wall, Some(DVec2::ZERO), &known, 0, 0);
        for t in (0..=40_000).step_by(1000) {
            p.absorb(&van, Some(DVec2::ZERO), &known, 0, t);
        }
        let forgotten = p.age(30_500);
        assert_eq!(forgotten.removed.len(), 40);
        assert_eq!(p.len(), 1, "the van stays");
        assert!(p.age(40_000).is_empty());
    }

    /// Issue 27, finding 3: six datagrams of hits filled the cap and the real van was
    /// never sensed. Past the cap (or a source's share) the marks seen longest ago make
    /// room: what is seen now always gets in.
    #[test]
    fn a_full_store_makes_room_for_what_is_seen_now() {
        let known = Map::new(Vec::new());
        let limits = PerceptionLimits {
            max_range: 1e9,
            bounds: None,
            ..LIMITS
        };
        let mut p = Perception::new(limits);
        let flood: Vec<DVec2> = (0..MAX_SENSED)
            .map(|k| DVec2::new((k % 100) as f64 * 0.3, (k / 100) as f64 * 0.3))
            .collect();
        let first = p.absorb(&flood, Some(DVec2::ZERO), &known, 1, 0);
        assert_eq!(first.added.len(), MAX_SENSED);
        assert_eq!(p.len(), SOURCE_SHARE, "one source holds its share only");
        let van = [DVec2::new(-10.0, -10.0)];
        let seen = p.absorb(&van, Some(DVec2::ZERO), &known, 0, 100);
        assert_eq!(seen.added.len(), 1, "another source still gets in");
        let again = p.absorb(
            &[DVec2::new(-20.0, -20.0)],
            Some(DVec2::ZERO),
            &known,
            1,
            200,
        );
        assert_eq!((again.added.len(), again.removed.len()), (1, 1));
        assert!(p.counts().evicted > 0);
    }
}
