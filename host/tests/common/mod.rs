//! Shared by the CLI tests.
#![allow(dead_code)]

pub mod fleet;

use std::path::Path;
use std::process::{Child, Command};

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
