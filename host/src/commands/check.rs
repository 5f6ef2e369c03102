//! `basestation check SCENARIO`: validate a file and print what it describes.

use clap::Args;

#[derive(Args, Debug)]
pub struct CheckArgs {
    /// A scenario file, or a shipped scenario's name (paper-obstacles, paper-passage).
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
