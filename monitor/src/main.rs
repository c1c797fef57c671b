//! The `monitor` process: subscribes to everything, shows the run live, logs it and plots it at the end.
//!
//! Its logic lives in this crate's library; the iceoryx2 wiring (subscribe → call the library → publish)
//! arrives with the process-pipeline issue. Until then the binary only documents itself and refuses to
//! run, so a launcher or systemd unit never mistakes it for a working process.

use clap::Parser;

/// subscribes to everything, shows the run live, logs it and plots it at the end.
#[derive(Parser, Debug)]
#[command(
    name = "monitor",
    version,
    after_help = "Not wired to iceoryx2 yet (process-pipeline issue). For the same loop in one process: `uavloc simulate`."
)]
struct Args {}

fn main() -> std::process::ExitCode {
    let _ = Args::parse();
    eprintln!("error: the monitor process is not wired to iceoryx2 yet; run `uavloc simulate` for the in-process loop");
    std::process::ExitCode::from(2)
}
