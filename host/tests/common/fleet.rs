//! The real-time fleet: `basestation run` and `basestation robots` as processes in a
//! scratch site, and what their reports and traces say.

use std::io::BufRead;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

/// The fleet key of every scratch site.
pub const KEY_HEX: &str = "5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a";

/// How much larger a follower's max tracking error after join may be in real time than in
/// `sim`: issue 13's bound. Measured on the paper's passage (13 runs, docs/operating.md
/// #rehearsing-without-robots): −0.04 to +0.03 m.
pub const REAL_TIME_MARGIN_M: f64 = 0.05;
/// The same with fixes forwarded from a localization source (NMEA, the short passage):
/// measured +0.02 to +0.055 m (2026-11-30), +0.05 m (2026-12-01, 4 s shape changes); the
/// fix reaches the robot up to a station period later than the simulated receiver's.
pub const FORWARDED_FIX_MARGIN_M: f64 = 0.10;

/// The paper's passage, shortened for real-time tests: the same 3 m gap in a 2 m thick
/// wall, the fleet starting 6 m before it, the goal 6 m after it; placed on the globe for
/// NMEA, with tighter localization limits.
pub const SHORT_PASSAGE: &str = include_str!("../fixtures/short-passage.toml");

/// A scratch directory with the fleet key (mode 600) and the short passage.
pub struct Site {
    pub dir: PathBuf,
}

impl Site {
    pub fn new(name: &str) -> Self {
        use std::os::unix::fs::PermissionsExt;
        let dir = std::env::temp_dir().join(format!("operate-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let key = dir.join("fleet.key");
        std::fs::write(&key, format!("{KEY_HEX}\n")).unwrap();
        std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o600)).unwrap();
        std::fs::write(dir.join("short-passage.toml"), SHORT_PASSAGE).unwrap();
        Self { dir }
    }
    pub fn path(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }
}

/// A child process killed when dropped (a failing test leaves nothing running).
pub struct Process(pub Child, Option<std::sync::mpsc::Receiver<String>>);

impl Drop for Process {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

impl Process {
    pub fn start(site: &Site, args: &[&str]) -> Self {
        Self::start_keyed(&site.path("fleet.key"), args)
    }

    /// [`Process::start`] with the key in `key` (a site's other key).
    pub fn start_keyed(key: &Path, args: &[&str]) -> Self {
        let child = super::basestation()
            .args(args)
            .arg("--key-file")
            .arg(key)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        Self(child, None)
    }

    /// `robots`' first line: how to reach it (`udp ADDR` or `pty PATH`).
    pub fn address(&mut self) -> String {
        let mut line = String::new();
        BufReader::new(self.0.stdout.as_mut().unwrap())
            .read_line(&mut line)
            .unwrap();
        line.split_whitespace()
            .nth(1)
            .expect("an address")
            .to_string()
    }

    /// The console's URL `run --console` prints first on standard error (the rest of
    /// standard error is kept for [`Process::finish`]).
    pub fn console_url(&mut self) -> String {
        let mut reader = BufReader::new(self.0.stderr.take().unwrap());
        let mut line = String::new();
        while !line.starts_with("console: ") {
            line.clear();
            assert!(reader.read_line(&mut line).unwrap() > 0, "no console URL");
        }
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut rest = String::new();
            let _ = std::io::Read::read_to_string(&mut reader, &mut rest);
            let _ = tx.send(rest);
        });
        self.1 = Some(rx);
        line.trim()
            .strip_prefix("console: ")
            .unwrap_or_else(|| panic!("no console URL: {line}"))
            .to_string()
    }

    /// Waits for the process to end by itself, successfully (exit code 0: `run`'s goal
    /// reached); its stderr.
    pub fn finish(self, limit: Duration) -> String {
        self.finish_with(limit, 0)
    }

    /// Waits for the process to end by itself with exit code `code` (README.md, exit
    /// codes); its stderr.
    pub fn finish_with(mut self, limit: Duration, code: i32) -> String {
        let start = Instant::now();
        while self.0.try_wait().unwrap().is_none() {
            assert!(start.elapsed() < limit, "still running after {limit:?}");
            std::thread::sleep(Duration::from_millis(100));
        }
        let err = match self.1.take() {
            Some(rest) => rest.recv().unwrap_or_default(),
            None => {
                let mut err = String::new();
                std::io::Read::read_to_string(self.0.stderr.as_mut().unwrap(), &mut err).unwrap();
                err
            }
        };
        assert_eq!(self.0.wait().unwrap().code(), Some(code), "{err}");
        err
    }
}

pub fn json(path: &Path) -> Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}

/// Follower id → max tracking error after its join.
pub fn follower_errors(report: &Value) -> Vec<(u64, f64)> {
    report["robots"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|r| r["role"] == "follower")
        .map(|r| {
            (
                r["id"].as_u64().unwrap(),
                r["max_tracking_error_m"]
                    .as_f64()
                    .expect("the follower joined"),
            )
        })
        .collect()
}

/// `sim` of the same scenario and seed: its report.
pub fn sim_report(site: &Site, scenario: &str) -> Value {
    let dir = site.path("sim");
    std::fs::create_dir_all(&dir).unwrap();
    let (out, report) = super::sim_into(&dir, scenario, &[]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    json(&report)
}

/// A free local UDP port (bound, then released for the process under test).
pub fn free_udp_port() -> u16 {
    std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// The robots' trace: (t, id, x, y, v) per robot per sample.
pub fn trace(path: &Path) -> Vec<(f64, u64, f64, f64, f64)> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (t, id, x, y, v) = (col("t"), col("id"), col("x"), col("y"), col("v"));
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (
                f[t].parse().unwrap(),
                f[id].parse().unwrap(),
                f[x].parse().unwrap(),
                f[y].parse().unwrap(),
                f[v].parse().unwrap(),
            )
        })
        .collect()
}

/// How far each robot drove between `from` and `to` (s, robots' clock), and its speed at
/// `to`.
pub fn driven(trace: &[(f64, u64, f64, f64, f64)], from: f64, to: f64) -> Vec<(u64, f64, f64)> {
    let mut ids: Vec<u64> = trace.iter().map(|s| s.1).collect();
    ids.sort();
    ids.dedup();
    ids.into_iter()
        .map(|id| {
            let own: Vec<_> = trace
                .iter()
                .filter(|s| s.1 == id && s.0 >= from && s.0 <= to)
                .collect();
            let path = own
                .windows(2)
                .map(|w| (w[1].2 - w[0].2).hypot(w[1].3 - w[0].3))
                .sum();
            (id, path, own.last().map_or(f64::NAN, |s| s.4))
        })
        .collect()
}

pub fn events(run_report: &Value) -> Vec<(f64, String, Option<u64>)> {
    run_report["station_events"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| {
            (
                e["at_s"].as_f64().unwrap(),
                e["event"].as_str().unwrap().to_string(),
                e["robot"].as_u64(),
            )
        })
        .collect()
}

/// `robots` over UDP with its report and trace in the site's directory, and `extra`
/// arguments: the process, its report's path, its trace's path.
/// `run SCENARIO --udp AT --bind 127.0.0.1:0 EXTRA…` in `site`: the station driving the
/// robots that listen at `at` (`robots_over_udp`'s address).
pub fn run_over_udp(site: &Site, scenario: &str, at: &str, extra: &[&str]) -> Process {
    let args = ["run", scenario, "--udp", at, "--bind", "127.0.0.1:0"];
    Process::start(site, &[&args[..], extra].concat())
}

pub fn robots_over_udp(site: &Site, scenario: &str, extra: &[&str]) -> (Process, PathBuf, PathBuf) {
    let (report, trace) = (site.path("robots.json"), site.path("robots.csv"));
    let mut args = vec!["robots", scenario, "--udp", "127.0.0.1:0", "--report"];
    args.extend([report.to_str().unwrap(), "--trace", trace.to_str().unwrap()]);
    args.extend(extra);
    (Process::start(site, &args), report, trace)
}

/// `lines` sealed as source `source` of the scratch sites' fleet key would seal them
/// (`base_station::seal`), with `counter`.
pub fn seal(source: &str, lines: &str, counter: u64) -> String {
    let master = protocol::MasterKey::from_hex(KEY_HEX).unwrap();
    base_station::seal::SourceKey::derive(&master, source).seal(lines, counter)
}

/// The wall clock, µs since 1970: a sealing source's counter.
pub fn unix_us() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_micros() as u64
}

/// A van parked across the way, not on the station's map (`[map] unmapped`: only the
/// simulated site has it).
pub const VAN_ON_THE_WAY: &str = include_str!("../fixtures/van-on-the-way.toml");
