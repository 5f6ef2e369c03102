//! Who gets a place on the station's doors (the console, the live stream). A connection
//! is *anonymous* until a request on it shows it is trusted (a paired session, the live
//! stream's token); a trusted one is never closed to make room. When the doors are full, a
//! newcomer takes the place of the oldest anonymous connection (of its own address when it
//! is that address that is over its share), so idle or churning anonymous connections
//! cannot shut the operator out: a fresh connection of the operator's is closed only if
//! more than [`Limits::total`] newer ones come before its first request is read, which on
//! this machine takes well under a millisecond (`docs/RELIABILITY.md`).

use std::net::IpAddr;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use tokio::sync::Notify;

/// How many connections a door holds.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    pub total: usize,
    pub per_address: usize,
}

/// One open connection.
struct Entry {
    id: u64,
    address: IpAddr,
    trusted: Arc<AtomicBool>,
    close: Arc<Notify>,
}

/// The open connections of one door, oldest first.
pub struct Admission {
    limits: Limits,
    open: Mutex<Vec<Entry>>,
    next: AtomicU64,
}

/// One open connection's place: given up when dropped.
pub struct Slot {
    admission: Arc<Admission>,
    id: u64,
    trusted: Arc<AtomicBool>,
    close: Arc<Notify>,
}

impl Admission {
    pub fn new(limits: Limits) -> Arc<Self> {
        Arc::new(Self {
            limits,
            open: Mutex::new(Vec::new()),
            next: AtomicU64::new(0),
        })
    }

    /// A place for a connection from `address` (`trusted` already when what it sent first
    /// shows it), making room if needed; `None` when every connection in the way is
    /// trusted.
    pub fn open(self: &Arc<Self>, address: IpAddr, trusted: bool) -> Option<Slot> {
        let mut open = self.open.lock().ok()?;
        let mine = open.iter().filter(|e| e.address == address).count();
        let full = if mine >= self.limits.per_address {
            Some(Some(address))
        } else {
            (open.len() >= self.limits.total).then_some(None)
        };
        if let Some(among) = full {
            let victim = open.iter().position(|e| {
                !e.trusted.load(Ordering::Relaxed) && among.is_none_or(|a| e.address == a)
            })?;
            open.remove(victim).close.notify_one();
        }
        let id = self.next.fetch_add(1, Ordering::Relaxed);
        let (trusted, close) = (Arc::new(AtomicBool::new(trusted)), Arc::new(Notify::new()));
        open.push(Entry {
            id,
            address,
            trusted: trusted.clone(),
            close: close.clone(),
        });
        Some(Slot {
            admission: self.clone(),
            id,
            trusted,
            close,
        })
    }

    /// How many open connections are trusted.
    pub fn trusted(&self) -> usize {
        self.open.lock().map_or(0, |open| {
            open.iter()
                .filter(|e| e.trusted.load(Ordering::Relaxed))
                .count()
        })
    }
}

/// The bytes a new connection has sent so far, without taking them (at most `buf`'s
/// length; none when nothing has come yet): a browser's request usually arrives with the
/// connection, so a door can see it is trusted before making room for it.
pub fn peek<'a>(stream: &impl std::os::fd::AsRawFd, buf: &'a mut [u8]) -> &'a [u8] {
    use nix::sys::socket::{recv, MsgFlags};
    let flags = MsgFlags::MSG_PEEK | MsgFlags::MSG_DONTWAIT;
    let n = recv(stream.as_raw_fd(), buf, flags).unwrap_or(0);
    &buf[..n]
}

/// Deepens a listening socket's queue of connections not yet accepted to `backlog` (a
/// second `listen` on a listening socket only changes its backlog).
pub fn deepen(listener: &std::net::TcpListener, backlog: i32) {
    let deeper =
        nix::sys::socket::Backlog::new(backlog).and_then(|b| nix::sys::socket::listen(listener, b));
    if let Err(e) = deeper {
        tracing::debug!("cannot deepen the listening queue: {e}");
    }
}

impl Slot {
    /// The flag a request sets when it shows the connection is trusted.
    pub fn trust_flag(&self) -> Arc<AtomicBool> {
        self.trusted.clone()
    }

    pub fn is_trusted(&self) -> bool {
        self.trusted.load(Ordering::Relaxed)
    }

    /// Resolves when the place was given to a newcomer.
    pub async fn evicted(&self) {
        self.close.notified().await
    }
}

impl Drop for Slot {
    fn drop(&mut self) {
        if let Ok(mut open) = self.admission.open.lock() {
            open.retain(|e| e.id != self.id);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn newcomers_displace_the_oldest_anonymous_never_the_trusted() {
        let door = Admission::new(Limits {
            total: 3,
            per_address: 2,
        });
        let (a, b) = ("10.0.0.1".parse().unwrap(), "10.0.0.2".parse().unwrap());
        let first = door.open(a, true).unwrap();
        let second = door.open(a, false).unwrap();
        // `a` is over its share: its anonymous one goes, its trusted one stays.
        let third = door.open(a, false).unwrap();
        assert_eq!(door.open.lock().unwrap().len(), 2);
        let _b1 = door.open(b, false).unwrap();
        // Full: the oldest anonymous (`third`) makes room.
        let _b2 = door.open(b, false).unwrap();
        let ids: Vec<u64> = door.open.lock().unwrap().iter().map(|e| e.id).collect();
        assert!(ids.contains(&first.id) && !ids.contains(&second.id));
        assert!(!ids.contains(&third.id));
        third.trust_flag().store(true, Ordering::Relaxed);
        assert_eq!(door.trusted(), 1, "a closed connection is not counted");
        drop(first);
        assert_eq!(door.trusted(), 0);
    }

    #[test]
    fn a_door_full_of_trusted_connections_refuses() {
        let door = Admission::new(Limits {
            total: 1,
            per_address: 1,
        });
        let a = "10.0.0.1".parse().unwrap();
        let only = door.open(a, false).unwrap();
        only.trust_flag().store(true, Ordering::Relaxed);
        assert!(door.open(a, false).is_none());
    }
}
