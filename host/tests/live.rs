//! `sim --realtime --live`: a WebSocket client speaking the Foxglove protocol (as Foxglove or
//! Lichtblick do) subscribes to a robot's pose and receives it, stamped with the simulated
//! clock.

mod common;

use std::process::Stdio;
use std::time::{Duration, Instant};

use serde_json::{json, Value};
use tungstenite::client::IntoClientRequest;
use tungstenite::Message;

use common::Killed;

#[test]
fn a_foxglove_client_receives_the_robots_poses_live() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("live-test");
    std::fs::create_dir_all(&dir).unwrap();
    let mut sim = common::basestation()
        .args([
            "sim",
            "paper-passage",
            "--realtime",
            "--live",
            "127.0.0.1:0",
            "--report",
        ])
        .arg(dir.join("report.json"))
        .arg("--plot")
        .arg(dir.join("figure.svg"))
        .arg("--mcap")
        .arg(dir.join("run.mcap"))
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let prefix = "live (Foxglove WebSocket): ";
    let line = common::stderr_line(&mut sim, prefix, "sim ended without serving");
    let url = line.strip_prefix(prefix).unwrap().to_string();
    let _sim = Killed(sim);

    let request_to = |url: &str, origin: Option<&str>| {
        let mut request = url.into_client_request().unwrap();
        let headers = request.headers_mut();
        headers.insert("Sec-WebSocket-Protocol", "foxglove.sdk.v1".parse().unwrap());
        if let Some(o) = origin {
            headers.insert("Origin", o.parse().unwrap());
        }
        request
    };
    let request = |origin: Option<&str>| request_to(&url, origin);
    // Issue 27, finding 4: a page of any other site cannot open the stream in a visitor's
    // browser (nor a name rebound to the station); Foxglove's web app can.
    match tungstenite::connect(request(Some("http://evil.example"))) {
        Err(tungstenite::Error::Http(response)) => assert_eq!(response.status(), 403),
        other => panic!("another origin opened the stream: {:?}", other.map(|_| ())),
    }
    assert!(tungstenite::connect(request(Some("https://app.foxglove.dev"))).is_ok());
    // Issue 52, finding 4: the stream is served by the station itself, on this address
    // only, and wants the run's token: a local process without it reads nothing.
    let (base, token) = url.split_once("?token=").expect("the URL carries a token");
    // A token one digit off (the first digit changed, whatever it was) is refused too.
    let flipped = if token.starts_with('0') { '1' } else { '0' };
    for wrong in [
        base.to_string(),
        format!("{base}?token={flipped}{}", &token[1..]),
    ] {
        match tungstenite::connect(request_to(&wrong, None)) {
            Err(tungstenite::Error::Http(response)) => assert_eq!(response.status(), 401),
            other => panic!("{wrong} opened the stream: {:?}", other.map(|_| ())),
        }
    }
    // Idle connections that never pass the door give way; the operator's viewer gets in.
    let addr = base
        .trim_start_matches("ws://")
        .trim_end_matches('/')
        .to_string();
    let idle: Vec<std::net::TcpStream> = (0..200)
        .filter_map(|_| std::net::TcpStream::connect(&addr).ok())
        .collect();
    assert!(idle.len() > 150, "{} idle connections", idle.len());
    let viewers: Vec<_> = (0..32)
        .map(|i| {
            tungstenite::connect(request(None))
                .unwrap_or_else(|e| panic!("viewer {i} beside 200 idle connections: {e}"))
        })
        .collect();
    // The viewers' places are not taken from them: the 33rd token holder waits.
    match tungstenite::connect(request(None)) {
        Err(tungstenite::Error::Http(response)) => assert_eq!(response.status(), 503),
        other => panic!("a 33rd viewer: {:?}", other.map(|_| ())),
    }
    drop((idle, viewers));
    std::thread::sleep(Duration::from_millis(200));
    let (mut socket, _) = tungstenite::connect(request(None)).unwrap();
    let start = Instant::now();
    let mut pose_channel = None;
    let mut stamps = Vec::new();
    while stamps.len() < 20 {
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "{} poses in 20 s (channel {pose_channel:?})",
            stamps.len()
        );
        match socket.read().unwrap() {
            Message::Text(text) => {
                let msg: Value = serde_json::from_str(&text).unwrap();
                if msg["op"] != "advertise" {
                    continue;
                }
                let Some(ch) = msg["channels"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .find(|c| c["topic"] == "/robot_0/pose")
                else {
                    continue;
                };
                assert_eq!(ch["schemaName"], "foxglove.PoseInFrame", "{ch}");
                pose_channel = ch["id"].as_u64();
                let subscribe = json!({
                    "op": "subscribe",
                    "subscriptions": [{ "id": 7, "channelId": pose_channel }],
                });
                socket.send(Message::text(subscribe.to_string())).unwrap();
            }
            // Message data: opcode 1, subscription id (u32 LE), timestamp (u64 LE, ns), payload.
            Message::Binary(data) if data.first() == Some(&1) && data.len() > 13 => {
                let sub = u32::from_le_bytes(data[1..5].try_into().unwrap());
                let t = u64::from_le_bytes(data[5..13].try_into().unwrap());
                assert_eq!(sub, 7);
                stamps.push(t);
            }
            _ => {}
        }
    }
    // On the simulated clock: from the run's start, increasing, about 10 Hz.
    assert!(stamps.windows(2).all(|w| w[1] >= w[0]), "{stamps:?}");
    let span_s = (stamps[stamps.len() - 1] - stamps[0]) as f64 / 1e9;
    assert!((1.0..4.0).contains(&span_s), "20 poses over {span_s} s");
    assert!(
        stamps[0] < 60_000_000_000,
        "not the simulated clock: {}",
        stamps[0]
    );
}
