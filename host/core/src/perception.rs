//! What the leader's range scanner sees that the site map does not hold (a parked van, a
//! skip, a bin moved into the street): scan hits become small obstacles the planner
//! avoids and routes round.
//!
//! A hit within `EXPLAINED` of a mapped surface is the map's own obstacle and ignored;
//! the others are kept one per `CELL`-sized cell, as discs of radius `CELL / 2` centred on
//! the first hit of that cell. They are never forgotten (a route planned round something
//! stays valid), and their number is bounded: past `MAX_SENSED` new hits are dropped and
//! counted.
//!
//! Where the station has no simulated scanner (`basestation run`), the scans come in as a
//! line feed ([`parse_scan_line`]) from whatever processes the leader's lidar.

use std::collections::HashSet;

use glam::DVec2;

use crate::geometry::Obstacle;
use crate::map::Map;

/// Side of the cells hits are merged in, m.
pub const CELL: f64 = 0.2;
/// A hit closer than this to a mapped surface is that surface, m.
pub const EXPLAINED: f64 = 0.15;
/// Most sensed obstacles kept.
pub const MAX_SENSED: usize = 8192;

#[derive(Debug, Clone, Default)]
pub struct Perception {
    cells: HashSet<(i64, i64)>,
    obstacles: Vec<Obstacle>,
    dropped: u64,
}

impl Perception {
    /// Takes one scan's hits (site frame); returns the obstacles it adds.
    pub fn absorb(&mut self, hits: &[DVec2], known: &Map) -> Vec<Obstacle> {
        let mut added = Vec::new();
        for &hit in hits {
            if !hit.is_finite() || known.clearance(hit, EXPLAINED) < EXPLAINED {
                continue;
            }
            let cell = ((hit.x / CELL).floor() as i64, (hit.y / CELL).floor() as i64);
            if self.cells.contains(&cell) {
                continue;
            }
            if self.obstacles.len() >= MAX_SENSED {
                self.dropped += 1;
                continue;
            }
            self.cells.insert(cell);
            let o = Obstacle::Circle {
                center: hit,
                radius: 0.5 * CELL,
            };
            self.obstacles.push(o.clone());
            added.push(o);
        }
        added
    }

    /// Everything sensed so far.
    pub fn obstacles(&self) -> &[Obstacle] {
        &self.obstacles
    }

    /// Hits dropped because `MAX_SENSED` obstacles were already kept.
    pub fn dropped(&self) -> u64 {
        self.dropped
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

    #[test]
    fn mapped_surfaces_are_ignored_and_new_ones_kept_once_per_cell() {
        let known = Map::new(vec![Obstacle::Circle {
            center: DVec2::new(5.0, 0.0),
            radius: 1.0,
        }]);
        let mut p = Perception::default();
        let added = p.absorb(
            &[
                DVec2::new(4.0, 0.0),   // on the mapped bin
                DVec2::new(0.0, 3.01),  // new
                DVec2::new(0.05, 3.05), // same cell
                DVec2::new(0.0, 3.5),   // next cell
                DVec2::new(f64::NAN, 0.0),
            ],
            &known,
        );
        assert_eq!(added.len(), 2);
        assert_eq!(p.obstacles().len(), 2);
        assert!(p.absorb(&[DVec2::new(0.0, 3.02)], &known).is_empty());
    }
}
