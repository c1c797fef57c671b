//! The planning inputs timed: the exact arguments of `plan_step` at every planned step of closed-loop
//! runs of the scenario (analytical × PSO).

use model::Scenario;
use nalgebra::{Matrix2, Vector2};
use planning::{ObjectiveKind, PlanRequest, SolverKind};
use tdoa::rng::{Purpose, derive_seed};

use super::REFERENCE;
use crate::error::CliError;

/// The exact inputs of one `plan_step` call, apart from the scenario, objective and solver.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanInput {
    pub positions: Vec<Vector2<f64>>,
    pub headings: Vec<f64>,
    pub estimate: Vector2<f64>,
    pub covariance: Matrix2<f64>,
    pub run_seed: u64,
    pub step: u64,
    /// The emitter's estimated motion (a constant-velocity model), as the closed loop plans with it.
    pub motion: Option<planning::EmitterMotion>,
}

impl PlanInput {
    pub(super) fn request<'a>(
        &'a self,
        scenario: &'a Scenario,
        objective: ObjectiveKind,
        solver: SolverKind,
    ) -> PlanRequest<'a> {
        PlanRequest {
            positions: &self.positions,
            headings: &self.headings,
            estimate: self.estimate,
            covariance: self.covariance,
            scenario,
            objective,
            solver,
            run_seed: self.run_seed,
            step: self.step,
            motion: self.motion,
        }
    }
}

/// The planner inputs of the first `count` planned steps of consecutive closed-loop runs of `sc`
/// (analytical × PSO): run 0 with `sc.seed`, run r ≥ 1 with `derive_seed(sc.seed, r, OuterRun)`.
/// Each input is what `closed_loop::run_closed_loop` gave `plan_step` (its [`closed_loop::StepTrace`]).
pub fn collect_inputs(sc: &Scenario, count: usize) -> Result<(Vec<PlanInput>, usize), CliError> {
    collect_inputs_of_runs(sc, count, sc.steps)
}

/// [`collect_inputs`] from input runs of `run_steps` steps each.
pub fn collect_inputs_of_runs(
    sc: &Scenario,
    count: usize,
    run_steps: usize,
) -> Result<(Vec<PlanInput>, usize), CliError> {
    let (objective, solver) = REFERENCE;
    let mut inputs = Vec::with_capacity(count);
    let mut runs = 0u64;
    while inputs.len() < count {
        let mut run_sc = Scenario { steps: run_steps, ..sc.clone() };
        if runs > 0 {
            run_sc.seed = derive_seed(sc.seed, runs, Purpose::OuterRun);
        }
        let before = inputs.len();
        let seed = run_sc.seed;
        closed_loop::run_closed_loop(&run_sc, objective, solver, |rec, trace| {
            if trace.plan.is_some() && inputs.len() < count {
                let (estimate, covariance) = trace.target;
                inputs.push(PlanInput {
                    positions: tdoa::points_from_arrays(&rec.uavs),
                    headings: trace.measured_headings.to_vec(),
                    estimate,
                    covariance,
                    run_seed: seed,
                    step: rec.step,
                    motion: trace.motion,
                });
            }
        })
        .map_err(|e| CliError::failed_because(format!("input run {runs} (seed {seed})"), e))?;
        runs += 1;
        if inputs.len() == before {
            return Err(CliError::Input("scenario: a run has no planned steps".into()));
        }
    }
    Ok((inputs, runs as usize))
}
