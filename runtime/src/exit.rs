//! How a uavloc process (emitter-sim, estimator, planner, monitor) ends with an error, and its exit code.

use protocol::TransportError;

/// Exit code of a process stopped by SIGINT/SIGTERM before the end of its run.
pub const EXIT_INTERRUPTED: u8 = 130;

/// Exit code of a process whose run cannot go on ([`ProcessError::Unrecoverable`]): a supervisor must
/// not restart it.
pub const EXIT_UNRECOVERABLE: u8 = 3;

/// Why a process stopped with an error.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ProcessError {
    /// Bad flags or scenario (exit code 2).
    Input(String),
    /// A runtime failure: iceoryx2, a missing command, … (exit code 1). A supervisor restarts the process.
    Failed(String),
    /// The run cannot go on, and a restart would only repeat it: e.g. two UAVs collided, so the world
    /// cannot measure (exit code 3). A supervisor fails the run at once instead of restarting.
    Unrecoverable(String),
    /// SIGINT/SIGTERM (exit code 130).
    Interrupted,
}

impl ProcessError {
    /// The exit code: 2 bad input, 1 runtime failure, 3 unrecoverable run, 130 interrupted.
    pub fn code(&self) -> u8 {
        match self {
            ProcessError::Input(_) => 2,
            ProcessError::Failed(_) => 1,
            ProcessError::Unrecoverable(_) => EXIT_UNRECOVERABLE,
            ProcessError::Interrupted => EXIT_INTERRUPTED,
        }
    }
}

impl std::fmt::Display for ProcessError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ProcessError::Input(m) | ProcessError::Failed(m) | ProcessError::Unrecoverable(m) => f.write_str(m),
            ProcessError::Interrupted => f.write_str("interrupted by a signal"),
        }
    }
}

impl std::error::Error for ProcessError {}

impl From<TransportError> for ProcessError {
    fn from(e: TransportError) -> Self {
        match e {
            TransportError::Interrupted => ProcessError::Interrupted,
            TransportError::Environment(why) => ProcessError::Input(why),
            e => ProcessError::Failed(e.to_string()),
        }
    }
}

/// CPU time this process has used so far (user + system, all threads), seconds; reported in every
/// process's summary line.
pub fn cpu_seconds() -> f64 {
    protocol::cpu_ns() as f64 * 1e-9
}
