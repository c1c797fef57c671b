//! `uavloc swap <planner|estimator>`: replaces the running planner (or estimator) of a pipeline by a new
//! instance while the other processes keep running.
//!
//! The new instance is `uavloc process <role> --takeover` with the given flags, started *detached* (its own
//! session: it outlives the `swap` command, and a Ctrl-C in the terminal of the swap does not reach it;
//! its error messages still go to the swap's stderr). It follows the running pipeline, announces on the
//! domain's control topic that it takes over from the next step, the running instance handles the steps
//! before that and exits, and the new one goes on (see `planner::process` / `estimator::process`). The swap
//! command returns once the old instance is gone, with the step the new one took over from.
//!
//! The new instance is not a child of `uavloc launch`: the launcher does not restart it if it crashes,
//! but stops it at the end of the run (or on Ctrl-C) with the shutdown message on the control topic; a
//! pipeline started by hand stops it with SIGTERM.

use std::io::{BufRead, BufReader};
use std::os::unix::process::CommandExt as _;
use std::process::Stdio;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use clap::{Args, Subcommand};
use protocol::resources;
use protocol::services::Domain;
use serde::Serialize;

use crate::error::CliError;
use crate::output::{Diagnostic, Report, Table};

pub const LONG_ABOUT: &str = "\
Replace the running planner (or estimator) of a pipeline by a new instance, e.g. with another solver,
while the other processes keep running. The new process takes over at the next planning step, the old
one plans the step in progress and exits: no step is missed or planned twice. The monitor shows the
switch, and its record names the planner of every step.

The new process is started detached (it outlives this command) and stops with the pipeline: `uavloc
launch` stops it at the end of the run. One swap of a role at a time: a second `uavloc swap` of the same
role in the domain while one runs is refused (exit 2); a swap whose new process is itself replaced
before this command returns (by a process started with --takeover) fails (exit 1).

Give it --domain and the flags to change: every flag not given is the running launch's (its solver,
objective, transport, wait mode, estimator settings, …), not the process's default, so a swap without
flags restarts the role as it was. A planner's --scenario, --steps and --seed must be the launch's if
given (exit 2 otherwise). A pipeline started by hand has no launch to take them from: then the flags not
given are the defaults.";

pub const AFTER_HELP: &str = "\
Examples:
  uavloc launch --domain lab1 --steps 60 --step-delay-ms 200 &
  uavloc swap planner --domain lab1 --steps 60 --solver ga
  uavloc swap estimator --domain lab1";

/// Flags of `uavloc swap`.
#[derive(Args, Debug, Clone, PartialEq)]
pub struct SwapArgs {
    #[command(subcommand)]
    pub role: SwapRole,
    /// Give up (and stop the new process) when the swap is not done after this many seconds.
    #[arg(long, value_name = "S", default_value_t = 30.0, global = true)]
    pub timeout_s: f64,
}

/// The processes that can be swapped.
#[derive(Subcommand, Debug, Clone, PartialEq)]
pub enum SwapRole {
    /// A new planner (e.g. another --solver or --objective) takes over from the running one.
    Planner(planner::args::PlannerArgs),
    /// A new estimator takes over from the running one (its state is handed over exactly).
    Estimator(estimator::args::EstimatorArgs),
}

/// What `uavloc swap` prints.
#[derive(Debug, Clone, Serialize)]
pub struct SwapReport {
    pub role: String,
    pub domain: String,
    /// The new process.
    pub pid: u32,
    /// The first step it handles.
    pub from_step: u64,
    /// Its solver/objective (planner only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub planner: Option<String>,
}

/// A planner's `--scenario`, `--steps`, `--seed` against the running launch's: taken from the run when
/// not given; a given one that differs is refused (exit 2) — a planner with another horizon or seed would
/// stall the run or plan another one.
fn reconcile(
    a: &mut planner::args::PlannerArgs,
    run: &crate::launch::state_dir::RunSettings,
    file: &std::path::Path,
) -> Result<(), CliError> {
    let mismatch = |flag: &str, given: String, running: String| {
        CliError::Input(format!(
            "{flag} {given} does not match the running launch's {running} (from {}); leave it out to take the run's",
            file.display()
        ))
    };
    match a.process.run.steps {
        Some(n) if n != run.steps => return Err(mismatch("--steps", n.to_string(), run.steps.to_string())),
        _ => a.process.run.steps = Some(run.steps),
    }
    match a.process.run.seed {
        Some(s) if s != run.seed => return Err(mismatch("--seed", s.to_string(), run.seed.to_string())),
        _ => a.process.run.seed = Some(run.seed),
    }
    match (&a.process.run.scenario, &run.scenario) {
        (Some(given), Some(running)) if std::path::absolute(given).unwrap_or_else(|_| given.clone()) != *running => {
            return Err(mismatch("--scenario", given.display().to_string(), running.display().to_string()));
        }
        (Some(given), None) => {
            return Err(mismatch("--scenario", given.display().to_string(), "default scenario".into()));
        }
        // The launch's own copy: the original may have been edited since the launch started.
        _ => a.process.run.scenario = run.scenario_copy.clone().or_else(|| run.scenario.clone()),
    }
    Ok(())
}

/// The ids of the flags of `uavloc swap <role>` given on the command line (or by an environment
/// variable) in `matches` (the whole command line's): what a swap takes from the user rather than from the
/// running launch.
pub fn given_flags(matches: &clap::ArgMatches) -> Vec<String> {
    use clap::parser::ValueSource;
    let Some((_, role)) = matches.subcommand_matches("swap").and_then(|m| m.subcommand()) else { return Vec::new() };
    role.ids()
        .filter(|id| {
            matches!(role.value_source(id.as_str()), Some(ValueSource::CommandLine | ValueSource::EnvVariable))
        })
        .map(|id| id.as_str().to_owned())
        .collect()
}

/// The flags of a swapped-in process: the running launch's for the role, but each one whose id is in
/// `given` taken from `user` instead (both `--name=value` lists, as `runtime::flags::to_flags` writes
/// them). `--quiet` is not taken from the launch (its children are quiet; a swapped-in process speaks to
/// the swap's terminal unless told not to).
fn merged_flags(launch: &[String], user: &[String], given: &[String]) -> Vec<String> {
    let id = |flag: &str| flag.trim_start_matches("--").split('=').next().unwrap_or_default().replace('-', "_");
    let mut out: Vec<String> = launch.iter().filter(|f| !given.contains(&id(f)) && id(f) != "quiet").cloned().collect();
    out.extend(user.iter().filter(|f| given.contains(&id(f))).cloned());
    out
}

/// `T` parsed from `flags` (a process's own parser).
fn parse_flags<T: clap::Args + clap::FromArgMatches>(role: &'static str, flags: &[String]) -> Result<T, CliError> {
    runtime::flags::from_flags(flags).map_err(|e| {
        CliError::Input(format!(
            "the running launch's {role} flags with this swap's: {}",
            crate::one_line_clap_error(&e)
        ))
    })
}

/// `user` (the swap's flags of the role) completed from the launch's flags for the role (`launch`), each
/// flag the user did not give (`given`) taken from there.
fn completed<T>(role: &'static str, user: &T, launch: &[String], given: &[String]) -> Result<T, CliError>
where
    T: clap::Args + clap::FromArgMatches + Serialize + Clone,
{
    if launch.is_empty() {
        return Ok(user.clone()); // a launch of an older build, or a pipeline started by hand
    }
    let mine = runtime::flags::to_flags(user).map_err(|e| CliError::input_because(role.to_string(), e))?;
    parse_flags(role, &merged_flags(launch, &mine, given))
}

/// Runs `uavloc swap`; `given`: the ids of the role's flags given on the command line ([`given_flags`]).
/// A flag not given is the running launch's (when a launch runs the domain), not the process's default.
pub fn run(args: &SwapArgs, given: &[String]) -> Result<SwapReport, CliError> {
    if !(args.timeout_s > 0.0 && args.timeout_s.is_finite()) {
        return Err(CliError::Input(format!("--timeout-s must be > 0, got {}", args.timeout_s)));
    }
    let timeout = Duration::from_secs_f64(args.timeout_s);
    let (role, domain_flag) = match &args.role {
        SwapRole::Planner(a) => ("planner", a.process.node.domain.as_deref()),
        SwapRole::Estimator(a) => ("estimator", a.node.domain.as_deref()),
    };
    protocol::transport::quiet_logs();
    let domain = Domain::resolve_named(domain_flag).map_err(CliError::Input)?;
    // One swap of a role at a time (held until this command returns).
    let _lock = crate::launch::state_dir::DomainLock::acquire_swap(&domain, role)?;
    let node_name = protocol::services::node_name(&domain, role);
    let running = |domain: &Domain| -> Result<usize, CliError> {
        Ok(resources::list(domain).map_err(CliError::Failed)?.alive_nodes().filter(|n| *n == node_name).count())
    };
    if running(&domain)? == 0 {
        return Err(CliError::Input(format!(
            "no {role} is running in domain {domain}; start a pipeline first (e.g. uavloc launch --domain {domain})"
        )));
    }
    // The processes to see gone: a node is released a moment before its process exits.
    let old_pids = resources::list(&domain).map_err(CliError::Failed)?.alive_pids(&node_name);
    // The run's settings, when a launch runs the domain: a swapped-in planner runs the same scenario.
    let run = crate::launch::state_dir::find_run_settings(&domain);
    // The new process runs in the domain found above, under this command's supervision.
    // It stops when the launch does (it is not the launch's child): nothing outlives its launcher.
    let launcher = run.as_ref().map(|(_, _, pid)| *pid);
    let node = |a: &runtime::NodeArgs| runtime::NodeArgs {
        domain: Some(domain.to_string()),
        supervised: true,
        watch_pid: launcher,
        ..a.clone()
    };
    let no_flags: Vec<String> = Vec::new();
    let launch_flags = |f: fn(&crate::launch::state_dir::RunSettings) -> &Vec<String>| {
        run.as_ref().map_or(&no_flags, |(settings, ..)| f(settings))
    };
    let mut planner = None;
    let flags = match &args.role {
        SwapRole::Planner(a) => {
            let mut a = a.clone();
            // The run's scenario, steps and seed (a given one that differs is refused), the launch's other
            // flags where none is given.
            let mut given = given.to_vec();
            if let Some((settings, file, _)) = &run {
                reconcile(&mut a, settings, file)?;
                given.extend(["scenario", "steps", "seed"].map(String::from));
            }
            let a = completed(role, &a, launch_flags(|s| &s.planner), &given)?;
            planner = Some(format!("{}/{}", a.solver.name(), a.objective.name()));
            let process = runtime::ProcessArgs { node: node(&a.process.node), ..a.process.clone() };
            runtime::flags::to_flags(&planner::args::PlannerArgs { process, takeover: true, ..a })
        }
        SwapRole::Estimator(a) => {
            let a = completed(role, a, launch_flags(|s| &s.estimator), given)?;
            runtime::flags::to_flags(&estimator::args::EstimatorArgs { node: node(&a.node), takeover: true, ..a })
        }
    }
    .map_err(|e| CliError::input_because(role.to_string(), e))?;

    let exe = std::env::current_exe().map_err(|e| CliError::failed_because("cannot find this executable", e))?;
    let mut command = std::process::Command::new(exe);
    command.arg("process").arg(role).args(&flags).stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::inherit());
    // SAFETY: the closure runs in the forked child before exec and only calls setsid(2), which is
    // async-signal-safe; it allocates nothing and touches no lock.
    unsafe {
        command.pre_exec(|| {
            libc::setsid();
            Ok(())
        });
    }
    let mut child = command.spawn().map_err(|e| CliError::failed_because(format!("cannot start the new {role}"), e))?;
    let pid = child.id();
    let stdout = child.stdout.take().expect("piped stdout");
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                return;
            }
        }
    });
    let give_up = |child: &mut std::process::Child, why: String| {
        let _ = child.kill();
        let _ = child.wait();
        let _ = resources::remove_dead_nodes(&domain);
        CliError::Failed(why)
    };
    // The new instance takes over at the next step …
    let deadline = Instant::now() + timeout;
    let from_step = loop {
        match rx.recv_timeout(deadline.saturating_duration_since(Instant::now())) {
            Ok(line) => {
                if let Some(runtime::SupervisorLine::TakeOver { from_step }) = runtime::SupervisorLine::parse(&line) {
                    break from_step;
                }
            }
            Err(_) => {
                let why = match child.try_wait() {
                    Ok(Some(status)) => format!("the new {role} stopped ({status}) before taking over"),
                    _ => format!("the new {role} did not take over within {timeout:?} (is the pipeline running?)"),
                };
                return Err(give_up(&mut child, why));
            }
        }
    };
    // A run that has ended has nothing to take over (the new process saw the last step).
    if let Some((settings, ..)) = &run
        && let Err(e) = check_not_over(role, &domain, from_step, settings.steps)
    {
        let _ = give_up(&mut child, String::new());
        return Err(e);
    }
    // … and the old one exits once it has handled the steps before (its node, then its process).
    while running(&domain)? > 1 || old_pids.iter().any(|p| crate::launch::state_dir::pid_alive(*p)) {
        if Instant::now() > deadline {
            return Err(CliError::Failed(format!(
                "the new {role} (pid {pid}) took over from step {from_step}, but the old one is still running after \
                 {timeout:?}"
            )));
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    // The new process must be the one running now: a process started with --takeover by hand may have
    // taken over from it in the meantime.
    if let Ok(Some(status)) = child.try_wait() {
        return Err(CliError::Failed(format!(
            "the new {role} (pid {pid}) took over from step {from_step}, but it has already exited ({status}): \
             another process took over from it (a {role} started with --takeover?)"
        )));
    }
    // The new process runs on by itself (its later `summary` line goes nowhere).
    drop(child);
    Ok(SwapReport { role: role.into(), domain: domain.to_string(), pid, from_step, planner })
}

/// Refuses a take-over from `from_step` that leaves the new `role` nothing to do in a run of `steps`
/// planning steps: the planner plans steps `0..steps`, the estimator estimates `0..=steps`.
fn check_not_over(role: &str, domain: &Domain, from_step: u64, steps: usize) -> Result<(), CliError> {
    let last = if role == "planner" { steps as u64 } else { steps as u64 + 1 };
    if from_step >= last {
        return Err(CliError::Input(format!(
            "the run in domain {domain} has ended (its last step is {steps}; the new {role} would take over from \
             step {from_step}): there is nothing to take over"
        )));
    }
    Ok(())
}

impl Report for SwapReport {
    fn table(&self) -> Table {
        let mut t = Table::new()
            .row("domain", self.domain.clone())
            .row(format!("new {}", self.role), format!("pid {}", self.pid))
            .row("takes over from step", self.from_step.to_string());
        if let Some(p) = &self.planner {
            t = t.row("solver / objective", p.clone());
        }
        t.row(format!("old {}", self.role), "exited".to_string())
    }

    fn diagnostics(&self) -> Vec<Diagnostic> {
        Vec::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_swapped_in_process_takes_the_launchs_flags_but_those_given() {
        let launch: Vec<String> =
            ["--domain=d", "--quiet", "--solver=pso", "--transport=uds", "--plan-delay-steps=1,2"]
                .map(String::from)
                .into();
        let user: Vec<String> =
            ["--solver=gradient", "--objective=mc", "--transport=iceoryx2"].map(String::from).into();
        // Nothing given: the launch's, but its --quiet.
        assert_eq!(
            merged_flags(&launch, &user, &[]),
            ["--domain=d", "--solver=pso", "--transport=uds", "--plan-delay-steps=1,2"]
        );
        // Given ones replace the launch's (all of a flag's values), in the user's words.
        let given = ["solver", "objective", "plan_delay_steps"].map(String::from);
        assert_eq!(
            merged_flags(&launch, &user, &given),
            ["--domain=d", "--transport=uds", "--solver=gradient", "--objective=mc"]
        );
        // Parsed back by the process's own parser: the launch's transport, the user's solver.
        let a: planner::args::PlannerArgs =
            parse_flags("planner", &merged_flags(&launch, &user, &["solver".to_string()])).unwrap();
        assert_eq!((a.solver.name(), a.process.node.link.transport), ("gradient", protocol::TransportKind::Uds));
        assert!(!a.process.node.quiet);
        // A launch's flag the process does not know (a newer launch) is an error naming both sides.
        let e = parse_flags::<planner::args::PlannerArgs>("planner", &["--no-such=1".to_string()]).unwrap_err();
        assert!(e.to_string().contains("running launch's planner flags"), "{e}");
    }

    #[test]
    fn a_take_over_after_the_last_step_is_refused() {
        // A swap after the last step of a 40-step run said "takes over from step 41".
        let d = Domain::new("swap-end").unwrap();
        for (role, from, ok) in [
            ("planner", 39, true),
            ("planner", 40, false), // step 40 is measured, not planned: nothing left to plan
            ("planner", 41, false),
            ("estimator", 40, true), // the final measurement is still estimated
            ("estimator", 41, false),
        ] {
            let got = check_not_over(role, &d, from, 40);
            assert_eq!(got.is_ok(), ok, "{role} from {from}: {got:?}");
            if let Err(e) = got {
                assert_eq!(e.code(), 2);
                assert!(e.to_string().contains("nothing to take over"), "{e}");
            }
        }
    }
}
