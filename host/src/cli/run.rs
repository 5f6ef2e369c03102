//! `basestation run SCENARIO --port DEV [--baud N]` or `--udp ADDR`: drive real robots.
//!
//! The station steps at 10 Hz on the wall clock. The fleet key is required (file or
//! environment); there is no built-in key. Ctrl-C sends a Stop to every robot before
//! exiting.

use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use base_station::station::{BaseStation, StationConfig};
use base_station::transport::{Serial, Transport, Udp};
use clap::Args;

#[derive(Args, Debug)]
pub struct RunArgs {
    /// A site/scenario file, or a shipped scenario's name.
    pub scenario: String,
    /// Serial device of the radio modem (e.g. /dev/ttyUSB0).
    #[arg(long, required_unless_present = "udp", conflicts_with = "udp")]
    pub port: Option<String>,
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
    /// Send frames as UDP datagrams to this address (a radio bridge or broadcast).
    #[arg(long)]
    pub udp: Option<SocketAddr>,
    /// Local UDP address to bind.
    #[arg(long, default_value = "0.0.0.0:0")]
    pub bind: SocketAddr,
    /// Stop after this many seconds (default: until the goal is reached or Ctrl-C).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Record the run as MCAP: radio bytes both ways, events, robots' reported poses.
    #[arg(long, value_name = "FILE.mcap")]
    pub mcap: Option<std::path::PathBuf>,
    #[command(flatten)]
    pub key: super::KeyArgs,
}

pub fn run(args: RunArgs) -> anyhow::Result<()> {
    let scenario = super::load_scenario(&args.scenario)?;
    let Some(key) = args.key.load()? else {
        bail!("no fleet key: pass --key-file FILE or set SWEEPER_KEY_FILE or SWEEPER_FLEET_KEY (64 hex digits)");
    };
    let mut transport: Box<dyn Transport> = match (&args.port, args.udp) {
        (Some(port), _) => {
            Box::new(Serial::open(port, args.baud).with_context(|| format!("cannot open {port}"))?)
        }
        (None, Some(peer)) => {
            Box::new(Udp::open(args.bind, peer).context("cannot open the UDP socket")?)
        }
        (None, None) => unreachable!("clap requires --port or --udp"),
    };
    let mut random = [0u8; 8];
    getrandom::fill(&mut random).map_err(|e| anyhow::anyhow!("no OS randomness: {e}"))?;
    let session = u32::from_le_bytes(random[..4].try_into().expect("4 bytes"));
    let start_ms = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_err(|_| anyhow::anyhow!("the system clock is before 1970: set it before a run"))?
        .as_millis() as u64;
    let nonce_base = base_station::station::nonce_base(
        start_ms,
        u32::from_le_bytes(random[4..8].try_into().expect("4 bytes")),
    );
    let mut station = BaseStation::new(
        StationConfig::from_scenario(&scenario),
        &key,
        session,
        nonce_base,
    );

    let mut recording = match &args.mcap {
        Some(path) => Some(super::record::LiveRecording::create(path, &station)?),
        None => None,
    };

    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst)).context("installing Ctrl-C")?;

    tracing::info!(scenario = %scenario.name, "base station running");
    let start = Instant::now();
    let period = Duration::from_millis(100);
    let mut next = start;
    let mut buf = [0u8; 2048];
    let mut last_report = 0u32;
    while !stop.load(Ordering::SeqCst) {
        let now_ms = start.elapsed().as_millis() as u32;
        if args.duration.is_some_and(|d| now_ms as f64 / 1000.0 >= d) {
            break;
        }
        // Receive until the next tick.
        loop {
            let left = next.saturating_duration_since(Instant::now());
            if left.is_zero() {
                break;
            }
            let n = transport.recv(&mut buf, left)?;
            if n > 0 {
                station.receive(&buf[..n], start.elapsed().as_millis() as u32);
                if let Some(r) = &recording {
                    r.radio("air", &buf[..n]);
                }
            }
        }
        next += period;
        let now_ms = start.elapsed().as_millis() as u32;
        station.step(now_ms);
        let out = station.take_outbox();
        transport.send(&out)?;
        if let Some(r) = recording.as_mut() {
            r.radio("base", &out);
            r.station(&station);
        }
        if now_ms / 1000 != last_report {
            last_report = now_ms / 1000;
            let stats = station.link().stats();
            tracing::info!(
                accepted = stats.accepted,
                rejected = stats.rejects.total(),
                lost = stats.lost,
                planner = ?station.planner().mode(),
                "link"
            );
            // Per-robot link health every 5 s: last seen, accepted, lost, rejects by reason.
            if last_report.is_multiple_of(5) {
                for peer in station.link().peers() {
                    let seen = peer
                        .last_rx_ms
                        .map(|t| format!("{} ms ago", now_ms.wrapping_sub(t)))
                        .unwrap_or_else(|| "never".into());
                    let rejects: Vec<String> = protocol::Reject::ALL
                        .iter()
                        .filter(|r| peer.rejects.get(**r) > 0)
                        .map(|r| format!("{}={}", r.name(), peer.rejects.get(*r)))
                        .collect();
                    tracing::info!(
                        robot = ?peer.address,
                        linked = peer.is_linked(),
                        seen = %seen,
                        accepted = peer.accepted,
                        lost = peer.lost,
                        rejects = %rejects.join(","),
                        "robot link"
                    );
                }
            }
        }
        if station.planner().arrived() && args.duration.is_none() {
            tracing::info!("goal reached");
            break;
        }
    }
    // Leave the fleet standing.
    station.broadcast_stop(start.elapsed().as_millis() as u32);
    let out = station.take_outbox();
    transport.send(&out)?;
    if let Some(r) = recording {
        r.radio("base", &out);
        r.close()?;
    }
    Ok(())
}
