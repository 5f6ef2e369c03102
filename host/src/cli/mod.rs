//! One module per subcommand, and what they share: scenarios and the fleet key.

pub mod check;
pub mod console;
pub mod decode;
pub mod feed;
pub mod feed_key;
pub mod feed_relay;
pub mod live_gate;
pub mod localization;
pub mod record;
pub mod robot_config;
pub mod robots;
pub mod run;
pub mod scan;
pub mod sim;
pub mod timing;

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use base_station::scenario::Scenario;
use clap::Args;
use protocol::MasterKey;
use zeroize::Zeroizing;

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
        // Read no more than a scenario may hold: a huge file is refused, not loaded.
        let max = base_station::scenario::MAX_FILE_BYTES as u64;
        let mut src = String::new();
        std::fs::File::open(path)
            .and_then(|f| {
                std::io::Read::read_to_string(&mut std::io::Read::take(f, max + 1), &mut src)
            })
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

/// The wall clock, ms since the Unix epoch: for stamping real runs, never for simulated
/// results.
pub fn unix_ms() -> anyhow::Result<u64> {
    Ok(std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_err(|_| anyhow::anyhow!("the system clock is before 1970: set it before a run"))?
        .as_millis() as u64)
}

/// Creates the directory `path` goes in, if it names one.
pub fn create_parent(path: &Path) -> anyhow::Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    Ok(())
}

/// A run's report as JSON (`sim`, `robots`).
pub fn write_report(report: &hil_sim::report::Report, path: &Path) -> anyhow::Result<()> {
    std::fs::write(path, serde_json::to_string_pretty(report)? + "\n")
        .with_context(|| format!("cannot write {}", path.display()))
}

/// A run's CSV trace (`sim --trace`, `robots --trace`).
pub fn write_trace(world: &hil_sim::world::World, path: &Path) -> anyhow::Result<()> {
    let roles: Vec<_> = world.robots.iter().map(|r| (r.id, r.role)).collect();
    let file =
        std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    hil_sim::trace::write_csv(&world.recorder, &roles, std::io::BufWriter::new(file))
        .with_context(|| format!("cannot write {}", path.display()))
}

/// Where the fleet key comes from. Never from the binary: a real run without one fails.
#[derive(Args, Debug, Clone)]
pub struct KeyArgs {
    /// File holding the fleet's master key: 64 hexadecimal digits.
    #[arg(long, env = "SWEEPER_KEY_FILE")]
    pub key_file: Option<PathBuf>,
}

impl KeyArgs {
    /// The fleet's master key from `--key-file`, `SWEEPER_KEY_FILE`, or
    /// `SWEEPER_FLEET_KEY` (hex), if any.
    pub fn load(&self) -> anyhow::Result<Option<MasterKey>> {
        let Some(hex) = self.load_hex()? else {
            return Ok(None);
        };
        Ok(Some(MasterKey::from_hex(&hex).context(self.source())?))
    }

    /// The key's text, zeroed when dropped.
    pub fn load_hex(&self) -> anyhow::Result<Option<Zeroizing<String>>> {
        if let Some(path) = &self.key_file {
            return read_key_file(path).map(Some);
        }
        Ok(std::env::var("SWEEPER_FLEET_KEY").ok().map(Zeroizing::new))
    }

    fn source(&self) -> String {
        match &self.key_file {
            Some(path) => format!("key file {}", path.display()),
            None => "SWEEPER_FLEET_KEY".into(),
        }
    }
}

/// The fleet's master key, or the one error every command that needs it gives.
pub fn require_key(key: &KeyArgs) -> anyhow::Result<MasterKey> {
    key.load()?.ok_or_else(|| {
        anyhow::anyhow!(
            "no fleet key: pass --key-file FILE or set SWEEPER_KEY_FILE or SWEEPER_FLEET_KEY \
             (64 hex digits; make one with  (umask 077; openssl rand -hex 32 > fleet.key))"
        )
    })
}

/// Largest key file read: a key is 64 hex digits and a newline.
const MAX_KEY_FILE: u64 = 1024;

/// Reads a key file as ssh reads a private key: only if nobody but its owner can read it,
/// and only if it is small enough to be one.
pub fn read_key_file(path: &Path) -> anyhow::Result<Zeroizing<String>> {
    use std::os::unix::fs::PermissionsExt;
    let meta = std::fs::metadata(path)
        .with_context(|| format!("cannot read the key file {}", path.display()))?;
    if !meta.is_file() || meta.len() > MAX_KEY_FILE {
        bail!(
            "{} is not a key file ({} bytes; a key is 64 hex digits)",
            path.display(),
            meta.len()
        );
    }
    let mode = meta.permissions().mode() & 0o777;
    if mode & 0o077 != 0 {
        bail!(
            "the key file {} can be read by others (mode {mode:03o}): run  chmod 600 {}",
            path.display(),
            path.display()
        );
    }
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read the key file {}", path.display()))?;
    Ok(Zeroizing::new(text))
}
