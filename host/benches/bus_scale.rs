//! A city's bus at scale: N formations of 3 robots (`sim --realtime --zenoh`, each its own
//! process publishing at 10 Hz) through one `basestation router` to one `basestation ops`.
//! Prints the publish-to-`ops` latency p50/p99 (from the samples' timestamps), the samples
//! lost, the CPU of the router and of `ops`, and how often the `ops` page updates in
//! headless Chromium (skipped without a browser).
//!
//! `cargo bench -p host --bench bus_scale -- [--formations 50] [--seconds 30] [--acl]`;
//! with `--acl` the router checks every station's user and keys, as the sample
//! configuration does (a rule per formation).
//! (figures: docs/operating.md#a-citys-fleet-on-zenoh).

#[path = "../tests/common/mod.rs"]
mod common;

use std::path::Path;
use std::time::{Duration, Instant};

use common::bus::{free_tcp_port, live_with_robots, ops, station_for, Api};
use common::Killed;
use serde_json::{json, Value};

/// CPU time (s) a process has used so far.
fn cpu_s(pid: u32) -> f64 {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap_or_default();
    // The fields after the command's closing parenthesis: utime and stime are 12th and 13th.
    let fields: Vec<&str> = stat
        .rsplit_once(')')
        .map_or("", |x| x.1)
        .split_whitespace()
        .collect();
    let ticks: f64 = fields[11..13]
        .iter()
        .filter_map(|f| f.parse::<f64>().ok())
        .sum();
    // /proc counts in USER_HZ, 100 a second on Linux whatever the kernel's own tick.
    ticks / 100.0
}

fn arg(name: &str, default: u64) -> u64 {
    let args: Vec<String> = std::env::args().collect();
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// The site and name of formation `i`.
fn formation(i: u64) -> (String, String) {
    (format!("district-{}", i % 5), format!("f{i:02}"))
}

/// A client's configuration on `port`, as `user` when access control is on.
fn client(port: u16, user: Option<&str>) -> String {
    let auth = user.map_or(String::new(), |u| {
        format!("transport: {{ auth: {{ usrpwd: {{ user: \"{u}\", password: \"pw-{u}\" }} }} }},")
    });
    format!(
        "{{ mode: \"client\", connect: {{ endpoints: [\"tcp/127.0.0.1:{port}\"] }}, \
         scouting: {{ multicast: {{ enabled: false }} }}, {auth} }}"
    )
}

/// The router's access control for `n` stations and `ops`, as the sample's rules.
fn access_control(n: u64) -> String {
    let own = "[\"put\", \"delete\", \"declare_queryable\", \"query\", \"reply\", \
               \"liveliness_token\", \"liveliness_query\"]";
    let read = "[\"declare_subscriber\", \"put\", \"declare_liveliness_subscriber\", \
                \"liveliness_token\", \"liveliness_query\", \"query\", \"reply\"]";
    let (mut rules, mut subjects, mut policies) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..n {
        let (site, name) = formation(i);
        rules.push(format!(
            "{{ id: \"r{i}\", permission: \"allow\", messages: {own}, key_exprs: [\"sweeper/{site}/{name}/**\"] }}"
        ));
        subjects.push(format!("{{ id: \"s{i}\", usernames: [\"station-{i}\"] }}"));
        policies.push(format!(
            "{{ rules: [\"r{i}\", \"listeners\"], subjects: [\"s{i}\"] }}"
        ));
    }
    rules.push(format!(
        "{{ id: \"listeners\", permission: \"allow\", flows: [\"egress\"], \
         messages: [\"declare_subscriber\"], key_exprs: [\"sweeper/**\"] }}, \
         {{ id: \"read-all\", permission: \"allow\", messages: {read}, key_exprs: [\"sweeper/**\"] }}"
    ));
    subjects.push("{ id: \"ops\", usernames: [\"ops\"] }".into());
    policies.push("{ rules: [\"read-all\"], subjects: [\"ops\"] }".into());
    format!(
        "access_control: {{ enabled: true, default_permission: \"deny\", rules: [{}], \
         subjects: [{}], policies: [{}] }}",
        rules.join(", "),
        subjects.join(", "),
        policies.join(", ")
    )
}

/// A router on `port` (with access control and the users' dictionary when `acl`), and
/// the clients' files.
fn configure(dir: &Path, port: u16, n: u64, acl: bool) -> Killed {
    let mut router = format!(
        "{{ mode: \"router\", listen: {{ endpoints: [\"tcp/127.0.0.1:{port}\"] }}, \
         scouting: {{ multicast: {{ enabled: false }} }}"
    );
    if acl {
        let users: Vec<String> = (0..n)
            .map(|i| format!("station-{i}:pw-station-{i}"))
            .chain(["ops:pw-ops".to_string()])
            .collect();
        std::fs::write(dir.join("users.txt"), users.join("\n") + "\n").unwrap();
        router += ", transport: { auth: { usrpwd: { dictionary_file: \"users.txt\" } } }, ";
        router += &access_control(n);
    }
    router += " }";
    std::fs::write(dir.join("router.json5"), router).unwrap();
    for i in 0..n {
        let user = format!("station-{i}");
        let text = client(port, acl.then_some(user.as_str()));
        std::fs::write(dir.join(format!("station-{i}.json5")), text).unwrap();
    }
    std::fs::write(dir.join("ops.json5"), client(port, acl.then_some("ops"))).unwrap();
    let child = common::basestation()
        .current_dir(dir)
        .args(["router", "--zenoh", "router.json5"])
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    Killed(child)
}

/// The page's update rate over `seconds` in headless Chromium, if there is one.
fn page_rate(dir: &Path, url: &str, seconds: u64) -> Option<f64> {
    let (_browser, mut page) = common::browser::open_browser(dir)?;
    page.call("Page.navigate", json!({ "url": url }));
    std::thread::sleep(Duration::from_secs(3));
    let count = |p: &mut common::browser::Page| {
        p.eval("Number(document.body.dataset.updates || 0)")
            .as_f64()
            .unwrap_or(0.0)
    };
    let (u0, t0) = (count(&mut page), Instant::now());
    std::thread::sleep(Duration::from_secs(seconds));
    let rate = (count(&mut page) - u0) / t0.elapsed().as_secs_f64();
    page.screenshot(&dir.join("ops-scale.png"));
    Some(rate)
}

fn main() {
    let (n, seconds) = (arg("--formations", 50), arg("--seconds", 30));
    let acl = std::env::args().any(|a| a == "--acl");
    let dir = common::scratch("bus-bench");
    let port = free_tcp_port();
    let router = configure(&dir, port, n, acl);
    std::thread::sleep(Duration::from_millis(500));
    let duration = (seconds + 120) as f64;
    let mut stations = Vec::new();
    for i in 0..n {
        let (site, name) = formation(i);
        let config = format!("station-{i}.json5");
        stations.push(station_for(&dir, &config, &site, &name, duration));
        std::thread::sleep(Duration::from_millis(100));
    }
    let (ops_process, url) = ops(&dir);
    let api = Api::of(&url);
    api.until(Duration::from_secs(90), "every formation live", |s| {
        (0..n).all(|i| {
            let (site, name) = formation(i);
            live_with_robots(s, &format!("{site}/{name}"))
        })
    });
    std::thread::sleep(Duration::from_secs(3));
    let bus = |api: &Api| api.state()["bus"].clone();
    let (b0, t0) = (bus(&api), Instant::now());
    let cpu0 = (cpu_s(router.0.id()), cpu_s(ops_process.0.id()));
    let mut windows: Vec<Value> = Vec::new();
    let rate = page_rate(&dir, &url, seconds / 2);
    while t0.elapsed() < Duration::from_secs(seconds) {
        std::thread::sleep(Duration::from_secs(2));
        windows.push(bus(&api)["latency_ms"].clone());
    }
    let (b1, wall) = (bus(&api), t0.elapsed().as_secs_f64());
    let cpu1 = (cpu_s(router.0.id()), cpu_s(ops_process.0.id()));
    let cpu = (cpu1.0 - cpu0.0, cpu1.1 - cpu0.1);
    println!(
        "access control      {}",
        if acl {
            "on (a rule per formation)"
        } else {
            "off"
        }
    );
    report(n, wall, (&b0, &b1), &windows, cpu, rate);
    drop(stations);
}

fn report(
    n: u64,
    wall: f64,
    (b0, b1): (&Value, &Value),
    windows: &[Value],
    cpu: (f64, f64),
    rate: Option<f64>,
) {
    let diff = |k: &str| b1[k].as_u64().unwrap_or(0) - b0[k].as_u64().unwrap_or(0);
    let mut p50: Vec<f64> = windows.iter().filter_map(|w| w["p50"].as_f64()).collect();
    p50.sort_by(f64::total_cmp);
    let worst = |k: &str| {
        windows
            .iter()
            .filter_map(|w| w[k].as_f64())
            .fold(0.0, f64::max)
    };
    let samples = diff("samples");
    println!("formations          {n} (3 robots each, 10 Hz)");
    println!("window              {wall:.1} s");
    println!(
        "samples to ops      {samples} ({:.0}/s)",
        samples as f64 / wall
    );
    println!("samples lost        {}", diff("lost"));
    println!("malformed           {}", diff("malformed"));
    println!(
        "latency p50         {:.2} ms (median of {} windows of 2 s)",
        p50.get(p50.len() / 2).copied().unwrap_or(f64::NAN),
        p50.len()
    );
    println!(
        "latency p99         {:.2} ms (worst window); max {:.2} ms",
        worst("p99"),
        worst("max")
    );
    println!(
        "CPU router          {:.1} % of one core",
        100.0 * cpu.0 / wall
    );
    println!(
        "CPU ops             {:.1} % of one core",
        100.0 * cpu.1 / wall
    );
    match rate {
        Some(r) => println!("ops page            {r:.1} updates/s (headless Chromium)"),
        None => println!("ops page            not measured (no chromium)"),
    }
}
