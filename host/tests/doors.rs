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
/// genuine record changed, and genuine records replayed a second late. The fleet goes on
/// as without them; every forged datagram is counted by why it was refused.
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
    let run = Process::start(
        &site,
        &[
            "run",
            scenario,
            "--udp",
            &at,
            "--bind",
            "127.0.0.1:0",
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
    let heard = refused[0] + refused[1];
    assert!(heard <= forged && heard * 10 >= forged * 8, "{counts}");
    assert!(
        events(&run).iter().all(|e| e.1 != "localization_lost"),
        "{run}"
    );
    let timing: &Value = &run["loop"];
    println!("control loop under the flood: {timing}");
    assert!(timing["late_p99_ms"].as_f64().unwrap() < 20.0, "{timing}");
}
