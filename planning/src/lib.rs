//! # uavloc-planning — the step-by-step heading planner of uavloc
//!
//! Pure functions over plain data (paper Sections 3.1, 3.5–3.6, 4.3, 5.4): at every step each UAV
//! chooses a new heading; the headings minimise a CRLB criterion of the next waypoints (single-point,
//! Monte Carlo or analytical global CRLB, or a 25-point cubature) under four motion constraints, with
//! PSO, GA or ACO_R. The fixed-formation baseline needs no solver. No IPC: the planner process
//! (crate `uavloc-planner`) and the in-process closed loop (crate `uavloc-closed-loop`) both call
//! [`plan_step`].
//!
//! - the scenario, the kinematics, the constraint names and the safety certificate are the shared
//!   model's (crate `uavloc-model`);
//! - [`constraints`]: turn radius, spacing, approach distance, heading cone (eqs. 55–59);
//! - [`fitness`]: the lexicographic penalised fitness (eq. 78);
//! - [`objective`]: the criteria, one adapter over `tdoa`'s global CRLB methods;
//! - [`formation`]: the traditional fixed-formation baseline;
//! - [`solver`], [`pso`], [`ga`], [`aco`], [`gradient`]: one solver trait, the paper's three solvers and
//!   a deterministic gradient solver; [`factory`] builds one by name;
//! - [`shield`]: the safety certificate as the planner's first ranking (`safety = "certified"`);
//! - [`step`]: one planning step, [`plan_step`].
//!
//! Units: metres, seconds, radians (degrees only in TOML keys ending in `_deg`).

pub mod aco;
pub mod constraints;
pub mod factory;
pub mod fitness;
pub mod formation;
pub mod ga;
pub mod gradient;
pub mod heading_interval;
pub mod hold;
pub mod objective;
pub mod pso;
pub mod shield;
pub mod solver;
pub mod step;

/// Steps a run may wait for its first fix: while no step so far has given an estimate (a silent emitter,
/// lost arrivals, a burst with no physical solution), the swarm holds — with the certified planner every
/// UAV loiters on its backup circle ([`hold`]) — and the next burst is tried; from step `FIRST_FIX_STEPS − 1` on, a burst heard by three or
/// more UAVs that still gives no fix ends the run (the geometry or the noise leaves no fix). Steps the
/// receiver delivered too little (a silent emitter, arrivals lost) never end it: the swarm holds until
/// the emitter is heard. See [`gives_up_without_fix`]; shared by the pipeline's planner and the
/// in-process closed loop, so both hold and give up at the same step.
pub const FIRST_FIX_STEPS: u64 = 20;

/// Whether a run that has no fix yet ends at `step`, whose burst was heard by `heard` UAVs (see
/// [`FIRST_FIX_STEPS`]). A function of the step alone, so a restarted planner decides as the one before.
pub fn gives_up_without_fix(step: u64, heard: usize) -> bool {
    step + 1 >= FIRST_FIX_STEPS && heard >= 3
}

/// `scenario` with the range σ an estimate states (`protocol::Estimate::range_sigmas`) — `None` when it
/// states none or the scenario's already are those (no copy on the hot path of a simulated run).
pub fn scenario_with_sigmas(scenario: &model::Scenario, sigmas: Option<&[f64]>) -> Option<model::Scenario> {
    let sigmas = sigmas?;
    if sigmas.len() != scenario.uavs.len() || scenario.range_sigmas() == sigmas {
        return None;
    }
    Some(model::Scenario { sigma: model::RangeSigma::PerUav(sigmas.to_vec()), ..scenario.clone() })
}

pub use aco::{Aco, AcoConfig};
pub use constraints::{ActiveConstraint, ConstraintKind, ConstraintReport, Constraints};
pub use fitness::{Fitness, TIE_TOLERANCE, TIERS};
pub use formation::formation_headings;
pub use ga::{Ga, GaConfig};
pub use gradient::{Gradient, GradientConfig};
pub use objective::{CrlbObjective, ObjectiveKind, PlanObjective};
pub use pso::{Pso, PsoConfig};
pub use shield::EmitterMotion;
pub use solver::{EarlyStop, SearchSpace, SearchSpaceError, Solver, SolverKind, SolverResult, StopRule};
pub use step::{PlanError, PlanOutput, PlanRequest, plan_step};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_without_a_fix_ends_only_on_a_burst_that_could_have_given_one() {
        // Before step FIRST_FIX_STEPS − 1: never; after: only when three or more UAVs heard the burst.
        for step in 0..FIRST_FIX_STEPS - 1 {
            assert!((0..=8).all(|heard| !gives_up_without_fix(step, heard)), "step {step}");
        }
        for step in [FIRST_FIX_STEPS - 1, FIRST_FIX_STEPS, 1000] {
            assert!((0..3).all(|heard| !gives_up_without_fix(step, heard)), "step {step}: silent or lost");
            assert!((3..=8).all(|heard| gives_up_without_fix(step, heard)), "step {step}");
        }
    }
}
