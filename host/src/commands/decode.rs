//! `basestation decode [FILE]`: a captured byte stream (file or stdin) in, one JSON line
//! per frame out: the decoded fields, or why the frame was rejected. Never panics. An MCAP
//! recording of a run (`sim --mcap`) is read too: the frames of its `/radio` channel, each
//! with its time and sender.
//!
//! With the fleet key (`--key-file` / `SWEEPER_FLEET_KEY`), handshake frames are verified
//! and the sessions they announce are learnt, so that later frames of those senders are
//! verified too. Without it, or before a sender's session is seen, frames are decoded but
//! marked `"verified": false`. Frames carry the low bits of their sequence number and
//! clock: a verified frame's are completed from its sender's previous frames in the
//! capture (its clock within 4 s of them); an unverified frame shows the low bits, with
//! `"low_bits"` saying how many. A simulation's recording is verified with the key `sim`
//! derives from its seed: the one its metadata holds, or `--seed N`.

use std::collections::HashMap;
use std::io::{Read, Write};
use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use protocol::frame::{self, Address, Expect, Header, WireHeader, SEQ_BITS, TIME_BITS};
use protocol::{FrameDecoder, MasterKey, Message, Reject};
use serde_json::{json, Value};

#[derive(Args, Debug)]
pub struct DecodeArgs {
    /// The capture (raw bytes) or an MCAP recording (`sim --mcap`); standard input when
    /// absent or `-`.
    pub file: Option<PathBuf>,
    #[command(flatten)]
    pub key: crate::key::KeyArgs,
    /// Verify with the key a simulation derives from this seed (`sim --seed N`, the
    /// scenario's seed otherwise): a `sim` recording's frames.
    #[arg(long, conflicts_with = "key_file")]
    pub seed: Option<u64>,
}

fn address(a: Address) -> String {
    match a {
        Address::Base => "base".into(),
        Address::Robot(id) => format!("robot:{id}"),
        Address::Broadcast => "broadcast".into(),
    }
}

fn frame_json(header: &Header, message: &Message, verified: bool) -> Value {
    json!({
        "ok": true,
        "verified": verified,
        "message": message.name(),
        "from": address(header.from),
        "to": address(header.to),
        "seq": header.seq,
        "time_ms": header.time_ms,
        "fields": serde_json::to_value(message).unwrap_or(Value::Null),
    })
}

/// An unverified frame: its header's values as carried (low bits unless whole).
fn unverified_json(header: &WireHeader, message: &Message) -> Value {
    let mut v = frame_json(&header.carried(), message, false);
    if !header.whole {
        v["low_bits"] = json!({ "seq": SEQ_BITS, "time_ms": TIME_BITS });
    }
    v
}

/// What the capture showed of its senders so far, from verified frames only.
#[derive(Default)]
struct Heard {
    sessions: HashMap<Address, u32>,
    /// The last sequence number of each (sender, destination) stream.
    streams: HashMap<(Address, Address), u32>,
    /// Each sender's last clock.
    clocks: HashMap<Address, u32>,
}

impl Heard {
    /// What a sender's next frame is completed against: its clock in the 4.096 s after its
    /// last frame.
    fn expect(&self, wire: &WireHeader) -> Result<Expect, Reject> {
        let session = self.sessions.get(&wire.from);
        let seq = self.streams.get(&(wire.from, wire.to));
        let time = self.clocks.get(&wire.from);
        match (session, seq, time) {
            (Some(&session), Some(&seq), Some(&time)) => Ok(Expect {
                session,
                seq: seq.wrapping_add(1),
                time_ms: time.wrapping_add(frame::TIME_BEHIND_MS),
            }),
            _ => Err(Reject::UnknownSession),
        }
    }

    fn verified(&mut self, h: &Header, m: &Message) {
        if let Message::Welcome(w) = m {
            self.sessions.insert(h.from, w.session);
            self.streams
                .insert((h.from, Address::Broadcast), w.broadcast_seq);
        }
        self.streams.insert((h.from, h.to), h.seq);
        self.clocks.insert(h.from, h.time_ms);
    }
}

/// Decodes one deframed frame.
fn decode_one(raw: &[u8], master: Option<&MasterKey>, heard: &mut Heard) -> Value {
    let header = match frame::peek_header(raw) {
        Ok(h) => h,
        Err(reason) => return json!({"ok": false, "reject": reason.name()}),
    };
    let unverified = |note: Option<&str>| match frame::parse_unverified(raw) {
        Ok((h, m)) => {
            let mut v = unverified_json(&h, &m);
            if let Some(note) = note {
                v["note"] = json!(note);
            }
            v
        }
        Err(reason) => json!({"ok": false, "reject": reason.name()}),
    };
    let Some(master) = master else {
        return unverified(None);
    };
    if !header.whole && !heard.sessions.contains_key(&header.from) {
        return unverified(Some("sender's session not seen in this capture yet"));
    }
    // The key the sender used: broadcast, or the robot's own on its link with the base.
    let key = match (header.to, header.from) {
        (Address::Broadcast, _) => master.broadcast(),
        (Address::Robot(id), _) | (_, Address::Robot(id)) => master.robot(id),
        _ => master.broadcast(),
    };
    match frame::open(&key, raw, |wire| heard.expect(wire)) {
        Ok((h, m)) => {
            heard.verified(&h, &m);
            frame_json(&h, &m, true)
        }
        Err(reason) => json!({"ok": false, "reject": reason.name(), "from": address(header.from)}),
    }
}

/// The first bytes of an MCAP file.
const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// The largest MCAP record `decode` takes, bytes: a radio message is a few hundred; a
/// damaged or hostile file that claims more is refused, not allocated.
const MAX_RECORD: usize = 16 * 1024 * 1024;

/// The frames of a recording's radio channel, one JSON line each, read as a stream: what
/// is held at once is bounded by [`MAX_RECORD`] whatever the file says.
fn decode_recording(
    file: std::fs::File,
    given: Option<MasterKey>,
    given_seed: Option<u64>,
) -> anyhow::Result<()> {
    use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};
    let mut input = std::io::BufReader::new(file);
    let mut reader = LinearReader::new_with_options(
        LinearReaderOptions::default().with_record_length_limit(MAX_RECORD),
    );
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    let mut air = Air {
        key: given,
        ..Air::default()
    };
    // The channels of the radio topic (by id): nothing else of the file is kept.
    let mut radio = std::collections::HashSet::new();
    while let Some(event) = reader.next_event() {
        let (opcode, data) = match event.context("a damaged MCAP file")? {
            LinearReadEvent::ReadRequest(need) => {
                let n = input
                    .read(reader.insert(need.min(MAX_RECORD)))
                    .context("reading the recording")?;
                reader.notify_read(n);
                continue;
            }
            LinearReadEvent::Record { opcode, data } => (opcode, data),
        };
        let record = mcap::parse_record(opcode, data).context("a damaged MCAP record")?;
        let open = match record {
            mcap::records::Record::Channel(c) => {
                let ours = c.topic == base_station::recording::RADIO_TOPIC;
                ours.then(|| radio.insert(c.id));
                true
            }
            mcap::records::Record::Message { header, data }
                if radio.contains(&header.channel_id) =>
            {
                air.message(header.log_time, &data, &mut out)?
            }
            mcap::records::Record::Metadata(m)
                if m.name == base_station::recording::METADATA_NAME =>
            {
                let seed = m.metadata.get("seed").and_then(|s| s.parse::<u64>().ok());
                air.key = key_from_metadata(air.key.take(), given_seed, seed);
                true
            }
            _ => true,
        };
        if !open {
            return Ok(());
        }
    }
    out.flush().ok();
    air.count.report(air.key.is_some());
    Ok(())
}

/// A recording's radio channel as `decode` reads it: a frame decoder per sender, the
/// sessions learnt, the key, what was seen.
#[derive(Default)]
struct Air {
    key: Option<MasterKey>,
    decoders: HashMap<String, FrameDecoder>,
    heard: Heard,
    count: Count,
}

impl Air {
    /// One radio message (`data`, at `log_time` ns): its frames out as JSON lines; false
    /// when `out` is closed.
    fn message(
        &mut self,
        log_time: u64,
        data: &[u8],
        out: &mut impl Write,
    ) -> anyhow::Result<bool> {
        let sent: Value = serde_json::from_slice(data).context("a radio message")?;
        let (Some(from), Some(bytes)) = (
            sent["from"].as_str(),
            sent["hex"].as_str().and_then(|h| hex::decode(h).ok()),
        ) else {
            anyhow::bail!("a radio message without `from` and `hex`");
        };
        // A sender per name, of the few a recording has (base, air, the attacker).
        if self.decoders.len() >= 64 && !self.decoders.contains_key(from) {
            anyhow::bail!("more than 64 senders on the radio channel");
        }
        let decoder = self.decoders.entry(from.to_string()).or_default();
        for b in bytes {
            let Some(result) = decoder.push(b) else {
                continue;
            };
            let mut line = match result {
                Ok(raw) => decode_one(raw, self.key.as_ref(), &mut self.heard),
                Err(reason) => json!({"ok": false, "reject": reason.name()}),
            };
            line["t_s"] = json!(log_time as f64 / 1e9);
            line["sender"] = json!(from);
            self.count.add(&line);
            if writeln!(out, "{line}").is_err() {
                return Ok(false);
            }
        }
        Ok(true)
    }
}

/// The key a `sim` recording is verified with: the one given, else the one its metadata's
/// seed derives; a seed given that differs from the recording's is said, not overridden.
fn key_from_metadata(
    key: Option<MasterKey>,
    given_seed: Option<u64>,
    recorded: Option<u64>,
) -> Option<MasterKey> {
    match (key, recorded) {
        (None, Some(seed)) => {
            eprintln!("verifying with the key of sim seed {seed}, from the recording's metadata");
            Some(MasterKey::from_bytes(&hil_sim::world::sim_key_bytes(seed)))
        }
        (key, Some(seed)) if given_seed.is_some_and(|g| g != seed) => {
            eprintln!(
                "warning: the recording was made with --seed {seed}, not {}: its frames will \
                 not verify (bad_tag); leave --seed out to take the recording's",
                given_seed.unwrap_or_default()
            );
            key
        }
        (key, _) => key,
    }
}

/// What a decode saw, for its closing line.
#[derive(Debug, Default)]
struct Count {
    frames: u64,
    verified: u64,
    rejected: u64,
    bad_tag: u64,
}

impl Count {
    fn add(&mut self, line: &Value) {
        self.frames += 1;
        if line["ok"] == json!(false) {
            self.rejected += 1;
            if line["reject"] == json!("bad_tag") {
                self.bad_tag += 1;
            }
        } else if line["verified"] == json!(true) {
            self.verified += 1;
        }
    }

    /// The closing line on stderr, with a hint where every sealed frame failed its tag.
    fn report(&self, keyed: bool) {
        eprintln!(
            "{} frames, {} verified, {} rejected",
            self.frames, self.verified, self.rejected
        );
        if keyed && self.verified == 0 && self.bad_tag > 0 {
            eprintln!(
                "no frame verified and {} failed their tag: the key (or --seed) is not the \
                 one the frames were sealed with",
                self.bad_tag
            );
        }
    }
}

pub fn run(args: DecodeArgs) -> anyhow::Result<()> {
    let key = match args.seed {
        Some(seed) => Some(MasterKey::from_bytes(&hil_sim::world::sim_key_bytes(seed))),
        None => args.key.load()?,
    };
    if let Some(path) = args.file.as_ref().filter(|p| p.as_os_str() != "-") {
        let mut head = [0u8; 8];
        let is_mcap = std::fs::File::open(path)
            .and_then(|mut f| f.read_exact(&mut head))
            .is_ok()
            && head == MCAP_MAGIC;
        if is_mcap {
            let file = std::fs::File::open(path)
                .with_context(|| format!("cannot read {}", path.display()))?;
            return decode_recording(file, key, args.seed);
        }
    }
    let mut input: Box<dyn Read> = match &args.file {
        Some(p) if p.as_os_str() != "-" => Box::new(
            std::fs::File::open(p).with_context(|| format!("cannot open {}", p.display()))?,
        ),
        _ => Box::new(std::io::stdin().lock()),
    };
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    let mut decoder = FrameDecoder::new();
    let mut heard = Heard::default();
    let mut buf = [0u8; 4096];
    let mut offset = 0u64;
    let mut count = Count::default();
    loop {
        let n = match input.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e).context("reading the capture"),
        };
        for &b in &buf[..n] {
            offset += 1;
            let Some(result) = decoder.push(b) else {
                continue;
            };
            let mut line = match result {
                Ok(raw) => decode_one(raw, key.as_ref(), &mut heard),
                Err(reason) => json!({"ok": false, "reject": reason.name()}),
            };
            line["end_offset"] = json!(offset);
            count.add(&line);
            if writeln!(out, "{line}").is_err() {
                return Ok(()); // stdout closed (e.g. `| head`): stop quietly
            }
        }
    }
    out.flush().ok();
    count.report(key.is_some());
    Ok(())
}
