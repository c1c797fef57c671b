//! # uavloc-closed-loop — the pipeline's closed loop in one process
//!
//! Emitter → estimator → planner → move, step by step, with the same library calls the processes make
//! (the world's [`model::world::World`], the estimator's [`estimation::Estimator`], the planner's
//! [`planning::plan_step`], the record's [`record::step_metrics`]), so a run through the processes
//! reproduces it bit for bit. `uavloc simulate` is one such run; every outer run of `uavloc paper` is
//! another. No IPC.

use model::Scenario;
use nalgebra::{Matrix2, Vector2};
use planning::{ObjectiveKind, PlanRequest, SolverKind, plan_step};
use record::{RunRecord, StepRecord, crlb_at, step_metrics};
use thiserror::Error;

mod open_loop;
pub use open_loop::{OpenLoopStep, estimate_along};

/// Why a closed-loop run stopped: which stage of which step failed, and why.
#[derive(Debug, Error)]
#[error("{stage}: {source}")]
pub struct LoopError {
    /// `world`, `estimator`, or `step k: measurement|estimate|geometry|plan|move`.
    pub stage: String,
    /// The underlying error (the world's, the estimator's, the planner's).
    #[source]
    pub source: Box<dyn std::error::Error + Send + Sync>,
}

/// The [`LoopError`] of `stage` (of step `step`, when there is one) for an error of that stage.
fn failed<E: std::error::Error + Send + Sync + 'static>(
    step: Option<u64>,
    stage: &'static str,
) -> impl FnOnce(E) -> LoopError {
    move |e| LoopError {
        stage: step.map_or_else(|| stage.to_string(), |k| format!("step {k}: {stage}")),
        source: Box::new(e),
    }
}

fn pair(v: &Vector2<f64>) -> [f64; 2] {
    [v.x, v.y]
}

/// What a step carried besides its record — what the pipeline's messages of the step would carry (the
/// measurement's range differences and σ, the estimator's whole output, the plan), for `simulate
/// --record`.
#[derive(Debug)]
pub struct StepTrace<'a> {
    /// The true emitter position, metres.
    pub truth: [f64; 2],
    /// The UAV headings at the measurement, radians.
    pub measured_headings: &'a [f64],
    /// The world's measurement: the burst as the receivers gave it (who heard it, the arrivals, the
    /// stated σ, a silent emitter, the reflections).
    pub measurement: &'a model::world::Measurement,
    /// The estimator's output for the step.
    pub estimate: &'a estimation::EstimateOut,
    /// The plan of the step (`None` on the last step).
    pub plan: Option<&'a planning::PlanOutput>,
    /// What the planner planned from: ẑ (metres) and its covariance (m²) — the live estimate, or in
    /// controlled mode the truth plus the fixed error.
    pub target: (Vector2<f64>, Matrix2<f64>),
    /// The emitter's estimated motion the planner was given (fused constant-velocity only).
    pub motion: Option<planning::EmitterMotion>,
}

/// What the estimator makes of the receivers' bursts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ReceiverView {
    /// Every burst as the receivers give it: any two or more arrivals, the stated σ (GNSS and clock
    /// errors included), the scenario's outlier policy — the pipeline's estimator.
    #[default]
    Stated,
    /// A receiver-blind estimator, for comparison: a step counts only when every UAV heard the burst
    /// (a step with a lost arrival is lost whole, as with range differences to UAV0), the range σ only
    /// (no GNSS or clock errors in the noise), and a burst that fails the gate is rejected whole.
    CompleteOnly,
}

/// The closed loop for `scenario` (its `steps` and `seed`), planning with `objective` × `solver`.
/// Step 0 is the initial geometry; the last step is measured but not planned. `on_step` is called after
/// every recorded step (for progress, or to record the step's messages).
pub fn run_closed_loop(
    scenario: &Scenario,
    objective: ObjectiveKind,
    solver: SolverKind,
    on_step: impl FnMut(&StepRecord, &StepTrace<'_>),
) -> Result<RunRecord, LoopError> {
    run_closed_loop_with(scenario, objective, solver, ReceiverView::Stated, on_step)
}

/// [`run_closed_loop`] with the estimator seeing the bursts as `view` says.
pub fn run_closed_loop_with(
    scenario: &Scenario,
    objective: ObjectiveKind,
    solver: SolverKind,
    view: ReceiverView,
    mut on_step: impl FnMut(&StepRecord, &StepTrace<'_>),
) -> Result<RunRecord, LoopError> {
    let mut world = model::world::World::from_scenario(scenario).map_err(failed(None, "world"))?;
    let mut estimator = estimator_of(scenario, view)?;
    // The σ the receivers state, recorded where it is not the scenario's (as the pipeline's monitor does).
    let (stated_sigmas, _) = world.stated_sigmas();
    let stated = (stated_sigmas != scenario.range_sigmas()).then_some(stated_sigmas);
    // The planner plans for the noise the receivers state (as the pipeline's planner does).
    let planned_for = planning::scenario_with_sigmas(scenario, stated.as_deref());
    let plan_scenario = planned_for.as_ref().unwrap_or(scenario);
    let start = world.truth();
    let mut steps = Vec::with_capacity(scenario.steps + 1);
    for k in 0..=scenario.steps as u64 {
        let truth = world.truth();
        let meas = world.measure().map_err(failed(Some(k), "measurement"))?;
        let seen = seen_by(view, &meas, &world).map_err(failed(Some(k), "measurement"))?;
        // No fix so far (a silent emitter, lost arrivals, a burst without a physical solution): the swarm
        // holds (planning::hold) and tries the next burst, until planning::gives_up_without_fix (what the
        // pipeline's planner does with such an estimate).
        let (est, awaiting_fix) = match estimator.estimate_burst(k, &seen) {
            Ok(est) => (est, false),
            Err(e) if !planning::gives_up_without_fix(k, seen.heard_count()) => {
                (no_fix_yet(&seen, e.to_string(), estimator.held()), true)
            }
            Err(e) => return Err(failed(Some(k), "estimate")(e)),
        };
        let status = est.status.name();
        let velocity = est.posterior.and_then(|p| p.velocity());
        let motion = velocity.map(|(velocity, velocity_cov)| planning::EmitterMotion { velocity, velocity_cov });
        // The geometry as reported, with the range σ (what the pipeline's monitor has).
        let reported: Vec<[f64; 2]> = meas.uavs.iter().map(pair).collect();
        let sensors = tdoa::Sensors::new(&reported, world.noise().clone()).map_err(failed(Some(k), "geometry"))?;
        let metrics = step_metrics(&sensors, &truth, scenario.rmse_resamples, scenario.seed, k, Some(est.position));
        // The planner sees the live estimate, or in controlled mode the truth plus a fixed error.
        let target = scenario.controlled_target(truth);
        let (z_hat, m) = target.map_or((est.position, est.total_covariance()), |t| (t.estimate, t.covariance));
        let mut record = StepRecord {
            step: k,
            geo: None,
            uavs: meas.uavs.iter().map(pair).collect(),
            headings_rad: world.headings().to_vec(),
            estimate: pair(&est.position),
            estimate_cov: tdoa::matrix_to_rows(&est.total_covariance()),
            estimate_status: status.to_string(),
            estimate_velocity: velocity.map(|(v, _)| pair(&v)),
            estimate_velocity_cov: velocity.map(|(_, c)| tdoa::matrix_to_rows(&c)),
            truth: Some(pair(&truth)),
            estimate_error_m: None,
            nees: None,
            pcrlb_m: None,
            min_true_distance_m: None,
            crlb_true_m: Some(metrics.crlb_true_m),
            crlb_at_estimate_m: crlb_at(&sensors, &est.position),
            pcrlb_at_estimate_m: None,
            rmse_m: metrics.rmse_m,
            objective_value: None,
            plan_ms: None,
            active_constraints: Vec::new(),
            planner: None,
            criterion_ess: None,
            range_sigmas_m: stated.clone(),
            estimator: Some(scenario.estimator.name().to_string()),
            safety: None,
            receiver: record::StepReceiver::from_masks(
                meas.uavs.len(),
                meas.arrivals.heard_mask(),
                est.outliers,
                Some(meas.silent),
                Some(meas.multipath),
            )
            .unless_complete(meas.uavs.len()),
        };
        let measured_headings = world.headings().to_vec();
        let plan = if k < scenario.steps as u64 && awaiting_fix {
            // A hold (planning::hold: the backup circles' step, certified for the spacing); recorded as
            // the pipeline's monitor records a hold.
            let hold = planning::hold::without_plan(&meas.uavs, world.headings(), plan_scenario);
            world.apply(&hold.headings).map_err(failed(Some(k), "move"))?;
            record.headings_rad = hold.headings;
            record.active_constraints = vec![HOLD_LABEL.to_string()];
            record.safety = hold.safety.map(|r| record::StepSafety::of_word(r.certified));
            None
        } else if k < scenario.steps as u64 {
            let plan = plan_step(&PlanRequest {
                // Where the UAVs report they are (the pipeline plans from the same).
                positions: &meas.uavs,
                headings: world.headings(),
                estimate: z_hat,
                covariance: m,
                scenario: plan_scenario,
                objective,
                solver,
                run_seed: scenario.seed,
                step: k,
                motion,
            })
            .map_err(failed(Some(k), "plan"))?;
            world.apply(&plan.headings).map_err(failed(Some(k), "move"))?;
            record.headings_rad = plan.headings.clone();
            record.objective_value = plan.objective_value.is_finite().then(|| plan.objective_value.sqrt());
            record.plan_ms = Some(plan.plan_time_ms);
            // The wire form, as the pipeline's monitor records it (no violation magnitudes).
            record.active_constraints = model::active_mask::labels(&plan.active_constraints, plan.headings.len());
            record.criterion_ess = plan.criterion_ess;
            record.safety = plan.safety.map(|r| record::StepSafety::of_word(r.certified));
            Some(plan)
        } else {
            None
        };
        let trace = StepTrace {
            truth: pair(&truth),
            measured_headings: &measured_headings,
            measurement: &meas,
            estimate: &est,
            plan: plan.as_ref(),
            target: (z_hat, m),
            motion,
        };
        on_step(&record, &trace);
        steps.push(record);
    }
    let mut run = RunRecord::new(
        scenario.clone(),
        (objective.name(), solver.name()),
        scenario.seed,
        Some(pair(&start)),
        scenario.estimator.name(),
        steps,
    );
    record::annotate(&mut run);
    Ok(run)
}

/// The record label of a step held because there was no estimate to plan from (the monitor's label of a
/// hold command).
pub const HOLD_LABEL: &str = "estimate_stale";

/// The estimator's output for a step without a first fix yet: no position (NaN), status `failed`.
fn no_fix_yet(a: &tdoa::Arrivals, reason: String, held: &[estimation::HeldBurst]) -> estimation::EstimateOut {
    estimation::EstimateOut {
        position: Vector2::repeat(f64::NAN),
        covariance: Matrix2::repeat(f64::NAN),
        status: estimation::EstimateStatus::Failed { reason },
        candidates: Vec::new(),
        posterior: None,
        nis: None,
        track: estimation::TrackCounters::default(),
        heard: a.heard_mask(),
        outliers: 0,
        bias_cov: Matrix2::zeros(),
        sensitivity: None,
        alternative: None,
        held: held.to_vec(),
        window: None,
    }
}

/// The estimator of `scenario` as `view` makes it (its emitter model; the scenario's outlier policy, or
/// whole-burst rejection for [`ReceiverView::CompleteOnly`]).
fn estimator_of(scenario: &Scenario, view: ReceiverView) -> Result<estimation::Estimator, LoopError> {
    let dynamics = scenario.dynamics().map_err(failed(None, "estimator"))?;
    let outliers = match view {
        ReceiverView::Stated => scenario.outliers,
        ReceiverView::CompleteOnly => tdoa::arrivals::OutlierPolicy::Snapshot,
    };
    Ok(estimation::Estimator::with_config(
        estimation::EstimatorConfig::new(scenario.estimator, dynamics).with_outliers(outliers),
    ))
}

/// The burst of `meas` as the estimator of `view` sees it.
fn seen_by(
    view: ReceiverView,
    meas: &model::world::Measurement,
    world: &model::world::World,
) -> Result<tdoa::Arrivals, tdoa::TdoaError> {
    match view {
        ReceiverView::Stated => Ok(meas.arrivals),
        ReceiverView::CompleteOnly => complete_only(&meas.arrivals, world.noise().sigmas()),
    }
}

/// The burst as a receiver-blind estimator sees it ([`ReceiverView::CompleteOnly`]): nothing unless every
/// UAV heard it, with the range σ `range_sigmas` only.
fn complete_only(a: &tdoa::Arrivals, range_sigmas: &[f64]) -> Result<tdoa::Arrivals, tdoa::TdoaError> {
    let n = a.len();
    let pts: Vec<[f64; 2]> = a.positions().iter().map(pair).collect();
    let arrivals: Vec<f64> = (0..n).map(|i| a.arrival(i).unwrap_or(0.0)).collect();
    let heard = if a.heard_count() == n { a.heard_mask() } else { 0 };
    tdoa::Arrivals::new(&pts, &arrivals, heard, range_sigmas, &vec![0.0; n])
}

#[cfg(test)]
mod tests {
    use super::run_closed_loop;
    use estimation::{EstimateStatus, EstimatorKind};
    use model::Scenario;
    use planning::{ObjectiveKind, SolverKind};

    /// Measure → estimate → plan → move for the nominal 24 steps with the paper's per-step Chan: every
    /// estimate is unambiguous, every plan feasible, and planning on the analytical global CRLB ends
    /// with a smaller CRLB at the truth than the fixed formation.
    #[test]
    fn closed_loop_nominal_run() {
        let sc = Scenario { estimator: EstimatorKind::Snapshot, ..Scenario::default() };
        let run = |objective: ObjectiveKind| -> f64 {
            let mut planned = 0;
            let run = run_closed_loop(&sc, objective, SolverKind::Pso, |rec, trace| {
                assert_eq!(trace.estimate.status, EstimateStatus::Ok, "{objective} step {}", rec.step);
                if let Some(plan) = trace.plan {
                    planned += 1;
                    assert!(plan.fitness.is_feasible(), "{objective} step {}: {:?}", rec.step, plan.active_constraints);
                }
            })
            .unwrap();
            assert_eq!(planned, sc.steps);
            run.steps.last().and_then(|s| s.crlb_true_m).unwrap()
        };
        let formation = run(ObjectiveKind::Formation);
        let analytical = run(ObjectiveKind::Analytical);
        assert!(analytical < 0.9 * formation, "analytical {analytical:.1} m vs formation {formation:.1} m");
    }

    /// An emitter heard by too few UAVs for a first fix (95 % of the arrivals lost) for 80 steps: the
    /// swarm, heading at it, loiters on its backup circles (planning::hold) instead of flying on — every
    /// hold certified for the spacing, no pair below `D_min`, no UAV inside `L_min` of the true emitter,
    /// none more than a circle's diameter from where it started. Holding course flies them over it.
    #[test]
    fn a_swarm_that_never_hears_enough_for_a_fix_loiters_where_it_is() {
        let mut sc = Scenario { steps: 80, ..Scenario::default() };
        sc.receiver.loss = 0.95;
        let start: Vec<[f64; 2]> = sc.uavs.clone();
        let radius = planning::shield::safety_limits(&sc).backup_radius();
        let mut held = 0;
        let run = run_closed_loop(&sc, ObjectiveKind::Analytical, SolverKind::Gradient, |rec, trace| {
            if trace.plan.is_none() && rec.step < sc.steps as u64 {
                held += 1;
                assert_eq!(rec.safety.as_ref().and_then(|s| s.certified), Some(true), "step {}", rec.step);
            }
        })
        .unwrap();
        assert!(held >= 60, "{held} holds");
        assert_eq!((run.true_spacing_violations, run.true_standoff_violations, run.uncertified_steps), (0, Some(0), 0));
        for s in run.steps.iter().take(held) {
            for (u, p) in s.uavs.iter().zip(&start) {
                assert!((u[0] - p[0]).hypot(u[1] - p[1]) <= 2.0 * radius + 1e-6, "step {}", s.step);
            }
        }
    }
}
