//! `basestation check SCENARIO`: validate a file and print what it describes.

use clap::Args;

#[derive(Args, Debug)]
pub struct CheckArgs {
    /// A scenario file, or a shipped scenario's name (paper-obstacles, paper-passage,
    /// street-crossing, plaza-crowd).
    pub scenario: String,
}

pub fn run(args: CheckArgs) -> anyhow::Result<()> {
    let s = super::load_scenario(&args.scenario)?;
    let spec = s.formation_spec();
    println!("scenario    {} — {}", s.name, s.description.trim());
    println!("map         {} obstacles", s.map.obstacles.len());
    for r in &s.robots {
        let role = r.role.name();
        println!(
            "robot {:<5} {role:<8} start ({:.2}, {:.2}) heading {:.0}°",
            r.id, r.start.x, r.start.y, r.start.heading_deg
        );
    }
    println!(
        "formation   {} with {} followers, width {:.2} m; line spacing {:.2} m",
        s.wide_name(),
        spec.followers,
        spec.wide_width(),
        spec.line_spacing
    );
    let route = s.route.points();
    let last = route.last().expect("validated");
    println!(
        "route       {} point(s), goal ({:.2}, {:.2})",
        route.len(),
        last.x,
        last.y
    );
    print_movers(&s);
    println!(
        "gains       k1 {} k2 {} d {} | k_a {} k_r {} R_det {}",
        s.follower.k1, s.follower.k2, s.follower.d, s.planner.k_a, s.planner.k_r, s.planner.r_det
    );
    println!(
        "sim link    {} ms ± {} ms, {:.0} % loss, {} baud",
        s.link.latency_ms,
        s.link.jitter_ms,
        s.link.loss * 100.0,
        s.link.baud
    );
    println!("ok");
    Ok(())
}

/// The scenario's movers, one line each, and its crowds (simulation only).
fn print_movers(s: &base_station::scenario::Scenario) {
    use base_station::scenario::movers::Behavior;
    let manner = |b: Behavior| match b {
        Behavior::Oblivious => "oblivious",
        Behavior::Social => "social",
    };
    for (i, m) in s.movers.iter().enumerate() {
        let (a, b) = (m.path[0], m.path[m.path.len() - 1]);
        println!(
            "mover {i:<5} {} {}, {:.1} m/s from {:.1} s, ({:.1}, {:.1}) to ({:.1}, {:.1}){}",
            manner(m.behavior),
            m.kind.name(),
            m.speed,
            m.start_s,
            a[0],
            a[1],
            b[0],
            b[1],
            if m.pauses.is_empty() { "" } else { ", pausing" }
        );
    }
    for (i, c) in s.crowds.iter().enumerate() {
        let (w, h) = (c.area.max[0] - c.area.min[0], c.area.max[1] - c.area.min[1]);
        println!(
            "crowd {i:<5} {} at {:.2} persons/m² ({:.0} people) over {w:.0} m × {h:.0} m, from {:.1} s",
            manner(c.behavior),
            c.density,
            c.density * w * h,
            c.start_s
        );
    }
}
