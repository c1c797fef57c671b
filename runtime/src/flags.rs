//! Command lines built from a process's own argument type (`to_flags`), so a supervisor never spells a
//! child's flags itself: the type that parses them also writes them, and a round-trip test of each type
//! (`parse(to_flags(a)) == a`) keeps the two from drifting apart.

use std::fmt::Debug;
use std::path::Path;

/// Builds a command line flag by flag.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Flags(Vec<String>);

impl Flags {
    /// No flags.
    pub fn new() -> Self {
        Self::default()
    }

    /// `--name value` (any `Display`).
    pub fn value(mut self, name: &str, value: impl std::fmt::Display) -> Self {
        self.0.extend([name.to_string(), value.to_string()]);
        self
    }

    /// `--name value` with a float written so that it parses back to the same bits (`{:?}`).
    pub fn float(mut self, name: &str, value: f64) -> Self {
        self.0.extend([name.to_string(), format!("{value:?}")]);
        self
    }

    /// `--name value` when `value` is `Some`.
    pub fn opt(self, name: &str, value: Option<impl std::fmt::Display>) -> Self {
        match value {
            Some(v) => self.value(name, v),
            None => self,
        }
    }

    /// `--name path` when `path` is `Some`.
    pub fn path(self, name: &str, path: Option<&Path>) -> Self {
        self.opt(name, path.map(|p| p.display()))
    }

    /// `--name` when `on`.
    pub fn switch(mut self, name: &str, on: bool) -> Self {
        if on {
            self.0.push(name.to_string());
        }
        self
    }

    /// `--name a,b,c` when the list is not empty.
    pub fn list<T: Debug + std::fmt::Display>(mut self, name: &str, values: &[T]) -> Self {
        if !values.is_empty() {
            let joined: Vec<String> = values.iter().map(ToString::to_string).collect();
            self.0.extend([name.to_string(), joined.join(",")]);
        }
        self
    }

    /// These flags followed by `more`.
    pub fn extend(mut self, more: impl IntoIterator<Item = String>) -> Self {
        self.0.extend(more);
        self
    }

    /// The command line.
    pub fn into_vec(self) -> Vec<String> {
        self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builds_the_command_line() {
        let f = Flags::new()
            .value("--domain", "lab")
            .float("--time-scale", 0.1 + 0.2)
            .opt("--seed", None::<u64>)
            .opt("--steps", Some(5))
            .switch("--quiet", true)
            .switch("--linger", false)
            .list("--plan-delay-steps", &[3u64, 5])
            .list::<u64>("--none", &[])
            .into_vec();
        assert_eq!(
            f,
            [
                "--domain",
                "lab",
                "--time-scale",
                "0.30000000000000004",
                "--steps",
                "5",
                "--quiet",
                "--plan-delay-steps",
                "3,5"
            ]
        );
        assert_eq!("0.30000000000000004".parse::<f64>().unwrap(), 0.1 + 0.2);
    }
}
