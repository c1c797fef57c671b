//! The `planner` process: plans one heading per UAV on each estimate (PSO/GA/ACO over the chosen
//! objective) and publishes the command. The loop lives in the library ([`planner::process`]); `uavloc
//! process planner` runs the same code.

use clap::Parser;
use planner::args::{AFTER_HELP, PlannerArgs};
use planner::process::main_with;

/// The planner process of the uavloc pipeline: on each estimate, plans one heading per UAV (the chosen
/// objective minimised by PSO, GA or ACO under the motion constraints) and publishes the command.
#[derive(Parser, Debug)]
#[command(name = "planner", version, after_help = AFTER_HELP)]
struct Cli {
    #[command(flatten)]
    args: PlannerArgs,
}

fn main() -> std::process::ExitCode {
    main_with(&Cli::parse().args)
}
