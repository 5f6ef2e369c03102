//! Areas to sweep nobody tuned for: open yards at any angle, L-shaped yards with a few
//! bins, plazas with bin fields and benches, the streets round a city block, a plaza with
//! a social crowd and one oblivious walker. The fleet is the sweeping triangle: followers
//! 0.65 m either side of the leader, 0.7 m brushes (a 2 m swath), starting outside the
//! area.

use std::fmt::Write as _;

use glam::DVec2;
use rand::Rng;

use super::{rng, Generated};

/// The site file round `area` (its outline) with `obstacles` (TOML inline tables) and
/// `extra` tables, the fleet starting at `start` heading `heading_deg`.
fn site(
    name: &str,
    area: &[DVec2],
    obstacles: &[String],
    start: DVec2,
    heading_deg: f64,
    extra: &str,
) -> Generated {
    let lo = area.iter().fold(start, |m, q| m.min(*q)) - DVec2::splat(6.0);
    let hi = area.iter().fold(start, |m, q| m.max(*q)) + DVec2::splat(6.0);
    let outline: f64 = area
        .iter()
        .zip(area.iter().cycle().skip(1))
        .map(|(a, b)| a.distance(*b))
        .sum();
    let square: f64 = base_station::coverage::area(area);
    // About 2 m² a metre at 0.4 m/s, a turn every pass, and slack for the touch-ups.
    let duration = 600.0 + 3.0 * (square / 2.0 / 0.4) + outline;
    let mut t = String::new();
    let _ = writeln!(t, "name = \"{name}\"\n[map]");
    let _ = writeln!(
        t,
        "bounds = {{ min = [{:.2}, {:.2}], max = [{:.2}, {:.2}] }}",
        lo.x, lo.y, hi.x, hi.y
    );
    let _ = writeln!(t, "obstacles = [\n  {}\n]", obstacles.join(",\n  "));
    let back = DVec2::from_angle((heading_deg + 180.0).to_radians());
    let side = back.perp();
    let fleet = [
        start,
        start + back * 1.13 + side * 0.65,
        start + back * 1.13 - side * 0.65,
    ];
    for (i, p) in fleet.iter().enumerate() {
        let role = if i == 0 { "leader" } else { "follower" };
        let _ = writeln!(
            t,
            "[[robots]]\nid = {i}\nrole = \"{role}\"\nstart = {{ x = {:.3}, y = {:.3}, heading_deg = {heading_deg:.1} }}",
            p.x, p.y
        );
    }
    let _ = writeln!(
        t,
        "[formation]\nshape = \"triangle\"\ndistance = 1.3\nangle_deg = 150.0"
    );
    let poly: Vec<String> = area
        .iter()
        .map(|p| format!("[{:.3}, {:.3}]", p.x, p.y))
        .collect();
    let _ = writeln!(
        t,
        "[[sweep]]\nname = \"area\"\npolygon = [{}]\noverlap = 0.1",
        poly.join(", ")
    );
    let _ = writeln!(t, "[sim]\nduration_s = {duration:.0}");
    t.push_str(extra);
    Generated {
        name: name.to_string(),
        toml: t,
        way: true,
    }
}

fn circle(c: DVec2, r: f64) -> String {
    format!(
        "{{ kind = \"circle\", center = [{:.3}, {:.3}], radius = {r:.2} }}",
        c.x, c.y
    )
}

fn rectangle(lo: DVec2, hi: DVec2) -> String {
    format!(
        "{{ kind = \"rectangle\", min = [{:.3}, {:.3}], max = [{:.3}, {:.3}] }}",
        lo.x, lo.y, hi.x, hi.y
    )
}

/// A rectangle `w` × `h` turned by `angle` about the origin.
fn turned_rect(w: f64, h: f64, angle: f64) -> Vec<DVec2> {
    [(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)]
        .iter()
        .map(|(x, y)| DVec2::from_angle(angle).rotate(DVec2::new(*x, *y)))
        .collect()
}

/// An open yard 15–35 m by 10–25 m at any angle, nothing in it.
pub fn open_yard(seed: u64) -> Generated {
    let mut r = rng(20, seed);
    let (w, h) = (r.random_range(15.0..35.0), r.random_range(10.0..25.0));
    let angle = r.random_range(0.0..std::f64::consts::PI);
    let area = turned_rect(w, h, angle);
    let out = DVec2::from_angle(angle).rotate(DVec2::new(-3.0, -3.0));
    let heading = angle.to_degrees();
    site(
        &format!("open-yard-seed{seed}"),
        &area,
        &[],
        out,
        heading,
        "",
    )
}

/// Bins (0.3–0.5 m) scattered over `area`'s bounding box, at least `apart` from each
/// other and inside it by a robot's width.
fn bins(r: &mut impl Rng, area: &[DVec2], count: usize, apart: f64) -> Vec<(DVec2, f64)> {
    let lo = area.iter().fold(DVec2::INFINITY, |m, q| m.min(*q));
    let hi = area.iter().fold(DVec2::NEG_INFINITY, |m, q| m.max(*q));
    let mut out: Vec<(DVec2, f64)> = Vec::new();
    for _ in 0..count * 50 {
        if out.len() == count {
            break;
        }
        let c = DVec2::new(r.random_range(lo.x..hi.x), r.random_range(lo.y..hi.y));
        let inside = base_station::geometry::point_in_polygon(c, area);
        let margin = area.iter().zip(area.iter().cycle().skip(1)).all(|(a, b)| {
            let t = ((c - *a).dot(*b - *a) / (*b - *a).length_squared()).clamp(0.0, 1.0);
            c.distance(*a + (*b - *a) * t) > 1.5
        });
        if inside && margin && out.iter().all(|(o, _)| o.distance(c) > apart) {
            out.push((c, r.random_range(0.3..0.5)));
        }
    }
    out
}

/// An L-shaped yard (two arms 8–14 m wide, 20–35 m long) with 0–4 bins.
pub fn l_yard(seed: u64) -> Generated {
    let mut r = rng(21, seed);
    let (a, b) = (r.random_range(20.0..35.0), r.random_range(20.0..35.0));
    let (wa, wb) = (r.random_range(8.0..14.0), r.random_range(8.0..14.0));
    let area = vec![
        DVec2::new(0.0, 0.0),
        DVec2::new(a, 0.0),
        DVec2::new(a, wa),
        DVec2::new(wb, wa),
        DVec2::new(wb, b),
        DVec2::new(0.0, b),
    ];
    let n = r.random_range(0..=4);
    let obstacles: Vec<String> = bins(&mut r, &area, n, 6.0)
        .into_iter()
        .map(|(c, rad)| circle(c, rad))
        .collect();
    let start = DVec2::new(-3.0, -3.0);
    site(
        &format!("l-yard-seed{seed}"),
        &area,
        &obstacles,
        start,
        0.0,
        "",
    )
}

/// A plaza 25–40 m by 18–30 m with 4–12 bins and 0–2 benches (2–4 m by 0.6 m).
pub fn bin_plaza(seed: u64) -> Generated {
    let mut r = rng(22, seed);
    let (w, h) = (r.random_range(25.0..40.0), r.random_range(18.0..30.0));
    let area = turned_rect(w, h, 0.0);
    let n = r.random_range(4..=12);
    let mut obstacles: Vec<String> = bins(&mut r, &area, n, 5.0)
        .into_iter()
        .map(|(c, rad)| circle(c, rad))
        .collect();
    for _ in 0..r.random_range(0..=2) {
        let c = DVec2::new(r.random_range(5.0..w - 5.0), r.random_range(5.0..h - 5.0));
        let half = DVec2::new(r.random_range(1.0..2.0), 0.3);
        obstacles.push(rectangle(c - half, c + half));
    }
    site(
        &format!("bin-plaza-seed{seed}"),
        &area,
        &obstacles,
        DVec2::new(-3.0, -3.0),
        0.0,
        "",
    )
}

/// The streets round a city block: a building 20–40 m by 15–30 m, streets 6–10 m wide
/// round it; the area is the outer outline, the building inside it.
pub fn street_block(seed: u64) -> Generated {
    let mut r = rng(23, seed);
    let (bw, bh) = (r.random_range(20.0..40.0), r.random_range(15.0..30.0));
    let street = r.random_range(6.0..10.0);
    let area = turned_rect(bw + 2.0 * street, bh + 2.0 * street, 0.0);
    let building = rectangle(
        DVec2::new(street, street),
        DVec2::new(street + bw, street + bh),
    );
    site(
        &format!("street-block-seed{seed}"),
        &area,
        &[building],
        DVec2::new(-3.0, -3.0),
        0.0,
        "",
    )
}

/// A 30 m by 20 m plaza with a few bins, a social crowd at 0.05 persons/m² and one
/// oblivious walker across it.
pub fn crowd_plaza(seed: u64) -> Generated {
    let mut r = rng(24, seed);
    let area = turned_rect(30.0, 20.0, 0.0);
    let n = r.random_range(0..=4);
    let obstacles: Vec<String> = bins(&mut r, &area, n, 6.0)
        .into_iter()
        .map(|(c, rad)| circle(c, rad))
        .collect();
    let (y0, y1) = (r.random_range(2.0..18.0), r.random_range(2.0..18.0));
    let extra = format!(
        "[[crowds]]\narea = {{ min = [1.0, 1.0], max = [29.0, 19.0] }}\ndensity = 0.05\n\
         seed = {seed}\nbehavior = \"social\"\n\
         [[movers]]\nkind = \"pedestrian\"\nbehavior = \"oblivious\"\npath = [[-4.0, {y0:.2}], [34.0, {y1:.2}]]\n\
         speed = 1.3\nstart_s = {:.0}\nrepeat = \"back_and_forth\"\n",
        r.random_range(20.0..200.0)
    );
    site(
        &format!("crowd-plaza-seed{seed}"),
        &area,
        &obstacles,
        DVec2::new(-3.0, -3.0),
        0.0,
        &extra,
    )
}
