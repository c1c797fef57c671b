//! The open-loop control of a closed-loop run: its estimator on the run's paths flown whatever the
//! estimates, measured with fresh noise.
//!
//! In the closed loop the planner chooses the next geometry from the current estimate, so the paths
//! depend on the very noise the estimates are judged against; the NEES of a closed-loop run mixes the
//! estimator's consistency with that feedback. Flown open loop — the same paths, a world with another
//! seed — the paths no longer depend on the noise, and the NEES says what the estimator alone does.

use model::Scenario;
use model::world::{Snapshot, World};
use nalgebra::Vector2;
use record::StepRecord;

use crate::{LoopError, ReceiverView, estimator_of, failed, seen_by};

/// One step of [`estimate_along`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OpenLoopStep {
    /// `|ẑ − z|`, metres (`None` before a first fix).
    pub error_m: Option<f64>,
    /// The NEES of the estimate against the truth (`None` before a first fix, or with a covariance that
    /// is not positive definite).
    pub nees: Option<f64>,
}

/// The estimator of [`run_closed_loop_with`](crate::run_closed_loop_with)`(scenario, …, view, …)` on the
/// paths of `steps` (each step's UAV positions and headings, e.g. a closed-loop run's record), measured
/// by the world of `scenario` — its seed, its receiver — at those positions and at each record's
/// `step`: one [`OpenLoopStep`] per step. A step the estimator cannot fix (no first fix yet) is `None`s
/// and the next burst is tried, as the closed loop does. Errors on a step whose geometry cannot be measured (a wrong UAV count, UAVs
/// that coincide) or an estimator failure other than a missing first fix.
pub fn estimate_along(
    scenario: &Scenario,
    view: ReceiverView,
    steps: &[StepRecord],
) -> Result<Vec<OpenLoopStep>, LoopError> {
    let mut estimator = estimator_of(scenario, view)?;
    let mut out = Vec::with_capacity(steps.len());
    for s in steps {
        let k = s.step;
        let at = Snapshot { step: k, positions: s.uavs.clone(), headings: s.headings_rad.clone() };
        let world = World::restore(scenario, &at).map_err(failed(Some(k), "world"))?;
        let meas = world.measure().map_err(failed(Some(k), "measurement"))?;
        let seen = seen_by(view, &meas, &world).map_err(failed(Some(k), "measurement"))?;
        let truth: Vector2<f64> = world.truth();
        let step = match estimator.estimate_burst(k, &seen) {
            Ok(est) => {
                let cov = est.total_covariance();
                OpenLoopStep {
                    error_m: Some((est.position - truth).norm()),
                    nees: tdoa::nees(&est.position, &cov, &truth),
                }
            }
            Err(_) if !planning::gives_up_without_fix(k, seen.heard_count()) => {
                OpenLoopStep { error_m: None, nees: None }
            }
            Err(e) => return Err(failed(Some(k), "estimate")(e)),
        };
        out.push(step);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::run_closed_loop_with;
    use estimation::EstimatorKind;
    use planning::{ObjectiveKind, SolverKind};

    /// Flown along its own paths with its own seed, the open-loop control is the closed-loop run: every
    /// step's error and NEES bit for bit (the same world's draws, the same estimator) — with lost
    /// arrivals, silence and reflections; with another seed it is another run.
    #[test]
    fn along_its_own_paths_with_its_own_seed_the_control_is_the_run() {
        let mut sc = Scenario { steps: 12, estimator: EstimatorKind::Fused, ..Scenario::default() };
        sc.uavs.extend([[-2000.0, 6000.0], [8000.0, -4000.0]]);
        sc.receiver.loss = 0.1;
        sc.receiver.silence = 0.2;
        sc.receiver.multipath = 0.15;
        for view in [ReceiverView::Stated, ReceiverView::CompleteOnly] {
            let run =
                run_closed_loop_with(&sc, ObjectiveKind::Analytical, SolverKind::Gradient, view, |_, _| {}).unwrap();
            let control = estimate_along(&sc, view, &run.steps).unwrap();
            assert_eq!(control.len(), run.steps.len());
            let mut fixed = 0;
            for (s, c) in run.steps.iter().zip(&control) {
                assert_eq!(
                    s.estimate_error_m.map(f64::to_bits),
                    c.error_m.map(f64::to_bits),
                    "{view:?} step {}",
                    s.step
                );
                assert_eq!(s.nees.map(f64::to_bits), c.nees.map(f64::to_bits), "{view:?} step {}", s.step);
                fixed += usize::from(c.nees.is_some());
            }
            assert!(fixed >= 10, "{view:?}: {fixed} steps with an estimate");
            let other = Scenario { seed: sc.seed + 1, ..sc.clone() };
            let control = estimate_along(&other, view, &run.steps).unwrap();
            assert!(run.steps.iter().zip(&control).any(|(s, c)| s.nees != c.nees), "{view:?}");
        }
    }

    /// A path with UAVs that coincide cannot be measured: an error naming the step, not a panic.
    #[test]
    fn a_path_that_cannot_be_measured_is_an_error() {
        let sc = Scenario::default();
        let mut steps: Vec<record::StepRecord> = (0..3)
            .map(|k| record::StepRecord {
                step: k,
                uavs: sc.uavs.clone(),
                headings_rad: vec![0.0; sc.uavs.len()],
                ..Default::default()
            })
            .collect();
        steps[2].uavs[1] = steps[2].uavs[0];
        let e = estimate_along(&sc, ReceiverView::Stated, &steps).unwrap_err();
        assert_eq!(e.stage, "step 2: measurement", "{e}");
    }
}
