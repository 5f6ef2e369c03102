//! `basestation decode [FILE]`: a captured byte stream (file or stdin) in, one JSON line
//! per frame out: the decoded fields, or why the frame was rejected. Never panics. An MCAP
//! recording of a run (`sim --mcap`) is read too: the frames of its `/radio` channel, each
//! with its time and sender.
//!
//! With the fleet key (`--key-file` / `SWEEPER_FLEET_KEY`), handshake frames are verified
//! and the sessions they announce are learnt, so that later frames of those senders are
//! verified too. Without it, or before a sender's session is seen, frames are decoded but
//! marked `"verified": false`. A simulation's recording is verified with `--seed N`: `sim`
//! derives its key from the seed.

use std::collections::HashMap;
use std::io::{Read, Write};
use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use protocol::frame::{self, Address, Header};
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

/// Decodes one deframed frame.
fn decode_one(
    raw: &[u8],
    master: Option<&MasterKey>,
    sessions: &mut HashMap<Address, u32>,
) -> Value {
    let header = match frame::peek_header(raw) {
        Ok(h) => h,
        Err(reason) => return json!({"ok": false, "reject": reason.name()}),
    };
    let Some(master) = master else {
        return match frame::parse_unverified(raw) {
            Ok((h, m)) => frame_json(&h, &m, false),
            Err(reason) => json!({"ok": false, "reject": reason.name()}),
        };
    };
    let known = sessions.get(&header.from).copied();
    let handshake = Message::is_handshake(header.id);
    if !handshake && known.is_none() {
        return match frame::parse_unverified(raw) {
            Ok((h, m)) => {
                let mut v = frame_json(&h, &m, false);
                v["note"] = json!("sender's session not seen in this capture yet");
                v
            }
            Err(reason) => json!({"ok": false, "reject": reason.name()}),
        };
    }
    // The key the sender used: broadcast, or the robot's own on its link with the base.
    let key = match (header.to, header.from) {
        (Address::Broadcast, _) => master.broadcast(),
        (Address::Robot(id), _) | (_, Address::Robot(id)) => master.robot(id),
        _ => master.broadcast(),
    };
    match frame::open(&key, raw, |_| known.ok_or(Reject::UnknownSession)) {
        Ok((h, m)) => {
            if let Message::Welcome(w) = m {
                sessions.insert(h.from, w.session);
            }
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
fn decode_recording(file: std::fs::File, key: Option<&MasterKey>) -> anyhow::Result<()> {
    use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};
    let mut input = std::io::BufReader::new(file);
    let mut reader = LinearReader::new_with_options(
        LinearReaderOptions::default().with_record_length_limit(MAX_RECORD),
    );
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    let mut decoders: HashMap<String, FrameDecoder> = HashMap::new();
    let mut sessions = HashMap::new();
    // The channels of the radio topic (by id): nothing else of the file is kept.
    let mut radio = std::collections::HashSet::new();
    let (mut frames, mut rejected) = (0u64, 0u64);
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
        let message = match mcap::parse_record(opcode, data).context("a damaged MCAP record")? {
            mcap::records::Record::Channel(c) => {
                if c.topic == base_station::recording::RADIO_TOPIC {
                    radio.insert(c.id);
                }
                continue;
            }
            mcap::records::Record::Message { header, data }
                if radio.contains(&header.channel_id) =>
            {
                (header.log_time, data)
            }
            _ => continue,
        };
        let (log_time, data) = message;
        let sent: Value = serde_json::from_slice(&data).context("a radio message")?;
        let (Some(from), Some(bytes)) = (
            sent["from"].as_str(),
            sent["hex"].as_str().and_then(|h| hex::decode(h).ok()),
        ) else {
            anyhow::bail!("a radio message without `from` and `hex`");
        };
        // A sender per name, of the few a recording has (base, air, the attacker).
        if decoders.len() >= 64 && !decoders.contains_key(from) {
            anyhow::bail!("more than 64 senders on the radio channel");
        }
        let decoder = decoders.entry(from.to_string()).or_default();
        for b in bytes {
            let Some(result) = decoder.push(b) else {
                continue;
            };
            let mut line = match result {
                Ok(raw) => decode_one(raw, key, &mut sessions),
                Err(reason) => json!({"ok": false, "reject": reason.name()}),
            };
            line["t_s"] = json!(log_time as f64 / 1e9);
            line["sender"] = json!(from);
            frames += 1;
            if line["ok"] == json!(false) {
                rejected += 1;
            }
            if writeln!(out, "{line}").is_err() {
                return Ok(());
            }
        }
    }
    out.flush().ok();
    eprintln!("{frames} frames, {rejected} rejected");
    Ok(())
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
            return decode_recording(file, key.as_ref());
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
    let mut sessions = HashMap::new();
    let mut buf = [0u8; 4096];
    let mut offset = 0u64;
    let (mut frames, mut rejected) = (0u64, 0u64);
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
                Ok(raw) => decode_one(raw, key.as_ref(), &mut sessions),
                Err(reason) => json!({"ok": false, "reject": reason.name()}),
            };
            line["end_offset"] = json!(offset);
            frames += 1;
            if line["ok"] == json!(false) {
                rejected += 1;
            }
            if writeln!(out, "{line}").is_err() {
                return Ok(()); // stdout closed (e.g. `| head`): stop quietly
            }
        }
    }
    out.flush().ok();
    eprintln!("{frames} frames, {rejected} rejected");
    Ok(())
}
