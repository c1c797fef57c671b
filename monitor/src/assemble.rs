//! Rebuilds the [`RunRecord`] of a pipeline run from the messages the monitor receives — the same record,
//! number for number, that `uavloc simulate` builds in one process.
//!
//! Messages of the four topics arrive in any interleaving; the [`Assembler`] keeps them per step and
//! completes steps strictly in order. Step k is complete when its [`Measurement`], [`Estimate`] and
//! [`Truth`] have arrived, and — for every step but the last (`scenario.steps`, measured but not planned) —
//! the truth of step k + 1, which says what the world did with step k's command
//! ([`CommandOutcome`]: only emitter-sim knows whether a command came in time), and unless that says
//! *missed*, the [`Command`] of step k. The [`StepRecord`] then takes:
//!
//! - `uavs` from the measurement, `headings_rad` from the command (the headings chosen at step k), or on
//!   the last step the measurement's current headings;
//! - `estimate`, `estimate_cov`, `estimate_status` from the estimate; a `failed` estimate carries the
//!   standing (last usable) estimate on the wire ([`Estimate::plan_from`]) — which is what the estimator
//!   library reports on failure — so the assembler keeps no estimate of its own;
//! - `crlb_true_m`, `rmse_m` from [`step_metrics`] with the measurement's geometry and σ, the truth, the
//!   scenario's R and seed, and the estimate as prior;
//! - `objective_value` = √(the command's criterion) (`None` when the planner sent the "not finite" marker,
//!   a negative value), `plan_ms` from the command's microseconds (so rounded to 1 µs);
//! - `active_constraints` decoded from the command's bitmask ([`model::active_mask::decode`]: the same
//!   strings as `simulate`, except that a violated constraint has no magnitude).
//!
//! A step whose command was *missed* (emitter-sim's real-time mode: no command before the next step was
//! due) records what the world flew: `headings_rad` = the hold of a step without a plan
//! ([`planning::hold::without_plan`] of the measurement's positions and headings: the backup circles,
//! or the current headings with `safety = "waypoints"`) with its spacing certificate
//! (`safety.certified`), `objective_value` and `plan_ms` null, `active_constraints` =
//! `["command_missed"]` ([`COMMAND_MISSED`]), no planner; a command for it that arrives anyway is
//! ignored.
//!
//! A step whose command is a *hold* ([`Command::FLAG_HOLD`]: no fresh estimate reached the planner within
//! its staleness deadline, or none to plan from before a first fix; the UAVs loiter on their backup
//! circles) records its headings, `objective_value` and `plan_ms` null, `active_constraints` =
//! `["estimate_stale"]` ([`ESTIMATE_STALE`]), its spacing certificate (`safety.certified`), and the
//! planner that held.
//!
//! Messages for steps already completed or beyond the last step are ignored (and counted).
//!
//! **Without a truth** ([`Assembler::without_truth`]: an external front end publishes the measurements,
//! no world publishes truths) step k is complete with its measurement, estimate and — unless it is the
//! last — command; nobody says whether a command was flown, so none is *missed*. The truth-based fields
//! (`truth`, `crlb_true_m`, `rmse_m`, `estimate_error_m`, …) are absent, not zero; `crlb_at_estimate_m`
//! (the CRLB of the step's geometry at its estimate) is there in both kinds of run. Truths that arrive
//! anyway are ignored (and counted).

use std::collections::BTreeMap;

use model::Scenario;
use model::active_mask;
use nalgebra::Vector2;
use protocol::{Command, CommandOutcome, Estimate, EstimateStatus, Latencies, Measurement, Stamps, Truth};
use tdoa::fusion::EstimatorKind;
use tdoa::{NoiseModel, Sensors};

use record::metrics::{crlb_at, step_metrics};
use record::record::{PlannerRef, RunRecord, StepReceiver, StepRecord, StepSafety};

/// The `active_constraints` entry of a step whose command was missed (see the module docs).
pub const COMMAND_MISSED: &str = "command_missed";

/// The `active_constraints` entry of a step whose command was a hold (see the module docs).
pub const ESTIMATE_STALE: &str = "estimate_stale";

/// The planner that produced a step's command.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct PlannerInfo {
    /// Its instance id.
    pub instance: u64,
    /// Solver name.
    pub solver: String,
    /// Objective name.
    pub objective: String,
}

/// One completed step: its record plus what the live view shows.
#[derive(Debug, Clone, PartialEq)]
pub struct CompletedStep {
    /// The record, as `simulate` would write it.
    pub record: StepRecord,
    /// Latencies of the step's chain (from the command's stamps; on the last step from the estimate's).
    pub latencies: Latencies,
    /// The planner of the step's command (`None` on the last step).
    pub planner: Option<PlannerInfo>,
    /// Distance of the estimate from the truth, metres (`None` without a truth).
    pub error_m: Option<f64>,
    /// The true emitter position of the step, metres (`None` without a truth).
    pub truth: Option<[f64; 2]>,
    /// The step's command was missed (real-time mode): the UAVs kept their headings.
    pub missed: bool,
    /// The step's command was a hold: no fresh estimate reached the planner in time, the UAVs kept their
    /// headings.
    pub held: bool,
    /// The stamps of the step's chain (the command's; on the last step, or a missed one, the estimate's).
    pub chain: Stamps,
    /// When emitter-sim received the step's command (from the next step's truth; 0 if unknown).
    pub command_received_ns: u64,
}

#[derive(Debug, Clone, Default)]
struct Pending {
    measurement: Option<Measurement>,
    estimate: Option<Estimate>,
    truth: Option<Truth>,
    command: Option<Command>,
}

/// Collects messages and completes steps in order; see the module docs.
#[derive(Debug, Clone)]
pub struct Assembler {
    scenario: Scenario,
    next: u64,
    pending: BTreeMap<u64, Pending>,
    /// The estimator's kind, from the first estimate (`fused` / `snapshot`).
    estimator: Option<&'static str>,
    steps: Vec<StepRecord>,
    /// Whether completed records are kept in `steps` (else the caller keeps them, e.g. in a log).
    keep: bool,
    emitter: Option<[f64; 2]>,
    names: Option<(String, String)>,
    ignored: u64,
    /// Whether a world publishes truths (see the module docs).
    truth: bool,
}

/// The estimator a recorded step names (the run's as it was known then, or the scenario's).
fn recorded_estimator(s: &StepRecord) -> Option<&'static str> {
    s.estimator.as_deref()?.parse::<EstimatorKind>().ok().map(EstimatorKind::name)
}

/// [`recorded_estimator`] of a step that had a fix ([`Estimate::estimator_name`]: the first one is the
/// run's).
fn known_estimator(s: &StepRecord) -> Option<&'static str> {
    if s.estimate_status == EstimateStatus::Failed.name() { None } else { recorded_estimator(s) }
}

impl Assembler {
    /// An assembler for a run of `scenario` (its `steps`, `rmse_resamples` and `seed` are used).
    pub fn new(scenario: Scenario) -> Self {
        Self {
            scenario,
            next: 0,
            pending: BTreeMap::new(),
            estimator: None,
            steps: Vec::new(),
            keep: true,
            emitter: None,
            names: None,
            ignored: 0,
            truth: true,
        }
    }

    /// The same assembler for a run without a truth (see the module docs).
    pub fn without_truth(mut self) -> Self {
        self.truth = false;
        self
    }

    /// Whether this run has a truth.
    pub fn has_truth(&self) -> bool {
        self.truth
    }

    /// An assembler that continues a run whose steps `0..steps.len()` are already recorded (e.g. read back
    /// from a monitor's log after a restart): `emitter` is the truth, `names` the run's (objective,
    /// solver). `None` if the steps are not numbered 0, 1, 2, ….
    pub fn resume(
        scenario: Scenario,
        steps: Vec<StepRecord>,
        emitter: Option<[f64; 2]>,
        names: Option<(String, String)>,
    ) -> Option<Self> {
        if steps.iter().enumerate().any(|(i, s)| s.step != i as u64) || steps.len() as u64 > scenario.steps as u64 + 1 {
            return None;
        }
        let mut a = Self::new(scenario);
        a.next = steps.len() as u64;
        a.emitter = emitter;
        a.names = names;
        a.estimator = steps.iter().find_map(known_estimator);
        a.steps = steps;
        Some(a)
    }

    /// The same assembler, but it does not keep the completed records (its memory then does not grow with
    /// the run): [`record`](Self::record) has no steps, the caller keeps them (the monitor's log).
    pub fn forgetting(mut self) -> Self {
        self.keep = false;
        self.steps = Vec::new();
        self
    }

    /// Like [`resume`](Self::resume) for an assembler that does not keep records ([`forgetting`](Self::forgetting)):
    /// steps `0..next` are recorded elsewhere, `last` is the record of step `next − 1` (`None` when
    /// `next` is 0). `None` if `last` is not that step or `next` is beyond the run.
    pub fn resume_forgetting(
        scenario: Scenario,
        next: u64,
        last: Option<&StepRecord>,
        emitter: Option<[f64; 2]>,
        names: Option<(String, String)>,
    ) -> Option<Self> {
        if next > scenario.steps as u64 + 1 || last.map(|s| s.step + 1).unwrap_or(0) != next {
            return None;
        }
        let mut a = Self::new(scenario).forgetting();
        a.next = next;
        a.emitter = emitter;
        a.names = names;
        // The run's estimator as known at that step (a failed step's was resolved from the run's).
        a.estimator = last.and_then(recorded_estimator);
        Some(a)
    }

    /// The last step of the run (`scenario.steps`).
    pub fn last_step(&self) -> u64 {
        self.scenario.steps as u64
    }

    /// The newest step of which a message is waiting (none when nothing is pending).
    pub fn newest_pending_step(&self) -> Option<u64> {
        self.pending.keys().next_back().copied()
    }

    /// The next step to record when its measurement has not come while a later step's has: `(that
    /// step, the first later step whose measurement is in)`. A front end that skipped a step (or whose
    /// measurement of it was lost) leaves the run waiting here; a lock-step world never does.
    pub fn measurement_gap(&self) -> Option<(u64, u64)> {
        if self.is_done() || self.pending.get(&self.next).is_some_and(|p| p.measurement.is_some()) {
            return None;
        }
        let later = self.pending.range(self.next + 1..).find(|(_, p)| p.measurement.is_some())?;
        Some((self.next, *later.0))
    }

    /// The measurement of `step` waiting for the rest of its step (the copy accepted first).
    pub fn pending_measurement(&self, step: u64) -> Option<&Measurement> {
        self.pending.get(&step).and_then(|p| p.measurement.as_ref())
    }

    /// The next step to complete.
    pub fn next_step(&self) -> u64 {
        self.next
    }

    /// Whether every step up to the last one is complete.
    pub fn is_done(&self) -> bool {
        self.next > self.last_step()
    }

    /// Messages ignored so far (for a completed step or beyond the last one).
    pub fn ignored(&self) -> u64 {
        self.ignored
    }

    fn slot(&mut self, step: u64) -> Option<&mut Pending> {
        if step < self.next || step > self.last_step() {
            self.ignored += 1;
            return None;
        }
        Some(self.pending.entry(step).or_default())
    }

    /// Adds a (validated) measurement; `false` if it is ignored. A repeat of one already in (a replay: same
    /// content, new sequence number, no publish stamp) keeps the first, whose stamps time the step.
    pub fn add_measurement(&mut self, m: Measurement) -> bool {
        self.slot(m.header.step).map(|p| p.measurement.get_or_insert(m)).is_some()
    }

    /// Adds a (validated) estimate; `false` if it is ignored. A repeat keeps the first (see
    /// [`Assembler::add_measurement`]).
    pub fn add_estimate(&mut self, e: Estimate) -> bool {
        self.slot(e.header.step).map(|p| p.estimate.get_or_insert(e)).is_some()
    }

    /// Adds a (validated) truth; `false` if it is ignored. A repeat keeps the first (see
    /// [`Assembler::add_measurement`]).
    pub fn add_truth(&mut self, t: Truth) -> bool {
        if !self.truth {
            self.ignored += 1;
            return false;
        }
        self.slot(t.header.step).map(|p| p.truth.get_or_insert(t)).is_some()
    }

    /// Adds a (validated) command; `false` if it is ignored (also a command for the last step, which is
    /// never planned, and a second command for a step: emitter-sim flies the first one it gets, so that is
    /// the one recorded).
    pub fn add_command(&mut self, c: Command) -> bool {
        if c.header.step >= self.last_step() {
            self.ignored += 1;
            return false;
        }
        match self.slot(c.header.step) {
            Some(p) if p.command.is_none() => {
                p.command = Some(c);
                true
            }
            Some(_) => {
                self.ignored += 1;
                false
            }
            None => false,
        }
    }

    /// Completes every step whose messages are all in, in order.
    pub fn complete_ready(&mut self) -> Vec<CompletedStep> {
        std::iter::from_fn(|| self.complete_next()).collect()
    }

    /// Completes the next step if its messages are all in (one at a time: a caller may do other work, or
    /// give the CPU away, between two steps).
    pub fn complete_next(&mut self) -> Option<CompletedStep> {
        if self.is_done() {
            return None;
        }
        let k = self.next;
        let planned = k < self.last_step();
        // What became of step k's command, from the truth of step k + 1.
        let next_truth = self.pending.get(&(k + 1)).and_then(|p| p.truth.as_ref());
        let outcome = next_truth.map(Truth::previous_command);
        let command_received_ns = next_truth.map_or(0, |t| t.header.stamps.trigger_command_received_ns);
        let missed = outcome == Some(Some(CommandOutcome::Missed));
        let truth = self.truth;
        let ready = self.pending.get(&k).is_some_and(|p| {
            p.measurement.is_some()
                && p.estimate.is_some()
                && (p.truth.is_some() || !truth)
                && (!planned || ((outcome.is_some() || !truth) && (missed || p.command.is_some())))
        });
        if !ready {
            return None;
        }
        let p = self.pending.remove(&k).unwrap_or_default();
        let (Some(m), Some(e), t) = (p.measurement, p.estimate, p.truth) else { return None };
        if missed && p.command.is_some() {
            self.ignored += 1; // it came, but too late for the world
        }
        let command = if missed { None } else { p.command.as_ref() };
        let mut step = self.complete(k, &m, &e, t.as_ref(), command, planned && missed);
        if command.is_some() {
            step.command_received_ns = command_received_ns;
        }
        self.next += 1;
        Some(step)
    }

    fn complete(
        &mut self,
        k: u64,
        m: &Measurement,
        e: &Estimate,
        t: Option<&Truth>,
        c: Option<&Command>,
        missed: bool,
    ) -> CompletedStep {
        let status = e.status().unwrap_or(EstimateStatus::Failed);
        let estimator = e.estimator_name();
        if let Some(kind) = estimator {
            self.estimator.get_or_insert(kind);
        }
        let velocity = (status.is_usable() && e.model == 1).then_some((e.velocity, e.velocity_cov));
        let (position, covariance) = e.plan_from().unwrap_or(([f64::NAN; 2], [[f64::NAN; 2]; 2]));
        let truth = t.map(|t| Vector2::new(t.position[0], t.position[1]));
        if let Some(t) = t {
            self.emitter.get_or_insert(t.position);
        }
        let estimate = Vector2::new(position[0], position[1]);
        let geometry = NoiseModel::from_range_sigmas(m.sigmas()).and_then(|noise| Sensors::new(m.uavs(), noise)).ok();
        let (crlb_true_m, rmse_m) = match (&geometry, &truth) {
            (Some(sensors), Some(truth)) => {
                let metrics =
                    step_metrics(sensors, truth, self.scenario.rmse_resamples, self.scenario.seed, k, Some(estimate));
                (Some(metrics.crlb_true_m), metrics.rmse_m)
            }
            (None, Some(_)) => (Some(f64::INFINITY), None),
            (_, None) => (None, None),
        };
        let crlb_at_estimate_m = geometry.as_ref().and_then(|sensors| crlb_at(sensors, &estimate));
        let mut record = StepRecord {
            step: k,
            geo: None,
            uavs: m.uavs().to_vec(),
            headings_rad: m.headings().to_vec(),
            estimate: position,
            estimate_cov: covariance,
            estimate_status: status.name().to_string(),
            estimate_velocity: velocity.map(|v| v.0),
            estimate_velocity_cov: velocity.map(|v| v.1),
            truth: t.map(|t| t.position),
            estimate_error_m: None,
            nees: None,
            pcrlb_m: None,
            min_true_distance_m: None,
            crlb_true_m,
            crlb_at_estimate_m,
            pcrlb_at_estimate_m: None,
            rmse_m,
            objective_value: None,
            plan_ms: None,
            active_constraints: if missed { vec![COMMAND_MISSED.to_string()] } else { Vec::new() },
            planner: None,
            criterion_ess: None,
            range_sigmas_m: {
                let stated = m.stated_sigmas().0;
                (stated != self.scenario.range_sigmas()).then_some(stated)
            },
            estimator: Some(estimator.or(self.estimator).unwrap_or(self.scenario.estimator.name()).to_string()),
            safety: None,
            // The reflections are the world's truth (absent with an external front end).
            receiver: StepReceiver::from_masks(
                m.len(),
                m.heard,
                e.outliers,
                Some(m.is_silent()),
                t.map(|t| (t.multipath & 0xff) as u8),
            )
            .unless_complete(m.len()),
        };
        let mut planner = None;
        let chain = c.map_or(e.header.stamps, |c| c.header.stamps);
        let latencies = match c {
            Some(c) => {
                record.headings_rad = c.headings().to_vec();
                // A plan and a hold carry their certificate (a hold's: the spacing; none with
                // `safety = "waypoints"`).
                record.safety = c.certified().map(StepSafety::of_word);
                if c.is_hold() {
                    record.active_constraints = vec![ESTIMATE_STALE.to_string()];
                } else {
                    record.objective_value = (c.objective >= 0.0).then(|| c.objective.sqrt());
                    record.plan_ms = Some(c.plan_time_us as f64 / 1e3);
                    record.active_constraints =
                        active_mask::decode(c.active_constraints, c.violated_constraints, c.len());
                }
                let info = PlannerInfo {
                    instance: c.planner_instance,
                    solver: c.solver().unwrap_or("?").to_string(),
                    objective: c.objective_name().unwrap_or("?").to_string(),
                };
                self.names.get_or_insert_with(|| (info.objective.clone(), info.solver.clone()));
                record.planner = Some(PlannerRef {
                    solver: info.solver.clone(),
                    objective: info.objective.clone(),
                    instance: info.instance,
                });
                planner = Some(info);
                c.header.stamps.latencies()
            }
            None => {
                if missed {
                    // What the world flew: the hold of a step without a plan, from the positions and
                    // headings the measurement reported (emitter-sim makes the same one).
                    let positions = tdoa::points_from_arrays(m.uavs());
                    let hold = planning::hold::without_plan(&positions, m.headings(), &self.scenario);
                    record.headings_rad = hold.headings;
                    record.safety = hold.safety.map(|s| StepSafety::of_word(s.certified));
                }
                e.header.stamps.latencies()
            }
        };
        let error_m = truth.map(|z| (position[0] - z.x).hypot(position[1] - z.y));
        if self.keep {
            self.steps.push(record.clone());
        }
        let held = c.is_some_and(Command::is_hold);
        CompletedStep {
            record,
            latencies,
            planner,
            error_m,
            truth: t.map(|t| t.position),
            missed,
            held,
            chain,
            command_received_ns: 0,
        }
    }

    /// The record of the steps completed so far (the whole run once [`is_done`](Self::is_done)).
    pub fn record(&self) -> RunRecord {
        let (objective, solver) = self.names.clone().unwrap_or_else(|| ("-".into(), "-".into()));
        RunRecord::new(
            self.scenario.clone(),
            (&objective, &solver),
            self.scenario.seed,
            self.truth.then(|| self.emitter.unwrap_or(self.scenario.emitter)),
            self.estimator.unwrap_or(self.scenario.estimator.name()),
            self.steps.clone(),
        )
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use protocol::{Fix, MessageKind, PlanInfo, PosteriorExtra};

    const UAVS: [[f64; 2]; 3] = [[1500.0, 500.0], [10000.0, 1500.0], [5000.0, 8500.0]];

    pub(crate) fn scenario(steps: usize) -> Scenario {
        Scenario { steps, rmse_resamples: 5, ..Scenario::default() }
    }

    pub(crate) fn measurement(k: u64) -> Measurement {
        Measurement::new(k, k + 1, &UAVS, &[-2012.3, -4010.9], &[28.7712; 3], &[0.1, 0.2, 0.3]).unwrap()
    }

    pub(crate) fn estimate(k: u64, fix: Fix) -> Estimate {
        Estimate::from_measurement(&measurement(k), 10, k + 1, 7, fix).unwrap()
    }

    /// A failed estimate carrying the standing estimate of `ok(x)`.
    fn failed(k: u64, x: f64) -> Estimate {
        estimate(k, Fix::Failed).with_standing(ok(x).usable())
    }

    pub(crate) fn ok(x: f64) -> Fix {
        Fix::Ok { position: [x, 15000.0], covariance: [[4.0e4, 0.0], [0.0, 9.0e4]] }
    }

    pub(crate) fn command(k: u64, objective: f64, mask: u64) -> Command {
        let plan = PlanInfo {
            headings: &[0.5, 0.6, 0.7],
            waypoints: &UAVS,
            objective,
            solver: "pso",
            objective_name: "analytical",
            plan_time_us: 1234,
            active_constraints: mask,
            violated_constraints: 0,
        };
        Command::from_estimate(&estimate(k, ok(25000.0)), 20, k + 1, 99, &plan).unwrap()
    }

    pub(crate) fn truth(k: u64) -> Truth {
        Truth::new(k, k + 1, [25000.0, 15000.0])
    }

    /// The truth of step k, saying that the command of step k − 1 was flown.
    pub(crate) fn flown(k: u64) -> Truth {
        truth(k).with_previous_command(CommandOutcome::Flown)
    }

    /// Every message of step `k` (with `truth`), its command unless `command` is false.
    fn add_step(a: &mut Assembler, k: u64, truth: Truth, command: bool) {
        a.add_measurement(measurement(k));
        a.add_truth(truth);
        a.add_estimate(estimate(k, ok(25000.0)));
        if command {
            a.add_command(command_of(k));
        }
    }

    fn command_of(k: u64) -> Command {
        command(k, 4.0, 0)
    }

    /// A fused estimator sends no posterior before its first fix, so the wire's `estimator` reads 0 there
    /// as it does for the snapshot estimator: the run and those steps are still the fused estimator's.
    #[test]
    fn steps_before_a_first_fix_are_the_estimators_of_the_run() {
        let fused = PosteriorExtra { estimator: 1, ..PosteriorExtra::default() };
        for (kind, later) in [(EstimatorKind::Fused, Some(fused)), (EstimatorKind::Snapshot, None)] {
            let mut a = Assembler::new(Scenario { estimator: kind, ..scenario(2) });
            for k in 0..=2 {
                a.add_measurement(measurement(k));
                a.add_truth(if k == 0 { truth(k) } else { flown(k) });
                let e = match (k, later) {
                    (0, _) => estimate(k, Fix::Failed),
                    (_, Some(extra)) => estimate(k, ok(25000.0)).with_extra(&extra),
                    (_, None) => estimate(k, ok(25000.0)),
                };
                a.add_estimate(e);
                if k < 2 {
                    a.add_command(command_of(k));
                }
            }
            let done = a.complete_ready();
            assert_eq!(done.len(), 3);
            let run = a.record();
            assert_eq!(run.estimator, kind.name(), "the run's estimator");
            for d in &done {
                assert_eq!(d.record.estimator.as_deref(), Some(kind.name()), "step {}", d.record.step);
            }
        }
        // A run whose estimator never fixed: the scenario's.
        let mut a = Assembler::new(scenario(0));
        a.add_measurement(measurement(0));
        a.add_truth(truth(0));
        a.add_estimate(estimate(0, Fix::Failed));
        assert_eq!(a.complete_ready()[0].record.estimator.as_deref(), Some("fused"));
        assert_eq!(a.record().estimator, "fused");
    }

    /// The messages of steps 0 and 1 (and step 2's truth, which completes step 1) in 2 000 random
    /// orders: the steps complete in step order, each once, with the same records as in step order.
    #[test]
    fn every_arrival_order_completes_the_same_steps_in_order() {
        #[derive(Clone, Copy)]
        enum M {
            Measurement(u64),
            Truth(u64),
            Estimate(u64),
            Command(u64),
        }
        let feed = |order: &[M]| {
            let mut a = Assembler::new(scenario(2));
            let mut done = Vec::new();
            for m in order {
                match *m {
                    M::Measurement(k) => a.add_measurement(measurement(k)),
                    M::Truth(k) => a.add_truth(if k == 0 { truth(0) } else { flown(k) }),
                    M::Estimate(k) => a.add_estimate(estimate(k, ok(24000.0 + k as f64))),
                    M::Command(k) => a.add_command(command_of(k)),
                };
                done.extend(a.complete_ready().into_iter().map(|d| serde_json::to_string(&d.record).unwrap()));
            }
            done
        };
        let mut order = vec![M::Truth(2)];
        for k in 0..2 {
            order.extend([M::Measurement(k), M::Truth(k), M::Estimate(k), M::Command(k)]);
        }
        order.rotate_left(1); // step order: step 0's, step 1's, then the truth of step 2
        let reference = feed(&order);
        assert_eq!(reference.len(), 2);
        let mut rng = tdoa::rng::SplitMix64::new(97);
        for _ in 0..2000 {
            // Fisher–Yates.
            for i in (1..order.len()).rev() {
                order.swap(i, (rng.next_u64() % (i as u64 + 1)) as usize);
            }
            assert_eq!(feed(&order), reference);
        }
    }

    #[test]
    fn completes_steps_in_order_when_a_later_step_comes_first() {
        let mut a = Assembler::new(scenario(2));
        // Step 1 complete before step 0: nothing is emitted until step 0 is.
        assert!(a.add_command(command(1, 4.0, 0)));
        assert!(a.add_truth(truth(1)));
        assert!(a.add_estimate(failed(1, 24000.0)));
        assert!(a.add_measurement(measurement(1)));
        assert!(a.complete_ready().is_empty());
        a.add_measurement(measurement(0));
        a.add_truth(truth(0));
        a.add_estimate(estimate(0, ok(24000.0)));
        assert!(a.complete_ready().is_empty(), "step 0 still lacks its command");
        a.add_command(command(0, 9.0, 1 << 8));
        let mut done = a.complete_ready();
        assert_eq!(done.iter().map(|d| d.record.step).collect::<Vec<_>>(), vec![0], "step 1 awaits the truth of 2");
        // The truth of step 2 says that step 1's command was flown: step 1 is complete.
        assert!(a.add_truth(flown(2)));
        done.extend(a.complete_ready());
        assert_eq!(done.iter().map(|d| d.record.step).collect::<Vec<_>>(), vec![0, 1]);
        let s0 = &done[0].record;
        assert_eq!(s0.uavs, UAVS.to_vec());
        assert_eq!(s0.headings_rad, vec![0.5, 0.6, 0.7], "the command's headings");
        assert_eq!(s0.estimate, [24000.0, 15000.0]);
        assert_eq!(s0.objective_value, Some(3.0));
        assert_eq!(s0.plan_ms, Some(1.234));
        assert_eq!(s0.active_constraints, vec!["heading_cone(UAV 0) binding".to_string()]);
        assert!(s0.crlb_true_m.unwrap() > 1000.0 && s0.rmse_m.is_some());
        // The CRLB at the estimate [24000, 15000] equals the one at a truth placed there.
        let sensors = Sensors::new(&UAVS, NoiseModel::from_range_sigmas(&[28.7712; 3]).unwrap()).unwrap();
        let at = tdoa::crlb(&sensors, &Vector2::new(24000.0, 15000.0)).unwrap().crlb_m;
        assert_eq!(s0.crlb_at_estimate_m, Some(at));
        // A failed estimate reports the standing one it carries.
        let s1 = &done[1].record;
        assert_eq!((s1.estimate_status.as_str(), s1.estimate), ("failed", [24000.0, 15000.0]));
        assert_eq!(s1.estimate_cov, [[4.0e4, 0.0], [0.0, 9.0e4]]);
        assert_eq!(done[0].planner.as_ref().unwrap().instance, 99);
        // The last step needs no command; its headings are the measurement's.
        assert!(!a.add_command(command(2, 1.0, 0)), "the last step is never planned");
        a.add_measurement(measurement(2));
        a.add_estimate(estimate(2, ok(25000.0)));
        let last = a.complete_ready();
        assert_eq!(last.len(), 1);
        assert_eq!(last[0].record.headings_rad, vec![0.1, 0.2, 0.3]);
        assert_eq!((last[0].record.objective_value, last[0].record.plan_ms), (None, None));
        assert!(a.is_done());
        let run = a.record();
        assert_eq!((run.objective.as_str(), run.solver.as_str(), run.steps.len()), ("analytical", "pso", 3));
        assert_eq!(run.emitter, Some([25000.0, 15000.0]));
        // Late and out-of-range messages are ignored.
        assert!(!a.add_measurement(measurement(1)));
        assert!(!a.add_truth(truth(3)));
        assert_eq!(a.ignored(), 3);
    }

    #[test]
    fn resumes_from_recorded_steps() {
        let mut a = Assembler::new(scenario(2));
        for k in 0..2 {
            a.add_measurement(measurement(k));
            a.add_truth(truth(k));
            a.add_estimate(if k == 0 { estimate(k, ok(24000.0)) } else { failed(k, 24000.0) });
            a.add_command(command(k, 4.0, 0));
        }
        assert!(a.add_truth(flown(2)));
        let first = a.complete_ready();
        assert_eq!(first.len(), 2);
        let names = Some(("analytical".to_string(), "pso".to_string()));
        let records: Vec<StepRecord> = first.iter().map(|d| d.record.clone()).collect();
        let mut b = Assembler::resume(scenario(2), records.clone(), Some([25000.0, 15000.0]), names.clone()).unwrap();
        assert_eq!(b.next_step(), 2);
        assert!(!b.add_measurement(measurement(1)), "recorded steps are ignored");
        for x in [&mut a, &mut b] {
            x.add_measurement(measurement(2));
            x.add_truth(flown(2));
            // A failed last estimate: both fall back on step 0's.
            x.add_estimate(failed(2, 24000.0));
        }
        let mut c =
            Assembler::resume_forgetting(scenario(2), 2, records.last(), Some([25000.0, 15000.0]), names.clone())
                .unwrap();
        c.add_measurement(measurement(2));
        c.add_truth(flown(2));
        c.add_estimate(failed(2, 24000.0));
        let from_b = b.complete_ready();
        assert_eq!(a.complete_ready(), from_b);
        assert_eq!(c.complete_ready(), from_b, "a forgetting assembler completes the same steps");
        assert_eq!(a.record(), b.record());
        assert!(c.record().steps.is_empty(), "and keeps none");
        assert!(Assembler::resume_forgetting(scenario(2), 2, records.first(), None, None).is_none(), "not step 1");
        assert!(Assembler::resume_forgetting(scenario(2), 9, None, None, None).is_none());
        let mut gap = records;
        gap.remove(0);
        assert!(Assembler::resume(scenario(2), gap, None, names).is_none(), "steps must start at 0");
    }

    #[test]
    fn a_replayed_message_keeps_the_stamps_of_the_first() {
        // A lock-step retry (a command late under load) re-publishes a pending step without stamps, and the
        // estimator answers it again: the last step, timed by its estimate, kept the replay's zero stamps
        // and lost its emitter→estimator sample.
        let mut a = Assembler::new(scenario(0));
        let mut original = measurement(0);
        original.header.stamps.mark_published(MessageKind::Measurement, 5);
        let first = Estimate::from_measurement(&original, 10, 1, 7, ok(25000.0)).unwrap();
        assert_eq!(first.header.stamps.latencies().measurement_hop_ns, Some(5));
        assert!(a.add_measurement(original) && a.add_truth(truth(0)) && a.add_estimate(first));
        // The replay: no stamps; the estimator's answer again (received at 30).
        let replayed = measurement(0);
        let again = Estimate::from_measurement(&replayed, 30, 2, 7, ok(25000.0)).unwrap();
        assert_eq!(again.header.stamps.latencies().measurement_hop_ns, None);
        assert!(a.add_measurement(replayed) && a.add_estimate(again) && a.add_truth(truth(0)));
        let done = a.complete_ready();
        assert_eq!(done.len(), 1);
        assert_eq!(done[0].chain, first.header.stamps);
        assert_eq!(done[0].latencies.measurement_hop_ns, Some(5));
    }

    #[test]
    fn a_negative_objective_means_no_value() {
        let mut a = Assembler::new(scenario(1));
        a.add_measurement(measurement(0));
        a.add_truth(truth(0));
        a.add_estimate(estimate(0, ok(25000.0)));
        a.add_command(command(0, -1.0, 0));
        assert!(a.complete_ready().is_empty(), "step 0 awaits the truth of step 1");
        a.add_truth(flown(1));
        assert_eq!(a.complete_ready()[0].record.objective_value, None);
    }

    #[test]
    fn a_missed_command_records_what_the_world_flew() {
        let mut a = Assembler::new(scenario(3));
        add_step(&mut a, 0, truth(0), true);
        // Step 1's command comes, but the truth of step 2 says the world missed it.
        add_step(&mut a, 1, flown(1), true);
        add_step(&mut a, 2, truth(2).with_previous_command(CommandOutcome::Missed), false);
        let done = a.complete_ready();
        assert_eq!(done.iter().map(|d| (d.record.step, d.missed)).collect::<Vec<_>>(), [(0, false), (1, true)]);
        let s1 = &done[1].record;
        // The world flew the hold: one step of each UAV's backup circle (certified here), from the
        // measurement's positions and headings — not the command, nor straight on.
        let positions = tdoa::points_from_arrays(&UAVS);
        let hold = planning::hold::without_plan(&positions, &[0.1, 0.2, 0.3], &scenario(3));
        assert!(hold.loiters(&[0.1, 0.2, 0.3]), "{hold:?}");
        assert_eq!(s1.headings_rad, hold.headings);
        assert_eq!(s1.safety.as_ref().and_then(|s| s.certified), Some(true));
        assert_eq!((s1.objective_value, s1.plan_ms, s1.planner.as_ref()), (None, None, None));
        assert_eq!(s1.active_constraints, vec![COMMAND_MISSED.to_string()]);
        assert!(done[1].planner.is_none());
        assert_eq!(a.ignored(), 1, "the command that came too late");
        // A missed step needs no command at all, and a late one afterwards is ignored.
        add_step(&mut a, 3, truth(3).with_previous_command(CommandOutcome::Missed), false);
        let done = a.complete_ready();
        assert_eq!(done.iter().map(|d| (d.record.step, d.missed)).collect::<Vec<_>>(), [(2, true), (3, false)]);
        assert!(done[1].record.active_constraints.is_empty(), "the last step is not planned, so not missed");
        assert!(!a.add_command(command_of(2)));
        assert!(a.is_done());
    }

    /// A front end that skipped step 1: the gap names it and the first later step in; it closes when
    /// step 1 comes, and a measurement beyond the last step is ignored and leaves no gap.
    #[test]
    fn a_skipped_measurement_is_a_gap_until_it_comes() {
        let mut a = Assembler::new(scenario(4)).without_truth();
        assert_eq!(a.measurement_gap(), None, "nothing in yet");
        a.add_measurement(measurement(0));
        a.add_estimate(estimate(0, ok(25000.0)));
        a.add_command(command_of(0));
        assert_eq!(a.complete_ready().len(), 1);
        assert_eq!(a.measurement_gap(), None, "step 1 not in, and nothing later");
        assert!(!a.add_measurement(measurement(9)), "beyond the last step (4)");
        assert_eq!(a.measurement_gap(), None);
        a.add_measurement(measurement(3));
        a.add_measurement(measurement(2));
        assert_eq!(a.measurement_gap(), Some((1, 2)));
        a.add_estimate(estimate(1, ok(25000.0)));
        assert_eq!(a.measurement_gap(), Some((1, 2)), "an estimate without its measurement changes nothing");
        a.add_measurement(measurement(1));
        assert_eq!(a.measurement_gap(), None, "step 1 is in: waiting for the rest of it is no gap");
    }

    #[test]
    fn a_missed_command_of_the_paper_s_planner_holds_course() {
        let paper = Scenario { safety: model::safety::SafetyMode::Waypoints, ..scenario(3) };
        let mut a = Assembler::new(paper);
        add_step(&mut a, 0, truth(0), true);
        add_step(&mut a, 1, truth(1).with_previous_command(CommandOutcome::Missed), false);
        let done = a.complete_ready();
        let s0 = &done[0].record;
        assert!(done[0].missed);
        assert_eq!(s0.headings_rad, vec![0.1, 0.2, 0.3], "the headings kept (the measurement's)");
        assert_eq!(s0.safety, None, "the waypoint planner certifies nothing");
    }
}
