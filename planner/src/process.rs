//! The `planner` process: receive an [`Estimate`] → [`plan_step`] → publish a [`Command`].
//!
//! A handler on the node runtime ([`runtime::node`]): it waits on the estimate topic (and, with a
//! staleness deadline, the measurement topic) in the runtime's event loop. For every valid estimate of a
//! step below the scenario's `steps` it builds the [`PlanRequest`] exactly as `uavloc simulate` does (UAV
//! positions and headings from the estimate, ẑ and M from it, run seed and step) and publishes the
//! command. The final step (`step == steps`) is measured and estimated but not planned, as in the
//! in-process loop.
//!
//! **The planner is a function of the estimate it receives**: it keeps no state across steps. A usable
//! estimate is planned from its own fix; a *failed* one carries the standing estimate (the last usable
//! one, which the estimator keeps: [`Estimate::plan_from`]) and is planned from that — exactly what
//! `uavloc simulate` plans from. So a replayed estimate gets the same command again, and a restarted or
//! swapped-in planner plans exactly what its predecessor would have, with no checkpoint and no replay of
//! the past: at start-up it announces itself ([`ControlKind::Hello`]), asks for a replay of
//! [`ControlKind::IN_FLIGHT`] ([`ControlKind::Replay`]) and
//! emitter-sim publishes the step in flight again, whose estimate the dead planner may have taken with
//! it.
//!
//! - Only `target = "chan"` is supported: `controlled` mode needs the true emitter, which the pipeline
//!   never shows the planner (use `uavloc simulate` for it).
//! - Invalid estimates are counted (per rejection kind) and ignored. A valid estimate that cannot be
//!   planned (the wire's checks are the planner's, so none is known) ends the run (exit code 3, naming
//!   the step and why), as it ends `uavloc simulate`: a replay of the step would fail the same way.
//! - **Staleness deadline** (`--estimate-deadline-ms D`, off by default): the planner also subscribes to
//!   the measurements; when the estimate of the newest measured step has not arrived D ms after its
//!   measurement (a deadline of the event loop), the planner *holds*: it publishes a command flagged
//!   [`Command::FLAG_HOLD`] (objective −1, no plan time) in which the UAVs loiter on their backup
//!   circles ([`planning::hold`]; with `safety = "waypoints"` they hold course), counts it (`held`) and
//!   logs it; the monitor shows the step as `estimate_stale`. The
//!   estimate that comes later is answered with the same hold (`late_estimates`). With a deadline the run
//!   depends on timing (like emitter-sim's real-time mode), so lock-step reproductions of `simulate`
//!   leave it off.
//! - `--plan-delay-ms` (with `--plan-delay-steps`) is a test / fault-injection aid: the planner sleeps
//!   before planning those steps, like a slow one, e.g. to make its commands miss their step in
//!   emitter-sim's real-time mode (`tests/e2e/realtime.rs`).
//! - SIGINT/SIGTERM, or a [`ControlKind::Shutdown`] on the control topic, end the loop cleanly (exit 0);
//!   the iceoryx2 resources are released on the way out.
//!
//! # Swapping planners (`--takeover`, what `uavloc swap planner` starts)
//!
//! A planner started with `--takeover` joins a running pipeline without a replay: on the first estimate
//! it sees (step k) it announces [`ControlKind::TakeOver`] from step k + 1 and prints
//! `takeover {"from_step": k + 1}` (supervised). The running planner plans every step before k + 1 —
//! step k included — and then exits (exit 0, its summary says `handed_over`); the new one plans from
//! k + 1 on. No step is planned twice and none is missed; should the old planner die before its last
//! command, the emitter-sim's retry replays step k and the new planner plans it. A planner that sees a
//! take-over by a newer planner behaves as the old one.

use std::process::ExitCode;
use std::time::{Duration, Instant};

use model::load_scenario;
use nalgebra::Vector2;
use protocol::services;
use protocol::{Command, ControlKind, Estimate, Measurement, Topic, TopicPublisher, TopicSubscriber};
use runtime::recovery::HISTORY_STEPS;
use runtime::{Flow, Handler, Join, Node, ProcessError};

use crate::args::{PlannerArgs, check_scenario};
use crate::staleness::{self, Freshness, HoldTracker};
use crate::summary::PlannerSummary;
use crate::wire;
use model::scenario::Scenario;
use planning::step::{PlanRequest, plan_step};

pub use crate::ROLE;

/// The planner's handler: its ports, the scenario, and the bookkeeping of a swap and of the staleness
/// deadline (no state of the run: see the module docs).
struct Planner<'a> {
    args: &'a PlannerArgs,
    scenario: Scenario,
    detail: String,
    estimates: &'a TopicSubscriber<Estimate>,
    measurements: Option<&'a TopicSubscriber<Measurement>>,
    commands: &'a TopicPublisher<Command>,
    last_seq: Option<u64>,
    /// One measurement source per run, one measurement per step ([`protocol::source`]).
    measurement_gate: protocol::MeasurementGate,
    /// With a staleness deadline: the steps measured and not yet estimated, and the steps held.
    tracker: Option<HoldTracker>,
    /// With --takeover: the step this planner takes over from, and how often the step before it was seen.
    from_step: Option<u64>,
    seen_before_takeover: u32,
    last_planned: Option<u64>,
    summary: PlannerSummary,
    /// With --stated-position-margins: the largest stated UAV position σ of each recent step, metres.
    position_sigmas: std::collections::BTreeMap<u64, f64>,
}

impl Planner<'_> {
    /// Publishes `command` as the answer to its step (`again`: a step answered before, sent as a copy
    /// without a publish stamp, so that nobody times it as the step's).
    fn answer(&mut self, node: &mut Node, mut command: Command, again: bool) -> Result<(), ProcessError> {
        command.header.seq = node.next_seq();
        self.commands.publish(&command, again)?;
        node.summary().published += 1;
        self.last_planned = self.last_planned.max(Some(command.header.step));
        Ok(())
    }

    /// Whether a step is the running planner's (this one is taking over); the take-over is announced on the
    /// first estimate.
    fn belongs_to_predecessor(&mut self, node: &mut Node, step: u64) -> Result<bool, ProcessError> {
        if !self.args.takeover {
            return Ok(false);
        }
        match self.from_step {
            None => {
                // The running planner plans this step; this one takes over from the next.
                self.from_step = Some(step + 1);
                node.take_over(step + 1, &self.detail)?;
                self.seen_before_takeover = 1;
                Ok(true)
            }
            Some(f) if step + 1 == f => {
                // Seen again: the old planner did not answer it (a retry); plan it here.
                self.seen_before_takeover += 1;
                Ok(self.seen_before_takeover < 2)
            }
            Some(f) => Ok(step < f),
        }
    }

    /// The staleness deadline: measurements start a step's deadline.
    fn track_measurements(&mut self, node: &mut Node) -> Result<(), ProcessError> {
        let Some(sub) = self.measurements else { return Ok(()) };
        let (batch, _) = node.receive_measurements(sub, &mut self.measurement_gate)?;
        // The deadline runs from when the measurements are in hand (see `Node::receive`).
        let now = Instant::now();
        for m in batch {
            let step = m.header.step;
            if self.args.stated_position_margins {
                let most = m.position_sigmas[..m.len()].iter().copied().fold(0.0, f64::max);
                self.position_sigmas.insert(step, most);
                while self.position_sigmas.len() as u64 > HISTORY_STEPS {
                    self.position_sigmas.pop_first();
                }
            }
            let Some(t) = self.tracker.as_mut() else { continue };
            let positions = tdoa::points_from_arrays(m.uavs());
            let plannable = step < self.scenario.steps as u64 && self.last_planned.is_none_or(|l| step > l);
            t.on_measurement(step, now, positions, m.headings().to_vec(), staleness::fingerprint(&m), plannable);
        }
        Ok(())
    }

    /// The scenario step `step` is planned with ([`wire::scenario_for`]).
    fn scenario_of(&self, step: u64, range_sigmas: Option<&[f64]>) -> Option<Scenario> {
        wire::scenario_for(&self.scenario, range_sigmas, self.position_sigmas.get(&step).copied())
    }

    /// The hold command of a step without a plan ([`planning::hold`], [`wire::hold_command`]): the UAVs
    /// at `at` with `headings` loiter on their backup circles (certified planner) or hold course.
    fn hold(&self, step: u64, at: &[Vector2<f64>], headings: &[f64], instance: u64) -> Result<Command, ProcessError> {
        let hold = planning::hold::without_plan(at, headings, &self.scenario);
        let names = (self.args.solver, self.args.objective);
        wire::hold_command(step, at, headings, &hold, &self.scenario, names, instance).map_err(ProcessError::Failed)
    }

    /// The command of one estimate; an estimate that cannot be planned ends the run (naming the step and
    /// the reason), as it ends `uavloc simulate`.
    fn plan(&mut self, node: &mut Node, est: &Estimate, received_ns: u64) -> Result<Command, ProcessError> {
        let step = est.header.step;
        // A valid estimate of another formation than the scenario's (an external front end flying other
        // UAVs than the launch's --scenario): rejected, naming both counts — not planned as a length error.
        let (got, want) = (est.uavs().len(), self.scenario.uav_count());
        if got != want {
            // Counted, and the run ends at once: every later estimate is of the same other formation.
            node.summary().rejected += 1;
            return Err(ProcessError::Unrecoverable(format!(
                "rejected the estimate of step {step}: {got} UAVs, this run's scenario has {want} (a front end \
                 flying another formation than --scenario?); the run cannot go on"
            )));
        }
        let Some((position, covariance)) = est.plan_from() else {
            if !planning::gives_up_without_fix(step, est.heard.count_ones() as usize) {
                // No fix so far (a silent emitter, lost arrivals, a burst without a physical solution): hold
                // and try the next burst, as `uavloc simulate` does.
                let hold = self.hold(step, &tdoa::points_from_arrays(est.uavs()), est.headings(), node.instance())?;
                return Ok(hold.with_state_of(est));
            }
            // No fix in the first FIRST_FIX_STEPS steps, and this step's burst was heard well enough for
            // one: the run cannot go on, as `uavloc simulate` of the scenario says at the same step.
            return Err(ProcessError::Unrecoverable(format!(
                "step {step}: the estimator found no fix in the first {} steps and has no estimate to plan from \
                 (no emitter position fits the range differences: too much noise for this geometry, or no burst \
                 heard?) — the run cannot go on",
                planning::FIRST_FIX_STEPS
            )));
        };
        let args = self.args;
        if args.plan_delay_ms > 0 && (args.plan_delay_steps.is_empty() || args.plan_delay_steps.contains(&step)) {
            // Fault injection: a slow planner (a signal ends the sleep and the loop).
            node.say(format_args!("step {step}: delaying the plan by {} ms (--plan-delay-ms)", args.plan_delay_ms));
            node.link().sleep(Duration::from_millis(args.plan_delay_ms))?;
        }
        let (z_hat, m) = tdoa::estimate_from_arrays(&position, &covariance);
        let positions = tdoa::points_from_arrays(est.uavs());
        // The noise the measurement stated (an external front end's σ) is the noise planned for; a quiet
        // link's reach widens the safety margins (--stated-position-margins).
        let stated = self.scenario_of(step, est.range_sigmas());
        let plan = match plan_step(&PlanRequest {
            positions: &positions,
            headings: est.headings(),
            estimate: z_hat,
            covariance: m,
            scenario: stated.as_ref().unwrap_or(&self.scenario),
            objective: args.objective,
            solver: args.solver,
            run_seed: self.scenario.seed,
            step,
            motion: wire::motion_of(est),
        }) {
            Ok(plan) => plan,
            Err(e) => {
                // The planner is a function of the estimate: a replay would fail the same way, and the
                // step would wait for a command for ever. The run ends, as `uavloc simulate` of the same
                // estimate ends with this error.
                return Err(ProcessError::unrecoverable_because(
                    format!("step {step}: no plan for the estimate at ({:.1}, {:.1}) m", z_hat.x, z_hat.y),
                    e,
                    " — the run cannot go on",
                ));
            }
        };
        let names = (args.solver, args.objective);
        wire::plan_command(est, received_ns, node.instance(), &plan, names).map_err(ProcessError::Failed)
    }
}

impl Handler for Planner<'_> {
    fn on_wake(&mut self, node: &mut Node) -> Result<Flow, ProcessError> {
        self.track_measurements(node)?;
        let (batch, received_ns) = node.receive(self.estimates, &mut self.last_seq, "an estimate")?;
        for est in batch {
            let step = est.header.step;
            if node.hands_over(step) {
                return Ok(Flow::Stop);
            }
            if self.belongs_to_predecessor(node, step)? || step >= self.scenario.steps as u64 {
                continue; // the running planner's step, or the final step (recorded, not planned)
            }
            let late = self.tracker.as_mut().is_some_and(|t| t.on_estimate(step) == Freshness::Late);
            let again = late || self.last_planned.is_some_and(|l| step <= l);
            let command = if late {
                // Held already: the step's answer is its hold.
                self.summary.late_estimates += 1;
                node.summary().resent += 1;
                self.hold(step, &tdoa::points_from_arrays(est.uavs()), est.headings(), node.instance())?
            } else {
                if again {
                    node.summary().resent += 1; // a replayed estimate: planned again, the same command
                }
                self.plan(node, &est, received_ns)?
            };
            self.answer(node, command, again)?;
        }
        // Steps whose estimate missed the deadline: hold (planning::hold).
        let due = self.tracker.as_mut().map(|t| t.due(Instant::now())).unwrap_or_default();
        for due in due {
            if self.args.takeover && self.from_step.is_none_or(|f| due.step < f) {
                continue; // the running planner's step
            }
            let hold = self.hold(due.step, &due.positions, &due.headings, node.instance())?;
            self.answer(node, hold, false)?;
            self.summary.held += 1;
            node.warn(format_args!(
                "step {}: no estimate within {} ms of the measurement; holding ({})",
                due.step,
                self.args.estimate_deadline_ms,
                if hold.headings() == due.headings.as_slice() { "course" } else { "on the backup circles" }
            ));
        }
        Ok(Flow::Continue)
    }

    fn deadline(&self) -> Option<Instant> {
        self.tracker.as_ref().and_then(HoldTracker::next_deadline)
    }

    fn last_answered(&self) -> Option<u64> {
        self.last_planned
    }
}

/// Runs the planner until SIGINT/SIGTERM, a shutdown or a hand-over.
pub fn run(args: &PlannerArgs) -> Result<PlannerSummary, ProcessError> {
    let scenario = load_scenario(args.process.run.scenario.as_deref(), args.process.run.steps, args.process.run.seed)
        .map_err(|e| ProcessError::input_because("--scenario", e))?;
    check_scenario(&scenario).map_err(ProcessError::Input)?;
    let Some(mut node) = Node::open(ROLE, &args.process.node)? else {
        return Ok(PlannerSummary { node: runtime::NodeSummary::new(ROLE, 0), ..PlannerSummary::default() });
    };
    node.set_run(scenario.run_id());
    let domain = node.domain().clone();
    let estimates = Topic::<Estimate>::subscriber(node.link(), &services::estimate(&domain))?;
    let commands = Topic::<Command>::publisher(node.link(), &services::command(&domain))?;
    // With a staleness deadline: the measurements start each step's deadline.
    let measurements = (args.estimate_deadline_ms > 0 || args.stated_position_margins)
        .then(|| Topic::<Measurement>::subscriber(node.link(), &services::measurement(&domain)))
        .transpose()?;
    let detail = control_detail(args.solver.name(), args.objective.name());
    node.join(if args.takeover { Join::TakeOver } else { Join::Replay(ControlKind::IN_FLIGHT) }, &detail)?;
    node.say(format_args!(
        "domain {domain}, {} / {}, {} steps, seed {}, instance {:#x}",
        args.objective.name(),
        args.solver.name(),
        scenario.steps,
        scenario.seed,
        node.instance()
    ));
    let tracker = (args.estimate_deadline_ms > 0)
        .then(|| HoldTracker::new(Duration::from_millis(args.estimate_deadline_ms), HISTORY_STEPS));
    let mut planner = Planner {
        args,
        scenario,
        detail,
        estimates: &estimates,
        measurements: measurements.as_ref(),
        commands: &commands,
        last_seq: None,
        measurement_gate: protocol::MeasurementGate::default(),
        tracker,
        from_step: None,
        seen_before_takeover: 0,
        last_planned: None,
        summary: PlannerSummary::default(),
        position_sigmas: std::collections::BTreeMap::new(),
    };
    let mut inputs: Vec<&dyn protocol::Waitable> = vec![&estimates];
    if let Some(m) = &measurements {
        inputs.push(m);
    }
    node.run(&inputs, &mut planner)?;
    let published = node.summary().published;
    let accepted = node.summary().accepted;
    node.say(format_args!("stopped after {published} commands ({accepted} messages received)"));
    Ok(PlannerSummary { node: node.finish(), ..planner.summary })
}

/// Runs the planner and maps the outcome to an exit code (errors as one `error:` line on stderr); in
/// supervised mode the summary goes to stdout as `summary {json}`.
pub fn main_with(args: &PlannerArgs) -> ExitCode {
    runtime::exit_with(ROLE, args.process.node.supervised, run(args))
}

/// The planner's detail on the control topic (what the monitor shows when it joins): `solver/objective`,
/// or the solver alone where that does not fit the field's [`protocol::Name16::CAPACITY`] bytes — never a
/// name cut short ("gradient/analyti"). Its plans name both in full (`PlanInfo`).
fn control_detail(solver: &str, objective: &str) -> String {
    let both = format!("{solver}/{objective}");
    if both.len() <= protocol::Name16::CAPACITY { both } else { solver.to_string() }
}

#[cfg(test)]
mod tests {
    use super::control_detail;

    #[test]
    fn the_control_detail_is_never_a_cut_name() {
        assert_eq!(control_detail("ga", "analytical"), "ga/analytical");
        assert_eq!(control_detail("pso", "posterior"), "pso/posterior");
        // 19 bytes: the solver alone.
        assert_eq!(control_detail("gradient", "analytical"), "gradient");
        assert_eq!(control_detail("formation", "posterior-cubature"), "formation");
    }
}
