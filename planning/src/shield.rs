//! The planner's safety shield (`safety = "certified"`): every candidate plan ranked first by its
//! safety certificate ([`model::safety`]), then by the heading cone, then by the criterion.
//!
//! The certificate is a hard constraint, never traded. The lexicographic [`Fitness`] has six tiers,
//! each the largest, summed or mean normalised deficit of a group of limits, 0 when they hold:
//!
//! 1. a collision — turn radius, spacing along the arcs, and the spacing of the backup circles, for
//!    ever (never bought with a standoff margin, whose bound already carries the chance constraint's
//!    `k·σ`): the spacing does not depend on the emitter, so the backup step keeps it by induction
//!    even when a moving emitter leaves no certified plan;
//! 2. the step's own limits — the standoff along the arcs too (no backup margin bought with them);
//! 3. every limit, the backup's included (0 exactly when certified): every certified plan ranks above
//!    every uncertified one whatever its criterion, and among uncertified plans the one with the
//!    largest minimum margin (relative to each bound) wins;
//! 4. the deficits summed: ranks the plans whose worst limit cannot be helped (a UAV already deep
//!    inside the ring) by the others;
//! 5. the reserve beyond the standoff bounds (`SafetyReport::reserve_deficit`, the mean shortfall
//!    over the UAVs: one estimate update's worth and one step of the emitter's motion), kept where it
//!    can be so that a small move of the estimate does not take the next step's certificate away —
//!    every UAV's, not only the one furthest short;
//! 6. the heading cone (eq. 58): a preference of the paper's method that a certified plan may have to
//!    give up (on the standoff ring every heading in the cone leads inwards).
//!
//! The criterion decides among the rest; for an uncertified plan it is not evaluated.
//!
//! Where the gradient planner's joint search freed the UAVs from their own boxes,
//! [`Shield::pull_into_cones`] then takes back what it left of the heading cone, UAV by UAV — and where
//! a neighbour is in a UAV's way, with the neighbour turning too, or beyond what blocks the way.
//!
//! Every solver's result is compared with the **backup step** (every UAV turns right by `θ_b`, the first
//! step of the backup orbits of `model::safety`), which is certified whenever the previous step's plan
//! was and the estimate has not moved its margins away: so a certified plan is found at every step
//! after a certified one, whatever the solver (see `model::safety` for the argument).
//!
//! Units: metres, seconds, radians.

use std::cell::RefCell;

use model::safety::{Certifier, EmitterPrediction, SafetyLimits, SafetyReport, certify};
use nalgebra::{Matrix2, Vector2};

use crate::constraints::{Constraints, FEASIBILITY_EPS};
use crate::fitness::Fitness;
use model::kinematics::wrap_angle;
use model::scenario::Scenario;

/// The estimated motion of a constant-velocity emitter, as the fused estimator gives it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EmitterMotion {
    /// Velocity estimate, m/s.
    pub velocity: Vector2<f64>,
    /// Its covariance, m²/s².
    pub velocity_cov: Matrix2<f64>,
}

pub use model::safety::SPACING_POSITION_SIGMAS;

/// Halvings of a UAV's pull towards its cone ([`Shield::pull_into_cones`]) before it gives up.
pub const CONE_PULL_HALVINGS: usize = 8;
/// Headings of a UAV's reach [`Shield::pull_into_cones`] tries beyond what blocks its pull (intervals).
pub const LEAP_SAMPLES: usize = 16;
/// Rounds over the UAVs of [`Shield::pull_into_cones`] at most.
pub const CONE_PULL_ROUNDS: usize = 2;
/// Bisections of a UAV's pull between the accepted fraction of the way and the rejected one above it.
pub const CONE_PULL_BISECTIONS: usize = 4;
/// Halvings of a group's turn in [`Shield::pull_into_cones`]'s group pull.
pub const GROUP_PULL_HALVINGS: usize = 3;
/// Golden sections of a group member's reach in the group pull (the interval shrinks to 0.618ⁿ).
pub const GROUP_PULL_SECTIONS: usize = 14;
/// UAVs a group pull turns besides the one pulled, at most.
pub const GROUP_PULL_OTHERS: usize = 1;
/// Evaluations of all group pulls of one [`Shield::pull_into_cones`], at most.
pub const GROUP_PULL_BUDGET: usize = 80;
/// The index of the heading cone's tier in the shield's [`Fitness`] (the last one).
pub const CONE_TIER: usize = 5;
const _: () = assert!(CONE_TIER == crate::fitness::TIERS - 1, "the cone is the shield's last tier");

/// What the UAVs' own position errors cost the safety constraints: the planner knows each UAV where its
/// GNSS reports it, `σ_g` per axis per step and `σ_gb` for the flight (the scenario's `receiver.gnss_*`),
/// so the true distance between two UAVs differs from the reported one by a Gaussian of variance
/// `2 (σ_g² + σ_gb²)` along their line, and a UAV's true distance to the emitter by one of variance
/// `σ_g² + σ_gb²` more than the emitter's own.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionMargin {
    /// Added to the emitter's covariance in the standoff's chance bound (isotropic), m².
    pub variance_m2: f64,
    /// Added to `D_min` for the certificate: [`SPACING_POSITION_SIGMAS`] relative σ, metres.
    pub spacing_m: f64,
}

impl PositionMargin {
    /// The margin of `sc`'s receiver (zero for exact positions: the paper's world, unchanged).
    pub fn of(sc: &Scenario) -> Self {
        let var = sc.receiver.gnss_sigma_m.powi(2) + sc.receiver.gnss_bias_sigma_m.powi(2);
        Self { variance_m2: var, spacing_m: SPACING_POSITION_SIGMAS * (2.0 * var).sqrt() }
    }
}

/// The limits of `scenario` as the certificate takes them: `D_min` with the [`PositionMargin`] (a pair
/// below `D_min` itself is what the first tier, a collision, ranks).
pub fn safety_limits(scenario: &Scenario) -> SafetyLimits {
    let margin = PositionMargin::of(scenario).spacing_m;
    SafetyLimits {
        arc_len: scenario.speed * scenario.dt,
        dt: scenario.dt,
        r_min: scenario.r_min,
        d_min: scenario.d_min + margin,
        position_margin_m: margin,
        l_min: scenario.l_min,
        standoff_k: crate::constraints::standoff_k(scenario.standoff_confidence),
        horizon_s: scenario.safety_horizon_s,
    }
}

/// The emitter as predicted from ẑ (`estimate`, covariance `cov`) and, for a moving emitter, its
/// estimated motion (white-acceleration noise of `scenario`).
pub fn prediction(
    scenario: &Scenario,
    estimate: Vector2<f64>,
    cov: &Matrix2<f64>,
    motion: Option<EmitterMotion>,
) -> EmitterPrediction {
    match motion {
        Some(m) => EmitterPrediction::moving(estimate, cov, m.velocity, &m.velocity_cov, scenario.process_noise_accel),
        None => EmitterPrediction::fixed(estimate, cov),
    }
}

/// One planning step's shield: the UAVs' state, the limits and the predicted emitter.
#[derive(Debug)]
pub struct Shield<'a> {
    /// Current positions, metres.
    pub positions: &'a [Vector2<f64>],
    /// Current headings, radians.
    pub headings: &'a [f64],
    /// The limits.
    pub limits: SafetyLimits,
    /// The predicted emitter.
    pub emitter: EmitterPrediction,
    /// The heading-cone half-width Δα and the bearings to ẑ come from here.
    pub constraints: &'a Constraints,
    /// ẑ, metres.
    pub estimate: Vector2<f64>,
    /// The step's certifier, keeping what one heading or one pair decided while it is unchanged.
    certifier: RefCell<Certifier<'a>>,
    /// Each UAV's cone centre `α_i` (the midpoint of [`Constraints::cone`]), computed once per step.
    cone_centres: Vec<f64>,
}

/// A plan being pulled into the cones ([`Shield::pull_into_cones`]): its headings, their fitness, the
/// evaluations spent and those left to group pulls.
struct Pulling<'f> {
    x: Vec<f64>,
    best: Fitness,
    evaluations: usize,
    group_budget: usize,
    fitness: &'f mut dyn FnMut(&[f64]) -> Fitness,
}

impl Pulling<'_> {
    /// The fitness of the headings `x` holds now, counted.
    fn evaluate(&mut self) -> Fitness {
        self.evaluations += 1;
        (self.fitness)(&self.x)
    }

    /// [`Self::evaluate`] for a group pull, out of its budget.
    fn evaluate_grouped(&mut self) -> Fitness {
        self.group_budget = self.group_budget.saturating_sub(1);
        self.evaluate()
    }
}

impl<'a> Shield<'a> {
    /// The shield of UAVs at `positions` with headings `headings`.
    pub fn new(
        positions: &'a [Vector2<f64>],
        headings: &'a [f64],
        limits: SafetyLimits,
        emitter: EmitterPrediction,
        constraints: &'a Constraints,
        estimate: Vector2<f64>,
    ) -> Self {
        let certifier = RefCell::new(Certifier::new(positions, headings, emitter, limits));
        let cone_centres = positions
            .iter()
            .map(|p| {
                let (lo, hi) = constraints.cone(*p, estimate);
                0.5 * (lo + hi)
            })
            .collect();
        Self { positions, headings, limits, emitter, constraints, estimate, certifier, cone_centres }
    }

    /// The certificate of the plan `phi` (fast: minima only checked against their bounds).
    pub fn check(&self, phi: &[f64]) -> SafetyReport {
        self.certifier.borrow_mut().check(phi, false)
    }

    /// The certificate of the plan `phi` with its minima bracketed (for the step's report).
    pub fn report(&self, phi: &[f64]) -> SafetyReport {
        certify(self.positions, self.headings, phi, &self.emitter, &self.limits, true)
    }

    /// The summed normalised excess of the headings `phi` over their cones (eq. 58), 0 inside.
    pub fn cone_excess(&self, phi: &[f64]) -> f64 {
        phi.iter().take(self.cone_centres.len()).enumerate().map(|(i, h)| self.uav_cone_excess(i, *h)).sum()
    }

    /// How far the heading `h` of UAV `i` lies outside its cone, radians (0 inside).
    fn cone_overshoot(&self, i: usize, h: f64) -> f64 {
        (wrap_angle(h - self.cone_centres[i]).abs() - self.constraints.delta_alpha).max(0.0)
    }

    /// [`Self::cone_overshoot`] normalised by Δα as the cone tier counts it: 0 within its tolerance.
    fn uav_cone_excess(&self, i: usize, h: f64) -> f64 {
        let v = self.cone_overshoot(i, h) / self.constraints.delta_alpha;
        if v > FEASIBILITY_EPS { v } else { 0.0 }
    }

    /// The shield's fitness of `phi`: the six tiers of the module docs, then `objective()` — evaluated
    /// only for a certified plan.
    pub fn fitness(&self, phi: &[f64], objective: impl FnOnce() -> f64) -> Fitness {
        let report = self.check(phi);
        let cone = self.cone_excess(phi);
        let value = if report.certified { objective() } else { f64::INFINITY };
        let [collision, step, deficit, total, reserve] = report.tiers();
        Fitness::tiered([collision, step, deficit, total, reserve, cone], value)
    }

    /// The largest deficit of UAV `i`'s own limits (standoff along its arc, its backup's standoff; the
    /// turn radius holds in reach) and of its standoff reserve if it flies the heading `phi` — 0 when
    /// they hold: the gradient planner's per-UAV box ([`crate::heading_interval::heading_interval_of`]).
    ///
    /// In the order of the shield's tiers: a heading whose own step breaks a limit scores `3 + ` that
    /// deficit, one whose backup breaks a limit `1 + ` that deficit (at most 2), and a certified heading
    /// its reserve shortfall (at most 1). So the box keeps the reserve (tier 5) where a heading can, and
    /// gives up the heading cone (tier 6) for it, as the joint search's order does: a UAV on the standoff
    /// ring is pinned to the heading nearest its cone that keeps the reserve, and the backup step (every
    /// UAV turning away, far outside its cone) no longer wins over the box plan on the reserve alone.
    pub fn own_deficit(&self, i: usize, phi: f64) -> f64 {
        let r = certify(&self.positions[i..=i], &self.headings[i..=i], &[phi], &self.emitter, &self.limits, false);
        if r.step_deficit > 0.0 {
            3.0 + r.step_deficit
        } else if r.deficit() > 0.0 {
            1.0 + r.deficit().min(1.0)
        } else {
            r.reserve_deficit.min(1.0)
        }
    }

    /// Pulls each UAV whose heading lies outside its cone (eq. 58) towards the nearest edge of the cone,
    /// within its reach `ψ ± θ_max`: the whole way, or the largest of [`CONE_PULL_HALVINGS`] halvings
    /// of it that makes `fitness` lexicographically smaller (`current` is the fitness of `plan`); UAV by
    /// UAV, in rounds while one moves (at most [`CONE_PULL_ROUNDS`]). The cone is the last tier and a
    /// sum over the UAVs, so one UAV's move lowers it alone, and the fitness keeps every earlier tier
    /// from paying for it: a certified plan stays certified with its reserve. What a joint search over
    /// every reachable heading leaves of the cone where the UAVs' boxes conflict (8 UAVs on a small
    /// ring) is taken back here in a few evaluations per UAV. A UAV still outside its cone after its
    /// own pull, because another UAV is in its way, is pulled again with that UAV turning too
    /// (a group pull, at most [`GROUP_PULL_BUDGET`] evaluations in all; none with a moving emitter,
    /// whose backups may fly away: two UAVs left at the edge of their spacing leave their fly-aways no
    /// room to turn). Where neither takes a UAV nearer its cone, it leaps: [`LEAP_SAMPLES`] + 1 headings
    /// over its whole reach, nearest the cone first (`Shield::leap`). Returns the plan, its fitness and
    /// the evaluations spent.
    pub fn pull_into_cones(
        &self,
        plan: &[f64],
        current: Fitness,
        fitness: &mut dyn FnMut(&[f64]) -> Fitness,
    ) -> (Vec<f64>, Fitness, usize) {
        // A moving emitter: no group pulls. UAVs turned together stay at the edge of their spacing, where
        // their fly-aways (the backups a moving emitter may need) have no room to turn: in the safety
        // study it tripled the uncertified steps late in a run (σ < 100 m) whose tightest limit is a
        // fly-away pair. Backup circles, a static emitter's only backups, keep their spacing by induction.
        let group_budget = if self.emitter.is_static() { GROUP_PULL_BUDGET } else { 0 };
        let mut p = Pulling { x: plan.to_vec(), best: current, evaluations: 0, group_budget, fitness };
        for _ in 0..CONE_PULL_ROUNDS {
            let mut moved = false;
            for i in 0..p.x.len() {
                let pulled = self.pull(&mut p, i);
                // Still outside: the UAVs in its way turned with it.
                let grouped = self.group_pull(&mut p, i);
                // Where neither takes it nearer its cone: a heading beyond what blocks the way.
                moved |= pulled || grouped || self.leap(&mut p, i);
            }
            if !moved {
                break;
            }
        }
        (p.x, p.best, p.evaluations)
    }

    /// The target heading of UAV `i` from `phi`: the reachable heading nearest its cone (the nearer
    /// edge clamped into the reach, or the other edge the other way round where that is nearer), `None`
    /// when `phi` is in the cone or already that heading.
    fn cone_target(&self, i: usize, phi: f64) -> Option<f64> {
        // Outside as the cone tier counts it (an excess within its tolerance is none).
        if self.uav_cone_excess(i, phi) == 0.0 {
            return None;
        }
        let (theta, half) = (self.constraints.max_turn(), self.constraints.delta_alpha);
        let off = wrap_angle(phi - self.cone_centres[i]);
        // The nearer edge, or — where the reach ends first on that side (a cone nearly behind the
        // UAV) — the other edge the other way round, whichever reachable heading is nearer the cone.
        let reach = |h: f64| h.clamp(self.headings[i] - theta, self.headings[i] + theta);
        let near = reach(phi - off + off.signum() * half);
        let far = reach(phi - off - off.signum() * half + off.signum() * std::f64::consts::TAU);
        let target = if self.cone_overshoot(i, far) < self.cone_overshoot(i, near) { far } else { near };
        Some(target).filter(|t| *t != phi)
    }

    /// One pull of [`Self::pull_into_cones`]: UAV `i` (outside its cone) moved the largest of the
    /// halvings of the way to its target that lowers `best`; `false` (and `x` unchanged) when none does.
    fn pull(&self, p: &mut Pulling<'_>, i: usize) -> bool {
        let from = p.x[i];
        let Some(target) = self.cone_target(i, from) else { return false };
        let mut t = 1.0;
        for _ in 0..=CONE_PULL_HALVINGS {
            p.x[i] = from + t * (target - from);
            let f = p.evaluate();
            if f < p.best {
                p.best = f;
                // As far as bisection finds between this fraction and the rejected one above it.
                let (mut ok, mut rejected) = (t, 2.0 * t);
                for _ in 0..if t < 1.0 { CONE_PULL_BISECTIONS } else { 0 } {
                    let mid = 0.5 * (ok + rejected);
                    p.x[i] = from + mid * (target - from);
                    let f = p.evaluate();
                    if f < p.best {
                        p.best = f;
                        ok = mid;
                    } else {
                        rejected = mid;
                    }
                }
                p.x[i] = from + ok * (target - from);
                return true;
            }
            t *= 0.5;
        }
        p.x[i] = from;
        false
    }

    /// A heading of UAV `i` (outside its cone) nearer its cone than its own, beyond whatever blocks the
    /// straight way there ([`Self::pull`] stops at the first limit): [`LEAP_SAMPLES`] + 1 headings evenly
    /// over its reach `ψ ± θ_max`, tried nearest the cone first, the first that makes `fitness`
    /// lexicographically smaller kept. The certified headings of one UAV, the others held, are a union
    /// of intervals (another UAV's arc or backup circle cuts the reach); the pull of the next round
    /// takes it further from there. `false` (and `x` unchanged) when no sample improves.
    fn leap(&self, p: &mut Pulling<'_>, i: usize) -> bool {
        // Inside as the cone tier counts it (an excess within its tolerance is none). (The pull's
        // target may be none outside too: the nearest edge the other way round, beyond the reach.)
        if self.uav_cone_excess(i, p.x[i]) == 0.0 {
            return false;
        }
        let theta = self.constraints.max_turn();
        let (from, now) = (p.x[i], self.cone_overshoot(i, p.x[i]));
        let mut samples: Vec<(f64, f64)> = (0..=LEAP_SAMPLES)
            .map(|s| self.headings[i] - theta + 2.0 * theta * s as f64 / LEAP_SAMPLES as f64)
            .map(|h| (self.cone_overshoot(i, h), h))
            .filter(|(e, _)| *e < now)
            .collect();
        samples.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (_, h) in samples {
            p.x[i] = h;
            let f = p.evaluate();
            if f < p.best {
                p.best = f;
                return true;
            }
        }
        p.x[i] = from;
        false
    }

    /// A pull of UAV `i` that [`Self::pull`] could not make because it would bring `i` too near another
    /// UAV (along the arcs or on the backup circles): UAV `i` and the UAVs in its way turned with it.
    /// The group starts as `i` alone and grows by the other UAV of the tightest pair limit when the
    /// group has turned the whole way, up to [`GROUP_PULL_OTHERS`] others. Each size tries every member
    /// turned by `i`'s angle (within its reach: their spacing changes little), the whole way and
    /// [`GROUP_PULL_HALVINGS`] halvings of it; then, the group the whole way, the newest member's own
    /// heading over its reach by [`GROUP_PULL_SECTIONS`] golden sections (the heading that makes room,
    /// often a narrow window between two pair limits). The smallest group whose tries make `fitness`
    /// lexicographically smaller moves, to its best try (the cone tier sums every UAV's excess, so a
    /// member pushed out of its own cone counts against the move). At most the pull's group budget of
    /// evaluations, which it lowers; `false` (and the plan unchanged) when no try improves.
    fn group_pull(&self, p: &mut Pulling<'_>, i: usize) -> bool {
        let Some(target) = self.cone_target(i, p.x[i]) else { return false };
        let from = p.x.clone();
        let (turn, theta) = (target - from[i], self.constraints.max_turn());
        let reach = |k: usize, h: f64| h.clamp(self.headings[k] - theta, self.headings[k] + theta);
        let mut group = vec![i];
        while group.len() <= 1 + GROUP_PULL_OTHERS {
            let mut blocker = None;
            // The best plan of this group size.
            let mut found = None::<(Vec<f64>, Fitness)>;
            let mut t = 1.0;
            for _ in 0..=GROUP_PULL_HALVINGS {
                if p.group_budget == 0 {
                    break;
                }
                for &k in &group {
                    p.x[k] = reach(k, from[k] + t * turn);
                }
                let f = p.evaluate_grouped();
                if f < found.as_ref().map_or(p.best, |b| b.1) {
                    found = Some((p.x.clone(), f));
                }
                if t == 1.0 {
                    blocker = self.blocker(&p.x, &group);
                }
                t *= 0.5;
            }
            if let Some(&j) = group.last().filter(|j| **j != i && p.group_budget >= 2) {
                for &k in &group {
                    p.x[k] = reach(k, from[k] + turn);
                }
                // Golden sections of j's reach, the best plan seen kept.
                let g = 0.5 * (5f64.sqrt() - 1.0);
                let (mut lo, mut hi) = (self.headings[j] - theta, self.headings[j] + theta);
                let probe = |h: f64, p: &mut Pulling<'_>| {
                    p.x[j] = h;
                    p.evaluate_grouped()
                };
                let (mut c, mut d) = (hi - g * (hi - lo), lo + g * (hi - lo));
                let (mut fc, mut fd) = (probe(c, p), probe(d, p));
                let mut section = None::<(f64, Fitness)>;
                for _ in 0..GROUP_PULL_SECTIONS {
                    for (h, f) in [(c, fc), (d, fd)] {
                        if f < section.map_or(p.best, |b| b.1) {
                            section = Some((h, f));
                        }
                    }
                    if p.group_budget == 0 {
                        break;
                    }
                    if fc < fd {
                        (hi, d, fd) = (d, c, fc);
                        c = hi - g * (hi - lo);
                        fc = probe(c, p);
                    } else {
                        (lo, c, fc) = (c, d, fd);
                        d = lo + g * (hi - lo);
                        fd = probe(d, p);
                    }
                }
                for (h, f) in [(c, fc), (d, fd)] {
                    if f < section.map_or(p.best, |b| b.1) {
                        section = Some((h, f));
                    }
                }
                if let Some((h, f)) = section
                    && f < found.as_ref().map_or(p.best, |b| b.1)
                {
                    p.x[j] = h;
                    found = Some((p.x.clone(), f));
                }
            }
            if let Some((plan, f)) = found {
                p.x = plan;
                p.best = f;
                return true;
            }
            p.x.copy_from_slice(&from);
            match blocker {
                Some(j) if p.group_budget > 0 => group.push(j),
                _ => break,
            }
        }
        p.x.copy_from_slice(&from);
        false
    }

    /// The UAV outside `group` of the tightest limit of `x` when that is a pair limit with one UAV in
    /// the group.
    fn blocker(&self, x: &[f64], group: &[usize]) -> Option<usize> {
        let lim = self.check(x).tightest?;
        let other = lim.other?;
        match (group.contains(&lim.uav), group.contains(&other)) {
            (true, false) => Some(other),
            (false, true) => Some(lim.uav),
            _ => None,
        }
    }

    /// The backup step from the current state: every UAV turns right by `θ_b` on its backup circle, or
    /// towards the exit heading of its fly-away from a moving emitter (`Certifier::backup_plan`).
    pub fn backup(&self) -> Vec<f64> {
        self.certifier.borrow().backup_plan()
    }

    /// The backup circles' step from the current state: every UAV turns right by `θ_b` (the spacing of
    /// the circles holds by induction, whatever the emitter does).
    pub fn circle_backup(&self) -> Vec<f64> {
        self.limits.backup_headings(self.headings)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::kinematics::bearing;
    use model::safety::SafetyMode;

    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self) -> f64 {
            self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// A scenario, the UAVs' positions and headings, the estimate and its covariance.
    type State = (Scenario, Vec<Vector2<f64>>, Vec<f64>, Vector2<f64>, Matrix2<f64>);

    /// The paper's nominal state (certified), the estimate at the emitter with σ = 50 m.
    fn nominal() -> State {
        let sc = Scenario { safety: SafetyMode::Certified, ..Scenario::default() };
        let (pos, psi, z) = (sc.uav_positions(), sc.initial_headings(), sc.emitter_position());
        (sc, pos, psi, z, Matrix2::identity() * 2500.0)
    }

    #[test]
    fn a_cone_nearly_behind_is_approached_the_way_the_reach_allows() {
        // Every UAV flies away from ẑ, its cone centred 170° to its left. From a full right turn the
        // cone's nearer edge is clockwise (195°), beyond the reach on that side: the nearest reachable
        // heading is the full left turn, which the pull takes whole.
        let (sc, pos, _, z, m) = nominal();
        let psi: Vec<f64> = pos.iter().map(|p| bearing(*p, z) - 170f64.to_radians()).collect();
        let constraints = Constraints::from_scenario(&sc).with_covariance(m).for_step(&pos, z);
        let shield = Shield::new(&pos, &psi, safety_limits(&sc), prediction(&sc, z, &m, None), &constraints, z);
        let mut fitness = |phi: &[f64]| shield.fitness(phi, || 0.0);
        let theta = constraints.max_turn();
        let right: Vec<f64> = psi.iter().map(|p| p - theta).collect();
        assert!(shield.check(&right).certified);
        let before = fitness(&right);
        let (plan, after, _) = shield.pull_into_cones(&right, before, &mut fitness);
        assert!(after < before, "{after:?} not below {before:?}");
        for (i, (a, p)) in plan.iter().zip(&psi).enumerate() {
            assert!((a - (p + theta)).abs() < 1e-12, "UAV {i} turned {:.2}°", (a - p).to_degrees());
        }
        assert!(shield.check(&plan).certified);
    }

    #[test]
    fn a_uav_blocked_on_the_way_to_its_cone_leaps_beyond_what_blocks_it() {
        // UAV 0's cone lies 60° to its right, beyond its reach; what it may fly is cut by a limit (here
        // a tier added to the certificate's first) into turns of [−22°, −15°] and of at least −0.5°.
        // Every halving of the straight pull lands in the cut (or within 0.5° of straight on): only a
        // look over the whole reach finds the interval beyond.
        let (sc, pos, mut psi, z, m) = nominal();
        psi[0] = bearing(pos[0], z) + 60f64.to_radians();
        let constraints = Constraints::from_scenario(&sc).with_covariance(m).for_step(&pos, z);
        let shield = Shield::new(&pos, &psi, safety_limits(&sc), prediction(&sc, z, &m, None), &constraints, z);
        let theta = constraints.max_turn();
        let psi0 = psi[0];
        let mut fitness = |phi: &[f64]| {
            let f = shield.fitness(phi, || 0.0);
            let turn = (phi[0] - psi0).to_degrees();
            let cut = if (-22.0..=-15.0).contains(&turn) || turn >= -0.5 { 0.0 } else { 1.0 };
            let mut tiers = f.tiers();
            tiers[0] += cut;
            Fitness::tiered(tiers, f.objective())
        };
        let plan = psi.clone();
        let before = fitness(&plan);
        let (after_plan, after, _) = shield.pull_into_cones(&plan, before, &mut fitness);
        let turn = (after_plan[0] - psi0).to_degrees();
        assert!(after < before, "{after:?} not below {before:?}");
        assert!((-22.0..=-15.0).contains(&turn), "UAV 0 turned {turn:.2}°");
        assert!(theta.to_degrees() > 22.0);
    }

    #[test]
    fn pulling_into_the_cones_never_ranks_a_plan_lower_and_keeps_its_certificate() {
        let (sc, pos, psi, z, m) = nominal();
        let constraints = Constraints::from_scenario(&sc).with_covariance(m).for_step(&pos, z);
        let shield = Shield::new(&pos, &psi, safety_limits(&sc), prediction(&sc, z, &m, None), &constraints, z);
        // A criterion that prefers turning left, away from the cone for some UAVs.
        let mut fitness = |phi: &[f64]| shield.fitness(phi, || phi.iter().map(|p| (p - 3.0).powi(2)).sum());
        let theta = constraints.max_turn();
        let mut r = Lcg(5);
        let (mut pulled, mut outside) = (0, 0);
        for case in 0..300 {
            let plan: Vec<f64> = psi.iter().map(|p| p + (2.0 * r.next() - 1.0) * theta).collect();
            let before = fitness(&plan);
            let (after_plan, after, evaluations) = shield.pull_into_cones(&plan, before, &mut fitness);
            assert!(after <= before, "case {case}: {after:?} above {before:?}");
            assert_eq!(after, fitness(&after_plan), "case {case}: the fitness returned is the plan's");
            let own =
                CONE_PULL_ROUNDS * plan.len() * (CONE_PULL_HALVINGS + 1 + CONE_PULL_BISECTIONS + LEAP_SAMPLES + 1);
            assert!(evaluations <= own + GROUP_PULL_BUDGET, "case {case}: {evaluations} evaluations");
            for (a, p) in after_plan.iter().zip(&psi) {
                assert!((a - p).abs() <= theta + 1e-12, "case {case}: {a} beyond the reach of {p}");
            }
            if shield.check(&plan).certified {
                assert!(shield.check(&after_plan).certified, "case {case}: a certified plan lost its certificate");
            }
            if after < before {
                pulled += 1;
                assert!(shield.cone_excess(&after_plan) < shield.cone_excess(&plan), "case {case}");
                assert_eq!(shield.cone_excess(&after_plan), 0.0, "case {case}: {after_plan:?}");
            }
            if shield.check(&plan).certified && shield.cone_excess(&plan) > 0.0 {
                outside += 1;
            }
        }
        // Far from the emitter every UAV can reach its cone and nothing else binds: every certified plan
        // outside the cones is pulled into them.
        assert_eq!(pulled, outside, "{pulled} of the {outside} certified plans outside their cones pulled");
        assert!(outside >= 50, "only {outside} of 300 random plans left their cones");
    }

    /// The nominal state with UAV 1 flying straight on, off its cone by 0.8 θ_max (the initial headings
    /// point at the emitter, the cones' centres), where a turn of θ_max would take it back in; and the
    /// step's constraints.
    fn uav_1_off_its_cone() -> (State, Constraints) {
        let (sc, pos, mut psi, z, m) = nominal();
        let constraints = Constraints::from_scenario(&sc).with_covariance(m).for_step(&pos, z);
        psi[1] += constraints.delta_alpha + 0.8 * constraints.max_turn();
        ((sc, pos, psi, z, m), constraints)
    }

    #[test]
    fn a_uav_freed_outside_a_reachable_cone_is_pulled_back_into_it() {
        let ((sc, pos, psi, z, m), constraints) = uav_1_off_its_cone();
        let shield = Shield::new(&pos, &psi, safety_limits(&sc), prediction(&sc, z, &m, None), &constraints, z);
        let mut fitness = |phi: &[f64]| shield.fitness(phi, || 0.0);
        let plan = psi.clone();
        assert!(shield.cone_excess(&plan) > 0.0, "UAV 1 was meant to leave its cone");
        let before = fitness(&plan);
        let (after_plan, after, _) = shield.pull_into_cones(&plan, before, &mut fitness);
        assert_eq!(shield.cone_excess(&after_plan), 0.0, "{after_plan:?}");
        assert!(after < before && shield.check(&after_plan).certified);
        assert_eq!((after_plan[0], after_plan[2]), (plan[0], plan[2]), "the UAVs in their cones stay");
    }

    #[test]
    fn certified_boxes_keep_each_uavs_own_limits_and_end_where_one_binds() {
        use crate::heading_interval::{CERTIFIED_RESOLUTION, Uav, heading_interval_of};
        let (sc, _, _, z, m) = nominal();
        let mut r = Lcg(11);
        let (mut ends, mut binding) = (0, 0);
        for case in 0..1000 {
            // Three UAVs near the standoff ring, at random bearings and headings.
            let pos: Vec<Vector2<f64>> = (0..3)
                .map(|_| {
                    let (a, d) = (std::f64::consts::TAU * r.next(), sc.l_min * (1.1 + 0.5 * r.next()));
                    z + Vector2::new(a.cos(), a.sin()) * d
                })
                .collect();
            let psi: Vec<f64> = (0..3).map(|_| std::f64::consts::TAU * (r.next() - 0.5)).collect();
            let constraints = Constraints::from_scenario(&sc).with_covariance(m).for_step(&pos, z);
            let shield = Shield::new(&pos, &psi, safety_limits(&sc), prediction(&sc, z, &m, None), &constraints, z);
            let theta = constraints.max_turn();
            for i in 0..3 {
                let uav = Uav { position: pos[i], heading: psi[i], speed: sc.speed, dt: sc.dt };
                let own = |phi: f64| shield.own_deficit(i, phi);
                let b = heading_interval_of(&constraints, &uav, z, &own, CERTIFIED_RESOLUTION);
                if b.lo == b.hi {
                    continue;
                }
                let alpha = shield.cone_centres[i];
                for (end, outward) in [(b.lo, -1.0), (b.hi, 1.0)] {
                    assert_eq!(own(end), 0.0, "case {case} UAV {i}: the box end {end} breaks the UAV's own limits");
                    let at_reach = (end - psi[i]).abs() >= theta - 1e-12;
                    let at_cone = b.in_cone && (wrap_angle(end - alpha).abs() - constraints.delta_alpha).abs() < 1e-9;
                    ends += 1;
                    if !at_reach && !at_cone {
                        // Neither the turn nor the cone ends the box here: one of the UAV's own limits does,
                        // found to the resolution's 3e-9 rad.
                        binding += 1;
                        assert!(own(end + outward * 1e-8) > 0.0, "case {case} UAV {i}: the box could go on past {end}");
                    }
                }
            }
        }
        assert!(ends >= 300 && binding >= 100, "{binding} of {ends} box ends set by a limit");
    }

    #[test]
    fn a_pull_blocked_part_of_the_way_goes_as_far_as_bisection_finds() {
        let ((sc, pos, psi, z, m), constraints) = uav_1_off_its_cone();
        let shield = Shield::new(&pos, &psi, safety_limits(&sc), prediction(&sc, z, &m, None), &constraints, z);
        let plan = psi.clone();
        let mut free = |phi: &[f64]| shield.fitness(phi, || 0.0);
        let edge = shield.pull_into_cones(&plan, free(&plan), &mut free).0[1];
        // A limit 70 % of the way to the cone's edge: halvings alone stop at half the way.
        let fraction = |phi: f64| (phi - plan[1]) / (edge - plan[1]);
        let mut blocked = |phi: &[f64]| {
            if fraction(phi[1]) > 0.7 {
                Fitness::tiered([1.0, 0.0, 0.0, 0.0, 0.0, 0.0], 0.0)
            } else {
                shield.fitness(phi, || 0.0)
            }
        };
        let (after, _, evaluations) = shield.pull_into_cones(&plan, blocked(&plan), &mut blocked);
        let got = fraction(after[1]);
        assert!((0.65..=0.7).contains(&got), "pulled {got} of the way");
        let own = CONE_PULL_ROUNDS * (CONE_PULL_HALVINGS + 1 + CONE_PULL_BISECTIONS);
        assert!(evaluations <= own + GROUP_PULL_BUDGET, "{evaluations}");
    }
}
