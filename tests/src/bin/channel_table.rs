//! `channel_table`: fleets of growing size on one shared radio channel, for each preset and
//! access scheme, on generated open lots; per run the leader state's age at the followers
//! (p99), the channel's collisions and use, the uplink's delivery, the followers' error and
//! the contacts; then, per preset and scheme, the largest fleet that kept the leader
//! state's age p99 ≤ 150 ms and every follower within 0.35 m after joining, with the goal
//! reached and no contact, on every seed.
//!
//! ```text
//! cargo run --release -p e2e --bin channel_table -- --seeds 2
//! cargo run --release -p e2e --bin channel_table -- --seeds 2 --rows 3 --followers 2,4,7,9,15,31
//! ```
//!
//! `--rows N` gives the generated lots a formation in rows of N abreast instead of a V.
//! Runs `BIN sim WORLD --seed N --report …` (worlds in `OUT/worlds/`, reports in
//! `OUT/reports/`; a report already there is kept, so an interrupted run resumes).

use std::path::PathBuf;
use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use clap::Parser;
use serde_json::Value;

#[derive(Parser, Debug)]
#[command(about = "Fleets of growing size on one shared radio channel, per preset and access")]
struct Args {
    /// The `basestation` binary.
    #[arg(long, default_value = "target/release/basestation")]
    bin: PathBuf,
    /// Radio presets, comma-separated.
    #[arg(
        long,
        default_value = "sik-64k,multipoint-250k,lora-sf7-125,lora-sf7-250,lora-sf7-500,esp-now"
    )]
    presets: String,
    /// Access schemes, comma-separated.
    #[arg(long, default_value = "scheduled,csma,aloha")]
    access: String,
    /// Fleet sizes as numbers of followers, comma-separated.
    #[arg(long, default_value = "2,4,7,9,15")]
    followers: String,
    /// The first seed, and how many.
    #[arg(long, default_value_t = 1)]
    first: u64,
    #[arg(long, default_value_t = 1)]
    seeds: u64,
    /// Runs at once (one core each).
    #[arg(long, default_value_t = 2)]
    jobs: usize,
    #[arg(long, default_value = "target/channel-table")]
    out: PathBuf,
    /// The formation in rows of this many abreast instead of the generated V.
    #[arg(long)]
    rows: Option<usize>,
}

/// The issue's bounds: leader-state age p99 and each follower's error after joining.
const AGE_P99_MAX_MS: f64 = 150.0;
const ERROR_MAX_M: f64 = 0.35;

#[derive(Debug, Clone)]
struct Job {
    preset: String,
    access: String,
    followers: usize,
    seed: u64,
}

impl Job {
    fn name(&self) -> String {
        format!(
            "{}-{}-{}f-seed{}",
            self.preset, self.access, self.followers, self.seed
        )
    }
}

/// One run's figures, from its report.
#[derive(Debug, Clone)]
struct Figures {
    goal: bool,
    contacts: u64,
    /// The worst follower's leader-state age p99, ms (`None`: none reached it).
    age_p99_ms: Option<f64>,
    worst_error_m: Option<f64>,
    collisions: u64,
    utilisation: f64,
    /// The worst robot's uplink delivery.
    uplink: f64,
    follower_every: Option<u64>,
}

impl Figures {
    fn parse(r: &Value) -> Self {
        let c = &r["link"]["channel"];
        let robots = c["robots"].as_array().cloned().unwrap_or_default();
        let leader = r["robots"]
            .as_array()
            .and_then(|rs| rs.iter().find(|x| x["role"] == "leader"))
            .and_then(|x| x["id"].as_u64());
        let followers = robots.iter().filter(|x| x["id"].as_u64() != leader);
        let age_p99_ms = followers
            .map(|x| {
                x["leader_state_age_ms_p99"]
                    .as_f64()
                    .unwrap_or(f64::INFINITY)
            })
            .fold(None, |m: Option<f64>, a| Some(m.map_or(a, |m| m.max(a))))
            .filter(|a| a.is_finite());
        let worst_error_m = r["robots"]
            .as_array()
            .into_iter()
            .flatten()
            .filter_map(|x| x["max_tracking_error_m"].as_f64())
            .fold(None, |m: Option<f64>, e| Some(m.map_or(e, |m| m.max(e))));
        Self {
            goal: r["goal_reached"].as_bool().unwrap_or(false),
            contacts: r["collisions"].as_u64().unwrap_or(0),
            age_p99_ms,
            worst_error_m,
            collisions: c["collisions"].as_u64().unwrap_or(0),
            utilisation: c["utilisation"].as_f64().unwrap_or(0.0),
            uplink: robots
                .iter()
                .map(|x| x["uplink_delivery"].as_f64().unwrap_or(0.0))
                .fold(1.0, f64::min),
            follower_every: c["schedule"]["follower_every_periods"].as_u64(),
        }
    }

    fn passes(&self) -> bool {
        self.goal
            && self.contacts == 0
            && self.age_p99_ms.is_some_and(|a| a <= AGE_P99_MAX_MS)
            && self.worst_error_m.is_some_and(|e| e <= ERROR_MAX_M)
    }
}

fn list(s: &str) -> Vec<String> {
    s.split(',')
        .map(|x| x.trim().to_string())
        .filter(|x| !x.is_empty())
        .collect()
}

/// Writes the world, runs it (unless its report is there) and reads the figures.
fn run(args: &Args, job: &Job) -> Result<Figures, String> {
    let name = match args.rows {
        Some(n) => format!("{}-rows{n}", job.name()),
        None => job.name(),
    };
    let world = args.out.join("worlds").join(format!("{name}.toml"));
    let report = args.out.join("reports").join(format!("{name}.json"));
    if !report.exists() {
        let mut g = e2e::generate::open_lot(job.seed, job.followers);
        if let Some(n) = args.rows {
            g = g.in_rows(n)?;
        }
        let toml = g.toml.replacen(&g.name, &name, 1);
        let text = format!(
            "{}\n[link]\nradio = \"{}\"\naccess = \"{}\"\n",
            toml, job.preset, job.access
        );
        std::fs::write(&world, text).map_err(|e| format!("{}: {e}", world.display()))?;
        let scratch = args.out.join("scratch");
        let out = Command::new(&args.bin)
            .arg("sim")
            .arg(&world)
            .args(["--seed", &job.seed.to_string(), "--report"])
            .arg(&report)
            .arg("--plot")
            .arg(scratch.join(format!("{name}.svg")))
            .arg("--mcap")
            .arg(scratch.join(format!("{name}.mcap")))
            .output()
            .map_err(|e| format!("{}: {e}", args.bin.display()))?;
        let _ = std::fs::remove_file(scratch.join(format!("{name}.mcap")));
        if !report.exists() {
            return Err(format!(
                "{name}: no report ({})",
                String::from_utf8_lossy(&out.stderr).trim()
            ));
        }
    }
    let text = std::fs::read_to_string(&report).map_err(|e| format!("{name}: {e}"))?;
    let json: Value = serde_json::from_str(&text).map_err(|e| format!("{name}: {e}"))?;
    Ok(Figures::parse(&json))
}

fn cell(v: Option<f64>, digits: usize) -> String {
    v.map_or("—".into(), |x| format!("{x:.digits$}"))
}

/// One preset's table: a row per access and fleet size (the worst seed's figures).
fn table(preset: &str, rows: &[(Job, Figures)]) {
    println!("\n#### {preset}\n");
    println!("| access | robots | age p99 (ms) | collisions | air used | uplink delivery | follower slot every | worst error (m) | goal | contacts | within bounds |");
    println!("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |");
    for (job, f) in rows.iter().filter(|(j, _)| j.preset == preset) {
        println!(
            "| {} | {} | {} | {} | {:.0} % | {:.2} | {} | {} | {} | {} | {} |",
            job.access,
            job.followers + 1,
            cell(f.age_p99_ms, 0),
            f.collisions,
            f.utilisation * 100.0,
            f.uplink,
            f.follower_every
                .map_or("—".into(), |k| format!("{k} period(s)")),
            cell(f.worst_error_m, 2),
            if f.goal { "yes" } else { "no" },
            f.contacts,
            if f.passes() { "yes" } else { "no" }
        );
    }
}

fn main() -> Result<(), String> {
    let args = Args::parse();
    for dir in ["worlds", "reports", "scratch"] {
        std::fs::create_dir_all(args.out.join(dir)).map_err(|e| e.to_string())?;
    }
    let followers: Vec<usize> = list(&args.followers)
        .iter()
        .map(|f| {
            f.parse()
                .map_err(|_| format!("--followers: {f} is not a number"))
        })
        .collect::<Result<_, _>>()?;
    let mut jobs = Vec::new();
    for preset in list(&args.presets) {
        for access in list(&args.access) {
            for &f in &followers {
                for seed in args.first..args.first + args.seeds {
                    jobs.push(Job {
                        preset: preset.clone(),
                        access: access.clone(),
                        followers: f,
                        seed,
                    });
                }
            }
        }
    }
    let results = run_all(&args, &jobs);
    // The worst seed stands for each cell: the one failing, else the oldest leader state.
    let mut rows: Vec<(Job, Figures)> = Vec::new();
    for (job, f) in results {
        let f = f?;
        match rows.iter_mut().find(|(j, _)| {
            (&j.preset, &j.access, j.followers) == (&job.preset, &job.access, job.followers)
        }) {
            Some((_, w)) if !w.passes() => {}
            Some((_, w)) => {
                if !f.passes() || f.age_p99_ms > w.age_p99_ms {
                    *w = f;
                }
            }
            None => rows.push((job, f)),
        }
    }
    for preset in list(&args.presets) {
        table(&preset, &rows);
    }
    largest(&args, &rows, &followers);
    Ok(())
}

fn run_all(args: &Args, jobs: &[Job]) -> Vec<(Job, Result<Figures, String>)> {
    let next = AtomicUsize::new(0);
    let out = Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..args.jobs.max(1) {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(job) = jobs.get(i) else { break };
                let f = run(args, job);
                eprintln!("{}/{} {}", i + 1, jobs.len(), job.name());
                out.lock().expect("not poisoned").push((i, job.clone(), f));
            });
        }
    });
    let mut out = out.into_inner().expect("not poisoned");
    out.sort_by_key(|(i, ..)| *i);
    out.into_iter().map(|(_, j, f)| (j, f)).collect()
}

/// Per preset and access: the largest fleet within bounds, the sizes below it all within.
fn largest(args: &Args, rows: &[(Job, Figures)], followers: &[usize]) {
    println!("\n| radio | {} |", list(&args.access).join(" | "));
    println!("| --- |{}", " --- |".repeat(list(&args.access).len()));
    for preset in list(&args.presets) {
        let cells: Vec<String> = list(&args.access)
            .iter()
            .map(|access| {
                let mut best = None;
                for &f in followers {
                    let ok = rows.iter().any(|(j, x)| {
                        j.preset == preset && &j.access == access && j.followers == f && x.passes()
                    });
                    if !ok {
                        break;
                    }
                    best = Some(f + 1);
                }
                best.map_or("none".into(), |n| format!("{n} robots"))
            })
            .collect();
        println!("| {preset} | {} |", cells.join(" | "));
    }
}
