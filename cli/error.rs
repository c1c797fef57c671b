//! The CLI's error type and its exit codes.

use std::process::ExitCode;

use thiserror::Error;

/// Exit code for bad input (same as clap's usage errors).
pub const EXIT_INPUT: u8 = 2;
/// Exit code for a computation that ran but produced no usable answer.
pub const EXIT_FAILED: u8 = 1;

/// Why a subcommand refused to answer. Displayed after `error: ` as one line.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum CliError {
    /// A flag value the maths core would accept but that is wrong for the command line
    /// (wrong count, σ ≤ 0, …). The message names the flag.
    #[error("{0}")]
    Input(String),
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
            CliError::Input(_) | CliError::Tdoa { .. } => EXIT_INPUT,
            CliError::Failed(_) => EXIT_FAILED,
        }
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
