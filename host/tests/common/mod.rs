//! Shared by the CLI tests.
#![allow(dead_code)]

pub mod browser;
pub mod bus;
pub mod fleet;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output};

/// `basestation`, with no fleet key and no log filter from the environment.
pub fn basestation() -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_basestation"));
    command
        .env_remove("SWEEPER_FLEET_KEY")
        .env_remove("SWEEPER_KEY_FILE")
        .env_remove("RUST_LOG");
    command
}

/// A fresh scratch directory for test `name`.
pub fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `basestation sim SCENARIO ARGS…` with its report, figure and recording in `dir`
/// (`report.json`, `figure.svg`, `run.mcap`): its output and the report's path.
pub fn sim_into(dir: &Path, scenario: &str, args: &[&str]) -> (Output, PathBuf) {
    let report = dir.join("report.json");
    let out = basestation()
        .args(["sim", scenario])
        .args(args)
        .arg("--report")
        .arg(&report)
        .arg("--plot")
        .arg(dir.join("figure.svg"))
        .arg("--mcap")
        .arg(dir.join("run.mcap"))
        .output()
        .unwrap();
    (out, report)
}

/// Reads `child`'s standard error up to the first line that starts with `prefix` and
/// returns that line, trimmed; its standard error is drained after that (a closed pipe
/// would end the process at its next log line). Panics, saying `what`, if it ends first.
pub fn stderr_line(child: &mut Child, prefix: &str, what: &str) -> String {
    use std::io::BufRead;
    let mut stderr = std::io::BufReader::new(child.stderr.take().expect("a piped stderr"));
    let found = loop {
        let mut line = String::new();
        assert!(stderr.read_line(&mut line).unwrap() > 0, "{what}");
        if line.starts_with(prefix) {
            break line.trim().to_string();
        }
    };
    std::thread::spawn(move || std::io::copy(&mut stderr, &mut std::io::sink()));
    found
}

/// A child process killed when dropped (a failing test leaves nothing running).
pub struct Killed(pub Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// `basestation decode FILE` with the fleet key `key_hex`: one JSON value per frame.
pub fn decode(path: &Path, key_hex: &str) -> Vec<serde_json::Value> {
    let out = Command::new(env!("CARGO_BIN_EXE_basestation"))
        .arg("decode")
        .arg(path)
        .env("SWEEPER_FLEET_KEY", key_hex)
        .env_remove("SWEEPER_KEY_FILE")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// The shipped Foxglove layout shows this recording: every topic its panels name is a
/// channel of it (robots beyond this run's three excepted: the layout has room for a
/// 7-follower V, and the topics in `may_lack`), and every plotted field is in that
/// channel's schema.
pub fn assert_layout_fits(schemas: &BTreeMap<String, Vec<u8>>, may_lack: &[&str]) {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/foxglove-layout.json");
    let layout: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let mut named = Vec::new();
    for (panel, config) in layout["configById"].as_object().unwrap() {
        if let Some(topics) = config["topics"].as_object() {
            named.extend(topics.keys().map(|t| (panel, t.clone(), None)));
        }
        if let Some(t) = config["topicToRender"].as_str() {
            named.push((panel, t.to_string(), None));
        }
        for p in config["paths"].as_array().into_iter().flatten() {
            let value = p["value"].as_str().unwrap();
            let (topic, field) = value.split_once('.').unwrap();
            named.push((panel, topic.to_string(), Some(field.to_string())));
        }
    }
    let absent_robot = |t: &str| {
        t.strip_prefix("/robot_")
            .and_then(|r| r.split('/').next())
            .and_then(|id| id.parse::<u32>().ok())
            .is_some_and(|id| id >= 3)
    };
    let mut checked = 0;
    for (panel, topic, field) in named {
        if absent_robot(&topic)
            || (may_lack.contains(&topic.as_str()) && !schemas.contains_key(&topic))
        {
            continue;
        }
        let schema = schemas
            .get(&topic)
            .unwrap_or_else(|| panic!("layout panel {panel} shows {topic}: not recorded"));
        if let Some(field) = field {
            let name = field.as_bytes();
            assert!(
                schema.windows(name.len()).any(|w| w == name),
                "layout panel {panel} plots {topic}.{field}: not in its schema"
            );
        }
        checked += 1;
    }
    assert!(checked >= 8, "{checked} layout references checked");
}

/// Every channel of the MCAP recording at `path`: its topic, its schema's name and
/// data, and how many messages it has.
pub fn channels(path: &Path) -> std::collections::BTreeMap<String, (String, Vec<u8>, u64)> {
    let bytes = std::fs::read(path).unwrap();
    let mut out = std::collections::BTreeMap::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let (name, data) = m
            .channel
            .schema
            .as_ref()
            .map(|s| (s.name.clone(), s.data.to_vec()))
            .unwrap_or_default();
        out.entry(m.channel.topic.clone())
            .or_insert((name, data, 0))
            .2 += 1;
    }
    out
}
