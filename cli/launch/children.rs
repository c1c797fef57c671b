//! The children of a launch: their flags, built from the launch's, and their start in order.

use std::time::Duration;

use planner::Scenario;
use protocol::services::Domain;
use runtime::flags::to_flags;

use super::args::LaunchArgs;
use super::role::Role;
use super::state_dir::StateDir;
use super::supervisor::{Supervisor, probe_idle_cpu};
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
    let node =
        |quiet| runtime::NodeArgs { domain: Some(domain.to_string()), link: args.link, quiet, supervised: false };
    let run = runtime::RunArgs { scenario: args.run.scenario.clone(), steps: args.run.steps, seed: args.run.seed };
    let flags = match role {
        Role::Monitor => to_flags(&monitor::args::MonitorArgs {
            source: args.source,
            mcap: args.record.as_ref().map(|p| std::path::absolute(p).unwrap_or_else(|_| p.clone())),
            stamps: args.stamps.clone(),
            process: runtime::ProcessArgs { node: node(args.headless || args.live), run: run.clone() },
            log: Some(log.to_path_buf()),
            out: args.out.clone(),
            ..defaults()
        }),
        Role::Planner => to_flags(&planner::args::PlannerArgs {
            process: runtime::ProcessArgs { node: node(true), run: run.clone() },
            objective: args.run.objective,
            solver: args.run.solver,
            estimate_deadline_ms: args.estimate_deadline_ms,
            plan_delay_ms: args.plan_delay_ms,
            plan_delay_steps: if args.plan_delay_ms > 0 { args.plan_delay_steps.clone() } else { Vec::new() },
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
        Role::EmitterSim => to_flags(&emitter_sim::args::EmitterSimArgs {
            process: runtime::ProcessArgs { node: node(true), run },
            // The world's snapshots: the one file of the recovery (the estimator and the planner keep no
            // state, it rides the messages; the monitor's is its log; see `runtime::recovery`).
            checkpoint: Some(state.path("emitter-sim.ckpt")),
            ..emitter_args(args)
        }),
    };
    flags.map_err(|e| CliError::Input(format!("{role}: {e}")))
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
    for role in Role::started(args.source) {
        if role == Role::EmitterSim && args.idle_probe_ms > 0 {
            sup.idle_cpu = probe_idle_cpu(sup, Duration::from_millis(args.idle_probe_ms));
        }
        sup.spawn(role, child_flags(role, args, sc, domain, state, log)?)?;
        sup.wait_ready(role)?;
    }
    if args.source == runtime::Source::External {
        let d = domain.as_str();
        eprintln!(
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
    let grace = Duration::from_secs_f64(args.command_timeout_s);
    if !args.live {
        return sup.wait_for_the_end(grace, &mut |_| {});
    }
    // The live view: the monitor's log as it grows, the children as the supervisor sees them; `q` stops.
    let mut terminal =
        crate::live::LiveTerminal::start().map_err(|e| CliError::Failed(format!("the live view: {e}")))?;
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
    use clap::{FromArgMatches, Parser};

    use super::*;

    /// `parse(to_flags(a)) == a`: the type that parses a process's flags writes them, and loses nothing
    /// on the way.
    fn round_trip<T>(a: T)
    where
        T: clap::Args + FromArgMatches + serde::Serialize + PartialEq + std::fmt::Debug,
    {
        assert_eq!(runtime::flags::from_flags::<T>(&to_flags(&a).unwrap()).unwrap(), a);
    }

    #[test]
    fn every_process_writes_its_own_flags_back() {
        let link = runtime::LinkArgs { transport: protocol::TransportKind::Uds, wait: None, spin_us: Some(30) };
        let m = monitor::args::MonitorArgs {
            process: runtime::ProcessArgs {
                node: runtime::NodeArgs { domain: Some("d".into()), link, quiet: true, supervised: true },
                run: runtime::RunArgs { scenario: Some("a b.toml".into()), steps: Some(7), seed: Some(9) },
            },
            source: runtime::Source::External,
            mcap: Some("run.mcap".into()),
            stamps: Some("s.csv".into()),
            log: Some("l.jsonl".into()),
            record: Some("r.json".into()),
            // A value that begins with `-` (written `--out=-o`, not taken for a flag).
            out: Some("-o".into()),
            print_record: true,
            resume: true,
        };
        round_trip(m);
        let p = planner::args::PlannerArgs {
            process: runtime::ProcessArgs {
                node: runtime::NodeArgs { domain: Some("d".into()), link, quiet: false, supervised: true },
                run: runtime::RunArgs { scenario: None, steps: Some(3), seed: None },
            },
            objective: planner::ObjectiveKind::PosteriorCubature,
            solver: planner::SolverKind::Aco,
            takeover: true,
            estimate_deadline_ms: 12,
            plan_delay_ms: 5,
            plan_delay_steps: vec![1, 4],
        };
        round_trip(p);
        let e = emitter_sim::args::EmitterSimArgs {
            process: runtime::ProcessArgs {
                node: runtime::NodeArgs { domain: Some("d".into()), link, quiet: true, supervised: false },
                run: runtime::RunArgs { scenario: Some("x.toml".into()), steps: Some(2), seed: Some(1) },
            },
            command_timeout_s: 0.1 + 0.2,
            retry_interval_ms: 77,
            connect_timeout_s: 3.5,
            min_subscribers: 2,
            step_delay_ms: 4,
            mode: emitter_sim::args::Mode::Realtime,
            time_scale: Some(1.0 / 3.0),
            checkpoint: None,
            linger: true,
            monitor_window: 17,
        };
        round_trip(e.clone());
        // A value that is not a finite number is an error, not a flag left out (the child's default).
        let nan = emitter_sim::args::EmitterSimArgs { time_scale: Some(f64::NAN), ..e.clone() };
        assert!(to_flags(&nan).unwrap_err().contains("finite"));
        let inf = emitter_sim::args::EmitterSimArgs { command_timeout_s: f64::INFINITY, ..e };
        assert!(to_flags(&inf).is_err());
        // The launch's children: every one parses its command line (no flag it does not know).
        #[derive(Parser)]
        struct Cli {
            #[command(subcommand)]
            process: super::super::ProcessRole,
        }
        let args = LaunchArgs::try_parse_from_defaults();
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
