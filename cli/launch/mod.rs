//! `uavloc launch`: the process pipeline — monitor, planner, estimator and emitter-sim as child processes
//! talking over iceoryx2 — run to the end of a scenario, in lock-step or in real time (`--mode`,
//! `--time-scale`, passed to emitter-sim; see `emitter_sim::process`); and the hidden
//! `uavloc process <role>` that makes `uavloc` a multi-call binary (each child is `uavloc` itself, running
//! the same library entry point as the standalone `monitor`, `planner`, `estimator`, `emitter-sim`
//! binaries).
//!
//! # How a launch runs
//!
//! 1. The scenario is loaded as `uavloc simulate` loads it; the domain is `--domain`, else
//!    `$UAVLOC_DOMAIN`, else `uavloc-<pid>` (unique per launch). A domain with live processes is refused;
//!    dead leftovers of an earlier crash in it are cleaned up.
//! 2. The children start in the order monitor → planner → estimator → emitter-sim, each only after the
//!    previous one has printed `ready` on its stdout (its subscriptions exist), so no message is published
//!    before its subscribers are there (the topics keep no history). emitter-sim also checks the topics
//!    itself (≥ 2 measurement subscribers, a planner) before step 0.
//! 3. The run ends when emitter-sim has published the last step (it prints `finished` and, started with
//!    `--linger`, stays to replay the run to a monitor that fell behind or was restarted meanwhile) and the
//!    monitor has recorded it and exited 0; emitter-sim, the estimator and the planner are then stopped
//!    with SIGTERM (SIGKILL after a grace period).
//! 4. A child that exits before that (a crash, a kill, an error) is restarted: the restart is written to
//!    the `--log` (`{"event": "restart", "role", "pid", "exit", "attempt", "backoff_ms"}`) and counted in
//!    `restarts`; the dead node's iceoryx2 resources are removed; after min(50 ms · 2^(attempt − 1), 1.6 s)
//!    the same role starts again with the same flags (a monitor with `--resume`: it takes the steps of its
//!    log). The new process announces itself on the control topic and emitter-sim replays the run to it (see
//!    `emitter_sim::process`), so the run resumes exactly where it was; a restarted emitter-sim starts
//!    from the older world snapshot of its checkpoint (step 0 in a run younger than 512 steps) and flies
//!    on from there; the estimator and the planner keep no state of their own (it rides the messages, see
//!    `runtime::recovery`). In lock-step mode emitter-sim runs at most 48 steps ahead of the monitor (its
//!    `--monitor-window`), so a monitor starved of CPU never loses a message from its full buffers and one
//!    restarted many times does not fall behind what can be replayed to it. A child that exits with code 2
//!    (bad input) or 3 (the run cannot go on: two UAVs collided, so the world cannot measure), or crashes
//!    more than `--max-restarts` times, stops the others and fails the launch.
//!    (`tests/e2e/crash_restart.rs`.)
//! 5. At the end (or on an error or a signal), once its children are stopped, the launcher publishes a
//!    shutdown on the domain's control topic if processes of the domain are still alive — processes
//!    swapped in by `uavloc swap` are not its children and stop on it — and waits for them. A planner
//!    or estimator that exits because a swapped-in one took over (`handed_over_at` in its summary) is
//!    not restarted.
//! 6. Stale iceoryx2 resources of the domain (a child killed) are removed, and the launcher checks that
//!    none are left.
//!
//! Limits of restarts: in real-time mode emitter-sim does not wait for the monitor (the world keeps its
//! clock), so a monitor down for more than 256 steps while emitter-sim is restarted too may ask for a step
//! no longer kept (the run then stops with an error naming the steps); a process SIGKILLed inside
//! iceoryx2's node creation (a window of microseconds between its details file and its monitoring token)
//! leaves a node directory iceoryx2 cannot list or clean.
//!
//! Every child runs in its own process group (a terminal's Ctrl-C reaches only the launcher, which stops
//! the children in order) with `PR_SET_PDEATHSIG = SIGTERM`, so none outlives a launcher that dies.
//! SIGINT/SIGTERM on the launcher stop all children (exit code 1) and remove the iceoryx2 resources any of
//! them left behind (`tests/e2e/shutdown.rs`).
//!
//! The output is the monitor's run record, i.e. the JSON of `uavloc simulate --json` (built only from what
//! the monitor received), plus `restarts`, `rejected` (invalid messages counted by all four processes),
//! `rejected_by` (the same per process role; `tests/e2e/bad_messages.rs`) and `processes` (every instance
//! started: role, pid, exit, whether it was restarted, its summary).

mod args;
mod children;
mod process_cmd;
mod report;
mod role;
mod signals;
pub mod state_dir;
mod supervisor;

use std::collections::BTreeMap;
use std::time::Instant;

use emitter_sim::args::Mode;
use monitor::RunRecord;
use protocol::resources;
use protocol::services::{self, DOMAIN_ENV, Domain};

pub use args::{AFTER_HELP, LONG_ABOUT, LaunchArgs};
pub use process_cmd::{ProcessArgs, ProcessRole, ResourcesArgs, run_process};
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
        return Domain::new(&format!("uavloc-{}", std::process::id())).map_err(|e| CliError::Failed(e.to_string()));
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
    if let Some(dir) = &args.out {
        runtime::output::check_out_dir("--out", dir).map_err(CliError::Input)?;
    }
    let files =
        [("--record", args.record.as_deref()), ("--log", args.log.as_deref()), ("--stamps", args.stamps.as_deref())];
    for (flag, file) in files {
        if let Some(file) = file {
            runtime::output::check_out_file(flag, file).map_err(CliError::Input)?;
        }
    }
    runtime::output::check_distinct(&files, &[("--out", args.out.as_deref(), &monitor::export::RUN_FILES)])
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
    let half = resources::remove_half_created_services(&domain).map_err(CliError::Failed)?;
    if !half.is_empty() {
        eprintln!("launch: removed the half-created services {half:?} of domain {domain} (left by a killed run)");
    }
    resources::remove_dead_nodes(&domain).map_err(CliError::Failed)?;

    signals::catch_termination();
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
    let mut sup = Supervisor::new(domain.clone(), Some(log.clone()), args.max_restarts);
    let result = children::start_and_run(&mut sup, args, &sc, &domain, &state, &log);
    sup.stop_all();
    // Processes that are not our children (swapped in by `uavloc swap`) stop on the domain's shutdown
    // message.
    if resources::list(&domain).is_ok_and(|r| r.alive_nodes().next().is_some()) {
        match send_shutdown(&domain, args.link.transport) {
            Ok(control) => {
                wait_until_no_process_left(&domain);
                drop(control);
            }
            Err(e) => eprintln!("warning: cannot send the shutdown message to domain {domain}: {e}"),
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
    let interrupted = match result {
        Err(e) => match (signals::received(), &sup.record) {
            (Some(_), Some(_)) => Some(e.to_string()),
            _ => return Err(e),
        },
        Ok(()) => None,
    };
    cleaned?;
    let leftovers = resources::list(&domain).map_err(CliError::Failed)?;

    // Taken, so that the text (≈ 0.6 KB per step) is freed once parsed.
    let record = sup.record.take().ok_or_else(|| CliError::Failed("the monitor sent no run record".into()))?;
    let mut run: RunRecord =
        serde_json::from_str(&record).map_err(|e| CliError::Failed(format!("the monitor's run record: {e}")))?;
    drop(record);
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
    let missed_commands = children
        .iter()
        .filter(|c| c.role == Role::EmitterSim.name())
        .filter_map(|c| c.summary.as_ref().and_then(|s| s["missed_commands"].as_u64()))
        .sum();
    let stale_steps = run
        .steps
        .iter()
        .filter(|s| s.active_constraints.iter().any(|a| a == monitor::assemble::ESTIMATE_STALE))
        .count() as u64;
    Ok(LaunchReport {
        interrupted,
        run,
        restarts: sup.restarts,
        rejected: children.iter().map(|c| c.rejected).sum(),
        rejected_by,
        missed_commands,
        stale_steps,
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
            Ok(r) if r.alive_nodes().any(|n| !n.ends_with("/launcher")) => std::thread::sleep(TICK / 5),
            _ => return,
        }
    }
    eprintln!("warning: processes of domain {domain} are still running after the shutdown message");
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
