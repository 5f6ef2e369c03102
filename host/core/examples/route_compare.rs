//! Our route planner on the maps of `scripts/compare-pythonrobotics.sh`, beside
//! PythonRobotics' `potential_field_planning`: writes the maps (JSON, for the Python side)
//! and our results. Not run on its own: the script calls it.
//!
//! `cargo run --release -p base-station --example route_compare -- OUT_DIR`

use std::path::{Path, PathBuf};
use std::time::Instant;

use base_station::geometry::map::Map;
use base_station::geometry::Obstacle;
use base_station::planner::route::{RouteParams, RoutePlanner};
use base_station::scenario::Scenario;
use glam::DVec2;
use serde_json::json;

#[path = "../benches/common/sites.rs"]
mod sites;

/// Robot footprint radius, m (the shipped robots').
const FOOTPRINT: f64 = 0.3;

struct Case {
    name: String,
    map: Map,
    start: DVec2,
    goal: DVec2,
    /// PythonRobotics' grid and repulsion range, m.
    reso: f64,
    rr: f64,
}

fn cases() -> Vec<Case> {
    let mut out = Vec::new();
    // PythonRobotics' own map (its `main()`): four point obstacles, here 0.25 m poles.
    let own = [(15.0, 25.0), (5.0, 15.0), (20.0, 26.0), (25.0, 25.0)];
    out.push(Case {
        name: "pythonrobotics-own".into(),
        map: Map::new(
            own.iter()
                .map(|&(x, y)| Obstacle::Circle {
                    center: DVec2::new(x, y),
                    radius: 0.25,
                })
                .collect(),
        ),
        start: DVec2::new(0.0, 10.0),
        goal: DVec2::new(30.0, 30.0),
        reso: 0.5,
        rr: 5.0,
    });
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios/paper-obstacles.toml");
    let paper = Scenario::load(&path).expect("the shipped scenario loads");
    let start = DVec2::new(paper.leader().start.x, paper.leader().start.y);
    let goal = *paper.route.points().last().expect("a goal");
    out.push(Case {
        name: "paper-obstacles".into(),
        map: paper.build_map(),
        start,
        goal,
        reso: 0.5,
        rr: 2.0,
    });
    // The paper's start and goal with 100 thin poles scattered between them.
    let mut rng = sites::Rng::new(7);
    let (lo, hi) = (start.min(goal), start.max(goal));
    let mut poles = Vec::new();
    while poles.len() < 100 {
        let c = lo + (hi - lo) * DVec2::new(rng.next(), rng.next());
        if (c - start).length() > 1.5 && (c - goal).length() > 1.5 {
            poles.push(Obstacle::Circle {
                center: c,
                radius: 0.1,
            });
        }
    }
    out.push(Case {
        name: "paper-100-poles".into(),
        map: Map::new(poles),
        start,
        goal,
        reso: 0.5,
        rr: 2.0,
    });
    for n in [100, 1_000] {
        out.push(Case {
            name: format!("site-100m-{n}"),
            map: sites::site(n, 1),
            start: sites::START,
            goal: sites::GOAL,
            reso: 0.5,
            rr: 2.0,
        });
    }
    out
}

/// Points along an obstacle's outline every `step` m: what a point-obstacle planner sees.
fn outline(o: &Obstacle, step: f64) -> Vec<[f64; 2]> {
    let along = |a: DVec2, b: DVec2| {
        let n = ((b - a).length() / step).ceil().max(1.0) as usize;
        (0..n)
            .map(|k| a.lerp(b, k as f64 / n as f64))
            .map(|p| [p.x, p.y])
            .collect::<Vec<_>>()
    };
    match o {
        Obstacle::Circle { center, radius } => {
            let n = ((std::f64::consts::TAU * radius / step).ceil() as usize).max(4);
            (0..n)
                .map(|k| {
                    *center
                        + DVec2::from_angle(k as f64 / n as f64 * std::f64::consts::TAU) * *radius
                })
                .map(|p| [p.x, p.y])
                .collect()
        }
        Obstacle::Segment { a, b } => {
            let mut v = along(*a, *b);
            v.push([b.x, b.y]);
            v
        }
        Obstacle::Polygon { points } => (0..points.len())
            .flat_map(|i| along(points[i], points[(i + 1) % points.len()]))
            .collect(),
    }
}

fn main() {
    let out_dir = PathBuf::from(
        std::env::args()
            .nth(1)
            .expect("usage: route_compare OUT_DIR"),
    );
    std::fs::create_dir_all(&out_dir).expect("the output directory");
    let params = RouteParams::for_fleet(FOOTPRINT, 3.6, 0.5);
    let mut maps = Vec::new();
    let mut results = Vec::new();
    for case in cases() {
        // Median of 5 of everything: the grid from the map, then the route.
        let mut times = Vec::new();
        let mut outcome = None;
        for _ in 0..5 {
            let t0 = Instant::now();
            let rp = RoutePlanner::new(&case.map, &[case.start, case.goal], params);
            let r = rp.plan(case.start, case.goal, &[]);
            times.push(t0.elapsed().as_secs_f64() * 1e3);
            outcome = Some(r);
        }
        times.sort_by(f64::total_cmp);
        // The truth, whatever the planner says: the route ends at the goal and keeps the
        // robot off every obstacle all along.
        let (said, reached, min_clear) = match outcome.expect("ran") {
            Ok(route) => {
                let ends = (*route.points.last().expect("a point") - case.goal).length() < 1e-6;
                let clear = route
                    .sample(0.0, route.length(), 0.02)
                    .iter()
                    .map(|p| case.map.clearance(*p, 10.0))
                    .fold(f64::INFINITY, f64::min);
                (true, ends && clear >= FOOTPRINT, clear)
            }
            Err(_) => (false, false, f64::NAN),
        };
        results.push(json!({
            "name": case.name,
            "ms": times[2],
            "said_goal": said,
            "reached_goal": reached,
            "min_clearance_m": min_clear,
        }));
        let points: Vec<[f64; 2]> = case
            .map
            .obstacles()
            .iter()
            .flat_map(|o| outline(o, case.reso))
            .collect();
        maps.push(json!({
            "name": case.name,
            "start": [case.start.x, case.start.y],
            "goal": [case.goal.x, case.goal.y],
            "reso": case.reso,
            "rr": case.rr,
            "footprint": FOOTPRINT,
            "points": points,
            "obstacles": case.map.obstacles(),
        }));
    }
    let write = |name: &str, v: serde_json::Value| {
        let p = out_dir.join(name);
        std::fs::write(&p, serde_json::to_string(&v).expect("json")).expect("write");
    };
    write("maps.json", json!(maps));
    write("ours.json", json!(results));
}
