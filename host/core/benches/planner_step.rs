//! One planner step (the leader inflated to the triangle's width) with 10, 1,000 and 10,000 obstacles. `cargo bench -p host --bench planner_step`.

use std::hint::black_box;

use base_station::geometry::map::Map;
use base_station::geometry::Obstacle;
use base_station::planner::{PlanPose, Planner, PlannerParams};
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use glam::DVec2;

/// `n` poles spread over a square whose side grows with √n (constant density, like a
/// city district), seeded.
fn map(n: usize) -> (Map, f64) {
    let side = (n as f64).sqrt() * 10.0;
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let obstacles = (0..n)
        .map(|_| Obstacle::Circle {
            center: DVec2::new(next() * side, next() * side),
            radius: 0.2 + 0.4 * next(),
        })
        .collect();
    (Map::new(obstacles), side)
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("planner_step");
    for n in [10usize, 1_000, 10_000] {
        let (map, side) = map(n);
        // A goal far outside the map: the planner never arrives.
        let mut planner = Planner::new(PlannerParams::DEFAULT, vec![DVec2::splat(-1e4)], 0.4);
        let mut t = 0.0;
        group.bench_with_input(BenchmarkId::from_parameter(n), &n, |b, _| {
            b.iter(|| {
                t += 0.1;
                // Move the query point around so caches do not flatter the index.
                let p = DVec2::new((t * 0.37) % side, (t * 0.61) % side);
                let pose = PlanPose {
                    position: p,
                    heading: 0.7,
                };
                // The paper's triangle: 1.5 m lateral half-width.
                black_box(planner.step(t, 0.1, pose, &map, 1.5, 1.0))
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
