//! What the line feeds read from the network share (the localization feed, NMEA, the scan
//! feed): who may speak on them, and a bounded queue to the station's loop.
//!
//! Every input has a [`Gate`]: datagrams from addresses outside the site's allow-list
//! (`run --feed-allow`) are dropped, and only records sealed by the input's own source
//! (`base_station::seal`) pass, line by line. What the gate drops is counted on the reader
//! thread and never queued, so a flood of forged datagrams cannot crowd the genuine lines
//! out of the queue. The queue to the station's loop drops and counts what does not fit
//! rather than block the reader.

use std::io::{BufRead, BufReader, Read};
use std::net::{IpAddr, UdpSocket};
use std::str::FromStr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{SyncSender, TrySendError};
use std::sync::Arc;

use anyhow::Context;
use base_station::seal::{Opener, SealError, SourceKey, StreamRecords, MAX_RECORD};
use protocol::MasterKey;
use serde::Serialize;

/// Queues `item`, or counts it in `dropped` when the queue is full; `false` once the
/// receiver is gone.
pub fn offer<T>(tx: &SyncSender<T>, item: T, dropped: &AtomicU64) -> bool {
    match tx.try_send(item) {
        Ok(()) => true,
        Err(TrySendError::Full(_)) => {
            dropped.fetch_add(1, Ordering::Relaxed);
            true
        }
        Err(TrySendError::Disconnected(_)) => false,
    }
}

/// A network and its prefix, `ADDR[/PREFIX]`: the addresses a feed takes datagrams from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AllowNet(ipnet::IpNet);

impl FromStr for AllowNet {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        s.parse::<ipnet::IpNet>()
            .or_else(|_| s.parse::<IpAddr>().map(ipnet::IpNet::from))
            .map(AllowNet)
            .map_err(|_| format!("{s}: expected an address or ADDR/PREFIX (10.1.0.0/24)"))
    }
}

/// What one input's gate dropped.
#[derive(Debug, Default)]
pub struct GateCounts {
    not_allowed: AtomicU64,
    unsealed: AtomicU64,
    bad_seal: AtomicU64,
    replayed: AtomicU64,
    ahead: AtomicU64,
    stale: AtomicU64,
}

/// [`GateCounts`] at one moment, for the run's report.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct GateTally {
    /// Datagrams from an address outside `--feed-allow`.
    pub not_allowed: u64,
    /// Records without a seal: a sender without a key.
    pub unsealed: u64,
    /// Records whose seal does not verify, names another source, or does not parse.
    pub bad_seal: u64,
    /// Records taken before (a replay within the window).
    pub replayed: u64,
    /// Records whose counter runs more than 2 s ahead of the station's clock.
    pub ahead: u64,
    /// Records more than 10 s behind the station's clock.
    pub stale: u64,
}

impl GateTally {
    /// Everything the gate refused.
    pub fn refused(&self) -> u64 {
        self.not_allowed + self.unsealed + self.bad_seal + self.replayed + self.ahead + self.stale
    }
}

/// This many refused in a second is an attack or a broken source, not a stray datagram.
pub const BULK_PER_S: u64 = 50;
/// One event per input at most this often: a flood is one story, not one a second, ms.
const BULK_EVENT_EVERY_MS: u32 = 10_000;

/// Which inputs refuse records in bulk: checked once a second with each input's total.
#[derive(Debug, Default)]
pub struct Bulk {
    last: std::collections::HashMap<String, u64>,
    said_ms: std::collections::HashMap<String, u32>,
}

impl Bulk {
    /// How many `input` refused since the last check, when it is a bulk to tell (at least
    /// [`BULK_PER_S`], and not told in the last [`BULK_EVENT_EVERY_MS`]).
    pub fn check(&mut self, input: &str, total: u64, now_ms: u32) -> Option<u64> {
        let before = self.last.insert(input.to_string(), total).unwrap_or(0);
        let new = total.saturating_sub(before);
        let recently = self
            .said_ms
            .get(input)
            .is_some_and(|t| now_ms.wrapping_sub(*t) < BULK_EVENT_EVERY_MS);
        if new < BULK_PER_S || recently {
            return None;
        }
        self.said_ms.insert(input.to_string(), now_ms);
        Some(new)
    }
}

impl GateCounts {
    pub fn tally(&self) -> GateTally {
        let get = |c: &AtomicU64| c.load(Ordering::Relaxed);
        GateTally {
            not_allowed: get(&self.not_allowed),
            unsealed: get(&self.unsealed),
            bad_seal: get(&self.bad_seal),
            replayed: get(&self.replayed),
            ahead: get(&self.ahead),
            stale: get(&self.stale),
        }
    }

    fn count(&self, error: SealError) {
        let counter = match error {
            SealError::Unsealed => &self.unsealed,
            SealError::Replay => &self.replayed,
            SealError::Ahead => &self.ahead,
            SealError::Stale => &self.stale,
            SealError::Malformed
            | SealError::WrongSource
            | SealError::BadTag
            | SealError::TooLong => &self.bad_seal,
        };
        counter.fetch_add(1, Ordering::Relaxed);
    }
}

/// Who may speak on one input.
pub struct Gate {
    name: String,
    allow: Arc<[AllowNet]>,
    opener: Opener,
    counts: Arc<GateCounts>,
    warned: bool,
}

impl Gate {
    /// The gate of an input that takes source `source`'s records (its key derived from
    /// `master`) from the addresses of `allow` (all, when empty).
    pub fn new(name: &str, source: &str, master: &MasterKey, allow: Arc<[AllowNet]>) -> Self {
        Self {
            name: name.to_string(),
            allow,
            opener: Opener::new(SourceKey::derive(master, source)),
            counts: Arc::default(),
            warned: false,
        }
    }

    pub fn counts(&self) -> Arc<GateCounts> {
        self.counts.clone()
    }

    fn allows(&self, from: IpAddr) -> bool {
        let from = match from {
            IpAddr::V6(v6) => v6.to_ipv4_mapped().map_or(from, IpAddr::V4),
            v4 => v4,
        };
        self.allow.is_empty() || self.allow.iter().any(|net| net.0.contains(&from))
    }

    /// The lines of one record, when its seal is its source's and fresh.
    fn open<'a>(&mut self, record: &'a [u8]) -> Option<&'a [u8]> {
        // A clock before 1970 refuses every record as ahead of it, as it should.
        let now_us = crate::commands::unix_ms().unwrap_or(0) * 1000;
        match self.opener.open(record, now_us) {
            Ok(lines) => Some(lines),
            Err(e) => {
                self.counts.count(e);
                if !std::mem::replace(&mut self.warned, true) {
                    tracing::warn!(
                        input = %self.name,
                        source = self.opener.source(),
                        "feed record refused: {e} (further ones are counted)"
                    );
                }
                None
            }
        }
    }
}

/// Hands each line of `lines` to `line` until it returns `false`; `false` then.
fn each_line(lines: &[u8], line: &mut impl FnMut(&[u8]) -> bool) -> bool {
    lines
        .split(|b| *b == b'\n')
        .filter(|text| !text.is_empty())
        .all(line)
}

/// Reads datagrams on `socket` on a thread named `name`; each one the gate lets through
/// is split into lines for `line`, until `line` returns `false` or the socket fails.
pub fn read_udp_records(
    socket: UdpSocket,
    name: &str,
    mut gate: Gate,
    mut line: impl FnMut(&[u8]) -> bool + Send + 'static,
) -> anyhow::Result<()> {
    std::thread::Builder::new()
        .name(name.into())
        .spawn(move || {
            let mut buf = vec![0u8; MAX_RECORD + 1];
            while let Ok((n, from)) = socket.recv_from(&mut buf) {
                if !gate.allows(from.ip()) {
                    gate.counts.not_allowed.fetch_add(1, Ordering::Relaxed);
                    continue;
                }
                if let Some(lines) = gate.open(&buf[..n]) {
                    if !each_line(lines, &mut line) {
                        return;
                    }
                }
            }
        })
        .with_context(|| format!("cannot start the {name} reader"))?;
    Ok(())
}

/// Longest line read from a stream, bytes.
const MAX_LINE: usize = 4096;

/// Reads a byte stream line by line (each bounded); every record the gate lets through
/// goes to `line`, line by line. Ends with the stream; `false` once `line` did.
pub fn read_stream_records(
    stream: impl Read,
    gate: &mut Gate,
    line: &mut impl FnMut(&[u8]) -> bool,
) -> bool {
    let mut reader = BufReader::new(stream);
    let mut records = StreamRecords::default();
    let mut text = Vec::new();
    loop {
        text.clear();
        match (&mut reader)
            .take(MAX_LINE as u64 + 1)
            .read_until(b'\n', &mut text)
        {
            Ok(0) | Err(_) => return true,
            Ok(_) => {}
        }
        let Some(record) = records.line(&text) else {
            continue;
        };
        let lines = match record {
            Ok(record) => gate.open(&record).map(<[u8]>::to_vec),
            Err(e) => {
                gate.counts.count(e);
                None
            }
        };
        if lines.is_some_and(|lines| !each_line(&lines, line)) {
            return false;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use base_station::seal::Sealer;

    #[test]
    fn the_gate_takes_its_source_from_its_networks_and_nothing_else() {
        let master = MasterKey::from_bytes(&[1; 32]);
        let allow: Arc<[AllowNet]> = Arc::from(vec!["10.1.0.0/24".parse().unwrap()]);
        let mut gate = Gate::new("feed", "fixes", &master, allow);
        assert!(gate.allows("10.1.0.7".parse().unwrap()));
        assert!(gate.allows("::ffff:10.1.0.7".parse().unwrap()));
        assert!(!gate.allows("10.1.1.7".parse().unwrap()));
        let mut sealer = Sealer::new(SourceKey::derive(&master, "fixes"));
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_micros() as u64;
        let record = sealer.seal("a\nb\n", now);
        assert_eq!(gate.open(record.as_bytes()), Some(&b"a\nb\n"[..]));
        assert_eq!(gate.open(record.as_bytes()), None);
        assert_eq!(gate.open(b"a\n"), None);
        // One sealed with the largest counter is refused, and the source goes on.
        assert_eq!(gate.open(sealer.seal("c\n", u64::MAX).as_bytes()), None);
        let mut genuine = Sealer::new(SourceKey::derive(&master, "fixes"));
        let next = genuine.seal("d\n", now + 1_000);
        assert_eq!(gate.open(next.as_bytes()), Some(&b"d\n"[..]));
        let t = gate.counts.tally();
        assert_eq!((t.replayed, t.unsealed, t.bad_seal, t.ahead), (1, 1, 0, 1));
        assert!("nonsense".parse::<AllowNet>().is_err());
        // Refusals in bulk are told once, then again only after a while.
        let mut bulk = Bulk::default();
        assert_eq!(bulk.check("feed", 10, 1_000), None);
        assert_eq!(bulk.check("feed", 500, 2_000), Some(490));
        assert_eq!(bulk.check("feed", 1_000, 3_000), None, "told 1 s ago");
        assert_eq!(bulk.check("feed", 2_000, 13_000), Some(1_000));
        assert!("127.0.0.1".parse::<AllowNet>().is_ok());
    }
}
