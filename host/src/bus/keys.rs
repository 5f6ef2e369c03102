//! The fleet's key space on the bus, one place for every key a station publishes, answers
//! or declares and every key `ops` reads (docs/operating.md#the-key-space):
//!
//! ```text
//! sweeper/<site>/<formation>/station           liveliness token: the station is up
//! sweeper/<site>/<formation>/formation         the formation: gate, shape, progress (10 Hz)
//! sweeper/<site>/<formation>/robot/<id>/pose   a robot's pose (10 Hz)
//! sweeper/<site>/<formation>/robot/<id>/state  its mode, faults, speed, error (10 Hz)
//! sweeper/<site>/<formation>/robot/<id>/link   its link: linked, last heard (10 Hz)
//! sweeper/<site>/<formation>/route             the route (when it changes, and each 5 s)
//! sweeper/<site>/<formation>/map               the site's obstacles and goal (each 5 s)
//! sweeper/<site>/<formation>/events            one sample per station event
//! sweeper/<site>/<formation>/command           queryable: stop, emergency_stop, resume
//! ```

/// The first chunk of every key.
pub const ROOT: &str = "sweeper";

/// Every key of every formation.
pub const ALL: &str = "sweeper/**";

/// Every station's liveliness token.
pub const ALL_STATIONS: &str = "sweeper/*/*/station";

/// A formation's place in the key space.
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Formation {
    pub site: String,
    pub name: String,
}

impl Formation {
    /// `site` and `name` as chunks of a key: refused with the rule they break.
    pub fn new(site: &str, name: &str) -> Result<Self, String> {
        chunk("site", site)?;
        chunk("formation", name)?;
        Ok(Self {
            site: site.into(),
            name: name.into(),
        })
    }

    /// `sweeper/<site>/<formation>/<rest>`.
    pub fn key(&self, rest: &str) -> String {
        format!("{ROOT}/{}/{}/{rest}", self.site, self.name)
    }

    pub fn robot_key(&self, id: u16, topic: &str) -> String {
        self.key(&format!("robot/{id}/{topic}"))
    }

    /// `<site>/<formation>`, as `ops` names it.
    pub fn label(&self) -> String {
        format!("{}/{}", self.site, self.name)
    }
}

/// What a key of the fleet's space is about.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Topic {
    Station,
    Formation,
    Route,
    Map,
    Events,
    Command,
    Robot { id: u16, topic: String },
}

/// Splits a key of the fleet's space; `None` for any other key.
pub fn parse(key: &str) -> Option<(Formation, Topic)> {
    let mut parts = key.split('/');
    if parts.next()? != ROOT {
        return None;
    }
    let formation = Formation::new(parts.next()?, parts.next()?).ok()?;
    let topic = match (parts.next()?, parts.next(), parts.next(), parts.next()) {
        ("station", None, ..) => Topic::Station,
        ("formation", None, ..) => Topic::Formation,
        ("route", None, ..) => Topic::Route,
        ("map", None, ..) => Topic::Map,
        ("events", None, ..) => Topic::Events,
        ("command", None, ..) => Topic::Command,
        ("robot", Some(id), Some(topic), None) => Topic::Robot {
            id: id.parse().ok()?,
            topic: topic.into(),
        },
        _ => return None,
    };
    Some((formation, topic))
}

/// A site's or formation's name must be one chunk of a key and plain: letters, digits,
/// `-`, `_` and `.`, at most 64 of them, so that it never reads as a wildcard or a path.
fn chunk(what: &str, name: &str) -> Result<(), String> {
    let plain = |c: char| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.');
    if name.is_empty() || name.len() > 64 || !name.chars().all(plain) {
        return Err(format!(
            "{what} name {name:?}: use 1 to 64 letters, digits, '-', '_' or '.'"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_round_trip_and_nothing_else_parses() {
        let f = Formation::new("north", "sweep-1").expect("plain names");
        assert_eq!(f.robot_key(3, "pose"), "sweeper/north/sweep-1/robot/3/pose");
        assert_eq!(
            parse(&f.robot_key(3, "pose")),
            Some((
                f.clone(),
                Topic::Robot {
                    id: 3,
                    topic: "pose".into()
                }
            ))
        );
        assert_eq!(parse(&f.key("station")), Some((f.clone(), Topic::Station)));
        for bad in [
            "other/north/sweep-1/station",
            "sweeper/north",
            "sweeper/north/sweep-1/robot/x/pose",
            "sweeper/north/sweep-1/station/extra",
            "sweeper/no*/sweep-1/station",
        ] {
            assert_eq!(parse(bad), None, "{bad}");
        }
        for bad in ["", "a/b", "*", "**", "a$b", "a b", &"x".repeat(65)] {
            assert!(Formation::new(bad, "f").is_err(), "{bad:?}");
        }
    }
}
