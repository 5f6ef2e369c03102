//! The city's bus for the tests and the scale benchmark: the shipped sample configuration
//! in a scratch directory, `basestation router`, stations (`sim --realtime --zenoh`) and
//! `ops` as processes, and `ops`'s page API as a script uses it.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::process::Stdio;
use std::time::{Duration, Instant};

use serde_json::{json, Value};

use super::Killed;

/// The formations of the sample configuration, with their station's user.
pub const FORMATIONS: [(&str, &str, &str); 3] = [
    ("north", "a", "station-north-a"),
    ("north", "b", "station-north-b"),
    ("south", "c", "station-south-c"),
];

pub fn free_tcp_port() -> u16 {
    let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    l.local_addr().unwrap().port()
}

/// The shipped configuration in `dir`, on `port`; a station file per formation.
pub fn configure(dir: &Path, port: u16) {
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("zenoh");
    for name in ["router.json5", "station.json5", "ops.json5", "users.txt"] {
        let text = std::fs::read_to_string(shipped.join(name)).unwrap();
        let text = text
            .replace("tcp/0.0.0.0:7447", &format!("tcp/127.0.0.1:{port}"))
            .replace("tcp/127.0.0.1:7447", &format!("tcp/127.0.0.1:{port}"));
        std::fs::write(dir.join(name), text).unwrap();
    }
    let station = std::fs::read_to_string(dir.join("station.json5")).unwrap();
    for (site, name, _) in FORMATIONS {
        let own = station.replace("north-a", &format!("{site}-{name}"));
        std::fs::write(dir.join(format!("station-{site}-{name}.json5")), own).unwrap();
    }
}

pub fn router(dir: &Path) -> Killed {
    let child = super::basestation()
        .current_dir(dir)
        .args(["router", "--zenoh", "router.json5"])
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    Killed(child)
}

/// A formation's station: `sim --realtime` of the paper's obstacles for 90 s, on the bus
/// with `config`, as `site/name`.
pub fn station(dir: &Path, config: &str, site: &str, name: &str) -> Killed {
    station_for(dir, config, site, name, 90.0)
}

/// [`station`] running `duration_s` of simulated (and wall) time.
pub fn station_for(dir: &Path, config: &str, site: &str, name: &str, duration_s: f64) -> Killed {
    let out = dir.join(format!("{site}-{name}"));
    std::fs::create_dir_all(&out).unwrap();
    let scenario = out.join("scenario.toml");
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/paper-obstacles.toml");
    let text = std::fs::read_to_string(shipped).unwrap()
        + &format!("\n[sim]\nduration_s = {duration_s}\n");
    std::fs::write(&scenario, text).unwrap();
    let child = super::basestation()
        .current_dir(dir)
        .arg("sim")
        .arg(&scenario)
        .args([
            "--realtime",
            "--zenoh",
            config,
            "--site",
            site,
            "--formation",
            name,
        ])
        .arg("--report")
        .arg(out.join("report.json"))
        .arg("--plot")
        .arg(out.join("figure.svg"))
        .arg("--mcap")
        .arg(out.join("run.mcap"))
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    Killed(child)
}

/// `ops` on the bus, and its page's URL with the pairing code.
pub fn ops(dir: &Path) -> (Killed, String) {
    let mut child = super::basestation()
        .current_dir(dir)
        .args(["ops", "--zenoh", "ops.json5", "--page", "127.0.0.1:0"])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let line = super::stderr_line(&mut child, "ops: http", "ops printed no URL");
    let url = line.strip_prefix("ops: ").unwrap().to_string();
    (Killed(child), url)
}

/// `ops`'s page API, as a script uses it (the pairing code in a header).
pub struct Api {
    pub port: u16,
    pub code: String,
}

impl Api {
    pub fn of(url: &str) -> Self {
        let port = url.split(':').nth(2).unwrap().split('/').next().unwrap();
        let code = url.split("#pair=").nth(1).unwrap();
        Self {
            port: port.parse().unwrap(),
            code: code.into(),
        }
    }

    pub fn request(&self, method: &str, path: &str, body: &str) -> (u16, Value) {
        let mut s = TcpStream::connect(("127.0.0.1", self.port)).unwrap();
        let host = format!("127.0.0.1:{}", self.port);
        write!(
            s,
            "{method} {path} HTTP/1.1\r\nHost: {host}\r\nOrigin: http://{host}\r\n\
             X-Console-Token: {}\r\nContent-Type: application/json\r\n\
             Content-Length: {}\r\nConnection: close\r\n\r\n{body}",
            self.code,
            body.len()
        )
        .unwrap();
        let mut text = String::new();
        s.read_to_string(&mut text).unwrap();
        let status = text[9..12].parse().unwrap();
        let body = text.split_once("\r\n\r\n").map_or("", |x| x.1);
        (status, serde_json::from_str(body).unwrap_or(Value::Null))
    }

    pub fn state(&self) -> Value {
        self.request("GET", "/api/state", "").1
    }

    pub fn command(&self, formation: &str, command: &str) -> (u16, Value) {
        let body = json!({ "formation": formation, "command": command }).to_string();
        self.request("POST", "/api/command", &body)
    }

    /// The formation `label` as `ops` shows it now.
    pub fn formation(&self, label: &str) -> Value {
        let state = self.state();
        let all = state["formations"].as_array().cloned().unwrap_or_default();
        all.into_iter()
            .find(|f| f["label"] == label)
            .unwrap_or(Value::Null)
    }

    /// Waits up to `limit` for `ok` to hold of the state; how long it took.
    pub fn until(&self, limit: Duration, what: &str, ok: impl Fn(&Value) -> bool) -> Duration {
        let start = Instant::now();
        loop {
            let state = self.state();
            if ok(&state) {
                return start.elapsed();
            }
            assert!(
                start.elapsed() < limit,
                "{what} not within {limit:?}: {state}"
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

pub fn live_with_robots(state: &Value, label: &str) -> bool {
    state["formations"]
        .as_array()
        .into_iter()
        .flatten()
        .any(|f| {
            f["label"] == label
                && f["station"] == "live"
                && f["robots"].as_array().map_or(0, Vec::len) == 3
        })
}

/// Every robot of `f` stands (its last speed under 2 cm/s).
pub fn standing(f: &Value) -> bool {
    f["robots"].as_array().is_some_and(|r| {
        r.iter()
            .all(|r| r["state"]["v"].as_f64().is_some_and(|v| v.abs() < 0.02))
    })
}
