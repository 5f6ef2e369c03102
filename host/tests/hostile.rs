//! Issue 27, finding 6 and deliverable 5: hostile files. A site file with a goal at 1e300
//! panicked `check`, one at 1e13 allocated 9 GB, a million circles took 3 GB, a
//! million-point polygon did not finish in two minutes; `decode` aborted on 4 of 60
//! byte-flipped recordings (a chunk's size trusted). Here every such file gets a clear
//! error naming its field (or a clean result), within 1 GB (`check`) and 256 MB (`decode`)
//! of address space, and never a panic.

mod common;

use std::os::unix::process::CommandExt;
use std::process::Output;

/// Runs `basestation ARGS` with its address space limited to `mb` MiB.
fn limited(mb: u64, args: &[&str]) -> Output {
    let mut command = common::basestation();
    command.args(args);
    let bytes = mb << 20;
    // SAFETY: setrlimit is async-signal-safe; nothing else runs between fork and exec.
    unsafe {
        command.pre_exec(move || {
            nix::sys::resource::setrlimit(nix::sys::resource::Resource::RLIMIT_AS, bytes, bytes)
                .map_err(std::io::Error::from)
        });
    }
    command.output().unwrap()
}

/// The paper's obstacle scenario without its bounds and obstacles, with `map` and `goal`.
fn site(map: &str, goal: &str) -> String {
    let paper = include_str!("../../scenarios/paper-obstacles.toml");
    let kept: Vec<&str> = paper
        .lines()
        .filter(|l| {
            !(l.starts_with("bounds")
                || l.starts_with("goal")
                || l.starts_with("obstacles")
                || l.starts_with("    {")
                || l.trim() == "]")
        })
        .collect();
    kept.join("\n")
        .replace("[map]", &format!("[map]\n{map}"))
        .replace("[route]", &format!("[route]\ngoal = {goal}"))
}

#[test]
fn hostile_site_files_get_a_clear_error_within_a_gigabyte() {
    let dir = common::scratch("hostile-sites");
    let circle = "{kind=\"circle\",center=[40,40],radius=0.2},";
    let big_circle = "{kind=\"circle\",center=[0,500000],radius=400000},";
    let cases: Vec<(&str, String, &str)> = vec![
        ("goal at 1e300", site("", "[1e300, 20.0]"), "route.goal"),
        ("goal at 1e13", site("", "[1e13, 20.0]"), "route.goal"),
        (
            "a radius of 1e300",
            site(
                "obstacles = [{kind=\"circle\",center=[9,9],radius=1e300}]",
                "[20.0, 20.0]",
            ),
            "radius",
        ),
        (
            "a file over 4 MiB",
            site(
                &format!("obstacles = [{}]", circle.repeat(110_000)),
                "[20.0, 20.0]",
            ),
            "at most 4194304 bytes",
        ),
        (
            "100,001 obstacles",
            site(
                &format!(
                    "obstacles = [{}]",
                    "{kind=\"circle\",center=[4,4],radius=1},".repeat(100_001)
                ),
                "[20.0, 20.0]",
            ),
            "at most 100000",
        ),
        (
            "a polygon of 2,000 points",
            site(
                &format!(
                    "obstacles = [{{kind=\"polygon\",points=[{}]}}]",
                    "[1,1],".repeat(2000)
                ),
                "[20.0, 20.0]",
            ),
            "points",
        ),
        (
            "boxes covering the site a thousand times over",
            site(
                &format!("obstacles = [{}]", big_circle.repeat(5000)),
                "[20.0, 20.0]",
            ),
            "times over",
        ),
        (
            "20,000 waypoints",
            site("", "[20.0, 20.0]").replace(
                "[route]",
                &format!("[route]\nwaypoints = [{}]", "[10,10],".repeat(20_000)),
            ),
            "waypoints",
        ),
        (
            "arrays nested a million deep",
            format!("a = {}{}", "[".repeat(1_000_000), "]".repeat(1_000_000)),
            "",
        ),
    ];
    for (what, text, says) in cases {
        let file = dir.join("site.toml");
        std::fs::write(&file, &text).unwrap();
        let out = limited(1024, &["check", file.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&out.stderr);
        let shown: String = err.chars().take(300).collect();
        println!("{what}: {:?} {shown}", out.status.code());
        assert_eq!(out.status.code(), Some(1), "{what}: {shown}");
        assert!(!err.contains("panicked"), "{what}: {shown}");
        assert!(err.contains(says), "{what}: {shown}");
    }
}

/// A 64-bit xorshift: byte flips reproducible without a dependency.
fn xorshift(state: &mut u64) -> u64 {
    *state ^= *state << 13;
    *state ^= *state >> 7;
    *state ^= *state << 17;
    *state
}

#[test]
fn byte_flipped_recordings_decode_within_256_mb_without_a_crash() {
    let dir = common::scratch("hostile-recordings");
    let (sim, _) = common::sim_into(&dir, "paper-passage", &[]);
    assert!(sim.status.success());
    let mcap = dir.join("run.mcap");
    let clean = std::fs::read(&mcap).unwrap();
    let mut rng = 0x2545_f491_4f6c_dd1d_u64;
    let mut outcomes = [0; 2];
    for k in 0..60 {
        let mut bytes = clean.clone();
        for _ in 0..=(xorshift(&mut rng) % 8) {
            let at = (xorshift(&mut rng) % bytes.len() as u64) as usize;
            bytes[at] = xorshift(&mut rng) as u8;
        }
        // Every 6th: a chunk claiming an absurd size, as the review's crash had it.
        if k % 6 == 0 {
            if let Some(at) = bytes.windows(4).position(|w| w == b"zstd") {
                bytes[at - 16..at - 8].copy_from_slice(&u64::MAX.to_le_bytes());
            }
        }
        let file = dir.join("flipped.mcap");
        std::fs::write(&file, &bytes).unwrap();
        let out = limited(256, &["decode", file.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&out.stderr);
        let code = out.status.code();
        assert!(
            matches!(code, Some(0 | 1)) && !err.contains("panicked"),
            "flip {k}: {code:?} {err}"
        );
        outcomes[code.unwrap() as usize] += 1;
    }
    println!(
        "60 damaged recordings: {} decoded, {} refused with an error",
        outcomes[0], outcomes[1]
    );
}
