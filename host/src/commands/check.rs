//! `basestation check SCENARIO`: validate a file and print what it describes.

use clap::Args;

#[derive(Args, Debug)]
pub struct CheckArgs {
    /// A scenario file, or a shipped scenario's name (paper-obstacles, paper-passage,
    /// street-crossing, plaza-crowd, plaza-sweep, street-block-sweep).
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
    match route.last() {
        Some(last) => println!(
            "route       {} point(s), goal ({:.2}, {:.2})",
            route.len(),
            last.x,
            last.y
        ),
        None => println!("route       none: the fleet stops where the sweep ends"),
    }
    print_sweep(&s);
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

/// The sweep's plan, before anything moves: per area its passes and their length, then
/// the swath, the ground the passes cover, the length and an estimate of the time.
fn print_sweep(s: &base_station::scenario::Scenario) {
    use base_station::coverage::grid::Coverage;
    let Some(plan) = s.sweep_plan() else {
        return;
    };
    let sw = plan.swath;
    println!(
        "sweep       swath {:.2} m ({} robots' brushes of {:.2} m), passes {:.2} m apart",
        sw.width,
        s.robots.len(),
        sw.brush,
        plan.spacing
    );
    if sw.gap > 0.0 {
        println!(
            "            the wide shape leaves gaps of {:.2} m between brushes: each pass \
             sweeps the leader's brush; bring the followers closer (formation.distance) \
             to sweep side by side",
            sw.gap
        );
    }
    let areas: Vec<Vec<glam::DVec2>> = s.sweep.iter().map(|a| a.points()).collect();
    let mut expected = Coverage::new(&areas, &s.build_map(), s.robot.footprint_radius, sw.width);
    let mut length = 0.0;
    for a in &plan.areas {
        let l = a.plan.length();
        length += l;
        println!(
            "area {:<6} {}: {:.0} m², {} cells, {} passes at {:.0}°, {:.0} m",
            a.index,
            a.name,
            a.outline_m2,
            a.plan.cells,
            a.plan.passes.len(),
            a.plan.direction.to_degrees(),
            l
        );
        for p in &a.plan.passes {
            let heading = (p.to - p.from).to_angle();
            expected.sweep(0, (p.from, heading), (p.to, heading), 0.0);
        }
    }
    let e = expected.summary();
    let cruise = s.planner.max_speed.min(s.robot.max_speed);
    let minutes = (length / cruise + plan.passes() as f64 * TURN_S) / 60.0;
    println!(
        "            {} passes, {length:.0} m; the passes cover {:.1} % of {:.0} m² to sweep; \
         about {minutes:.0} min at {cruise:.1} m/s",
        plan.passes(),
        100.0 * e.swept_fraction,
        e.to_sweep_m2
    );
}

/// A turn between passes, s: slowing, turning through 180° with the followers, settling.
const TURN_S: f64 = 8.0;

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
