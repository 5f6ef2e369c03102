//! The paper's two scenarios, simulated at the default realism (50 ms latency, 5 % loss,
//! σ = 2 cm pose noise, motor lag), with the paper's gains: the bounds of the hil-sim issue.

mod common;

use common::{assert_paper_bounds, run, shipped};

#[test]
fn paper_obstacles_meets_the_bounds() {
    let (r, _) = run(shipped("paper-obstacles"), 1);
    println!("{}", serde_json::to_string_pretty(&r).unwrap());
    assert_paper_bounds(&r);
}

#[test]
fn paper_passage_meets_the_bounds_and_changes_shape_around_the_gap() {
    let (r, world) = run(shipped("paper-passage"), 1);
    println!("{}", serde_json::to_string_pretty(&r).unwrap());
    assert_paper_bounds(&r);

    let shapes: Vec<&str> = r.transformations.iter().map(|t| t.to.as_str()).collect();
    assert_eq!(shapes, ["line", "triangle"]);
    for t in &r.transformations {
        let d = t.duration_s.expect("every transformation completes");
        assert!(d <= 5.0, "transformation to {} took {d} s", t.to);
    }
    // A line before the gap (x = 12), all the way through it (to x = 18 + 3 m of line).
    let samples = &world.recorder.samples;
    let leader = world.robots.iter().position(|x| x.id == 0).unwrap();
    for s in samples.iter() {
        let x = s.robots[leader].x;
        if (12.0..=21.0).contains(&x) {
            assert!(
                s.blend >= 1.0,
                "not yet a line at x = {x:.2} (blend {:.2})",
                s.blend
            );
        }
    }
    // A triangle again only once every follower has left the gap.
    let back = r.transformations[1].start_s;
    let at = samples.iter().find(|s| s.t >= back).unwrap();
    for (i, robot) in world.robots.iter().enumerate() {
        if robot.id != 0 {
            assert!(
                at.robots[i].x > 18.0,
                "follower {} still in the gap",
                robot.id
            );
        }
    }
    let end = samples.last().unwrap();
    assert_eq!(end.blend, 0.0, "back to the triangle at the end");
}

#[test]
fn the_same_seed_gives_the_same_report() {
    let strip = |mut r: hil_sim::report::Report| {
        r.wall_time_s = 0.0;
        serde_json::to_string(&r).unwrap()
    };
    for name in ["paper-obstacles", "paper-passage"] {
        let (a, _) = run(shipped(name), 7);
        let (b, _) = run(shipped(name), 7);
        assert_eq!(
            strip(a.clone()),
            strip(b),
            "{name}: two runs of seed 7 differ"
        );
        let (c, _) = run(shipped(name), 8);
        assert_ne!(strip(a), strip(c), "{name}: the seed changes nothing?");
    }
}

#[test]
fn five_followers_in_a_v_reach_the_goal_without_contact() {
    let mut s = shipped("paper-obstacles");
    s.formation.shape = base_station::scenario::ShapeName::V;
    let template = s.robots[2].clone();
    for (id, (x, y)) in [(3u16, (-6.0, -2.0)), (4, (-3.0, -6.0)), (5, (-7.0, -5.0))] {
        let mut r = template.clone();
        r.id = id;
        r.start.x = x;
        r.start.y = y;
        r.start.heading_deg = 45.0;
        s.robots.push(r);
    }
    s.validate().expect("valid");
    let (r, _) = run(s, 1);
    println!("{}", serde_json::to_string_pretty(&r).unwrap());
    assert!(r.goal_reached);
    assert_eq!(r.collisions, 0);
    assert_eq!(r.robots.len(), 6);
}
