//! A city's fleet on Zenoh, for real: the shipped sample configuration (router with access
//! control, stations, `ops`) in a scratch directory, `basestation router`, three
//! `sim --realtime --zenoh` formations and `basestation ops` as processes. All three appear;
//! an emergency stop from `ops` stops exactly one; a killed station is shown lost within 2 s;
//! a restarted router loses nothing; a station with another's credentials cannot publish as
//! it; a client nobody here wrote (the `eclipse-zenoh` Python package) reads the key space
//! and may not command; the page is driven in headless Chromium.
//!
//! The Python client and the browser are skipped (saying so) when missing, unless
//! `BUS_CLIENTS_REQUIRED` is set (CI sets it).

mod common;

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use serde_json::{json, Value};

use common::browser::open_browser;
use common::bus::{
    configure, free_tcp_port, live_with_robots, ops, router, standing, station, Api, FORMATIONS,
};
use common::Killed;

fn required() -> bool {
    std::env::var_os("BUS_CLIENTS_REQUIRED").is_some()
}

#[test]
fn three_formations_one_router_one_ops_page() {
    let dir = common::scratch("bus-test");
    let port = free_tcp_port();
    configure(&dir, port);
    let mut router_process = router(&dir);
    std::thread::sleep(Duration::from_millis(500));
    let mut stations: Vec<Killed> = FORMATIONS
        .iter()
        .map(|(site, name, _)| station(&dir, &format!("station-{site}-{name}.json5"), site, name))
        .collect();
    // North/b's credentials claiming south/x: access control keeps it off the bus.
    let _impostor = station(&dir, "station-north-b.json5", "south", "x");
    let (_ops, url) = ops(&dir);
    let api = Api::of(&url);

    // All three appear, with their robots.
    api.until(Duration::from_secs(20), "three live formations", |s| {
        ["north/a", "north/b", "south/c"]
            .iter()
            .all(|l| live_with_robots(s, l))
    });
    assert!(api.formation("south/x").is_null(), "the impostor was shown");
    // Under way: every formation's robots move.
    api.until(
        Duration::from_secs(20),
        "three formations under way",
        |_| {
            ["north/a", "north/b", "south/c"].iter().all(|l| {
                let f = api.formation(l);
                let moving = f["robots"].as_array().is_some_and(|r| {
                    r.iter()
                        .all(|r| r["state"]["v"].as_f64().is_some_and(|v| v.abs() > 0.05))
                });
                moving && f["formation"]["gate"] == "running"
            })
        },
    );

    // An emergency stop from ops stops exactly north/b.
    let (status, answer) = api.command("north/b", "emergency_stop");
    assert_eq!(status, 200, "{answer}");
    assert_eq!(answer["answer"]["done"], "emergency_stop", "{answer}");
    api.until(Duration::from_secs(5), "north/b standing", |_| {
        standing(&api.formation("north/b"))
    });
    for label in ["north/a", "south/c"] {
        let f = api.formation(label);
        assert!(f["formation"]["hold"].is_null(), "{label} held: {f}");
        assert!(!standing(&f), "{label} stopped too: {f}");
    }
    assert_eq!(
        api.formation("north/b")["formation"]["hold"],
        "emergency_stop"
    );

    // A killed station is shown lost within 2 s.
    stations[2].0.kill().unwrap();
    let shown = api.until(Duration::from_secs(2), "south/c lost", |_| {
        api.formation("south/c")["station"] == "lost"
    });
    println!("a killed station was shown lost after {shown:?}");
    // A command to it is reported undelivered within the bound.
    let asked = Instant::now();
    let (status, answer) = api.command("south/c", "stop");
    assert_eq!(
        (status, &answer["delivered"]),
        (504, &json!(false)),
        "{answer}"
    );
    assert!(
        asked.elapsed() < Duration::from_millis(1500),
        "{:?}",
        asked.elapsed()
    );

    // An ops started late shows every formation at once: the live ones from their caches
    // and the router's storage, the lost one, with its last state, from the storage.
    let (_first_late, first_late_url) = ops(&dir);
    let late = Api::of(&first_late_url);
    for label in ["north/a", "north/b", "south/c"] {
        let f = late.formation(label);
        let robots = f["robots"].as_array().map_or(0, Vec::len);
        assert_eq!(robots, 3, "{label}: {f}");
    }
    assert_eq!(late.formation("south/c")["station"], "lost");
    let b = late.formation("north/b");
    assert_eq!(b["formation"]["hold"], "emergency_stop", "{b}");

    // The router restarts: the live formations come back, fresh, and nothing is lost.
    let before = api.formation("north/a")["formation"]["t_s"]
        .as_f64()
        .unwrap();
    router_process.0.kill().unwrap();
    let _ = router_process.0.wait();
    api.until(
        Duration::from_secs(2),
        "ops saying the router is gone",
        |s| {
            s["alerts"][0]["alert"]
                .as_str()
                .is_some_and(|a| a.contains("router is out of reach"))
        },
    );
    let _router_again = router(&dir);
    api.until(
        Duration::from_secs(20),
        "the formations back after the router",
        |s| live_with_robots(s, "north/a") && live_with_robots(s, "north/b"),
    );
    api.until(Duration::from_secs(5), "fresh samples", |_| {
        api.formation("north/a")["formation"]["t_s"]
            .as_f64()
            .unwrap()
            > before + 1.0
    });
    let c = api.formation("south/c");
    assert_eq!(c["station"], "lost", "{c}");
    assert_eq!(
        c["robots"].as_array().unwrap().len(),
        3,
        "south/c forgotten: {c}"
    );
    let (status, answer) = api.command("north/a", "stop");
    assert_eq!(
        status, 200,
        "a command after the router's restart: {answer}"
    );

    // After the router's restart too: the live formations from the stations' caches.
    let (_late, late_url) = ops(&dir);
    let late = Api::of(&late_url);
    for label in ["north/a", "north/b"] {
        let f = late.formation(label);
        assert_eq!(
            f["robots"].as_array().map_or(0, Vec::len),
            3,
            "{label}: {f}"
        );
        assert!(!f["formation"]["gate"].is_null(), "{label}: {f}");
    }

    python_client(&dir, port);
    browser(&dir, &url);
    drop(stations);
}

/// The `eclipse-zenoh` Python package, as the sample's viewer: decodes the samples of every
/// formation, and may not command one; a client without credentials may not connect.
fn python_client(dir: &Path, port: u16) {
    let probe = Command::new("python3")
        .args(["-c", "import zenoh"])
        .output();
    if !probe.is_ok_and(|o| o.status.success()) {
        assert!(
            !required(),
            "BUS_CLIENTS_REQUIRED is set but python3 has no zenoh"
        );
        eprintln!("SKIPPED: no eclipse-zenoh for python3 (pip install eclipse-zenoh)");
        return;
    }
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/bus_client.py");
    let out = Command::new("python3")
        .arg(script)
        .arg(format!("tcp/127.0.0.1:{port}"))
        .current_dir(dir)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let r: Value = serde_json::from_str(text.trim()).unwrap();
    // Live formations' robots' poses decoded as JSON with numbers.
    assert!(r["poses"].as_u64().unwrap() >= 6, "{r}");
    assert_eq!(r["formations"], json!(["north/a", "north/b"]), "{r}");
    assert_eq!(r["command_replies"], 0, "the viewer commanded: {r}");
    assert_eq!(r["anonymous"], "refused", "{r}");
}

/// The page in headless Chromium: a card per formation, updated at 5 Hz or more, the lost
/// station marked.
fn browser(dir: &Path, url: &str) {
    let Some((_browser, mut page)) = open_browser(dir) else {
        assert!(
            !required(),
            "BUS_CLIENTS_REQUIRED is set but no chromium was found"
        );
        return;
    };
    page.call("Page.navigate", json!({ "url": url }));
    std::thread::sleep(Duration::from_secs(3));
    let cards = page.eval("document.querySelectorAll('.card').length");
    assert_eq!(cards, 3, "cards");
    let lost = page.eval("document.querySelectorAll('.card.lost').length");
    assert_eq!(lost, 1, "lost cards");
    let updates = |page: &mut common::browser::Page| {
        page.eval("Number(document.body.dataset.updates || 0)")
            .as_f64()
            .unwrap()
    };
    let (u0, t0) = (updates(&mut page), Instant::now());
    std::thread::sleep(Duration::from_secs(2));
    let rate = (updates(&mut page) - u0) / t0.elapsed().as_secs_f64();
    println!("the ops page updated at {rate:.1} Hz");
    assert!(rate >= 5.0, "the page updated at {rate:.1} Hz");
    page.screenshot(&dir.join("ops.png"));
}

/// With the bus out of reach from the start, a formation's run is the one it is without
/// `--zenoh`: the report identical (a realtime run is lockstep, so it matches a plain one).
#[test]
fn a_bus_out_of_reach_changes_nothing_of_the_run() {
    let dir = common::scratch("bus-gone");
    let passage = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/paper-passage.toml");
    let text = std::fs::read_to_string(passage).unwrap() + "\n[sim]\nduration_s = 12.0\n";
    let scenario = dir.join("passage-12s.toml");
    std::fs::write(&scenario, text).unwrap();
    let closed = free_tcp_port();
    let config = dir.join("nowhere.json5");
    let client =
        format!("{{ mode: \"client\", connect: {{ endpoints: [\"tcp/127.0.0.1:{closed}\"] }} }}");
    std::fs::write(&config, client).unwrap();
    let file = scenario.to_str().unwrap();
    for sub in ["plain", "bus"] {
        std::fs::create_dir_all(dir.join(sub)).unwrap();
    }
    let (plain, plain_report) = common::sim_into(&dir.join("plain"), file, &[]);
    let bus_dir = dir.join("bus");
    let args = ["--realtime", "--zenoh", config.to_str().unwrap()];
    let (on_bus, bus_report) = common::sim_into(&bus_dir, file, &args);
    assert_eq!(plain.status.code(), on_bus.status.code());
    let err = String::from_utf8_lossy(&on_bus.stderr);
    assert!(err.contains("bus: cannot open a session yet"), "{err}");
    let strip = |path: &Path| {
        let mut v: Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
        v.as_object_mut()
            .unwrap()
            .retain(|k, _| !k.contains("wall"));
        v
    };
    assert_eq!(strip(&plain_report), strip(&bus_report));
}
