//! `basestation feed-key --source NAME -o FILE`: the key of one localization or scan
//! source of the site (`fixes`, `scan`, `nmea-ID`, ...), derived from the fleet's master
//! key, as 64 hexadecimal digits in a file only its owner can read. The source seals its
//! datagrams with it (docs/operating.md#who-may-speak-on-the-feeds); the base station
//! derives the same key from the master key and needs no file of its own.

use std::path::PathBuf;

use anyhow::bail;
use base_station::seal::valid_name;
use clap::Args;
use zeroize::Zeroizing;

#[derive(Args, Debug)]
pub struct FeedKeyArgs {
    /// The source's name: `fixes` (the line feed), `scan` (the scan feed) or `nmea-ID`
    /// (robot ID's GNSS receiver).
    #[arg(long)]
    pub source: String,
    /// Where to write the key.
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub key: crate::key::KeyArgs,
}

pub fn run(args: FeedKeyArgs) -> anyhow::Result<()> {
    if !valid_name(&args.source) {
        bail!(
            "{:?}: a source name is 1 to 32 of a-z, 0-9, '-', '_', '.'",
            args.source
        );
    }
    let master = crate::key::require_key(&args.key)?;
    let bytes = Zeroizing::new(master.source_bytes(&args.source));
    let text = Zeroizing::new(hex::encode(&bytes[..]) + "\n");
    super::robot_config::write_private(&args.output, text.as_bytes())?;
    println!(
        "wrote {}: the key of source {:?} (give it to that source only)",
        args.output.display(),
        args.source
    );
    Ok(())
}
