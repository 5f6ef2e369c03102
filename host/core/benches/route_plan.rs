//! Route planning from scratch (the clearance grid of the map, then A* and string pulling)
//! on the paper's map and on 100 × 100 m sites with 100, 1,000 and 10,000 obstacles.
//! `cargo bench -p base-station --bench route_plan`.

use std::hint::black_box;
use std::path::Path;

use base_station::planner::route::{RouteParams, RoutePlanner};
use base_station::scenario::Scenario;
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use glam::DVec2;

#[path = "common/sites.rs"]
mod sites;

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("route_plan");
    group.sample_size(20);

    let path = format!(
        "{}/../../scenarios/paper-obstacles.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let paper = Scenario::load(Path::new(&path)).expect("the shipped scenario loads");
    let map = paper.build_map();
    let params = RouteParams::for_formation(&paper.formation_spec());
    let start = DVec2::new(paper.leader().start.x, paper.leader().start.y);
    let mut points = vec![start];
    points.extend(paper.route.points());
    let goal = *points.last().expect("a goal");
    group.bench_function("paper-obstacles", |b| {
        b.iter(|| {
            let rp = RoutePlanner::new(&map, &points, params);
            black_box(
                rp.plan(start, goal, &[])
                    .expect("the paper's map has a way"),
            )
        })
    });

    let params = RouteParams::for_fleet(0.3, 3.6, 0.5);
    for n in [100usize, 1_000, 10_000] {
        let map = sites::site(n, 1);
        let ends = [sites::START, sites::GOAL];
        group.bench_with_input(BenchmarkId::new("site-100m", n), &n, |b, _| {
            b.iter(|| {
                let rp = RoutePlanner::new(&map, &ends, params);
                black_box(rp.plan(sites::START, sites::GOAL, &[]).is_ok())
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
