//! # uavloc-monitor — the monitor process of uavloc
//!
//! The pipeline's observer: [`assemble`] rebuilds each step's record from the pipeline's messages (no
//! IPC), [`process`] is its handler on the node runtime over what it keeps of the run (`session`, also
//! without IPC; with [`runlog`], [`stamps`] and [`latency`]: its log, stamp file and latency
//! statistics), [`front_end`] tells whether an external front end is still there; [`args`] is its
//! command line and [`summary`] its `summary` line. The run record, its metrics, files, plots and MCAP
//! recording are the library crate `uavloc-record`.

/// The role name (node name suffix, `uavloc process monitor`).
pub const ROLE: &str = "monitor";

pub mod args;
pub mod assemble;
pub mod front_end;
pub mod latency;
mod lines;
pub mod process;
pub mod runlog;
mod session;
pub mod stamps;
mod status;
pub mod summary;

pub use assemble::{Assembler, CompletedStep};
