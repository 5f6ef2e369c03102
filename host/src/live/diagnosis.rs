//! What is wrong with a live run's link, said in words at the default log level: robots
//! not heard after [`QUIET_AFTER_MS`] (by id, once, and again when they are heard), and
//! frames rejected since the last look with the likely cause per reason (a key that
//! differs, a garbled line, another protocol version…), at most every
//! [`REPEAT_EVERY_MS`] per reason.

use std::collections::{BTreeMap, BTreeSet};

use base_station::station::BaseStation;
use protocol::{Address, Reject, RejectCounts};

/// A robot not heard this long after the start is named, ms.
pub const QUIET_AFTER_MS: u32 = 5000;
/// A reason already said is said again after this long if it goes on, ms.
pub const REPEAT_EVERY_MS: u32 = 5000;

/// What the run has said so far.
#[derive(Debug, Default)]
pub struct Diagnosis {
    /// The robots named as not heard (and not heard since).
    quiet: BTreeSet<u16>,
    /// The rejects at the last look.
    seen: RejectCounts,
    /// When each reason was last said, ms.
    said: BTreeMap<Reject, u32>,
}

/// Warns of the frames rejected (`now`, counted since the start) since the last look, per
/// reason with its likely cause, at most every [`REPEAT_EVERY_MS`] per reason.
fn say_rejects(
    seen: &mut RejectCounts,
    said: &mut BTreeMap<Reject, u32>,
    now: RejectCounts,
    now_ms: u32,
    what: &str,
) {
    for reason in Reject::ALL {
        // Robots talk before their handshake: a session unknown in the first seconds is
        // the normal start, not a fault.
        if reason == Reject::UnknownSession && now_ms < QUIET_AFTER_MS {
            seen.0[reason as usize] = now.get(reason);
            continue;
        }
        let new = now.get(reason).saturating_sub(seen.get(reason));
        let due = said
            .get(&reason)
            .is_none_or(|t| now_ms.saturating_sub(*t) >= REPEAT_EVERY_MS);
        if new > 0 && due {
            tracing::warn!(
                reason = reason.name(),
                frames = new,
                "{new} {what} ({}): {}",
                reason.name(),
                cause(reason)
            );
            said.insert(reason, now_ms);
            seen.0[reason as usize] = now.get(reason);
        }
    }
}

/// What `robots` (the simulated robots behind a real transport) says of its link: no
/// station heard after [`QUIET_AFTER_MS`] (once), and the frames its robots reject, with
/// the likely cause.
#[derive(Debug, Default)]
pub struct RobotsDiagnosis {
    heard_bytes: usize,
    said_silent: bool,
    seen: RejectCounts,
    said: BTreeMap<Reject, u32>,
}

impl RobotsDiagnosis {
    /// Bytes from the air (the station's, if it is there).
    pub fn heard(&mut self, bytes: usize) {
        self.heard_bytes += bytes;
    }

    /// At `now_ms` of the run, the robots' rejects so far; `at`: where they listen.
    pub fn look(&mut self, rejects: RejectCounts, now_ms: u32, at: &str) {
        if now_ms >= QUIET_AFTER_MS && self.heard_bytes == 0 && !self.said_silent {
            self.said_silent = true;
            tracing::warn!(
                "no station heard for {} s: point `basestation run --udp` (or `--port`) at {at}, \
                 with the same fleet key",
                now_ms / 1000
            );
        }
        say_rejects(
            &mut self.seen,
            &mut self.said,
            rejects,
            now_ms,
            "frames rejected by the robots",
        );
    }
}

/// The likely cause of frames rejected for `reason`, and what to check.
pub fn cause(reason: Reject) -> &'static str {
    match reason {
        Reject::BadTag => {
            "frames fail authentication: do the station and the robots share the fleet key \
             (--key-file / SWEEPER_FLEET_KEY, and each robot's page from `robot-config`)?"
        }
        Reject::BadCobs | Reject::TooLong | Reject::Truncated => {
            "bytes garbled on the link: check the serial rate (--baud), the cable or the radio"
        }
        Reject::UnknownVersion | Reject::UnknownMessage | Reject::Malformed => {
            "the robots speak another protocol: flash the firmware that goes with this station"
        }
        Reject::UnknownSession => {
            "robots talk in a session this station does not know: no handshake got through \
             yet (see the other rejects), or the station restarted (they link again on \
             their own within seconds)"
        }
        Reject::Replay => "frames repeated: an echo on the link, or someone replaying them",
        Reject::Stale => "frames arrive too late by their sender's clock: a slow or delaying link",
        Reject::WrongDestination => {
            "commands broadcast that only a unicast may carry: a robot is forging them \
             (a captured robot?)"
        }
    }
}

impl Diagnosis {
    /// Looks at the station's link at `now_ms` (the station's clock, from the run's
    /// start); `robots`: the scenario's robot ids.
    pub fn look(&mut self, station: &BaseStation, robots: &[u16], now_ms: u32) {
        self.quiet_robots(station, robots, now_ms);
        self.rejects(station, now_ms);
    }

    fn quiet_robots(&mut self, station: &BaseStation, robots: &[u16], now_ms: u32) {
        if now_ms < QUIET_AFTER_MS {
            return;
        }
        for id in robots {
            let heard = station
                .link()
                .peers()
                .iter()
                .any(|p| p.address == Address::Robot(*id) && p.last_rx_ms.is_some());
            match (heard, self.quiet.contains(id)) {
                (false, false) => {
                    tracing::warn!(
                        robot = id,
                        "robot {id} not heard for {} s: is it on, on this radio / address, \
                         and configured as robot {id}?",
                        now_ms / 1000
                    );
                    self.quiet.insert(*id);
                }
                (true, true) => {
                    tracing::warn!(robot = id, "robot {id} heard at last");
                    self.quiet.remove(id);
                }
                _ => {}
            }
        }
    }

    fn rejects(&mut self, station: &BaseStation, now_ms: u32) {
        let now = station.link().stats().rejects;
        say_rejects(
            &mut self.seen,
            &mut self.said,
            now,
            now_ms,
            "frames rejected",
        );
    }
}
