//! The live stream of `--live`: the station serves the Foxglove WebSocket protocol (v1,
//! read-only) itself, on the address the operator gave and nowhere else, so nothing reaches
//! the stream without passing its door. The door lets a connection through when
//!
//! - its `Origin` is allowed: none (a desktop app, a script), one of [`DEFAULT_ORIGINS`] or
//!   `--live-origin`; a page of any other site, or a name rebound to the station, gets 403;
//! - its URL carries the run's token (`?token=…`, 128 random bits printed with the URL),
//!   so a local process or a host on the site network that does not hold it gets 401;
//! - it offers the protocol (`foxglove.sdk.v1` or `foxglove.websocket.v1`).
//!
//! Places are kept as the console's are ([`crate::live::admission`]): a connection that
//! has not passed the door yet is anonymous and gives way to newcomers; [`MAX_VIEWERS`]
//! viewers who passed it are never closed to make room, so idle or anonymous connections
//! cannot shut the operator's Foxglove out. The stream is read-only: no services,
//! parameters or client publishing; a viewer too slow for the stream loses messages
//! (counted), and is closed if even the channel list cannot reach it.
//!
//! The messages come from the recording's [`Context`] through a [`Sink`]: the station's
//! loop only queues frames (never waits on a viewer); the server runs on a thread and
//! runtime of its own.

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use anyhow::Context as _;
use base64::Engine as _;
use foxglove::{Context, FoxgloveError, Metadata, RawChannel, Sink, SinkId};
use futures_util::{SinkExt, StreamExt};
use serde_json::{json, Value};
use tokio::sync::{mpsc, Notify};
use tokio_tungstenite::tungstenite::handshake::server::{ErrorResponse, Request, Response};
use tokio_tungstenite::tungstenite::http::{HeaderValue, StatusCode};
use tokio_tungstenite::tungstenite::protocol::WebSocketConfig;
use tokio_tungstenite::tungstenite::Message;

use crate::live::admission::{self, Admission, Limits};
use crate::live::console::same;

/// The web apps that open the stream in a browser.
pub const DEFAULT_ORIGINS: &[&str] = &[
    "https://app.foxglove.dev",
    "https://lichtblick-suite.github.io",
];
/// Viewers who passed the door at once.
pub const MAX_VIEWERS: usize = 32;
/// Connections held in all (viewers and those still at the door).
const MAX_CONNECTIONS: usize = 128;
/// How long a connection may take to pass the door.
const HANDSHAKE_TIMEOUT: Duration = Duration::from_secs(5);
/// Frames waiting for one viewer: about 10 s of a fleet of 9 at 10 Hz.
const QUEUE: usize = 2048;
/// A viewer's own messages (subscriptions) are small.
const MAX_CLIENT_MESSAGE: usize = 64 * 1024;
/// Subscriptions one viewer may hold.
const MAX_SUBSCRIPTIONS: usize = 1024;
const SUBPROTOCOLS: &[&str] = &["foxglove.sdk.v1", "foxglove.websocket.v1"];

/// One viewer: its queue and what it subscribed to (subscription id → channel id).
struct Viewer {
    id: u64,
    queue: mpsc::Sender<Message>,
    subscriptions: Mutex<BTreeMap<u32, u64>>,
    /// Rung when even the channel list could not be queued.
    lagging: Notify,
}

/// The stream's end of the recording: every message logged goes to each viewer that
/// subscribed to its channel.
pub struct Hub {
    id: SinkId,
    /// Each channel's advertisement, by channel id.
    channels: Mutex<BTreeMap<u64, Value>>,
    viewers: Mutex<Vec<Arc<Viewer>>>,
    next_viewer: AtomicU64,
    /// Frames a slow viewer did not get.
    pub dropped: AtomicU64,
    /// Connections refused at the door.
    pub refused: AtomicU64,
}

/// A channel as the protocol advertises it.
fn advertisement(channel: &RawChannel) -> Value {
    let id = u64::from(channel.id());
    let mut ad = json!({
        "id": id,
        "topic": channel.topic(),
        "encoding": channel.message_encoding(),
        "schemaName": "",
        "schema": "",
    });
    if let Some(schema) = channel.schema() {
        let binary = matches!(schema.encoding.as_str(), "protobuf" | "flatbuffer");
        ad["schemaName"] = json!(schema.name);
        ad["schemaEncoding"] = json!(schema.encoding);
        ad["schema"] = if binary {
            json!(base64::engine::general_purpose::STANDARD.encode(&schema.data))
        } else {
            json!(String::from_utf8_lossy(&schema.data))
        };
    }
    ad
}

/// A message as the protocol carries it: opcode 1, subscription (u32 LE), log time (u64
/// LE, ns), payload.
fn message_data(subscription: u32, log_time: u64, payload: &[u8]) -> Vec<u8> {
    let mut frame = Vec::with_capacity(13 + payload.len());
    frame.push(1);
    frame.extend_from_slice(&subscription.to_le_bytes());
    frame.extend_from_slice(&log_time.to_le_bytes());
    frame.extend_from_slice(payload);
    frame
}

impl Hub {
    fn new() -> Arc<Self> {
        Arc::new(Self {
            id: SinkId::next(),
            channels: Mutex::default(),
            viewers: Mutex::default(),
            next_viewer: AtomicU64::new(0),
            dropped: AtomicU64::new(0),
            refused: AtomicU64::new(0),
        })
    }

    /// Queues a control message to every viewer; one that cannot take it is closed.
    fn tell_all(&self, message: &Value) {
        let Ok(viewers) = self.viewers.lock() else {
            return;
        };
        for v in viewers.iter() {
            if v.queue
                .try_send(Message::text(message.to_string()))
                .is_err()
            {
                v.lagging.notify_one();
            }
        }
    }

    /// A new viewer, given the channels as they are now.
    fn join(&self) -> (Arc<Viewer>, mpsc::Receiver<Message>) {
        let (queue, rx) = mpsc::channel(QUEUE);
        let viewer = Arc::new(Viewer {
            id: self.next_viewer.fetch_add(1, Ordering::Relaxed),
            queue,
            subscriptions: Mutex::default(),
            lagging: Notify::new(),
        });
        if let Ok(mut viewers) = self.viewers.lock() {
            viewers.push(viewer.clone());
        }
        (viewer, rx)
    }

    fn leave(&self, viewer: &Viewer) {
        if let Ok(mut viewers) = self.viewers.lock() {
            viewers.retain(|v| v.id != viewer.id);
        }
    }

    /// The opening messages for a new viewer: who we are, and the channels.
    fn greeting(&self) -> [Value; 2] {
        let channels: Vec<Value> = self
            .channels
            .lock()
            .map(|c| c.values().cloned().collect())
            .unwrap_or_default();
        [
            json!({
                "op": "serverInfo",
                "name": "sweeper base station",
                "capabilities": [],
                "supportedEncodings": [],
                "metadata": {},
            }),
            json!({ "op": "advertise", "channels": channels }),
        ]
    }
}

impl Sink for Hub {
    fn id(&self) -> SinkId {
        self.id
    }

    fn log(
        &self,
        channel: &RawChannel,
        msg: &[u8],
        metadata: &Metadata,
    ) -> Result<(), FoxgloveError> {
        let id = u64::from(channel.id());
        let Ok(viewers) = self.viewers.lock() else {
            return Ok(());
        };
        for v in viewers.iter() {
            let subs: Vec<u32> = v.subscriptions.lock().map_or(Vec::new(), |s| {
                s.iter()
                    .filter(|(_, c)| **c == id)
                    .map(|(s, _)| *s)
                    .collect()
            });
            for sub in subs {
                let frame = message_data(sub, metadata.log_time, msg);
                if v.queue.try_send(Message::binary(frame)).is_err() {
                    self.dropped.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
        Ok(())
    }

    fn add_channels(&self, channels: &[&Arc<RawChannel>]) -> Option<Vec<foxglove::ChannelId>> {
        let ads: Vec<Value> = channels.iter().map(|c| advertisement(c)).collect();
        if let Ok(mut known) = self.channels.lock() {
            for ad in &ads {
                known.insert(ad["id"].as_u64().unwrap_or_default(), ad.clone());
            }
        }
        self.tell_all(&json!({ "op": "advertise", "channels": ads }));
        None
    }

    fn remove_channel(&self, channel: &RawChannel) {
        let id = u64::from(channel.id());
        if let Ok(mut known) = self.channels.lock() {
            known.remove(&id);
        }
        self.tell_all(&json!({ "op": "unadvertise", "channelIds": [id] }));
    }
}

/// What a viewer may send: subscribe and unsubscribe; anything else is ignored.
fn take_request(viewer: &Viewer, text: &str) {
    let Ok(request) = serde_json::from_str::<Value>(text) else {
        return;
    };
    let Ok(mut subs) = viewer.subscriptions.lock() else {
        return;
    };
    match request["op"].as_str() {
        Some("subscribe") => {
            for s in request["subscriptions"].as_array().into_iter().flatten() {
                let (Some(id), Some(channel)) = (s["id"].as_u64(), s["channelId"].as_u64()) else {
                    continue;
                };
                if subs.len() < MAX_SUBSCRIPTIONS {
                    subs.insert(id as u32, channel);
                }
            }
        }
        Some("unsubscribe") => {
            for id in request["subscriptionIds"].as_array().into_iter().flatten() {
                if let Some(id) = id.as_u64() {
                    subs.remove(&(id as u32));
                }
            }
        }
        _ => {}
    }
}

/// What the door checks before a connection becomes a viewer.
struct Door {
    origins: Vec<String>,
    token: String,
}

impl Door {
    /// The answer to an opening request: the protocol chosen, or why it was refused.
    fn check(&self, request: &Request) -> Result<&'static str, (StatusCode, &'static str)> {
        let headers = request.headers();
        if let Some(origin) = headers.get("origin") {
            let origin = String::from_utf8_lossy(origin.as_bytes()).to_ascii_lowercase();
            if !self.origins.iter().any(|a| a.eq_ignore_ascii_case(&origin)) {
                return Err((StatusCode::FORBIDDEN, "this origin may not open the stream"));
            }
        }
        let path = request.uri().path_and_query().map_or("", |p| p.as_str());
        if !self.token_of(path) {
            return Err((
                StatusCode::UNAUTHORIZED,
                "the stream's token is missing or wrong",
            ));
        }
        let offered: Vec<&str> = headers
            .get_all("sec-websocket-protocol")
            .iter()
            .flat_map(|h| h.to_str().unwrap_or_default().split(','))
            .map(str::trim)
            .collect();
        SUBPROTOCOLS
            .iter()
            .find(|p| offered.contains(p))
            .copied()
            .ok_or((StatusCode::BAD_REQUEST, "offer foxglove.sdk.v1"))
    }
}

impl Door {
    /// Whether `head`, what a new connection sent first, carries the token.
    fn knows(&self, head: &[u8]) -> bool {
        let mut headers = [httparse::EMPTY_HEADER; 32];
        let mut request = httparse::Request::new(&mut headers);
        request.parse(head).is_ok() && request.path.is_some_and(|p| self.token_of(p))
    }

    /// Whether a request's path carries the token.
    fn token_of(&self, path: &str) -> bool {
        let token = path
            .split_once('?')
            .into_iter()
            .flat_map(|(_, q)| q.split('&'))
            .find_map(|pair| pair.strip_prefix("token="))
            .unwrap_or_default();
        same(token.as_bytes(), self.token.as_bytes())
    }
}

fn refusal(status: StatusCode, why: &str) -> ErrorResponse {
    let mut response = ErrorResponse::new(Some(why.to_string()));
    *response.status_mut() = status;
    response
}

/// One connection: at the door, then a viewer until either side closes.
#[allow(clippy::result_large_err)] // the handshake's callback type is tungstenite's
async fn serve_one(
    stream: tokio::net::TcpStream,
    slot: admission::Slot,
    door: Arc<Door>,
    hub: Arc<Hub>,
    viewers: Arc<Admission>,
) {
    let trusted = slot.trust_flag();
    let hub_at_door = hub.clone();
    let callback = move |request: &Request, mut response: Response| {
        let refuse = |status, why| {
            hub_at_door.refused.fetch_add(1, Ordering::Relaxed);
            Err(refusal(status, why))
        };
        let protocol = match door.check(request) {
            Ok(p) => p,
            Err((status, why)) => return refuse(status, why),
        };
        // This connection is among the trusted already when its token came with it.
        let others = viewers
            .trusted()
            .saturating_sub(usize::from(trusted.load(Ordering::Relaxed)));
        if others >= MAX_VIEWERS {
            return refuse(
                StatusCode::SERVICE_UNAVAILABLE,
                "the stream has all its viewers",
            );
        }
        trusted.store(true, Ordering::Relaxed);
        response
            .headers_mut()
            .insert("sec-websocket-protocol", HeaderValue::from_static(protocol));
        Ok(response)
    };
    let config = WebSocketConfig::default()
        .max_message_size(Some(MAX_CLIENT_MESSAGE))
        .max_frame_size(Some(MAX_CLIENT_MESSAGE));
    let handshake = tokio_tungstenite::accept_hdr_async_with_config(stream, callback, Some(config));
    let socket = tokio::select! {
        done = tokio::time::timeout(HANDSHAKE_TIMEOUT, handshake) => match done {
            Ok(Ok(socket)) => socket,
            _ => return,
        },
        _ = slot.evicted() => return,
    };
    watch(socket, &hub).await;
}

/// A viewer's life: the greeting, then frames out and requests in.
async fn watch(mut socket: tokio_tungstenite::WebSocketStream<tokio::net::TcpStream>, hub: &Hub) {
    let (viewer, mut frames) = hub.join();
    for message in hub.greeting() {
        if socket
            .send(Message::text(message.to_string()))
            .await
            .is_err()
        {
            return hub.leave(&viewer);
        }
    }
    loop {
        tokio::select! {
            frame = frames.recv() => {
                let Some(frame) = frame else { break };
                if socket.send(frame).await.is_err() {
                    break;
                }
            }
            incoming = socket.next() => match incoming {
                Some(Ok(Message::Text(text))) => take_request(&viewer, &text),
                Some(Ok(Message::Close(_))) | Some(Err(_)) | None => break,
                Some(Ok(_)) => {}
            },
            _ = viewer.lagging.notified() => break,
        }
    }
    hub.leave(&viewer);
}

/// The served stream: remove it from the recording when the run ends.
pub struct Stream {
    ctx: Arc<Context>,
    hub: Arc<Hub>,
}

impl Stream {
    pub fn stop(self) {
        self.ctx.remove_sink(self.hub.id);
        let (dropped, refused) = (
            self.hub.dropped.load(Ordering::Relaxed),
            self.hub.refused.load(Ordering::Relaxed),
        );
        if dropped + refused > 0 {
            tracing::info!(
                "live: {dropped} frames a slow viewer missed, {refused} connections refused"
            );
        }
    }
}

/// Serves `ctx`'s channels on `addr` to pages of the default origins and `extra`; the URL a
/// viewer opens (with the token).
pub fn start(
    ctx: &Arc<Context>,
    addr: SocketAddr,
    extra: &[String],
) -> anyhow::Result<(Stream, String)> {
    let listener = std::net::TcpListener::bind(addr)
        .with_context(|| format!("cannot serve Foxglove on {addr}"))?;
    let bound = listener.local_addr()?;
    listener.set_nonblocking(true)?;
    admission::deepen(&listener, 1024);
    let mut token = [0u8; 16];
    getrandom::fill(&mut token).map_err(|e| anyhow::anyhow!("no OS randomness: {e}"))?;
    let door = Arc::new(Door {
        origins: DEFAULT_ORIGINS
            .iter()
            .map(|o| o.to_string())
            .chain(extra.iter().map(|o| o.trim_end_matches('/').to_string()))
            .collect(),
        token: hex::encode(token),
    });
    let url = format!("ws://{bound}/?token={}", door.token);
    let hub = Hub::new();
    ctx.add_sink(hub.clone());
    let serving = hub.clone();
    std::thread::Builder::new()
        .name("live-stream".into())
        .spawn(move || {
            let runtime = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build();
            match runtime {
                Ok(runtime) => runtime.block_on(accept(listener, door, serving)),
                Err(e) => tracing::error!("live: no runtime: {e}"),
            }
        })
        .context("cannot start the live stream")?;
    let stream = Stream {
        ctx: ctx.clone(),
        hub,
    };
    Ok((stream, url))
}

async fn accept(listener: std::net::TcpListener, door: Arc<Door>, hub: Arc<Hub>) {
    let Ok(listener) = tokio::net::TcpListener::from_std(listener) else {
        return tracing::error!("live: cannot listen");
    };
    let places = Admission::new(Limits {
        total: MAX_CONNECTIONS,
        per_address: MAX_CONNECTIONS,
    });
    loop {
        let Ok((client, peer)) = listener.accept().await else {
            tokio::time::sleep(Duration::from_millis(50)).await;
            continue;
        };
        let mut first = [0u8; 4096];
        let trusted = door.knows(admission::peek(&client, &mut first));
        let Some(slot) = places.open(peer.ip(), trusted) else {
            continue;
        };
        let (door, hub, places) = (door.clone(), hub.clone(), places.clone());
        tokio::spawn(serve_one(client, slot, door, hub, places));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn door() -> Door {
        Door {
            origins: DEFAULT_ORIGINS.iter().map(|o| o.to_string()).collect(),
            token: "00ff".into(),
        }
    }

    fn request(path: &str, origin: Option<&str>, protocol: &str) -> Request {
        let mut r = Request::builder()
            .uri(path)
            .header("sec-websocket-protocol", protocol);
        if let Some(o) = origin {
            r = r.header("origin", o);
        }
        r.body(()).unwrap()
    }

    #[test]
    fn the_door_wants_an_allowed_origin_the_token_and_the_protocol() {
        let d = door();
        let ok = request("/?token=00ff", None, "foxglove.sdk.v1");
        assert_eq!(d.check(&ok), Ok("foxglove.sdk.v1"));
        let app = request(
            "/?token=00ff",
            Some("https://app.foxglove.dev"),
            "foxglove.websocket.v1",
        );
        assert_eq!(d.check(&app), Ok("foxglove.websocket.v1"));
        let evil = request(
            "/?token=00ff",
            Some("http://evil.example"),
            "foxglove.sdk.v1",
        );
        assert_eq!(d.check(&evil).unwrap_err().0, StatusCode::FORBIDDEN);
        for path in ["/", "/?token=00fe", "/?token=00ff0", "/?x=1"] {
            let r = request(path, None, "foxglove.sdk.v1");
            assert_eq!(
                d.check(&r).unwrap_err().0,
                StatusCode::UNAUTHORIZED,
                "{path}"
            );
        }
        let other = request("/?token=00ff", None, "chat");
        assert_eq!(d.check(&other).unwrap_err().0, StatusCode::BAD_REQUEST);
    }

    #[test]
    fn a_message_is_framed_as_the_protocol_says() {
        let frame = message_data(7, 0x0102, b"ab");
        assert_eq!(frame, [1, 7, 0, 0, 0, 2, 1, 0, 0, 0, 0, 0, 0, b'a', b'b']);
    }
}
