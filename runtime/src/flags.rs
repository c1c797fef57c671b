//! Command lines built from a process's own argument type, so a supervisor never spells a child's flags
//! itself: the type that parses them (clap) also writes them ([`to_flags`], through its `Serialize`
//! derive), and a round-trip test of each type (`parse(to_flags(a)) == a`) keeps the two from drifting
//! apart.
//!
//! The rules, which every argument type follows: a field `foo_bar` is the flag `--foo-bar=value` (clap's
//! default `long`; one argument with `=`, so a value that begins with `-` is never taken for a flag); a
//! flattened group (`#[command(flatten)]`) is `#[serde(flatten)]`; a value is written as clap parses it —
//! numbers in full precision (`f64` as the shortest text that parses back to the same bits; every `f64`
//! flag is marked [`finite`], so a NaN is an error, not a flag left out), enums by their flag name
//! ([`display`]), lists comma-joined; `true` is the bare switch, and `false`, `None` and an empty list are
//! left out.

use std::fmt::Display;

use serde::{Serialize, Serializer};
use serde_json::Value;

/// The command line of `args`: `--name=value` per field set (see the module docs). An error only for a
/// type that breaks the rules (not a flat record of values), which the round-trip tests catch.
pub fn to_flags(args: &impl Serialize) -> Result<Vec<String>, String> {
    let Value::Object(fields) = serde_json::to_value(args).map_err(|e| e.to_string())? else {
        return Err("argument type is not a record of flags".into());
    };
    let mut out = Vec::new();
    for (name, value) in fields {
        let flag = format!("--{}", name.replace('_', "-"));
        let text = match value {
            Value::Null | Value::Bool(false) => continue,
            Value::Bool(true) => {
                out.push(flag);
                continue;
            }
            Value::Array(items) if items.is_empty() => continue,
            Value::Array(items) => items.iter().map(scalar).collect::<Result<Vec<_>, _>>()?.join(","),
            other => scalar(&other)?,
        };
        out.push(format!("{flag}={text}"));
    }
    Ok(out)
}

/// `T` parsed from `flags` by its own parser (clap): the other way of [`to_flags`]; no flags give every
/// flag's default.
pub fn from_flags<T: clap::Args + clap::FromArgMatches>(flags: &[String]) -> Result<T, clap::Error> {
    let matches = T::augment_args(clap::Command::new("flags"))
        .try_get_matches_from(std::iter::once("flags").chain(flags.iter().map(String::as_str)))?;
    T::from_arg_matches(&matches)
}

/// `args` written as flags ([`to_flags`]) and parsed back ([`from_flags`]): what a child given `args` runs
/// with. Each process's round-trip test asserts that it equals `args` (nothing lost on the way).
pub fn round_trip<T: Serialize + clap::Args + clap::FromArgMatches>(args: &T) -> Result<T, String> {
    from_flags(&to_flags(args)?).map_err(|e| e.to_string())
}

fn scalar(v: &Value) -> Result<String, String> {
    match v {
        Value::String(s) => Ok(s.clone()),
        Value::Number(n) => Ok(n.to_string()),
        other => Err(format!("not a flag value: {other}")),
    }
}

/// `#[serde(serialize_with = "runtime::flags::finite")]` on every `f64` flag: a NaN or an infinity is an
/// error. (Serialized plainly it would become JSON `null`, indistinguishable from an absent value, and
/// the child would silently take its default.)
pub fn finite<S: Serializer>(value: &f64, s: S) -> Result<S::Ok, S::Error> {
    if value.is_finite() {
        s.serialize_f64(*value)
    } else {
        Err(serde::ser::Error::custom(format!("a flag value must be a finite number, got {value}")))
    }
}

/// [`finite`] for an optional value.
pub fn finite_opt<S: Serializer>(value: &Option<f64>, s: S) -> Result<S::Ok, S::Error> {
    match value {
        Some(v) => finite(v, s),
        None => s.serialize_none(),
    }
}

/// `#[serde(serialize_with = "runtime::flags::display")]`: a value written as its `Display` text (an
/// enum's flag name).
pub fn display<T: Display, S: Serializer>(value: &T, s: S) -> Result<S::Ok, S::Error> {
    s.collect_str(value)
}

/// [`display`] for an optional value.
pub fn display_opt<T: Display, S: Serializer>(value: &Option<T>, s: S) -> Result<S::Ok, S::Error> {
    match value {
        Some(v) => s.collect_str(v),
        None => s.serialize_none(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Serialize)]
    struct Inner {
        seed: Option<u64>,
        steps: Option<usize>,
    }

    #[derive(Serialize)]
    struct Example {
        domain: String,
        time_scale: f64,
        #[serde(flatten)]
        inner: Inner,
        quiet: bool,
        linger: bool,
        plan_delay_steps: Vec<u64>,
        none: Vec<u64>,
        #[serde(serialize_with = "display")]
        mode: std::net::Ipv4Addr,
    }

    #[derive(Serialize)]
    struct Floats {
        #[serde(serialize_with = "finite")]
        x: f64,
        #[serde(serialize_with = "finite_opt")]
        y: Option<f64>,
    }

    #[test]
    fn builds_the_command_line() {
        let e = Example {
            domain: "lab".into(),
            time_scale: 0.1 + 0.2,
            inner: Inner { seed: None, steps: Some(5) },
            quiet: true,
            linger: false,
            plan_delay_steps: vec![3, 5],
            none: vec![],
            mode: std::net::Ipv4Addr::LOCALHOST,
        };
        // The order of the flags is not part of the contract.
        let mut f = to_flags(&e).unwrap();
        f.sort();
        let mut want = [
            "--domain=lab",
            "--time-scale=0.30000000000000004",
            "--steps=5",
            "--quiet",
            "--plan-delay-steps=3,5",
            "--mode=127.0.0.1",
        ];
        want.sort();
        assert_eq!(f, want);
        assert_eq!("0.30000000000000004".parse::<f64>().unwrap(), 0.1 + 0.2);
        assert!(to_flags(&5).is_err());
        assert_eq!(to_flags(&Floats { x: -1.5, y: None }).unwrap(), ["--x=-1.5"]);
        for (x, y) in [(f64::NAN, None), (1.0, Some(f64::INFINITY)), (f64::NEG_INFINITY, Some(1.0))] {
            assert!(to_flags(&Floats { x, y }).unwrap_err().contains("finite"), "{x} {y:?}");
        }
        assert!(to_flags(&vec![vec![1]]).is_err());
    }
}
