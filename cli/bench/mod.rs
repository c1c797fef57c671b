//! `uavloc bench`: latency of the process pipeline (per hop, per stage, end to end) over iceoryx2 and over
//! a Unix-domain-socket baseline, and the planner's compute time per objective and solver.

pub mod histogram;
pub mod ipc;
pub mod latency;
pub mod planner;
pub mod plot;
pub mod sys;

use clap::{Args, Subcommand};

pub const LONG_ABOUT: &str = "\
Benchmarks, measured with the real processes and the real transports (no timing inside tests):

  latency   one run of the process set pinned to --cores: per hop, per compute stage and end to end
            (p50/p90/p99/p99.9/max µs from the stamps in the messages), CPU per process, lost messages
  compare   every transport (iceoryx2, uds) × wait mode (block, spin-then-block, spin) back to back in
            one invocation, with the iceoryx2/uds ratios per percentile and the goals met or missed
  planner   the planning step's compute time per objective and solver, beside the paper's Table 7
  ipc       a payload-size sweep between two pinned processes: iceoryx2 written in place (zero-copy)
            against a Unix stream socket, one-way latency p50/p99 and CPU per message

See BENCHMARKS.md for the figures of this machine and how to reproduce them.";

/// Flags of `uavloc bench`.
#[derive(Args, Debug, Clone, PartialEq)]
pub struct BenchArgs {
    #[command(subcommand)]
    pub what: BenchCommand,
}

/// The benchmarks.
#[derive(Subcommand, Debug, Clone, PartialEq)]
pub enum BenchCommand {
    /// Latency of one transport × wait mode: per hop, per stage, end to end, CPU per process.
    #[command(long_about = latency::LONG_ABOUT, after_help = latency::AFTER_HELP)]
    Latency(latency::LatencyArgs),
    /// Every transport × wait mode back to back, with iceoryx2/uds ratios per percentile.
    #[command(long_about = latency::LONG_ABOUT, after_help = latency::AFTER_HELP)]
    Compare(latency::CompareArgs),
    /// Compute time of the planning step per objective and solver (median, p99), beside the paper.
    #[command(long_about = planner::LONG_ABOUT, after_help = planner::AFTER_HELP)]
    Planner(planner::PlannerBenchArgs),
    /// Payload-size sweep between two pinned processes: iceoryx2 zero-copy against a Unix stream socket.
    #[command(long_about = ipc::LONG_ABOUT, after_help = ipc::AFTER_HELP)]
    Ipc(ipc::IpcArgs),
}
