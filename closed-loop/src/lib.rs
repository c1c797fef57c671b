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
    /// The measured range differences d_i = r_i − r_0, metres.
    pub range_diffs: &'a [f64],
    /// The range noise σ per UAV, metres.
    pub sigmas: &'a [f64],
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

/// The closed loop for `scenario` (its `steps` and `seed`), planning with `objective` × `solver`.
/// Step 0 is the initial geometry; the last step is measured but not planned. `on_step` is called after
/// every recorded step (for progress, or to record the step's messages).
pub fn run_closed_loop(
    scenario: &Scenario,
    objective: ObjectiveKind,
    solver: SolverKind,
    mut on_step: impl FnMut(&StepRecord, &StepTrace<'_>),
) -> Result<RunRecord, LoopError> {
    let mut world = model::world::World::from_scenario(scenario).map_err(failed(None, "world"))?;
    let dynamics = scenario.dynamics().map_err(failed(None, "estimator"))?;
    let mut estimator =
        estimation::Estimator::with_config(estimation::EstimatorConfig::new(scenario.estimator, dynamics));
    let start = world.truth();
    let mut steps = Vec::with_capacity(scenario.steps + 1);
    for k in 0..=scenario.steps as u64 {
        let truth = world.truth();
        let meas = world.measure().map_err(failed(Some(k), "measurement"))?;
        let est =
            estimator.estimate(k, &meas.uavs, &meas.range_diffs, world.noise()).map_err(failed(Some(k), "estimate"))?;
        let status = est.status.name();
        let velocity = est.posterior.and_then(|p| p.velocity());
        let motion = velocity.map(|(velocity, velocity_cov)| planning::EmitterMotion { velocity, velocity_cov });
        let sensors = world.sensors().map_err(failed(Some(k), "geometry"))?;
        let metrics = step_metrics(&sensors, &truth, scenario.rmse_resamples, scenario.seed, k, Some(est.position));
        // The planner sees the live estimate, or in controlled mode the truth plus a fixed error.
        let target = scenario.controlled_target(truth);
        let (z_hat, m) = target.map_or((est.position, est.covariance), |t| (t.estimate, t.covariance));
        let mut record = StepRecord {
            step: k,
            uavs: meas.uavs.iter().map(pair).collect(),
            headings_rad: world.headings().to_vec(),
            estimate: pair(&est.position),
            estimate_cov: tdoa::matrix_to_rows(&est.covariance),
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
            range_sigmas_m: None,
            estimator: Some(scenario.estimator.name().to_string()),
            safety: None,
        };
        let measured_headings = world.headings().to_vec();
        let plan = if k < scenario.steps as u64 {
            let plan = plan_step(&PlanRequest {
                positions: world.positions(),
                headings: world.headings(),
                estimate: z_hat,
                covariance: m,
                scenario,
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
            record.safety =
                plan.safety.map(|r| record::StepSafety { certified: Some(r.certified), ..Default::default() });
            Some(plan)
        } else {
            None
        };
        let trace = StepTrace {
            truth: pair(&truth),
            measured_headings: &measured_headings,
            range_diffs: meas.range_diffs.as_slice(),
            sigmas: world.noise().sigmas(),
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
}
