//! Coverage planning of one area from scratch (scan lines against the grown obstacles,
//! cells, their order, the run-on of each pass): a 100 × 100 m area (10,000 m²) with
//! 0, 100 and 500 obstacles (bins, blocks and wall pieces, about a tenth of the ground),
//! for the sweeping triangle (a 2 m swath, passes 1.9 m apart).
//! `cargo bench -p base-station --bench coverage_plan`.

use std::hint::black_box;

use base_station::coverage::plan::{plan_area, SweepParams};
use base_station::geometry::map::Map;
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use glam::DVec2;

#[path = "common/sites.rs"]
mod sites;

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("coverage_plan");
    group.sample_size(20);
    let area = [
        DVec2::ZERO,
        DVec2::new(sites::SIDE, 0.0),
        DVec2::new(sites::SIDE, sites::SIDE),
        DVec2::new(0.0, sites::SIDE),
    ];
    let params = SweepParams {
        swath: 2.0,
        spacing: 1.9,
        clearance: 0.49,
        trail: 1.13,
        direction: None,
    };
    for n in [0usize, 100, 500] {
        let map = if n == 0 {
            Map::new(Vec::new())
        } else {
            sites::site(n, 1)
        };
        group.bench_with_input(BenchmarkId::new("10000m2", n), &n, |b, _| {
            b.iter(|| black_box(plan_area(&area, &map, &params, sites::START).passes.len()))
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
