//! The children of a launch: their flags, built from the launch's, and their start in order.

use std::time::Duration;

use model::Scenario;
use protocol::services::Domain;
use runtime::flags::to_flags;

use super::args::LaunchArgs;
use super::role::Role;
use super::state_dir::StateDir;
use super::supervisor::Supervisor;
use crate::error::CliError;

/// The default value of every flag of a process's argument type (what its parser gives for no flags).
fn defaults<T: clap::Args + clap::FromArgMatches>() -> T {
    runtime::flags::from_flags(&[]).expect("every flag of a process has a default or is optional")
}

/// The command line of `role` in this launch, built from the role's own argument type.
pub(super) fn child_flags(
    role: Role,
    args: &LaunchArgs,
    sc: &Scenario,
    domain: &Domain,
    state: &StateDir,
    log: &std::path::Path,
) -> Result<Vec<String>, CliError> {
    let node = |quiet| runtime::NodeArgs {
        domain: Some(domain.to_string()),
        link: args.link,
        quiet,
        supervised: false,
        watch_pid: None,
    };
    let run = runtime::RunArgs { scenario: args.run.scenario.clone(), steps: args.run.steps, seed: args.run.seed };
    let flags = match role {
        Role::Monitor => to_flags(&monitor::args::MonitorArgs {
            source: args.source,
            mcap: args.record.as_ref().map(|p| std::path::absolute(p).unwrap_or_else(|_| p.clone())),
            stamps: args.stamps.clone(),
            process: runtime::ProcessArgs { node: node(args.headless || args.live), run: run.clone() },
            log: Some(log.to_path_buf()),
            out: args.out.clone(),
            links: !args.autopilots.is_empty(),
            ..defaults()
        }),
        Role::Planner => to_flags(&planner::args::PlannerArgs {
            process: runtime::ProcessArgs { node: node(true), run: run.clone() },
            objective: args.run.objective,
            solver: args.run.solver,
            estimate_deadline_ms: args.estimate_deadline_ms,
            plan_delay_ms: args.plan_delay_ms,
            plan_delay_steps: if args.plan_delay_ms > 0 { args.plan_delay_steps.clone() } else { Vec::new() },
            // Aircraft: a quiet link's reach widens the safety margins.
            stated_position_margins: !args.autopilots.is_empty(),
            ..defaults()
        }),
        Role::Estimator => to_flags(&estimator::args::EstimatorArgs {
            estimator: sc.estimator,
            emitter_model: sc.emitter_model,
            process_noise_accel: sc.process_noise_accel,
            velocity_prior_sigma: sc.velocity_prior_sigma,
            interval_s: sc.dt,
            node: node(true),
            ..defaults()
        }),
        Role::Bridge => to_flags(&bridge::args::BridgeArgs {
            process: runtime::ProcessArgs { node: node(true), run },
            ..bridge_args(args)
        }),
        Role::EmitterSim => to_flags(&emitter_sim::args::EmitterSimArgs {
            process: runtime::ProcessArgs { node: node(true), run },
            // The world's snapshots: the one file of the recovery (the estimator and the planner keep no
            // state, it rides the messages; the monitor's is its log; see `runtime::recovery`).
            checkpoint: Some(state.path("emitter-sim.ckpt")),
            ..emitter_args(args)
        }),
    };
    flags.map_err(|e| CliError::input_because(format!("{role}"), e))
}

/// emitter-sim's flags in this launch, but its node (domain, link) and checkpoint file.
pub(super) fn emitter_args(args: &LaunchArgs) -> emitter_sim::args::EmitterSimArgs {
    emitter_sim::args::EmitterSimArgs {
        command_timeout_s: args.command_timeout_s,
        retry_interval_ms: args.retry_interval_ms,
        // The estimator and the monitor.
        min_subscribers: 2,
        step_delay_ms: args.step_delay_ms,
        mode: args.mode,
        time_scale: args.time_scale,
        // Stays after the last step to replay it to a monitor behind.
        linger: true,
        uavs: if args.autopilots.is_empty() {
            emitter_sim::args::UavSource::World
        } else {
            emitter_sim::args::UavSource::Autopilots
        },
        ..defaults()
    }
}

/// The bridge's flags in this launch (aircraft, `--autopilot`), but its node and run.
pub(super) fn bridge_args(args: &LaunchArgs) -> bridge::args::BridgeArgs {
    bridge::args::BridgeArgs {
        autopilots: args.autopilots.clone(),
        // The autopilots' simulated time runs with the world's.
        time_scale: args.time_scale.unwrap_or(1.0),
        ..defaults()
    }
}

/// Starts the children in order, each after the previous one is ready, and waits for the end of the run.
pub(super) fn start_and_run(
    sup: &mut Supervisor,
    args: &LaunchArgs,
    sc: &Scenario,
    domain: &Domain,
    state: &StateDir,
    log: &std::path::Path,
) -> Result<(), CliError> {
    for role in Role::started(args.source, !args.autopilots.is_empty()) {
        if role == Role::EmitterSim && args.idle_probe_ms > 0 {
            let idle: Vec<(String, u32)> = sup.procs.iter().map(|p| (p.role.to_string(), p.child.id())).collect();
            sup.idle_cpu = crate::bench::sys::idle_cpu(&idle, Duration::from_millis(args.idle_probe_ms));
        }
        sup.spawn(role, child_flags(role, args, sc, domain, state, log)?)?;
        sup.wait_ready(role)?;
    }
    if args.source == runtime::Source::External {
        let d = domain.as_str();
        protocol::log_line!(
            "launch: estimator, planner and monitor are ready in domain {d}; waiting for an external front end to \
             publish {} (steps 0..={}) on {}/measurement and read {} on {}/command (docs/wire-format.md). Ctrl-C \
             stops the run.",
            <protocol::Measurement as protocol::Message>::TYPE_NAME,
            sc.steps,
            d,
            <protocol::Command as protocol::Message>::TYPE_NAME,
            d
        );
    }
    let grace = super::supervisor::EndGrace::new(Duration::from_secs_f64(args.command_timeout_s), sc.steps);
    if !args.live {
        return sup.wait_for_the_end(grace, &mut |_| {});
    }
    // The live view: the monitor's log as it grows, the children as the supervisor sees them; `q` stops.
    let mut terminal = crate::live::LiveTerminal::start().map_err(|e| CliError::failed_because("the live view", e))?;
    let title = format!("launch {domain} ({})", args.source);
    let mut view = crate::live::LiveState::new(title, sc.steps as u64, sc.l_min).with_bound(sc);
    let mut tail = crate::live::LogTail::new(log);
    let mut on_tick = |sup: &Supervisor| {
        for line in tail.poll() {
            if let Ok(event) = serde_json::from_str::<serde_json::Value>(&line) {
                view.apply_event(&event);
            }
        }
        view.processes = sup.process_rows();
        let _ = terminal.draw(&view);
        if terminal.quit_pressed(Duration::ZERO) {
            super::signals::stop_requested_by_user();
        }
    };
    sup.wait_for_the_end(grace, &mut on_tick)
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;

    /// Each process's own flags round-trip (tested beside its argument type); here the launch's children:
    /// every one parses the command line the launch builds for it (no flag it does not know).
    #[test]
    fn every_child_parses_its_command_line() {
        #[derive(Parser)]
        struct Cli {
            #[command(subcommand)]
            process: crate::process_cmd::ProcessRole,
        }
        // With aircraft, so that the bridge is a child too.
        let args = LaunchArgs {
            autopilots: vec![
                "udpin:127.0.0.1:14550".into(),
                "tcpout:10.0.0.2:5760".into(),
                "serial:/dev/ttyACM0:57600".into(),
            ],
            ..LaunchArgs::try_parse_from_defaults()
        };
        let sc = Scenario::default();
        let domain = Domain::new("t").unwrap();
        let state = StateDir::create(&domain).unwrap();
        for role in Role::START_ORDER {
            let flags = child_flags(role, &args, &sc, &domain, &state, std::path::Path::new("log.jsonl")).unwrap();
            let line = ["uavloc".to_string(), role.name().to_string()].into_iter().chain(flags.clone());
            assert!(Cli::try_parse_from(line).is_ok(), "{role}: {flags:?}");
        }
    }
}
