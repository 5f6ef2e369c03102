//! The leader's scans in and out. In: `run --scan-feed ADDR` reads the scan feed
//! (`base_station::perception::parse_scan_line`: one scan a line, site frame) from UDP
//! datagrams sealed by source `scan` (`base_station::seal`), on a thread of its own,
//! through a bounded channel, and hands each fresh scan to the station, which routes round
//! what the map does not hold. Out: `robots --publish-scan ADDR` sends the simulated
//! leader's scans in the same format, sealed.

use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{self, Receiver};
use std::sync::Arc;

use anyhow::Context;
use base_station::perception::parse_scan_line;
use base_station::seal::{Sealer, SourceKey};
use base_station::station::BaseStation;
use glam::DVec2;
use protocol::MasterKey;
use serde::Serialize;

use super::gate::{AllowNet, Gate, GateCounts, GateTally};

/// The scan feed's source name: its key is `MasterKey::source_bytes("scan")`.
pub const SCAN_SOURCE: &str = "scan";

/// A scan older than this when the station takes it is dropped, ms.
const MAX_AGE_MS: f64 = 1000.0;
/// Scans in flight from the reader to the station at most.
const IN_FLIGHT: usize = 64;

/// What the feed brought, by what became of it.
#[derive(Debug, Default, Clone, Copy, Serialize)]
pub struct ScanCounts {
    /// Scans handed to the station.
    pub scans: u64,
    /// Their hits.
    pub hits: u64,
    /// Lines that did not parse.
    pub malformed: u64,
    /// Scans older than 1 s (or from over 0.5 s ahead) when taken.
    pub out_of_time: u64,
    /// Scans dropped because the station fell behind.
    pub dropped: u64,
    /// What the feed's gate refused (address, seal).
    #[serde(flatten)]
    pub gate: GateTally,
}

pub struct ScanFeed {
    lines: Receiver<Result<(f64, Vec<DVec2>), String>>,
    dropped: Arc<AtomicU64>,
    gate: Arc<GateCounts>,
    counts: ScanCounts,
}

impl ScanFeed {
    /// Listens on `addr` (UDP), one thread, for records sealed by source `scan` (its key
    /// derived from `master`) from `allow`'s addresses (any, when empty).
    pub fn open(
        addr: SocketAddr,
        master: &MasterKey,
        allow: Arc<[AllowNet]>,
    ) -> anyhow::Result<Self> {
        let socket = UdpSocket::bind(addr).with_context(|| format!("cannot bind {addr}"))?;
        let (tx, lines) = mpsc::sync_channel(IN_FLIGHT);
        let dropped = Arc::new(AtomicU64::new(0));
        let full = dropped.clone();
        let gate = Gate::new("scan feed", SCAN_SOURCE, master, allow);
        let gate_counts = gate.counts();
        super::gate::read_udp_records(socket, "scan feed", gate, move |line| {
            let parsed = match std::str::from_utf8(line) {
                Ok(text) => parse_scan_line(text).transpose(),
                Err(_) => Some(Err("not UTF-8".to_string())),
            };
            parsed.is_none_or(|p| super::gate::offer(&tx, p, &full))
        })?;
        Ok(Self {
            lines,
            dropped,
            gate: gate_counts,
            counts: ScanCounts::default(),
        })
    }

    /// Hands every fresh scan that came in to `station`; `now_unix_ms`: the Unix clock now,
    /// `now_ms` the station's.
    pub fn poll(&mut self, station: &mut BaseStation, now_unix_ms: u64, now_ms: u32) {
        while let Ok(line) = self.lines.try_recv() {
            match line {
                Err(why) => {
                    self.counts.malformed += 1;
                    tracing::debug!("scan feed: {why}");
                }
                Ok((time_s, hits)) => {
                    let age_ms = now_unix_ms as f64 - time_s * 1000.0;
                    if !(-500.0..=MAX_AGE_MS).contains(&age_ms) {
                        self.counts.out_of_time += 1;
                        continue;
                    }
                    self.counts.scans += 1;
                    self.counts.hits += hits.len() as u64;
                    station.sense(&hits, now_ms);
                }
            }
        }
        self.counts.dropped = self.dropped.load(Ordering::Relaxed);
        self.counts.gate = self.gate.tally();
    }

    pub fn counts(&self) -> ScanCounts {
        self.counts
    }
}

/// Sends scans as the scan feed's lines, one sealed datagram each.
pub struct ScanPublisher {
    socket: UdpSocket,
    to: SocketAddr,
    sealer: Sealer,
}

impl ScanPublisher {
    pub fn open(to: SocketAddr, master: &MasterKey) -> anyhow::Result<Self> {
        let socket = UdpSocket::bind(if to.is_ipv4() { "0.0.0.0:0" } else { "[::]:0" })
            .context("cannot open a UDP socket for the scans")?;
        Ok(Self {
            socket,
            to,
            sealer: Sealer::new(SourceKey::derive(master, SCAN_SOURCE)),
        })
    }

    /// One scan taken at `unix_ms`; nothing to send for an empty one.
    pub fn publish(&mut self, hits: &[DVec2], unix_ms: u64) {
        if hits.is_empty() {
            return;
        }
        use std::fmt::Write;
        let mut line = format!("{:.3}", unix_ms as f64 / 1000.0);
        for h in hits {
            let _ = write!(line, ",{:.3},{:.3}", h.x, h.y);
        }
        line.push('\n');
        let record = self.sealer.seal(&line, unix_ms * 1000);
        // A lost scan is made up by the next, 100 ms later.
        let _ = self.socket.send_to(record.as_bytes(), self.to);
    }
}
