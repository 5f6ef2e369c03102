//! `basestation`: the operator's program.
//!
//! Module map: [`commands`], one module per subcommand (run, sim, robots, check, decode,
//! robot-config, feed-key, feed-relay, ops, router) and the flag groups they share; [`live`], what runs
//! beside a live run (the console, the site's feeds, the recording and live stream, the
//! loop's timing); [`bus`], the city's bus (Zenoh) and its operations view; [`key`], the
//! fleet key and its one check.

mod bus;
mod commands;
mod key;
mod live;
mod pty;

use std::process::ExitCode;

use clap::{Parser, Subcommand};
use commands::outcome::Outcome;
use tracing_subscriber::EnvFilter;

/// The sanitation fleet's base station.
#[derive(Parser)]
#[command(name = "basestation", version, about)]
struct Cli {
    /// More log output (-v info, -vv debug, -vvv trace); RUST_LOG overrides.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Drive real robots over a serial radio modem or UDP.
    Run(commands::run::RunArgs),
    /// Validate a scenario or site file and print a summary.
    Check(commands::check::CheckArgs),
    /// Decode a captured byte stream or a recording's radio channel: one JSON line per frame.
    Decode(commands::decode::DecodeArgs),
    /// Simulate the fleet (software in the loop) and report against the paper.
    Sim(commands::sim::SimArgs),
    /// Run a scenario's simulated robots in real time behind UDP or a pseudo-terminal, for
    /// `run` to drive as it drives real robots.
    Robots(commands::robots::RobotsArgs),
    /// Write a robot's configuration page (id, role, fleet key) for flashing.
    RobotConfig(commands::robot_config::RobotConfigArgs),
    /// Write the key of one localization or scan source of the site.
    FeedKey(commands::feed_key::FeedKeyArgs),
    /// Seal lines (standard input, a serial port, a TCP stream) with a source's key and
    /// send them to the base station's feed.
    FeedRelay(commands::feed_relay::FeedRelayArgs),
    /// The operations view: every formation on the bus (Zenoh) on one page, with their
    /// alerts and commands.
    Ops(commands::ops::OpsArgs),
    /// A Zenoh router for the stations and `ops` to meet at (what `zenohd` does, from the
    /// same configuration file, without its plugins).
    Router(commands::ops::RouterArgs),
}

fn main() -> ExitCode {
    use clap::{CommandFactory, FromArgMatches};
    // `-V` says which revision it was built from: a field report names the build.
    let version: &'static str = Box::leak(
        format!(
            "{} (revision {})",
            env!("CARGO_PKG_VERSION"),
            base_station::recording::GIT_REVISION
        )
        .into_boxed_str(),
    );
    let matches = Cli::command().version(version).get_matches();
    let cli = match Cli::from_arg_matches(&matches) {
        Ok(cli) => cli,
        Err(e) => e.exit(),
    };
    // A live run says how it goes at the default level: the station's progress (links,
    // fleet ready, shape changes, yielding) and what is wrong (diagnosis, warnings).
    let live = matches!(
        cli.command,
        Command::Run(_) | Command::Robots(_) | Command::Ops(_) | Command::Router(_)
    );
    // Zenoh's own retries and reconnections are the bus's business: the station says in its
    // own words when the bus is away (`bus: …`), Zenoh's details from -vv on.
    const QUIET_BUS: &str = "zenoh=error,zenoh_transport=error,zenoh_link_commons=error,\
                             zenoh_link_tcp=error,zenoh_plugin_trait=error,zenoh_config=error";
    let default = match cli.verbose {
        0 if live => format!(
            "warn,base_station::station=info,basestation::commands::run=info,\
             basestation::bus=info,{QUIET_BUS}"
        ),
        0 => format!("warn,{QUIET_BUS}"),
        1 => format!("info,{QUIET_BUS}"),
        2 => "debug".into(),
        _ => "trace".into(),
    };
    let filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new(default));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        // No colour codes in a log piped to a file.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    // How `run` and `sim` ended is their exit code (commands/outcome.rs); the rest
    // succeed or fail.
    let done = |r: anyhow::Result<()>| r.map(|()| None);
    let result = match cli.command {
        Command::Run(args) => commands::run::run(args).map(Some),
        Command::Sim(args) => commands::sim::run(args).map(Some),
        Command::Check(args) => done(commands::check::run(args)),
        Command::Decode(args) => done(commands::decode::run(args)),
        Command::Robots(args) => done(commands::robots::run(args)),
        Command::RobotConfig(args) => done(commands::robot_config::run(args)),
        Command::FeedKey(args) => done(commands::feed_key::run(args)),
        Command::FeedRelay(args) => done(commands::feed_relay::run(args)),
        Command::Ops(args) => done(commands::ops::run(args)),
        Command::Router(args) => done(commands::ops::router(args)),
    };
    match result {
        Ok(outcome) => outcome.map_or(ExitCode::SUCCESS, Outcome::exit_code),
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(commands::outcome::BAD_INPUT)
        }
    }
}
