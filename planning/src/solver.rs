//! The one solver trait behind PSO, GA and ACO: minimise a [`Fitness`] over a box of headings.
//!
//! A solver sees only plain numbers: a vector `x` with `lo_i ≤ x_i ≤ hi_i` ([`SearchSpace`]) and a
//! fitness function. The planner passes each UAV's heading cone `α_i ± Δα` *unwrapped* around `α_i`
//! (so an interval may extend past ±π); the solvers never wrap, which keeps every proposal inside its
//! interval, and the planner wraps the result. Every solver is deterministic for a given seed
//! (a `ChaCha8Rng` seeded with it) and evaluates sequentially.

use std::fmt;
use std::str::FromStr;

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use thiserror::Error;

use crate::fitness::Fitness;

/// Why a search space was refused.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SearchSpaceError {
    /// `lo`, `hi` and the start do not have one value per dimension, or there are none.
    #[error("search space: {what} has {got} values, expected {expected} (one per dimension, at least 1)")]
    Length { what: &'static str, expected: usize, got: usize },
    /// A bound or a start value is NaN or infinite.
    #[error("search space: {what}[{index}] is not finite ({value})")]
    NotFinite { what: &'static str, index: usize, value: f64 },
    /// `lo_i > hi_i`.
    #[error("search space: dimension {index} has lo {lo} > hi {hi}")]
    Inverted { index: usize, lo: f64, hi: f64 },
}

/// A box `[lo_i, hi_i]` and a starting point inside it (clamped into it on construction).
#[derive(Debug, Clone, PartialEq)]
pub struct SearchSpace {
    lo: Vec<f64>,
    hi: Vec<f64>,
    start: Vec<f64>,
}

impl SearchSpace {
    /// Validates finite bounds with `lo_i ≤ hi_i` and a finite start of the same length; the start is
    /// clamped into the box.
    pub fn new(lo: Vec<f64>, hi: Vec<f64>, start: Vec<f64>) -> Result<Self, SearchSpaceError> {
        let n = lo.len();
        if n == 0 {
            return Err(SearchSpaceError::Length { what: "lo", expected: 1, got: 0 });
        }
        for (what, v) in [("hi", &hi), ("start", &start)] {
            if v.len() != n {
                return Err(SearchSpaceError::Length { what, expected: n, got: v.len() });
            }
        }
        for (what, v) in [("lo", &lo), ("hi", &hi), ("start", &start)] {
            if let Some((index, &value)) = v.iter().enumerate().find(|(_, x)| !x.is_finite()) {
                return Err(SearchSpaceError::NotFinite { what, index, value });
            }
        }
        if let Some(index) = (0..n).find(|&i| lo[i] > hi[i]) {
            return Err(SearchSpaceError::Inverted { index, lo: lo[index], hi: hi[index] });
        }
        let start = (0..n).map(|i| start[i].clamp(lo[i], hi[i])).collect();
        Ok(Self { lo, hi, start })
    }

    /// Number of dimensions.
    pub fn dim(&self) -> usize {
        self.lo.len()
    }

    /// Lower bounds.
    pub fn lo(&self) -> &[f64] {
        &self.lo
    }

    /// Upper bounds.
    pub fn hi(&self) -> &[f64] {
        &self.hi
    }

    /// The starting point (inside the box).
    pub fn start(&self) -> &[f64] {
        &self.start
    }

    /// `hi_i − lo_i`.
    pub fn width(&self, i: usize) -> f64 {
        self.hi[i] - self.lo[i]
    }

    /// `x` clamped into `[lo_i, hi_i]`.
    pub fn clamp(&self, i: usize, x: f64) -> f64 {
        x.clamp(self.lo[i], self.hi[i])
    }

    /// The initial population of [`initial_population`](Self::initial_population) (the same points from
    /// the same draws) in one flat array, point j at `[j·dim, (j+1)·dim)`: one allocation for the swarm.
    pub fn initial_population_flat(&self, size: usize, rng: &mut ChaCha8Rng) -> Vec<f64> {
        let n = self.dim();
        let mut flat = Vec::with_capacity(size * n);
        if size > 0 {
            flat.extend_from_slice(&self.start);
        }
        for _ in 1..size {
            flat.extend((0..n).map(|i| self.lo[i] + rng.random::<f64>() * self.width(i)));
        }
        flat
    }

    /// The initial population shared by every solver: the start point, then `size − 1` uniform draws.
    pub fn initial_population(&self, size: usize, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
        self.initial_population_flat(size, rng).chunks_exact(self.dim()).map(<[f64]>::to_vec).collect()
    }
}

/// What a solver returns.
#[derive(Debug, Clone, PartialEq)]
pub struct SolverResult {
    /// The best point found (inside the box).
    pub best: Vec<f64>,
    /// Its fitness.
    pub fitness: Fitness,
    /// Iterations (PSO), generations (GA) or ant iterations (ACO) run after the initial population.
    pub iterations: usize,
    /// Fitness evaluations spent, the initial population included.
    pub evaluations: usize,
}

pub use model::solver_config::EarlyStop;

/// The stopping rule applied to fitness values (the rule's settings are plain data in `model`).
pub trait StopRule {
    /// Whether going from `old` to `new` best is a significant improvement.
    fn significant(&self, old: Fitness, new: Fitness) -> bool;
    /// A fresh tracker starting from the best fitness of the initial population.
    fn tracker(&self, initial_best: Fitness) -> StallTracker;
}

impl StopRule for EarlyStop {
    fn significant(&self, old: Fitness, new: Fitness) -> bool {
        if new >= old {
            return false;
        }
        if !old.is_feasible() {
            // The first tier that changed decides (with one tier: the total violation).
            let (a, b) = old.tiers().into_iter().zip(new.tiers()).find(|(a, b)| a != b).unwrap_or((0.0, 0.0));
            return b == 0.0 && a > 0.0 || a - b > self.tolerance * a;
        }
        if !old.objective().is_finite() {
            return new.objective().is_finite();
        }
        old.objective() - new.objective() > self.tolerance * old.objective().abs()
    }

    fn tracker(&self, initial_best: Fitness) -> StallTracker {
        StallTracker { rule: *self, best: initial_best, stalled: 0 }
    }
}

/// Counts consecutive insignificant iterations under an [`EarlyStop`] rule.
#[derive(Debug, Clone, Copy)]
pub struct StallTracker {
    rule: EarlyStop,
    best: Fitness,
    stalled: usize,
}

impl StallTracker {
    /// Records the best fitness after one iteration; true when the search should stop.
    pub fn observe(&mut self, best: Fitness) -> bool {
        if self.rule.significant(self.best, best) {
            self.stalled = 0;
        } else {
            self.stalled += 1;
        }
        self.best = self.best.min(best);
        self.rule.window > 0 && self.stalled >= self.rule.window
    }
}

/// Wraps the fitness function and counts evaluations.
pub(crate) struct Counted<'a> {
    f: &'a mut dyn FnMut(&[f64]) -> Fitness,
    pub(crate) count: usize,
}

impl<'a> Counted<'a> {
    pub(crate) fn new(f: &'a mut dyn FnMut(&[f64]) -> Fitness) -> Self {
        Self { f, count: 0 }
    }

    pub(crate) fn eval(&mut self, x: &[f64]) -> Fitness {
        self.count += 1;
        (self.f)(x)
    }
}

/// Index of the smallest fitness (the first one on ties).
pub(crate) fn argmin(fit: &[Fitness]) -> usize {
    let mut best = 0;
    for (i, f) in fit.iter().enumerate() {
        if *f < fit[best] {
            best = i;
        }
    }
    best
}

/// A bounded minimiser of a [`Fitness`].
pub trait Solver: Send + Sync {
    /// Which solver this is.
    fn kind(&self) -> SolverKind;

    /// Minimises `f` over `space`, starting from `space.start()`, with a `ChaCha8Rng` seeded by `seed`.
    /// Every point passed to `f` and the returned best lie inside the box.
    fn minimize(&self, f: &mut dyn FnMut(&[f64]) -> Fitness, space: &SearchSpace, seed: u64) -> SolverResult;
}

/// The solver names accepted on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SolverKind {
    /// Particle swarm (paper Section 4.3).
    Pso,
    /// Genetic algorithm (paper Section 5.4).
    Ga,
    /// Ant colony optimisation for continuous domains, ACO_R (paper Section 5.4).
    Aco,
    /// Multi-start projected quasi-Newton descent (ours; [`crate::gradient`]).
    Gradient,
}

impl SolverKind {
    /// All solvers.
    pub const ALL: [SolverKind; 4] = [SolverKind::Pso, SolverKind::Ga, SolverKind::Aco, SolverKind::Gradient];
    /// The paper's solvers (what `uavloc paper` compares).
    pub const PAPER: [SolverKind; 3] = [SolverKind::Pso, SolverKind::Ga, SolverKind::Aco];

    /// The lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            SolverKind::Pso => "pso",
            SolverKind::Ga => "ga",
            SolverKind::Aco => "aco",
            SolverKind::Gradient => "gradient",
        }
    }
}

impl fmt::Display for SolverKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for SolverKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        SolverKind::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| format!("unknown solver '{s}' (expected one of: pso, ga, aco, gradient)"))
    }
}

#[cfg(test)]
pub(crate) mod tests {
    //! The tests every solver must pass, run by each solver's own test module.

    use super::*;
    use std::f64::consts::PI;

    /// Shifted quadratic in 3 dimensions, minimum 0 at `C` inside `[-1, 1]³`.
    pub(crate) const C: [f64; 3] = [0.3, -0.5, 0.7];

    pub(crate) fn quadratic(x: &[f64]) -> Fitness {
        Fitness::feasible(x.iter().zip(C).map(|(a, c)| (a - c) * (a - c)).sum())
    }

    pub(crate) fn cube() -> SearchSpace {
        SearchSpace::new(vec![-1.0; 3], vec![1.0; 3], vec![-0.9, 0.9, -0.9]).unwrap()
    }

    pub(crate) fn finds_quadratic_minimum(solver: &dyn Solver, tol: f64) {
        let r = solver.minimize(&mut quadratic, &cube(), 7);
        let err = r.best.iter().zip(C).map(|(a, c)| (a - c).abs()).fold(0.0, f64::max);
        assert!(err < tol, "{}: best {:?} err {err} after {} evals", solver.kind(), r.best, r.evaluations);
        assert_eq!(r.fitness, quadratic(&r.best));
        assert!(r.iterations >= 1 && r.evaluations > r.iterations);
    }

    /// Minimum on a bound (outside the box along x): the solver must converge onto the bound, not past it.
    pub(crate) fn respects_bounds_straddling_pi(solver: &dyn Solver, tol: f64) {
        // Three heading cones of ±25° around α ≈ π (unwrapped: they extend past π).
        let centres = [PI, PI - 0.01, -PI + 0.02 + 2.0 * PI];
        let da = 25f64.to_radians();
        let lo: Vec<f64> = centres.iter().map(|c| c - da).collect();
        let hi: Vec<f64> = centres.iter().map(|c| c + da).collect();
        let space = SearchSpace::new(lo.clone(), hi.clone(), centres.to_vec()).unwrap();
        let mut outside = 0usize;
        // Pulls every coordinate far beyond its upper bound.
        let mut f = |x: &[f64]| {
            for (i, v) in x.iter().enumerate() {
                if *v < lo[i] || *v > hi[i] {
                    outside += 1;
                }
            }
            Fitness::feasible(x.iter().map(|v| (v - 10.0).powi(2)).sum())
        };
        let r = solver.minimize(&mut f, &space, 3);
        assert_eq!(outside, 0, "{} proposed headings outside the cone", solver.kind());
        for i in 0..3 {
            assert!(r.best[i] >= lo[i] && r.best[i] <= hi[i]);
            assert!((r.best[i] - hi[i]).abs() < tol, "{}: {:?} vs {:?}", solver.kind(), r.best, hi);
        }
    }

    fn trace(solver: &dyn Solver, seed: u64) -> (Vec<Vec<f64>>, SolverResult) {
        let mut seen = Vec::new();
        let mut f = |x: &[f64]| {
            seen.push(x.to_vec());
            quadratic(x)
        };
        let r = solver.minimize(&mut f, &cube(), seed);
        (seen, r)
    }

    pub(crate) fn deterministic_per_seed(solver: &dyn Solver) {
        let (a, ra) = trace(solver, 11);
        let (b, rb) = trace(solver, 11);
        assert_eq!(a, b);
        assert_eq!(ra, rb);
        let (c, _) = trace(solver, 12);
        assert_ne!(a, c, "{}: different seeds gave the same evaluations", solver.kind());
        assert_eq!(ra.evaluations, a.len());
    }

    pub(crate) fn prefers_feasible(solver: &dyn Solver) {
        // Feasible only for x0 ≥ 0.5; the objective alone would pull x0 to −1.
        let mut f = |x: &[f64]| Fitness::new((0.5 - x[0]).max(0.0), x[0] + x[1].abs() + x[2].abs());
        let r = solver.minimize(&mut f, &cube(), 5);
        assert!(r.fitness.is_feasible(), "{}: {:?}", solver.kind(), r);
        assert!((r.best[0] - 0.5).abs() < 0.05, "{}: {:?}", solver.kind(), r.best);
    }

    #[test]
    fn search_space_validates() {
        assert!(SearchSpace::new(vec![], vec![], vec![]).is_err());
        assert!(matches!(
            SearchSpace::new(vec![0.0], vec![1.0, 2.0], vec![0.0]),
            Err(SearchSpaceError::Length { what: "hi", .. })
        ));
        assert!(matches!(
            SearchSpace::new(vec![0.0], vec![f64::NAN], vec![0.0]),
            Err(SearchSpaceError::NotFinite { what: "hi", .. })
        ));
        assert!(matches!(SearchSpace::new(vec![2.0], vec![1.0], vec![1.5]), Err(SearchSpaceError::Inverted { .. })));
        let s = SearchSpace::new(vec![0.0, 0.0], vec![1.0, 1.0], vec![5.0, -1.0]).unwrap();
        assert_eq!(s.start(), &[1.0, 0.0]);
    }

    #[test]
    fn early_stop_counts_insignificant_iterations() {
        let rule = EarlyStop { window: 3, tolerance: 1e-3 };
        let mut t = rule.tracker(Fitness::feasible(100.0));
        assert!(!t.observe(Fitness::feasible(50.0)));
        assert!(!t.observe(Fitness::feasible(49.99)));
        assert!(!t.observe(Fitness::feasible(49.99)));
        assert!(!t.observe(Fitness::feasible(40.0)));
        assert!(!t.observe(Fitness::feasible(40.0)));
        assert!(!t.observe(Fitness::feasible(40.0)));
        assert!(t.observe(Fitness::feasible(40.0)));
        assert!(rule.significant(Fitness::new(1.0, 1.0), Fitness::feasible(1e9)));
        assert!(rule.significant(Fitness::feasible(f64::INFINITY), Fitness::feasible(1e9)));
        assert!(!rule.significant(Fitness::feasible(1.0), Fitness::feasible(2.0)));
    }

    #[test]
    fn names_round_trip() {
        for k in SolverKind::ALL {
            assert_eq!(k.name().parse::<SolverKind>().unwrap(), k);
        }
        assert!("sa".parse::<SolverKind>().is_err());
    }
}
