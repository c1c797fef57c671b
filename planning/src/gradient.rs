//! A deterministic gradient solver for the planner's small box-constrained problem (one heading per
//! UAV): multi-start projected quasi-Newton descent on the lexicographic [`Fitness`], with the
//! constraints that are not box bounds handled by an active set, and a compass-search polish.
//!
//! The planner (`--solver gradient`, [`crate::step`]) first settles each UAV's own constraints exactly
//! ([`crate::heading_interval`]) and hands this solver the product of the UAVs' heading boxes, where only
//! the criterion and the spacing are left; as a [`Solver`] it also takes any box and fitness, as PSO,
//! GA and ACO do.
//!
//! **Merit and gradient.** At a point `x` the search descends one scalar of the fitness: the first
//! non-zero violation tier that a free coordinate can still lower (a tier at its least within the box
//! gives way to the next, which is then descended with the earlier ones as constraints), else the
//! criterion (m²). Gradients are forward differences with step [`FD_STEP`] (backwards at an upper bound):
//! `n` evaluations (fewer with coordinates held at a bound, see below) give the differences of every tier
//! and the criterion at once. (The criterion's
//! analytic gradient through the arc kinematics is not used: every evaluation goes through the fitness.)
//!
//! **Starts.** Given by the caller ([`Gradient::minimize_from`]); as a [`Solver`]: the box's start, its
//! centre and, up to [`MAX_CORNER_DIM`] dimensions, its corners. All are evaluated; the local search
//! runs from the best [`GradientConfig::starts`] of them.
//!
//! **Local search (per start).** BFGS on the free coordinates (those not held at a bound by the
//! gradient): direction `d = −H g`, the trial point `clamp(x + t d)` with `t = 1, ¼, ¼², …` (at most
//! [`MAX_BACKTRACKS`] times), accepted when its fitness is lexicographically smaller. When a trial
//! breaks a constraint of a higher priority than the merit, its gradient at the nearest such trial point
//! is the normal `a` of the constraint met: it joins the active set, and the next directions are
//! projected onto the tangent of the active normals (`d ← d − Σ (d·â) â`, Gram–Schmidt), so the search
//! slides along the constraint instead of zig-zagging into it; the set is cleared when a projected
//! direction finds nothing. `H` is reset to the scaled identity whenever the free set or the merit
//! changes, or a step shows no curvature. The search stops when no backtracked step improves, the step is
//! below `tolerance` rad, [`MAX_STALLED`] iterations in a row met a constraint without a step, or after
//! `iterations` iterations.
//!
//! **Coordinates held at a bound** (a heading at the edge of its box that the gradient pushes outwards)
//! are not probed again while the merit stays the same: a UAV pinned to its box edge costs no
//! evaluation per iteration. Where the search would stop, or its merit changes, one full probe checks
//! them first; a coordinate the gradient now pulls inwards is free again and the search goes on.
//!
//! **Polish.** The best point of all local searches then gets a compass search along the coordinates
//! (doubling steps along a coordinate that improves, a quarter of the step after a pass that did not,
//! down to `tolerance`, at most [`POLISH_EVALUATIONS`] evaluations): the kinks where a constraint meets
//! a bound, which quasi-Newton steps cannot resolve.
//!
//! **Handing over** ([`Handoff`], off by default). A caller with a later stage of its own can cut the
//! search short: a local search stops at a point whose first non-zero tier is the one the caller lowers
//! itself (the certified planner pulls the heading cone, a sum of per-UAV excesses, UAV by UAV:
//! quasi-Newton steps on that piecewise-linear tier stall against the certificate at every step length);
//! the local searches after one that reached a point with every tier 0 are skipped; and a local search
//! descending a violation tier stops on a plateau above 0 (less than a given fraction lowered over
//! [`PLATEAU_ITERATIONS`] iterations: a conflict the caller's other starts resolve).
//!
//! Deterministic: the seed is not used; the same inputs give the same evaluations.

use crate::fitness::Fitness;
use crate::solver::{Counted, SearchSpace, Solver, SolverKind, SolverResult};

pub use model::solver_config::GradientConfig;

/// Corners of the box are starts up to this many dimensions (2ⁿ of them).
pub const MAX_CORNER_DIM: usize = 4;
/// Halvings (by 4) of a trial step before the search gives up at a point.
pub const MAX_BACKTRACKS: usize = 12;
/// Most evaluations of the compass search that ends each local search.
pub const POLISH_EVALUATIONS: usize = 60;
/// Forward-difference step of the gradient, radians.
pub const FD_STEP: f64 = 1e-7;
/// Iterations in a row without an accepted step (a constraint met again and again) after which a
/// local search stops: enough for the active set to gather a few normals, not for cycling between them.
pub const MAX_STALLED: usize = 4;

/// Iterations over which [`Handoff::plateau`] measures a violation tier's progress.
pub const PLATEAU_ITERATIONS: usize = 5;

/// The gradient solver.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Gradient {
    /// Starts, iterations and tolerance.
    pub config: GradientConfig,
    /// Where a local search hands over to its caller (none by default).
    pub handoff: Handoff,
}

/// Where the local searches of a [`Gradient`] stop early because the caller takes over (see the
/// module docs); the default runs every search to its own end.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Handoff {
    /// A local search stops at a point whose first non-zero violation tier has this index or a larger
    /// one (every earlier tier 0): lowering that tier is the caller's. The polish still runs.
    pub from_tier: Option<usize>,
    /// The local searches after one that ends at a point with every tier 0 are not run.
    pub first_feasible: bool,
    /// A local search descending a violation tier stops when the last [`PLATEAU_ITERATIONS`]
    /// iterations lowered it by less than this fraction of its value (a plateau above 0).
    pub plateau: Option<f64>,
}

impl Gradient {
    /// The solver with `config`, running every search to its own end.
    pub fn new(config: GradientConfig) -> Self {
        Self { config, handoff: Handoff::default() }
    }

    /// The same solver with `handoff`.
    pub fn with_handoff(self, handoff: Handoff) -> Self {
        Self { handoff, ..self }
    }
}

/// Which scalar of the fitness the search descends; ordered by priority (a tier before the later
/// tiers, every tier before the criterion).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Merit {
    /// The violation tier with this index (the first non-zero one).
    Tier(usize),
    /// The criterion (every tier is 0).
    Objective,
}

impl Merit {
    fn of(f: &Fitness) -> Self {
        f.tiers().iter().position(|v| *v > 0.0).map_or(Merit::Objective, Merit::Tier)
    }

    fn value(self, f: &Fitness) -> f64 {
        match self {
            Merit::Tier(t) => f.tiers()[t],
            Merit::Objective => f.objective(),
        }
    }
}

/// A point with its fitness.
#[derive(Debug, Clone)]
struct Point {
    x: Vec<f64>,
    f: Fitness,
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The box corner with index `bits` (bit i set: coordinate i at its upper bound).
fn corner(space: &SearchSpace, bits: usize) -> Vec<f64> {
    (0..space.dim()).map(|i| if bits >> i & 1 == 1 { space.hi()[i] } else { space.lo()[i] }).collect()
}

/// The forward differences at `p` (one evaluation per coordinate, backwards where the forward step
/// leaves the box): the fitness at each perturbed point, from which the gradient of any merit follows.
struct Probe {
    steps: Vec<f64>,
    fitness: Vec<Fitness>,
}

impl Probe {
    /// The differences at `p` along every coordinate but those `skip` marks (their gradient reads 0).
    fn at(f: &mut Counted<'_>, space: &SearchSpace, p: &Point, skip: &[bool]) -> Self {
        let mut x = p.x.clone();
        let mut steps = Vec::with_capacity(x.len());
        let mut fitness = Vec::with_capacity(x.len());
        for i in 0..x.len() {
            if skip[i] {
                steps.push(0.0);
                fitness.push(p.f);
                continue;
            }
            let h = if p.x[i] + FD_STEP <= space.hi()[i] { FD_STEP } else { -FD_STEP };
            x[i] = p.x[i] + h;
            fitness.push(f.eval(&x));
            x[i] = p.x[i];
            steps.push(h);
        }
        Self { steps, fitness }
    }

    /// The gradient of `merit` at `p` (0 along a skipped coordinate); `None` where it or a difference
    /// is not finite.
    fn gradient(&self, p: &Point, merit: Merit) -> Option<Vec<f64>> {
        let m0 = merit.value(&p.f);
        if !m0.is_finite() {
            return None;
        }
        self.steps
            .iter()
            .zip(&self.fitness)
            .map(
                |(h, fi)| {
                    if *h == 0.0 { Some(0.0) } else { Some((merit.value(fi) - m0) / h).filter(|g| g.is_finite()) }
                },
            )
            .collect()
    }

    /// Whether coordinate `i` was probed.
    fn probed(&self, i: usize) -> bool {
        self.steps[i] != 0.0
    }
}

/// The gradient of the first merit at `p` (from [`Merit::of`] on, through the later non-zero tiers to
/// the criterion) with a free descent direction, the merit and the free set: a tier at its least within
/// the box (every coordinate that moves it held at a bound) gives way to the next, which is then
/// descended with the earlier ones as constraints.
fn descent(probe: &Probe, space: &SearchSpace, p: &Point) -> Option<(Merit, Vec<f64>, Vec<bool>)> {
    let n = p.x.len();
    let first = Merit::of(&p.f);
    let merits = (0..crate::fitness::TIERS).map(Merit::Tier).chain([Merit::Objective]);
    for merit in merits.filter(|m| *m >= first && (*m == Merit::Objective || m.value(&p.f) > 0.0)) {
        let Some(g) = probe.gradient(p, merit) else { continue };
        let free: Vec<bool> = (0..n)
            .map(|i| {
                probe.probed(i) && !((p.x[i] <= space.lo()[i] && g[i] > 0.0) || (p.x[i] >= space.hi()[i] && g[i] < 0.0))
            })
            .collect();
        let gf: Vec<f64> = (0..n).map(|i| if free[i] { g[i] } else { 0.0 }).collect();
        if gf.iter().any(|v| *v != 0.0) {
            return Some((merit, gf, free));
        }
    }
    None
}

/// `d` with its components along the orthonormal `normals` removed.
fn project(d: &mut [f64], normals: &[Vec<f64>]) {
    for a in normals {
        let c = dot(d, a);
        for (di, ai) in d.iter_mut().zip(a) {
            *di -= c * ai;
        }
    }
}

/// Adds `a` to the orthonormal set `normals` (Gram–Schmidt); `false` when it is (nearly) in their span.
fn add_normal(normals: &mut Vec<Vec<f64>>, mut a: Vec<f64>) -> bool {
    project(&mut a, normals);
    let norm = dot(&a, &a).sqrt();
    if norm.is_nan() || norm <= 1e-12 {
        return false;
    }
    a.iter_mut().for_each(|v| *v /= norm);
    normals.push(a);
    true
}

/// The BFGS inverse-Hessian approximation, `n × n` row-major.
struct InverseHessian {
    n: usize,
    h: Vec<f64>,
}

impl InverseHessian {
    fn scaled_identity(n: usize, scale: f64) -> Self {
        let mut h = vec![0.0; n * n];
        for i in 0..n {
            h[i * n + i] = scale;
        }
        Self { n, h }
    }

    fn times(&self, g: &[f64]) -> Vec<f64> {
        (0..self.n).map(|i| dot(&self.h[i * self.n..(i + 1) * self.n], g)).collect()
    }

    /// The BFGS update for step `s` and gradient change `y`; skipped (`false`) unless `sᵀy > 0`.
    fn update(&mut self, s: &[f64], y: &[f64]) -> bool {
        let sy = dot(s, y);
        let floor = 1e-12 * dot(s, s).sqrt() * dot(y, y).sqrt();
        if sy.is_nan() || sy <= floor || sy <= 0.0 {
            return false;
        }
        let n = self.n;
        let hy = self.times(y);
        let yhy = dot(y, &hy);
        let rho = 1.0 / sy;
        // H ← H − ρ(H y sᵀ + s yᵀ H) + (ρ² yᵀHy + ρ) s sᵀ
        for i in 0..n {
            for j in 0..n {
                self.h[i * n + j] += -rho * (hy[i] * s[j] + s[i] * hy[j]) + (rho * rho * yhy + rho) * s[i] * s[j];
            }
        }
        true
    }
}

impl Gradient {
    /// The local search from `start` (see the module docs): the point reached, the iterations run and
    /// the length of the last steps (radians).
    fn descend(&self, f: &mut Counted<'_>, space: &SearchSpace, start: Point) -> (Point, usize, f64) {
        let n = space.dim();
        let mut p = start;
        let mut normals: Vec<Vec<f64>> = Vec::new();
        let mut h = InverseHessian::scaled_identity(n, 0.0);
        // The merit, free set and (free) gradient of the last iteration, and the step accepted since.
        let mut prev: Option<(Merit, Vec<bool>, Vec<f64>)> = None;
        let mut step: Option<Vec<f64>> = None;
        let mut scale = 0.05f64;
        let mut iterations = 0;
        let mut stalled = 0;
        // Coordinates a full probe found held at a bound: not probed again until the search would stop
        // (or its merit changes), when a full probe checks that they still are.
        let mut pinned = vec![false; n];
        // The merit and its value at each iteration's probe (for the plateau rule of the handoff).
        let mut history: Vec<(Merit, f64)> = Vec::new();
        // Where the search would stop: after a partial probe, one more iteration with a full one.
        macro_rules! converged {
            ($partial:expr) => {{
                if $partial {
                    pinned.fill(false);
                    continue;
                }
                break;
            }};
        }
        while iterations < self.config.iterations {
            iterations += 1;
            // Coordinates held at a bound by the gradient are fixed this iteration.
            let partial = pinned.iter().any(|b| *b);
            let probe = Probe::at(f, space, &p, &pinned);
            let Some((merit, gf, free)) = descent(&probe, space, &p) else { converged!(partial) };
            if self.hands_over(merit, &p.f, &mut history) {
                break;
            }
            if partial && prev.as_ref().is_none_or(|(m, _, _)| *m != merit) {
                // The merit changed: which coordinates its gradient holds at a bound is not known.
                pinned.fill(false);
                continue;
            }
            for i in 0..n {
                pinned[i] = !free[i];
            }
            let gnorm = gf.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            match (&prev, step.take()) {
                (Some((m, fr, g0)), Some(s)) if *m == merit && *fr == free => {
                    let y: Vec<f64> = (0..n).map(|i| gf[i] - g0[i]).collect();
                    let s: Vec<f64> = (0..n).map(|i| if free[i] { s[i] } else { 0.0 }).collect();
                    if !h.update(&s, &y) {
                        // No curvature seen (a linear stretch): the step length follows the last step.
                        h = InverseHessian::scaled_identity(n, scale / gnorm);
                    }
                }
                (Some((m, fr, _)), None) if *m == merit && *fr == free => {}
                (prev, _) => {
                    if prev.as_ref().is_none_or(|(m, _, _)| *m != merit) {
                        normals.clear();
                    }
                    h = InverseHessian::scaled_identity(n, scale / gnorm);
                }
            }
            prev = Some((merit, free.clone(), gf.clone()));
            let mut d: Vec<f64> = h.times(&gf).iter().zip(&free).map(|(v, fr)| if *fr { -v } else { 0.0 }).collect();
            project(&mut d, &normals);
            let slope = dot(&d, &gf);
            if slope.is_nan() || slope >= 0.0 {
                // No descent left along the active constraints (or BFGS lost it): steepest descent afresh.
                normals.clear();
                h = InverseHessian::scaled_identity(n, scale / gnorm);
                d = gf.iter().map(|v| -v * scale / gnorm).collect();
            }
            match self.line_search(f, space, &p, &d, merit) {
                Search::Better(q, met) => {
                    stalled = 0;
                    // Cut short by a constraint: slide along it from now on.
                    if let Some(trial) = met
                        && let Some(a) = Probe::at(f, space, &trial, &pinned).gradient(&trial, Merit::of(&trial.f))
                    {
                        update_normals(&mut normals, a, n);
                    }
                    let s: Vec<f64> = (0..n).map(|i| q.x[i] - p.x[i]).collect();
                    let moved = s.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                    scale = (2.0 * moved).clamp(1e-6, 0.5);
                    p = q;
                    step = Some(s);
                    if moved < self.config.tolerance {
                        converged!(partial);
                    }
                }
                Search::Blocked(trial) => {
                    stalled += 1;
                    if stalled > MAX_STALLED {
                        converged!(partial);
                    }
                    // A constraint of a higher priority was met: its normal joins (or refreshes) the active set.
                    let Some(a) = Probe::at(f, space, &trial, &pinned).gradient(&trial, Merit::of(&trial.f)) else {
                        converged!(partial)
                    };
                    if !update_normals(&mut normals, a, n) {
                        converged!(partial);
                    }
                }
                Search::Stuck if normals.is_empty() => converged!(partial),
                Search::Stuck => {
                    // Blocked along the active constraints: once more without them, as long as the
                    // search has not stalled too often.
                    stalled += 1;
                    if stalled > MAX_STALLED {
                        converged!(partial);
                    }
                    normals.clear();
                }
            }
        }
        (p, iterations, scale)
    }

    /// Whether the local search stops at a point of fitness `f` whose merit is `merit` for the caller
    /// to take over ([`Handoff`]); `history` gathers the merits seen.
    fn hands_over(&self, merit: Merit, f: &Fitness, history: &mut Vec<(Merit, f64)>) -> bool {
        let handoff = &self.handoff;
        if handoff.from_tier.is_some_and(|t| merit >= Merit::Tier(t)) {
            return true;
        }
        let (Some(fraction), Merit::Tier(_)) = (handoff.plateau, merit) else { return false };
        let value = merit.value(f);
        history.push((merit, value));
        let k = history.len();
        k > PLATEAU_ITERATIONS && {
            let (m0, v0) = history[k - 1 - PLATEAU_ITERATIONS];
            m0 == merit && value > (1.0 - fraction) * v0
        }
    }

    /// Backtracks along `d` from `p`; see [`Search`].
    fn line_search(&self, f: &mut Counted<'_>, space: &SearchSpace, p: &Point, d: &[f64], merit: Merit) -> Search {
        let mut t = 1.0;
        let mut first_infeasible: Option<Point> = None;
        for _ in 0..=MAX_BACKTRACKS {
            let x: Vec<f64> = (0..p.x.len()).map(|i| space.clamp(i, p.x[i] + t * d[i])).collect();
            if x == p.x {
                break;
            }
            let q = Point { f: f.eval(&x), x };
            if q.f < p.f {
                return Search::Better(q, first_infeasible);
            }
            if Merit::of(&q.f) < merit && Merit::of(&q.f) <= Merit::of(&p.f) {
                // A constraint of a higher priority than the merit is met: the nearest such point so far.
                first_infeasible = Some(q);
            }
            t *= 0.25;
        }
        first_infeasible.map_or(Search::Stuck, Search::Blocked)
    }
}

impl Gradient {
    /// Compass search from `p` along the coordinates, step `scale` (at most 1e-3 rad) doubled after a pass
    /// that improved and divided by 4 after one that did not, down to `tolerance` or
    /// [`POLISH_EVALUATIONS`] evaluations: what the quasi-Newton steps cannot do
    /// at a kink of the violation (a constraint meeting a bound, two constraints meeting).
    fn polish(&self, f: &mut Counted<'_>, space: &SearchSpace, mut p: Point, scale: f64) -> Point {
        // At most 1e-3 rad, at least the tolerance (which may be the coarser of the two).
        let mut step = scale.min(1e-3).max(self.config.tolerance);
        let mut x = p.x.clone();
        let budget = f.count + POLISH_EVALUATIONS;
        while step >= self.config.tolerance && f.count < budget {
            let mut improved = false;
            for i in 0..x.len() {
                let mut moved = false;
                for sign in [1.0, -1.0] {
                    // Along a coordinate that improves, keep going with doubling steps.
                    let mut s = step;
                    while f.count < budget {
                        x[i] = space.clamp(i, p.x[i] + sign * s);
                        if x[i] == p.x[i] {
                            break;
                        }
                        let fx = f.eval(&x);
                        if fx >= p.f {
                            break;
                        }
                        p.f = fx;
                        p.x[i] = x[i];
                        moved = true;
                        s *= 2.0;
                    }
                    x[i] = p.x[i];
                    if moved {
                        improved = true;
                        break;
                    }
                }
            }
            step *= if improved { 2.0 } else { 0.25 };
        }
        p
    }
}

/// Adds the constraint normal `a` to the orthonormal active set (Gram–Schmidt), or — when it is nearly
/// parallel to the span of the set (the same constraint met again further along) — replaces the set
/// with it; `false` when `a` is 0.
fn update_normals(normals: &mut Vec<Vec<f64>>, a: Vec<f64>, n: usize) -> bool {
    let norm = dot(&a, &a).sqrt();
    if norm.is_nan() || norm <= 0.0 {
        return false;
    }
    let mut residual = a.clone();
    project(&mut residual, normals);
    if dot(&residual, &residual).sqrt() < 0.5 * norm || normals.len() + 1 >= n {
        normals.clear();
    }
    add_normal(normals, a)
}

/// What a line search found.
enum Search {
    /// A point with a smaller fitness, and from a feasible start the infeasible trial point nearest to
    /// it when the step was cut short by a constraint.
    Better(Point, Option<Point>),
    /// None; from a feasible start, the infeasible trial point nearest to it (a constraint met).
    Blocked(Point),
    /// None.
    Stuck,
}

impl Solver for Gradient {
    fn kind(&self) -> SolverKind {
        SolverKind::Gradient
    }

    fn minimize(&self, f: &mut dyn FnMut(&[f64]) -> Fitness, space: &SearchSpace, _seed: u64) -> SolverResult {
        let n = space.dim();
        let mut starts: Vec<Vec<f64>> = vec![space.start().to_vec()];
        starts.push((0..n).map(|i| 0.5 * (space.lo()[i] + space.hi()[i])).collect());
        if n <= MAX_CORNER_DIM {
            starts.extend((0..1usize << n).map(|b| corner(space, b)));
        }
        self.minimize_from(f, space, &starts)
    }
}

impl Gradient {
    /// Minimises `f` over `space` from the best [`GradientConfig::starts`] of `starts` (clamped into the
    /// box; ties keep the earlier start), then polishes the best point found.
    pub fn minimize_from(
        &self,
        f: &mut dyn FnMut(&[f64]) -> Fitness,
        space: &SearchSpace,
        starts: &[Vec<f64>],
    ) -> SolverResult {
        let mut f = Counted::new(f);
        let mut points: Vec<Point> = Vec::with_capacity(starts.len() + 1);
        for x in starts.iter().chain(std::iter::once(&space.start().to_vec())) {
            let x: Vec<f64> = x.iter().enumerate().map(|(i, v)| space.clamp(i, *v)).collect();
            if points.iter().any(|p| p.x == x) {
                continue;
            }
            points.push(Point { f: f.eval(&x), x });
        }
        points.sort_by_key(|p| p.f);
        let mut best = (points[0].clone(), 1e-3);
        let mut iterations = 0;
        for p in points.into_iter().take(self.config.starts.max(1)) {
            let (q, it, scale) = self.descend(&mut f, space, p);
            iterations += it;
            if q.f < best.0.f {
                best = (q, scale);
            }
            if self.handoff.first_feasible && best.0.f.tiers().iter().all(|t| *t == 0.0) {
                break;
            }
        }
        let best = self.polish(&mut f, space, best.0, best.1);
        SolverResult { best: best.x, fitness: best.f, iterations, evaluations: f.count }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::tests as common;

    #[test]
    fn finds_quadratic_minimum() {
        common::finds_quadratic_minimum(&Gradient::default(), 1e-5);
    }

    #[test]
    fn respects_bounds_straddling_pi() {
        common::respects_bounds_straddling_pi(&Gradient::default(), 1e-12);
    }

    #[test]
    fn a_tolerance_coarser_than_the_polish_step_still_converges() {
        // The polish starts at 1e-3 rad; a coarser tolerance (a scenario may give up to π) still ends within
        // half a tolerance of the minimum (the last step halves it), and one wider than the box still ends
        // in the box, better than where it started.
        for tolerance in [2e-3, 0.1, 0.5] {
            let g = Gradient::new(GradientConfig { tolerance, ..GradientConfig::default() });
            common::finds_quadratic_minimum(&g, 0.5 * tolerance + 1e-12);
        }
        let g = Gradient::new(GradientConfig { tolerance: std::f64::consts::PI, ..GradientConfig::default() });
        let r = g.minimize(&mut common::quadratic, &common::cube(), 7);
        assert!(r.best.iter().all(|x| (-1.0..=1.0).contains(x)), "{:?}", r.best);
        let start = common::quadratic(&[-0.9, 0.9, -0.9]);
        assert!(r.fitness.objective() < 0.1 * start.objective(), "{:?} vs the start's {:?}", r.fitness, start);
    }

    #[test]
    fn prefers_feasible() {
        common::prefers_feasible(&Gradient::default());
    }

    #[test]
    fn deterministic_whatever_the_seed() {
        let run = |seed| {
            let mut seen = Vec::new();
            let mut f = |x: &[f64]| {
                seen.push(x.to_vec());
                common::quadratic(x)
            };
            let r = Gradient::default().minimize(&mut f, &common::cube(), seed);
            (seen, r)
        };
        let (a, ra) = run(1);
        let (b, rb) = run(2);
        assert_eq!(a, b);
        assert_eq!(ra, rb);
        assert_eq!(ra.evaluations, a.len());
    }

    /// A feasible region outside a disc (as the spacing and approach constraints are, in waypoint space)
    /// with the unconstrained minimum inside it: the optimum lies on the circle, where the objective's
    /// gradient is normal to it. The active set slides along the circle to it.
    #[test]
    fn slides_along_a_nonlinear_constraint_to_the_constrained_minimum() {
        let (cx, cy, r) = (0.2, 0.1, 0.5);
        let target = [0.35, 0.25]; // inside the disc
        let mut f = |x: &[f64]| {
            let d = ((x[0] - cx).powi(2) + (x[1] - cy).powi(2)).sqrt();
            let obj = (x[0] - target[0]).powi(2) + 3.0 * (x[1] - target[1]).powi(2);
            Fitness::new((r - d).max(0.0) / r, obj)
        };
        let space = SearchSpace::new(vec![-1.0; 2], vec![1.0; 2], vec![-0.9, -0.9]).unwrap();
        let got = Gradient::default().minimize(&mut f, &space, 0);
        assert!(got.fitness.is_feasible(), "{got:?}");
        // The reference: the minimum of the objective over the circle, by a fine scan and a refinement.
        let on_circle = |a: f64| [cx + r * a.cos(), cy + r * a.sin()];
        let obj = |p: [f64; 2]| (p[0] - target[0]).powi(2) + 3.0 * (p[1] - target[1]).powi(2);
        let mut best = (0.0, f64::INFINITY);
        for k in 0..200_000 {
            let a = k as f64 * std::f64::consts::TAU / 200_000.0;
            let v = obj(on_circle(a));
            if v < best.1 {
                best = (a, v);
            }
        }
        let rel = (got.fitness.objective() - best.1) / best.1;
        assert!(rel < 1e-6, "objective {} vs the constrained minimum {} ({rel:e})", got.fitness.objective(), best.1);
    }

    /// Six of eight coordinates have their minimum beyond the box's upper bound: held there, they are
    /// probed only by the full probes that check them, while the two free ones take a curved valley
    /// that needs many iterations. The minimum is still found exactly.
    #[test]
    fn coordinates_held_at_a_bound_are_not_probed_every_iteration() {
        let valley = |x: &[f64]| 10.0 * (x[1] - x[0] * x[0]).powi(2) + (0.7 - x[0]).powi(2);
        let beyond = |x: &[f64]| x[2..].iter().map(|v| (v - 2.0).powi(2)).sum::<f64>();
        let space = SearchSpace::new(vec![-1.0; 8], vec![1.0; 8], vec![-0.5; 8]).unwrap();
        let (mut evaluations, mut off_bound) = (0usize, 0usize);
        let mut f = |x: &[f64]| {
            evaluations += 1;
            // An evaluation that moves a held coordinate off its bound is one of a probe's differences.
            off_bound += usize::from(x[2..].iter().any(|v| *v < 1.0));
            Fitness::feasible(valley(x) + beyond(x))
        };
        let g = Gradient::new(GradientConfig { starts: 1, ..GradientConfig::default() });
        let r = g.minimize_from(&mut f, &space, &[vec![-0.5, 0.9, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0]]);
        assert!((r.best[0] - 0.7).abs() < 1e-4 && (r.best[1] - 0.49).abs() < 1e-4, "{:?}", r.best);
        assert!(r.best[2..].iter().all(|v| *v == 1.0), "{:?}", r.best);
        assert!(r.iterations >= 10, "the valley was meant to take many iterations: {}", r.iterations);
        // Every full probe of the held coordinates costs 6 evaluations, and so does a pass of the polish:
        // a handful of them, not one per iteration (a full probe per iteration: ≥ 6 × iterations).
        assert!(off_bound <= 6 * 6, "{off_bound} evaluations off the bound in {} iterations", r.iterations);
        assert_eq!(evaluations, r.evaluations);
    }

    /// A coordinate held at its lower bound at the start is pulled inwards once the other moves: the
    /// full probe where the search would stop frees it, and the search reaches the interior minimum.
    #[test]
    fn a_held_coordinate_is_freed_when_the_gradient_turns_inwards() {
        // At the start (−1, −1) ∂f/∂x₀ = 20·0.5 > 0 holds x₀ at its lower bound; the minimum is (0.4, 0.9).
        let mut f = |x: &[f64]| Fitness::feasible((x[1] - 0.9).powi(2) + 10.0 * (x[0] - x[1] + 0.5).powi(2));
        let space = SearchSpace::new(vec![-1.0; 2], vec![1.0; 2], vec![-1.0; 2]).unwrap();
        let g = Gradient::new(GradientConfig { starts: 1, ..GradientConfig::default() });
        let r = g.minimize_from(&mut f, &space, &[vec![-1.0, -1.0]]);
        assert!((r.best[0] - 0.4).abs() < 1e-5 && (r.best[1] - 0.9).abs() < 1e-5, "{:?}", r.best);
    }

    /// A violation tier (`x₀ ≥ 0.5`), the last tier (`|x₁ − 1|`) and a criterion, over `[−2, 2]²`.
    fn two_tiers(x: &[f64]) -> Fitness {
        let mut tiers = [0.0; crate::fitness::TIERS];
        tiers[0] = (0.5 - x[0]).max(0.0);
        tiers[crate::fitness::TIERS - 1] = (x[1] - 1.0).abs();
        Fitness::tiered(tiers, (x[0] - 1.0).powi(2) + x[1] * x[1])
    }

    #[test]
    fn a_handoff_at_a_tier_stops_the_local_search_once_the_earlier_tiers_hold() {
        let space = SearchSpace::new(vec![-2.0; 2], vec![2.0; 2], vec![0.0, 0.0]).unwrap();
        let single = GradientConfig { starts: 1, ..GradientConfig::default() };
        let last = crate::fitness::TIERS - 1;
        let plain = Gradient::new(single).minimize_from(&mut two_tiers, &space, &[vec![0.0, 0.0]]);
        let handoff = Handoff { from_tier: Some(last), ..Handoff::default() };
        let handed =
            Gradient::new(single).with_handoff(handoff).minimize_from(&mut two_tiers, &space, &[vec![0.0, 0.0]]);
        // Both lower the first tier to 0; only the plain search goes on to the last tier and the criterion.
        assert_eq!(handed.fitness.tiers()[0], 0.0, "{handed:?}");
        assert_eq!(plain.fitness.tiers(), [0.0; crate::fitness::TIERS], "{plain:?}");
        assert!((plain.best[0] - 1.0).abs() < 1e-4, "{plain:?}");
        assert!(handed.iterations < plain.iterations, "{} vs {} iterations", handed.iterations, plain.iterations);
    }

    #[test]
    fn a_plateau_above_zero_ends_a_local_search_but_never_a_descent_of_the_criterion() {
        // A violation whose least value is 1 (at x = (5, 5)), approached slowly along a kink from (−9, −10).
        let mut slow =
            |x: &[f64]| Fitness::new(1.0 + 0.2 * (x[0] - x[1]).abs() + 1e-3 * (x[0] + x[1] - 10.0).powi(2), 0.0);
        let start = vec![-9.0, -10.0];
        let space = SearchSpace::new(vec![-10.0; 2], vec![10.0; 2], start.clone()).unwrap();
        let single = Gradient::new(GradientConfig { starts: 1, ..GradientConfig::default() });
        let plateau = Handoff { plateau: Some(0.05), ..Handoff::default() };
        let plain = single.minimize_from(&mut slow, &space, std::slice::from_ref(&start));
        let handed = single.with_handoff(plateau).minimize_from(&mut slow, &space, std::slice::from_ref(&start));
        assert!((plain.best[0] - 5.0).abs() < 1e-2 && (plain.best[1] - 5.0).abs() < 1e-2, "{plain:?}");
        // Less than 5 % lowered over five iterations: the handed-over search stops there, far from (5, 5).
        assert!(handed.iterations <= 2 * PLATEAU_ITERATIONS && handed.iterations < plain.iterations, "{handed:?}");
        assert!(handed.evaluations < plain.evaluations && handed.fitness < slow(&start), "{handed:?}");
        // The criterion is not a violation tier: the rule leaves its descent alone.
        common::finds_quadratic_minimum(&Gradient::default().with_handoff(plateau), 1e-5);
    }

    #[test]
    fn after_a_feasible_local_search_the_next_starts_are_skipped_when_asked() {
        let space = common::cube();
        let starts = [vec![-0.9, 0.9, -0.9], vec![0.9, -0.9, 0.9]];
        let plain = Gradient::default().minimize_from(&mut common::quadratic, &space, &starts);
        let first = Handoff { first_feasible: true, ..Handoff::default() };
        let handed = Gradient::default().with_handoff(first).minimize_from(&mut common::quadratic, &space, &starts);
        for r in [&plain, &handed] {
            let err = r.best.iter().zip(common::C).map(|(a, c)| (a - c).abs()).fold(0.0, f64::max);
            assert!(err < 1e-5, "{r:?}");
        }
        assert!(handed.iterations < plain.iterations, "{} vs {}", handed.iterations, plain.iterations);
    }

    #[test]
    fn starts_include_every_corner_in_low_dimensions() {
        let space = SearchSpace::new(vec![-1.0; 3], vec![1.0; 3], vec![0.1, 0.2, 0.3]).unwrap();
        let mut seen = Vec::new();
        let mut f = |x: &[f64]| {
            seen.push(x.to_vec());
            Fitness::feasible(1.0) // flat: no local search moves
        };
        let r = Gradient::default().minimize(&mut f, &space, 0);
        for b in 0..8 {
            assert!(seen.contains(&corner(&space, b)), "corner {b}");
        }
        assert!(seen.contains(&vec![0.1, 0.2, 0.3]) && seen.contains(&vec![0.0; 3]));
        assert_eq!(r.best, vec![0.1, 0.2, 0.3], "ties keep the first start");
    }
}
