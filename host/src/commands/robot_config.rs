//! `basestation robot-config --id N --role leader|follower -o FILE [--boot-log FILE]`: the
//! 80-byte configuration page a robot reads at boot (its id, its role, the broadcast key and
//! its own key, derived from the fleet's master key), and the first word of its boot
//! counter. Flash them to the NUCLEO-F411RE's sectors 6 and 7:
//! `probe-rs download --chip STM32F411RETx --binary-format bin --base-address 0x08040000 FILE`
//! (and `0x08060000` for the boot log). Both files are written readable by their owner only:
//! the page holds the key.

use std::io::Write;
use std::os::unix::fs::{OpenOptionsExt, PermissionsExt};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use clap::{Args, ValueEnum};
use protocol::config_page::ConfigPage;
use zeroize::Zeroizing;

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum RoleArg {
    Leader,
    Follower,
}

#[derive(Args, Debug)]
pub struct RobotConfigArgs {
    /// The robot's fleet id (0–65534).
    #[arg(long)]
    pub id: u16,
    #[arg(long, value_enum)]
    pub role: RoleArg,
    /// Where to write the page.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Also write the boot counter's first word here (flash it at 0x08060000 once, when
    /// provisioning: the firmware refuses to link with an empty counter).
    #[arg(long)]
    pub boot_log: Option<PathBuf>,
    /// The last boot count this id used: a replacement board continues above it, so its
    /// sessions never repeat the old board's.
    #[arg(long, default_value_t = 0, requires = "boot_log")]
    pub last_boot_count: u32,
    #[command(flatten)]
    pub key: crate::key::KeyArgs,
}

pub fn run(args: RobotConfigArgs) -> anyhow::Result<()> {
    if args.id == u16::MAX {
        bail!("id 65535 is reserved");
    }
    let master = crate::key::require_key(&args.key)?;
    // The page holds the broadcast key and this robot's own key, never the master key.
    let page = ConfigPage::new(args.id, matches!(args.role, RoleArg::Leader), &master);
    let encoded = Zeroizing::new(page.encode());
    write_private(&args.output, &encoded[..])?;
    if let Some(path) = &args.boot_log {
        write_private(path, &args.last_boot_count.to_le_bytes())?;
        println!(
            "wrote {}: the boot counter starts above {}",
            path.display(),
            args.last_boot_count
        );
    }
    println!(
        "wrote {} ({} bytes) for robot {} ({:?})",
        args.output.display(),
        encoded.len(),
        args.id,
        args.role
    );
    Ok(())
}

/// Writes `bytes` to `path`, readable and writable by the owner only (also when it
/// already existed).
pub fn write_private(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(true)
        .mode(0o600)
        .open(path)
        .with_context(|| format!("cannot write {}", path.display()))?;
    file.set_permissions(std::fs::Permissions::from_mode(0o600))
        .with_context(|| format!("cannot restrict {}", path.display()))?;
    file.write_all(bytes)
        .with_context(|| format!("cannot write {}", path.display()))
}
