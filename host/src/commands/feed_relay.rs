//! `basestation feed-relay --source NAME --key-file SOURCE.key --to ADDR`: seals each line
//! of standard input (or of `--from SOURCE`) with the source's key and sends it to the base
//! station as one datagram: the adapter for a localization system or GNSS receiver that
//! cannot seal by itself (`ros2 topic echo … | basestation feed-relay …`, a receiver on a
//! serial port of a companion computer). It holds the source's key only, never the fleet's.

use std::io::BufRead;
use std::net::{SocketAddr, UdpSocket};
use std::path::PathBuf;

use anyhow::{bail, Context};
use base_station::seal::{valid_name, Sealer, SourceKey};
use clap::Args;

use crate::live::feeds::localization::Source;

#[derive(Args, Debug)]
pub struct FeedRelayArgs {
    /// The source's name, as the base station expects it on that input (`fixes`, `scan`,
    /// `nmea-ID`).
    #[arg(long)]
    pub source: String,
    /// The source's key (`basestation feed-key`): 64 hexadecimal digits.
    #[arg(long = "key-file", value_name = "FILE")]
    pub key_file: PathBuf,
    /// The base station's feed (its `--fix-feed`, `--scan-feed` or `--nmea ID=udp:` address).
    #[arg(long)]
    pub to: SocketAddr,
    /// Read lines from here instead of standard input: `serial:PATH[@BAUD]` or
    /// `tcp:HOST:PORT`.
    #[arg(long, value_name = "SOURCE")]
    pub from: Option<Source>,
}

pub fn run(args: FeedRelayArgs) -> anyhow::Result<()> {
    if !valid_name(&args.source) {
        bail!("{:?} is not a source name", args.source);
    }
    let text = crate::key::read_key_file(&args.key_file)?;
    let mut bytes = protocol::auth::key_bytes_from_hex(&text)
        .map_err(|e| anyhow::anyhow!("{}: {e}", args.key_file.display()))?;
    let key = SourceKey::from_bytes(&args.source, &bytes);
    zeroize::Zeroize::zeroize(&mut bytes);
    let mut sealer = Sealer::new(key);
    let socket = UdpSocket::bind(if args.to.is_ipv4() {
        "0.0.0.0:0"
    } else {
        "[::]:0"
    })
    .context("cannot open a UDP socket")?;
    let input: Box<dyn std::io::Read> = match &args.from {
        None => Box::new(std::io::stdin().lock()),
        Some(Source::Serial { path, baud }) => Box::new(
            serialport::new(path, *baud)
                .timeout(std::time::Duration::from_secs(3600))
                .open()
                .with_context(|| format!("cannot open {path}"))?,
        ),
        Some(Source::Tcp(addr)) => Box::new(
            std::net::TcpStream::connect(addr)
                .with_context(|| format!("cannot connect to {addr}"))?,
        ),
        Some(Source::Udp(_)) => {
            bail!("--from takes serial: or tcp: (a UDP source can seal itself)")
        }
    };
    let mut sent = 0u64;
    for line in std::io::BufReader::new(input).lines() {
        let line = line.context("reading the input")?;
        if line.trim().is_empty() {
            continue;
        }
        let record = sealer.seal(&(line + "\n"), super::unix_ms()? * 1000);
        // A datagram that cannot go now is lost, as the next line will be on time.
        if socket.send_to(record.as_bytes(), args.to).is_ok() {
            sent += 1;
        }
    }
    eprintln!("{sent} lines sealed and sent");
    Ok(())
}
