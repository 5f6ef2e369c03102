//! Issue 27, "the new doors": the base station's inputs from the site network under
//! attack, with `basestation run` driving `basestation robots` in real time. Each test
//! reproduces a finding of the review and fails on the code before it.

mod common;

use std::net::UdpSocket;
use std::time::Duration;

use common::fleet::*;
use serde_json::Value;

/// The lines of a sealed record, without its seal line.
fn lines_of(record: &str) -> Vec<&str> {
    record.lines().filter(|l| !l.starts_with("#seal")).collect()
}

/// Robot 1's line of a fix-feed record moved `dx` metres along x.
fn shifted(line: &str, dx: f64) -> String {
    let mut f: Vec<String> = line.split(',').map(str::to_string).collect();
    let x: f64 = f[2].parse().unwrap();
    f[2] = format!("{:.4}", x + dx);
    f.join(",") + "\n"
}

/// Finding 1 (high): anyone on the site network could send fixes; a flood 2 m off moved
/// follower 1 4.3 m off its slot and the goal was never reached. Here an attacker who
/// hears every genuine record sends, for each, 20 datagrams of 10 forged fixes of
/// follower 1, 2 m off (2,000 lines/s): unsealed, sealed with another site's key, the
/// genuine record changed, and genuine records replayed a second late; and once a record
/// sealed with the site's own key and the largest counter. The fleet goes on as without
/// them; every forged datagram is counted by why it was refused.
#[test]
fn a_flood_of_forged_fixes_moves_no_robot() {
    let site = Site::new("fix-flood");
    let scenario = site.path("short-passage.toml");
    let scenario = scenario.to_str().unwrap();
    let sim = sim_report(&site, scenario);
    let relay = UdpSocket::bind("127.0.0.1:0").unwrap();
    let feed = format!("127.0.0.1:{}", free_udp_port());
    let publish = format!("feed:{}", relay.local_addr().unwrap());
    let (mut robots, report, _) = robots_over_udp(&site, scenario, &["--publish-fixes", &publish]);
    let at = robots.address();
    let run_report = site.path("run.json");
    let run = run_over_udp(
        &site,
        scenario,
        &at,
        &[
            "--fix-feed",
            &feed,
            "--report",
            run_report.to_str().unwrap(),
        ],
    );
    // The relay: the genuine records go on to the station, and each is replayed a second
    // later; the latest genuine line of follower 1 is what the flood forges from.
    let latest = std::sync::Arc::new(std::sync::Mutex::new(None::<(String, String)>));
    let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let relayed = {
        let (feed, latest, done) = (feed.clone(), latest.clone(), done.clone());
        std::thread::spawn(move || {
            let out = UdpSocket::bind("127.0.0.1:0").unwrap();
            relay
                .set_read_timeout(Some(Duration::from_secs(1)))
                .unwrap();
            let mut buf = [0u8; 65_536];
            let mut recent: Vec<Vec<u8>> = Vec::new();
            let mut replays = 0u64;
            while let Ok(n) = relay.recv(&mut buf) {
                let record = &buf[..n];
                out.send_to(record, &feed).unwrap();
                let text = String::from_utf8_lossy(record).to_string();
                if let Some(line) = lines_of(&text).into_iter().find(|l| l.starts_with("1,")) {
                    *latest.lock().unwrap() = Some((line.to_string(), text.clone()));
                }
                recent.push(record.to_vec());
                if recent.len() > 10 {
                    out.send_to(&recent.remove(0), &feed).unwrap();
                    replays += 1;
                }
            }
            done.store(true, std::sync::atomic::Ordering::SeqCst);
            replays
        })
    };
    // The flood: every 5 ms, whatever the genuine feed does, 10 fixes of follower 1 2 m
    // ahead of where it is, stamped now.
    let flood = {
        let (feed, latest, done) = (feed.clone(), latest.clone(), done.clone());
        std::thread::spawn(move || {
            let out = UdpSocket::bind("127.0.0.1:0").unwrap();
            let other_site = protocol::MasterKey::from_bytes(&[7; 32]);
            let mut foreign = base_station::seal::Sealer::new(
                base_station::seal::SourceKey::derive(&other_site, "fixes"),
            );
            let mut sent = 0u64;
            while !done.load(std::sync::atomic::Ordering::SeqCst) {
                std::thread::sleep(Duration::from_millis(5));
                let Some((genuine, record)) = latest.lock().unwrap().clone() else {
                    continue;
                };
                let mut f: Vec<String> = genuine.split(',').map(str::to_string).collect();
                f[1] = format!("{:.3}", unix_us() as f64 / 1e6);
                let fresh = f.join(",");
                let forged = shifted(&fresh, 2.0).repeat(10);
                let datagram = match sent % 4 {
                    0 | 1 => forged,
                    2 => foreign.seal(&forged, unix_us()),
                    _ => record.replace(&genuine, shifted(&genuine, 2.0).trim_end()),
                };
                if out.send_to(datagram.as_bytes(), &feed).is_ok() {
                    sent += 1;
                }
            }
            sent
        })
    };
    // A captured key: one record with no lines and the largest counter, which under a
    // replay floor ended the feed for good (issue 52). It is refused as ahead of the
    // station's clock, and the genuine feed goes on.
    std::thread::sleep(Duration::from_secs(2));
    let out = UdpSocket::bind("127.0.0.1:0").unwrap();
    out.send_to(seal("fixes", "", u64::MAX - 1).as_bytes(), &feed)
        .unwrap();
    run.finish(Duration::from_secs(90));
    robots.finish(Duration::from_secs(30));
    let replays = relayed.join().unwrap();
    let forged = flood.join().unwrap();

    let r = json(&report);
    assert_eq!(r["goal_reached"], true, "{r}");
    assert_eq!(r["collisions"], 0);
    let run = json(&run_report);
    for ((id, real), (_, simulated)) in follower_errors(&r).into_iter().zip(follower_errors(&sim)) {
        println!("fix flood: follower {id}: {real:.3} m (sim {simulated:.3} m)");
        assert!(
            real <= simulated + FORWARDED_FIX_MARGIN_M,
            "follower {id}: {real:.3} m, sim {simulated:.3} m"
        );
    }
    let counts = &run["localization"][format!("feed udp:{feed}")];
    println!("{forged} forged datagrams, {replays} replays; feed: {counts}");
    assert!(forged > 2000, "the attack ran: {forged}");
    let refused = ["unsealed", "bad_seal", "replayed"].map(|k| counts[k].as_u64().unwrap());
    assert!(
        refused[0] > 1000 && refused[1] > 500 && refused[2] > 50,
        "{counts}"
    );
    // Every forged datagram the station heard was refused (it stops listening a little
    // before the robots stop publishing: the last ones go unheard).
    assert_eq!(counts["ahead"], 1, "{counts}");
    let heard = refused[0] + refused[1];
    assert!(heard <= forged && heard * 10 >= forged * 8, "{counts}");
    assert!(
        events(&run).iter().all(|e| e.1 != "localization_lost"),
        "{run}"
    );
    // The flood is told as a station event (issue 52), not only counted.
    let told = format!("feed_refused:feed udp:{feed}");
    assert!(events(&run).iter().any(|e| e.1 == told), "{run}");
    let timing: &Value = &run["loop"];
    println!("control loop under the flood: {timing}");
    assert!(timing["late_p99_ms"].as_f64().unwrap() < 20.0, "{timing}");
}

/// The console's `host:port` and pairing code from the URL the run prints.
fn host_and_code(url: &str) -> (String, String) {
    url.strip_prefix("http://")
        .and_then(|u| u.split_once("/#pair="))
        .map(|(h, c)| (h.to_string(), c.to_string()))
        .unwrap_or_else(|| panic!("not a console URL: {url}"))
}

/// One raw HTTP request on a fresh connection to `addr`: the status (0 when none came)
/// and how long the answer took.
fn http_status(addr: &str, request: &str) -> (u16, Duration) {
    use std::io::{Read, Write};
    let start = std::time::Instant::now();
    let Ok(mut s) = std::net::TcpStream::connect(addr) else {
        return (0, start.elapsed());
    };
    s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    let _ = s.write_all(request.as_bytes());
    let mut head = [0u8; 64];
    let n = s.read(&mut head).unwrap_or(0);
    let status = String::from_utf8_lossy(&head[..n])
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    (status, start.elapsed())
}

/// The peak resident memory of process `pid`, MB.
fn peak_rss_mb(pid: u32) -> f64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.split_whitespace().next()?.parse::<f64>().ok())
        .map_or(0.0, |kb| kb / 1024.0)
}

/// Finding 4 (medium): an endless header grew the station to 3 GB and aborted it, control
/// loop included; 554 idle connections killed the console for the rest of the run; one
/// stalled POST body froze the operator's Emergency stop for 25 s. Here all three go on
/// at once through a real run (600 connections held open and renewed, four endless
/// headers, eight stalled bodies, all from the operator's own address): the operator's
/// emergency stop still answers within a second and stops the fleet, Resume sets it
/// going, the station stays small, the console alive, and the control loop on time.
#[test]
fn the_console_survives_floods_of_connections_headers_and_stalled_bodies() {
    use std::io::Write;
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    let site = Site::new("console-flood");
    let scenario = site.path("short-passage.toml");
    let scenario = scenario.to_str().unwrap();
    let (mut robots, report, trace_csv) = robots_over_udp(&site, scenario, &[]);
    let at = robots.address();
    let run_report = site.path("run.json");
    let mut run = run_over_udp(
        &site,
        scenario,
        &at,
        &[
            "--console",
            "127.0.0.1:0",
            "--report",
            run_report.to_str().unwrap(),
        ],
    );
    let (host, code) = host_and_code(&run.console_url());
    let stop = Arc::new(AtomicBool::new(false));
    let mut attackers = Vec::new();
    // 600 connections held open, the oldest dropped for a new one.
    attackers.push({
        let (host, stop) = (host.clone(), stop.clone());
        std::thread::spawn(move || {
            let mut held = std::collections::VecDeque::new();
            while !stop.load(Ordering::Relaxed) {
                if let Ok(s) = std::net::TcpStream::connect(&host) {
                    held.push_back(s);
                }
                if held.len() > 600 {
                    held.pop_front();
                }
                std::thread::sleep(Duration::from_millis(2));
            }
        })
    });
    // Endless headers and stalled bodies.
    for k in 0..12 {
        let (host, stop) = (host.clone(), stop.clone());
        attackers.push(std::thread::spawn(move || {
            let filler = vec![b'a'; 65_536];
            while !stop.load(Ordering::Relaxed) {
                let Ok(mut s) = std::net::TcpStream::connect(&host) else {
                    continue;
                };
                if k < 4 {
                    let _ = write!(s, "GET / HTTP/1.1\r\nHost: {host}\r\nX-Long: ");
                    while !stop.load(Ordering::Relaxed) && s.write_all(&filler).is_ok() {}
                } else {
                    let _ = write!(
                        s,
                        "POST /api/command HTTP/1.1\r\nHost: {host}\r\nContent-Type: \
                         application/json\r\nContent-Length: 100\r\n\r\n{{"
                    );
                    let mut buf = [0u8; 256];
                    let _ = std::io::Read::read(&mut s, &mut buf);
                }
            }
        }));
    }
    let command = |name: &str| {
        let body = format!("{{\"command\":\"{name}\"}}");
        let request = format!(
            "POST /api/command HTTP/1.1\r\nHost: {host}\r\nX-Console-Token: {code}\r\n\
             Content-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
            body.len()
        );
        http_status(&host, &request)
    };
    std::thread::sleep(Duration::from_secs(10));
    let (status, took) = command("emergency_stop");
    println!("emergency stop under the floods: {status} in {took:?}");
    assert_eq!(status, 200);
    assert!(took < Duration::from_secs(1), "{took:?}");
    std::thread::sleep(Duration::from_secs(4));
    let rss = peak_rss_mb(run.0.id());
    let (status, took) = command("resume");
    println!("resume: {status} in {took:?}; the station's peak memory {rss:.0} MB");
    assert_eq!(status, 200);
    assert!(rss < 200.0, "{rss} MB");
    run.finish(Duration::from_secs(120));
    stop.store(true, Ordering::Relaxed);
    robots.finish(Duration::from_secs(30));
    for a in attackers {
        let _ = a.join();
    }

    let r = json(&report);
    assert_eq!(r["goal_reached"], true, "{r}");
    assert_eq!(r["collisions"], 0);
    let run = json(&run_report);
    let stopped = events(&run)
        .iter()
        .find(|e| e.1 == "operator_emergency_stop")
        .map(|e| e.0)
        .expect("the stop reached the station");
    // The robots' clock starts a little before the station's: 0.5 s of slack.
    for (id, _, v) in driven(&trace(&trace_csv), stopped + 1.5, stopped + 3.0) {
        assert!(v.abs() < 0.01, "robot {id} at {v:.3} m/s after the stop");
    }
    assert_eq!(run["console"]["alive"], true, "{}", run["console"]);
    let timing = &run["loop"];
    println!("control loop under the floods: {timing}");
    assert!(timing["late_p99_ms"].as_f64().unwrap() < 20.0, "{timing}");
}

/// A scan line of `hits` taken now.
fn scan_line(hits: impl Iterator<Item = (f64, f64)>) -> String {
    let mut line = format!("{:.3}", unix_us() as f64 / 1e6);
    for (x, y) in hits {
        line.push_str(&format!(",{x:.3},{y:.3}"));
    }
    line + "\n"
}

/// Finding 3 (medium): one datagram of hits in a wall across the site stopped the mission
/// for good; six datagrams of far-away hits filled the store and the real van was never
/// sensed; one hit at 1e300 before the first plan made the start "inside an obstacle".
/// Here, beside the genuine scans of a van across the way: the same unsealed (a wall at
/// once, the far hits, the 1e300 hit), a wall sealed with another site's key, and a wall
/// sealed with the site's own scan key (a faulty scan processor: taken, then forgotten
/// when no scan sees it again). The van is still sensed and routed round, and the goal
/// reached.
#[test]
fn forged_scans_neither_stop_nor_blind_the_station() {
    let site = Site::new("scan-forgery");
    let scenario = site.path("van.toml");
    // A short memory, so that the test sees the genuine wall forgotten within its run.
    let text = format!("{VAN_ON_THE_WAY}\n[perception]\nforget_after_s = 4.0\n");
    std::fs::write(&scenario, text).unwrap();
    let scenario = scenario.to_str().unwrap();
    let feed = format!("127.0.0.1:{}", free_udp_port());
    let (mut robots, report, _) = robots_over_udp(&site, scenario, &["--publish-scan", &feed]);
    let at = robots.address();
    let run_report = site.path("run.json");
    let run = run_over_udp(
        &site,
        scenario,
        &at,
        &[
            "--scan-feed",
            &feed,
            "--report",
            run_report.to_str().unwrap(),
        ],
    );
    let out = UdpSocket::bind("127.0.0.1:0").unwrap();
    let send = |text: &str| out.send_to(text.as_bytes(), &feed).unwrap();
    std::thread::sleep(Duration::from_millis(300));
    send(&scan_line([(1e300, 1e300)].into_iter()));
    std::thread::sleep(Duration::from_secs(2));
    // A wall across the whole site at x = 9 (the fleet starts at x = 1..4).
    let wall = || scan_line((0..1400).map(|k| (9.0, -2.0 + 0.017 * k as f64)));
    send(&wall());
    for k in 0..6 {
        send(&scan_line(
            (0..1440).map(|i| (1000.0 + k as f64, 0.1 * i as f64)),
        ));
    }
    let other_site = protocol::MasterKey::from_bytes(&[7; 32]);
    let foreign = base_station::seal::SourceKey::derive(&other_site, "scan");
    send(&foreign.seal(&wall(), unix_us()));
    std::thread::sleep(Duration::from_secs(2));
    // The simulated robots seal each scan with the time it was taken, up to one physics
    // step ahead of the wall clock: a processor sharing their key whose clock runs 50 ms
    // ahead, so that its wall is not a replay of the last genuine scan.
    send(&seal("scan", &wall(), unix_us() + 50_000));
    run.finish(Duration::from_secs(120));
    robots.finish(Duration::from_secs(30));

    let r = json(&report);
    assert_eq!(r["goal_reached"], true, "{r}");
    assert_eq!(r["collisions"], 0);
    let run = json(&run_report);
    let (feed, perception) = (&run["scan_feed"], &run["perception"]);
    println!("scan feed: {feed}; perception: {perception}");
    assert_eq!(feed["unsealed"], 8, "{feed}");
    assert_eq!(feed["bad_seal"], 1, "{feed}");
    assert!(
        perception["forgotten"].as_u64().unwrap() >= 100,
        "{perception}"
    );
    let replans = events(&run).iter().filter(|e| e.1 == "replanned").count();
    assert!(replans > 0, "never planned round the van");
}

/// A TCP connection to `to` from the loopback address `source` (any of 127.0.0.0/8).
fn connect_from(
    source: std::net::Ipv4Addr,
    to: std::net::SocketAddrV4,
) -> Option<std::net::TcpStream> {
    use nix::sys::socket::{bind, connect, socket, AddressFamily, SockFlag, SockType, SockaddrIn};
    use std::os::fd::AsRawFd;
    let fd = socket(
        AddressFamily::Inet,
        SockType::Stream,
        SockFlag::empty(),
        None,
    )
    .ok()?;
    bind(
        fd.as_raw_fd(),
        &SockaddrIn::from(std::net::SocketAddrV4::new(source, 0)),
    )
    .ok()?;
    connect(fd.as_raw_fd(), &SockaddrIn::from(to)).ok()?;
    Some(std::net::TcpStream::from(fd))
}

/// One request on `stream`, kept open: the status and how long the answer took.
fn on_connection(stream: &mut std::net::TcpStream, request: &str) -> (u16, Duration) {
    use std::io::{BufRead, BufReader, Read, Write};
    let start = std::time::Instant::now();
    if stream.write_all(request.as_bytes()).is_err() {
        return (0, start.elapsed());
    }
    let mut reader = BufReader::new(&mut *stream);
    let (mut status, mut length) = (0, 0usize);
    loop {
        let mut line = String::new();
        if reader.read_line(&mut line).unwrap_or(0) == 0 {
            return (0, start.elapsed());
        }
        let lower = line.to_ascii_lowercase();
        if let Some(code) = lower.strip_prefix("http/1.1 ") {
            status = code[..3].parse().unwrap_or(0);
        } else if let Some(n) = lower.strip_prefix("content-length:") {
            length = n.trim().parse().unwrap_or(0);
        } else if line == "\r\n" {
            break;
        }
    }
    let mut body = vec![0u8; length];
    let _ = reader.read_exact(&mut body);
    (status, start.elapsed())
}

/// The console's session cookie for the pairing code `code`.
fn paired_cookie(host: &str, code: &str) -> String {
    use std::io::{Read, Write};
    let body = format!("{{\"code\":\"{code}\"}}");
    let mut s = std::net::TcpStream::connect(host).unwrap();
    write!(
        s,
        "POST /api/pair HTTP/1.1\r\nHost: {host}\r\nContent-Type: application/json\r\n\
         Content-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    )
    .unwrap();
    let mut answer = String::new();
    let _ = s.read_to_string(&mut answer);
    answer
        .lines()
        .find_map(|l| {
            l.strip_prefix("set-cookie: ")
                .or(l.strip_prefix("Set-Cookie: "))
        })
        .and_then(|c| c.split(';').next())
        .map(str::to_string)
        .unwrap_or_else(|| panic!("not paired: {answer}"))
}

/// Issue 52, finding 5: connections churned from ever-new loopback sources reset 3 of 38
/// of the operator's requests, one took 1.2 s. Here four threads open connections from
/// rotating 127.x.y.z sources as fast as they can, each holding its newest 300, while the
/// paired operator polls the state as the page does (40 times, on its kept-alive
/// connection), then sends the emergency stop on it, then asks 40 times more, each on a
/// fresh connection (as a browser does when its connection closed): every answer comes,
/// the stop within a second (under 100 ms on this machine, even beside the other suites).
#[test]
fn the_operator_is_served_under_connection_churn() {
    use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
    use std::sync::Arc;
    let site = Site::new("console-churn");
    let scenario = site.path("short-passage.toml");
    let scenario = scenario.to_str().unwrap();
    let (mut robots, _report, _trace) = robots_over_udp(&site, scenario, &[]);
    let at = robots.address();
    let mut run = run_over_udp(&site, scenario, &at, &["--console", "127.0.0.1:0"]);
    let (host, code) = host_and_code(&run.console_url());
    let cookie = paired_cookie(&host, &code);
    let target: std::net::SocketAddrV4 = host.parse().unwrap();
    let mut page = std::net::TcpStream::connect(&host).unwrap();
    page.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    // The page's connection, as a browser opens it: with a request.
    let state = format!("GET /api/state HTTP/1.1\r\nHost: {host}\r\nCookie: {cookie}\r\n\r\n");
    assert_eq!(on_connection(&mut page, &state).0, 200);
    let (stop, opened) = (
        Arc::new(AtomicBool::new(false)),
        Arc::new(AtomicU64::new(0)),
    );
    let churn: Vec<_> = (0..4u8)
        .map(|k| {
            let (stop, opened) = (stop.clone(), opened.clone());
            std::thread::spawn(move || {
                let mut held = std::collections::VecDeque::new();
                let mut n = 0u32;
                while !stop.load(Ordering::Relaxed) {
                    n = n.wrapping_add(1);
                    let [_, b, c, d] = (n % 4_000_000 + 2).to_be_bytes();
                    let source = std::net::Ipv4Addr::new(127, b.max(1) ^ k, c, d.max(1));
                    if let Some(s) = connect_from(source, target) {
                        held.push_back(s);
                        opened.fetch_add(1, Ordering::Relaxed);
                    }
                    if held.len() > 300 {
                        held.pop_front();
                    }
                }
            })
        })
        .collect();

    let body = "{\"command\":\"emergency_stop\"}";
    let estop = format!(
        "POST /api/command HTTP/1.1\r\nHost: {host}\r\nCookie: {cookie}\r\n\
         Content-Type: application/json\r\nContent-Length: {}\r\n\r\n{body}",
        body.len()
    );
    std::thread::sleep(Duration::from_secs(2));
    let mut kept = Vec::new();
    for _ in 0..40 {
        kept.push(on_connection(&mut page, &state));
        std::thread::sleep(Duration::from_millis(100));
    }
    let (status, took) = on_connection(&mut page, &estop);
    let mut fresh = Vec::new();
    for _ in 0..40 {
        let close = state.replace("\r\n\r\n", "\r\nConnection: close\r\n\r\n");
        fresh.push(http_status(&host, &close));
        std::thread::sleep(Duration::from_millis(100));
    }
    let churned = opened.load(Ordering::Relaxed);
    stop.store(true, Ordering::Relaxed);
    for c in churn {
        let _ = c.join();
    }
    let tally = |answers: &[(u16, Duration)]| {
        let failed = answers.iter().filter(|(s, _)| *s != 200).count();
        (failed, answers.iter().map(|a| a.1).max().unwrap())
    };
    let ((kept_failed, kept_slowest), (fresh_failed, fresh_slowest)) =
        (tally(&kept), tally(&fresh));
    println!(
        "under churn ({churned} connections): kept-alive {kept_failed} of 40 failed, slowest \
         {kept_slowest:?}; emergency stop {status} in {took:?}; fresh connections \
         {fresh_failed} of 40 failed, slowest {fresh_slowest:?}"
    );
    // Every answer comes; how fast depends on what else the machine runs (0.14 ms quiet,
    // 59 ms beside the other suites: docs/RELIABILITY.md), so the time is bounded loosely,
    // as the floods' test bounds it.
    assert_eq!((kept_failed, status), (0, 200), "{kept:?}");
    assert!(took < Duration::from_secs(1), "{took:?}");
    assert_eq!(fresh_failed, 0, "{fresh:?}");
    let resume = estop.replace("emergency_stop", "resume").replace(
        &format!("{}\r\n\r\n", body.len()),
        &format!("{}\r\nConnection: close\r\n\r\n", body.len() - 8),
    );
    assert_eq!(http_status(&host, &resume).0, 200, "{resume}");
    run.finish(Duration::from_secs(120));
    robots.finish(Duration::from_secs(30));
}
