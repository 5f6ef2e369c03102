//! `paired`: the same generated worlds through two `basestation` binaries (or one with two
//! sets of flags), side by side, and a table per suite of what changed. This is how a
//! change to the fleet's manners is judged: a world's intrusion swings by seconds with
//! any change anywhere, so only paired runs over hundreds of worlds pin a difference.
//!
//! ```text
//! cargo run --release -p e2e --bin paired -- \
//!     --old "/tmp/before/basestation" --new target/release/basestation \
//!     --suites streets --first 1701 --count 576
//! ```
//!
//! Each side runs `BIN [ARGS] sim WORLD --seed N --report …` (the worlds written to
//! `OUT/worlds/`, the reports to `OUT/old/` and `OUT/new/`; a report already there is
//! kept, so an interrupted run resumes). `--old "BIN --baseline parked"` gives a side its
//! own flags.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use clap::Parser;
use e2e::generate::Generated;
use e2e::judge::{self, Run};
use e2e::suites::{self, Suite};

#[derive(Parser, Debug)]
#[command(about = "The same generated worlds through two basestation binaries, side by side")]
struct Args {
    /// The first side: a `basestation` binary, and flags for its `sim` after it.
    #[arg(long)]
    old: String,
    /// The second side.
    #[arg(long)]
    new: String,
    /// Suites: a group (`streets`, `crowds`, `static`), suite names, or `all`,
    /// comma-separated.
    #[arg(long, default_value = "streets")]
    suites: String,
    /// The first seed, and how many seeds per suite.
    #[arg(long, default_value_t = 1)]
    first: u64,
    #[arg(long, default_value_t = 4)]
    count: u64,
    /// Runs at once (one core each).
    #[arg(long, default_value_t = 2)]
    jobs: usize,
    /// Where the worlds and reports go.
    #[arg(long, default_value = "target/paired")]
    out: PathBuf,
}

/// One side: the binary and its extra `sim` flags.
struct Side {
    name: &'static str,
    program: String,
    flags: Vec<String>,
}

impl Side {
    fn new(name: &'static str, words: &str) -> Result<Self, String> {
        let mut it = words.split_whitespace().map(str::to_string);
        let program = it.next().ok_or(format!("--{name}: no binary"))?;
        Ok(Self {
            name,
            program,
            flags: it.collect(),
        })
    }

    /// Runs `world` (seed `seed`) unless its report is there; the report's path.
    fn run(&self, out: &Path, world: &Path, name: &str, seed: u64) -> Result<PathBuf, String> {
        let dir = out.join(self.name);
        let report = dir.join(format!("{name}.json"));
        if report.exists() {
            return Ok(report);
        }
        let scratch = |ext: &str| dir.join(format!("{name}.scratch.{ext}"));
        let status = Command::new(&self.program)
            .arg("sim")
            .arg(world)
            .arg("--seed")
            .arg(seed.to_string())
            .arg("--report")
            .arg(dir.join(format!("{name}.partial.json")))
            .arg("--plot")
            .arg(scratch("svg"))
            .arg("--mcap")
            .arg(scratch("mcap"))
            .args(&self.flags)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .status()
            .map_err(|e| format!("{}: {e}", self.program))?;
        let _ = std::fs::remove_file(scratch("svg"));
        let _ = std::fs::remove_file(scratch("mcap"));
        // 0 reached, 3 not reached: both wrote a report.
        if !matches!(status.code(), Some(0) | Some(3)) {
            return Err(format!("{} on {name}: {status}", self.program));
        }
        std::fs::rename(dir.join(format!("{name}.partial.json")), &report)
            .map_err(|e| format!("{name}: {e}"))?;
        Ok(report)
    }
}

/// One world to run.
struct Job {
    suite: &'static str,
    seed: u64,
    world: Generated,
}

fn jobs(suites: &[&'static Suite], seeds: std::ops::RangeInclusive<u64>) -> Vec<Job> {
    suites
        .iter()
        .flat_map(|s| {
            seeds.clone().map(move |seed| Job {
                suite: s.name,
                seed,
                world: (s.make)(seed),
            })
        })
        .collect()
}

/// Runs every job through both sides on `n` threads; each finished world's pair of runs.
fn run_all(
    args: &Args,
    sides: &[Side; 2],
    jobs: &[Job],
) -> Result<Vec<(String, Run, Run)>, String> {
    for d in ["worlds", "old", "new"] {
        std::fs::create_dir_all(args.out.join(d)).map_err(|e| e.to_string())?;
    }
    let next = AtomicUsize::new(0);
    let done = Mutex::new(Vec::new());
    let failed = Mutex::new(Vec::new());
    std::thread::scope(|scope| {
        for _ in 0..args.jobs.max(1) {
            scope.spawn(|| {
                while let Some(job) = jobs.get(next.fetch_add(1, Ordering::SeqCst)) {
                    match run_pair(&args.out, sides, job) {
                        Ok(pair) => done.lock().expect("not poisoned").push(pair),
                        Err(e) => failed.lock().expect("not poisoned").push(e),
                    }
                    let n = done.lock().expect("not poisoned").len();
                    eprint!("\r{n} of {} worlds", jobs.len());
                }
            });
        }
    });
    eprintln!();
    let failed = failed.into_inner().expect("not poisoned");
    if !failed.is_empty() {
        return Err(failed.join("\n"));
    }
    Ok(done.into_inner().expect("not poisoned"))
}

fn run_pair(out: &Path, sides: &[Side; 2], job: &Job) -> Result<(String, Run, Run), String> {
    let path = out.join("worlds").join(format!("{}.toml", job.world.name));
    std::fs::write(&path, &job.world.toml).map_err(|e| e.to_string())?;
    let name = &job.world.name;
    let load = |side: &Side| -> Result<Run, String> {
        let report = side.run(out, &path, name, job.seed)?;
        let text = std::fs::read_to_string(&report).map_err(|e| e.to_string())?;
        Run::parse(name, &text)
    };
    Ok((job.suite.to_string(), load(&sides[0])?, load(&sides[1])?))
}

fn main() -> std::process::ExitCode {
    let args = Args::parse();
    let result = (|| -> Result<String, String> {
        let sides = [Side::new("old", &args.old)?, Side::new("new", &args.new)?];
        let suites = suites::named(&args.suites)?;
        let seeds = args.first..=args.first + args.count.max(1) - 1;
        let jobs = jobs(&suites, seeds);
        let pairs = run_all(&args, &sides, &jobs)?;
        let order: Vec<&str> = suites.iter().map(|s| s.name).collect();
        Ok(judge::paired_table(&order, &pairs))
    })();
    match result {
        Ok(table) => {
            println!("{table}");
            std::process::ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}
