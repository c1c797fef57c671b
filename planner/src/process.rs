//! The `planner` process: receive an [`Estimate`] → [`plan_step`] → publish a [`Command`].
//!
//! One loop over the pipeline's estimate and control topics (blocking in a `WaitSet`, event-driven;
//! optionally busy-polling for `--spin-us` first). For every valid estimate of a step below the
//! scenario's `steps` it builds the [`PlanRequest`] exactly as `uavloc simulate` does (UAV positions and
//! headings from the estimate, ẑ and M from the estimate, run seed and step) and publishes the command.
//! The final step (`step == steps`) is measured and estimated but not planned, as in the in-process loop.
//!
//! - A *failed* estimate carries no position (NaN on the wire); the planner then plans with the usable
//!   estimate of the latest step before it, which is exactly the fallback of the estimator library (it
//!   keeps its previous estimate on failure). That is the latest in step order, not in arrival order: a
//!   replay from the middle of the run comes after the estimates of later steps ([`crate::fallback`]).
//! - Each step's command is kept: an estimate seen again (a replay by emitter-sim, or a restarted
//!   emitter-sim running the same scenario from step 0) gets the same command again (`resent`), without
//!   planning. Plans depend only on the estimate, the last usable one, the scenario, the seed and the
//!   step, so a restarted planner — which announces itself on the control topic
//!   ([`ControlKind::Hello`], from step 0) and gets the run replayed — plans exactly what its
//!   predecessor would have.
//! - With `--checkpoint FILE` it writes its state (the estimate the step planned from) to FILE every
//!   [`checkpoint::CHECKPOINT_EVERY`] steps, before publishing that step's command; started again with
//!   the same FILE (a restart) it resumes from it and asks for the replay from that step (planned again
//!   from the same inputs: the same command) instead of step 0. It keeps its last checkpoints and takes
//!   one up again when the world was rewound to its step (a restarted emitter-sim) (see [`runtime::checkpoint`]). Commands are kept for the last [`MAX_CACHED_STEPS`] steps, so
//!   its memory does not grow with the run.
//! - Only `target = "chan"` is supported: `controlled` mode needs the true emitter, which the pipeline
//!   never shows the planner (use `uavloc simulate` for it).
//! - Invalid estimates are counted (per rejection kind) and ignored.
//! - **Staleness deadline** (`--estimate-deadline-ms D`, off by default): the planner also subscribes to
//!   the measurements; when the estimate of the newest measured step has not arrived D ms after its
//!   measurement, the planner *holds course*: it publishes a command with the UAVs' current headings (they
//!   fly straight on) flagged [`Command::FLAG_HOLD`] (objective −1, no plan time), counts it (`held`) and
//!   logs it; the monitor shows the step as `estimate_stale`. The estimate that comes later still becomes
//!   the last usable one, and the step is answered with its hold (`late_estimates`). With a deadline the
//!   run depends on timing (like emitter-sim's real-time mode), so lock-step reproductions of `simulate`
//!   leave it off.
//! - `--plan-delay-ms` (with `--plan-delay-steps`) is a test / fault-injection aid: the planner sleeps
//!   before planning those steps, like a slow one, e.g. to make its commands miss their step in
//!   emitter-sim's real-time mode (`tests/realtime.rs`).
//! - SIGINT/SIGTERM, or a [`ControlKind::Shutdown`] on the control topic, end the loop cleanly (exit 0);
//!   the iceoryx2 resources are released on the way out.
//!
//! # Swapping planners (`--takeover`, what `uavloc swap planner` starts)
//!
//! A planner started with `--takeover` joins a running pipeline without a replay: it follows the
//! estimates (keeping the last usable one), and on the first one (step k) it announces
//! [`ControlKind::TakeOver`] from step k + 1 and prints `takeover {"from_step": k + 1}` (supervised). The
//! running planner plans every step before k + 1 — step k included — and then exits (exit 0, its summary
//! says `handed_over`); the new one plans from k + 1 on. No step is planned twice and none is missed;
//! should the old planner die before its last command, the emitter-sim's retry replays step k and the
//! new planner plans it. A planner that sees a take-over by a newer planner behaves as the old one.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::Args;
use nalgebra::{Matrix2, Vector2};
use protocol::control::instance_id_at;
use protocol::services::{self, Domain};
use protocol::{
    Command, ControlChannel, ControlKind, Estimate, EstimateStatus, Measurement, Message, PlanInfo, RejectionCounter,
    Topic, TopicSubscriber, TransportError, now_ns,
};
use runtime::SupervisorLine;
use runtime::checkpoint::{self, HISTORY_STEPS, PROCESS_CHECKPOINTS};

use crate::active_mask;
use crate::fallback::UsableEstimates;
use crate::objective::ObjectiveKind;
use crate::scenario::{Scenario, TargetMode};
use crate::solver::SolverKind;
use crate::staleness::{self, DueStep, Freshness, HoldTracker, hold_plan};
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
  planner --domain lab1 --estimate-deadline-ms 50   hold course when a step's estimate is 50 ms late
  UAVLOC_DOMAIN=lab1 planner --spin-us 50";

/// Flags of the planner process (`planner [FLAGS]` or `uavloc process planner [FLAGS]`).
#[derive(Args, Debug, Clone, PartialEq)]
pub struct PlannerArgs {
    /// Pipeline domain: prefix of every service name (default: $UAVLOC_DOMAIN, else "uavloc").
    #[arg(long, value_name = "NAME")]
    pub domain: Option<String>,
    /// The run: scenario, steps, seed.
    #[command(flatten)]
    pub run: runtime::RunArgs,
    /// Planning objective: single | mc | analytical | cubature | formation.
    #[arg(long, default_value = "analytical")]
    pub objective: ObjectiveKind,
    /// Solver: pso | ga | aco (ignored by formation).
    #[arg(long, default_value = "pso")]
    pub solver: SolverKind,
    /// Transport and waiting.
    #[command(flatten)]
    pub link: runtime::LinkArgs,
    /// Take over from the running planner at the next step (see `uavloc swap planner`).
    #[arg(long)]
    pub takeover: bool,
    /// Checkpoint file: the state is written there every 256 steps, and a start that finds it (a restart
    /// in the same run) resumes from it instead of having the run replayed from step 0. Remove it before
    /// a new run. (`uavloc launch` gives each process one in a fresh directory per launch.)
    #[arg(long, value_name = "FILE")]
    pub checkpoint: Option<PathBuf>,
    /// Staleness deadline: when a step's estimate has not arrived this many milliseconds after its
    /// measurement, hold course (command the current headings, flagged as a hold; the monitor shows
    /// `estimate_stale`). 0: no deadline (wait for every estimate; what lock-step reproductions need).
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
    /// Print nothing but errors.
    #[arg(long)]
    pub quiet: bool,
    /// Under a launcher: print `ready` on stdout once subscribed, and `summary {json}` at exit.
    #[arg(long, hide = true)]
    pub supervised: bool,
}

pub use runtime::ProcessError;

impl PlannerArgs {
    /// The command line of these flags (see [`runtime::flags`]).
    pub fn to_flags(&self) -> Vec<String> {
        runtime::Flags::new()
            .opt("--domain", self.domain.as_deref())
            .extend(self.run.to_flags())
            .value("--objective", self.objective)
            .value("--solver", self.solver)
            .extend(self.link.to_flags())
            .switch("--takeover", self.takeover)
            .path("--checkpoint", self.checkpoint.as_deref())
            .value("--estimate-deadline-ms", self.estimate_deadline_ms)
            .value("--plan-delay-ms", self.plan_delay_ms)
            .list("--plan-delay-steps", &self.plan_delay_steps)
            .switch("--quiet", self.quiet)
            .switch("--supervised", self.supervised)
            .into_vec()
    }
}

pub use model::scenario::load_scenario;

/// What the planner did, printed as its `summary` line.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct PlannerSummary {
    /// What every data process reports (role, instance, counts, hand-over, CPU).
    #[serde(flatten)]
    pub node: runtime::NodeSummary,
    /// Estimates that could not be planned (no usable estimate yet, or `plan_step` refused).
    pub errors: u64,
    /// Steps held: no fresh estimate within `--estimate-deadline-ms`, the current headings commanded.
    pub held: u64,
    /// Estimates of held steps (arrived after the deadline; answered with the hold, not planned).
    pub late_estimates: u64,
}

/// Steps whose commands are kept (the oldest is forgotten beyond): emitter-sim's replay history.
pub const MAX_CACHED_STEPS: usize = HISTORY_STEPS as usize;

/// What the planner writes to its `--checkpoint` file.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Checkpoint {
    /// The step it was written at (a restart asks for the replay from it and plans it again).
    pub step: u64,
    /// The usable estimate (metres) and its covariance (m²) that step was planned from (its own, or the
    /// latest before it: see [`crate::fallback`]).
    pub usable: Option<([f64; 2], [[f64; 2]; 2])>,
}

fn to_wire(u: &(Vector2<f64>, Matrix2<f64>)) -> ([f64; 2], [[f64; 2]; 2]) {
    tdoa::estimate_to_arrays(&u.0, &u.1)
}

fn from_wire(u: &([f64; 2], [[f64; 2]; 2])) -> (Vector2<f64>, Matrix2<f64>) {
    tdoa::estimate_from_arrays(&u.0, &u.1)
}

/// Everything a plan depends on besides the step (the estimate's geometry, status, ẑ and M, and the usable
/// estimate it plans from), bit for bit.
fn content_key(e: &Estimate, usable: Option<&(Vector2<f64>, Matrix2<f64>)>) -> Vec<u64> {
    let mut key = vec![u64::from(e.count), u64::from(e.status)];
    if let Some((z, m)) = usable {
        key.extend(z.iter().chain(m.iter()).map(|v| v.to_bits()));
    }
    key.extend(
        e.uavs()
            .iter()
            .flatten()
            .chain(e.headings())
            .chain(&e.position)
            .chain(e.covariance.iter().flatten())
            .map(|v| v.to_bits()),
    );
    key
}

/// Runs the planner until SIGINT/SIGTERM.
pub fn run(args: &PlannerArgs) -> Result<PlannerSummary, ProcessError> {
    protocol::transport::quiet_logs();
    let domain = Domain::resolve(args.domain.as_deref()).map_err(|e| ProcessError::Input(e.to_string()))?;
    let scenario = load_scenario(args.run.scenario.as_deref(), args.run.steps, args.run.seed)
        .map_err(|e| ProcessError::Input(format!("--scenario: {e}")))?;
    if scenario.target == TargetMode::Controlled {
        return Err(ProcessError::Input(
            "scenario key `target`: \"controlled\" is not supported by the process pipeline (it needs the true \
             emitter, which the planner never receives); use `uavloc simulate` for controlled runs"
                .into(),
        ));
    }
    let link = protocol::Link::open(args.link.transport, &services::node_name(&domain, ROLE))?;
    // The first wait installs iceoryx2's SIGINT/SIGTERM handler, so a signal ends the loop cleanly.
    if link.interrupted() {
        return Ok(PlannerSummary { node: runtime::NodeSummary::new(ROLE, 0), ..PlannerSummary::default() });
    }
    let started_ns = now_ns();
    let instance = instance_id_at(started_ns);
    let estimates = Topic::<Estimate>::subscriber(&link, &services::estimate(&domain))?;
    let commands = Topic::<Command>::publisher(&link, &services::command(&domain))?;
    let control = ControlChannel::open(&link, &domain, ROLE, instance, started_ns)?;
    // With a staleness deadline: the measurements start each step's deadline.
    let measurements: Option<TopicSubscriber<Measurement>> = if args.estimate_deadline_ms > 0 {
        Some(Topic::<Measurement>::subscriber(&link, &services::measurement(&domain))?)
    } else {
        None
    };
    let waitset = protocol::transport::waitset()?;
    let attach_failed = |e| ProcessError::Failed(format!("attaching to the WaitSet: {e:?}"));
    let mut guards = vec![
        waitset.attach_notification(&estimates).map_err(attach_failed)?,
        waitset.attach_notification(control.subscriber()).map_err(attach_failed)?,
    ];
    if let Some(m) = &measurements {
        guards.push(waitset.attach_notification(m).map_err(attach_failed)?);
    }
    let detail = format!("{}/{}", args.solver.name(), args.objective.name());
    // A restart in the same run resumes from its checkpoint.
    let mut kept = match (&args.checkpoint, args.takeover) {
        (Some(path), false) => checkpoint::load::<Vec<Checkpoint>>(path, ROLE, domain.as_str())
            .map_err(|e| ProcessError::Input(format!("--checkpoint: {e}")))?
            .unwrap_or_default(),
        _ => Vec::new(),
    };
    let resumed = kept.last().copied();
    if !args.takeover {
        // "Replay the run for me from my checkpoint's step, else from step 0" (a no-op at the start of a
        // launch: emitter-sim is not there).
        control.send(ControlKind::Hello, resumed.map_or(0, |c| c.step), &detail)?;
    }
    let mut summary = PlannerSummary { node: runtime::NodeSummary::new(ROLE, instance), ..PlannerSummary::default() };
    runtime::tell(args.supervised, &SupervisorLine::Ready);
    if !args.quiet {
        eprintln!(
            "planner: domain {domain}, {} / {}, {} steps, seed {}, instance {instance:#x}",
            args.objective.name(),
            args.solver.name(),
            scenario.steps,
            scenario.seed
        );
        if let Some(c) = &resumed {
            eprintln!("planner: resumed from the checkpoint of step {}", c.step);
        }
    }

    let (spin, block) = args.link.policy().split(IDLE_WAKEUP);
    let mut counter = RejectionCounter::new();
    let mut last_seq = None;
    // Sequence numbers start at the monotonic clock: a restarted planner continues above its predecessor.
    let mut seq = now_ns();
    let mut usable = UsableEstimates::new(MAX_CACHED_STEPS);
    let mut answers: BTreeMap<u64, (Vec<u64>, Command)> = BTreeMap::new();
    // The swap: the step a newer planner takes over from (this one stops before it), and with
    // --takeover the step this one takes over from (and how often the step before it was seen).
    let mut handover: Option<u64> = None;
    let mut from_step: Option<u64> = None;
    let mut seen_before_takeover = 0u32;
    let mut last_planned: Option<u64> = None;
    let mut tracker = (args.estimate_deadline_ms > 0)
        .then(|| HoldTracker::new(Duration::from_millis(args.estimate_deadline_ms), MAX_CACHED_STEPS as u64));
    let mut measurement_seq = None;
    'run: loop {
        let ready = || {
            Ok(estimates.has_samples()?
                || control.subscriber().has_samples()?
                || measurements.as_ref().map_or(Ok(false), |m| m.has_samples())?)
        };
        // Wake up for the earliest staleness deadline too.
        let (spin, block) = match tracker.as_ref().and_then(HoldTracker::next_deadline) {
            Some(d) => {
                let left = d.saturating_duration_since(Instant::now());
                (spin.min(left), block.min(left.max(Duration::from_micros(1))))
            }
            None => (spin, block),
        };
        match protocol::transport::wait_any(&waitset, spin, block, ready) {
            Ok(()) => {}
            Err(TransportError::Interrupted) => break,
            Err(e) => return Err(e.into()),
        }
        if link.interrupted() {
            break;
        }
        for msg in control.receive(&mut counter)? {
            match msg {
                Err(r) => {
                    summary.node.rejected += 1;
                    eprintln!("planner: rejected a control message: {r}");
                }
                Ok(c) if c.kind() == Some(ControlKind::Shutdown) => break 'run,
                Ok(c) if protocol::control::is_newer(&c, ControlKind::TakeOver, ROLE, started_ns) => {
                    let f = c.header.step;
                    if !args.quiet {
                        eprintln!("planner: a newer planner ({}) takes over from step {f}", c.detail());
                    }
                    handover = Some(handover.map_or(f, |h| h.min(f)));
                }
                Ok(_) => {}
            }
        }
        if let Some(f) = handover
            && last_planned.is_some_and(|l| l + 1 >= f)
        {
            summary.node.handed_over_at = Some(f);
            break 'run;
        }
        if let (Some(t), Some(sub)) = (tracker.as_mut(), measurements.as_ref()) {
            let now = Instant::now();
            for m in sub.receive_all()? {
                if let Err(r) = counter.check(&m, &mut measurement_seq) {
                    summary.node.rejected += 1;
                    eprintln!("planner: rejected a measurement: {r}");
                    continue;
                }
                let step = m.header.step;
                let positions = m.uavs().iter().map(|p| Vector2::new(p[0], p[1])).collect();
                let plannable = step < scenario.steps as u64 && !answers.contains_key(&step);
                t.on_measurement(step, now, positions, m.headings().to_vec(), staleness::fingerprint(&m), plannable);
            }
        }
        let received_ns = now_ns();
        for est in estimates.receive_all()? {
            if let Err(r) = counter.check(&est, &mut last_seq) {
                summary.node.rejected += 1;
                eprintln!("planner: rejected an estimate: {r}");
                continue;
            }
            summary.node.accepted += 1;
            let step = est.header.step;
            let own = matches!(est.status(), Some(EstimateStatus::Ok | EstimateStatus::Ambiguous))
                .then(|| from_wire(&(est.position, est.covariance)));
            let checkpoints = kept.iter().map(|c| (c.step, c.usable.as_ref().map(from_wire)));
            let plan_from = usable.record(step, own, checkpoints);
            if let Some(f) = handover
                && step >= f
            {
                summary.node.handed_over_at = Some(f);
                break 'run;
            }
            if args.takeover {
                match from_step {
                    None => {
                        // The running planner plans this step; this one takes over from the next.
                        let f = step + 1;
                        from_step = Some(f);
                        summary.node.took_over_at = Some(f);
                        control.send(ControlKind::TakeOver, f, &detail)?;
                        runtime::tell(args.supervised, &SupervisorLine::TakeOver { from_step: f });
                        if !args.quiet {
                            eprintln!("planner: taking over from step {f}");
                        }
                        seen_before_takeover = 1;
                        continue;
                    }
                    Some(f) if step + 1 == f => {
                        // Seen again: the old planner did not answer it (a retry); plan it here.
                        seen_before_takeover += 1;
                        if seen_before_takeover < 2 {
                            continue;
                        }
                    }
                    Some(f) if step < f => continue, // planned by the old planner
                    Some(_) => {}
                }
            }
            if step >= scenario.steps as u64 {
                continue; // the final step is recorded, not planned
            }
            if let Some(t) = tracker.as_mut()
                && t.on_estimate(step) == Freshness::Late
            {
                // Held already: the estimate updated the last usable one; the step's answer is its hold.
                summary.late_estimates += 1;
                if let Some((_, hold)) = answers.get(&step) {
                    seq += 1;
                    let mut again = *hold;
                    again.header.seq = seq;
                    commands.send(&again)?;
                    summary.node.resent += 1;
                    summary.node.published += 1;
                }
                continue;
            }
            let key = content_key(&est, plan_from.as_ref());
            if let Some((known, cached)) = answers.get(&step)
                && *known == key
            {
                seq += 1;
                let mut again = cached.carrying(&est, received_ns);
                again.header.seq = seq;
                commands.send(&again)?;
                summary.node.resent += 1;
                summary.node.published += 1;
                last_planned = last_planned.max(Some(step));
                continue;
            }
            let Some((z_hat, m)) = plan_from else {
                summary.errors += 1;
                eprintln!("planner: step {step}: the estimator has no fix yet, nothing to plan from");
                continue;
            };
            if args.plan_delay_ms > 0 && (args.plan_delay_steps.is_empty() || args.plan_delay_steps.contains(&step)) {
                // Fault injection: a slow planner (a signal ends the sleep and the loop).
                if !args.quiet {
                    eprintln!("planner: step {step}: delaying the plan by {} ms (--plan-delay-ms)", args.plan_delay_ms);
                }
                if link.sleep(Duration::from_millis(args.plan_delay_ms)).is_err() {
                    break 'run;
                }
            }
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
                    violated_constraints: active_mask::encode_violated(&plan.active_constraints),
                },
            )
            .map_err(|e| ProcessError::Failed(format!("step {step}: command: {e}")))?;
            // The checkpoint goes out before the answer that depends on it.
            if let Some(path) = &args.checkpoint
                && checkpoint::is_checkpoint_step(step)
                && kept.last().is_none_or(|c| c.step < step)
            {
                let state = Checkpoint { step, usable: plan_from.as_ref().map(to_wire) };
                checkpoint::push_kept(&mut kept, state, PROCESS_CHECKPOINTS);
                if let Err(e) = checkpoint::save(path, ROLE, domain.as_str(), &kept) {
                    eprintln!("planner: {e}");
                }
            }
            commands.send(&command)?;
            summary.node.published += 1;
            last_planned = last_planned.max(Some(step));
            answers.insert(step, (key, command));
            if answers.len() > MAX_CACHED_STEPS {
                answers.pop_first();
            }
        }
        // Steps whose estimate missed the deadline: hold course.
        if let Some(t) = tracker.as_mut() {
            for due in t.due(Instant::now()) {
                if from_step.is_some_and(|f| due.step < f) || (args.takeover && from_step.is_none()) {
                    continue; // the running planner's step
                }
                let hold = hold_command(&due, &scenario, args, &mut seq, instance)?;
                commands.send(&hold)?;
                summary.held += 1;
                summary.node.published += 1;
                last_planned = last_planned.max(Some(due.step));
                eprintln!(
                    "planner: step {}: no estimate within {} ms of the measurement; holding course",
                    due.step, args.estimate_deadline_ms
                );
                answers.insert(due.step, (Vec::new(), hold));
                if answers.len() > MAX_CACHED_STEPS {
                    answers.pop_first();
                }
            }
        }
        // A newer planner took over and this one has planned every step before it: hand over.
        if let Some(f) = handover
            && last_planned.is_some_and(|l| l + 1 >= f)
        {
            summary.node.handed_over_at = Some(f);
            break 'run;
        }
    }
    drop(guards);
    if !args.quiet {
        if let Some(f) = summary.node.handed_over_at {
            eprintln!("planner: handed over to the newer planner at step {f}");
        }
        eprintln!(
            "planner: stopped after {} commands ({} estimates, {counter})",
            summary.node.published, summary.node.accepted
        );
    }
    summary.node.cpu_s = runtime::cpu_seconds();
    Ok(summary)
}

/// The hold command of a step whose estimate missed the deadline (see the module docs).
fn hold_command(
    due: &DueStep,
    scenario: &Scenario,
    args: &PlannerArgs,
    seq: &mut u64,
    instance: u64,
) -> Result<Command, ProcessError> {
    let (headings, waypoints) = hold_plan(&due.positions, &due.headings, scenario.speed, scenario.dt);
    *seq += 1;
    let mut hold = Command::new(
        due.step,
        *seq,
        instance,
        &PlanInfo {
            headings: &headings,
            waypoints: &waypoints,
            objective: -1.0,
            solver: args.solver.name(),
            objective_name: args.objective.name(),
            plan_time_us: 0,
            active_constraints: 0,
            violated_constraints: 0,
        },
    )
    .map_err(|e| ProcessError::Failed(format!("step {}: hold command: {e}", due.step)))?;
    hold.flags |= Command::FLAG_HOLD;
    Ok(hold)
}

/// Runs the planner and maps the outcome to an exit code (errors as one `error:` line on stderr); in
/// supervised mode the summary goes to stdout as `summary {json}`.
pub fn main_with(args: &PlannerArgs) -> ExitCode {
    runtime::exit_with(ROLE, args.supervised, run(args))
}
