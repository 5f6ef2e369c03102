//! What the line feeds read from the network share (the localization feed, the scan
//! feed): datagrams split into lines on a thread of their own, and a bounded queue to the
//! station's loop that drops and counts what does not fit rather than block the reader.

use std::net::UdpSocket;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{SyncSender, TrySendError};

use anyhow::Context;

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

/// Reads datagrams on `socket` on a thread named `name` and hands each non-empty line of
/// them to `line`, until `line` returns `false` or the socket fails.
pub fn read_udp_lines(
    socket: UdpSocket,
    name: &str,
    mut line: impl FnMut(&[u8]) -> bool + Send + 'static,
) -> anyhow::Result<()> {
    std::thread::Builder::new()
        .name(name.into())
        .spawn(move || {
            let mut buf = [0u8; 65_536];
            while let Ok(n) = socket.recv(&mut buf) {
                for text in buf[..n].split(|b| *b == b'\n') {
                    if !text.is_empty() && !line(text) {
                        return;
                    }
                }
            }
        })
        .with_context(|| format!("cannot start the {name} reader"))?;
    Ok(())
}
