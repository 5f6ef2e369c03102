//! Headless Chromium over the DevTools protocol, for the pages' tests (the console's,
//! `ops`'s): Debian's `chromium`, which `.ci/run` installs.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use base64::Engine;
use serde_json::{json, Value};

use super::Killed;

pub fn browser() -> Option<&'static str> {
    ["chromium", "chromium-browser", "google-chrome"]
        .into_iter()
        .find(|b| {
            Command::new(b)
                .arg("--version")
                .output()
                .is_ok_and(|o| o.status.success())
        })
}

/// A plain HTTP GET on localhost (the DevTools endpoint).
pub fn http_get(port: u16, path: &str) -> String {
    let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    // The endpoint may keep the connection open: read what comes within a moment.
    s.set_read_timeout(Some(Duration::from_millis(500)))
        .unwrap();
    let mut bytes = Vec::new();
    let _ = s.read_to_end(&mut bytes);
    let text = String::from_utf8_lossy(&bytes);
    text.split_once("\r\n\r\n")
        .map(|x| x.1.to_string())
        .unwrap_or_default()
}

/// The DevTools protocol over one page's WebSocket.
pub struct Page {
    pub socket: tungstenite::WebSocket<tungstenite::stream::MaybeTlsStream<TcpStream>>,
    pub next: u64,
}

impl Page {
    pub fn call(&mut self, method: &str, params: Value) -> Value {
        self.next += 1;
        let id = self.next;
        let msg = json!({ "id": id, "method": method, "params": params });
        self.socket.send(msg.to_string().into()).unwrap();
        loop {
            let reply: Value = match self.socket.read().unwrap() {
                tungstenite::Message::Text(t) => serde_json::from_str(&t).unwrap(),
                _ => continue,
            };
            if reply["id"] == id {
                assert!(reply.get("error").is_none(), "{method}: {reply}");
                return reply["result"].clone();
            }
        }
    }

    pub fn eval(&mut self, js: &str) -> Value {
        let r = self.call(
            "Runtime.evaluate",
            json!({ "expression": js, "returnByValue": true, "awaitPromise": true }),
        );
        r["result"]["value"].clone()
    }

    /// The element `id`'s class attribute.
    pub fn class(&mut self, id: &str) -> Value {
        self.eval(&format!("document.getElementById('{id}').className"))
    }

    /// The element `id`'s text.
    pub fn text(&mut self, id: &str) -> Value {
        self.eval(&format!("document.getElementById('{id}').textContent"))
    }

    /// A screenshot of the page to `path` (looked at by a person: the closing notes).
    pub fn screenshot(&mut self, path: &Path) {
        let shot = self.call("Page.captureScreenshot", json!({ "format": "png" }));
        let png = base64::engine::general_purpose::STANDARD
            .decode(shot["data"].as_str().unwrap())
            .unwrap();
        std::fs::write(path, &png).unwrap();
        println!("screenshot: {}", path.display());
    }

    /// A mouse click at the centre of the element `id`, as a finger or a mouse gives it.
    pub fn click(&mut self, id: &str) {
        let rect = self.eval(&format!(
            "(() => {{ const r = document.getElementById('{id}').getBoundingClientRect(); \
             return [r.x + r.width / 2, r.y + r.height / 2]; }})()"
        ));
        let (x, y) = (rect[0].as_f64().unwrap(), rect[1].as_f64().unwrap());
        for kind in ["mousePressed", "mouseReleased"] {
            self.call(
                "Input.dispatchMouseEvent",
                json!({ "type": kind, "x": x, "y": y, "button": "left", "clickCount": 1 }),
            );
        }
    }
}

/// Headless Chromium with a fresh profile in `dir`, and its first page; `None` (the test
/// skips) without a browser, unless `CONSOLE_BROWSER_REQUIRED` is set.
pub fn open_browser(dir: &Path) -> Option<(Killed, Page)> {
    let Some(chromium) = browser() else {
        assert!(
            std::env::var_os("CONSOLE_BROWSER_REQUIRED").is_none(),
            "CONSOLE_BROWSER_REQUIRED is set but no chromium was found"
        );
        eprintln!("SKIPPED: no chromium on this machine (apt-get install chromium)");
        return None;
    };
    let profile = dir.join("chromium-profile");
    let browser = Killed(
        Command::new(chromium)
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                // Containers often have a small /dev/shm.
                "--disable-dev-shm-usage",
                "--no-first-run",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
            ])
            .args(["--window-size=1300,800", "--remote-debugging-port=0"])
            .arg(format!("--user-data-dir={}", profile.display()))
            .arg("about:blank")
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let started = Instant::now();
    let port: u16 = loop {
        if let Ok(text) = std::fs::read_to_string(profile.join("DevToolsActivePort")) {
            if let Some(p) = text.lines().next().and_then(|l| l.parse().ok()) {
                break p;
            }
        }
        assert!(
            started.elapsed() < Duration::from_secs(30),
            "chromium did not start"
        );
        std::thread::sleep(Duration::from_millis(100));
    };
    let targets: Value = loop {
        if let Ok(v) = serde_json::from_str(&http_get(port, "/json/list")) {
            break v;
        }
        assert!(
            started.elapsed() < Duration::from_secs(30),
            "no DevTools targets"
        );
        std::thread::sleep(Duration::from_millis(200));
    };
    let ws = targets
        .as_array()
        .unwrap()
        .iter()
        .find(|t| t["type"] == "page")
        .and_then(|t| t["webSocketDebuggerUrl"].as_str())
        .expect("a page")
        .to_string();
    let (socket, _) = tungstenite::connect(ws).unwrap();
    let mut page = Page { socket, next: 0 };
    page.call("Page.enable", json!({}));
    Some((browser, page))
}
