//! The planner's flags (`planner [FLAGS]`, `uavloc process planner [FLAGS]`) and the check of the
//! scenarios the process pipeline can run.

use clap::Args;

use model::scenario::{Scenario, TargetMode};
use planning::objective::ObjectiveKind;
use planning::solver::SolverKind;

/// What `planner --help` shows after the flags.
pub const AFTER_HELP: &str = "\
The planner subscribes to <domain>/estimate and publishes <domain>/command. Start it with the same
--scenario, --steps and --seed as emitter-sim (the scenario gives the motion, constraints, objective
and solver settings; the seed drives the MC samples and the solver). Only target = \"chan\" scenarios
are supported (controlled mode needs the truth, which only `uavloc simulate` can give the planner).

Examples:
  planner --domain lab1
  planner --domain lab1 --objective mc --solver ga --scenario scenarios/nominal.toml --seed 7
  planner --domain lab1 --estimate-deadline-ms 50   hold when a step's estimate is 50 ms late
  UAVLOC_DOMAIN=lab1 planner --spin-us 50";

/// Flags of the planner process (`planner [FLAGS]` or `uavloc process planner [FLAGS]`).
/// Also `Serialize`: [`runtime::flags::to_flags`] writes the command line of these flags.
#[derive(Args, serde::Serialize, Debug, Clone, PartialEq)]
pub struct PlannerArgs {
    /// The node (domain, link, quiet, supervised) and the run (scenario, steps, seed).
    #[command(flatten)]
    #[serde(flatten)]
    pub process: runtime::ProcessArgs,
    /// Planning objective: single | mc | analytical | cubature | formation.
    #[arg(long, default_value = "analytical")]
    #[serde(serialize_with = "runtime::flags::display")]
    pub objective: ObjectiveKind,
    /// Solver: gradient | pso | ga | aco (ignored by formation).
    #[arg(long, default_value = "gradient")]
    #[serde(serialize_with = "runtime::flags::display")]
    pub solver: SolverKind,
    /// Take over from the running planner at the next step (see `uavloc swap planner`).
    #[arg(long)]
    pub takeover: bool,
    /// Staleness deadline: when a step's estimate has not arrived this many milliseconds after its
    /// measurement, hold: the UAVs loiter on their backup circles (with `safety = "waypoints"` they hold
    /// course), flagged as a hold; the monitor shows `estimate_stale`. 0: no deadline (wait for every estimate; what lock-step reproductions need).
    #[arg(long, value_name = "MS", default_value_t = 0)]
    pub estimate_deadline_ms: u64,
    /// Test / fault-injection aid: sleep this many milliseconds before planning a step (see
    /// --plan-delay-steps), as a slow planner would; e.g. to make commands miss their step in emitter-sim's
    /// realtime mode. 0: no delay. The plan itself does not change.
    #[arg(long, value_name = "MS", default_value_t = 0)]
    pub plan_delay_ms: u64,
    /// Test / fault-injection aid: the steps --plan-delay-ms applies to, comma-separated (default: every
    /// step).
    #[arg(long, value_name = "K,..", value_delimiter = ',')]
    pub plan_delay_steps: Vec<u64>,
    /// Take each step's stated UAV position σ (the measurement's `position_sigmas`) into the safety
    /// margins when it exceeds the scenario's GNSS σ: with aircraft over MAVLink, a UAV whose link is quiet
    /// is stated with the σ of how far it may have flown since its last fix, so the certificate covers it
    /// or says it cannot. `uavloc launch --autopilot` passes it.
    #[arg(long)]
    pub stated_position_margins: bool,
}

/// Checks that the process pipeline can run `scenario` (also what `uavloc launch` checks): only
/// `target = "chan"`, because controlled mode needs the true emitter, which the planner never receives.
pub fn check_scenario(scenario: &Scenario) -> Result<(), String> {
    if scenario.target == TargetMode::Controlled {
        return Err("scenario key `target`: \"controlled\" is not supported by the process pipeline (it needs \
                    the true emitter, which the planner never receives); use `uavloc simulate` for controlled runs"
            .into());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_flags_round_trip() {
        let link = runtime::LinkArgs {
            transport: protocol::TransportKind::Iceoryx2,
            wait: Some(protocol::WaitMode::Block),
            spin_us: None,
        };
        let p = PlannerArgs {
            process: runtime::ProcessArgs {
                node: runtime::NodeArgs {
                    domain: Some("d".into()),
                    link,
                    quiet: false,
                    supervised: true,
                    watch_pid: Some(4242),
                },
                run: runtime::RunArgs { scenario: None, steps: Some(3), seed: None },
            },
            objective: ObjectiveKind::PosteriorCubature,
            solver: SolverKind::Aco,
            takeover: true,
            estimate_deadline_ms: 12,
            plan_delay_ms: 5,
            plan_delay_steps: vec![1, 4],
            stated_position_margins: true,
        };
        assert_eq!(runtime::flags::round_trip(&p).unwrap(), p);
    }
}
