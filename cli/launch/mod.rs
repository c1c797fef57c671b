//! `uavloc launch`: the process pipeline — monitor, planner, estimator and emitter-sim as children
//! (`uavloc process <role>`) over iceoryx2 or Unix sockets — run to the end of a scenario in lock-step or
//! real time, or fed by an external front end (`--source external`). What the user sees is the `--help`
//! ([`LONG_ABOUT`]); how a launch runs — the domain and its lock, the start order, the end, restarts by
//! each [`Role`]'s policy, the shutdown of swapped-in processes, the clean-up of iceoryx2 resources — is
//! ARCHITECTURE.md, "The launcher"; [`run`] below is that sequence.

mod args;
mod children;
mod report;
mod role;
mod shm;
mod signals;
pub mod state_dir;
mod supervisor;

use std::collections::BTreeMap;
use std::time::Instant;

use emitter_sim::args::Mode;
use protocol::resources;
use protocol::services::{self, DOMAIN_ENV, Domain};

pub use args::{AFTER_HELP, LONG_ABOUT, LaunchArgs};
pub use report::{ChildReport, LaunchReport};
pub use role::{RestartDecision, Role};

use crate::error::CliError;
use state_dir::StateDir;
use supervisor::{STOP_GRACE, Supervisor, TICK};

/// The domain of a launch: the flag, else `$UAVLOC_DOMAIN`, else `uavloc-<pid>` — or, for an external
/// front end, which must know it beforehand, `uavloc` (every process's default).
fn launch_domain(flag: Option<&str>, source: runtime::Source) -> Result<Domain, CliError> {
    let named = flag.is_some() || std::env::var(DOMAIN_ENV).is_ok_and(|v| !v.is_empty());
    if source == runtime::Source::Simulator && !named {
        return Domain::new(&format!("uavloc-{}", std::process::id()))
            .map_err(|e| CliError::failed_because("the run's own domain", e));
    }
    // As every process resolves it (an error names the flag or the variable).
    Domain::resolve_named(flag).map_err(CliError::Input)
}

/// Runs `uavloc launch` as the command line asks: with the live view on a terminal, unless `--headless`
/// or `--json`.
pub fn run_from_cli(args: &LaunchArgs, json: bool) -> Result<LaunchReport, CliError> {
    let live = !json && !args.headless && crate::live::LiveTerminal::available();
    run(&LaunchArgs { live, ..args.clone() })
}

/// Runs `uavloc launch`.
pub fn run(args: &LaunchArgs) -> Result<LaunchReport, CliError> {
    let start = Instant::now();
    let sc = args.run.scenario()?;
    planner::args::check_scenario(&sc).map_err(CliError::Input)?;
    // The aircraft: --autopilot, else the scenario's `autopilots`.
    let args = &LaunchArgs {
        autopilots: if args.autopilots.is_empty() { sc.autopilots.clone() } else { args.autopilots.clone() },
        ..args.clone()
    };
    if !args.autopilots.is_empty() {
        if args.source == runtime::Source::External {
            return Err(CliError::Input(
                "--autopilot flies aircraft for emitter-sim's world; with --source external the front end \
                 places its UAVs (it may read the bridge's <domain>/swarm, docs/flying.md)"
                    .into(),
            ));
        }
        // The bridge's flags as it will get them, checked by the bridge's own rules.
        children::bridge_args(args).check(&sc).map_err(CliError::Input)?;
    }
    if args.source == runtime::Source::External
        && (args.mode != Mode::Lockstep || args.time_scale.is_some() || args.step_delay_ms > 0)
    {
        return Err(CliError::Input(
            "--mode, --time-scale and --step-delay-ms pace emitter-sim; with --source external the front end \
             sets the pace"
                .into(),
        ));
    }
    // emitter-sim's flags as it will get them, checked by emitter-sim's own rules.
    let emitter = children::emitter_args(args);
    emitter.check().and_then(|()| emitter.pacing(sc.dt, sc.steps)).map_err(CliError::Input)?;
    let files =
        [("--record", args.record.as_deref()), ("--log", args.log.as_deref()), ("--stamps", args.stamps.as_deref())];
    runtime::output::check_outputs(&files, ("--out", args.out.as_deref(), &record::export::RUN_FILES))
        .map_err(CliError::Input)?;
    if args.link.transport == protocol::TransportKind::Uds {
        protocol::transport::uds::check_socket_dir().map_err(CliError::Input)?;
    }
    let domain = launch_domain(args.domain.as_deref(), args.source)?;
    // Held until the launch returns: a second launch into this domain is refused here, atomically.
    let _lock = state_dir::DomainLock::acquire(&domain)?;
    protocol::transport::quiet_logs();
    let existing = resources::list(&domain).map_err(CliError::Failed)?;
    if let Some(node) = existing.alive_nodes().next() {
        return Err(CliError::Input(format!(
            "domain {domain} is in use (process node {node} is running); choose another --domain"
        )));
    }
    // Nobody uses the domain: services a killed run left half-created would make every open fail (and the
    // dead nodes' clean-up, which opens them, too).
    let half = resources::remove_leftovers(&domain).map_err(CliError::Failed)?;
    if !half.is_empty() {
        protocol::log_line!(
            "launch: removed the half-created services {half:?} of domain {domain} (left by a killed run)"
        );
    }

    signals::catch_termination();
    // Room in /dev/shm for the domain's topics, before anything starts (children would die of SIGBUS).
    if args.link.transport == protocol::TransportKind::Iceoryx2 {
        shm::check()?;
    }
    // Checkpoints (and the monitor's log when --log is not given) live in a private directory of this
    // launch, removed at the end: a restarted child resumes from what its predecessor wrote there.
    let state = StateDir::create(&domain)?;
    // The processes read the launch's own copy of the scenario file: a restart long after the start, or a
    // swapped-in process, runs the scenario the launch started with even if the file was edited since
    // (before, it read the edited file, was of another run and the launch failed).
    let copy = args.run.scenario.as_deref().map(|file| state.copy_scenario(file, &sc)).transpose()?;
    let scenario = args.run.scenario.as_ref().map(|p| std::path::absolute(p).unwrap_or_else(|_| p.clone()));
    let args = &LaunchArgs {
        run: crate::args::RunChoice {
            scenario: copy.clone().or_else(|| args.run.scenario.clone()),
            ..args.run.clone()
        },
        ..args.clone()
    };
    let log = args.log.clone().unwrap_or_else(|| state.path("monitor.jsonl"));
    let flags_of = |role| children::child_flags(role, args, &sc, &domain, &state, &log);
    state.write_run_settings(&state_dir::RunSettings {
        scenario,
        scenario_copy: copy,
        steps: sc.steps,
        seed: sc.seed,
        planner: flags_of(Role::Planner)?,
        estimator: flags_of(Role::Estimator)?,
    })?;
    let mut sup = Supervisor::new(domain.clone(), Some(log.clone()), args.max_restarts, args.source);
    sup.aircraft = !args.autopilots.is_empty();
    let result = children::start_and_run(&mut sup, args, &sc, &domain, &state, &log);
    sup.stop_all();
    // Processes that are not our children (swapped in by `uavloc swap`) stop on the domain's shutdown
    // message.
    let own = |n: &str| Role::START_ORDER.iter().any(|role| n.ends_with(&format!("/{role}")));
    if resources::list(&domain).is_ok_and(|r| r.alive_nodes().any(own)) {
        match send_shutdown(&domain, args.link.transport) {
            Ok(control) => {
                wait_until_no_process_left(&domain);
                drop(control);
            }
            Err(e) => protocol::log_line!("warning: cannot send the shutdown message to domain {domain}: {e}"),
        }
    }
    // A child that crashed or had to be killed leaves its iceoryx2 node behind: remove it — also when the
    // launch failed or was interrupted — then check.
    let cleaned = resources::remove_dead_nodes(&domain).map_err(CliError::Failed);
    if args.link.transport == protocol::TransportKind::Uds {
        protocol::transport::uds::cleanup_stale();
    }
    // Interrupted (SIGINT/SIGTERM): the steps done are kept — the monitor sent its partial record when it
    // was stopped — and printed with `"interrupted": true` (exit code 1).
    // A process ended the run with an error a restart cannot mend, and the monitor sent the steps done:
    // they are printed too, with `"failed"` (exit code 1).
    let (interrupted, failed) = match result {
        Err(e) => match (signals::received(), &sup.record) {
            (Some(_), Some(_)) => (Some(e.to_string()), None),
            (None, Some(Ok(_))) => (None, Some(e.to_string())),
            _ => return Err(e),
        },
        Ok(()) => (None, None),
    };
    cleaned?;
    let leftovers = resources::list(&domain).map_err(CliError::Failed)?;

    let record = sup.record.take().ok_or_else(|| CliError::Failed("the monitor sent no run record".into()))?;
    let mut run = record.map_err(|e| CliError::failed_because("the monitor's run record", e))?;
    // The scenario as loaded here, like `simulate` (the record's copy went through TOML-style degree
    // conversions on the way).
    run.scenario = sc;
    // The monitor names the run after the commands it recorded; if none was flown (every one missed, in
    // realtime mode), the names are the launch's.
    if run.objective == "-" && run.solver == "-" {
        run.objective = args.run.objective.name().to_string();
        run.solver = args.run.solver.name().to_string();
    }
    let children: Vec<ChildReport> = sup
        .procs
        .iter()
        .map(|p| ChildReport {
            role: p.role.to_string(),
            pid: p.child.id(),
            exit: p.describe_exit(),
            rejected: p.summary.as_ref().and_then(|s| s["rejected"].as_u64()).unwrap_or(0),
            restarted: p.replaced,
            summary: p.summary.clone(),
        })
        .collect();
    let latency = sup.procs[sup.index(Role::Monitor)].summary.as_ref().map(|s| s["latency"].clone());
    let mut rejected_by = BTreeMap::new();
    for c in &children {
        *rejected_by.entry(c.role.clone()).or_insert(0) += c.rejected;
    }
    // Counted in the record: what was flown, once per step, however often emitter-sim was restarted.
    let has = |s: &record::record::StepRecord, name: &str| s.active_constraints.iter().any(|a| a == name);
    let flagged = |name| run.steps.iter().filter(|s| has(s, name)).count() as u64;
    let (missed_commands, stale_steps) =
        (flagged(monitor::assemble::COMMAND_MISSED), flagged(monitor::assemble::ESTIMATE_STALE));
    // Of the holds, those with no estimate to plan from yet (before a first fix), not a late one.
    let held_before_first_fix = run
        .steps
        .iter()
        .filter(|s| {
            has(s, monitor::assemble::ESTIMATE_STALE) && s.estimate_status == protocol::EstimateStatus::Failed.name()
        })
        .count() as u64;
    Ok(LaunchReport {
        interrupted,
        failed,
        run,
        restarts: sup.restarts,
        rejected: children.iter().map(|c| c.rejected).sum(),
        rejected_by,
        missed_commands,
        stale_steps,
        held_before_first_fix,
        domain: domain.to_string(),
        mode: match args.mode {
            _ if args.source == runtime::Source::External => "external".to_string(),
            Mode::Lockstep => "lockstep".to_string(),
            Mode::Realtime => format!("realtime ×{}", args.time_scale.unwrap_or(1.0)),
        },
        wall_s: start.elapsed().as_secs_f64(),
        children,
        latency,
        leftovers,
        idle_cpu: std::mem::take(&mut sup.idle_cpu),
    })
}

/// The launcher's own node on the control topic, kept until the others have stopped.
type ControlNode = (protocol::ControlChannel, protocol::Link);

/// Publishes [`ControlKind::Shutdown`](protocol::ControlKind::Shutdown) on the domain's control topic.
fn send_shutdown(domain: &Domain, kind: protocol::TransportKind) -> Result<ControlNode, String> {
    let node = protocol::Link::open_without_signal_handling(kind, &services::node_name(domain, "launcher"))
        .map_err(|e| e.to_string())?;
    let started_ns = protocol::now_ns();
    let control = protocol::ControlChannel::open(
        &node,
        domain,
        "launcher",
        protocol::control::instance_id_at(started_ns),
        started_ns,
    )
    .map_err(|e| e.to_string())?;
    control.send(protocol::ControlKind::Shutdown, 0, "").map_err(|e| e.to_string())?;
    Ok((control, node))
}

/// Waits (at most [`STOP_GRACE`]) until no process of the domain is alive (swapped-in processes that got
/// the shutdown message).
fn wait_until_no_process_left(domain: &Domain) {
    let deadline = Instant::now() + STOP_GRACE;
    while Instant::now() < deadline {
        match resources::list(domain) {
            // uavloc's own processes (a swapped-in one): a foreign node — an external front end — is not
            // the launch's to wait for.
            Ok(r) if r.alive_nodes().any(|n| Role::START_ORDER.iter().any(|role| n.ends_with(&format!("/{role}")))) => {
                std::thread::sleep(TICK / 5)
            }
            _ => return,
        }
    }
    protocol::log_line!("warning: processes of domain {domain} are still running after the shutdown message");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_external_front_end_finds_the_default_domain_without_being_told() {
        assert_eq!(launch_domain(Some("lab1"), runtime::Source::External).unwrap().as_str(), "lab1");
        if std::env::var(DOMAIN_ENV).is_err() {
            assert_eq!(launch_domain(None, runtime::Source::External).unwrap().as_str(), "uavloc");
            let own = launch_domain(None, runtime::Source::Simulator).unwrap();
            assert_eq!(own.as_str(), format!("uavloc-{}", std::process::id()));
        }
        assert!(launch_domain(Some("no spaces"), runtime::Source::External).is_err());
    }
}
