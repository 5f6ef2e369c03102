//! Passage detection and the slot transition on synthetic maps.

use base_station::formation::{
    FollowerStatus, FormationManager, FormationSpec, LeaderMotion, Target, WideShape,
};
use base_station::geometry::map::Map;
use base_station::geometry::Obstacle;
use base_station::planner::PlanPose;
use glam::DVec2;

fn spec() -> FormationSpec {
    FormationSpec {
        wide: WideShape::V {
            distance: 3.0,
            angle: 150f64.to_radians(),
        },
        followers: 2,
        line_spacing: 1.5,
        margin: 0.5,
        transition_s: 3.0,
        min_dwell_s: 2.0,
        lookahead: 5.0,
        footprint: 0.3,
        slot_speed: 0.8,
        top_speed: 1.0,
    }
}

/// Every follower on its slot point.
fn at_their_slots(fm: &FormationManager, leader: PlanPose) -> Vec<Option<FollowerStatus>> {
    fm.slot_points(leader)
        .into_iter()
        .map(|position| {
            Some(FollowerStatus {
                position,
                error: 0.0,
                joined: true,
                detouring: false,
            })
        })
        .collect()
}

fn block(x0: f64, y0: f64, x1: f64, y1: f64) -> Obstacle {
    Obstacle::rectangle(DVec2::new(x0, y0), DVec2::new(x1, y1))
}

/// A wall across y with a gap of `width` centred on y = 10, x ∈ [12, 18].
fn gap(width: f64) -> Map {
    gap_and(width, None)
}

/// The gap, and an obstacle more.
fn gap_and(width: f64, extra: Option<Obstacle>) -> Map {
    let mut obstacles = vec![
        block(12.0, -10.0, 18.0, 10.0 - width / 2.0),
        block(12.0, 10.0 + width / 2.0, 18.0, 30.0),
    ];
    obstacles.extend(extra);
    Map::new(obstacles)
}

/// The leader at `t` s, driving along y = 10 from x = 2 at 0.4 m/s.
fn straight_along_the_street(t: f64) -> LeaderMotion {
    LeaderMotion {
        pose: PlanPose {
            position: DVec2::new(2.0 + 0.4 * t, 10.0),
            heading: 0.0,
        },
        v: 0.4,
        omega: 0.0,
    }
}

struct Run {
    events: Vec<(Target, f64, f64)>,
    line_done_at_x: Option<f64>,
}

/// The leader drives along y = 10 (+ a small weave) at 0.4 m/s; followers sit on their
/// slot points. Records each transformation with the leader's x and time.
fn drive(map: &Map, weave: f64) -> Run {
    drive_for(map, weave, 1000)
}

/// The path ahead (straight along the heading) and behind (driven, newest first).
fn paths(leader: PlanPose, driven: &[DVec2]) -> (Vec<DVec2>, Vec<DVec2>) {
    let dir = DVec2::new(leader.heading.cos(), leader.heading.sin());
    let ahead = (0..=80)
        .map(|i| leader.position + dir * (i as f64 * 0.25))
        .collect();
    let behind = std::iter::once(leader.position)
        .chain(driven.iter().rev().copied())
        .collect();
    (ahead, behind)
}

fn drive_for(map: &Map, weave: f64, steps: usize) -> Run {
    let mut fm = FormationManager::new(spec());
    let mut driven: Vec<DVec2> = Vec::new();
    let mut run = Run {
        events: vec![],
        line_done_at_x: None,
    };
    let dt = 0.1;
    for i in 0..steps {
        let t = i as f64 * dt;
        let x = 2.0 + 0.4 * t;
        let heading = weave * (t * 0.8).sin();
        let leader = PlanPose {
            position: DVec2::new(x, 10.0 + weave * (t * 0.8).cos()),
            heading,
        };
        let followers = at_their_slots(&fm, leader);
        let before = fm.transformations().len();
        let (ahead, behind) = paths(leader, &driven);
        let motion = LeaderMotion {
            pose: leader,
            v: 0.4,
            omega: weave * 0.8 * (t * 0.8).cos(),
        };
        fm.step(t, motion, &ahead, &behind, &followers, map);
        if driven
            .last()
            .is_none_or(|p| (*p - leader.position).length() >= 0.25)
        {
            driven.push(leader.position);
        }
        if fm.transformations().len() > before {
            run.events.push((fm.target(), t, x));
        }
        if fm.blend() >= 1.0 && run.line_done_at_x.is_none() {
            run.line_done_at_x = Some(x);
        }
    }
    run
}

#[test]
fn three_metre_gap_becomes_a_line_and_back() {
    let run = drive(&gap(3.0), 0.0);
    println!(
        "3 m gap: {:?}, line complete at x = {:?}",
        run.events, run.line_done_at_x
    );
    let targets: Vec<_> = run.events.iter().map(|e| e.0).collect();
    assert_eq!(targets, vec![Target::Line, Target::Wide]);
    // In line before the leader enters the gap at x = 12.
    assert!(run.line_done_at_x.unwrap() < 12.0);
    // Back to wide only after the last follower (3 m behind in the line) left at x = 18.
    assert!(run.events[1].2 - 3.0 > 18.0);
}

#[test]
fn six_metre_gap_stays_a_triangle() {
    let run = drive(&gap(6.0), 0.0);
    assert!(run.events.is_empty(), "{:?}", run.events);
}

#[test]
fn no_flapping_at_the_boundary() {
    // Widths around the threshold (3.6 m formation + 0.5 m margin), leader weaving.
    for width in [4.0, 4.05, 4.1, 4.15, 4.2, 4.4] {
        let run = drive(&gap(width), 0.15);
        assert!(run.events.len() <= 2, "width {width}: {:?}", run.events);
    }
}

#[test]
fn three_pinches_in_a_street_cost_at_most_two_changes_each() {
    // A 12 m wide street along y = 10 with three 3 m pinches, 2 m long, 12 m apart.
    let mut obstacles = vec![block(-20.0, 2.0, 80.0, 4.0), block(-20.0, 16.0, 80.0, 18.0)];
    for x in [12.0, 24.0, 36.0] {
        obstacles.push(block(x, 4.0, x + 2.0, 8.5));
        obstacles.push(block(x, 11.5, x + 2.0, 16.0));
    }
    let map = Map::new(obstacles);
    let run = drive_for(&map, 0.0, 1800);
    println!("pinches: {:?}", run.events);
    assert!(run.events.len() <= 6, "{:?}", run.events);
    assert_eq!(run.events.first().map(|e| e.0), Some(Target::Line));
    assert_eq!(
        run.events.last().map(|e| e.0),
        Some(Target::Wide),
        "never came back"
    );
}

#[test]
fn slots_move_without_jumps() {
    let mut fm = FormationManager::new(spec());
    let map = gap(3.0);
    let mut last: Option<Vec<DVec2>> = None;
    for i in 0..600 {
        let t = i as f64 * 0.1;
        let motion = straight_along_the_street(t);
        let leader = motion.pose;
        let (ahead, behind) = paths(leader, &[]);
        let followers = at_their_slots(&fm, leader);
        fm.step(t, motion, &ahead, &behind, &followers, &map);
        let pts = fm.slot_points(leader);
        if let Some(prev) = &last {
            for (a, b) in prev.iter().zip(&pts) {
                // Leader motion (0.04 m) plus the slot's own motion in one period.
                assert!((*a - *b).length() < 0.15, "jump at t = {t}");
            }
        }
        last = Some(pts);
    }
}

#[test]
fn v_slots_for_five_followers() {
    let s = FormationSpec {
        followers: 5,
        ..spec()
    };
    let slots = s.wide_slots();
    assert_eq!(slots.len(), 5);
    assert!((slots[0].0 - 3.0).abs() < 1e-12 && slots[0].1 > 0.0);
    assert!((slots[1].0 - 3.0).abs() < 1e-12 && slots[1].1 < 0.0);
    assert!((slots[2].0 - 6.0).abs() < 1e-12);
    assert!((slots[4].0 - 9.0).abs() < 1e-12);
    let line = s.line_slots();
    assert!((line[4].0 - 7.5).abs() < 1e-12);
    // 3.6 m for the paper's triangle: 2·3·sin 30° + 2·0.3.
    assert!((spec().wide_width() - 3.6).abs() < 1e-9);
}

/// A bin between follower 1's line slot and its wide slot, near neither: the wide slots
/// are free, the way to them is not.
#[test]
fn a_bin_on_the_way_back_to_the_wide_shape_is_seen() {
    let fm = FormationManager::new(spec());
    let leader = LeaderMotion {
        pose: PlanPose {
            position: DVec2::new(20.0, 10.0),
            heading: 0.0,
        },
        v: 0.4,
        omega: 0.0,
    };
    let behind: Vec<DVec2> = (0..=80)
        .map(|i| DVec2::new(20.0 - 0.25 * i as f64, 10.0))
        .collect();
    // Line slot (18.5, 10), wide slot (17.40, 11.5): the bin half way.
    let bin = Map::new(vec![Obstacle::Circle {
        center: DVec2::new(17.95, 10.75),
        radius: 0.2,
    }]);
    let need = fm.slot_need();
    assert!(!fm.wide_slot_blocked(&bin, leader, need));
    assert!(!fm.widening_clear(&bin, leader.pose, &behind, need));
    assert!(fm.widening_clear(&Map::new(vec![]), leader.pose, &behind, need));
}

/// Drives the leader at the 3 m gap (0.4 m/s along y = 10) until 4 s into the change
/// into the line; follower 1 reports itself at `hold` (where it stands, from the change's
/// start on) or at its slot point. Returns the blend then, when the change started and
/// follower 1's slot point then.
fn into_the_line(hold: Option<DVec2>, extra: Option<Obstacle>) -> (f64, f64, DVec2) {
    let mut fm = FormationManager::new(spec());
    let map = gap_and(3.0, extra);
    let mut driven: Vec<DVec2> = Vec::new();
    let mut started: Option<(f64, DVec2)> = None;
    for i in 0..400 {
        let t = i as f64 * 0.1;
        let motion = straight_along_the_street(t);
        let leader = motion.pose;
        let mut followers = at_their_slots(&fm, leader);
        if let (Some(at), Some(_)) = (hold, started) {
            followers[0] = Some(FollowerStatus {
                position: at,
                error: (at - fm.slot_points(leader)[0]).length(),
                joined: true,
                detouring: false,
            });
        }
        let (ahead, behind) = paths(leader, &driven);
        fm.step(t, motion, &ahead, &behind, &followers, &map);
        driven.push(leader.position);
        if started.is_none() && fm.target() == Target::Line {
            started = Some((t, fm.slot_points(leader)[0]));
        }
        if let Some((t0, slot)) = started.filter(|(t0, _)| t - t0 >= 4.0) {
            return (fm.blend(), t0, slot);
        }
    }
    panic!("no change into the line");
}

/// A follower falling behind on a clear way is waited for; one held behind a bin is not:
/// only the change takes its reference off the bin's far side.
#[test]
fn a_shape_change_waits_for_a_follower_falling_behind_on_a_clear_way() {
    let (on_time, t0, slot) = into_the_line(None, None);
    assert!(on_time > 0.9, "{on_time}");
    // Follower 1 stands 3 m behind and 1.5 m out from where its slot was at the start.
    let at = slot + DVec2::new(-3.0, 1.5);
    let (waited, t1, _) = into_the_line(Some(at), None);
    assert_eq!(t0, t1);
    assert!(waited < 0.1, "{waited}");
    // A bin 0.6 m from it toward its slot: it is held, and the change goes on.
    let bin = Obstacle::Circle {
        center: at + (slot - at).normalize() * 0.6,
        radius: 0.3,
    };
    let (held, t2, _) = into_the_line(Some(at), Some(bin));
    assert_eq!(t0, t2);
    assert!(held > 0.9, "{held}");
}

/// Into the line the rear slots move forward relative to the leader at up to
/// `slot_speed`, and the leader's own speed comes on top: the change slows so that no
/// slot point moves faster than the top speed in the world.
#[test]
fn a_shape_change_keeps_every_slot_point_under_the_top_speed() {
    // The rear slots' 4.5 m across at `slot_speed` 0.8 m/s, with the leader's 0.4 m/s
    // forward: 0.89 m/s at full pace.
    let s = FormationSpec {
        followers: 5,
        top_speed: 0.85,
        ..spec()
    };
    let mut fm = FormationManager::new(s.clone());
    let map = gap(3.0);
    let mut driven: Vec<DVec2> = Vec::new();
    let mut last: Option<Vec<DVec2>> = None;
    let mut fastest = 0.0f64;
    for i in 0..600 {
        let t = i as f64 * 0.1;
        let motion = straight_along_the_street(t);
        let leader = motion.pose;
        let (ahead, behind) = paths(leader, &driven);
        let followers = at_their_slots(&fm, leader);
        fm.step(t, motion, &ahead, &behind, &followers, &map);
        driven.push(leader.position);
        let points = fm.slot_points(leader);
        if let Some(prev) = &last {
            for (a, b) in prev.iter().zip(&points) {
                fastest = fastest.max((*b - *a).length() / 0.1);
            }
        }
        last = Some(points);
    }
    let changes = fm.transformations();
    assert!(changes[0].end_s.is_some(), "{changes:?}");
    assert!(fastest <= s.top_speed + 0.02, "{fastest}");
}

/// Rows of three behind the leader: seven followers in rows of 3, 3 and 1, each row
/// centred on the leader's path, `line_spacing` apart across and between rows; the width
/// is the widest row's.
#[test]
fn rows_sit_centred_behind_the_leader_row_by_row() {
    let s = FormationSpec {
        wide: WideShape::Rows {
            per_row: 3,
            spacing: 1.5,
        },
        followers: 7,
        ..spec()
    };
    let points: Vec<DVec2> = s
        .wide_slots()
        .into_iter()
        .map(|(l, phi)| DVec2::new(l * phi.cos(), l * phi.sin()))
        .collect();
    let want = [
        (-1.5, -1.5),
        (-1.5, 0.0),
        (-1.5, 1.5),
        (-3.0, -1.5),
        (-3.0, 0.0),
        (-3.0, 1.5),
        (-4.5, 0.0),
    ];
    for (p, (x, y)) in points.iter().zip(want) {
        assert!(
            p.distance(DVec2::new(x, y)) < 1e-9,
            "{p} against ({x}, {y})"
        );
    }
    assert!((s.wide_width() - (3.0 + 2.0 * 0.3)).abs() < 1e-9);
    // An even last row is centred too: followers 7 and 8 of 8 at ±0.75 m.
    let s = FormationSpec { followers: 8, ..s };
    let (l, phi) = s.wide_slots()[7];
    assert!((l * phi.sin() - 0.75).abs() < 1e-9 && (l * phi.cos() + 4.5).abs() < 1e-9);
}
