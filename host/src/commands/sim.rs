//! `basestation sim [SCENARIO]`: the whole system in software. The real base station code
//! drives simulated robots (their real control code, natively or as firmware in QEMU) over
//! a simulated radio. Prints the run's metrics beside the paper's, writes the JSON report
//! and an SVG figure.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use anyhow::Context;
use base_station::scenario::movers::MoverShape;
use clap::Args;
use hil_sim::recording::Recording;
use hil_sim::report::{Report, RobotReport};
use hil_sim::run::simulate_with;
use hil_sim::world::{SimOptions, World};

#[derive(Args, Debug)]
pub struct SimArgs {
    /// A scenario file, or a shipped scenario's name (paper-obstacles, paper-passage,
    /// street-crossing, plaza-crowd, plaza-sweep, street-block-sweep).
    #[arg(default_value = "paper-obstacles")]
    pub scenario: String,
    /// Where to write the JSON report [default: out/SCENARIO.json].
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Where to write the SVG figure [default: out/SCENARIO.svg].
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Where to write the MCAP recording, for Foxglove or Lichtblick [default:
    /// out/SCENARIO.mcap] (docs/sim.md#the-recording).
    #[arg(long, value_name = "FILE.mcap")]
    pub mcap: Option<PathBuf>,
    /// Write a Foxglove / Lichtblick layout for this fleet here (the shipped one with
    /// its plots for these robots): open it with the recording.
    #[arg(long, value_name = "FILE.json")]
    pub layout: Option<std::path::PathBuf>,
    /// Run no faster than the wall clock.
    #[arg(long)]
    pub realtime: bool,
    #[command(flatten)]
    pub robots: super::SimulatedArgs,
    /// With `--realtime`: the console and the live stream.
    #[command(flatten)]
    pub serve: super::ServeArgs,
    /// Inject a fault, as a TOML inline table with the fields of `[[faults]]`, e.g.
    /// `--fault '{ at_s = 30, kind = "loss_burst", duration_s = 10 }'`. Repeatable.
    #[arg(long = "fault", value_name = "TABLE")]
    pub faults: Vec<String>,
    /// Run a baseline to measure the station's manners against, in the same world:
    /// `parked` (the fleet assembles and stands for the whole run) or `ignore-movers`
    /// (the station does not act on what moves; the robots' own stops still do). The
    /// report says so (`baseline`).
    #[arg(long, value_enum)]
    pub baseline: Option<Baseline>,
}

/// `sim --baseline`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Baseline {
    Parked,
    IgnoreMovers,
}

impl From<Baseline> for base_station::station::MoverPolicy {
    fn from(b: Baseline) -> Self {
        match b {
            Baseline::Parked => Self::Parked,
            Baseline::IgnoreMovers => Self::Ignore,
        }
    }
}

fn parse_fault(text: &str) -> anyhow::Result<base_station::scenario::FaultSpec> {
    #[derive(serde::Deserialize)]
    struct Wrapper {
        fault: base_station::scenario::FaultSpec,
    }
    let doc = format!("fault = {text}");
    let w: Wrapper =
        toml::from_str(&doc).map_err(|e| anyhow::anyhow!("--fault {text}: {}", e.message()))?;
    Ok(w.fault)
}

pub fn run(args: SimArgs) -> anyhow::Result<super::outcome::Outcome> {
    let serves = args.serve.console.is_some() || args.serve.live.is_some();
    let needs_realtime = match (serves, args.serve.zenoh.is_some()) {
        (true, _) => Some("--console and --live need --realtime"),
        (false, true) => Some("--zenoh needs --realtime"),
        (false, false) => None,
    };
    if let Some(what) = needs_realtime.filter(|_| !args.realtime) {
        // A bad command line, as clap's own: exit code 2 (README.md#exit-codes).
        clap::Error::raw(
            clap::error::ErrorKind::MissingRequiredArgument,
            format!("{what} (a run no faster than the wall clock)\n"),
        )
        .exit();
    }
    let (scenario, options) = prepare(&args)?;
    let name = scenario.name.clone();
    let mcap_path = args
        .mcap
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("out/{name}.mcap")));
    super::create_parent(&mcap_path)?;
    let mut watch = Watch::open(&args, &scenario, &mcap_path)?;
    let empty_site = (scenario.clone(), options.clone());
    let result = simulate_with(scenario, options, |world| watch.step(world));
    let (console, bus, interrupted, recording) = watch.close()?;
    let (mut report, world) = result.context("the simulation failed")?;
    report.movers.time_to_goal_empty_s =
        hil_sim::run::empty_site_time(&empty_site.0, &empty_site.1)
            .context("the run without movers failed")?;
    let (report_path, plot_path) = write_outputs(&args, &name, &world, &report)?;
    let recording = match recording {
        Some(r) => r,
        None => Recording::create(&world, &super::partial_path(&mcap_path)),
    };
    recording
        .and_then(|r| r.finish(&world, &report))
        .map_err(anyhow::Error::msg)?;
    std::fs::rename(super::partial_path(&mcap_path), &mcap_path)
        .with_context(|| format!("cannot write {}", mcap_path.display()))?;
    print_table(&report, &report_path, &plot_path, &mcap_path);
    let ending = world.station.ending(world.base_ms(), interrupted);
    let outcome = super::outcome::Outcome::of(&ending);
    let last = crate::live::console::snapshot(&world.station, world.base_ms());
    let last = crate::live::console::finished(last, &ending.why());
    if let Some(mut bus) = bus {
        bus.publish(&last);
    }
    if let Some(console) = console.as_ref().filter(|c| c.alive()) {
        console.publish(&last);
        std::thread::sleep(crate::live::console::FINISHED_SHOWN);
    }
    if interrupted {
        eprintln!(
            "interrupted: report, figure and recording written up to {:.1} s",
            world.t_us as f64 / 1e6
        );
    }
    Ok(outcome)
}

/// The scenario with the command line's faults (validated again), its layout written if
/// asked, and the simulation's options.
fn prepare(args: &SimArgs) -> anyhow::Result<(base_station::scenario::Scenario, SimOptions)> {
    let mut scenario = super::load_scenario(&args.scenario)?;
    for text in &args.faults {
        scenario.faults.push(parse_fault(text)?);
    }
    if let Err(problems) = scenario.validate() {
        let lines: Vec<String> = problems
            .iter()
            .map(|(field, message)| format!("--fault: field `{field}`: {message}"))
            .collect();
        anyhow::bail!("{}", lines.join("\n"));
    }
    if let Some(path) = &args.layout {
        super::create_parent(path)?;
        crate::live::recording::layout::write(&scenario, path)?;
    }
    let mut options = SimOptions::new(args.robots.seed.unwrap_or(scenario.sim.seed));
    options.firmware = args.robots.firmware.into();
    options.realtime = args.realtime;
    if let Some(b) = args.baseline {
        options.movers = b.into();
    }
    Ok((scenario, options))
}

/// The report, the figure and the trace, where asked (or beside the scenario's name in
/// `out/`): the report's and the figure's paths.
fn write_outputs(
    args: &SimArgs,
    name: &str,
    world: &World,
    report: &Report,
) -> anyhow::Result<(PathBuf, PathBuf)> {
    let report_path = args
        .report
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("out/{name}.json")));
    let plot_path = args
        .plot
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("out/{name}.svg")));
    for p in [
        Some(&report_path),
        Some(&plot_path),
        args.robots.trace.as_ref(),
    ]
    .into_iter()
    .flatten()
    {
        super::create_parent(p)?;
    }
    super::write_report(report, &report_path)?;
    super::replace(&plot_path, |partial| {
        hil_sim::plot::write_svg(world, report, partial)
            .map_err(|e| anyhow::anyhow!("cannot draw {}: {e}", plot_path.display()))
    })?;
    if let Some(path) = &args.robots.trace {
        super::write_trace(world, path)?;
    }
    Ok((report_path, plot_path))
}

/// The way left in words: `12.3 m to go · waypoint 2 of 3 · about 40 s`.
pub fn progress_words(p: &base_station::station::Progress) -> String {
    let eta = p
        .eta_s
        .map_or(String::new(), |s| format!(" · about {s:.0} s"));
    let swept = p
        .swept
        .map_or(String::new(), |s| format!("swept {:.0} % · ", 100.0 * s));
    format!(
        "{swept}{:.0} % · {:.1} m to go · waypoint {} of {}{eta}",
        100.0 * p.share,
        p.left_m,
        p.waypoint,
        p.waypoints
    )
}

/// What watches a run as it goes: the terminal's bar, the recording (fed on a thread of
/// its own, to a partial file renamed into place at the end: an interrupted run never
/// truncates the last one), the console and the live stream, and Ctrl-C.
struct Watch {
    bar: indicatif::ProgressBar,
    end_s: f64,
    console: Option<crate::live::console::Console>,
    bus: Option<crate::bus::station::StationBus>,
    live: Option<crate::live::recording::LiveRecording>,
    live_sent: usize,
    recording: Option<Result<Recording, String>>,
    mcap_partial: PathBuf,
    interrupted: Arc<AtomicBool>,
}

/// What [`Watch::close`] hands back: the console, the bus, whether the run was interrupted,
/// the recording.
type Watched = (
    Option<crate::live::console::Console>,
    Option<crate::bus::station::StationBus>,
    bool,
    Option<Result<Recording, String>>,
);

impl Watch {
    fn open(
        args: &SimArgs,
        scenario: &base_station::scenario::Scenario,
        mcap_path: &Path,
    ) -> anyhow::Result<Self> {
        // Simulated time on a terminal (stderr); nothing when stderr is not one.
        let bar = indicatif::ProgressBar::new(1000);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} simulating {msg} [{bar:30}] {elapsed}",
            )
            .expect("a valid template")
            .progress_chars("=> "),
        );
        let live = match args.serve.live {
            Some(addr) => Some(crate::live::recording::LiveRecording::create(
                scenario,
                None,
                Some(addr),
                &args.serve.live_origin,
                scenario.robots.iter().map(|r| r.id),
            )?),
            None => None,
        };
        // In real time, Ctrl-C / SIGTERM end the run early; its report, figure and
        // recording are written as for any end (exit code 4).
        let interrupted = Arc::new(AtomicBool::new(false));
        if args.realtime {
            let flag = interrupted.clone();
            ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst))
                .context("installing Ctrl-C")?;
        }
        Ok(Self {
            bar,
            end_s: scenario.sim.duration_s,
            console: crate::live::console::Console::open(args.serve.console, scenario)?,
            bus: args.serve.bus(scenario)?,
            live,
            live_sent: 0,
            recording: None,
            mcap_partial: super::partial_path(mcap_path),
            interrupted,
        })
    }

    /// After each physics step.
    fn step(&mut self, world: &mut World) {
        match &mut self.recording {
            None => self.recording = Some(Recording::create(world, &self.mcap_partial)),
            Some(Ok(r)) if world.t_us.is_multiple_of(Recording::FEED_EVERY_US) => r.feed(world),
            Some(_) => {}
        }
        world.stop_requested |= self.interrupted.load(Ordering::SeqCst);
        if world.t_us.is_multiple_of(100_000) {
            self.show_progress(world);
        }
        let now_ms = world.base_ms();
        let console = self.console.as_ref().filter(|c| c.alive());
        for command in console.map(|c| c.commands()).unwrap_or_default() {
            world.station.operator(command, now_ms);
        }
        if let Some(bus) = &self.bus {
            for c in bus.commands() {
                let done = crate::bus::station::obey(&mut world.station, c.command, now_ms);
                bus.answer(c.id, done);
            }
        }
        if world.t_us.is_multiple_of(100_000) && (console.is_some() || self.bus.is_some()) {
            let mut snapshot = crate::live::console::snapshot(&world.station, now_ms);
            if let Some(bus) = self.bus.as_mut() {
                bus.publish(&snapshot);
            }
            if let Some(console) = console {
                snapshot["movers"] = movers_json(world);
                console.publish(&snapshot);
            }
        }
        if let Some(live) = self.live.as_mut() {
            // What went on the air since the last step: the station's as `base`, the rest
            // as the station heard it (`air`).
            for (t_us, from, bytes) in &world.transmitted[self.live_sent..] {
                live.radio(if *from == 0 { "base" } else { "air" }, bytes, t_us * 1000);
            }
            self.live_sent = world.transmitted.len();
            if world.t_us.is_multiple_of(100_000) {
                live.station(&world.station, world.base_ms(), world.t_us * 1000);
                live.scene(&world.station, world.base_ms(), world.t_us * 1000);
            }
        }
    }

    /// The bar at the share of the way done (of the run's time before the leader is
    /// known), with the way left and when the fleet should arrive.
    fn show_progress(&self, world: &World) {
        let t = world.t_us as f64 / 1e6;
        let (share, words) = match world.station.progress(world.base_ms()) {
            Some(p) => (p.share, format!("{t:.0} s · {}", progress_words(&p))),
            None => (t / self.end_s.max(1e-9), format!("{t:.0} s")),
        };
        self.bar
            .set_position((share.clamp(0.0, 1.0) * 1000.0) as u64);
        self.bar.set_message(words);
    }

    /// Ends the live stream and the bar.
    fn close(self) -> anyhow::Result<Watched> {
        if let Some(live) = self.live {
            live.close()?;
        }
        self.bar.finish_and_clear();
        let interrupted = self.interrupted.load(Ordering::SeqCst);
        Ok((self.console, self.bus, interrupted, self.recording))
    }
}

// Writes to stdout, ignoring a closed pipe (`| head`) instead of panicking.
macro_rules! out {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = write!(std::io::stdout(), $($t)*);
    }};
}
macro_rules! outln {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($t)*);
    }};
}

fn num(v: Option<f64>) -> String {
    v.map_or("—".to_string(), |v| format!("{v:.2}"))
}

/// The per-robot rows of the summary: label, figure, the paper's (leader / follower 1 /
/// follower 2).
type Row = (&'static str, fn(&RobotReport) -> Option<f64>, &'static str);
const ROWS: [Row; 7] = [
    (
        "average velocity (m/s)",
        |x| Some(x.avg_speed_mps),
        "0.40 / 0.39 / 0.41",
    ),
    (
        "average |angular velocity| (rad/s)",
        |x| Some(x.avg_abs_omega_radps),
        "0.60 / 0.59 / 0.61",
    ),
    (
        "average |ω| on straight legs (rad/s)",
        |x| x.straight_avg_abs_omega_radps,
        "",
    ),
    (
        "max tracking error after join (m)",
        |x| x.max_tracking_error_m,
        "— / 0.35 / 0.34",
    ),
    ("joined at (s)", |x| x.joined_at_s, ""),
    (
        "p95 tracking error after join (m)",
        |x| x.p95_tracking_error_m,
        "",
    ),
    (
        "stable max tracking error (m)",
        |x| x.stable_max_tracking_error_m,
        "< 0.1 (stable phases)",
    ),
];

fn print_table(r: &Report, report_path: &Path, plot_path: &Path, mcap_path: &Path) {
    let rtf = if r.wall_time_s > 0.0 {
        r.sim_time_s / r.wall_time_s
    } else {
        f64::INFINITY
    };
    outln!(
        "{} · seed {} · {} firmware · {:.1} s simulated in {:.2} s ({:.0}× real time)",
        r.scenario,
        r.seed,
        r.firmware,
        r.sim_time_s,
        r.wall_time_s,
        rtf
    );
    outln!("{}", r.why);
    print_robots(r);
    print_run(r);
    outln!(
        "report {} · figure {} · recording {}",
        report_path.display(),
        plot_path.display(),
        mcap_path.display()
    );
}

/// Whether the run is one of the paper's own scenarios: only there are its figures a
/// yardstick (elsewhere the paper's 0.60 rad/s beside a straight street's 0.00 reads as
/// a failure).
fn the_papers(r: &Report) -> bool {
    r.scenario.starts_with("paper-")
}

/// The per-robot figures, beside the paper's for its own scenarios.
fn print_robots(r: &Report) {
    let paper = the_papers(r);
    out!("{:<34}", "");
    for x in &r.robots {
        out!("{:>12}", format!("{} {}", x.role, x.id));
    }
    outln!("{}", if paper { "   paper (L / F1 / F2)" } else { "" });
    for (label, figure, theirs) in ROWS {
        out!("{label:<34}");
        for x in &r.robots {
            out!("{:>12}", num(figure(x)));
        }
        outln!(
            "{}",
            if paper {
                format!("   {theirs}")
            } else {
                String::new()
            }
        );
    }
}

/// The run's contacts, movers, shape changes and link.
fn print_run(r: &Report) {
    outln!(
        "collisions {} · {} · min robot separation {:.2} m · convergence {}",
        r.collisions,
        hil_sim::plot::clearance(r.min_obstacle_clearance_m),
        r.min_robot_separation_m,
        r.convergence_time_s
            .map_or("never".to_string(), |t| format!("{t:.1} s"))
    );
    let m = &r.movers;
    if m.count > 0 {
        outln!(
            "movers {} · contacts: drove into {}, walked into {} standing, {} braking · least person clearance {} m · intrusion {:.1} s · freezing {:.1} s · time to goal {} × the empty site's",
            m.count,
            m.drove_into,
            m.walked_into_standing,
            m.walked_into_braking,
            num(m.min_person_clearance_m),
            m.intrusion_s,
            m.freezing_s,
            num(m.slowdown(r.time_to_goal_s))
        );
    }
    let within = if the_papers(r) {
        " (paper: within 5 s)"
    } else {
        ""
    };
    for t in &r.transformations {
        outln!(
            "transformation to {} at {:.1} s ({}), done in {} s{within}",
            t.to,
            t.start_s,
            t.reason.replace('_', " "),
            num(t.duration_s)
        );
    }
    outln!(
        "link: {} frames sent, {} delivered, {} rejected",
        r.link.frames_sent,
        r.link.frames_delivered,
        r.link.frames_rejected
    );
}

/// The simulation's truth for the console: each mover's footprint (a real run knows only
/// the station's tracks).
fn movers_json(world: &World) -> serde_json::Value {
    let t_s = world.t_us as f64 / 1e6;
    let movers = world.movers.states(t_s).map(|m| {
        let (length, width, round) = match m.shape {
            MoverShape::Circle { radius } => (2.0 * radius, 2.0 * radius, true),
            MoverShape::Rectangle { length, width } => (length, width, false),
        };
        serde_json::json!({
            "at": [m.position.x, m.position.y],
            "heading": m.heading,
            "size": [length, width],
            "round": round,
        })
    });
    serde_json::Value::Array(movers.collect())
}
