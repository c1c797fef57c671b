//! The `emitter-sim` process: owns the world (true emitter, UAV kinematics, TDOA noise) and publishes a noisy measurement per step.
//!
//! Its logic lives in this crate's library; the iceoryx2 wiring (subscribe → call the library → publish)
//! arrives with the process-pipeline issue. Until then the binary only documents itself and refuses to
//! run, so a launcher or systemd unit never mistakes it for a working process.

use clap::Parser;

/// owns the world (true emitter, UAV kinematics, TDOA noise) and publishes a noisy measurement per step.
#[derive(Parser, Debug)]
#[command(
    name = "emitter-sim",
    version,
    after_help = "Not wired to iceoryx2 yet (process-pipeline issue). For the same loop in one process: `uavloc simulate`."
)]
struct Args {}

fn main() -> std::process::ExitCode {
    let _ = Args::parse();
    eprintln!(
        "error: the emitter-sim process is not wired to iceoryx2 yet; run `uavloc simulate` for the in-process loop"
    );
    std::process::ExitCode::from(2)
}
