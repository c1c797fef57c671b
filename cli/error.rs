//! The CLI's error type and its exit codes.

use std::process::ExitCode;

use thiserror::Error;

/// Exit code for bad input (same as clap's usage errors).
pub const EXIT_INPUT: u8 = 2;
/// Exit code for a computation that ran but produced no usable answer.
pub const EXIT_FAILED: u8 = 1;

/// Why a subcommand refused to answer. Displayed after `error: ` as one line.
#[derive(Debug, Error)]
pub enum CliError {
    /// A flag value the maths core would accept but that is wrong for the command line
    /// (wrong count, σ ≤ 0, …). The message names the flag.
    #[error("{0}")]
    Input(String),
    /// Bad input with the error that says why ([`std::error::Error::source`]): `context` names the flag
    /// (and file); the message is the context and the cause's, on one line.
    #[error("{context}: {source}")]
    InputBecause {
        /// The flag (and value or file) refused.
        context: String,
        /// Why.
        source: runtime::Cause,
    },
    /// A computation or an output that failed, with the error that caused it.
    #[error("{context}: {source}")]
    FailedBecause {
        /// What was being done.
        context: String,
        /// What failed.
        source: runtime::Cause,
    },
    /// The maths core refused the input; `context` names the flag when it is known.
    #[error("{}{err}", context.as_ref().map(|c| format!("{c}: ")).unwrap_or_default())]
    Tdoa { context: Option<String>, err: tdoa::TdoaError },
    /// The computation ran but gave no usable answer (e.g. every Monte Carlo draw failed).
    #[error("{0}")]
    Failed(String),
}

impl CliError {
    /// The process exit code for this error: 2 for bad input, 1 for a failed computation.
    pub fn exit_code(&self) -> ExitCode {
        ExitCode::from(self.code())
    }

    /// The numeric exit code.
    pub fn code(&self) -> u8 {
        match self {
            CliError::Input(_) | CliError::InputBecause { .. } | CliError::Tdoa { .. } => EXIT_INPUT,
            CliError::Failed(_) | CliError::FailedBecause { .. } => EXIT_FAILED,
        }
    }

    /// Bad input `context` (a flag, a file) refused because of `cause`.
    pub fn input_because(context: impl Into<String>, cause: impl Into<runtime::Cause>) -> Self {
        CliError::InputBecause { context: context.into(), source: cause.into() }
    }

    /// A failure of `context` (what was being done) caused by `cause`.
    pub fn failed_because(context: impl Into<String>, cause: impl Into<runtime::Cause>) -> Self {
        CliError::FailedBecause { context: context.into(), source: cause.into() }
    }

    /// Wraps a maths-core error with the flag (and value) it came from.
    pub fn tdoa_in(context: impl Into<String>) -> impl FnOnce(tdoa::TdoaError) -> CliError {
        let context = context.into();
        move |err| CliError::Tdoa { context: Some(context), err }
    }
}

impl From<tdoa::TdoaError> for CliError {
    fn from(err: tdoa::TdoaError) -> Self {
        CliError::Tdoa { context: None, err }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A refused file keeps the system's error as its cause, with exit code 2 and one line naming it.
    #[test]
    fn a_cause_is_kept_with_its_exit_code() {
        let io = std::fs::read_to_string("/nonexistent-of-uavloc/x.toml").unwrap_err();
        let e = CliError::input_because("--scenario /nonexistent-of-uavloc/x.toml", io);
        assert_eq!(e.code(), EXIT_INPUT);
        assert!(e.to_string().starts_with("--scenario /nonexistent-of-uavloc/x.toml: "), "{e}");
        assert!(!e.to_string().contains('\n'));
        let cause = std::error::Error::source(&e).and_then(|s| s.downcast_ref::<std::io::Error>()).unwrap();
        assert_eq!(cause.kind(), std::io::ErrorKind::NotFound);
        assert_eq!(CliError::failed_because("--out d", String::from("disk full")).code(), EXIT_FAILED);
    }
}
