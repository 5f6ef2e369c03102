//! Who may use the console, as Jupyter's server and ground-control stations decide it:
//!
//! - **Host** (DNS rebinding): a request must name the console by one of the addresses it
//!   is really served on (or `localhost`, or this machine's name), with its port. A page
//!   of `evil.example` that rebinds its name to 127.0.0.1 sends `Host: evil.example` and
//!   is refused before anything else is read.
//! - **Pairing**: the console prints a pairing code (and a URL carrying it in its fragment,
//!   which browsers never send to a server). A page that shows it gets a session cookie
//!   (`HttpOnly; SameSite=Strict`): every API request must carry that cookie or, for a
//!   script, the code itself in `X-Console-Token`. Wrong codes are rate-limited per
//!   address. This holds on the loopback too: another user's process or page on this
//!   machine cannot drive the robots.
//! - **Origin**: a state-changing request from a browser must come from the console's own
//!   origin, and be JSON (`Content-Type: application/json`), which a cross-site form
//!   cannot send without a preflight the console never grants.

use std::collections::{HashMap, VecDeque};
use std::net::{IpAddr, SocketAddr};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use hyper::header::{HeaderMap, CONTENT_TYPE, COOKIE, HOST, ORIGIN};

/// The cookie that carries a paired browser's session.
pub const COOKIE_NAME: &str = "sweeper_console";
/// Sessions kept; the oldest is forgotten past this (its browser pairs again).
const SESSIONS: usize = 64;
/// Wrong pairing codes an address may try per window.
const TRIES: u32 = 5;
const TRY_WINDOW: Duration = Duration::from_secs(60);
/// The alphabet of pairing codes: no 0/o, 1/l/i to misread on a tablet.
const ALPHABET: &[u8] = b"23456789abcdefghjkmnpqrstuvwxyz";

/// Random bytes from the OS.
fn random<const N: usize>() -> anyhow::Result<[u8; N]> {
    let mut bytes = [0u8; N];
    getrandom::fill(&mut bytes).map_err(|e| anyhow::anyhow!("no OS randomness: {e}"))?;
    Ok(bytes)
}

/// Compares in time independent of where the first difference is.
pub fn same(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |d, (x, y)| d | (x ^ y)) == 0
}

/// Why a request was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refusal {
    /// 421: not one of the console's own names (DNS rebinding).
    UnknownHost,
    /// 401: no session and no token.
    NotPaired,
    /// 403: a browser request from another origin.
    ForeignOrigin,
    /// 415: not JSON.
    NotJson,
    /// 429: too many wrong pairing codes from this address.
    TooManyTries,
}

impl Refusal {
    pub fn status(self) -> u16 {
        match self {
            Refusal::UnknownHost => 421,
            Refusal::NotPaired => 401,
            Refusal::ForeignOrigin => 403,
            Refusal::NotJson => 415,
            Refusal::TooManyTries => 429,
        }
    }

    pub fn message(self) -> &'static str {
        match self {
            Refusal::UnknownHost => "not a name of this console (open it by the address it prints)",
            Refusal::NotPaired => {
                "not paired: open the URL the console printed, or enter its pairing code"
            }
            Refusal::ForeignOrigin => "a request from another site",
            Refusal::NotJson => "commands are JSON (Content-Type: application/json)",
            Refusal::TooManyTries => "too many wrong pairing codes: wait a minute",
        }
    }
}

/// The console's names, pairing code and sessions.
pub struct Guard {
    /// Accepted `Host` values, lower case.
    hosts: Vec<String>,
    code: String,
    sessions: Mutex<VecDeque<String>>,
    tries: Mutex<HashMap<IpAddr, (u32, Instant)>>,
}

impl Guard {
    /// For a console bound to `bound` and reachable at `addresses` (the interfaces' when
    /// bound to every one).
    pub fn new(bound: SocketAddr, addresses: &[IpAddr]) -> anyhow::Result<Self> {
        let code: String = random::<10>()?
            .iter()
            .map(|b| ALPHABET[*b as usize % ALPHABET.len()] as char)
            .collect();
        Ok(Self {
            hosts: host_names(bound.port(), addresses),
            code,
            sessions: Mutex::new(VecDeque::new()),
            tries: Mutex::new(HashMap::new()),
        })
    }

    /// The pairing code, as printed: two groups of five.
    pub fn code(&self) -> String {
        format!("{}-{}", &self.code[..5], &self.code[5..])
    }

    /// Whether `Host` names this console.
    pub fn check_host(&self, headers: &HeaderMap) -> Result<(), Refusal> {
        let host = headers
            .get(HOST)
            .and_then(|h| h.to_str().ok())
            .map(str::to_ascii_lowercase)
            .ok_or(Refusal::UnknownHost)?;
        self.hosts
            .contains(&host)
            .then_some(())
            .ok_or(Refusal::UnknownHost)
    }

    /// Whether a browser sent this from the console's own origin (a request without an
    /// `Origin` is not a browser's cross-site request), as JSON.
    pub fn check_write(&self, headers: &HeaderMap) -> Result<(), Refusal> {
        if let Some(origin) = headers.get(ORIGIN) {
            let host = headers.get(HOST).and_then(|h| h.to_str().ok());
            let own = host.map(|h| format!("http://{}", h.to_ascii_lowercase()));
            let origin = origin.to_str().map(str::to_ascii_lowercase).ok();
            if origin.is_none() || origin != own {
                return Err(Refusal::ForeignOrigin);
            }
        }
        let json = headers
            .get(CONTENT_TYPE)
            .and_then(|c| c.to_str().ok())
            .is_some_and(|c| {
                c.split(';')
                    .next()
                    .is_some_and(|t| t.trim().eq_ignore_ascii_case("application/json"))
            });
        json.then_some(()).ok_or(Refusal::NotJson)
    }

    /// Whether the request carries a session cookie or the pairing code.
    pub fn check_paired(&self, headers: &HeaderMap) -> Result<(), Refusal> {
        if let Some(token) = headers.get("x-console-token") {
            let token = token.as_bytes();
            let code: Vec<u8> = token.iter().copied().filter(|b| *b != b'-').collect();
            if same(&code, self.code.as_bytes()) {
                return Ok(());
            }
            return Err(Refusal::NotPaired);
        }
        let sessions = self.sessions.lock().map_err(|_| Refusal::NotPaired)?;
        let paired = headers
            .get_all(COOKIE)
            .iter()
            .filter_map(|c| c.to_str().ok())
            .flat_map(|c| c.split(';'))
            .filter_map(|kv| kv.trim().strip_prefix(COOKIE_NAME)?.strip_prefix('='))
            .any(|v| sessions.iter().any(|s| same(s.as_bytes(), v.as_bytes())));
        paired.then_some(()).ok_or(Refusal::NotPaired)
    }

    /// A pairing attempt from `from` with `code`: a new session's cookie value.
    pub fn pair(&self, from: IpAddr, code: &str) -> Result<String, Refusal> {
        let mut tries = self.tries.lock().map_err(|_| Refusal::TooManyTries)?;
        let now = Instant::now();
        tries.retain(|_, (_, since)| now.duration_since(*since) < TRY_WINDOW);
        let entry = tries.entry(from).or_insert((0, now));
        if entry.0 >= TRIES {
            return Err(Refusal::TooManyTries);
        }
        let given: Vec<u8> = code
            .bytes()
            .filter(|b| *b != b'-' && !b.is_ascii_whitespace())
            .map(|b| b.to_ascii_lowercase())
            .collect();
        if !same(&given, self.code.as_bytes()) {
            entry.0 += 1;
            return Err(Refusal::NotPaired);
        }
        let session = hex::encode(random::<16>().map_err(|_| Refusal::NotPaired)?);
        let mut sessions = self.sessions.lock().map_err(|_| Refusal::NotPaired)?;
        if sessions.len() >= SESSIONS {
            sessions.pop_front();
        }
        sessions.push_back(session.clone());
        Ok(session)
    }
}

/// Every `Host` value that names a console on `port` at `addresses`: each address with the
/// port (bare too on port 80), `localhost` when a loopback address is among them, and this
/// machine's name (and `NAME.local`).
fn host_names(port: u16, addresses: &[IpAddr]) -> Vec<String> {
    let mut names: Vec<String> = addresses
        .iter()
        .map(|ip| match ip {
            IpAddr::V4(v4) => v4.to_string(),
            IpAddr::V6(v6) => format!("[{v6}]"),
        })
        .collect();
    if addresses.iter().any(IpAddr::is_loopback) {
        names.push("localhost".into());
    }
    if addresses.iter().any(|ip| !ip.is_loopback()) {
        if let Ok(name) = nix::unistd::gethostname() {
            if let Some(name) = name.to_str().filter(|n| !n.is_empty()) {
                names.push(name.to_ascii_lowercase());
                names.push(format!("{}.local", name.to_ascii_lowercase()));
            }
        }
    }
    let mut hosts: Vec<String> = names.iter().map(|n| format!("{n}:{port}")).collect();
    if port == 80 {
        hosts.extend(names);
    }
    hosts
}

#[cfg(test)]
mod tests {
    use super::*;
    use hyper::header::HeaderValue;

    fn headers(pairs: &[(&'static str, &str)]) -> HeaderMap {
        let mut h = HeaderMap::new();
        for (k, v) in pairs {
            h.append(*k, HeaderValue::from_str(v).unwrap());
        }
        h
    }

    fn guard() -> Guard {
        Guard::new(
            "127.0.0.1:8080".parse().unwrap(),
            &["127.0.0.1".parse().unwrap()],
        )
        .unwrap()
    }

    #[test]
    fn only_the_consoles_own_names_pass() {
        let g = guard();
        for ok in ["127.0.0.1:8080", "localhost:8080", "LOCALHOST:8080"] {
            assert_eq!(g.check_host(&headers(&[("host", ok)])), Ok(()), "{ok}");
        }
        for bad in ["evil.example:8080", "127.0.0.1:9999", "127.0.0.1"] {
            assert_eq!(
                g.check_host(&headers(&[("host", bad)])),
                Err(Refusal::UnknownHost),
                "{bad}"
            );
        }
        assert_eq!(g.check_host(&HeaderMap::new()), Err(Refusal::UnknownHost));
    }

    #[test]
    fn writes_come_from_the_own_origin_as_json() {
        let g = guard();
        let own = [
            ("host", "127.0.0.1:8080"),
            ("origin", "http://127.0.0.1:8080"),
            ("content-type", "application/json"),
        ];
        assert_eq!(g.check_write(&headers(&own)), Ok(()));
        let foreign = [
            ("host", "127.0.0.1:8080"),
            ("origin", "http://127.0.0.1:9999"),
            ("content-type", "application/json"),
        ];
        assert_eq!(
            g.check_write(&headers(&foreign)),
            Err(Refusal::ForeignOrigin)
        );
        let form = [
            ("host", "127.0.0.1:8080"),
            ("origin", "http://127.0.0.1:8080"),
            ("content-type", "text/plain"),
        ];
        assert_eq!(g.check_write(&headers(&form)), Err(Refusal::NotJson));
        let script = [
            ("host", "127.0.0.1:8080"),
            ("content-type", "application/json; charset=utf-8"),
        ];
        assert_eq!(g.check_write(&headers(&script)), Ok(()));
    }

    #[test]
    fn pairing_gives_a_session_and_wrong_codes_run_out() {
        let g = guard();
        let me: IpAddr = "10.0.0.5".parse().unwrap();
        assert_eq!(g.check_paired(&HeaderMap::new()), Err(Refusal::NotPaired));
        let session = g.pair(me, &g.code()).unwrap();
        let cookie = format!("a=b; {COOKIE_NAME}={session}");
        assert_eq!(g.check_paired(&headers(&[("cookie", &cookie)])), Ok(()));
        let forged = format!("{COOKIE_NAME}={}", "0".repeat(32));
        assert_eq!(
            g.check_paired(&headers(&[("cookie", &forged)])),
            Err(Refusal::NotPaired)
        );
        assert_eq!(
            g.check_paired(&headers(&[("x-console-token", &g.code())])),
            Ok(())
        );
        let attacker: IpAddr = "10.0.0.66".parse().unwrap();
        for _ in 0..TRIES {
            assert_eq!(g.pair(attacker, "aaaaa-aaaaa"), Err(Refusal::NotPaired));
        }
        assert_eq!(g.pair(attacker, &g.code()), Err(Refusal::TooManyTries));
        assert!(g.pair(me, &g.code()).is_ok(), "others still pair");
    }
}
