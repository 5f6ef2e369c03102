//! `basestation robot-config --id N --role leader|follower -o FILE`: the 48-byte
//! configuration page a robot reads at boot (its id, its role, the fleet key). Flash it to
//! the NUCLEO-F411RE's sector 6 with
//! `probe-rs download --chip STM32F411RETx --binary-format bin --base-address 0x08040000 FILE`.

use std::path::PathBuf;

use anyhow::{bail, Context};
use clap::{Args, ValueEnum};
use protocol::config_page::ConfigPage;

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
    #[command(flatten)]
    pub key: super::KeyArgs,
}

pub fn run(args: RobotConfigArgs) -> anyhow::Result<()> {
    if args.id == u16::MAX {
        bail!("id 65535 is reserved");
    }
    let hex = match (&args.key.key_file, std::env::var("SWEEPER_FLEET_KEY")) {
        (Some(path), _) => std::fs::read_to_string(path)
            .with_context(|| format!("cannot read the key file {}", path.display()))?,
        (None, Ok(hex)) => hex,
        (None, Err(_)) => bail!("no fleet key: pass --key-file FILE or set SWEEPER_FLEET_KEY"),
    };
    // Parse twice: FleetKey checks the text, then the bytes go into the page.
    protocol::FleetKey::from_hex(&hex).context("the fleet key")?;
    let bytes = hex::decode(hex.trim()).context("the fleet key")?;
    let key: [u8; 32] = bytes
        .try_into()
        .map_err(|_| anyhow::anyhow!("the fleet key is not 32 bytes"))?;
    let page = ConfigPage {
        id: args.id,
        leader: matches!(args.role, RoleArg::Leader),
        key,
    };
    std::fs::write(&args.output, page.encode())
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    println!(
        "wrote {} ({} bytes) for robot {} ({:?})",
        args.output.display(),
        page.encode().len(),
        args.id,
        args.role
    );
    Ok(())
}
