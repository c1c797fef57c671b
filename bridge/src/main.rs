//! The `bridge` process: flies the planner's commands on real autopilots over MAVLink and publishes
//! the swarm's reported state. The loop lives in the library ([`bridge::process`]); `uavloc process
//! bridge` runs the same code.

use bridge::args::{AFTER_HELP, BridgeArgs};
use bridge::process::main_with;
use clap::Parser;

/// The MAVLink bridge of the uavloc pipeline: one MAVLink 2 link per UAV; every command becomes a
/// guided position target per UAV, streamed to its autopilot, and the autopilots' positions go back
/// on the swarm topic.
#[derive(Parser, Debug)]
#[command(name = "bridge", version, after_help = AFTER_HELP)]
struct Cli {
    #[command(flatten)]
    args: BridgeArgs,
}

fn main() -> std::process::ExitCode {
    main_with(&Cli::parse().args)
}
