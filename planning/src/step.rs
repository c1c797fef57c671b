//! One planning step as a pure function (paper Section 3.6, eq. 59, with the criterion of eq. 52, 60
//! or 74 and the solver of Section 4.3 / 5.4).
//!
//! Given the current UAV positions and headings, the planner's estimate ẑ and its covariance M:
//!
//! 1. the target uncertainty is `Uncertainty::with_eq36_side(ẑ, M, r_avg, κ)`: a Gaussian `N(ẑ, M)`
//!    truncated to a square of side `A = min(10 σ_t, 6 σ_t + κ r_avg)` (eq. 36) with
//!    `σ_t = sqrt(λ_max(M))` (our rule: the scenario's `sigma_t` is only the controlled mode's input)
//!    and `r_avg` the mean distance from the *current* UAV positions to ẑ (eq. 35);
//! 2. the criterion is prepared once for that uncertainty (`mc` samples from
//!    `derive_seed(run_seed, step, ObjectiveSamples)`);
//! 3. the solver (seeded by `derive_seed(run_seed, step, Solver)`) searches the headings, UAV i inside
//!    its cone `α_i ± Δα` (unwrapped around `α_i`), starting from the current headings moved into the
//!    cone, minimising the lexicographic [`Fitness`] (constraint violation, then criterion);
//!    `formation` skips the search and uses [`formation_headings`];
//! 4. *standoff search* (our addition; the paper's runs never need it): when no candidate in the cones
//!    meets every constraint, the solver searches again (seeded by `derive_seed(run_seed, step,
//!    StandoffSolver)`), now over the headings each UAV can reach, `ψ_i ± L/R_min` (so the turn radius
//!    holds by construction), ranking candidates by priority tiers ([`Fitness::tiered`]): first the
//!    turn-radius and spacing violations (what the airframe can fly, collisions), then the approach
//!    distance, then the heading cone, then the criterion. The better of the two searches' best plans
//!    under that order is chosen. Without it, UAVs that have reached `L_min` — where every heading in a
//!    cone narrower than ±90° leads closer to ẑ — trade the constraints off as one sum and, over
//!    thousands of steps, fly turns tighter than `R_min` through the emitter's neighbourhood and into each
//!    other (the 100 000-step soak found two UAVs 0.6 mm apart). With it they orbit at the standoff
//!    distance: the heading cone is then reported violated;
//! 5. with `--solver gradient` (ours) steps 3–4 are one search instead: every UAV's own constraints —
//!    turn radius, approach distance, heading cone — are settled first, each UAV alone
//!    ([`crate::heading_interval`]: its box of the reachable headings that keep the approach distance in
//!    the cone, or the one heading that keeps it closest to the cone), then [`Gradient`] minimises the
//!    tiered fitness of step 4 over the product of those boxes (the criterion, with the spacing as a
//!    constraint; a second search over every reachable heading when the spacing cannot hold there —
//!    certified, followed by [`Shield::pull_into_cones`], which takes back UAV by UAV what that joint
//!    search left of the heading cone, turning a neighbour in the way with the UAV). The tiers being
//!    the same, its plans rank by the same order as the two searches'. Certified, the searches hand over to the shield ([`CERTIFIED_HANDOFF`],
//!    [`Handoff`]): the joint search stops where the heading cone is the last tier left (the pull
//!    lowers that piecewise-linear sum far more cheaply than quasi-Newton steps, which stall against
//!    the certificate), runs a local search from the box plan of its own, skips a second start after a
//!    certified one, and leaves a violation tier on a plateau; where that finds no certified plan, the
//!    searches run again to their own ends (a plan's last digits count when it is ranked by its
//!    margins). With
//!    `safety = "certified"`, when the local search ends without a certified plan, PSO searches every
//!    reachable heading too (seeded `(run_seed, step, StandoffSolver)`, started from the local best) and
//!    the better of the two is kept: the plan with the largest minimum margin, or a certified one the
//!    local search missed;
//! 6. the chosen headings (wrapped into (−π, π]), the waypoints they lead to, the criterion there and
//!    the violated or binding constraints are returned with the iteration and evaluation counts and
//!    the wall-clock planning time.

use std::time::Instant;

use nalgebra::{Matrix2, Vector2};
use tdoa::rng::{Purpose, derive_seed};
use tdoa::{MAX_UAVS, TdoaError, Uncertainty};
use thiserror::Error;

use crate::constraints::{ActiveConstraint, ConstraintKind, Constraints};
use crate::fitness::{Fitness, TIERS};
use crate::formation::formation_headings;
use crate::gradient::{Gradient, GradientConfig, Handoff};
use crate::heading_interval::{CERTIFIED_RESOLUTION, HeadingInterval, Uav, heading_interval, heading_interval_of};
use crate::objective::{ObjectiveKind, Sampling};
use crate::shield::{CONE_TIER, EmitterMotion, PositionMargin, Shield, prediction, safety_limits};
use crate::solver::{SearchSpace, SearchSpaceError, Solver, SolverKind, SolverResult};
use model::kinematics::{bearing, next_position, turn_angle, wrap_angle};
use model::safety::{SafetyMode, SafetyReport};
use model::scenario::{Scenario, ScenarioError};

/// Why a planning step could not run.
#[derive(Debug, Error)]
pub enum PlanError {
    /// Lists that must have one entry per UAV do not.
    #[error("{what}: expected {expected} values (one per UAV), got {got}")]
    LengthMismatch {
        /// Which list.
        what: &'static str,
        /// The scenario's UAV count.
        expected: usize,
        /// The length given.
        got: usize,
    },
    /// A position, heading, estimate or covariance entry is NaN or infinite.
    #[error("{what} is not a finite number ({value})")]
    NotFinite {
        /// Which input.
        what: String,
        /// Its value.
        value: f64,
    },
    /// The scenario is invalid.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// The estimate and covariance do not form a valid uncertainty (e.g. M not positive definite),
    /// or the criterion could not be built.
    #[error("target uncertainty: {0}")]
    Uncertainty(#[from] TdoaError),
    /// The heading cones could not form a search space.
    #[error(transparent)]
    SearchSpace(#[from] SearchSpaceError),
}

/// The inputs of one planning step.
#[derive(Debug, Clone, Copy)]
pub struct PlanRequest<'a> {
    /// Current UAV positions, metres.
    pub positions: &'a [Vector2<f64>],
    /// Current headings, radians.
    pub headings: &'a [f64],
    /// The planner's estimate ẑ of the emitter, metres.
    pub estimate: Vector2<f64>,
    /// Its covariance M, m² (symmetric positive definite).
    pub covariance: Matrix2<f64>,
    /// Motion, noise, constraint, criterion and solver settings.
    pub scenario: &'a Scenario,
    /// The planning criterion (or `formation`).
    pub objective: ObjectiveKind,
    /// The solver (ignored by `formation`).
    pub solver: SolverKind,
    /// The run seed.
    pub run_seed: u64,
    /// The step index (0-based).
    pub step: u64,
    /// The emitter's estimated motion (a constant-velocity model), or `None` for a static emitter: the
    /// safety certificate keeps the standoff from the emitter as predicted along the arcs.
    pub motion: Option<EmitterMotion>,
}

/// The plan of one step.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanOutput {
    /// Commanded headings, radians in (−π, π].
    pub headings: Vec<f64>,
    /// The next waypoints these headings lead to, metres.
    pub waypoints: Vec<Vector2<f64>>,
    /// The criterion at the waypoints, m² (`formation`: the single-point `tr F⁻¹(ẑ)`).
    pub objective_value: f64,
    /// Violation and criterion of the plan; after a standoff search (see the module docs) the violation
    /// by its priority tiers, the order that search ranked the plans by.
    pub fitness: Fitness,
    /// Violated or binding constraints of the plan.
    pub active_constraints: Vec<ActiveConstraint>,
    /// Solver iterations run (0 for `formation`).
    pub iterations: usize,
    /// Criterion evaluations by the solver (0 for `formation`).
    pub evaluations: usize,
    /// Wall-clock time of the whole step, milliseconds.
    pub plan_time_ms: f64,
    /// Kish's effective sample size of the `mc` criterion's weighted points this step (`None` for the
    /// other criteria); see [`crate::objective::CrlbObjective::effective_samples`].
    pub criterion_ess: Option<f64>,
    /// The plan's safety certificate with its minima (`safety = "certified"`; `None` for `waypoints`).
    pub safety: Option<SafetyReport>,
}

fn check_finite(what: impl Fn() -> String, value: f64) -> Result<(), PlanError> {
    if value.is_finite() { Ok(()) } else { Err(PlanError::NotFinite { what: what(), value }) }
}

/// Next waypoints of all UAVs for headings `phi`, on the stack.
pub(crate) fn waypoints_of(
    positions: &[Vector2<f64>],
    headings: &[f64],
    phi: &[f64],
    scenario: &Scenario,
) -> [Vector2<f64>; MAX_UAVS] {
    let mut next = [Vector2::zeros(); MAX_UAVS];
    for i in 0..positions.len() {
        next[i] = next_position(positions[i], headings[i], phi[i], scenario.speed, scenario.dt);
    }
    next
}

/// How the certified planner's gradient searches hand over (see the module docs): the search after a
/// certified one is skipped, and a local search that lowers a violation tier by less than 5 % over
/// [`crate::gradient::PLATEAU_ITERATIONS`] iterations stops (the reach search, or its other starts, take
/// the conflict on).
pub const CERTIFIED_HANDOFF: Handoff = Handoff { from_tier: None, first_feasible: true, plateau: Some(0.05) };

/// The priority tiers of the standoff search (see the module docs) from the violations by kind.
fn standoff_tiers(by_kind: [f64; 4]) -> [f64; TIERS] {
    let v = |k: ConstraintKind| by_kind[k.index()];
    [
        v(ConstraintKind::TurnRadius) + v(ConstraintKind::Spacing),
        v(ConstraintKind::Approach),
        v(ConstraintKind::HeadingCone),
        0.0,
        0.0,
        0.0,
    ]
}

/// The gradient planner's search (`--solver gradient`; see the module docs): the product of the UAVs'
/// own heading boxes ([`heading_interval`]), searched for the criterion by [`Gradient`] from the current
/// headings moved into the boxes, their centre and their corners; when the spacing (the one coupling
/// constraint) is violated there, a second search over every reachable heading from that plan. Returns
/// the better plan with its fitness, and the iterations and evaluations of both searches.
#[allow(clippy::too_many_arguments)]
fn gradient_search(
    constraints: &Constraints,
    pos: &[Vector2<f64>],
    psi: &[f64],
    z: Vector2<f64>,
    sc: &Scenario,
    tiered: &mut dyn FnMut(&[f64]) -> Fitness,
    hard_tiers: usize,
    shield: Option<&Shield<'_>>,
    handoff: Option<Handoff>,
) -> Result<SolverResult, PlanError> {
    let n = pos.len();
    let solver = Gradient::new(sc.gradient).with_handoff(handoff.unwrap_or_default());
    let boxes: Vec<HeadingInterval> = (0..n)
        .map(|i| {
            let uav = Uav { position: pos[i], heading: psi[i], speed: sc.speed, dt: sc.dt };
            match shield {
                Some(sh) => {
                    heading_interval_of(constraints, &uav, z, &|phi| sh.own_deficit(i, phi), CERTIFIED_RESOLUTION)
                }
                None => heading_interval(constraints, &uav, z),
            }
        })
        .collect();
    let lo: Vec<f64> = boxes.iter().map(|b| b.lo).collect();
    let hi: Vec<f64> = boxes.iter().map(|b| b.hi).collect();
    let moved: Vec<f64> = (0..n).map(|i| psi[i].clamp(lo[i], hi[i])).collect();
    // The solver's own starts: the current headings moved into the boxes, their centre, their corners.
    let first = solver.minimize(tiered, &SearchSpace::new(lo, hi, moved)?, 0);
    if first.fitness.tiers()[..hard_tiers].iter().all(|t| *t == 0.0) {
        return Ok(first);
    }
    // The spacing is violated: every reachable heading, from that plan and from straight on.
    let theta = constraints.max_turn();
    let reach = SearchSpace::new(
        psi.iter().map(|p| p - theta).collect(),
        psi.iter().map(|p| p + theta).collect(),
        first.best.clone(),
    )?;
    // Also the cone centres moved into reach, and the backup step (every UAV turning right as far as the
    // backup does), which the shield's certificate always holds when the previous plan was certified.
    let centre: Vec<f64> =
        (0..n).map(|i| psi[i] + turn_angle(psi[i], bearing(pos[i], z)).clamp(-theta, theta)).collect();
    let backup: Vec<f64> = psi.iter().map(|p| p - model::safety::backup_turn(theta)).collect();
    let second = match (shield, handoff) {
        (Some(_), Some(handoff)) => {
            // Handing over to the shield's pull (below): the joint search stops where the heading cone is
            // the last tier left; the box plan, nearest the cones, always gets a local search of its own
            // (it ranks below every certified start, and the certified plan nearest it is the one wanted).
            let reach_solver = solver.with_handoff(Handoff { from_tier: Some(CONE_TIER), ..handoff });
            let single = Gradient { config: GradientConfig { starts: 1, ..sc.gradient }, ..reach_solver };
            let from_box = single.minimize_from(tiered, &reach, std::slice::from_ref(&first.best));
            better_of(from_box, reach_solver.minimize_from(tiered, &reach, &[psi.to_vec(), centre, backup]))
        }
        _ => solver.minimize_from(tiered, &reach, &[first.best.clone(), psi.to_vec(), centre, backup]),
    };
    let found = better_of(first, second);
    // Certified: what the joint search left of the heading cone, taken back UAV by UAV (a UAV the
    // boxes kept is already as near its cone as its own limits allow; one the joint search freed may
    // not be).
    match shield {
        Some(sh) if is_certified(&found.fitness) => {
            let (best, fitness, extra) = sh.pull_into_cones(&found.best, found.fitness, tiered);
            Ok(SolverResult { best, fitness, evaluations: found.evaluations + extra, ..found })
        }
        _ => Ok(found),
    }
}

/// The better of two searches' results (the first on a tie), with the iterations and evaluations of
/// both.
fn better_of(first: SolverResult, second: SolverResult) -> SolverResult {
    let (iterations, evaluations) = (first.iterations + second.iterations, first.evaluations + second.evaluations);
    let best = if second.fitness < first.fitness { second } else { first };
    SolverResult { iterations, evaluations, ..best }
}

/// Whether a certified search's fitness is certified: its first three tiers (the certificate's, see
/// `crate::shield`) are zero.
fn is_certified(fitness: &Fitness) -> bool {
    fitness.tiers()[..3].iter().all(|t| *t == 0.0)
}

/// The receiver's odds the posterior criteria count: the scenario's `receiver.loss` per arrival and
/// `receiver.silence` (with an external front end: the loss and silence its user declares there).
fn arrival_odds(sc: &Scenario) -> Result<tdoa::loss::ArrivalOdds, TdoaError> {
    tdoa::loss::ArrivalOdds::uniform(sc.uav_count(), sc.receiver.loss, sc.receiver.silence)
}

/// Plans one step; see the module docs. With UAV positions known only to their GNSS error
/// ([`PositionMargin`]), the safety constraints keep its margin: `D_min` plus the spacing margin between
/// reported positions, and the standoff's chance bound over the emitter's covariance plus the UAV's
/// position variance; the criterion keeps the estimate's own covariance.
pub fn plan_step(req: &PlanRequest<'_>) -> Result<PlanOutput, PlanError> {
    let start = Instant::now();
    let sc = req.scenario;
    sc.validate()?;
    let n = sc.uav_count();
    for (what, got) in [("positions", req.positions.len()), ("headings", req.headings.len())] {
        if got != n {
            return Err(PlanError::LengthMismatch { what, expected: n, got });
        }
    }
    for (i, p) in req.positions.iter().enumerate() {
        check_finite(|| format!("x of UAV {i}"), p.x)?;
        check_finite(|| format!("y of UAV {i}"), p.y)?;
        check_finite(|| format!("heading of UAV {i}"), req.headings[i])?;
    }
    if let Some(m) = &req.motion {
        for (k, v) in m.velocity.iter().chain(m.velocity_cov.iter()).enumerate() {
            check_finite(|| if k < 2 { "the emitter's velocity".into() } else { "its covariance".into() }, *v)?;
        }
    }
    let (pos, psi, z) = (req.positions, req.headings, req.estimate);
    // The safety constraints see the UAVs' own position errors too (zero for exact positions).
    let safety_cov = req.covariance + Matrix2::identity() * PositionMargin::of(sc).variance_m2;
    let constraints = Constraints::from_scenario(sc).with_covariance(safety_cov).for_step(pos, req.estimate);
    let r_avg = pos.iter().map(|p| (p - z).norm()).sum::<f64>() / n as f64;
    let unc = Uncertainty::with_eq36_side(z, req.covariance, r_avg, sc.kappa)?;
    let objective = crate::objective::prepare(
        req.objective,
        &unc,
        sc.noise_model()?,
        Some(arrival_odds(sc)?),
        Sampling { mc_samples: sc.mc_samples, mc_scheme: sc.mc_scheme, run_seed: req.run_seed, step: req.step },
    )?;

    if sc.safety == SafetyMode::Certified {
        let shield =
            Shield::new(pos, psi, safety_limits(sc), prediction(sc, z, &safety_cov, req.motion), &constraints, z);
        let mut safe = |phi: &[f64]| {
            shield.fitness(phi, || {
                let next = waypoints_of(pos, psi, phi, sc);
                objective.evaluate(&next[..n])
            })
        };
        let found = if !req.objective.is_optimised() {
            // The formation's headings, each moved into reach (the turn radius is never traded).
            let theta = constraints.max_turn();
            let formation = formation_headings(pos, psi, z, &constraints);
            let best: Vec<f64> =
                psi.iter().zip(formation).map(|(p, f)| p + turn_angle(*p, f).clamp(-theta, theta)).collect();
            SolverResult { fitness: safe(&best), best, iterations: 0, evaluations: 0 }
        } else if req.solver == SolverKind::Gradient {
            let mut local =
                gradient_search(&constraints, pos, psi, z, sc, &mut safe, 3, Some(&shield), Some(CERTIFIED_HANDOFF))?;
            if !is_certified(&local.fitness) {
                // The handover trades the searches' last digits for time, which only a certified plan can
                // spare: where none was found, the searches run to their own ends.
                let full = gradient_search(&constraints, pos, psi, z, sc, &mut safe, 3, Some(&shield), None)?;
                local = better_of(local, full);
            }
            if is_certified(&local.fitness) {
                local
            } else {
                // No certified plan found by the local search: the shield's ranking of uncertified plans
                // (the largest minimum margin) has corners a local search misses, so a global one (PSO)
                // over every reachable heading, started from the local search's best.
                let global = reach_with(&*SolverKind::Pso.build(sc), req, &constraints, &mut safe, &local.best)?;
                better_of(local, global)
            }
        } else {
            cone_then_reach(req, &constraints, &mut safe)?
        };
        let SolverResult { best: mut chosen, mut fitness, iterations, evaluations } = found;
        // The backup steps: certified whenever the previous plan was (see `crate::shield`) — the
        // fly-aways' and the circles', the same plan where no UAV flies away (evaluated once).
        let (backup, circles) = (shield.backup(), shield.circle_backup());
        let candidates = if backup == circles { vec![backup] } else { vec![backup, circles] };
        for backup in candidates {
            let fit_backup = safe(&backup);
            if fit_backup < fitness {
                chosen = backup;
                fitness = fit_backup;
            }
        }
        let next = waypoints_of(pos, psi, &chosen, sc);
        let waypoints = next[..n].to_vec();
        let report = constraints.check(pos, psi, z, &chosen, &waypoints);
        let objective_value = objective.evaluate(&waypoints);
        return Ok(PlanOutput {
            headings: chosen.iter().map(|h| wrap_angle(*h)).collect(),
            waypoints,
            objective_value,
            fitness: Fitness::tiered(fitness.tiers(), objective_value),
            active_constraints: report.active,
            iterations,
            evaluations,
            plan_time_ms: start.elapsed().as_secs_f64() * 1e3,
            criterion_ess: objective.effective_samples(),
            safety: Some(shield.report(&chosen)),
        });
    }

    let mut standoff_ran = false;
    let (chosen, iterations, evaluations) = if req.objective.is_optimised() && req.solver == SolverKind::Gradient {
        standoff_ran = true;
        let mut tiered = |phi: &[f64]| {
            let next = waypoints_of(pos, psi, phi, sc);
            let by_kind = constraints.violations_by_kind(pos, psi, z, phi, &next[..n]);
            Fitness::tiered(standoff_tiers(by_kind), objective.evaluate(&next[..n]))
        };
        let r = gradient_search(&constraints, pos, psi, z, sc, &mut tiered, 1, None, None)?;
        (r.best, r.iterations, r.evaluations)
    } else if req.objective.is_optimised() {
        let space = cone_space(&constraints, pos, psi, z, None)?;
        let solver = req.solver.build(sc);
        let mut fitness = |phi: &[f64]| {
            let next = waypoints_of(pos, psi, phi, sc);
            Fitness::new(constraints.violation(pos, psi, z, phi, &next[..n]), objective.evaluate(&next[..n]))
        };
        let result = solver.minimize(&mut fitness, &space, derive_seed(req.run_seed, req.step, Purpose::Solver));
        let (mut best, mut iterations, mut evaluations) = (result.best, result.iterations, result.evaluations);
        if !result.fitness.is_feasible() {
            standoff_ran = true;
            let theta = constraints.max_turn();
            let lo = psi.iter().map(|p| p - theta).collect();
            let hi = psi.iter().map(|p| p + theta).collect();
            let start_point = psi.iter().zip(&best).map(|(p, b)| p + turn_angle(*p, *b).clamp(-theta, theta)).collect();
            let space = SearchSpace::new(lo, hi, start_point)?;
            let mut tiered = |phi: &[f64]| {
                let next = waypoints_of(pos, psi, phi, sc);
                let by_kind = constraints.violations_by_kind(pos, psi, z, phi, &next[..n]);
                Fitness::tiered(standoff_tiers(by_kind), objective.evaluate(&next[..n]))
            };
            let seed = derive_seed(req.run_seed, req.step, Purpose::StandoffSolver);
            let standoff = solver.minimize(&mut tiered, &space, seed);
            iterations += standoff.iterations;
            evaluations += standoff.evaluations + 1;
            if standoff.fitness < tiered(&best) {
                best = standoff.best;
            }
        }
        (best, iterations, evaluations)
    } else {
        (formation_headings(pos, psi, z, &constraints), 0, 0)
    };

    let next = waypoints_of(pos, psi, &chosen, sc);
    let waypoints = next[..n].to_vec();
    let report = constraints.check(pos, psi, z, &chosen, &waypoints);
    let objective_value = objective.evaluate(&waypoints);
    let fitness = if standoff_ran && report.violation > 0.0 {
        Fitness::tiered(
            standoff_tiers(constraints.violations_by_kind(pos, psi, z, &chosen, &waypoints)),
            objective_value,
        )
    } else {
        Fitness::new(report.violation, objective_value)
    };
    Ok(PlanOutput {
        headings: chosen.iter().map(|h| wrap_angle(*h)).collect(),
        waypoints,
        objective_value,
        fitness,
        active_constraints: report.active,
        iterations,
        evaluations,
        plan_time_ms: start.elapsed().as_secs_f64() * 1e3,
        criterion_ess: objective.effective_samples(),
        safety: None,
    })
}

/// The heading cones `α_i ± Δα` as a search space, started from the current headings (unwrapped around
/// α); with `reach = Some(θ_max)` each cone within the UAV's reach `ψ_i ± θ_max` (the turn radius is never
/// traded), or the reachable heading nearest it when they do not meet.
fn cone_space(
    constraints: &Constraints,
    pos: &[Vector2<f64>],
    psi: &[f64],
    z: Vector2<f64>,
    reach: Option<f64>,
) -> Result<SearchSpace, PlanError> {
    let n = pos.len();
    let (mut lo, mut hi, mut start_point) = (Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n));
    for i in 0..n {
        let (l, h) = constraints.cone(pos[i], z);
        let alpha = 0.5 * (l + h);
        let here = alpha + turn_angle(alpha, psi[i]);
        let (l, h) = match reach {
            None => (l, h),
            Some(theta) => {
                let (l, h) = (l.max(here - theta), h.min(here + theta));
                if l <= h {
                    (l, h)
                } else if here - theta > h {
                    (here - theta, here - theta)
                } else {
                    (here + theta, here + theta)
                }
            }
        };
        lo.push(l);
        hi.push(h);
        start_point.push(here);
    }
    Ok(SearchSpace::new(lo, hi, start_point)?)
}

/// The certified search of PSO, GA and ACO: the heading cones within reach first (the paper's search
/// space, where the turn radius holds); when
/// their best plan is not certified, every reachable heading `ψ_i ± L/R_min` (seeded by
/// `derive_seed(run_seed, step, StandoffSolver)`, started from the cone search's best moved into
/// reach). Returns the better plan with its fitness, and the iterations and evaluations of both.
fn cone_then_reach(
    req: &PlanRequest<'_>,
    constraints: &Constraints,
    safe: &mut dyn FnMut(&[f64]) -> Fitness,
) -> Result<SolverResult, PlanError> {
    let (pos, psi, z, sc) = (req.positions, req.headings, req.estimate, req.scenario);
    let theta = constraints.max_turn();
    let solver = req.solver.build(sc);
    let cone = solver.minimize(
        safe,
        &cone_space(constraints, pos, psi, z, Some(theta))?,
        derive_seed(req.run_seed, req.step, Purpose::Solver),
    );
    if is_certified(&cone.fitness) {
        return Ok(cone);
    }
    let reach = reach_with(&*solver, req, constraints, safe, &cone.best)?;
    Ok(better_of(cone, reach))
}

/// `solver` over every reachable heading `ψ_i ± L/R_min` (seeded by `derive_seed(run_seed, step,
/// StandoffSolver)`), started from `from` moved into reach.
fn reach_with(
    solver: &dyn Solver,
    req: &PlanRequest<'_>,
    constraints: &Constraints,
    safe: &mut dyn FnMut(&[f64]) -> Fitness,
    from: &[f64],
) -> Result<SolverResult, PlanError> {
    let (psi, theta) = (req.headings, constraints.max_turn());
    let start_point = psi.iter().zip(from).map(|(p, b)| p + turn_angle(*p, *b).clamp(-theta, theta)).collect();
    let space = SearchSpace::new(
        psi.iter().map(|p| p - theta).collect(),
        psi.iter().map(|p| p + theta).collect(),
        start_point,
    )?;
    Ok(solver.minimize(safe, &space, derive_seed(req.run_seed, req.step, Purpose::StandoffSolver)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::kinematics::bearing;
    use tdoa::{Sensors, crlb};

    /// A planning situation: scenario, current positions and headings, ẑ and M.
    struct Case {
        sc: Scenario,
        pos: Vec<Vector2<f64>>,
        psi: Vec<f64>,
        z: Vector2<f64>,
        m: Matrix2<f64>,
    }

    impl Case {
        /// The nominal step 0 with ẑ = truth and M = F⁻¹(truth).
        fn nominal() -> Self {
            let sc = Scenario::default();
            let sensors = Sensors::new(&sc.uavs, sc.noise_model().unwrap()).unwrap();
            let z = sc.emitter_position();
            let m = crlb(&sensors, &z).unwrap().bound;
            Self { pos: sc.uav_positions(), psi: sc.initial_headings(), z, m, sc }
        }

        fn request(&self, objective: ObjectiveKind, solver: SolverKind) -> PlanRequest<'_> {
            PlanRequest {
                positions: &self.pos,
                headings: &self.psi,
                estimate: self.z,
                covariance: self.m,
                scenario: &self.sc,
                objective,
                solver,
                run_seed: 42,
                step: 3,
                motion: None,
            }
        }

        fn assert_in_cones(&self, out: &PlanOutput, label: &str) {
            for (i, (p, h)) in self.pos.iter().zip(&out.headings).enumerate() {
                let off = turn_angle(bearing(*p, self.z), *h).abs();
                assert!(off <= self.sc.delta_alpha + 1e-12, "{label}: UAV {i} off by {off}");
                assert!(*h > -std::f64::consts::PI && *h <= std::f64::consts::PI);
            }
        }
    }

    fn bits(out: &PlanOutput) -> Vec<u64> {
        let mut v: Vec<u64> = out.headings.iter().map(|h| h.to_bits()).collect();
        v.extend(out.waypoints.iter().flat_map(|w| [w.x.to_bits(), w.y.to_bits()]));
        v.push(out.objective_value.to_bits());
        v.push(out.fitness.violation().to_bits());
        v.extend([out.iterations as u64, out.evaluations as u64, out.active_constraints.len() as u64]);
        v
    }

    #[test]
    fn deterministic() {
        let case = Case::nominal();
        for objective in ObjectiveKind::ALL {
            for solver in SolverKind::ALL {
                let req = case.request(objective, solver);
                let a = plan_step(&req).unwrap();
                let b = plan_step(&req).unwrap();
                assert_eq!(bits(&a), bits(&b), "{objective} {solver}");
                assert_eq!(a.active_constraints, b.active_constraints);
            }
        }
        // Another seed changes the solver's trajectory.
        let req = case.request(ObjectiveKind::Analytical, SolverKind::Pso);
        let a = plan_step(&req).unwrap();
        let c = plan_step(&PlanRequest { run_seed: 43, ..req }).unwrap();
        assert_ne!(bits(&a), bits(&c));
    }

    /// Every covariance the wire takes (positive normal variances, a finite trace) is planned by every
    /// criterion — also where its determinant under- or overflows (1e-300 m², 1e±200 m²), which a direct
    /// inverse refuses: a refused step would end the run.
    #[test]
    fn a_covariance_at_the_edges_of_the_floats_is_planned() {
        let case = Case::nominal();
        for m in [
            Matrix2::new(1e-300, 0.0, 0.0, 2e-300),
            Matrix2::new(1e-200, 5e-201, 5e-201, 1e-200),
            Matrix2::new(1e200, 0.0, 0.0, 1e200),
            Matrix2::new(1e-150, 0.0, 0.0, 1e150),
        ] {
            for objective in ObjectiveKind::ALL {
                let req = PlanRequest { covariance: m, ..case.request(objective, SolverKind::Gradient) };
                let out = plan_step(&req).unwrap_or_else(|e| panic!("{objective} with M = {m:?}: {e}"));
                assert!(out.headings.iter().all(|h| h.is_finite()), "{objective} {m:?}");
            }
        }
    }

    #[test]
    fn nominal_plans_are_feasible_and_beat_flying_straight() {
        let case = Case::nominal();
        let sc = &case.sc;
        let noise = sc.noise_model().unwrap();
        let r_avg = case.pos.iter().map(|p| (p - case.z).norm()).sum::<f64>() / 3.0;
        let unc = Uncertainty::with_eq36_side(case.z, case.m, r_avg, sc.kappa).unwrap();
        let straight: Vec<_> =
            case.pos.iter().zip(&case.psi).map(|(p, h)| next_position(*p, *h, *h, sc.speed, sc.dt)).collect();
        let constraints = Constraints::from_scenario(sc);
        assert!(constraints.check(&case.pos, &case.psi, case.z, &case.psi, &straight).is_feasible());
        for objective in ObjectiveKind::ALL {
            for solver in SolverKind::ALL {
                if objective != ObjectiveKind::Analytical && solver != SolverKind::Pso {
                    continue; // every criterion with PSO, every solver with the analytical criterion
                }
                let label = format!("{objective}/{solver}");
                let out = plan_step(&case.request(objective, solver)).unwrap();
                assert!(out.fitness.is_feasible(), "{label}: {:?}", out.active_constraints);
                assert!(out.active_constraints.iter().all(|c| !c.is_violated()));
                case.assert_in_cones(&out, &label);
                for i in 0..3 {
                    let w = next_position(case.pos[i], case.psi[i], out.headings[i], sc.speed, sc.dt);
                    assert!((w - out.waypoints[i]).norm() < 1e-6);
                }
                if objective.is_optimised() {
                    let obj = crate::objective::prepare(
                        objective,
                        &unc,
                        noise.clone(),
                        None,
                        Sampling { mc_samples: sc.mc_samples, mc_scheme: sc.mc_scheme, run_seed: 42, step: 3 },
                    )
                    .unwrap();
                    let keep = obj.evaluate(&straight);
                    assert!(out.objective_value < keep, "{label}: planned {} vs straight {keep}", out.objective_value);
                    assert!(out.iterations >= 1 && out.evaluations > 0);
                } else {
                    assert_eq!((out.iterations, out.evaluations), (0, 0));
                }
            }
        }
    }

    /// Three UAVs orbiting ẑ just outside `L_min`, 120° apart, heading tangentially (counter-clockwise).
    fn orbiting() -> Case {
        let mut case = Case::nominal();
        let r = case.sc.l_min + 50.0;
        case.pos.clear();
        case.psi.clear();
        for i in 0..3 {
            let a = 2.0 * std::f64::consts::PI * i as f64 / 3.0;
            case.pos.push(case.z + Vector2::new(a.cos(), a.sin()) * r);
            case.psi.push(wrap_angle(a + std::f64::consts::FRAC_PI_2));
        }
        case
    }

    /// On the standoff ring, where every heading of the cone leads inwards, the certified gradient plan
    /// ranks at least as well as PSO's in the shield's order, whatever the UAVs' distances and headings:
    /// a UAV's box keeps its standoff reserve before the cone, so the backup step (every UAV turning
    /// away, far out of its cone) does not win over a plan that keeps the reserve nearer the cone.
    #[test]
    fn on_the_ring_the_certified_gradient_plan_ranks_at_least_as_well_as_pso() {
        let mut compared = 0;
        for (k, extra) in [30.0, 150.0, 400.0, 900.0].into_iter().enumerate() {
            for turn in [-0.4, -0.15, 0.0, 0.2, 0.45] {
                let mut case = orbiting();
                case.sc.safety = SafetyMode::Certified;
                // A settled estimate (σ 50 m), so that the ring is where the UAVs are.
                case.m = Matrix2::identity() * 2500.0;
                let r = case.sc.l_min + extra;
                for i in 0..3 {
                    let a = 2.0 * std::f64::consts::PI * i as f64 / 3.0 + 0.2 * k as f64;
                    case.pos[i] = case.z + Vector2::new(a.cos(), a.sin()) * r;
                    case.psi[i] = wrap_angle(a + std::f64::consts::FRAC_PI_2 + turn);
                }
                let gradient = plan_step(&case.request(ObjectiveKind::Analytical, SolverKind::Gradient)).unwrap();
                let pso = plan_step(&case.request(ObjectiveKind::Analytical, SolverKind::Pso)).unwrap();
                if !pso.safety.is_some_and(|s| s.certified) {
                    continue;
                }
                compared += 1;
                let label = format!("{extra} m outside L_min, turned {turn} rad");
                assert!(
                    gradient.fitness <= pso.fitness,
                    "{label}: gradient {:?} vs PSO {:?}",
                    gradient.fitness,
                    pso.fitness
                );
            }
        }
        assert!(compared >= 10, "only {compared} of the states had a certified PSO plan to compare with");
    }

    /// With arrivals lost (receiver.loss 0.3), the posterior criterion is the expected posterior trace
    /// over the arrivals received: the step reports that value at its waypoints, and its plan is at least
    /// as good under it as the plan made for a perfect receiver — which the loss changes.
    #[test]
    fn the_posterior_criterion_counts_lost_arrivals() {
        // Step 6 of a nominal run (seed 1) with 30 % of arrivals lost: UAV 0 is free of its cone.
        let mut case = Case::nominal();
        case.pos = vec![
            Vector2::new(3486.154777252734, 2682.135104045065),
            Vector2::new(12700.668853960275, 2710.1764819217765),
            Vector2::new(7392.023194338519, 10241.121245111975),
        ];
        case.psi = vec![0.4703387296845407, 0.35410593578786415, 0.6983479283652942];
        case.z = Vector2::new(24609.786955059564, 14815.713568627936);
        case.m = Matrix2::new(239755.06194176787, 138077.2756263937, 138077.2756263937, 81408.0017322886);
        let blind = plan_step(&case.request(ObjectiveKind::Posterior, SolverKind::Gradient)).unwrap();
        case.sc.receiver.loss = 0.3;
        let aware = plan_step(&case.request(ObjectiveKind::Posterior, SolverKind::Gradient)).unwrap();
        let odds = tdoa::loss::ArrivalOdds::uniform(3, 0.3, 0.0).unwrap();
        let info = case.m.try_inverse().unwrap();
        let expected = |w: &[Vector2<f64>]| {
            let pts: Vec<[f64; 2]> = w.iter().map(|p| [p.x, p.y]).collect();
            let sensors = Sensors::new(&pts, case.sc.noise_model().unwrap()).unwrap();
            tdoa::loss::expected_posterior_trace(&info, &sensors, &case.z, &odds).unwrap()
        };
        let (ea, eb) = (expected(&aware.waypoints), expected(&blind.waypoints));
        assert!((aware.objective_value - ea).abs() <= 1e-9 * ea, "{} vs {ea}", aware.objective_value);
        assert!(ea <= eb * (1.0 + 1e-9), "the loss-aware plan {ea} m² is worse than the blind one {eb} m²");
        assert!(blind.objective_value < ea, "losing arrivals must cost information");
        assert_ne!(aware.headings, blind.headings, "the loss changed nothing");
    }

    #[test]
    fn where_the_local_search_finds_no_certified_plan_the_global_one_does_at_least_as_well() {
        // Three UAVs 1 km inside the standoff ring, all flying at ẑ: no plan of this step is certified.
        // The local search's best (as plan_step's first stage finds it) against plan_step's answer.
        let mut case = orbiting();
        let r = case.sc.l_min - 1000.0;
        for i in 0..3 {
            let a = 2.0 * std::f64::consts::PI * i as f64 / 3.0;
            case.pos[i] = case.z + Vector2::new(a.cos(), a.sin()) * r;
            case.psi[i] = wrap_angle(a + std::f64::consts::PI);
        }
        let req = case.request(ObjectiveKind::Analytical, SolverKind::Gradient);
        let (sc, pos, psi, z) = (&case.sc, &case.pos[..], &case.psi[..], case.z);
        let constraints = Constraints::from_scenario(sc).with_covariance(case.m).for_step(pos, z);
        let shield = Shield::new(pos, psi, safety_limits(sc), prediction(sc, z, &case.m, None), &constraints, z);
        let mut safe = |phi: &[f64]| shield.fitness(phi, || 0.0);
        let found = gradient_search(&constraints, pos, psi, z, sc, &mut safe, 3, Some(&shield), None).unwrap();
        let (local, local_evaluations) = (found.best, found.evaluations);
        let local_report = shield.check(&local);
        assert!(!local_report.certified, "the state was meant to be uncertifiable: {local_report:?}");
        let out = plan_step(&req).unwrap();
        let report = out.safety.unwrap();
        assert!(!report.certified);
        // The global search ran (at least a swarm of 40 more evaluations; PSO stops early) and its plan is
        // at least as good in the shield's ranking as the local one.
        assert!(out.evaluations >= local_evaluations + 40, "{} vs {local_evaluations}", out.evaluations);
        let (fit_out, fit_local) = (safe(&out.headings), safe(&local));
        assert!(fit_out <= fit_local, "{fit_out:?} vs {fit_local:?}");
        assert!(report.deficit() <= local_report.deficit(), "{} vs {}", report.deficit(), local_report.deficit());
    }

    #[test]
    fn at_the_standoff_distance_the_plan_orbits_instead_of_closing_in() {
        // Every heading in a ±25° cone around the bearing to ẑ leads inside L_min: the cone search finds
        // no feasible plan, and the standoff search keeps the turn radius, the spacing and the approach
        // distance, giving up only the cone.
        let case = orbiting();
        let constraints = Constraints::from_scenario(&case.sc);
        for solver in SolverKind::ALL {
            let out = plan_step(&case.request(ObjectiveKind::Analytical, solver)).unwrap();
            let label = format!("{solver:?}");
            let by_kind = constraints.violations_by_kind(&case.pos, &case.psi, case.z, &out.headings, &out.waypoints);
            assert_eq!(by_kind[ConstraintKind::TurnRadius.index()], 0.0, "{label}: {:?}", out.active_constraints);
            assert_eq!(by_kind[ConstraintKind::Spacing.index()], 0.0, "{label}: {:?}", out.active_constraints);
            assert_eq!(by_kind[ConstraintKind::Approach.index()], 0.0, "{label}: {:?}", out.active_constraints);
            assert!(by_kind[ConstraintKind::HeadingCone.index()] > 0.0, "{label}: the cone cannot hold");
            for (w, i) in out.waypoints.iter().zip(0..) {
                assert!((w - case.z).norm() >= case.sc.l_min, "{label}: UAV {i} inside L_min");
            }
            assert!(out.objective_value.is_finite(), "{label}");
            // The cone search alone (what the paper does) would have closed in: its best plan cannot keep
            // the approach distance, whatever the heading in the cone.
            let mut inward = case.psi.clone();
            for (h, p) in inward.iter_mut().zip(&case.pos) {
                let (lo, hi) = constraints.cone(*p, case.z);
                *h = if turn_angle(*h, lo).abs() < turn_angle(*h, hi).abs() { lo } else { hi };
            }
            let next = waypoints_of(&case.pos, &case.psi, &inward, &case.sc);
            let cone_best = constraints.violations_by_kind(&case.pos, &case.psi, case.z, &inward, &next[..3]);
            assert!(cone_best[ConstraintKind::Approach.index()] > 0.0, "{label}: {cone_best:?}");
        }
    }

    #[test]
    fn the_standoff_search_is_deterministic_and_leaves_feasible_steps_alone() {
        let case = orbiting();
        let a = plan_step(&case.request(ObjectiveKind::Analytical, SolverKind::Pso)).unwrap();
        let b = plan_step(&case.request(ObjectiveKind::Analytical, SolverKind::Pso)).unwrap();
        assert_eq!(bits(&a), bits(&b));
        // The nominal step 0 is feasible in the cones: the standoff search does not run (it would add
        // its evaluations) and the headings stay in the cones.
        let nominal = Case::nominal();
        let out = plan_step(&nominal.request(ObjectiveKind::Analytical, SolverKind::Pso)).unwrap();
        assert!(out.fitness.is_feasible());
        assert!(out.evaluations <= 40 * 16, "{}", out.evaluations);
        nominal.assert_in_cones(&out, "nominal");
    }

    #[test]
    fn cones_straddling_pi_are_respected() {
        // ẑ due west of the swarm: every cone is centred near ±π.
        let sc = Scenario {
            uavs: vec![[30000.0, 1000.0], [32000.0, -1500.0], [31000.0, 4000.0]],
            emitter: [0.0, 0.0],
            ..Scenario::default()
        };
        let case = Case {
            pos: sc.uav_positions(),
            psi: sc.initial_headings(),
            z: Vector2::new(0.0, 0.0),
            m: Matrix2::new(4e4, 0.0, 0.0, 9e4),
            sc,
        };
        for solver in SolverKind::ALL {
            let out = plan_step(&case.request(ObjectiveKind::Analytical, solver)).unwrap();
            assert!(out.fitness.is_feasible(), "{solver}: {:?}", out.active_constraints);
            case.assert_in_cones(&out, solver.name());
        }
    }

    #[test]
    fn invalid_inputs_are_refused() {
        let case = Case::nominal();
        let req = case.request(ObjectiveKind::Single, SolverKind::Pso);
        assert!(matches!(
            plan_step(&PlanRequest { headings: &case.psi[..2], ..req }),
            Err(PlanError::LengthMismatch { what: "headings", .. })
        ));
        let bad = [case.psi[0], f64::NAN, case.psi[2]];
        assert!(matches!(plan_step(&PlanRequest { headings: &bad, ..req }), Err(PlanError::NotFinite { .. })));
        assert!(matches!(
            plan_step(&PlanRequest { covariance: Matrix2::new(1.0, 0.0, 0.0, -1.0), ..req }),
            Err(PlanError::Uncertainty(_))
        ));
    }
}
