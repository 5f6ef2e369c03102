//! Who may use the console, as Jupyter's server and ground-control stations decide it:
//!
//! - **Host** (DNS rebinding): a request must name the console by one of the addresses it
//!   is really served on (or `localhost`, or this machine's name), with its port. A page
//!   of `evil.example` that rebinds its name to 127.0.0.1 sends `Host: evil.example` and
//!   is refused before anything else is read.
//! - **Pairing**: the console prints a pairing code (and a URL carrying it in its fragment,
//!   which browsers never send to a server). A page that shows it gets a session cookie
//!   (`HttpOnly; SameSite=Strict`): every API request must carry that cookie or, for a
//!   script, the code itself in `X-Console-Token`. This holds on the loopback too:
//!   another user's process or page on this machine cannot drive the robots.
//! - **Wrong codes**: one budget for the console, whatever path a code comes by (the
//!   pairing form or the header) and whatever address it comes from: after [`TRIES`]
//!   wrong codes the code is replaced by a fresh one, printed on the station's terminal
//!   and logged. A guesser never gets more than [`TRIES`] tries at one code (of 2⁴⁹), and
//!   nobody is locked out: the operator's right code is never refused, and a paired page
//!   stays paired; a flood of wrong codes only makes new pages pair with the newest code.
//! - **Origin**: a state-changing request from a browser must come from the console's own
//!   origin, and be JSON (`Content-Type: application/json`), which a cross-site form
//!   cannot send without a preflight the console never grants.

use std::collections::{HashMap, VecDeque};
use std::net::{IpAddr, SocketAddr};
use std::sync::Mutex;

use hyper::header::{HeaderMap, CONTENT_TYPE, COOKIE, HOST, ORIGIN};

/// The cookie that carries a paired browser's session.
pub const COOKIE_NAME: &str = "sweeper_console";
/// Sessions kept; the oldest is forgotten past this (its browser pairs again).
const SESSIONS: usize = 64;
/// Wrong codes one pairing code takes before it is replaced: 20 tries at 2⁴⁹ codes.
pub const TRIES: u32 = 20;
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
    /// 401: a wrong code, the last one the code took: a new code is printed.
    CodeReplaced,
}

impl Refusal {
    pub fn status(self) -> u16 {
        match self {
            Refusal::UnknownHost => 421,
            Refusal::NotPaired => 401,
            Refusal::ForeignOrigin => 403,
            Refusal::NotJson => 415,
            Refusal::CodeReplaced => 401,
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
            Refusal::CodeReplaced => {
                "wrong pairing code: too many wrong codes came, so the station printed a new one"
            }
        }
    }
}

/// The console's names, pairing code and sessions.
pub struct Guard {
    /// Accepted `Host` values, lower case.
    hosts: Vec<String>,
    /// The pairing code, and the wrong codes it has taken.
    code: Mutex<(String, u32)>,
    sessions: Mutex<VecDeque<String>>,
    /// Where the last wrong codes came from, for the log when the code is replaced.
    wrong_from: Mutex<HashMap<IpAddr, u32>>,
}

/// A fresh pairing code: ten characters of [`ALPHABET`].
fn fresh_code() -> anyhow::Result<String> {
    Ok(random::<10>()?
        .iter()
        .map(|b| ALPHABET[*b as usize % ALPHABET.len()] as char)
        .collect())
}

impl Guard {
    /// For a console bound to `bound` and reachable at `addresses` (the interfaces' when
    /// bound to every one).
    pub fn new(bound: SocketAddr, addresses: &[IpAddr]) -> anyhow::Result<Self> {
        Ok(Self {
            hosts: host_names(bound.port(), addresses),
            code: Mutex::new((fresh_code()?, 0)),
            sessions: Mutex::new(VecDeque::new()),
            wrong_from: Mutex::new(HashMap::new()),
        })
    }

    /// The pairing code, as printed: two groups of five.
    pub fn code(&self) -> String {
        let code = self.code.lock().map(|c| c.0.clone()).unwrap_or_default();
        format!("{}-{}", &code[..5], &code[5..])
    }

    /// Whether `given` (dashes and blanks aside, any case) is the code; a wrong one spends
    /// the budget, and the last of it replaces the code (printed, logged).
    fn check_code(&self, from: Option<IpAddr>, given: &[u8]) -> Result<(), Refusal> {
        let given: Vec<u8> = given
            .iter()
            .filter(|b| **b != b'-' && !b.is_ascii_whitespace())
            .map(u8::to_ascii_lowercase)
            .collect();
        let mut code = self.code.lock().map_err(|_| Refusal::NotPaired)?;
        if same(&given, code.0.as_bytes()) {
            return Ok(());
        }
        code.1 += 1;
        if let (Some(ip), Ok(mut from)) = (from, self.wrong_from.lock()) {
            if from.len() < 1024 || from.contains_key(&ip) {
                *from.entry(ip).or_default() += 1;
            }
        }
        if code.1 < TRIES {
            return Err(Refusal::NotPaired);
        }
        *code = (fresh_code().map_err(|_| Refusal::NotPaired)?, 0);
        let from: Vec<String> = self
            .wrong_from
            .lock()
            .map(|mut f| f.drain().map(|(ip, n)| format!("{ip} ({n})")).collect())
            .unwrap_or_default();
        let printed = format!("{}-{}", &code.0[..5], &code.0[5..]);
        tracing::warn!(from = %from.join(", "), "{TRIES} wrong pairing codes: a new code");
        eprintln!("console: {TRIES} wrong pairing codes; the new pairing code is {printed}");
        Err(Refusal::CodeReplaced)
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
            return self.check_code(None, token.as_bytes());
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

    /// Whether the request carries a live session's cookie (a code is not looked at: only a
    /// request that is answered may spend the code's budget).
    pub fn knows(&self, headers: &HeaderMap) -> bool {
        !headers.contains_key("x-console-token") && self.check_paired(headers).is_ok()
    }

    /// A pairing attempt from `from` with `code`: a new session's cookie value.
    pub fn pair(&self, from: IpAddr, code: &str) -> Result<String, Refusal> {
        self.check_code(Some(from), code.as_bytes())?;
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
        // Wrong codes from many addresses and by the header spend one budget; its last
        // replaces the code. Nobody is locked out: the new code pairs at once, from the
        // address that sent wrong ones too, and the paired page stays paired.
        let before = g.code();
        for k in 0..TRIES - 1 {
            let from: IpAddr = format!("127.0.0.{}", k + 2).parse().unwrap();
            assert_eq!(g.pair(from, "aaaaa-aaaaa"), Err(Refusal::NotPaired));
        }
        assert!(
            g.pair(me, &before).is_ok(),
            "the right code is never refused"
        );
        let wrong = [("x-console-token", "aaaaa-aaaaa")];
        assert_eq!(g.check_paired(&headers(&wrong)), Err(Refusal::CodeReplaced));
        assert_ne!(g.code(), before, "a new code");
        assert_eq!(
            g.check_paired(&headers(&[("x-console-token", &before)])),
            Err(Refusal::NotPaired)
        );
        let attacker: IpAddr = "127.0.0.2".parse().unwrap();
        assert!(g.pair(attacker, &g.code()).is_ok(), "no lock-out");
        assert_eq!(g.check_paired(&headers(&[("cookie", &cookie)])), Ok(()));
    }
}
