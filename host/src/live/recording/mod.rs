//! `run --mcap FILE` / `--live [ADDR]`: the run recorded as MCAP and/or served live over
//! the Foxglove WebSocket protocol, from the same log calls (the same channels as a
//! simulation's recording where the station knows them): the radio bytes both ways, the
//! base station's events, each robot's pose as its telemetry reports it and its link's
//! health once a second. `sim --realtime
//! --live` serves the same. Timestamps: the caller's clock (the wall clock in `run`, the
//! simulated one in `sim`).

mod gate;

use std::collections::BTreeMap;
use std::io::BufWriter;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::SystemTime;

use anyhow::Context as _;
use base_station::recording::{
    events_channel, link_health, log_event, log_radio, pose, radio_channel, stamp, LinkHealth,
    FRAME,
};
use base_station::station::BaseStation;
use foxglove::messages::{Log, PoseInFrame};
use foxglove::{
    Channel, Context, McapWriter, McapWriterHandle, RawChannel, WebSocketServer,
    WebSocketServerHandle,
};

pub struct LiveRecording {
    _ctx: Arc<Context>,
    /// The writer, the partial file it writes and the path it takes at the end.
    writer: Option<(McapWriterHandle<BufWriter<std::fs::File>>, PathBuf, PathBuf)>,
    server: Option<WebSocketServerHandle>,
    radio: Arc<RawChannel>,
    events: Channel<Log>,
    poses: BTreeMap<u16, (Channel<PoseInFrame>, u32)>,
    links: BTreeMap<u16, Channel<LinkHealth>>,
    /// The station's clock at the last link health logged, ms.
    links_logged_ms: Option<u32>,
    events_logged: usize,
}

/// Now, ns since the Unix epoch.
pub fn now_ns() -> u64 {
    SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

impl LiveRecording {
    /// Records to `mcap` and/or serves on `live` (either may be absent; browsers' pages from
    /// `origins` and the default ones may open it), a pose channel per robot of `robots`;
    /// the file opens with a metadata record of `scenario`'s run.
    pub fn create(
        scenario: &str,
        mcap: Option<&Path>,
        live: Option<SocketAddr>,
        origins: &[String],
        robots: impl IntoIterator<Item = u16>,
    ) -> anyhow::Result<Self> {
        let ctx = Context::new();
        let writer = match mcap {
            Some(path) => {
                // Written beside, renamed into place when it closes: an interrupted run
                // never leaves the last recording truncated.
                let partial = crate::commands::partial_path(path);
                let file = std::fs::File::create(&partial)
                    .with_context(|| format!("cannot create {}", partial.display()))?;
                let writer = McapWriter::new()
                    .context(&ctx)
                    .create(BufWriter::new(file))
                    .with_context(|| format!("cannot write {}", partial.display()))?;
                let metadata = base_station::recording::run_metadata(
                    scenario,
                    None,
                    "robots",
                    std::time::SystemTime::now(),
                );
                writer
                    .write_metadata(base_station::recording::METADATA_NAME, metadata)
                    .with_context(|| format!("cannot write {}", partial.display()))?;
                Some((writer, partial, path.to_path_buf()))
            }
            None => None,
        };
        let server = match live {
            Some(addr) => {
                // The server itself on the loopback only; the gate on `addr` checks Origin.
                let server = WebSocketServer::new()
                    .name("sweeper base station")
                    .context(&ctx)
                    .bind("127.0.0.1", 0)
                    .start_blocking()
                    .context("cannot start the Foxglove server")?;
                let inner = SocketAddr::from(([127, 0, 0, 1], server.port()));
                let bound = gate::start(addr, inner, origins)?;
                eprintln!("live (Foxglove WebSocket): ws://{bound}");
                Some(server)
            }
            None => None,
        };
        let radio = radio_channel(&ctx).map_err(anyhow::Error::msg)?;
        let events = events_channel(&ctx);
        let robots: Vec<u16> = robots.into_iter().collect();
        let links = robots
            .iter()
            .map(|id| {
                let ch = ctx
                    .channel_builder(format!("/robot_{id}/link"))
                    .build::<LinkHealth>();
                (*id, ch)
            })
            .collect();
        let poses = robots
            .into_iter()
            .map(|id| {
                let ch = ctx
                    .channel_builder(format!("/robot_{id}/pose"))
                    .build::<PoseInFrame>();
                (id, (ch, u32::MAX))
            })
            .collect();
        Ok(Self {
            _ctx: ctx,
            writer,
            server,
            radio,
            events,
            poses,
            links,
            links_logged_ms: None,
            events_logged: 0,
        })
    }

    /// Bytes the station sent (`from` `base`) or received (`air`: any sender) at `t_ns`.
    pub fn radio(&self, from: &str, bytes: &[u8], t_ns: u64) {
        if !bytes.is_empty() {
            log_radio(&self.radio, from, bytes, t_ns);
        }
    }

    /// What the station learnt since the last call, at `t` (its clock `now_ms`): new
    /// events, new telemetry poses, and each robot's link health once a second.
    pub fn station(&mut self, station: &BaseStation, now_ms: u32, t: u64) {
        if self
            .links_logged_ms
            .is_none_or(|last| now_ms.wrapping_sub(last) >= 1000)
        {
            self.links_logged_ms = Some(now_ms);
            for (id, health) in link_health(station, now_ms) {
                if let Some(channel) = self.links.get(&id) {
                    channel.log_with_time(&health, t);
                }
            }
        }
        let leader = station.config().leader;
        for e in &station.events()[self.events_logged..] {
            let (_, name, robot) = e.describe(leader);
            log_event(&self.events, &name, robot, t);
        }
        self.events_logged = station.events().len();
        for (id, status) in station.robots() {
            let (Some(telemetry), Some((channel, seen))) =
                (status.telemetry, self.poses.get_mut(id))
            else {
                continue;
            };
            if *seen == status.received_ms {
                continue;
            }
            *seen = status.received_ms;
            let (x, y, heading) = telemetry.pose.to_si();
            channel.log_with_time(
                &PoseInFrame {
                    timestamp: stamp(t),
                    frame_id: FRAME.into(),
                    pose: pose(x as f64, y as f64, 0.0, heading as f64),
                },
                t,
            );
        }
    }

    pub fn close(self) -> anyhow::Result<()> {
        if let Some(server) = self.server {
            server.stop().wait_blocking();
        }
        let Some((writer, partial, path)) = self.writer else {
            return Ok(());
        };
        writer.close().context("cannot finish the recording")?;
        std::fs::rename(&partial, &path).with_context(|| format!("cannot write {}", path.display()))
    }
}
