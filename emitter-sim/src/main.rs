//! The `emitter-sim` process: owns the world (true emitter, UAV kinematics, TDOA noise), publishes a noisy
//! measurement per step and flies the planner's commands, in lock-step or in real time (`--mode`). The
//! loop lives in the library ([`emitter_sim::process`]); `uavloc process emitter-sim` runs the same code.

use clap::Parser;
use emitter_sim::args::{AFTER_HELP, EmitterSimArgs};
use emitter_sim::process::main_with;

/// The simulated world of the uavloc pipeline: publishes the truth and a noisy TDOA measurement per step,
/// waits for the planner's command for that step (lock-step; or until the next step is due, in real time),
/// flies it and exits after the last step.
#[derive(Parser, Debug)]
#[command(name = "emitter-sim", version, after_help = AFTER_HELP)]
struct Cli {
    #[command(flatten)]
    args: EmitterSimArgs,
}

fn main() -> std::process::ExitCode {
    main_with(&Cli::parse().args)
}
