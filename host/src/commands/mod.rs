//! One module per subcommand (the probe-rs layout), and what they share: scenarios,
//! files and the flag groups more than one takes. The live helpers they use while a run
//! goes on (console, feeds, recording) are in `crate::live`; the fleet key in `crate::key`.

pub mod check;
pub mod decode;
pub mod feed_key;
pub mod feed_relay;
pub mod ops;
pub mod outcome;
pub mod robot_config;
pub mod robots;
pub mod run;
pub mod sim;

use std::path::Path;

use std::net::SocketAddr;
use std::path::PathBuf;

use anyhow::{bail, Context};
use base_station::scenario::Scenario;
use clap::{Args, ValueEnum};
use hil_sim::world::Firmware;

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
    (
        "street-crossing",
        include_str!("../../../scenarios/street-crossing.toml"),
    ),
    (
        "plaza-crowd",
        include_str!("../../../scenarios/plaza-crowd.toml"),
    ),
    (
        "plaza-sweep",
        include_str!("../../../scenarios/plaza-sweep.toml"),
    ),
    (
        "street-block-sweep",
        include_str!("../../../scenarios/street-block-sweep.toml"),
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

/// A run's report as JSON (`sim`, `robots`), whole or not at all.
pub fn write_report(report: &hil_sim::report::Report, path: &Path) -> anyhow::Result<()> {
    let text = serde_json::to_string_pretty(report)? + "\n";
    replace(path, |partial| {
        std::fs::write(partial, &text)
            .with_context(|| format!("cannot write {}", partial.display()))
    })
}

/// Where a file is written before it takes `path`'s place: beside it, except where
/// `path` is something other than a file (`/dev/null`, a pipe), which is written
/// directly. Renamed over, `/dev/null` would become a file.
pub fn partial_path(path: &Path) -> std::path::PathBuf {
    if std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir()) {
        return path.to_path_buf();
    }
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".partial");
    path.with_file_name(name)
}

/// Writes `path` through `write` to a partial file beside it, then renames it into
/// place: an interrupted run never leaves half a file, nor loses the last whole one.
/// (Where `path` is not a file, [`partial_path`] is `path` and the rename does nothing.)
pub fn replace(path: &Path, write: impl FnOnce(&Path) -> anyhow::Result<()>) -> anyhow::Result<()> {
    let partial = partial_path(path);
    write(&partial)?;
    std::fs::rename(&partial, path)
        .with_context(|| format!("cannot move {} to {}", partial.display(), path.display()))
}

/// A run's CSV trace (`sim --trace`, `robots --trace`).
pub fn write_trace(world: &hil_sim::world::World, path: &Path) -> anyhow::Result<()> {
    let roles: Vec<_> = world.robots.iter().map(|r| (r.id, r.role)).collect();
    replace(path, |partial| {
        let file = std::fs::File::create(partial)
            .with_context(|| format!("cannot create {}", partial.display()))?;
        hil_sim::trace::write_csv(&world.recorder, &roles, std::io::BufWriter::new(file))
            .with_context(|| format!("cannot write {}", partial.display()))
    })
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum FirmwareArg {
    /// The control core compiled for this machine.
    Native,
    /// The real firmware ELF, one QEMU per robot.
    Qemu,
}

impl From<FirmwareArg> for Firmware {
    fn from(arg: FirmwareArg) -> Self {
        match arg {
            FirmwareArg::Native => Firmware::Native,
            FirmwareArg::Qemu => Firmware::Qemu,
        }
    }
}

/// How the simulated robots run and what they write beside the report (`sim`, `robots`).
#[derive(Args, Debug, Clone)]
pub struct SimulatedArgs {
    /// Random seed (radio, sensor noise) [default: the scenario's].
    #[arg(long)]
    pub seed: Option<u64>,
    #[arg(long, value_enum, default_value = "native")]
    pub firmware: FirmwareArg,
    /// Also write a CSV trace: one row per robot per sample (docs/sim.md#the-trace).
    #[arg(long, value_name = "FILE.csv")]
    pub trace: Option<PathBuf>,
}

/// What a live run serves the operator (`run`, `sim --realtime`).
#[derive(Args, Debug, Clone)]
pub struct ServeArgs {
    /// Serve the operator's console on ADDR [default: 127.0.0.1:8080]: the live map and
    /// Stop / Emergency stop / Resume. Open the URL it prints (it carries the pairing code),
    /// or enter the printed pairing code (docs/operating.md#7-stopping-and-the-console).
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = "127.0.0.1:8080")]
    pub console: Option<SocketAddr>,
    /// Serve the run live over the Foxglove WebSocket protocol on ADDR [default:
    /// 127.0.0.1:8765], read-only: the channels of a recording, for Foxglove or Lichtblick.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = "127.0.0.1:8765")]
    pub live: Option<SocketAddr>,
    /// A web page's origin allowed to open `--live` in a browser, beside Foxglove's and
    /// Lichtblick's web apps (repeatable; clients that send no Origin always may).
    #[arg(long, value_name = "ORIGIN", requires = "live")]
    pub live_origin: Vec<String>,
    /// Publish the formation on the city's bus with Zenoh's configuration file (JSON5),
    /// and take commands from it (docs/operating.md#a-citys-fleet-on-zenoh).
    #[arg(long, value_name = "CONFIG")]
    pub zenoh: Option<PathBuf>,
    /// With --zenoh: the site this formation works in (a chunk of its keys).
    #[arg(long, value_name = "NAME", default_value = "site", requires = "zenoh")]
    pub site: String,
    /// With --zenoh: the formation's name on the bus [default: the scenario's name].
    #[arg(long, value_name = "NAME", requires = "zenoh")]
    pub formation: Option<String>,
}

impl ServeArgs {
    /// The bus, when `--zenoh` is given, as this scenario's formation.
    pub fn bus(
        &self,
        scenario: &Scenario,
    ) -> anyhow::Result<Option<crate::bus::station::StationBus>> {
        let Some(path) = &self.zenoh else {
            return Ok(None);
        };
        let config = crate::bus::load_config(path)?;
        let name = self.formation.as_deref().unwrap_or(&scenario.name);
        let formation = crate::bus::keys::Formation::new(&self.site, name)
            .map_err(|e| anyhow::anyhow!("--site/--formation: {e}"))?;
        let map = crate::live::console::map_json(scenario);
        eprintln!(
            "bus: publishing as {} ({})",
            formation.label(),
            path.display()
        );
        Ok(Some(crate::bus::station::StationBus::open(
            config, formation, map,
        )?))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;
    use std::os::unix::fs::FileTypeExt;

    #[test]
    fn a_file_is_written_beside_and_renamed_and_a_pipe_in_place() {
        let dir = std::env::temp_dir().join(format!("basestation-replace-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("a temporary directory");
        // A file: written beside it, then renamed over it.
        let file = dir.join("report.json");
        assert_eq!(partial_path(&file), dir.join("report.json.partial"));
        replace(&file, |p| Ok(std::fs::write(p, "whole")?)).expect("written");
        assert_eq!(std::fs::read_to_string(&file).expect("read"), "whole");
        assert!(!dir.join("report.json.partial").exists());
        // A pipe (as `/dev/null` is a device): written through, and still a pipe after.
        let fifo = dir.join("out.fifo");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        assert!(made.is_ok_and(|s| s.success()), "mkfifo");
        assert_eq!(partial_path(&fifo), fifo);
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || {
                let mut text = String::new();
                std::fs::File::open(&fifo)
                    .and_then(|mut f| f.read_to_string(&mut text))
                    .map(|_| text)
            })
        };
        replace(&fifo, |p| Ok(std::fs::write(p, "through")?)).expect("written");
        assert_eq!(reader.join().expect("reader").expect("read"), "through");
        let kind = std::fs::metadata(&fifo).expect("still there").file_type();
        assert!(kind.is_fifo(), "renamed over: {kind:?}");
        assert_eq!(partial_path(Path::new("/dev/null")), Path::new("/dev/null"));
        std::fs::remove_dir_all(&dir).ok();
    }
}
