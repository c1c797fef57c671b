//! The planner's answers on the wire: a plan, and a hold, as [`Command`]s.

use nalgebra::Vector2;
use protocol::{Command, Estimate, PlanInfo};

use model::active_mask;
use model::scenario::Scenario;
use planning::objective::ObjectiveKind;
use planning::solver::SolverKind;
use planning::step::PlanOutput;

/// The command of `plan`, planned from `estimate` (received at `received_ns`; the command carries its
/// stamps on and echoes its state) by the planner `instance` with `solver` and `objective`.
pub fn plan_command(
    estimate: &Estimate,
    received_ns: u64,
    instance: u64,
    plan: &PlanOutput,
    (solver, objective): (SolverKind, ObjectiveKind),
) -> Result<Command, String> {
    let waypoints = waypoints(plan);
    let info = plan_info(plan, &waypoints, (solver, objective));
    let mut command = Command::from_estimate(estimate, received_ns, 0, instance, &info)
        .map_err(|e| format!("step {}: command: {e}", estimate.header.step))?;
    command.flags |= safety_flags(plan);
    Ok(command)
}

/// The [`Command::flags`] bits of `plan`'s safety certificate.
pub fn safety_flags(plan: &PlanOutput) -> u32 {
    certificate_flags(plan.safety.map(|s| s.certified))
}

/// The [`Command::flags`] bits of a certificate's word: certified, not certified, or none given.
fn certificate_flags(certified: Option<bool>) -> u32 {
    match certified {
        Some(true) => Command::FLAG_CERTIFIED,
        Some(false) => Command::FLAG_UNCERTIFIED,
        None => 0,
    }
}

/// The emitter's estimated motion an estimate carries (a fused constant-velocity estimate), as
/// `uavloc simulate` takes it from the estimator's posterior; `None` otherwise.
pub fn motion_of(est: &Estimate) -> Option<planning::shield::EmitterMotion> {
    (est.estimator == 1 && est.model == 1).then(|| planning::shield::EmitterMotion {
        velocity: Vector2::new(est.velocity[0], est.velocity[1]),
        velocity_cov: tdoa::estimate_from_arrays(&[0.0; 2], &est.velocity_cov).1,
    })
}

/// The waypoints of `plan` as the wire holds them, metres.
pub fn waypoints(plan: &PlanOutput) -> Vec<[f64; 2]> {
    plan.waypoints.iter().map(|w| [w.x, w.y]).collect()
}

/// What a command of `plan` says (its `waypoints`: [`waypoints`]), planned with `solver` and `objective`.
pub fn plan_info<'a>(
    plan: &'a PlanOutput,
    waypoints: &'a [[f64; 2]],
    (solver, objective): (SolverKind, ObjectiveKind),
) -> PlanInfo<'a> {
    PlanInfo {
        headings: &plan.headings,
        waypoints,
        // The wire requires a finite value: an infinite criterion (a singular geometry) is sent as −1, which
        // the monitor reads as "no value" like `simulate` does.
        objective: if plan.objective_value.is_finite() { plan.objective_value } else { -1.0 },
        solver: solver.name(),
        objective_name: objective.name(),
        plan_time_us: (plan.plan_time_ms * 1e3).round() as u64,
        active_constraints: active_mask::encode(&plan.active_constraints),
        violated_constraints: active_mask::encode_violated(&plan.active_constraints),
    }
}

/// The hold command of `step` (no first fix yet, or an estimate too late): `hold` ([`planning::hold`]:
/// the backup circles' step, or the current headings) flown by the UAVs at `positions` with headings
/// `headings`, flagged [`Command::FLAG_HOLD`] and, with its spacing certificate,
/// [`Command::FLAG_CERTIFIED`] or [`Command::FLAG_UNCERTIFIED`]; objective −1 and no plan time; named
/// after the planner's `solver` and `objective`.
pub fn hold_command(
    step: u64,
    positions: &[Vector2<f64>],
    headings: &[f64],
    hold: &planning::hold::Hold,
    scenario: &Scenario,
    (solver, objective): (SolverKind, ObjectiveKind),
    instance: u64,
) -> Result<Command, String> {
    let waypoints: Vec<[f64; 2]> = hold
        .waypoints(positions, headings, scenario)
        .ok_or_else(|| {
            format!(
                "step {step}: hold command: {} positions, {} headings, {} commanded",
                positions.len(),
                headings.len(),
                hold.headings.len()
            )
        })?
        .iter()
        .map(|w| [w.x, w.y])
        .collect();
    let info = PlanInfo {
        headings: &hold.headings,
        waypoints: &waypoints,
        objective: -1.0,
        solver: solver.name(),
        objective_name: objective.name(),
        plan_time_us: 0,
        active_constraints: 0,
        violated_constraints: 0,
    };
    let mut command = Command::new(step, 0, instance, &info).map_err(|e| format!("step {step}: hold command: {e}"))?;
    command.flags |= Command::FLAG_HOLD | certificate_flags(hold.safety.map(|s| s.certified));
    Ok(command)
}

pub use planning::scenario_with_sigmas;

/// The scenario a step is planned with, when it is not the run's own: the range σ the measurement stated
/// (an external front end's) and, with `--stated-position-margins`, the step's largest stated UAV position
/// σ as the GNSS σ of the safety margins when it is larger than the scenario's (a quiet link's reach:
/// the certificate then keeps `D_min` from everywhere that UAV could be, or says it cannot).
pub fn scenario_for(
    scenario: &Scenario,
    range_sigmas: Option<&[f64]>,
    position_sigma: Option<f64>,
) -> Option<Scenario> {
    let stated = scenario_with_sigmas(scenario, range_sigmas);
    let base = stated.as_ref().unwrap_or(scenario);
    match position_sigma {
        Some(sigma) if sigma > base.receiver.gnss_sigma_m => {
            Some(Scenario { receiver: model::ReceiverModel { gnss_sigma_m: sigma, ..base.receiver }, ..base.clone() })
        }
        _ => stated,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A quiet UAV stated with the σ of a 1.5 km reach widens the certificate's spacing to D_min + 1.5 km;
    /// a σ below the scenario's changes nothing; the stated range σ still applies.
    #[test]
    fn a_stated_position_sigma_widens_the_safety_margins() {
        let sc = Scenario::default();
        assert!(scenario_for(&sc, None, None).is_none());
        assert!(scenario_for(&sc, None, Some(0.0)).is_none(), "exact positions: the run's own scenario");
        let sigma = model::safety::position_sigma_of_reach(1500.0);
        let wide = scenario_for(&sc, None, Some(sigma)).unwrap();
        let limits = planning::shield::safety_limits(&wide);
        assert!((limits.d_min - (sc.d_min + 1500.0)).abs() < 1e-9, "{}", limits.d_min);
        let both = scenario_for(&sc, Some(&[10.0, 20.0, 30.0]), Some(sigma)).unwrap();
        assert_eq!(both.range_sigmas(), vec![10.0, 20.0, 30.0]);
        assert_eq!(both.receiver.gnss_sigma_m, sigma);
    }

    /// A hold with the certified planner: every UAV turns onto its backup circle, the waypoints are
    /// the ends of those arcs, the command is flagged a certified hold with no value; with the waypoint
    /// planner it flies straight on, neither safety bit set.
    #[test]
    fn a_hold_loiters_certified_or_flies_straight_on_flagged_with_no_value() {
        let sc = Scenario::default();
        let at = [Vector2::new(0.0, 0.0), Vector2::new(5000.0, 0.0), Vector2::new(0.0, 5000.0)];
        let headings = [0.5, -1.0, 2.0];
        let names = (SolverKind::Pso, ObjectiveKind::Analytical);
        let hold = planning::hold::without_plan(&at, &headings, &sc);
        let turn = planning::shield::safety_limits(&sc).backup_turn();
        let command = hold_command(7, &at, &headings, &hold, &sc, names, 3).unwrap();
        assert!(command.is_hold() && command.flags == Command::FLAG_HOLD | Command::FLAG_CERTIFIED);
        assert_eq!(command.certified(), Some(true));
        assert_eq!(
            (command.header.step, command.planner_instance, command.objective, command.plan_time_us),
            (7, 3, -1.0, 0)
        );
        for i in 0..3 {
            assert!((command.headings()[i] - (headings[i] - turn)).abs() < 1e-12);
            let w = model::kinematics::next_position(at[i], headings[i], headings[i] - turn, sc.speed, sc.dt);
            assert_eq!(command.waypoints()[i], [w.x, w.y]);
        }
        let paper = Scenario { safety: model::safety::SafetyMode::Waypoints, ..sc.clone() };
        let straight = planning::hold::without_plan(&at, &headings, &paper);
        let command = hold_command(7, &at, &headings, &straight, &paper, names, 3).unwrap();
        assert!(command.flags == Command::FLAG_HOLD && command.certified().is_none());
        assert_eq!(command.headings(), &headings);
        // Not one heading per UAV: an error, not a command.
        assert!(hold_command(7, &at, &headings[..1], &hold, &sc, names, 3).is_err());
    }
}
