//! The generated suites by name, grouped as the issues judge them: the street suites (one
//! to three movers on a street or in an alley), the crowds on a plaza, and the static maps.
//! The tests run them under their seeds; `paired` runs any of them through two
//! `basestation` binaries side by side.

use crate::generate::{self, movers as gen, sweeps, Generated};

/// A suite: its name and its world for a seed.
pub struct Suite {
    pub name: &'static str,
    pub group: Group,
    pub make: fn(u64) -> Generated,
}

/// How the issues group the suites.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Group {
    Streets,
    Crowds,
    Static,
    Sweeps,
}

impl Group {
    pub fn name(self) -> &'static str {
        match self {
            Group::Streets => "streets",
            Group::Crowds => "crowds",
            Group::Static => "static",
            Group::Sweeps => "sweeps",
        }
    }
}

macro_rules! suite {
    ($name:literal, $group:ident, $make:expr) => {
        Suite {
            name: $name,
            group: Group::$group,
            make: $make,
        }
    };
}

/// Every suite, streets first.
pub const SUITES: &[Suite] = &[
    suite!("crossing-social", Streets, |s| gen::crossing(s, true)),
    suite!("crossing-oblivious", Streets, |s| gen::crossing(s, false)),
    suite!("oncoming-social", Streets, |s| gen::oncoming_alley(s, true)),
    suite!("oncoming-oblivious", Streets, |s| gen::oncoming_alley(
        s, false
    )),
    suite!("along-social", Streets, |s| gen::along_the_street(s, true)),
    suite!("along-oblivious", Streets, |s| gen::along_the_street(
        s, false
    )),
    suite!("car-pulling-out", Streets, gen::car_pulling_out),
    suite!("standing-social", Streets, |s| gen::standing_person(
        s, true
    )),
    suite!("standing-oblivious", Streets, |s| gen::standing_person(
        s, false
    )),
    suite!("movers-unmapped", Streets, gen::movers_and_unmapped),
    suite!("plaza-0.05-social", Crowds, |s| gen::plaza_crowd(
        s, 0.05, true
    )),
    suite!("plaza-0.1-social", Crowds, |s| gen::plaza_crowd(
        s, 0.1, true
    )),
    suite!("plaza-0.2-social", Crowds, |s| gen::plaza_crowd(
        s, 0.2, true
    )),
    suite!("plaza-0.3-social", Crowds, |s| gen::plaza_crowd(
        s, 0.3, true
    )),
    suite!("plaza-any-social", Crowds, gen::plaza_any_social),
    suite!("plaza-0.05-oblivious", Crowds, |s| gen::plaza_crowd(
        s, 0.05, false
    )),
    suite!("plaza-0.1-oblivious", Crowds, |s| gen::plaza_crowd(
        s, 0.1, false
    )),
    suite!("plaza-0.2-oblivious", Crowds, |s| gen::plaza_crowd(
        s, 0.2, false
    )),
    suite!("plaza-0.3-oblivious", Crowds, |s| gen::plaza_crowd(
        s, 0.3, false
    )),
    suite!("bin-fields", Static, |s| generate::bin_field(s, 60, 2)),
    suite!("dense-bin-fields", Static, |s| generate::bin_field(
        s, 200, 2
    )),
    suite!("streets-pinched", Static, |s| generate::street(s, 2)),
    suite!("bin-on-the-line", Static, generate::bin_on_the_line),
    suite!("scattered-starts", Static, generate::scattered_starts),
    suite!("traps", Static, generate::trap),
    suite!("alleys-2m", Static, |s| generate::alley(s, 2.0)),
    suite!("alleys-1.3m", Static, |s| generate::alley(s, 1.3)),
    suite!("3-v-bin-fields", Static, |s| generate::bin_field(s, 50, 3)),
    suite!("4-v-streets", Static, |s| generate::street(s, 4)),
    suite!("5-v-bin-fields", Static, |s| generate::bin_field(s, 40, 5)),
    suite!("7-v-streets", Static, |s| generate::street(s, 7)),
    suite!("unmapped-vans", Static, |s| generate::unmapped_in_the_way(
        2 * s
    )),
    suite!("unmapped-barriers", Static, |s| {
        generate::unmapped_in_the_way(2 * s - 1)
    }),
    suite!("sweep-open-yards", Sweeps, sweeps::open_yard),
    suite!("sweep-l-yards", Sweeps, sweeps::l_yard),
    suite!("sweep-bin-plazas", Sweeps, sweeps::bin_plaza),
    suite!("sweep-street-blocks", Sweeps, sweeps::street_block),
    suite!("sweep-crowd-plazas", Sweeps, sweeps::crowd_plaza),
];

/// The suites a word names: a group (`streets`, `crowds`, `static`, `sweeps`), a suite's name, or
/// `all`; several joined by commas.
pub fn named(words: &str) -> Result<Vec<&'static Suite>, String> {
    let mut out: Vec<&'static Suite> = Vec::new();
    for word in words.split(',').map(str::trim) {
        let found: Vec<&'static Suite> = SUITES
            .iter()
            .filter(|s| word == "all" || s.group.name() == word || s.name == word)
            .collect();
        if found.is_empty() {
            return Err(format!(
                "no suite or group `{word}` (groups: streets, crowds, static, sweeps, all)"
            ));
        }
        for s in found {
            if !out.iter().any(|o| o.name == s.name) {
                out.push(s);
            }
        }
    }
    Ok(out)
}
