//! The docs against the binary (issue 53): what the program accepts is what its help,
//! the README and `docs/` say. Each check reads the program's own definitions (its help,
//! its fault kinds, the shipped scenarios) and fails naming what a page leaves out.

mod common;

use std::path::Path;

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

fn read(rel: &str) -> String {
    std::fs::read_to_string(root().join(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

/// The README and every page under `docs/`, as one text.
fn all_docs() -> String {
    let mut text = read("README.md");
    let mut pages: Vec<_> = std::fs::read_dir(root().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "md"))
        .collect();
    pages.sort();
    for p in pages {
        text += &std::fs::read_to_string(p).unwrap();
    }
    text
}

fn help(args: &[&str]) -> String {
    let out = common::basestation().args(args).output().unwrap();
    assert!(out.status.success(), "{args:?}");
    String::from_utf8(out.stdout).unwrap()
}

const COMMANDS: [&str; 8] = [
    "run",
    "sim",
    "robots",
    "check",
    "decode",
    "robot-config",
    "feed-key",
    "feed-relay",
];

/// Every `--option` of every command is documented, in the README or under `docs/`.
#[test]
fn every_option_of_every_command_is_documented() {
    let docs = all_docs();
    let mut missing = Vec::new();
    for command in COMMANDS {
        for word in help(&[command, "--help"]).split_whitespace() {
            let word = word.trim_start_matches(['(', '[', '`']);
            let end = word
                .find(|c: char| !(c.is_ascii_alphanumeric() || c == '-'))
                .unwrap_or(word.len());
            let option = &word[..end];
            let long = option.starts_with("--") && option.len() > 2;
            if long && !["--help", "--verbose"].contains(&option) && !documented(&docs, option) {
                missing.push(format!("{command} {option}"));
            }
        }
    }
    missing.sort();
    missing.dedup();
    assert!(missing.is_empty(), "options no page documents: {missing:?}");
}

/// Whether `option` appears in `docs` as a whole option (`--fix-feed`, not `--fix`).
fn documented(docs: &str, option: &str) -> bool {
    docs.match_indices(option).any(|(i, _)| {
        let next = docs[i + option.len()..].chars().next();
        !next.is_some_and(|c| c.is_ascii_alphanumeric() || c == '-')
    })
}

/// Every kind of `[[faults]]` the program reads (its enum, in the source) has its row in
/// docs/scenario.md, under the name a site file gives it.
#[test]
fn every_fault_kind_has_its_row() {
    let source = read("host/core/src/scenario/mod.rs");
    let start = source.find("pub enum FaultKind {").expect("the enum");
    let body = &source[start..];
    let body = &body[..body.find("\n}").unwrap()];
    let variants: Vec<&str> = body
        .lines()
        .map(str::trim)
        .filter(|l| l.ends_with(',') && l.starts_with(|c: char| c.is_ascii_uppercase()))
        .map(|l| l.trim_end_matches(','))
        .collect();
    assert_eq!(
        variants.len(),
        base_station::scenario::FaultKind::ALL.len(),
        "FaultKind::ALL lists every kind: {variants:?}"
    );
    let page = read("docs/scenario.md");
    let missing: Vec<String> = base_station::scenario::FaultKind::ALL
        .iter()
        .map(|k| k.name())
        .filter(|name| !page.contains(&format!("| `{name}` |")))
        .map(str::to_string)
        .collect();
    assert!(missing.is_empty(), "fault kinds without a row: {missing:?}");
}

/// Every shipped scenario is named where a scenario is taken (the help of `sim`, `run`,
/// `robots` and `check`) and in the README.
#[test]
fn every_shipped_scenario_is_named() {
    let mut shipped: Vec<String> = std::fs::read_dir(root().join("scenarios"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .map(|p| p.file_stem().unwrap().to_string_lossy().to_string())
        .collect();
    shipped.sort();
    assert!(shipped.len() >= 4, "{shipped:?}");
    let readme = read("README.md");
    for command in ["sim", "run", "robots", "check"] {
        let text = help(&[command, "--help"]);
        for name in &shipped {
            assert!(
                text.contains(name.as_str()),
                "`{command} --help` leaves out {name}"
            );
            assert!(
                readme.contains(name.as_str()),
                "README.md leaves out {name}"
            );
        }
    }
}

/// `-V` names the revision it was built from.
#[test]
fn the_version_names_its_revision() {
    let v = help(&["-V"]);
    assert!(
        v.contains(env!("CARGO_PKG_VERSION")) && v.contains("revision"),
        "{v}"
    );
}
