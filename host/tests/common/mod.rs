//! Shared by the CLI tests.
#![allow(dead_code)]

pub mod fleet;

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
