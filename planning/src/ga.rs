//! A real-coded genetic algorithm over bounded headings (the paper's GA of Section 5.4, Table 3:
//! 40 individuals × 15 generations, "continuous bounded-heading search"; the operators are our choice):
//!
//! - selection: tournament of `tournament` individuals drawn with replacement (2);
//! - crossover with probability `crossover_rate` (0.9): BLX-α (Eshelman & Schaffer 1993) — each
//!   child gene uniform in `[min − α d, max + α d]` of the parents' genes, `d = |a − b|`, α = 0.5;
//! - mutation: each gene with probability `mutation_rate` (0.2) gets Gaussian noise of standard
//!   deviation `mutation_scale` (0.1) × the interval width;
//! - every gene is clamped into its interval;
//! - elitism: the `elites` (2) best individuals pass unchanged (and are not re-evaluated).
//!
//! Initialisation: the start point plus uniform draws. Stops after `generations` or by the shared
//! [`EarlyStop`] rule.

pub use model::solver_config::GaConfig;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use crate::fitness::Fitness;
use crate::solver::{Counted, EarlyStop, SearchSpace, Solver, SolverKind, SolverResult, StopRule, argmin};

/// The genetic algorithm.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Ga {
    /// Sizes and operator settings.
    pub config: GaConfig,
    /// Stopping rule.
    pub stop: EarlyStop,
}

impl Ga {
    fn tournament(&self, fit: &[Fitness], rng: &mut ChaCha8Rng) -> usize {
        let mut best = rng.random_range(0..fit.len());
        for _ in 1..self.config.tournament.max(1) {
            let c = rng.random_range(0..fit.len());
            if fit[c] < fit[best] {
                best = c;
            }
        }
        best
    }

    fn blx(&self, a: f64, b: f64, rng: &mut ChaCha8Rng) -> f64 {
        let (lo, hi) = (a.min(b), a.max(b));
        let ext = self.config.blx_alpha * (hi - lo);
        lo - ext + rng.random::<f64>() * (hi - lo + 2.0 * ext)
    }

    fn child(&self, a: &[f64], b: &[f64], cross: bool, space: &SearchSpace, rng: &mut ChaCha8Rng) -> Vec<f64> {
        (0..space.dim())
            .map(|i| {
                let mut g = if cross { self.blx(a[i], b[i], rng) } else { a[i] };
                if rng.random::<f64>() < self.config.mutation_rate {
                    g += self.config.mutation_scale * space.width(i) * rng.sample::<f64, _>(StandardNormal);
                }
                space.clamp(i, g)
            })
            .collect()
    }
}

impl Solver for Ga {
    fn kind(&self) -> SolverKind {
        SolverKind::Ga
    }

    fn minimize(&self, f: &mut dyn FnMut(&[f64]) -> Fitness, space: &SearchSpace, seed: u64) -> SolverResult {
        let size = self.config.population.max(2);
        let elites = self.config.elites.min(size - 1);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut f = Counted::new(f);
        let mut pop = space.initial_population(size, &mut rng);
        let mut fit: Vec<Fitness> = pop.iter().map(|p| f.eval(p)).collect();
        let mut tracker = self.stop.tracker(fit[argmin(&fit)]);
        let mut iterations = 0;
        for _ in 0..self.config.generations {
            let mut order: Vec<usize> = (0..size).collect();
            order.sort_by_key(|&k| fit[k]);
            let mut next: Vec<Vec<f64>> = order[..elites].iter().map(|&k| pop[k].clone()).collect();
            let mut next_fit: Vec<Fitness> = order[..elites].iter().map(|&k| fit[k]).collect();
            while next.len() < size {
                let a = self.tournament(&fit, &mut rng);
                let b = self.tournament(&fit, &mut rng);
                let cross = rng.random::<f64>() < self.config.crossover_rate;
                for (p, q) in [(a, b), (b, a)] {
                    if next.len() < size {
                        let c = self.child(&pop[p], &pop[q], cross, space, &mut rng);
                        next_fit.push(f.eval(&c));
                        next.push(c);
                    }
                }
            }
            pop = next;
            fit = next_fit;
            iterations += 1;
            if tracker.observe(fit[argmin(&fit)]) {
                break;
            }
        }
        let best = argmin(&fit);
        SolverResult { best: pop[best].clone(), fitness: fit[best], iterations, evaluations: f.count }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::tests as common;

    #[test]
    fn finds_quadratic_minimum() {
        common::finds_quadratic_minimum(&Ga::default(), 0.05);
    }

    #[test]
    fn respects_bounds_straddling_pi() {
        common::respects_bounds_straddling_pi(&Ga::default(), 1e-2);
    }

    #[test]
    fn deterministic_per_seed() {
        common::deterministic_per_seed(&Ga::default());
    }

    #[test]
    fn prefers_feasible() {
        common::prefers_feasible(&Ga::default());
    }

    #[test]
    fn elitism_never_loses_the_best() {
        let mut bests = Vec::new();
        let ga = Ga { stop: EarlyStop { window: 0, tolerance: 0.0 }, ..Ga::default() };
        for gens in 0..6 {
            let g = Ga { config: GaConfig { generations: gens, ..ga.config }, ..ga };
            bests.push(g.minimize(&mut common::quadratic, &common::cube(), 4).fitness);
        }
        assert!(bests.windows(2).all(|w| w[1] <= w[0]), "{bests:?}");
    }
}
