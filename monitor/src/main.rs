//! The `monitor` process: subscribes to everything, shows the run live, logs it and writes the record and
//! plots at the end. The loop lives in the library ([`monitor::process`]); `uavloc process monitor` runs
//! the same code.

use clap::Parser;
use monitor::args::{AFTER_HELP, MonitorArgs};
use monitor::process::main_with;

/// The monitor of the uavloc pipeline: subscribes to every topic of a domain, shows one status line per
/// step (CRLB and RMSE at the truth, latencies, active planner, rejected messages), logs every event as
/// JSON lines and writes the run record, CSVs and plots when the last step is in.
#[derive(Parser, Debug)]
#[command(name = "monitor", version, after_help = AFTER_HELP)]
struct Cli {
    #[command(flatten)]
    args: MonitorArgs,
}

fn main() -> std::process::ExitCode {
    main_with(&Cli::parse().args)
}
