//! One module per subcommand, and what they share: scenarios and the fleet key.

pub mod check;
pub mod decode;
pub mod robot_config;
pub mod run;
pub mod sim;

use std::path::PathBuf;

use anyhow::{bail, Context};
use base_station::scenario::Scenario;
use clap::Args;
use protocol::FleetKey;

/// The scenarios shipped with the program, by name.
pub const SHIPPED: &[(&str, &str)] = &[
    (
        "paper-obstacles",
        include_str!("../../../scenarios/paper-obstacles.toml"),
    ),
    (
        "paper-passage",
        include_str!("../../../scenarios/paper-passage.toml"),
    ),
];

/// A scenario from a file, or a shipped one by name; refused, with every unreachable
/// waypoint named, when the fleet has no way to its goal.
pub fn load_scenario(arg: &str) -> anyhow::Result<Scenario> {
    let path = std::path::Path::new(arg);
    let (src, file) = if path.exists() {
        let src = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read {}", path.display()))?;
        (src, path.display().to_string())
    } else {
        match SHIPPED.iter().find(|(name, _)| *name == arg) {
            Some((name, src)) => (src.to_string(), format!("<shipped {name}>")),
            None => bail!(
                "{arg}: no such file, and not a shipped scenario ({})",
                SHIPPED.iter().map(|s| s.0).collect::<Vec<_>>().join(", ")
            ),
        }
    };
    let scenario = Scenario::parse(&src, &file)?;
    let problems = scenario.route_errors(&src, &file);
    if !problems.is_empty() {
        let lines: Vec<String> = problems.iter().map(ToString::to_string).collect();
        bail!(
            "{}\n{file}: no way for the fleet: refused before anything moves",
            lines.join("\n")
        );
    }
    Ok(scenario)
}

/// Where the fleet key comes from. Never from the binary: a real run without one fails.
#[derive(Args, Debug, Clone)]
pub struct KeyArgs {
    /// File holding the fleet key: 64 hexadecimal digits.
    #[arg(long, env = "SWEEPER_KEY_FILE")]
    pub key_file: Option<PathBuf>,
}

impl KeyArgs {
    /// The key from `--key-file`, `SWEEPER_KEY_FILE`, or `SWEEPER_FLEET_KEY` (hex), if any.
    pub fn load(&self) -> anyhow::Result<Option<FleetKey>> {
        if let Some(path) = &self.key_file {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("cannot read the key file {}", path.display()))?;
            let key = FleetKey::from_hex(&text)
                .with_context(|| format!("key file {}", path.display()))?;
            return Ok(Some(key));
        }
        if let Ok(hex) = std::env::var("SWEEPER_FLEET_KEY") {
            return Ok(Some(FleetKey::from_hex(&hex).context("SWEEPER_FLEET_KEY")?));
        }
        Ok(None)
    }
}
