//! One simulated run, start to report.

use std::collections::BTreeMap;
use std::time::Instant;

use base_station::scenario::radio::Access;
use base_station::scenario::Scenario;
use base_station::station::MoverPolicy;
use protocol::{Reject, RejectCounts};

use crate::brain::BrainError;
use crate::report::{
    self, quantile, ChannelReport, LinkReport, Report, RobotLinkReport, RunFacts, ScheduleReport,
    StationEventReport,
};
use crate::world::{SimOptions, World};

/// Runs a scenario; returns the report and the finished world (for the figure).
pub fn simulate(scenario: Scenario, options: SimOptions) -> Result<(Report, World), BrainError> {
    simulate_with(scenario, options, |_| {})
}

/// [`simulate`], calling `each_step` after every physics step.
pub fn simulate_with(
    scenario: Scenario,
    options: SimOptions,
    each_step: impl FnMut(&mut World),
) -> Result<(Report, World), BrainError> {
    let wall = Instant::now();
    let mut world = World::new(scenario, options)?;
    world.run_with(each_step)?;
    let report = report_of(&world, wall.elapsed().as_secs_f64());
    Ok((report, world))
}

/// The time to goal of `scenario` with nobody on the site (its movers and crowds taken
/// away), run as `options` say but at full speed and with a simulated base station: the
/// report's `movers.time_to_goal_empty_s`. `None` without movers, or short of the goal
/// (a parked fleet never leaves).
pub fn empty_site_time(
    scenario: &Scenario,
    options: &SimOptions,
) -> Result<Option<f64>, BrainError> {
    let parked = options.movers == MoverPolicy::Parked;
    if parked || scenario.movers.is_empty() && scenario.crowds.is_empty() {
        return Ok(None);
    }
    let mut empty = scenario.clone();
    empty.movers.clear();
    empty.crowds.clear();
    let mut quick = SimOptions::new(options.seed);
    quick.firmware = options.firmware;
    quick.key = options.key.clone();
    quick.fixes = options.fixes;
    quick.movers = options.movers;
    let (report, _) = simulate(empty, quick)?;
    Ok(report.time_to_goal_s)
}

/// The report of a world run so far. With an external base station, shape changes are
/// the ones heard on the air and the station's events are not known here.
pub fn report_of(world: &World, wall_time_s: f64) -> Report {
    // Rejects by reason from every receiver: the base station and each robot (a firmware
    // robot reports its counts over the lockstep link).
    let mut rejects = world.station.rejects();
    for r in &world.robots {
        rejects.merge(&r.brain.rejects());
    }
    let total = rejects.total() as u64;
    let link = LinkReport {
        frames_sent: world.radio.stats.frames_sent,
        frames_delivered: world.radio.stats.frames_delivered,
        frames_rejected: total,
        rejects_by_reason: by_reason(&rejects),
        channel: channel_report(world),
    };
    let s = &world.scenario;
    let transformations = report::transformations(
        &world.recorder,
        match &world.external {
            Some(external) => external.observer.transformations(),
            None => world.station.formation().transformations(),
        },
        s.wide_name(),
        s.formation_spec().transition_duration(),
    );
    let roles: Vec<_> = world.robots.iter().map(|r| (r.id, r.role)).collect();
    let facts = RunFacts {
        scenario: s,
        roles: &roles,
        seed: world.options.seed,
        firmware: world.options.firmware.name(),
        sim_time_s: world.t_us as f64 / 1e6,
        wall_time_s,
        time_to_goal_s: world.goal_time_s(),
        movers: world.movers.len(),
    };
    let mut report = report::build_report(&world.recorder, &facts, transformations, link);
    report.baseline = match world.options.movers {
        MoverPolicy::Heed => None,
        MoverPolicy::Ignore => Some("ignore_movers".to_string()),
        MoverPolicy::Parked => Some("parked".to_string()),
    };
    if world.external.is_some() {
        report.ending = "external".into();
        report.why = match report.time_to_goal_s {
            Some(t) => format!("goal reached at {t:.1} s"),
            None => "ended short of the goal (the station is another process: its summary \
                     says why)"
                .into(),
        };
        return report;
    }
    let ending = world.station.ending(world.base_ms(), world.stop_requested);
    report.ending = ending.kind().into();
    report.why = ending.why();
    let leader = world.station.config().leader;
    let epoch = world.base_epoch_s();
    report.station_events = world
        .station
        .events()
        .iter()
        .map(|e| {
            let (at_ms, event, robot) = e.describe(leader);
            StationEventReport {
                at_s: epoch + at_ms as f64 / 1000.0,
                event,
                robot,
            }
        })
        .collect();
    report
}

fn by_reason(counts: &RejectCounts) -> BTreeMap<String, u64> {
    Reject::ALL
        .iter()
        .filter(|r| counts.get(**r) > 0)
        .map(|r| (r.name().to_string(), counts.get(*r) as u64))
        .collect()
}

/// The channel over the run: its use and losses, and per robot the delivered shares and
/// the leader state's age.
fn channel_report(world: &World) -> ChannelReport {
    let radio = &world.radio;
    let stats = radio.channel_stats();
    let channel = world.scenario.link.channel().ok().flatten();
    let ms = |us: u64| us as f64 / 1000.0;
    let schedule = radio
        .medium()
        .filter(|_| channel.is_some_and(|c| c.access == Access::Scheduled))
        .map(|m| {
            let s = m.schedule();
            ScheduleReport {
                period_ms: ms(base_station::air::PERIOD_US),
                downlink_ms: ms(s.down_us),
                leader_slot_ms: ms(s.leader_slot_us),
                slot_ms: ms(s.slot_us),
                uplink_slots_per_period: s.slots,
                follower_every_periods: Some(s.cycle_periods()).filter(|c| *c != u64::MAX),
            }
        });
    let share = |(sent, got): (u64, u64)| (sent > 0).then(|| got as f64 / sent as f64);
    let links = radio.links();
    let robots = world
        .robots
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let node = i + 1;
            let down = links
                .iter()
                .filter(|((from, to), _)| *to == node && *from == 0)
                .fold((0, 0), |a, (_, (s, d))| (a.0 + s, a.1 + d));
            let (ages, gap) = world.leader_state_ages.of(node);
            let ages: Vec<f64> = ages.iter().map(|a| ms(*a)).collect();
            RobotLinkReport {
                id: r.id,
                uplink_delivery: links.get(&(node, 0)).copied().and_then(share),
                downlink_delivery: share(down),
                leader_state_age_ms_p50: quantile(ages.clone(), 0.5),
                leader_state_age_ms_p99: quantile(ages, 0.99),
                leader_state_gap_ms_max: (gap > 0).then(|| ms(gap)),
            }
        })
        .collect();
    ChannelReport {
        radio: channel.map_or("own_air".into(), |c| c.preset.name.into()),
        access: channel.map(|c| c.access.name().into()),
        utilisation: if world.t_us > 0 {
            stats.busy_us as f64 / world.t_us as f64
        } else {
            0.0
        },
        frames_on_air: stats.frames_on_air,
        collisions: stats.collisions,
        half_duplex_losses: stats.half_duplex,
        queue_drops: stats.queue_drops,
        unsendable: stats.unsendable,
        schedule,
        robots,
    }
}
