//! The console's HTTP server: hyper on a tokio runtime of its own thread, so that nothing a
//! client sends can stop or slow the station's loop, which only swaps a snapshot in and
//! takes commands out of a bounded queue. Everything a client can make it hold is bounded:
//!
//! - connections: [`MAX_CONNECTIONS`] in all and [`MAX_PER_ADDRESS`] from one address,
//!   admitted by [`crate::live::admission`]: a paired one (a request with the session
//!   cookie or the code) is never closed to make room, an anonymous one lives at most
//!   [`CONNECTION_LIFETIME`]; an idle one closes after [`HEAD_TIMEOUT`]; the listening
//!   queue holds [`BACKLOG`] connections not yet accepted;
//! - a request's head: [`MAX_HEAD`] bytes and 32 headers, read within [`HEAD_TIMEOUT`];
//! - a body: [`MAX_BODY`] bytes, read within [`BODY_TIMEOUT`];
//! - commands waiting for the station: [`COMMANDS`]; more are refused (503).

use std::convert::Infallible;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use super::guard::{Guard, Refusal, COOKIE_NAME};
use crate::live::admission::{self, Admission, Limits};
use base_station::station::OperatorCommand;
use bytes::Bytes;
use http_body_util::{BodyExt, Full, Limited};
use hyper::body::Incoming;
use hyper::header::{HeaderValue, CONTENT_TYPE, SET_COOKIE};
use hyper::{Method, Request, Response, StatusCode};
use hyper_util::rt::{TokioIo, TokioTimer};
use serde_json::Value;

pub const MAX_CONNECTIONS: usize = 256;
pub const MAX_PER_ADDRESS: usize = 64;
/// Connections the kernel queues before accept: a burst beyond it makes a client wait a
/// second for its SYN to be sent again.
pub const BACKLOG: i32 = 1024;
pub const CONNECTION_LIFETIME: Duration = Duration::from_secs(60);
pub const MAX_HEAD: usize = 8192;
pub const HEAD_TIMEOUT: Duration = Duration::from_secs(5);
pub const MAX_BODY: usize = 1024;
pub const BODY_TIMEOUT: Duration = Duration::from_secs(5);
pub const COMMANDS: usize = 16;

const PAGE: &str = include_str!("page.html");

/// What a page served this way shows and takes: the station's console, `ops`'s view.
pub trait Backend: Send + Sync + 'static {
    /// The page (HTML with its script).
    fn page(&self) -> &'static str;
    /// The slow-changing picture (JSON): maps, routes.
    fn map(&self) -> String;
    /// The state as the page shows it now (JSON).
    fn state(&self) -> String;
    /// A command's body (JSON, at most [`MAX_BODY`] bytes): what the page is told.
    fn command(
        &self,
        body: Bytes,
    ) -> impl std::future::Future<Output = Response<Full<Bytes>>> + Send;
}

/// Who may use the page, and what it serves.
pub struct Shared<B> {
    pub guard: Guard,
    pub backend: B,
}

/// The station's console: what its loop and the server share.
pub struct Station {
    /// The fleet as the page shows it now (JSON), swapped whole by the station's loop.
    pub snapshot: Mutex<Arc<str>>,
    /// The site's static picture (JSON).
    pub map: Arc<str>,
    pub commands: SyncSender<OperatorCommand>,
}

impl Backend for Station {
    fn page(&self) -> &'static str {
        PAGE
    }

    fn map(&self) -> String {
        self.map.to_string()
    }

    fn state(&self) -> String {
        let snapshot = self.snapshot.lock().map(|s| s.clone());
        snapshot.map(|s| s.to_string()).unwrap_or_default()
    }

    async fn command(&self, body: Bytes) -> Response<Full<Bytes>> {
        command(self, &body)
    }
}

/// A page served: what it serves, its thread, and where to open it.
pub struct Served<B> {
    pub shared: Arc<Shared<B>>,
    pub thread: std::thread::JoinHandle<()>,
    /// The page with its pairing code, on the first of its addresses.
    pub url: String,
    /// Every address the page can be opened at (the interfaces', bound to all).
    pub urls: Vec<String>,
}

/// Serves `backend`'s page on `addr` (port 0: any free port) as `name`, guarded by a fresh
/// pairing code.
pub fn open<B: Backend>(name: &str, addr: SocketAddr, backend: B) -> anyhow::Result<Served<B>> {
    let listener = std::net::TcpListener::bind(addr)
        .map_err(|e| anyhow::anyhow!("cannot serve the {name} on {addr}: {e}"))?;
    let bound = listener.local_addr()?;
    let addresses = super::reachable_at(bound);
    let guard = Guard::new(bound, &addresses)?;
    let urls: Vec<String> = addresses
        .iter()
        .map(|a| super::url_of(*a, bound.port()))
        .collect();
    let url = format!("{}#pair={}", urls[0], guard.code());
    let shared = Arc::new(Shared { guard, backend });
    let thread = spawn(name, listener, shared.clone())?;
    Ok(Served {
        shared,
        thread,
        url,
        urls,
    })
}

/// Serves `listener` on a thread named `name` with a runtime of its own.
fn spawn<B: Backend>(
    name: &str,
    listener: std::net::TcpListener,
    shared: Arc<Shared<B>>,
) -> anyhow::Result<std::thread::JoinHandle<()>> {
    let label = name.to_string();
    std::thread::Builder::new()
        .name(label.clone())
        .spawn(move || {
            let runtime = match tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
            {
                Ok(r) => r,
                Err(e) => return tracing::error!("{label}: no runtime: {e}"),
            };
            if let Err(e) = runtime.block_on(serve(listener, shared)) {
                tracing::error!("{label}: {e}");
            }
        })
        .map_err(|e| anyhow::anyhow!("cannot start the {name}'s thread: {e}"))
}

/// Serves `listener` until the process ends.
pub async fn serve<B: Backend>(
    listener: std::net::TcpListener,
    shared: Arc<Shared<B>>,
) -> std::io::Result<()> {
    listener.set_nonblocking(true)?;
    crate::live::admission::deepen(&listener, BACKLOG);
    let listener = tokio::net::TcpListener::from_std(listener)?;
    let connections = Admission::new(Limits {
        total: MAX_CONNECTIONS,
        per_address: MAX_PER_ADDRESS,
    });
    loop {
        let (stream, peer) = match listener.accept().await {
            Ok(accepted) => accepted,
            // Out of file descriptors, a reset before accept: wait and go on.
            Err(e) => {
                tracing::debug!("console: accept failed: {e}");
                tokio::time::sleep(Duration::from_millis(50)).await;
                continue;
            }
        };
        let mut first = [0u8; MAX_HEAD];
        let trusted = known(&shared.guard, admission::peek(&stream, &mut first));
        let Some(slot) = connections.open(peer.ip(), trusted) else {
            continue; // dropped: closes the connection
        };
        let shared = shared.clone();
        tokio::spawn(async move {
            let _ = stream.set_nodelay(true);
            let paired = slot.trust_flag();
            let service = hyper::service::service_fn(move |request| {
                let (shared, paired) = (shared.clone(), paired.clone());
                async move { Ok::<_, Infallible>(handle(&shared, peer, &paired, request).await) }
            });
            let connection = hyper::server::conn::http1::Builder::new()
                .timer(TokioTimer::new())
                .header_read_timeout(HEAD_TIMEOUT)
                .max_buf_size(MAX_HEAD)
                .max_headers(32)
                .serve_connection(TokioIo::new(stream), service);
            tokio::pin!(connection);
            // An anonymous connection's lifetime is bounded; a paired one's is not (a
            // browser that had to reconnect would be anonymous again for a moment).
            let lifetime = async {
                tokio::time::sleep(CONNECTION_LIFETIME).await;
                while slot.is_trusted() {
                    tokio::time::sleep(HEAD_TIMEOUT).await;
                }
            };
            tokio::select! {
                _ = &mut connection => {}
                _ = lifetime => {}
                _ = slot.evicted() => {}
            }
        });
    }
}

/// Whether `head`, what a new connection sent first, is a request with a live session.
fn known(guard: &Guard, head: &[u8]) -> bool {
    let mut headers = [httparse::EMPTY_HEADER; 32];
    let mut request = httparse::Request::new(&mut headers);
    if request.parse(head).is_err() {
        return false;
    }
    let mut map = hyper::HeaderMap::new();
    for h in request.headers.iter() {
        let (Ok(name), Ok(value)) = (
            hyper::header::HeaderName::from_bytes(h.name.as_bytes()),
            HeaderValue::from_bytes(h.value),
        ) else {
            continue;
        };
        map.append(name, value);
    }
    guard.knows(&map)
}

pub fn respond(status: u16, content_type: &str, body: impl Into<Bytes>) -> Response<Full<Bytes>> {
    let mut r = Response::new(Full::new(body.into()));
    *r.status_mut() = StatusCode::from_u16(status).unwrap_or(StatusCode::INTERNAL_SERVER_ERROR);
    let h = r.headers_mut();
    let set = |h: &mut hyper::HeaderMap, k: &'static str, v: &'static str| {
        h.insert(k, HeaderValue::from_static(v));
    };
    if let Ok(v) = HeaderValue::from_str(content_type) {
        h.insert(CONTENT_TYPE, v);
    }
    set(h, "cache-control", "no-store");
    set(h, "x-content-type-options", "nosniff");
    set(h, "x-frame-options", "DENY");
    set(h, "referrer-policy", "no-referrer");
    set(
        h,
        "content-security-policy",
        "default-src 'self'; script-src 'self' 'unsafe-inline'; \
         style-src 'self' 'unsafe-inline'; img-src 'self' data:; frame-ancestors 'none'",
    );
    r
}

pub fn json(status: u16, body: String) -> Response<Full<Bytes>> {
    respond(status, "application/json", body)
}

fn refused(why: Refusal) -> Response<Full<Bytes>> {
    respond(why.status(), "text/plain; charset=utf-8", why.message())
}

/// A request's body, if it is within [`MAX_BODY`] and comes within [`BODY_TIMEOUT`].
pub async fn body(request: Request<Incoming>) -> Result<Bytes, Response<Full<Bytes>>> {
    let limited = Limited::new(request.into_body(), MAX_BODY);
    match tokio::time::timeout(BODY_TIMEOUT, limited.collect()).await {
        Ok(Ok(collected)) => Ok(collected.to_bytes()),
        Ok(Err(_)) => Err(respond(413, "text/plain", "a body over 1 KiB")),
        Err(_) => Err(respond(408, "text/plain", "the body did not come in time")),
    }
}

/// One request from `peer` on a connection whose `paired` flag it sets when it shows it
/// is paired.
async fn handle<B: Backend>(
    shared: &Shared<B>,
    peer: SocketAddr,
    paired: &AtomicBool,
    request: Request<Incoming>,
) -> Response<Full<Bytes>> {
    let g = &shared.guard;
    if let Err(why) = g.check_host(request.headers()) {
        return refused(why);
    }
    let path = request.uri().path().to_string();
    match (request.method().clone(), path.as_str()) {
        (Method::GET, "/") => respond(200, "text/html; charset=utf-8", shared.backend.page()),
        (Method::POST, "/api/pair") => {
            if let Err(why) = g.check_write(request.headers()) {
                return refused(why);
            }
            let bytes = match body(request).await {
                Ok(b) => b,
                Err(r) => return r,
            };
            let code = serde_json::from_slice::<Value>(&bytes)
                .ok()
                .and_then(|v| v.get("code")?.as_str().map(str::to_string))
                .unwrap_or_default();
            match g.pair(peer.ip(), &code) {
                Ok(session) => {
                    paired.store(true, Ordering::Relaxed);
                    let mut r = json(200, "{\"paired\":true}".into());
                    let cookie =
                        format!("{COOKIE_NAME}={session}; HttpOnly; SameSite=Strict; Path=/");
                    if let Ok(v) = HeaderValue::from_str(&cookie) {
                        r.headers_mut().insert(SET_COOKIE, v);
                    }
                    r
                }
                Err(why) => refused(why),
            }
        }
        (method, "/api/map" | "/api/state" | "/api/command") => {
            if let Err(why) = g.check_paired(request.headers()) {
                return refused(why);
            }
            paired.store(true, Ordering::Relaxed);
            match (method, path.as_str()) {
                (Method::GET, "/api/map") => json(200, shared.backend.map()),
                (Method::GET, "/api/state") => json(200, shared.backend.state()),
                (Method::POST, "/api/command") => {
                    if let Err(why) = g.check_write(request.headers()) {
                        return refused(why);
                    }
                    match body(request).await {
                        Ok(bytes) => shared.backend.command(bytes).await,
                        Err(r) => r,
                    }
                }
                _ => respond(405, "text/plain", "method not allowed"),
            }
        }
        _ => respond(404, "text/plain", "not found"),
    }
}

fn command(station: &Station, bytes: &[u8]) -> Response<Full<Bytes>> {
    let Some(c) = std::str::from_utf8(bytes)
        .ok()
        .and_then(super::parse_command)
    else {
        return respond(
            400,
            "text/plain",
            "expected {\"command\": \"stop\" | \"emergency_stop\" | \"resume\"}",
        );
    };
    if c == OperatorCommand::Resume && halted(station) {
        return respond(
            409,
            "text/plain",
            "refused: the fleet halted for good (a robot cannot drive as told); \
             clear the fault and start the run again",
        );
    }
    match station.commands.try_send(c) {
        Ok(()) => json(200, format!("{{\"sent\":\"{}\"}}", c.name())),
        Err(TrySendError::Full(_)) => respond(503, "text/plain", "too many commands waiting"),
        Err(TrySendError::Disconnected(_)) => respond(410, "text/plain", "the run has ended"),
    }
}

/// Whether the last snapshot says the fleet halted for good: Resume cannot lift that.
fn halted(station: &Station) -> bool {
    let Ok(snapshot) = station.snapshot.lock().map(|s| s.clone()) else {
        return false;
    };
    serde_json::from_str::<serde_json::Value>(&snapshot).is_ok_and(|s| s["gate"] == "halted")
}
