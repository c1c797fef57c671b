//! The `planner` process: receive an [`Estimate`] → [`plan_step`] → publish a [`Command`].
//!
//! One loop over the pipeline's estimate topic (blocking, event-driven; optionally busy-polling for
//! `--spin-us` first). For every valid estimate of a step below the scenario's `steps` it builds the
//! [`PlanRequest`] exactly as `uavloc simulate` does (UAV positions and headings from the estimate, ẑ and
//! M from the estimate, run seed and step) and publishes the command. The final step (`step == steps`) is
//! measured and estimated but not planned, as in the in-process loop.
//!
//! - A *failed* estimate carries no position (NaN on the wire); the planner then plans with the last
//!   usable estimate it received, which is exactly the fallback of the estimator library (it keeps its
//!   previous estimate on failure). A step-0 estimate starts a new run and forgets the previous one.
//! - Only `target = "chan"` is supported: `controlled` mode needs the true emitter, which the pipeline
//!   never shows the planner (use `uavloc simulate` for it).
//! - Invalid estimates are counted (per rejection kind) and ignored.
//! - SIGINT/SIGTERM end the loop cleanly (exit 0); the iceoryx2 resources are released on the way out.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use clap::Args;
use iceoryx2::prelude::*;
use nalgebra::{Matrix2, Vector2};
use protocol::services::{self, Domain};
use protocol::{
    Command, Estimate, EstimateStatus, PlanInfo, RejectionCounter, Topic, TopicSubscriber, TransportError, now_ns,
};

use crate::active_mask;
use crate::objective::ObjectiveKind;
use crate::scenario::{Scenario, ScenarioError, TargetMode};
use crate::solver::SolverKind;
use crate::step::{PlanRequest, plan_step};

/// The role name (node name suffix, `uavloc process planner`).
pub const ROLE: &str = "planner";

/// How long a blocking wait lasts before the loop re-checks for a termination request that arrived
/// between two waits (a signal during a wait interrupts it at once).
pub const IDLE_WAKEUP: Duration = Duration::from_secs(1);

/// What `planner --help` shows after the flags.
pub const AFTER_HELP: &str = "\
The planner subscribes to <domain>/estimate and publishes <domain>/command. Start it with the same
--scenario, --steps and --seed as emitter-sim (the scenario gives the motion, constraints, objective
and solver settings; the seed drives the MC samples and the solver). Only target = \"chan\" scenarios
are supported (controlled mode needs the truth, which only `uavloc simulate` can give the planner).

Examples:
  planner --domain lab1
  planner --domain lab1 --objective mc --solver ga --scenario scenarios/nominal.toml --seed 7
  UAVLOC_DOMAIN=lab1 planner --spin-us 50";

/// Flags of the planner process (`planner [FLAGS]` or `uavloc process planner [FLAGS]`).
#[derive(Args, Debug, Clone, PartialEq)]
pub struct PlannerArgs {
    /// Pipeline domain: prefix of every service name (default: $UAVLOC_DOMAIN, else "uavloc").
    #[arg(long, value_name = "NAME")]
    pub domain: Option<String>,
    /// Scenario TOML file (default: the paper's nominal case).
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<PathBuf>,
    /// Planning objective: single | mc | analytical | cubature | formation.
    #[arg(long, default_value = "analytical", value_parser = parse_objective)]
    pub objective: ObjectiveKind,
    /// Solver: pso | ga | aco (ignored by formation).
    #[arg(long, default_value = "pso", value_parser = parse_solver)]
    pub solver: SolverKind,
    /// Steps of the run (default: the scenario's); the estimate of the last step is not planned.
    #[arg(long, value_name = "N")]
    pub steps: Option<usize>,
    /// Run seed (default: the scenario's): MC objective samples and the solver derive from it.
    #[arg(long, value_name = "N")]
    pub seed: Option<u64>,
    /// Busy-poll this many microseconds for the next estimate before blocking (0: block at once).
    #[arg(long, value_name = "US", default_value_t = 0)]
    pub spin_us: u64,
    /// Print nothing but errors.
    #[arg(long)]
    pub quiet: bool,
    /// Under a launcher: print `ready` on stdout once subscribed, and `summary {json}` at exit.
    #[arg(long, hide = true)]
    pub supervised: bool,
}

fn parse_objective(s: &str) -> Result<ObjectiveKind, String> {
    s.parse::<ObjectiveKind>()
}

fn parse_solver(s: &str) -> Result<SolverKind, String> {
    s.parse::<SolverKind>()
}

/// Why a process stopped with an error.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ProcessError {
    /// Bad flags or scenario (exit code 2).
    Input(String),
    /// A runtime failure, e.g. iceoryx2 (exit code 1).
    Failed(String),
}

impl ProcessError {
    /// The exit code: 2 for bad input, 1 for a runtime failure.
    pub fn code(&self) -> u8 {
        match self {
            ProcessError::Input(_) => 2,
            ProcessError::Failed(_) => 1,
        }
    }
}

impl std::fmt::Display for ProcessError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ProcessError::Input(m) | ProcessError::Failed(m) => f.write_str(m),
        }
    }
}

impl From<TransportError> for ProcessError {
    fn from(e: TransportError) -> Self {
        ProcessError::Failed(e.to_string())
    }
}

/// The scenario of a process: `path` (or the default) with `--steps` / `--seed` applied, validated —
/// the same rule as `uavloc simulate`, so every process of a run agrees on it.
pub fn load_scenario(path: Option<&Path>, steps: Option<usize>, seed: Option<u64>) -> Result<Scenario, ScenarioError> {
    let mut sc = match path {
        Some(p) => Scenario::from_file(p)?,
        None => Scenario::default(),
    };
    if let Some(n) = steps {
        sc.steps = n;
    }
    if let Some(s) = seed {
        sc.seed = s;
    }
    sc.validate()?;
    Ok(sc)
}

/// What the planner did, printed as its `summary` line.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct PlannerSummary {
    /// `"planner"`.
    pub role: &'static str,
    /// This process's instance id (in every command).
    pub instance: u64,
    /// Valid estimates received.
    pub accepted: u64,
    /// Invalid estimates ignored.
    pub rejected: u64,
    /// Commands published.
    pub published: u64,
    /// Estimates that could not be planned (no usable estimate yet, or `plan_step` refused).
    pub errors: u64,
}

/// A process instance id: the pid in the high 32 bits, the start time's low bits below (tells restarts
/// apart even when a pid is reused).
pub fn instance_id() -> u64 {
    (u64::from(std::process::id()) << 32) | (now_ns() & 0xffff_ffff)
}

/// Blocks (after busy-polling `spin`) until estimates arrive; `None` when SIGINT/SIGTERM asks to stop.
fn next_batch<T: protocol::Message>(
    node: &Node<ipc::Service>,
    sub: &TopicSubscriber<T>,
    spin: Duration,
    timeout: Duration,
) -> Result<Option<Vec<T>>, ProcessError> {
    if node.wait(Duration::ZERO).is_err() {
        return Ok(None);
    }
    match sub.wait(spin, timeout) {
        Ok(batch) => Ok(Some(batch)),
        // A signal interrupted the wait: stop if it was SIGINT/SIGTERM, else carry on.
        Err(TransportError::Interrupted) => {
            Ok(if node.wait(Duration::ZERO).is_err() { None } else { Some(Vec::new()) })
        }
        Err(e) => Err(e.into()),
    }
}

/// Prints one line on stdout for a supervising launcher.
fn announce(supervised: bool, line: &str) {
    if supervised {
        let mut out = std::io::stdout().lock();
        let _ = writeln!(out, "{line}");
        let _ = out.flush();
    }
}

/// Runs the planner until SIGINT/SIGTERM.
pub fn run(args: &PlannerArgs) -> Result<PlannerSummary, ProcessError> {
    protocol::transport::quiet_logs();
    let domain = Domain::resolve(args.domain.as_deref()).map_err(|e| ProcessError::Input(e.to_string()))?;
    let scenario = load_scenario(args.scenario.as_deref(), args.steps, args.seed)
        .map_err(|e| ProcessError::Input(format!("--scenario: {e}")))?;
    if scenario.target == TargetMode::Controlled {
        return Err(ProcessError::Input(
            "scenario key `target`: \"controlled\" is not supported by the process pipeline (it needs the true \
             emitter, which the planner never receives); use `uavloc simulate` for controlled runs"
                .into(),
        ));
    }
    let node = protocol::node(&services::node_name(&domain, ROLE))?;
    // The first wait installs iceoryx2's SIGINT/SIGTERM handler, so a signal ends the loop cleanly.
    if node.wait(Duration::ZERO).is_err() {
        return Ok(PlannerSummary { role: ROLE, ..PlannerSummary::default() });
    }
    let estimates = Topic::<Estimate>::subscriber(&node, &services::estimate(&domain))?;
    let commands = Topic::<Command>::publisher(&node, &services::command(&domain))?;
    let instance = instance_id();
    let mut summary = PlannerSummary { role: ROLE, instance, ..PlannerSummary::default() };
    announce(args.supervised, "ready");
    if !args.quiet {
        eprintln!(
            "planner: domain {domain}, {} / {}, {} steps, seed {}, instance {instance:#x}",
            args.objective.name(),
            args.solver.name(),
            scenario.steps,
            scenario.seed
        );
    }

    let spin = Duration::from_micros(args.spin_us);
    let mut counter = RejectionCounter::new();
    let mut last_seq = None;
    // Sequence numbers start at the monotonic clock: a restarted planner continues above its predecessor.
    let mut seq = now_ns();
    let mut usable: Option<(Vector2<f64>, Matrix2<f64>)> = None;
    while let Some(batch) = next_batch(&node, &estimates, spin, IDLE_WAKEUP)? {
        let received_ns = now_ns();
        for est in batch {
            if let Err(r) = counter.check(&est, &mut last_seq) {
                summary.rejected += 1;
                eprintln!("planner: rejected an estimate: {r}");
                continue;
            }
            summary.accepted += 1;
            let step = est.header.step;
            if step == 0 {
                usable = None; // a new run
            }
            if matches!(est.status(), Some(EstimateStatus::Ok | EstimateStatus::Ambiguous)) {
                let c = est.covariance;
                usable = Some((
                    Vector2::new(est.position[0], est.position[1]),
                    Matrix2::new(c[0][0], c[0][1], c[1][0], c[1][1]),
                ));
            }
            if step >= scenario.steps as u64 {
                continue; // the final step is recorded, not planned
            }
            let Some((z_hat, m)) = usable else {
                summary.errors += 1;
                eprintln!("planner: step {step}: the estimator has no fix yet, nothing to plan from");
                continue;
            };
            let positions: Vec<Vector2<f64>> = est.uavs().iter().map(|p| Vector2::new(p[0], p[1])).collect();
            let plan = match plan_step(&PlanRequest {
                positions: &positions,
                headings: est.headings(),
                estimate: z_hat,
                covariance: m,
                scenario: &scenario,
                objective: args.objective,
                solver: args.solver,
                run_seed: scenario.seed,
                step,
            }) {
                Ok(plan) => plan,
                Err(e) => {
                    summary.errors += 1;
                    eprintln!("planner: step {step}: {e}");
                    continue;
                }
            };
            let waypoints: Vec<[f64; 2]> = plan.waypoints.iter().map(|w| [w.x, w.y]).collect();
            seq += 1;
            let command = Command::from_estimate(
                &est,
                received_ns,
                seq,
                instance,
                &PlanInfo {
                    headings: &plan.headings,
                    waypoints: &waypoints,
                    // The wire requires a finite value: an infinite criterion (a singular geometry) is sent as
                    // −1, which the monitor reads as "no value" like `simulate` does.
                    objective: if plan.objective_value.is_finite() { plan.objective_value } else { -1.0 },
                    solver: args.solver.name(),
                    objective_name: args.objective.name(),
                    plan_time_us: (plan.plan_time_ms * 1e3).round() as u64,
                    active_constraints: active_mask::encode(&plan.active_constraints),
                },
            )
            .map_err(|e| ProcessError::Failed(format!("step {step}: command: {e}")))?;
            commands.send(&command)?;
            summary.published += 1;
        }
    }
    if !args.quiet {
        eprintln!("planner: stopped after {} commands ({} estimates, {counter})", summary.published, summary.accepted);
    }
    Ok(summary)
}

/// Runs the planner and maps the outcome to an exit code (errors as one `error:` line on stderr); in
/// supervised mode the summary goes to stdout as `summary {json}`.
pub fn main_with(args: &PlannerArgs) -> ExitCode {
    match run(args) {
        Ok(summary) => {
            announce(args.supervised, &format!("summary {}", serde_json::to_string(&summary).unwrap_or_default()));
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: planner: {e}");
            ExitCode::from(e.code())
        }
    }
}
