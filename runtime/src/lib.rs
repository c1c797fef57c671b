//! # uavloc-runtime — what every uavloc process runs on
//!
//! The part of a process that is not its handler: the event loop ([`node`]: one `WaitSet` over the
//! process's inputs, the control topic and its deadlines, calling the process's [`Handler`]), its flags
//! ([`args::LinkArgs`]; written back as a command line by [`flags`]), how it ends ([`exit`]:
//! [`ProcessError`] and the exit codes a supervisor acts on), what it tells its supervisor
//! ([`supervisor`]: typed stdout lines, written and read with one definition), the recovery rules with
//! what they keep ([`recovery`]: the meaning of a step, the state store, emitter-sim's snapshot file),
//! and the checks of output flags before a run ([`output`]). The wire format and the transports are
//! `uavloc-protocol`'s.

pub mod args;
pub mod exit;
pub mod flags;
pub mod log_budget;
pub mod node;
pub mod output;
pub mod recovery;
pub mod supervisor;

pub use args::{DEFAULT_SPIN_US, LinkArgs, NodeArgs, ProcessArgs, RunArgs, Source};
pub use exit::{Cause, EXIT_INTERRUPTED, EXIT_UNRECOVERABLE, ProcessError, cpu_seconds};
pub use log_budget::{Admit, LogBudget};
pub use node::{Ended, Flow, Handler, IDLE_WAKEUP, Join, Node};
pub use supervisor::{NodeSummary, Output, SupervisorLine, exit_with, fail, read_output, tell, tell_record};
