//! Particle swarm optimisation exactly as the paper's Section 4.3 (eqs. 76–79, Algorithm 1).
//!
//! Per iteration `k = 0, 1, …, k_max − 1` and per particle `j` and dimension `i`:
//!
//! - `u_j(k+1) = ξ(k) u_j(k) + c1(k) r1 (p_j − Θ_j(k)) + c2(k) r2 (p_g − Θ_j(k))` (eq. 76), with
//!   `ξ(k) = 0.9 − 0.5 k/k_max`, `c1(k) = 2.5 − 1.5 k/k_max`, `c2(k) = 0.5 + 1.5 k/k_max` and
//!   `r1, r2 ~ U(0, 1)` drawn independently per particle and dimension;
//! - `|u_j,i| ≤ v_max,i` with `v_max,i = v_max_fraction · (hi_i − lo_i)` — our choice, 20 % of the
//!   heading-cone width (the paper bounds the velocity without giving the value);
//! - `Θ_j(k+1) = Θ_j(k) + u_j(k+1)` (eq. 77), then clamped into `[lo_i, hi_i]`; a particle that hits
//!   a wall loses that velocity component (absorbing wall — our choice);
//! - personal bests by eq. 78's fitness (here the lexicographic [`Fitness`]), the global best after the
//!   whole swarm has moved (eq. 79).
//!
//! Initialisation (our choice): particle 0 sits on the start point (the current headings clamped into
//! the cone), the others are uniform in the box; initial velocities are uniform in `[−v_max, v_max]`.
//! The search stops after `k_max` iterations or by the shared [`EarlyStop`] rule, so it spends
//! `particles · (1 + iterations)` evaluations at most.

pub use model::solver_config::PsoConfig;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::fitness::Fitness;
use crate::solver::{Counted, EarlyStop, SearchSpace, Solver, SolverKind, SolverResult, StopRule, argmin};

/// The paper's PSO.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Pso {
    /// Sizes and velocity clamp.
    pub config: PsoConfig,
    /// Stopping rule.
    pub stop: EarlyStop,
}

impl Solver for Pso {
    fn kind(&self) -> SolverKind {
        SolverKind::Pso
    }

    fn minimize(&self, f: &mut dyn FnMut(&[f64]) -> Fitness, space: &SearchSpace, seed: u64) -> SolverResult {
        let n = space.dim();
        let np = self.config.particles.max(1);
        let kmax = self.config.iterations;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut f = Counted::new(f);
        let vmax: Vec<f64> = (0..n).map(|i| (self.config.v_max_fraction * space.width(i)).max(0.0)).collect();
        // The swarm as flat arrays, particle j at [j·n, (j+1)·n): positions, velocities, personal bests.
        let mut x: Vec<f64> = space.initial_population_flat(np, &mut rng);
        let mut v: Vec<f64> = Vec::with_capacity(np * n);
        for _ in 0..np {
            v.extend(vmax.iter().map(|vm| (2.0 * rng.random::<f64>() - 1.0) * vm));
        }
        // (A search space has at least one dimension.)
        let mut pfit: Vec<Fitness> = x.chunks_exact(n).map(|p| f.eval(p)).collect();
        let mut pbest = x.clone();
        let g = argmin(&pfit);
        let mut gbest = pbest[g * n..(g + 1) * n].to_vec();
        let mut gfit = pfit[g];
        let mut tracker = self.stop.tracker(gfit);
        let mut iterations = 0;
        for k in 0..kmax {
            let t = k as f64 / kmax as f64;
            let (xi, c1, c2) = (0.9 - 0.5 * t, 2.5 - 1.5 * t, 0.5 + 1.5 * t);
            for (j, best_fit) in pfit.iter_mut().enumerate() {
                let row = j * n..(j + 1) * n;
                {
                    let (xj, vj, pj) = (&mut x[row.clone()], &mut v[row.clone()], &pbest[row.clone()]);
                    for i in 0..n {
                        let r1: f64 = rng.random();
                        let r2: f64 = rng.random();
                        let u = xi * vj[i] + c1 * r1 * (pj[i] - xj[i]) + c2 * r2 * (gbest[i] - xj[i]);
                        let u = u.clamp(-vmax[i], vmax[i]);
                        let moved = xj[i] + u;
                        let clamped = space.clamp(i, moved);
                        vj[i] = if clamped == moved { u } else { 0.0 };
                        xj[i] = clamped;
                    }
                }
                let fit = f.eval(&x[row.clone()]);
                if fit < *best_fit {
                    *best_fit = fit;
                    pbest[row.clone()].copy_from_slice(&x[row]);
                }
            }
            let g = argmin(&pfit);
            if pfit[g] < gfit {
                gfit = pfit[g];
                gbest.copy_from_slice(&pbest[g * n..(g + 1) * n]);
            }
            iterations += 1;
            if tracker.observe(gfit) {
                break;
            }
        }
        SolverResult { best: gbest, fitness: gfit, iterations, evaluations: f.count }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::tests as common;

    #[test]
    fn finds_quadratic_minimum() {
        common::finds_quadratic_minimum(&Pso::default(), 0.02);
    }

    #[test]
    fn respects_bounds_straddling_pi() {
        common::respects_bounds_straddling_pi(&Pso::default(), 1e-3);
    }

    #[test]
    fn deterministic_per_seed() {
        common::deterministic_per_seed(&Pso::default());
    }

    #[test]
    fn prefers_feasible() {
        common::prefers_feasible(&Pso::default());
    }

    #[test]
    fn spends_at_most_the_budget() {
        let r = Pso::default().minimize(&mut common::quadratic, &common::cube(), 1);
        assert!(r.iterations <= 15);
        assert_eq!(r.evaluations, 40 * (1 + r.iterations));
    }

    #[test]
    fn starts_from_the_start_point() {
        // A function whose minimum is the start point: the result is exactly it.
        let space = common::cube();
        let s = space.start().to_vec();
        let mut f = |x: &[f64]| Fitness::feasible(x.iter().zip(&s).map(|(a, b)| (a - b).abs()).sum());
        let r = Pso::default().minimize(&mut f, &space, 9);
        assert_eq!(r.best, space.start());
        assert_eq!(r.fitness, Fitness::feasible(0.0));
    }
}
