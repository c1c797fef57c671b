//! `uavloc process <role>`: one pipeline process in this binary (what `uavloc launch` and `uavloc swap`
//! spawn: `uavloc` is a multi-call binary), and `uavloc process resources`.

use std::process::ExitCode;

use clap::{Args, Subcommand};
use protocol::resources;
use protocol::services::Domain;

use crate::error::CliError;

/// `uavloc process <role>`: runs one pipeline process in this binary (what `uavloc launch` spawns).
#[derive(Args, Debug, Clone, PartialEq)]
pub struct ProcessArgs {
    #[command(subcommand)]
    pub role: ProcessRole,
}

/// The processes `uavloc` can be.
#[derive(Subcommand, Debug, Clone, PartialEq)]
pub enum ProcessRole {
    /// The world: truth and a noisy measurement per step, flies each command (lock-step or real time).
    #[command(after_help = emitter_sim::args::AFTER_HELP)]
    EmitterSim(emitter_sim::args::EmitterSimArgs),
    /// Chan's estimator: an estimate per measurement.
    #[command(after_help = estimator::args::AFTER_HELP)]
    Estimator(estimator::args::EstimatorArgs),
    /// The planner: a command per estimate.
    #[command(after_help = planner::args::AFTER_HELP)]
    Planner(planner::args::PlannerArgs),
    /// The monitor: live view, event log, run record, plots.
    #[command(after_help = monitor::args::AFTER_HELP)]
    Monitor(monitor::args::MonitorArgs),
    /// The MAVLink bridge: each command to the UAVs' autopilots as guided targets, their positions back
    /// on the swarm topic.
    #[command(after_help = bridge::args::AFTER_HELP)]
    Bridge(bridge::args::BridgeArgs),
    /// Lists the iceoryx2 nodes and services of a domain as JSON (optionally removing dead nodes first).
    Resources(ResourcesArgs),
    /// The echo end of `uavloc bench ipc`.
    #[command(hide = true)]
    IpcEcho(crate::bench::ipc::EchoArgs),
}

/// Flags of `uavloc process resources`.
#[derive(Args, Debug, Clone, PartialEq)]
pub struct ResourcesArgs {
    /// The domain (default: $UAVLOC_DOMAIN, else "uavloc").
    #[arg(long, value_name = "NAME")]
    pub domain: Option<String>,
    /// Remove the stale resources of the domain's dead nodes before listing — and, when no node of the
    /// domain is alive, the services a killed run left half-created (what makes every open fail with
    /// HangsInCreation; `uavloc launch` does the same before it starts).
    #[arg(long)]
    pub remove_dead: bool,
}

/// Runs `uavloc process <role>`.
pub fn run_process(args: &ProcessArgs) -> ExitCode {
    match &args.role {
        ProcessRole::EmitterSim(a) => emitter_sim::process::main_with(a),
        ProcessRole::Estimator(a) => estimator::process::main_with(a),
        ProcessRole::Planner(a) => planner::process::main_with(a),
        ProcessRole::Monitor(a) => monitor::process::main_with(a),
        ProcessRole::Bridge(a) => bridge::process::main_with(a),
        ProcessRole::IpcEcho(a) => crate::bench::ipc::run_echo(a),
        ProcessRole::Resources(a) => {
            protocol::transport::quiet_logs();
            let listed = Domain::resolve(a.domain.as_deref())
                .map_err(|e| CliError::input_because("--domain", e))
                .and_then(|domain| {
                    if a.remove_dead {
                        let half = resources::remove_leftovers(&domain).map_err(CliError::Failed)?;
                        if !half.is_empty() {
                            protocol::log_line!("removed the half-created services {half:?}");
                        }
                    }
                    resources::list(&domain).map_err(CliError::Failed)
                });
            match listed {
                Ok(r) => {
                    println!("{}", serde_json::to_string_pretty(&r).unwrap_or_default());
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    protocol::log_line!("error: {e}");
                    e.exit_code()
                }
            }
        }
    }
}
