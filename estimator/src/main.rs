//! The `estimator` process: runs Chan's estimator on each measurement and publishes the estimate with its
//! covariance. The loop lives in the library ([`estimator::process`]); `uavloc process estimator` runs
//! the same code.

use clap::Parser;
use estimator::args::{AFTER_HELP, EstimatorArgs};
use estimator::process::main_with;

/// The estimator process of the uavloc pipeline: on each TDOA measurement, fixes the emitter with Chan's
/// method (the previous estimate as prior) and publishes the estimate with its covariance.
#[derive(Parser, Debug)]
#[command(name = "estimator", version, after_help = AFTER_HELP)]
struct Cli {
    #[command(flatten)]
    args: EstimatorArgs,
}

fn main() -> std::process::ExitCode {
    main_with(&Cli::parse().args)
}
