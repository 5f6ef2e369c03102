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
    print_channel(&s);
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

/// The shared channel, where `[link] radio` names one: air per frame, the load of every
/// robot at 10 Hz, and the station's schedule.
fn print_channel(s: &base_station::scenario::Scenario) {
    use base_station::air::{
        leader_node, Air, PeriodLoad, Schedule, DOWNLINK_FRAME_BYTES, UPLINK_FRAME_BYTES,
    };
    use base_station::scenario::radio::Access;
    let Ok(Some(channel)) = s.link.channel() else {
        return;
    };
    let air = Air::new(channel);
    let (down, up) = (air.us(DOWNLINK_FRAME_BYTES), air.us(UPLINK_FRAME_BYTES));
    let load = PeriodLoad::of(&air, s.robots.len()).share();
    println!(
        "channel     {} ({}), {}: {:.1} ms per {DOWNLINK_FRAME_BYTES} B down, {:.1} ms per \
         {UPLINK_FRAME_BYTES} B up; every robot at 10 Hz needs {:.0} % of the air",
        channel.preset.name,
        channel.preset.what,
        channel.access.name(),
        down as f64 / 1000.0,
        up as f64 / 1000.0,
        load * 100.0
    );
    println!(
        "reporting   the leader every period, each follower every {} period(s)",
        base_station::air::follower_report_every(s)
    );
    if channel.access != Access::Scheduled {
        return;
    }
    let schedule = Schedule::of(channel, s.robots.len(), leader_node(s));
    println!(
        "schedule    downlink {:.1} ms, the leader's slot {:.1} ms, {} follower slot(s) of \
         {:.1} ms per 100 ms{}",
        schedule.down_us as f64 / 1000.0,
        schedule.leader_slot_us as f64 / 1000.0,
        schedule.slots.saturating_sub(1),
        schedule.slot_us as f64 / 1000.0,
        if schedule.cycle_periods() == u64::MAX {
            ": no slot for the followers, this radio cannot carry the fleet"
        } else {
            ""
        }
    );
}
