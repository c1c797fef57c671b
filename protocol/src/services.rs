//! Every iceoryx2 service name of uavloc, in one place.
//!
//! Names are `"<domain>/<topic>"`, e.g. `uavloc/measurement`. The domain separates independent runs on one
//! machine (parallel tests, two experiments): processes talk only to processes of the same domain. It comes
//! from `--domain NAME`, else the environment variable `UAVLOC_DOMAIN` (an empty value counts as unset),
//! else `"uavloc"`, and must be 1 to 64 characters of `[A-Za-z0-9_-]`.
//!
//! The names carry no version: a process with a different message layout then fails loudly when opening
//! the service (the pinned type names differ) instead of silently talking to nobody.

use core::fmt;
use core::str::FromStr;

use crate::ProtocolError;

/// Environment variable naming the domain.
pub const DOMAIN_ENV: &str = "UAVLOC_DOMAIN";
/// Command-line flag naming the domain (`--domain NAME` or `--domain=NAME`).
pub const DOMAIN_FLAG: &str = "--domain";
/// The domain used when none is given.
pub const DEFAULT_DOMAIN: &str = "uavloc";
/// Longest accepted domain.
pub const MAX_DOMAIN_LEN: usize = 64;

/// A validated domain name (see the [module docs](self)).
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Domain(String);

impl Domain {
    /// Validates `name`: 1 to 64 characters of `[A-Za-z0-9_-]`.
    pub fn new(name: &str) -> Result<Self, ProtocolError> {
        let bad = |reason: String| ProtocolError::BadDomain { domain: name.to_owned(), reason };
        if name.is_empty() {
            return Err(bad("it is empty".into()));
        }
        if name.len() > MAX_DOMAIN_LEN {
            return Err(bad(format!("it has {} bytes, at most {MAX_DOMAIN_LEN} are allowed", name.len())));
        }
        if let Some(c) = name.chars().find(|c| !(c.is_ascii_alphanumeric() || *c == '_' || *c == '-')) {
            return Err(bad(format!("character {c:?} is not allowed (use A-Z, a-z, 0-9, '_' and '-')")));
        }
        Ok(Domain(name.to_owned()))
    }

    /// The domain from a `--domain` value if given, else from `UAVLOC_DOMAIN`, else the default.
    pub fn resolve(flag: Option<&str>) -> Result<Self, ProtocolError> {
        let env = std::env::var(DOMAIN_ENV).ok();
        Self::resolve_with(flag, env.as_deref())
    }

    /// [`resolve`](Self::resolve), its error naming where the bad name came from: `--domain` or
    /// `UAVLOC_DOMAIN`.
    pub fn resolve_named(flag: Option<&str>) -> Result<Self, String> {
        let source = if flag.is_some() { "--domain" } else { DOMAIN_ENV };
        Self::resolve(flag).map_err(|e| format!("{source}: {e}"))
    }

    /// [`resolve`](Self::resolve) with the environment value passed in (for tests).
    pub fn resolve_with(flag: Option<&str>, env: Option<&str>) -> Result<Self, ProtocolError> {
        match (flag, env) {
            (Some(name), _) => Self::new(name),
            (None, Some(name)) if !name.is_empty() => Self::new(name),
            _ => Ok(Self::default()),
        }
    }

    /// The domain from a process's arguments (`--domain NAME` or `--domain=NAME`, the last one wins; other
    /// arguments are ignored), else from `UAVLOC_DOMAIN`, else the default. For processes without a full
    /// argument parser; with clap, take the flag there and call [`resolve`](Self::resolve).
    pub fn from_args<I, S>(args: I) -> Result<Self, ProtocolError>
    where
        I: IntoIterator<Item = S>,
        S: AsRef<str>,
    {
        let env = std::env::var(DOMAIN_ENV).ok();
        Self::from_args_with(args, env.as_deref())
    }

    /// [`from_args`](Self::from_args) with the environment value passed in (for tests).
    pub fn from_args_with<I, S>(args: I, env: Option<&str>) -> Result<Self, ProtocolError>
    where
        I: IntoIterator<Item = S>,
        S: AsRef<str>,
    {
        let mut flag: Option<String> = None;
        let mut args = args.into_iter();
        while let Some(arg) = args.next() {
            let arg = arg.as_ref();
            if arg == DOMAIN_FLAG {
                let value = args.next().ok_or_else(|| ProtocolError::BadDomain {
                    domain: String::new(),
                    reason: format!("{DOMAIN_FLAG} needs a value"),
                })?;
                flag = Some(value.as_ref().to_owned());
            } else if let Some(value) = arg.strip_prefix(DOMAIN_FLAG).and_then(|r| r.strip_prefix('=')) {
                flag = Some(value.to_owned());
            }
        }
        Self::resolve_with(flag.as_deref(), env)
    }

    /// The name.
    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl Default for Domain {
    fn default() -> Self {
        Domain(DEFAULT_DOMAIN.to_owned())
    }
}

impl fmt::Display for Domain {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl FromStr for Domain {
    type Err = ProtocolError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Domain::new(s)
    }
}

/// Topic of [`Measurement`](crate::Measurement)s: emitter-sim → estimator.
pub fn measurement(domain: &Domain) -> String {
    format!("{domain}/measurement")
}

/// Topic of [`Estimate`](crate::Estimate)s: estimator → planner, monitor.
pub fn estimate(domain: &Domain) -> String {
    format!("{domain}/estimate")
}

/// Topic of [`Command`](crate::Command)s: planner → emitter-sim, monitor.
pub fn command(domain: &Domain) -> String {
    format!("{domain}/command")
}

/// Topic of [`SwarmState`](crate::SwarmState)s: the MAVLink bridge → emitter-sim (`--uavs autopilots`),
/// the monitor and external front ends: the UAVs as their autopilots report them.
pub fn swarm(domain: &Domain) -> String {
    format!("{domain}/swarm")
}

/// Topic of [`Truth`](crate::Truth)s: emitter-sim → monitor only.
pub fn truth(domain: &Domain) -> String {
    format!("{domain}/truth")
}

/// Topic of [`Control`](crate::Control) messages: every process → every process (a process joining or
/// restarted, a swap's takeover, the end of the run).
pub fn control(domain: &Domain) -> String {
    format!("{domain}/control")
}

/// Topic of [`EstimatorState`](crate::EstimatorState) messages: monitor → estimator, the states the
/// estimator asks for ([`ControlKind::State`](crate::ControlKind::State)).
pub fn state(domain: &Domain) -> String {
    format!("{domain}/state")
}

/// Topic of [`Measurement`](crate::Measurement) copies the monitor gives again with an external front
/// end: monitor → estimator, the measurement of a step whose estimate or command was lost (a crashed
/// estimator or planner), as the monitor recorded it. A front end measures each step once; emitter-sim's
/// replays make this topic unnecessary with the simulator.
pub fn measurement_replay(domain: &Domain) -> String {
    format!("{domain}/measurement-replay")
}

/// All service names of a domain, with a short label each.
pub fn all(domain: &Domain) -> [(&'static str, String); 7] {
    [
        ("measurement", measurement(domain)),
        ("measurement-replay", measurement_replay(domain)),
        ("estimate", estimate(domain)),
        ("command", command(domain)),
        ("truth", truth(domain)),
        ("control", control(domain)),
        ("state", state(domain)),
    ]
}

/// The payload service of `uavloc bench ipc`'s sweep `tag` (`[u8]` samples, sender → echo).
pub fn sweep_data(tag: &str) -> String {
    format!("{tag}/data")
}

/// The acknowledgement service of `uavloc bench ipc`'s sweep `tag` (echo → sender).
pub fn sweep_ack(tag: &str) -> String {
    format!("{tag}/ack")
}

/// The iceoryx2 node name of a process role in a domain, e.g. `uavloc/estimator` (shown by `iox2 node list`).
pub fn node_name(domain: &Domain, role: &str) -> String {
    format!("{domain}/{role}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_have_domain_prefix() {
        let d = Domain::new("run-7_a").unwrap();
        assert_eq!(measurement(&d), "run-7_a/measurement");
        assert_eq!(estimate(&d), "run-7_a/estimate");
        assert_eq!(command(&d), "run-7_a/command");
        assert_eq!(truth(&d), "run-7_a/truth");
        assert_eq!(control(&d), "run-7_a/control");
        assert_eq!(node_name(&d, "planner"), "run-7_a/planner");
        let names = all(&Domain::default());
        assert_eq!(names[0].1, "uavloc/measurement");
        for (i, (_, a)) in names.iter().enumerate() {
            assert!(names[i + 1..].iter().all(|(_, b)| a != b), "distinct");
            assert!(iceoryx2::prelude::ServiceName::new(a).is_ok(), "{a} is a valid ServiceName");
        }
        let longest = Domain::new(&"x".repeat(MAX_DOMAIN_LEN)).unwrap();
        assert!(iceoryx2::prelude::ServiceName::new(&measurement(&longest)).is_ok());
        assert!(iceoryx2::prelude::NodeName::new(&node_name(&longest, "emitter-sim")).is_ok());
    }

    #[test]
    fn validates_domain() {
        assert!(Domain::new("uavloc").is_ok());
        assert!(Domain::new(&"a".repeat(64)).is_ok());
        for bad in ["", "a/b", "a b", "ü", "x.y", "semi;colon"] {
            let err = Domain::new(bad).unwrap_err();
            assert!(matches!(err, ProtocolError::BadDomain { .. }), "{bad:?}");
            assert!(err.to_string().contains("invalid domain"), "{err}");
        }
        let long = Domain::new(&"a".repeat(65)).unwrap_err().to_string();
        assert!(long.contains("at most 64"), "{long}");
        assert!(Domain::new("a/b").unwrap_err().to_string().contains("'/'"));
        assert_eq!("abc".parse::<Domain>().unwrap().as_str(), "abc");
    }

    #[test]
    fn resolves_flag_then_env_then_default() {
        assert_eq!(Domain::resolve_with(Some("f"), Some("e")).unwrap().as_str(), "f");
        assert_eq!(Domain::resolve_with(None, Some("e")).unwrap().as_str(), "e");
        assert_eq!(Domain::resolve_with(None, Some("")).unwrap().as_str(), DEFAULT_DOMAIN);
        assert_eq!(Domain::resolve_with(None, None).unwrap().as_str(), DEFAULT_DOMAIN);
        assert!(Domain::resolve_with(Some(""), None).is_err());
        assert!(Domain::resolve_with(None, Some("bad name")).is_err());
    }

    #[test]
    fn parses_args() {
        let args = |a: &[&str]| a.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        assert_eq!(Domain::from_args_with(args(&["prog", "--domain", "d1"]), Some("e")).unwrap().as_str(), "d1");
        assert_eq!(Domain::from_args_with(args(&["prog", "--domain=d2", "-v"]), None).unwrap().as_str(), "d2");
        assert_eq!(Domain::from_args_with(args(&["prog", "--seed", "3"]), Some("e")).unwrap().as_str(), "e");
        assert_eq!(Domain::from_args_with(args(&["prog"]), None).unwrap(), Domain::default());
        assert!(Domain::from_args_with(args(&["prog", "--domain"]), None).unwrap_err().to_string().contains("needs"));
        assert!(Domain::from_args_with(args(&["prog", "--domain=no/slash"]), None).is_err());
        assert!(Domain::from_args_with(["--domainx=a"], None).unwrap() == Domain::default());
    }
}
