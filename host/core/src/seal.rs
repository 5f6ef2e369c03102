//! Sealed feeds: where the localization fixes and the leader's scans come from, proved.
//!
//! Each source of the site (a motion-capture bridge, a robot's GNSS receiver, the leader's
//! scan processor) holds a key of its own, derived from the fleet's master key by its name
//! ([`protocol::MasterKey::source_bytes`]; `basestation feed-key` writes it). It seals what
//! it sends: a *record* is any number of lines of the feed followed by one seal line,
//!
//! ```text
//! #seal v1 SOURCE COUNTER TAG
//! ```
//!
//! `COUNTER` a decimal number that grows with every record (the sender's clock in µs since
//! 1970 serves: a restarted source keeps counting up), `TAG` 32 hexadecimal digits: the
//! 128-bit BLAKE2s MAC under the source's key of
//! `"sweeper/feed/v1" 0x00 SOURCE 0x00 COUNTER(u64 LE) LINES`, `LINES` every byte of the
//! record before the seal line. A datagram is one record; on a byte stream every seal line
//! closes the record of the lines since the previous one.
//!
//! The base station opens a record only with the key of the source it expects on that
//! input, and never lets an unsealed line through: a datagram from anyone else on the
//! network is dropped and counted, not forwarded to a robot under the robot's own radio
//! key. **Replays** are refused by a window on the station's clock, not by a floor: a
//! counter more than [`AHEAD_US`] ahead of the station's clock or more than [`BEHIND_US`]
//! behind it is refused, and one within the window is taken once (the counters taken
//! within it are kept). A floor (a counter not above the last taken is a replay) let one
//! record sealed with a captured key and the counter 2⁶⁴−1 end a feed for good; a window
//! lets such a record do nothing, and a keyed flood only take the window's room (its
//! counters within [`AHEAD_US`], never more than [`SEEN_MAX`] of them held). Sources
//! must keep their clocks within [`AHEAD_US`] of the station's (NTP, GNSS); a record
//! captured and sent again later than [`BEHIND_US`] (an NMEA record of yesterday, at the
//! same time of day) is refused as stale.

use blake2::digest::{consts::U16, KeyInit, Mac};
use blake2::Blake2sMac;
use protocol::MasterKey;
use zeroize::Zeroize;

type Mac128 = Blake2sMac<U16>;

/// The start of a seal line.
pub const SEAL_PREFIX: &str = "#seal v1 ";
/// The longest record taken, bytes (a scan of 1,440 hits is ~30 kB).
pub const MAX_RECORD: usize = 65_536;
/// The longest source name.
pub const MAX_NAME: usize = 32;
const DOMAIN: &[u8] = b"sweeper/feed/v1\0";

/// Why a record was not taken.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SealError {
    /// No seal line: lines from a sender without a key.
    Unsealed,
    /// A seal line that does not parse.
    Malformed,
    /// Sealed by another source than the one this input takes.
    WrongSource,
    /// The tag does not verify: another key, or the lines were changed.
    BadTag,
    /// A counter taken before: a recorded record sent again.
    Replay,
    /// A counter more than [`AHEAD_US`] ahead of the station's clock.
    Ahead,
    /// A counter more than [`BEHIND_US`] behind the station's clock (or under the lowest
    /// one the window still holds): too old to tell from a replay.
    Stale,
    /// More than [`MAX_RECORD`] bytes.
    TooLong,
}

impl SealError {
    pub fn name(self) -> &'static str {
        match self {
            SealError::Unsealed => "unsealed",
            SealError::Malformed => "bad_seal",
            SealError::WrongSource => "wrong_source",
            SealError::BadTag => "bad_tag",
            SealError::Replay => "replay",
            SealError::Ahead => "ahead_of_the_clock",
            SealError::Stale => "stale",
            SealError::TooLong => "too_long",
        }
    }
}

impl std::fmt::Display for SealError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            SealError::Unsealed => "no seal: the sender holds no key of this site",
            SealError::Malformed => "a seal line that does not parse",
            SealError::WrongSource => "sealed by another source than this input's",
            SealError::BadTag => "the seal does not verify (another key, or changed lines)",
            SealError::Replay => "a counter already taken: a replayed record",
            SealError::Ahead => "a counter over 2 s ahead of the station's clock",
            SealError::Stale => "a counter over 10 s behind the station's clock",
            SealError::TooLong => "a record over 64 KiB",
        })
    }
}

/// Whether `name` can name a source: 1 to 32 of `a-z 0-9 - _ .`.
pub fn valid_name(name: &str) -> bool {
    (1..=MAX_NAME).contains(&name.len())
        && name
            .bytes()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b"-_.".contains(&b))
}

/// One source's key.
pub struct SourceKey {
    name: String,
    keyed: Mac128,
}

impl SourceKey {
    /// The key of source `name` from the fleet's master key.
    pub fn derive(master: &MasterKey, name: &str) -> Self {
        let mut bytes = master.source_bytes(name);
        let key = Self::from_bytes(name, &bytes);
        bytes.zeroize();
        key
    }

    pub fn from_bytes(name: &str, bytes: &[u8; 32]) -> Self {
        Self {
            name: name.to_string(),
            keyed: <Mac128 as KeyInit>::new_from_slice(bytes).expect("32 bytes is a valid key"),
        }
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    fn mac(&self, counter: u64, lines: &[u8]) -> Mac128 {
        let mut mac = self.keyed.clone();
        mac.update(DOMAIN);
        mac.update(self.name.as_bytes());
        mac.update(&[0]);
        mac.update(&counter.to_le_bytes());
        mac.update(lines);
        mac
    }

    /// `lines` (each ending in a newline) sealed as one record with `counter`.
    pub fn seal(&self, lines: &str, counter: u64) -> String {
        let tag = self.mac(counter, lines.as_bytes()).finalize().into_bytes();
        let mut out = String::with_capacity(lines.len() + 80);
        out.push_str(lines);
        if !lines.is_empty() && !lines.ends_with('\n') {
            out.push('\n');
        }
        out.push_str(&format!(
            "{SEAL_PREFIX}{} {counter} {}\n",
            self.name,
            hex::encode(tag)
        ));
        out
    }
}

impl std::fmt::Debug for SourceKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "SourceKey({}, <secret>)", self.name)
    }
}

/// Sealing for a sender: the key and a counter that only grows.
#[derive(Debug)]
pub struct Sealer {
    key: SourceKey,
    last: u64,
}

impl Sealer {
    pub fn new(key: SourceKey) -> Self {
        Self { key, last: 0 }
    }

    /// `lines` as one record; `clock_us`: the sender's clock (the counter is the larger of
    /// it and the last counter + 1).
    pub fn seal(&mut self, lines: &str, clock_us: u64) -> String {
        self.last = clock_us.max(self.last + 1);
        self.key.seal(lines, self.last)
    }
}

/// A source's counter may run this far ahead of the station's clock: disciplined clocks
/// agree within milliseconds, a relay's buffering adds a little, µs.
pub const AHEAD_US: u64 = 2_000_000;
/// A record this much older than the station's clock is refused: a datagram arrives in
/// milliseconds, a stream's relay may hold a few seconds, µs.
pub const BEHIND_US: u64 = 10_000_000;
/// The most counters the window holds: a source sealing 100 records a second fills a
/// tenth of it; a flood beyond it raises the window's floor, at most to [`AHEAD_US`].
pub const SEEN_MAX: usize = 16_384;

/// Opening one input's records: the source it expects, and the counters taken within
/// the window.
#[derive(Debug)]
pub struct Opener {
    key: SourceKey,
    seen: std::collections::BTreeSet<u64>,
    /// Under this nothing is taken: the highest counter pushed out of a full window.
    floor: u64,
}

impl Opener {
    pub fn new(key: SourceKey) -> Self {
        Self {
            key,
            seen: std::collections::BTreeSet::new(),
            floor: 0,
        }
    }

    pub fn source(&self) -> &str {
        self.key.name()
    }

    /// The lines of one record (a datagram, or a stream's lines up to and including a seal
    /// line), if its seal verifies and its counter is in the window round `now_us` (the
    /// station's clock, µs since 1970) and not taken before.
    pub fn open<'a>(&mut self, record: &'a [u8], now_us: u64) -> Result<&'a [u8], SealError> {
        if record.len() > MAX_RECORD {
            return Err(SealError::TooLong);
        }
        let body = record.strip_suffix(b"\n").unwrap_or(record);
        let start = body.iter().rposition(|b| *b == b'\n').map_or(0, |i| i + 1);
        let (lines, seal) = record.split_at(start);
        let seal = std::str::from_utf8(seal)
            .map_err(|_| SealError::Malformed)?
            .trim_end();
        let Some(fields) = seal.strip_prefix(SEAL_PREFIX) else {
            return Err(SealError::Unsealed);
        };
        let [name, counter, tag] = fields.split(' ').collect::<Vec<_>>()[..] else {
            return Err(SealError::Malformed);
        };
        let counter: u64 = counter.parse().map_err(|_| SealError::Malformed)?;
        let mut given = [0u8; 16];
        hex::decode_to_slice(tag, &mut given).map_err(|_| SealError::Malformed)?;
        if name != self.key.name() {
            return Err(SealError::WrongSource);
        }
        self.key
            .mac(counter, lines)
            .verify_slice(&given)
            .map_err(|_| SealError::BadTag)?;
        self.take(counter, now_us)?;
        Ok(lines)
    }

    /// Takes `counter` into the window round `now_us`, or says why not.
    fn take(&mut self, counter: u64, now_us: u64) -> Result<(), SealError> {
        if counter > now_us.saturating_add(AHEAD_US) {
            return Err(SealError::Ahead);
        }
        let oldest = now_us.saturating_sub(BEHIND_US);
        if counter < oldest || counter <= self.floor {
            return Err(SealError::Stale);
        }
        // What fell out of the window is refused by the clock check from now on.
        self.seen = self.seen.split_off(&oldest);
        if !self.seen.insert(counter) {
            return Err(SealError::Replay);
        }
        if self.seen.len() > SEEN_MAX {
            if let Some(pushed) = self.seen.pop_first() {
                self.floor = self.floor.max(pushed);
            }
        }
        Ok(())
    }
}

/// Splits a byte stream into records at its seal lines: lines are held until the seal
/// line that closes them comes, never more than [`MAX_RECORD`] bytes of them.
#[derive(Debug, Default)]
pub struct StreamRecords {
    held: Vec<u8>,
    overflowed: bool,
}

impl StreamRecords {
    /// One line of the stream (with or without its newline): the record it closes, if it
    /// is a seal line; `Err(TooLong)` when the lines before it overflowed (they are gone).
    pub fn line(&mut self, line: &[u8]) -> Option<Result<Vec<u8>, SealError>> {
        let is_seal = line.starts_with(SEAL_PREFIX.as_bytes());
        if self.held.len() + line.len() + 1 > MAX_RECORD {
            self.held.clear();
            self.overflowed = true;
        } else {
            self.held.extend_from_slice(line);
            if !line.ends_with(b"\n") {
                self.held.push(b'\n');
            }
        }
        if !is_seal {
            return None;
        }
        let record = std::mem::take(&mut self.held);
        if std::mem::take(&mut self.overflowed) {
            return Some(Err(SealError::TooLong));
        }
        Some(Ok(record))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The station's clock in these tests, µs since 1970.
    const NOW: u64 = 1_764_486_000_000_000;

    fn master() -> MasterKey {
        MasterKey::from_bytes(&[3; 32])
    }

    #[test]
    fn a_sealed_record_opens_once_and_only_with_its_source_key() {
        let mut sealer = Sealer::new(SourceKey::derive(&master(), "fixes"));
        let record = sealer.seal("1,1764486000.1,1.0,2.0,0.0,0.02\n", NOW + 5);
        let mut opener = Opener::new(SourceKey::derive(&master(), "fixes"));
        assert_eq!(
            opener.open(record.as_bytes(), NOW),
            Ok(&b"1,1764486000.1,1.0,2.0,0.0,0.02\n"[..])
        );
        assert_eq!(opener.open(record.as_bytes(), NOW), Err(SealError::Replay));
        // Another site's key, another source's key, changed lines, no seal.
        let other = MasterKey::from_bytes(&[4; 32]);
        let mut foreign = Sealer::new(SourceKey::derive(&other, "fixes"));
        let forged = foreign.seal("1,1764486000.2,9.0,2.0,0.0,0.02\n", NOW + 50);
        assert_eq!(opener.open(forged.as_bytes(), NOW), Err(SealError::BadTag));
        let mut scan = Sealer::new(SourceKey::derive(&master(), "scan"));
        let wrong = scan.seal("1,1764486000.2,9.0,2.0,0.0,0.02\n", NOW + 60);
        assert_eq!(
            opener.open(wrong.as_bytes(), NOW),
            Err(SealError::WrongSource)
        );
        let changed = sealer
            .seal("1,1764486000.3,1.0,2.0,0.0,0.02\n", NOW + 70)
            .replace("1.0,2.0", "1.4,2.0");
        assert_eq!(opener.open(changed.as_bytes(), NOW), Err(SealError::BadTag));
        assert_eq!(
            opener.open(b"1,1764486000.3,1.0,2.0,0.0,0.02\n", NOW),
            Err(SealError::Unsealed)
        );
        for bad in [
            "#seal v1 fixes 7\n",
            "#seal v1 fixes x 00\n",
            "#seal v1 fixes 9 zz\n",
        ] {
            assert_eq!(
                opener.open(bad.as_bytes(), NOW),
                Err(SealError::Malformed),
                "{bad}"
            );
        }
        assert_eq!(
            opener.open(&vec![b'a'; MAX_RECORD + 1], NOW),
            Err(SealError::TooLong)
        );
        // The genuine source goes on.
        let next = sealer.seal("1,1764486000.4,1.0,2.0,0.0,0.02\n", NOW + 80);
        assert!(opener.open(next.as_bytes(), NOW).is_ok());
    }

    #[test]
    fn a_stream_is_cut_into_records_at_its_seal_lines() {
        let mut sealer = Sealer::new(SourceKey::derive(&master(), "nmea-2"));
        let text =
            sealer.seal("$GPHDT,90.0,T*0C\n$GPGGA,a\n", NOW + 1) + &sealer.seal("$X\n", NOW + 2);
        let mut records = StreamRecords::default();
        let mut opener = Opener::new(SourceKey::derive(&master(), "nmea-2"));
        let mut opened = Vec::new();
        for line in text.split_inclusive('\n') {
            if let Some(record) = records.line(line.as_bytes()) {
                opened.push(opener.open(&record.unwrap(), NOW).unwrap().to_vec());
            }
        }
        assert_eq!(
            opened,
            [b"$GPHDT,90.0,T*0C\n$GPGGA,a\n".to_vec(), b"$X\n".to_vec()]
        );
        // A sender that never seals cannot make the station hold more than a record.
        let mut records = StreamRecords::default();
        for _ in 0..10_000 {
            assert!(records.line(&[b'x'; 100]).is_none());
        }
        assert!(records.held.len() <= MAX_RECORD);
        assert_eq!(
            records.line(b"#seal v1 nmea-2 3 00"),
            Some(Err(SealError::TooLong))
        );
    }

    /// The seal as docs/operating.md's Python computes it (`hashlib.blake2s(…, key=key,
    /// digest_size=16)`), so a source written in any language can check itself.
    #[test]
    fn the_tag_is_keyed_blake2s_as_documented() {
        let key = SourceKey::from_bytes("fixes", &[3; 32]);
        let record = key.seal(
            "2,1764486000.125,12.500,-3.250,1.5708,0.02\n",
            1764486000125000,
        );
        assert!(
            record.ends_with("#seal v1 fixes 1764486000125000 b5ed2b06aded3ce5ec782370117511f0\n")
        );
    }

    /// One record sealed with a captured key and the largest counter ends nothing; a
    /// keyed flood just ahead only takes the window's room; yesterday's record at the same
    /// time of day is stale; a replay within the window is refused.
    #[test]
    fn the_window_cannot_be_pushed_out_of_a_genuine_sources_reach() {
        let key = || SourceKey::derive(&master(), "scan");
        let mut opener = Opener::new(key());
        let mut attacker = Sealer::new(key());
        let far = attacker.seal("9,9\n", u64::MAX - 1);
        assert_eq!(opener.open(far.as_bytes(), NOW), Err(SealError::Ahead));
        let genuine = |t: u64| key().seal("1,2\n", t);
        for k in 0..10 {
            let t = NOW + k * 100_000;
            assert!(opener.open(genuine(t).as_bytes(), t).is_ok(), "{k}");
        }
        // A flood 1.9 s ahead, more than the window holds.
        for k in 0..(SEEN_MAX as u64 + 100) {
            let t = NOW + 1_900_000 + k;
            let _ = opener.open(key().seal("9,9\n", t).as_bytes(), NOW + 1_000_000);
        }
        // Refused only while the genuine clock is under the flood's pushed-out counters:
        // at most AHEAD_US.
        let later = NOW + 1_000_000 + AHEAD_US + 1;
        assert!(opener.open(genuine(later).as_bytes(), later).is_ok());
        assert_eq!(
            opener.open(genuine(later).as_bytes(), later),
            Err(SealError::Replay)
        );
        let yesterday = genuine(later - 86_400_000_000);
        assert_eq!(
            opener.open(yesterday.as_bytes(), later),
            Err(SealError::Stale)
        );
    }

    #[test]
    fn source_names_are_short_plain_words() {
        for good in ["fixes", "scan", "nmea-12", "mocap_1.a"] {
            assert!(valid_name(good), "{good}");
        }
        for bad in ["", "Fixes", "a b", "x/y", &"a".repeat(33)] {
            assert!(!valid_name(bad), "{bad}");
        }
    }
}
