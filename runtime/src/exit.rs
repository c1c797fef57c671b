//! How a uavloc process (emitter-sim, estimator, planner, monitor) ends with an error, and its exit code.

use protocol::TransportError;

/// Exit code of a process stopped by SIGINT/SIGTERM before the end of its run.
pub const EXIT_INTERRUPTED: u8 = 130;

/// Exit code of a process whose run cannot go on ([`ProcessError::Unrecoverable`]): a supervisor must
/// not restart it.
pub const EXIT_UNRECOVERABLE: u8 = 3;

/// A cause kept by a [`ProcessError`] (any error type of the crates below: scenario, I/O, maths, …).
pub type Cause = Box<dyn std::error::Error + Send + Sync + 'static>;

/// Why a process stopped with an error. A variant with a cause keeps it ([`std::error::Error::source`]);
/// its message is its context followed by the cause's, on one line.
#[derive(Debug, thiserror::Error)]
pub enum ProcessError {
    /// Bad flags or scenario (exit code 2).
    #[error("{0}")]
    Input(String),
    /// Bad flags or scenario, with the error that says why (exit code 2): e.g. the flag and the
    /// scenario's own error.
    #[error("{context}: {source}")]
    InputBecause {
        /// What was being read (e.g. `--scenario`).
        context: String,
        /// Why it was refused.
        source: Cause,
    },
    /// A runtime failure: a missing command, … (exit code 1). A supervisor restarts the process.
    #[error("{0}")]
    Failed(String),
    /// A runtime failure with the error that caused it (exit code 1).
    #[error("{context}: {source}")]
    FailedBecause {
        /// What was being done.
        context: String,
        /// What failed.
        source: Cause,
    },
    /// The transport failed (exit code 1): opening a service, sending, waiting.
    #[error(transparent)]
    Transport(TransportError),
    /// The run cannot go on, and a restart would only repeat it: e.g. two UAVs collided, so the world
    /// cannot measure (exit code 3). A supervisor fails the run at once instead of restarting.
    #[error("{0}")]
    Unrecoverable(String),
    /// The run cannot go on, with the error that says why (exit code 3): e.g. the step that could not be
    /// measured or planned, and the maths' own error.
    #[error("{context}: {source}{consequence}")]
    UnrecoverableBecause {
        /// What was being done (e.g. `step 7: no plan for the estimate at (…)`).
        context: String,
        /// Why it failed.
        source: Cause,
        /// What the run does about it (e.g. ` — the run cannot go on`), said after the cause.
        consequence: &'static str,
    },
    /// SIGINT/SIGTERM (exit code 130).
    #[error("interrupted by a signal")]
    Interrupted,
}

impl ProcessError {
    /// The exit code: 2 bad input, 1 runtime failure, 3 unrecoverable run, 130 interrupted.
    pub fn code(&self) -> u8 {
        match self {
            ProcessError::Input(_) | ProcessError::InputBecause { .. } => 2,
            ProcessError::Failed(_) | ProcessError::FailedBecause { .. } | ProcessError::Transport(_) => 1,
            ProcessError::Unrecoverable(_) | ProcessError::UnrecoverableBecause { .. } => EXIT_UNRECOVERABLE,
            ProcessError::Interrupted => EXIT_INTERRUPTED,
        }
    }

    /// Bad input `context` (e.g. a flag) refused because of `cause`.
    pub fn input_because(context: impl Into<String>, cause: impl Into<Cause>) -> Self {
        ProcessError::InputBecause { context: context.into(), source: cause.into() }
    }

    /// The run cannot go on: `context` (what was being done) failed because of `cause`, and the run does
    /// `consequence` (a clause said after the cause).
    pub fn unrecoverable_because(
        context: impl Into<String>,
        cause: impl Into<Cause>,
        consequence: &'static str,
    ) -> Self {
        ProcessError::UnrecoverableBecause { context: context.into(), source: cause.into(), consequence }
    }

    /// A failure of `context` (what was being done) caused by `cause`.
    pub fn failed_because(context: impl Into<String>, cause: impl Into<Cause>) -> Self {
        ProcessError::FailedBecause { context: context.into(), source: cause.into() }
    }
}

impl From<TransportError> for ProcessError {
    fn from(e: TransportError) -> Self {
        match e {
            TransportError::Interrupted => ProcessError::Interrupted,
            TransportError::Environment(why) => ProcessError::Input(why),
            e => ProcessError::Transport(e),
        }
    }
}

/// CPU time this process has used so far (user + system, all threads), seconds; reported in every
/// process's summary line.
pub fn cpu_seconds() -> f64 {
    protocol::cpu_ns() as f64 * 1e-9
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::error::Error as _;

    fn io_cause() -> std::io::Error {
        std::io::Error::new(std::io::ErrorKind::PermissionDenied, "no access")
    }

    #[test]
    fn a_cause_is_kept_and_said() {
        let e = ProcessError::input_because("--log /x", io_cause());
        assert_eq!(e.code(), 2);
        assert_eq!(e.to_string(), "--log /x: no access");
        let cause = e.source().and_then(|s| s.downcast_ref::<std::io::Error>()).expect("the I/O error kept");
        assert_eq!(cause.kind(), std::io::ErrorKind::PermissionDenied);
        let e = ProcessError::failed_because("step 3", String::from("out of range"));
        assert_eq!((e.code(), e.to_string()), (1, "step 3: out of range".to_string()));
        assert!(e.source().is_some());
        let e = ProcessError::unrecoverable_because("step 4: measurement", io_cause(), "; the run cannot go on");
        assert_eq!((e.code(), e.to_string()), (3, "step 4: measurement: no access; the run cannot go on".to_string()));
        assert!(e.source().and_then(|s| s.downcast_ref::<std::io::Error>()).is_some());
        // The transport's failures keep their variant; an interruption and a bad environment map to theirs.
        let t = TransportError::Failed { op: "opening", service: "d/measurement".into(), detail: "busy".into() };
        assert!(matches!(ProcessError::from(t.clone()), ProcessError::Transport(ref k) if *k == t));
        assert_eq!(ProcessError::from(t).code(), 1);
        assert!(matches!(ProcessError::from(TransportError::Interrupted), ProcessError::Interrupted));
        assert_eq!(ProcessError::from(TransportError::Environment("UAVLOC_UDS_DIR".into())).code(), 2);
    }
}
