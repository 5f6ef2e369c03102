//! Generated site maps for the route benchmarks: a 100 × 100 m site with `n` obstacles
//! (bins, blocks and wall pieces) at a density that leaves a way, seeded.

use base_station::geometry::map::Map;
use base_station::geometry::Obstacle;
use glam::DVec2;

pub const SIDE: f64 = 100.0;
pub const START: DVec2 = DVec2::new(2.0, 2.0);
pub const GOAL: DVec2 = DVec2::new(98.0, 98.0);

/// A xorshift stream in [0, 1).
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1)
    }

    pub fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// `n` obstacles on the 100 × 100 m site; their size shrinks as √(area / n) so that about
/// a tenth of the site is covered whatever `n` (10,000 obstacles are poles and bollards).
/// Nothing within 3 m of the start or the goal.
pub fn site(n: usize, seed: u64) -> Map {
    let mut rng = Rng::new(seed);
    let scale = (SIDE * SIDE / n as f64).sqrt() / 10.0_f64.sqrt();
    let mut obstacles = Vec::with_capacity(n);
    while obstacles.len() < n {
        let c = DVec2::new(rng.next() * SIDE, rng.next() * SIDE);
        if (c - START).length() < 3.0 || (c - GOAL).length() < 3.0 {
            continue;
        }
        let kind = rng.next();
        let o = if kind < 0.6 {
            Obstacle::Circle {
                center: c,
                radius: scale * (0.3 + 0.4 * rng.next()),
            }
        } else if kind < 0.85 {
            let (w, h) = (scale * (0.5 + rng.next()), scale * (0.5 + rng.next()));
            Obstacle::Polygon {
                points: vec![
                    c + DVec2::new(-w, -h) * 0.5,
                    c + DVec2::new(w, -h) * 0.5,
                    c + DVec2::new(w, h) * 0.5,
                    c + DVec2::new(-w, h) * 0.5,
                ],
            }
        } else {
            let a = rng.next() * std::f64::consts::TAU;
            let half = DVec2::from_angle(a) * scale * (0.5 + rng.next());
            Obstacle::Segment {
                a: c - half,
                b: c + half,
            }
        };
        obstacles.push(o);
    }
    Map::new(obstacles)
}
