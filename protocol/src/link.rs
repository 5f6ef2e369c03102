//! Sessions, the handshake and replay protection, on top of [`frame`](crate::frame).
//!
//! Every node picks a fresh 32-bit *session* at boot (robots: a boot counter kept in
//! flash; the base station: a random number). Every frame's tag covers the sender's
//! session, so frames from an earlier boot never verify again. A receiver learns a peer's
//! session only from a `Welcome` that answers its own `Hello` nonce, and the `Welcome` also
//! fixes the floor of the peer's sequence numbers. After that each stream (the peer's
//! broadcasts, the peer's unicasts to us) must strictly increase: duplicates, replays and
//! late (reordered) frames are refused. A control link wants the newest state only.
//!
//! A `Hello` is answered only when its nonce is newer than the last one seen from that
//! peer (nonces grow: robots put their boot count in the high half, the base station its
//! start time), so a recorded `Hello` replayed never gets an answer nor delays the genuine
//! one. The handshake also measures the round trip and the peer's clock offset; a node
//! that judges freshness by the sender's clock re-measures them every
//! [`Timing::resync_every_ms`], and a round trip over [`Timing::max_rtt_ms`] is refused.
//!
//! - A robot that reboots knows no session: it accepts nothing until the base station
//!   answers its fresh nonce, and the answer's sequence floor shuts out recorded frames.
//! - A restarted base station has a new session: robots reject its frames (`bad_tag`),
//!   notice the silence after [`Timing::relink_after_ms`] (or its `Hello`), challenge
//!   it, and accept it again. Nothing an attacker recorded earlier verifies.
//!
//! See `docs/protocol.md` for the threat model.

use heapless::{Deque, Vec};

/// Challenges kept per peer: answers to any of them are accepted.
const OUTSTANDING: usize = 4;
/// A challenge older than this is not accepted any more, ms.
const CHALLENGE_LIFETIME_MS: u32 = 3000;
/// Unanswered challenges double the wait for the next this many times at most: 16×,
/// 4.8 s by default, under a fifth of the slowest shared channel's slots.
const MAX_BACKOFF: u8 = 4;

use crate::auth::FleetKey;
use crate::frame::{self, Address, EncodeError, Expect, Header, WireHeader};
use crate::messages::{Destination, Hello, Message, Welcome};
use crate::{Reject, RejectCounts, PROTOCOL_VERSION};

/// When to (re)challenge a peer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Timing {
    /// A peer silent (no accepted frame) this long is challenged again.
    pub relink_after_ms: u32,
    /// At most one `Hello` per peer per this period.
    pub challenge_every_ms: u32,
    /// Challenge a linked peer again this often, to re-measure its clock offset (crystals
    /// drift ~0.2 s an hour); `None`: only when it falls silent.
    pub resync_every_ms: Option<u32>,
    /// A `Welcome` whose round trip took longer is refused: its clock offset could be off
    /// by half of it (a relay that delays frames stretches the round trip).
    pub max_rtt_ms: u32,
}

impl Default for Timing {
    fn default() -> Self {
        Self {
            relink_after_ms: 1000,
            challenge_every_ms: 300,
            resync_every_ms: None,
            max_rtt_ms: 1000,
        }
    }
}

#[derive(Debug, Clone, Copy, Default)]
struct Stream {
    last: Option<u32>,
}

impl Stream {
    /// Accepts a strictly newer sequence number; returns how many were skipped.
    fn advance(&mut self, seq: u32) -> Result<u32, Reject> {
        match self.last {
            Some(last) if seq <= last => Err(Reject::Replay),
            Some(last) => {
                self.last = Some(seq);
                Ok(seq - last - 1)
            }
            None => Err(Reject::UnknownSession),
        }
    }
}

/// A peer's clock as its accepted frames show it, to complete their headers' low bits:
/// the largest `peer clock − our clock` seen (the least delayed frame), decaying 1 ms per
/// 1.024 s so that a peer's crystal running slower than ours is followed (a thousand
/// times any crystal's drift). Only verified frames move it.
#[derive(Debug, Clone, Copy, Default)]
struct PeerClock {
    /// Peer clock minus our clock (wrapping), and our clock then.
    ahead: Option<(u32, u32)>,
}

impl PeerClock {
    /// The peer's clock now, if any frame of its session was heard.
    fn now(&self, now_ms: u32) -> Option<u32> {
        self.ahead.map(|(ahead, at)| {
            now_ms
                .wrapping_add(ahead)
                .wrapping_sub(now_ms.wrapping_sub(at) >> 10)
        })
    }

    /// A verified frame stamped `time_ms` arrived at `now_ms`; `same`: of the session
    /// already known (a new session's clock starts afresh).
    fn heard(&mut self, time_ms: u32, now_ms: u32, same: bool) {
        let ahead = time_ms.wrapping_sub(now_ms);
        let keep = same
            && self
                .now(now_ms)
                .is_some_and(|t| (t.wrapping_sub(now_ms).wrapping_sub(ahead) as i32) > 0);
        if !keep {
            self.ahead = Some((ahead, now_ms));
        }
    }
}

/// What this link knows about one peer.
#[derive(Debug, Clone)]
pub struct Peer {
    pub address: Address,
    /// The key of unicast frames and the handshake with this peer (the robot's key).
    key: FleetKey,
    session: Option<u32>,
    tx_seq: u32,
    rx_unicast: Stream,
    rx_broadcast: Stream,
    /// Outstanding challenges (nonce, sent at), newest last: a slow link may answer an
    /// earlier one after a newer one went out.
    challenges: Deque<(u64, u32), OUTSTANDING>,
    last_hello_ms: Option<u32>,
    /// Challenges sent since the last answer: each doubles the wait for the next.
    unanswered: u8,
    /// The newest `Hello` nonce seen from the peer: older or equal ones are replays.
    newest_hello: Option<u64>,
    /// Our clock when the last frame from this peer was accepted.
    pub last_rx_ms: Option<u32>,
    /// Peer clock minus our clock, from the handshake's round trip.
    pub clock_offset_ms: Option<i32>,
    /// The round trip of the handshake the offset came from, ms: the offset is good to
    /// half of it.
    pub rtt_ms: Option<u32>,
    /// Our clock when the offset was measured.
    synced_ms: u32,
    /// The peer's clock as its frames show it: see [`PeerClock`].
    clock: PeerClock,
    pub accepted: u32,
    pub lost: u32,
    /// Rejected frames whose (unverified) header named this peer as sender.
    pub rejects: RejectCounts,
}

impl Peer {
    /// Its `Welcome` (`header`, `welcome`) to us (`me`): a challenge of ours answered in
    /// time links it (or syncs its clock again within the same session).
    fn welcome(
        &mut self,
        header: &Header,
        welcome: &Welcome,
        me: Address,
        timing: Timing,
        now_ms: u32,
    ) -> Result<Event, Reject> {
        let answered = self.challenges.iter().find(|(n, sent)| {
            *n == welcome.nonce && now_ms.wrapping_sub(*sent) <= CHALLENGE_LIFETIME_MS
        });
        let Some(&(_, sent_ms)) = answered else {
            return Err(Reject::Replay);
        };
        if header.to != me {
            return Err(Reject::Replay);
        }
        let rtt = now_ms.wrapping_sub(sent_ms);
        if rtt > timing.max_rtt_ms {
            return Err(Reject::Stale);
        }
        self.challenges.clear();
        self.unanswered = 0;
        // Within the same session a floor never goes back: a Welcome held back and
        // delivered late must not reopen the frames accepted since it was sent.
        let same = self.session == Some(welcome.session);
        let floor = |old: Option<u32>, new: u32| match old {
            Some(old) if same => old.max(new),
            _ => new,
        };
        self.session = Some(welcome.session);
        self.clock.heard(header.time_ms, now_ms, same);
        self.rx_unicast.last = Some(floor(self.rx_unicast.last, header.seq));
        self.rx_broadcast.last = Some(floor(self.rx_broadcast.last, welcome.broadcast_seq));
        self.last_rx_ms = Some(now_ms);
        // NTP's estimate: the answer left halfway through the round trip. Within a
        // session, a longer round trip than the estimate's is less exact: it replaces the
        // estimate only as that ages (1 ms of round trip per 1.024 s, far above any
        // crystal's drift), as NTP's clock filter prefers the shortest round trips.
        let age = now_ms.wrapping_sub(self.synced_ms) >> 10;
        if !same || rtt <= self.rtt_ms.unwrap_or(0).saturating_add(age) {
            let mid = sent_ms.wrapping_add(rtt / 2);
            self.clock_offset_ms = Some(header.time_ms.wrapping_sub(mid) as i32);
            self.rtt_ms = Some(rtt);
            self.synced_ms = now_ms;
        }
        self.accepted = self.accepted.saturating_add(1);
        Ok(if same {
            Event::Synced { peer: header.from }
        } else {
            Event::Linked { peer: header.from }
        })
    }

    fn new(address: Address, key: FleetKey) -> Self {
        Self {
            address,
            key,
            session: None,
            tx_seq: 0,
            rx_unicast: Stream::default(),
            rx_broadcast: Stream::default(),
            challenges: Deque::new(),
            last_hello_ms: None,
            unanswered: 0,
            newest_hello: None,
            last_rx_ms: None,
            clock_offset_ms: None,
            rtt_ms: None,
            synced_ms: 0,
            clock: PeerClock::default(),
            accepted: 0,
            lost: 0,
            rejects: RejectCounts::default(),
        }
    }

    /// What we expect of the peer's next frame on `wire`'s stream.
    fn expect(&self, wire: &WireHeader, now_ms: u32) -> Result<Expect, Reject> {
        let stream = if wire.to == Address::Broadcast {
            &self.rx_broadcast
        } else {
            &self.rx_unicast
        };
        match (self.session, stream.last, self.clock.now(now_ms)) {
            (Some(session), Some(last), Some(time_ms)) => Ok(Expect {
                session,
                seq: last.wrapping_add(1),
                time_ms,
            }),
            _ => Err(Reject::UnknownSession),
        }
    }

    /// Our challenges to it since its last answer.
    pub fn unanswered(&self) -> u8 {
        self.unanswered
    }

    /// True once a handshake has given us the peer's session.
    pub fn is_linked(&self) -> bool {
        self.session.is_some()
    }

    fn silent_for(&self, now_ms: u32, ms: u32) -> bool {
        self.last_rx_ms.is_none_or(|t| now_ms.wrapping_sub(t) >= ms)
    }
}

/// What an accepted frame means for the caller.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Event {
    /// An authenticated, fresh application message.
    Message { header: Header, message: Message },
    /// A peer asks for our session: answer with [`Link::answer`].
    Challenged { from: Address, nonce: u64 },
    /// A peer answered our challenge with a new session: its frames are accepted from
    /// now on.
    Linked { peer: Address },
    /// A linked peer answered a re-synchronising challenge (same session): its clock
    /// offset and round trip are measured again.
    Synced { peer: Address },
    /// A frame for another node.
    Ignored,
}

/// Link-wide counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LinkStats {
    pub accepted: u32,
    pub lost: u32,
    pub ignored: u32,
    pub rejects: RejectCounts,
}

/// One node's end of the radio link, with up to `PEERS` peers. No heap, time passed in.
pub struct Link<const PEERS: usize> {
    me: Address,
    /// The key of broadcast frames (sent or received).
    broadcast_key: FleetKey,
    session: u32,
    next_nonce: u64,
    broadcast_seq: u32,
    timing: Timing,
    peers: Vec<Peer, PEERS>,
    stats: LinkStats,
}

impl<const PEERS: usize> Link<PEERS> {
    /// `broadcast_key`: for frames to [`Address::Broadcast`]. `session` must differ at
    /// every boot; `nonce_base` must never repeat a nonce this node used before, and
    /// should exceed those it used before (robots: the boot count in the high half; the
    /// base station: its start time).
    pub fn new(
        me: Address,
        broadcast_key: FleetKey,
        session: u32,
        nonce_base: u64,
        timing: Timing,
    ) -> Self {
        Self {
            me,
            broadcast_key,
            session,
            next_nonce: nonce_base,
            broadcast_seq: 0,
            timing,
            peers: Vec::new(),
            stats: LinkStats::default(),
        }
    }

    pub fn address(&self) -> Address {
        self.me
    }

    pub fn session(&self) -> u32 {
        self.session
    }

    /// The number of our last broadcast (public: every `Welcome` carries it).
    pub fn broadcast_seq(&self) -> u32 {
        self.broadcast_seq
    }

    /// Adds a peer with the key of its unicast frames and handshake; returns false when
    /// the table is full. Idempotent.
    pub fn add_peer(&mut self, address: Address, key: FleetKey) -> bool {
        match self.peers.binary_search_by(|p| p.address.cmp(&address)) {
            Ok(_) => true,
            Err(at) => self.peers.insert(at, Peer::new(address, key)).is_ok(),
        }
    }

    pub fn peer(&self, address: Address) -> Option<&Peer> {
        self.index(address).map(|i| &self.peers[i])
    }

    pub fn peers(&self) -> &[Peer] {
        &self.peers
    }

    pub fn stats(&self) -> &LinkStats {
        &self.stats
    }

    /// Counts a frame the byte decoder already dropped (bad COBS, too long).
    pub fn count_reject(&mut self, reason: Reject) {
        self.stats.rejects.count(reason);
    }

    fn index(&self, address: Address) -> Option<usize> {
        self.peers
            .binary_search_by(|p| p.address.cmp(&address))
            .ok()
    }

    /// Seals `message` for `to` (a peer, or [`Address::Broadcast`]) into `out`.
    pub fn send(
        &mut self,
        to: Address,
        now_ms: u32,
        message: &Message,
        out: &mut [u8],
    ) -> Result<usize, EncodeError> {
        let (seq, key) = if to == Address::Broadcast {
            self.broadcast_seq = self.broadcast_seq.wrapping_add(1);
            (self.broadcast_seq, &self.broadcast_key)
        } else {
            let i = self.index(to).ok_or(EncodeError::UnknownPeer)?;
            let peer = &mut self.peers[i];
            peer.tx_seq = peer.tx_seq.wrapping_add(1);
            (peer.tx_seq, &peer.key)
        };
        let header = Header {
            version: PROTOCOL_VERSION,
            id: message.id(),
            from: self.me,
            to,
            seq,
            time_ms: now_ms,
        };
        frame::seal(key, self.session, &header, message, out)
    }

    /// Sends a fresh challenge to `to`.
    pub fn challenge(
        &mut self,
        to: Address,
        now_ms: u32,
        out: &mut [u8],
    ) -> Result<usize, EncodeError> {
        let i = self.index(to).ok_or(EncodeError::UnknownPeer)?;
        let nonce = self.next_nonce;
        self.next_nonce = self.next_nonce.wrapping_add(1);
        let pending = &mut self.peers[i].challenges;
        if pending.is_full() {
            pending.pop_front();
        }
        let _ = pending.push_back((nonce, now_ms));
        self.peers[i].last_hello_ms = Some(now_ms);
        self.peers[i].unanswered = self.peers[i].unanswered.saturating_add(1);
        self.send(to, now_ms, &Message::Hello(Hello { nonce }), out)
    }

    /// The next peer that should be challenged now (unlinked, silent too long, or due a
    /// re-synchronisation, and not challenged within [`Timing::challenge_every_ms`], twice
    /// that for each further challenge of the last 3 s still unanswered), if any.
    pub fn due_challenge(&self, now_ms: u32) -> Option<Address> {
        let t = self.timing;
        let since_hello = |p: &Peer| p.last_hello_ms.map(|h| now_ms.wrapping_sub(h));
        self.peers
            .iter()
            .find(|p| {
                let stale = !p.is_linked() || p.silent_for(now_ms, t.relink_after_ms);
                let resync = t
                    .resync_every_ms
                    .is_some_and(|r| since_hello(p).is_none_or(|s| s >= r));
                // Each challenge unanswered since the last answer doubles the wait for
                // the next (up to 16×): on a slow shared channel new ones would queue up
                // behind the old in the modem, and a late answer to an old one is refused.
                let wait = t.challenge_every_ms << p.unanswered.saturating_sub(1).min(MAX_BACKOFF);
                let quiet = since_hello(p).is_none_or(|s| s >= wait);
                (stale || resync) && quiet
            })
            .map(|p| p.address)
    }

    /// Answers a peer's challenge with our session.
    pub fn answer(
        &mut self,
        to: Address,
        nonce: u64,
        now_ms: u32,
        out: &mut [u8],
    ) -> Result<usize, EncodeError> {
        let welcome = Welcome {
            nonce,
            session: self.session,
            broadcast_seq: self.broadcast_seq,
        };
        self.send(to, now_ms, &Message::Welcome(welcome), out)
    }

    /// Authenticates one frame from the byte decoder and updates the link state.
    pub fn receive(&mut self, frame: Result<&[u8], Reject>, now_ms: u32) -> Result<Event, Reject> {
        let result = frame.and_then(|raw| self.accept(raw, now_ms));
        match &result {
            Ok(Event::Ignored) => self.stats.ignored = self.stats.ignored.saturating_add(1),
            Ok(_) => self.stats.accepted = self.stats.accepted.saturating_add(1),
            Err(reason) => self.stats.rejects.count(*reason),
        }
        result
    }

    fn accept(&mut self, raw: &[u8], now_ms: u32) -> Result<Event, Reject> {
        let header = frame::peek_header(raw)?;
        if header.to != self.me && header.to != Address::Broadcast {
            return Ok(Event::Ignored);
        }
        let i = self.index(header.from).ok_or(Reject::UnknownSession)?;
        let result = self.accept_from(i, raw, header.to, now_ms);
        if let Err(reason) = result {
            self.peers[i].rejects.count(reason);
        }
        result
    }

    /// `to`: the frame's destination, from its (not yet verified) header: it picks the key.
    fn accept_from(
        &mut self,
        i: usize,
        raw: &[u8],
        to: Address,
        now_ms: u32,
    ) -> Result<Event, Reject> {
        let peer = &self.peers[i];
        let key = match to {
            Address::Broadcast => &self.broadcast_key,
            _ => &peer.key,
        };
        let (header, message) = frame::open(key, raw, |wire| peer.expect(wire, now_ms))?;
        if to == Address::Broadcast && Message::destination(header.id) == Some(Destination::Unicast)
        {
            return Err(Reject::WrongDestination);
        }
        let timing = self.timing;
        let peer = &mut self.peers[i];
        match message {
            Message::Hello(hello) => {
                // Unbound to a session: only a nonce newer than any seen is fresh.
                if peer.newest_hello.is_some_and(|n| hello.nonce <= n) {
                    return Err(Reject::Replay);
                }
                peer.newest_hello = Some(hello.nonce);
                // A peer that lost our session may have restarted: make sure we have its
                // current one too.
                if peer.silent_for(now_ms, timing.challenge_every_ms) {
                    peer.last_rx_ms = None;
                }
                Ok(Event::Challenged {
                    from: header.from,
                    nonce: hello.nonce,
                })
            }
            Message::Welcome(welcome) => peer.welcome(&header, &welcome, self.me, timing, now_ms),
            _ => {
                let stream = if header.to == Address::Broadcast {
                    &mut peer.rx_broadcast
                } else {
                    &mut peer.rx_unicast
                };
                let skipped = stream.advance(header.seq)?;
                peer.clock.heard(header.time_ms, now_ms, true);
                peer.lost = peer.lost.saturating_add(skipped);
                peer.accepted = peer.accepted.saturating_add(1);
                peer.last_rx_ms = Some(now_ms);
                self.stats.lost = self.stats.lost.saturating_add(skipped);
                Ok(Event::Message { header, message })
            }
        }
    }
}
