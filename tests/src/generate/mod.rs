//! Maps nobody tuned for: scenario generators, one seed each. Each returns the scenario
//! as TOML text (the parser is part of what is tested) and, by construction, whether a
//! way exists for the fleet.

use std::fmt::Write as _;

pub mod movers;
pub mod sweeps;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A generated scenario and what it must do.
pub struct Generated {
    pub name: String,
    pub toml: String,
    /// A way exists by construction (else the scenario must be refused up front).
    pub way: bool,
}

impl Generated {
    /// Writes the world to `target/FOLDER/NAME.toml` (to `basestation sim` it when a suite
    /// fails on it); its path.
    pub fn save(&self, folder: &str) -> String {
        let dir = format!("{}/../target/{folder}", env!("CARGO_MANIFEST_DIR"));
        let _ = std::fs::create_dir_all(&dir);
        let path = format!("{dir}/{}.toml", self.name);
        let _ = std::fs::write(&path, &self.toml);
        path
    }

    /// The same world with its formation in rows of `per_row` abreast instead of its V
    /// (or triangle).
    pub fn in_rows(mut self, per_row: usize) -> Result<Self, String> {
        let shape = ["shape = \"v\"", "shape = \"triangle\""]
            .into_iter()
            .find(|s| self.toml.contains(s))
            .ok_or_else(|| format!("{}: names no V or triangle to put in rows", self.name))?;
        let rows = format!("shape = \"rows\"\nper_row = {per_row}");
        self.toml = self.toml.replacen(shape, &rows, 1);
        Ok(self)
    }
}

/// The seeds a suite runs: `count_var` of them (default `default_count`) from
/// `first_var` (default 1; fresh worlds start at any other).
pub fn seeds(
    first_var: &str,
    count_var: &str,
    default_count: u64,
) -> std::ops::RangeInclusive<u64> {
    let var = |name: &str, default: u64| {
        std::env::var(name)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(default)
    };
    let (first, n) = (var(first_var, 1), var(count_var, default_count));
    first..=first + n.max(1) - 1
}

struct Builder {
    obstacles: Vec<String>,
    /// On the site, not on the map.
    unmapped: Vec<String>,
    robots: Vec<(f64, f64, f64)>,
    bounds: Option<([f64; 2], [f64; 2])>,
    waypoints: Vec<[f64; 2]>,
    goal: [f64; 2],
    shape: &'static str,
    /// More tables, as TOML (`[[movers]]`, `[[crowds]]`).
    tables: String,
    duration_s: f64,
}

impl Builder {
    fn new(goal: [f64; 2]) -> Self {
        Self {
            obstacles: Vec::new(),
            unmapped: Vec::new(),
            robots: Vec::new(),
            bounds: None,
            waypoints: Vec::new(),
            goal,
            shape: "triangle",
            tables: String::new(),
            duration_s: 400.0,
        }
    }

    fn circle(&mut self, c: [f64; 2], r: f64) {
        self.obstacles.push(format!(
            "{{ kind = \"circle\", center = [{:.3}, {:.3}], radius = {r:.3} }}",
            c[0], c[1]
        ));
    }

    fn rect(&mut self, lo: [f64; 2], hi: [f64; 2]) {
        self.obstacles.push(format!(
            "{{ kind = \"rectangle\", min = [{:.3}, {:.3}], max = [{:.3}, {:.3}] }}",
            lo[0], lo[1], hi[0], hi[1]
        ));
    }

    /// A rectangle on the site that the map does not hold.
    fn unmapped_rect(&mut self, lo: [f64; 2], hi: [f64; 2]) {
        self.rect(lo, hi);
        let r = self.obstacles.pop().expect("just pushed");
        self.unmapped.push(r);
    }

    fn polygon(&mut self, pts: &[[f64; 2]]) {
        let p: Vec<String> = pts
            .iter()
            .map(|p| format!("[{:.3}, {:.3}]", p[0], p[1]))
            .collect();
        self.obstacles.push(format!(
            "{{ kind = \"polygon\", points = [{}] }}",
            p.join(", ")
        ));
    }

    /// The leader at `leader` heading `deg`; `followers` V slots behind it (or `starts`).
    fn fleet(&mut self, leader: [f64; 2], deg: f64, followers: usize) {
        self.robots.push((leader[0], leader[1], deg));
        let h = deg.to_radians();
        for k in 0..followers {
            let rank = (k / 2 + 1) as f64;
            let side = if k % 2 == 0 { 1.0 } else { -1.0 };
            let a = h + side * 150f64.to_radians();
            // The slot is for the control point, 0.2 m ahead of the axle.
            let x = leader[0] + rank * 3.0 * a.cos() - 0.2 * h.cos();
            let y = leader[1] + rank * 3.0 * a.sin() - 0.2 * h.sin();
            self.robots.push((x, y, deg));
        }
        if followers > 2 {
            self.shape = "v";
        }
    }

    /// The leader at `leader` heading `deg`, `followers` in a line 1.5 m apart behind it.
    fn fleet_in_line(&mut self, leader: [f64; 2], deg: f64, followers: usize) {
        self.robots.push((leader[0], leader[1], deg));
        let h = deg.to_radians();
        for k in 1..=followers {
            let back = 1.5 * k as f64 + 0.2;
            self.robots
                .push((leader[0] - back * h.cos(), leader[1] - back * h.sin(), deg));
        }
        if followers > 2 {
            self.shape = "v";
        }
    }

    fn build(&self, name: &str, way: bool) -> Generated {
        let mut t = String::new();
        let _ = writeln!(t, "name = \"{name}\"\n[map]");
        if let Some((lo, hi)) = self.bounds {
            let _ = writeln!(
                t,
                "bounds = {{ min = [{:.3}, {:.3}], max = [{:.3}, {:.3}] }}",
                lo[0], lo[1], hi[0], hi[1]
            );
        }
        let _ = writeln!(t, "obstacles = [\n  {}\n]", self.obstacles.join(",\n  "));
        if !self.unmapped.is_empty() {
            let _ = writeln!(t, "unmapped = [\n  {}\n]", self.unmapped.join(",\n  "));
        }
        for (i, (x, y, h)) in self.robots.iter().enumerate() {
            let role = if i == 0 { "leader" } else { "follower" };
            let _ = writeln!(
                t,
                "[[robots]]\nid = {i}\nrole = \"{role}\"\nstart = {{ x = {x:.3}, y = {y:.3}, heading_deg = {h:.1} }}"
            );
        }
        let _ = writeln!(t, "[formation]\nshape = \"{}\"", self.shape);
        let wps: Vec<String> = self
            .waypoints
            .iter()
            .map(|p| format!("[{:.3}, {:.3}]", p[0], p[1]))
            .collect();
        let _ = writeln!(
            t,
            "[route]\nwaypoints = [{}]\ngoal = [{:.3}, {:.3}]",
            wps.join(", "),
            self.goal[0],
            self.goal[1]
        );
        let _ = writeln!(t, "[sim]\nduration_s = {:.1}", self.duration_s);
        t.push_str(&self.tables);
        Generated {
            name: name.to_string(),
            toml: t,
            way,
        }
    }
}

fn rng(kind: u64, seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(kind.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ seed)
}

/// Bins scattered over a 50 × 30 m site, a corridor ≥ `corridor` m wide kept free along a
/// random polyline from the start to the goal (so a way exists).
pub fn bin_field(seed: u64, bins: usize, followers: usize) -> Generated {
    let mut r = rng(1, seed);
    let mut b = Builder::new([46.0, r.random_range(5.0..25.0)]);
    b.bounds = Some(([-8.0, -2.0], [52.0, 32.0]));
    let start = [2.0, r.random_range(8.0..22.0)];
    let mid = [
        [17.0, r.random_range(4.0..26.0)],
        [32.0, r.random_range(4.0..26.0)],
    ];
    let way = [start, mid[0], mid[1], b.goal];
    let dist_to_way = |p: [f64; 2]| {
        way.windows(2)
            .map(|w| {
                let (a, c) = (glam::DVec2::from(w[0]), glam::DVec2::from(w[1]));
                let q = glam::DVec2::from(p);
                let t = ((q - a).dot(c - a) / (c - a).length_squared()).clamp(0.0, 1.0);
                (q - (a + (c - a) * t)).length()
            })
            .fold(f64::INFINITY, f64::min)
    };
    let mut placed = 0;
    while placed < bins {
        let c = [r.random_range(0.0..50.0), r.random_range(0.0..30.0)];
        let rad = r.random_range(0.3..0.6);
        // Keep a 2.2 m half-corridor free (the line passes; the V sometimes), and the starts.
        if dist_to_way(c) < 2.2 + rad
            || (c[0] - start[0]).abs() < 8.0 && (c[1] - start[1]).abs() < 5.0
        {
            continue;
        }
        b.circle(c, rad);
        placed += 1;
    }
    b.fleet(start, 0.0, followers);
    b.build(&format!("bin-field-{bins}-{followers}f-seed{seed}"), true)
}

/// An open lot 60 m long with a dozen bins off a bent way, sized for the fleet: its V
/// (any number of followers) starts at the lot's near edge however deep it is.
pub fn open_lot(seed: u64, followers: usize) -> Generated {
    let mut r = rng(9, seed);
    let ranks = followers.div_ceil(2) as f64;
    // A V's rank k sits 3k m from the leader at 150°: depth 2.6k, half-width 1.5k.
    let (depth, half) = (2.6 * ranks + 3.0, 1.5 * ranks + 3.0);
    let width = 30.0_f64.max(2.0 * half + 10.0);
    let mut b = Builder::new([60.0, r.random_range(0.3..0.7) * width]);
    b.bounds = Some(([-depth - 2.0, -2.0], [66.0, width + 2.0]));
    let start = [2.0, width / 2.0];
    let mid = [30.0, r.random_range(0.25..0.75) * width];
    b.waypoints.push(mid);
    let way = [start, mid, b.goal];
    let near_way = |p: glam::DVec2, m: f64| {
        way.windows(2).any(|w| {
            let (a, c) = (glam::DVec2::from(w[0]), glam::DVec2::from(w[1]));
            let t = ((p - a).dot(c - a) / (c - a).length_squared()).clamp(0.0, 1.0);
            (p - (a + (c - a) * t)).length() < m
        })
    };
    let mut placed = 0;
    while placed < 12 {
        let c = glam::DVec2::new(r.random_range(12.0..60.0), r.random_range(0.0..width));
        // Clear of the V's whole width along the way.
        if !near_way(c, half + 1.0) {
            b.circle([c.x, c.y], r.random_range(0.3..0.6));
            placed += 1;
        }
    }
    b.fleet(start, 0.0, followers);
    b.duration_s = 300.0;
    b.build(&format!("open-lot-{followers}f-seed{seed}"), true)
}

/// A street 9–12 m wide with two or three bends and pinches down to 2.4–3.5 m.
pub fn street(seed: u64, followers: usize) -> Generated {
    let mut r = rng(2, seed);
    let width: f64 = r.random_range(9.0..12.0);
    let half = width / 2.0;
    let pts = centre_line(&mut r, followers);
    let mut b = Builder::new({
        let g = pts[pts.len() - 1] - (pts[pts.len() - 1] - pts[pts.len() - 2]).normalize() * 4.0;
        [g.x, g.y]
    });
    street_walls(&mut b, &pts, half);
    pinches(&mut b, &mut r, &pts, half);
    let start = pts[0] + (pts[1] - pts[0]).normalize() * (5.0 + 1.5 * followers as f64);
    let deg = (pts[1] - pts[0]).y.atan2((pts[1] - pts[0]).x).to_degrees();
    if followers > 2 {
        // A V this wide does not fit the street: the fleet starts in its line.
        b.fleet_in_line([start.x, start.y], deg, followers);
    } else {
        b.fleet([start.x, start.y], deg, followers);
    }
    b.build(&format!("street-{followers}f-seed{seed}"), true)
}

/// A street's centre line: legs of 14–20 m turning by ±20–45°, the first longer by the
/// formation's length.
fn centre_line(r: &mut ChaCha8Rng, followers: usize) -> Vec<glam::DVec2> {
    let mut pts = vec![glam::DVec2::new(0.0, 0.0)];
    let mut heading: f64 = 0.0;
    let legs = r.random_range(3..=4);
    for _ in 0..legs {
        let extra = if pts.len() == 1 {
            1.5 * followers as f64
        } else {
            0.0
        };
        let len = r.random_range(14.0..20.0) + extra;
        let p = *pts.last().unwrap() + glam::DVec2::new(heading.cos(), heading.sin()) * len;
        pts.push(p);
        let turn: f64 = r.random_range(20.0f64..45.0).to_radians();
        heading += if r.random_bool(0.5) { turn } else { -turn };
        heading = heading.clamp(-1.2, 1.2);
    }
    pts
}

/// The unit normal at centre-line point `i`, mitred at the joints.
fn mitred_normal(pts: &[glam::DVec2], i: usize) -> glam::DVec2 {
    let d_in = if i > 0 {
        (pts[i] - pts[i - 1]).normalize()
    } else {
        (pts[1] - pts[0]).normalize()
    };
    let d_out = if i + 1 < pts.len() {
        (pts[i + 1] - pts[i]).normalize()
    } else {
        d_in
    };
    let n = (d_in + d_out).normalize().perp();
    n / n.dot(d_in.perp()).max(0.5)
}

/// Each leg's two sides as quadrilaterals 1 m thick, mitred at the joints, `half` the
/// street's width off its centre line; the ends closed.
fn street_walls(b: &mut Builder, pts: &[glam::DVec2], half: f64) {
    for i in 0..pts.len() - 1 {
        for side in [1.0, -1.0] {
            let a = pts[i] + mitred_normal(pts, i) * half * side;
            let c = pts[i + 1] + mitred_normal(pts, i + 1) * half * side;
            let a2 = pts[i] + mitred_normal(pts, i) * (half + 1.0) * side;
            let c2 = pts[i + 1] + mitred_normal(pts, i + 1) * (half + 1.0) * side;
            b.polygon(&[[a.x, a.y], [c.x, c.y], [c2.x, c2.y], [a2.x, a2.y]]);
        }
    }
    for (i, j) in [(0, 1), (pts.len() - 1, pts.len() - 2)] {
        let d = (pts[i] - pts[j]).normalize();
        let n = mitred_normal(pts, i);
        let a = pts[i] + n * (half + 1.0) + d * 0.2;
        let c = pts[i] - n * (half + 1.0) + d * 0.2;
        b.polygon(&[
            [a.x, a.y],
            [c.x, c.y],
            [(c + d).x, (c + d).y],
            [(a + d).x, (a + d).y],
        ]);
    }
}

/// One to three pinches on straight stretches: blocks from both walls leaving 2.4–3.5 m.
fn pinches(b: &mut Builder, r: &mut ChaCha8Rng, pts: &[glam::DVec2], half: f64) {
    let pinches = r.random_range(1..=3);
    for k in 0..pinches {
        let leg = 1 + k % (pts.len() - 2).max(1);
        let (p0, p1) = (pts[leg], pts[leg + 1]);
        let d = (p1 - p0).normalize();
        let at = p0 + d * r.random_range(5.0..9.0);
        let gap: f64 = r.random_range(2.4..3.5);
        let shift = r.random_range(-1.0..1.0);
        let n = d.perp();
        for side in [1.0, -1.0] {
            let inner = gap / 2.0 + side * shift;
            let q0 = at + n * side * inner.abs().max(gap / 2.0 - 1.0);
            let q1 = at + n * side * (half + 0.5);
            let len = r.random_range(1.0..3.0);
            b.polygon(&[
                [q0.x, q0.y],
                [(q0 + d * len).x, (q0 + d * len).y],
                [(q1 + d * len).x, (q1 + d * len).y],
                [q1.x, q1.y],
            ]);
        }
    }
}

/// An open field with a bin right on the leader's way, 3–6 m ahead.
pub fn bin_on_the_line(seed: u64) -> Generated {
    let mut r = rng(3, seed);
    let mut b = Builder::new([40.0, r.random_range(-1.0..1.0)]);
    b.circle(
        [r.random_range(5.0..8.0), r.random_range(-0.3..0.3)],
        r.random_range(0.3..0.6),
    );
    b.fleet([2.0, 0.0], 0.0, 2);
    b.build(&format!("bin-on-the-line-seed{seed}"), true)
}

/// Followers scattered 8–15 m from the leader on both sides, facing anywhere; two bins.
pub fn scattered_starts(seed: u64) -> Generated {
    let mut r = rng(4, seed);
    let mut b = Builder::new([35.0, 0.0]);
    b.circle([14.0, r.random_range(-6.0..6.0)], 0.5);
    b.circle([24.0, r.random_range(-6.0..6.0)], 0.5);
    b.robots.push((0.0, 0.0, 0.0));
    for side in [1.0, -1.0] {
        let d = r.random_range(8.0..15.0);
        let a: f64 = r.random_range(40.0f64..140.0).to_radians() * side;
        b.robots
            .push((d * a.cos(), d * a.sin(), r.random_range(-180.0..180.0)));
    }
    b.build(&format!("scattered-starts-seed{seed}"), true)
}

/// A U-shaped trap open toward the start, the goal straight behind its back wall.
pub fn trap(seed: u64) -> Generated {
    let mut r = rng(5, seed);
    let depth = r.random_range(4.0..8.0);
    let half = r.random_range(3.0..6.0);
    let x0 = r.random_range(12.0..16.0);
    let y = r.random_range(-1.0..1.0);
    let mut b = Builder::new([x0 + depth + r.random_range(3.0..8.0), y]);
    b.rect([x0 + depth, y - half], [x0 + depth + 0.5, y + half]);
    b.rect([x0, y + half], [x0 + depth + 0.5, y + half + 0.5]);
    b.rect([x0, y - half - 0.5], [x0 + depth + 0.5, y - half]);
    b.fleet([2.0, 0.0], 0.0, 2);
    b.build(&format!("trap-seed{seed}"), true)
}

/// A block with one alley through it, `width` m wide, with a right-angle bend: the only
/// way (the site's edge closes round the block).
pub fn alley(seed: u64, width: f64) -> Generated {
    let mut r = rng(6, seed);
    let (x0, x1) = (10.0, 26.0);
    let bend_x = r.random_range(14.0..21.0);
    let (ya, yb) = (r.random_range(-4.0..-1.0), r.random_range(1.0..4.0));
    let mut b = Builder::new([34.0, yb]);
    b.bounds = Some(([-6.0, -12.0], [40.0, 12.0]));
    let w = width / 2.0;
    // Alley: along y = ya from x0 to bend_x, up to yb, along y = yb to x1.
    b.rect([x0, -12.0], [bend_x + w, ya - w]);
    b.rect([x0, ya + w], [bend_x - w, 12.0]);
    b.rect([bend_x + w, -12.0], [x1, yb - w]);
    b.rect([bend_x - w, yb + w], [x1, 12.0]);
    b.fleet([2.0, ya], 0.0, 2);
    b.build(&format!("alley-{width}m-seed{seed}"), true)
}

/// No way: the goal in a closed box, or a wall across the whole site with a gap narrower
/// than a robot.
pub fn no_way(seed: u64) -> Generated {
    let mut r = rng(7, seed);
    let mut b = Builder::new([30.0, r.random_range(-5.0..5.0)]);
    b.bounds = Some(([-10.0, -15.0], [45.0, 15.0]));
    if seed.is_multiple_of(2) {
        let g = b.goal;
        b.rect([g[0] - 3.0, g[1] - 3.0], [g[0] + 3.0, g[1] - 2.5]);
        b.rect([g[0] - 3.0, g[1] + 2.5], [g[0] + 3.0, g[1] + 3.0]);
        b.rect([g[0] - 3.0, g[1] - 3.0], [g[0] - 2.5, g[1] + 3.0]);
        b.rect([g[0] + 2.5, g[1] - 3.0], [g[0] + 3.0, g[1] + 3.0]);
    } else {
        let gap = r.random_range(0.3..0.55);
        let y = r.random_range(-5.0..5.0);
        b.rect([18.0, -15.0], [19.0, y - gap / 2.0]);
        b.rect([18.0, y + gap / 2.0], [19.0, 15.0]);
    }
    b.fleet([2.0, 0.0], 0.0, 2);
    b.build(&format!("no-way-seed{seed}"), false)
}

/// Something the map does not hold across the way: a van parked across the straight way
/// to the goal (seen only when the leader's scanner reaches it), or, on odd seeds, a
/// barrier closing the nearer of two parallel streets so that the route must change
/// street.
pub fn unmapped_in_the_way(seed: u64) -> Generated {
    let mut r = rng(8, seed);
    if seed.is_multiple_of(2) {
        let y = r.random_range(-1.0..1.0);
        let mut b = Builder::new([45.0, r.random_range(-2.0..2.0)]);
        b.bounds = Some(([-8.0, -15.0], [52.0, 15.0]));
        let x = r.random_range(15.0..25.0);
        let (w, l) = (r.random_range(2.0..2.5), r.random_range(5.0..7.0));
        b.unmapped_rect([x, y - l / 2.0], [x + w, y + l / 2.0]);
        b.circle([r.random_range(30.0..38.0), r.random_range(4.0..8.0)], 0.5);
        b.fleet([2.0, 0.0], 0.0, 2);
        b.build(&format!("unmapped-van-seed{seed}"), true)
    } else {
        // Streets along y = 0 (the nearer) and y = 16, a block between them, joined at
        // both ends; the barrier closes the y = 0 street half way.
        let len = r.random_range(40.0..55.0);
        let mut b = Builder::new([len + 4.0, 0.0]);
        b.bounds = Some(([-10.0, -6.0], [len + 10.0, 22.0]));
        b.rect([6.0, 5.0], [len - 2.0, 11.0]);
        let x = r.random_range(18.0..len - 12.0);
        b.unmapped_rect([x, -6.0], [x + 0.5, 5.0]);
        b.fleet([0.0, 0.0], 0.0, 2);
        b.build(&format!("unmapped-barrier-seed{seed}"), true)
    }
}
