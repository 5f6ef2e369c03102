//! The door of `--live`: the Foxglove WebSocket server listens on the loopback only, on a
//! port of its own; this gate listens on the address the operator gave and lets a
//! connection through to it only when its opening request comes from an allowed `Origin`
//! (none, as from a desktop app or a script, or one of [`DEFAULT_ORIGINS`] and
//! `--live-origin`). A page of any other site (or a name rebound to the station's address)
//! cannot open the stream in a visitor's browser. The stream is read-only: the server
//! offers no services, parameters or client publishing, so a client can watch, not act.
//!
//! Bounded like the console: at most [`MAX_CONNECTIONS`], an opening request of at most
//! [`MAX_HEAD`] bytes within [`HEAD_TIMEOUT`]; on a thread and runtime of its own.

use std::net::SocketAddr;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context;
use tokio::io::{AsyncReadExt, AsyncWriteExt};

/// The web apps that open the stream in a browser.
pub const DEFAULT_ORIGINS: &[&str] = &[
    "https://app.foxglove.dev",
    "https://lichtblick-suite.github.io",
];
const MAX_CONNECTIONS: usize = 32;
const MAX_HEAD: usize = 8192;
const HEAD_TIMEOUT: Duration = Duration::from_secs(5);

/// Why an opening request was refused, with its HTTP answer.
fn refusal(head: &[u8], origins: &[String]) -> Option<&'static str> {
    let mut headers = [httparse::EMPTY_HEADER; 32];
    let mut request = httparse::Request::new(&mut headers);
    match request.parse(head) {
        Ok(httparse::Status::Complete(_)) => {}
        _ => return Some("400 Bad Request"),
    }
    let origin = request
        .headers
        .iter()
        .find(|h| h.name.eq_ignore_ascii_case("origin"))
        .map(|h| String::from_utf8_lossy(h.value).to_ascii_lowercase());
    match origin {
        None => None,
        Some(o) if origins.iter().any(|a| a.eq_ignore_ascii_case(&o)) => None,
        Some(_) => Some("403 Forbidden"),
    }
}

/// Reads one opening request, up to the blank line.
async fn read_head(stream: &mut tokio::net::TcpStream) -> Option<Vec<u8>> {
    let mut head = Vec::with_capacity(1024);
    let mut buf = [0u8; 1024];
    while !head.windows(4).any(|w| w == b"\r\n\r\n") {
        let n = stream.read(&mut buf).await.ok()?;
        if n == 0 || head.len() + n > MAX_HEAD {
            return None;
        }
        head.extend_from_slice(&buf[..n]);
    }
    Some(head)
}

async fn pass(mut client: tokio::net::TcpStream, inner: SocketAddr, origins: Arc<[String]>) {
    let Ok(Some(head)) = tokio::time::timeout(HEAD_TIMEOUT, read_head(&mut client)).await else {
        return;
    };
    if let Some(status) = refusal(&head, &origins) {
        let answer = format!("HTTP/1.1 {status}\r\nContent-Length: 0\r\nConnection: close\r\n\r\n");
        let _ = client.write_all(answer.as_bytes()).await;
        return;
    }
    let Ok(mut server) = tokio::net::TcpStream::connect(inner).await else {
        return;
    };
    if server.write_all(&head).await.is_ok() {
        let _ = tokio::io::copy_bidirectional(&mut client, &mut server).await;
    }
}

/// Listens on `addr` and passes the allowed connections to the server at `inner`; the
/// address it listens on.
pub fn start(addr: SocketAddr, inner: SocketAddr, extra: &[String]) -> anyhow::Result<SocketAddr> {
    let listener = std::net::TcpListener::bind(addr)
        .with_context(|| format!("cannot serve Foxglove on {addr}"))?;
    let bound = listener.local_addr()?;
    listener.set_nonblocking(true)?;
    let origins: Arc<[String]> = DEFAULT_ORIGINS
        .iter()
        .map(|o| o.to_string())
        .chain(extra.iter().map(|o| o.trim_end_matches('/').to_string()))
        .collect();
    std::thread::Builder::new()
        .name("live-gate".into())
        .spawn(move || {
            let Ok(runtime) = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
            else {
                return tracing::error!("live: no runtime");
            };
            runtime.block_on(async move {
                let Ok(listener) = tokio::net::TcpListener::from_std(listener) else {
                    return tracing::error!("live: cannot listen");
                };
                let open = Arc::new(AtomicUsize::new(0));
                loop {
                    let Ok((client, _)) = listener.accept().await else {
                        tokio::time::sleep(Duration::from_millis(50)).await;
                        continue;
                    };
                    if open.fetch_add(1, Ordering::SeqCst) >= MAX_CONNECTIONS {
                        open.fetch_sub(1, Ordering::SeqCst);
                        continue;
                    }
                    let (open, origins) = (open.clone(), origins.clone());
                    tokio::spawn(async move {
                        pass(client, inner, origins).await;
                        open.fetch_sub(1, Ordering::SeqCst);
                    });
                }
            });
        })
        .context("cannot start the live gate")?;
    Ok(bound)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_allowed_origins_open_the_stream() {
        let origins: Vec<String> = DEFAULT_ORIGINS.iter().map(|o| o.to_string()).collect();
        let head = |origin: &str| {
            format!("GET / HTTP/1.1\r\nHost: 127.0.0.1:8765\r\nUpgrade: websocket\r\n{origin}\r\n")
        };
        assert_eq!(refusal(head("").as_bytes(), &origins), None);
        assert_eq!(
            refusal(
                head("Origin: https://app.foxglove.dev\r\n").as_bytes(),
                &origins
            ),
            None
        );
        assert_eq!(
            refusal(head("Origin: http://evil.example\r\n").as_bytes(), &origins),
            Some("403 Forbidden")
        );
        assert_eq!(
            refusal(b"garbage\r\n\r\n", &origins),
            Some("400 Bad Request")
        );
    }
}
