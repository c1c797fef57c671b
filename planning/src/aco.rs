//! Ant colony optimisation for continuous domains, ACO_R (Socha & Dorigo 2008), over bounded headings
//! (the paper's ACO of Section 5.4, Table 3: 40 ants × 15 iterations, "evaporation 0.35 / elite
//! fraction 0.25").
//!
//! The pheromone is a solution archive of `archive` (k = 40) points sorted by fitness. Rank `l`
//! (0 = best) has weight `ω_l ∝ exp(−l² / (2 q² k²))` with locality `q` = `elite_fraction` = 0.25: the
//! best quarter of the archive carries most of the weight (Table 3's "elite fraction"). Each of the
//! `ants` (40) ants picks a guide `l` with probability ∝ `ω_l` and samples every dimension from
//! `N(s_l,i, σ_l,i)`, `σ_l,i = ξ Σ_e |s_e,i − s_l,i| / (k − 1)`, with `ξ` = `evaporation` = 0.35
//! (Table 3's "evaporation": like pheromone evaporation, a larger ξ forgets the archive's consensus
//! more slowly and converges more slowly). Samples are clamped into the box (our choice). After all ants
//! have been evaluated, the archive keeps the k best of itself and the new points.
//!
//! Initialisation: the start point plus uniform draws fill the archive. Dimensions are sampled
//! independently (without the rotated basis of the original paper — our choice, the 3–8 headings are
//! weakly coupled). Stops after `iterations` or by the shared [`EarlyStop`] rule.

pub use model::solver_config::AcoConfig;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use crate::fitness::Fitness;
use crate::solver::{Counted, EarlyStop, SearchSpace, Solver, SolverKind, SolverResult, StopRule};

/// ACO_R.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Aco {
    /// Sizes and parameters.
    pub config: AcoConfig,
    /// Stopping rule.
    pub stop: EarlyStop,
}

impl Aco {
    /// Cumulative rank weights `Σ_{m ≤ l} ω_m` of an archive of `k` solutions.
    fn cumulative_weights(&self, k: usize) -> Vec<f64> {
        let qk = (self.config.elite_fraction * k as f64).max(f64::MIN_POSITIVE);
        let mut acc = 0.0;
        (0..k)
            .map(|l| {
                acc += (-((l * l) as f64) / (2.0 * qk * qk)).exp();
                acc
            })
            .collect()
    }
}

impl Solver for Aco {
    fn kind(&self) -> SolverKind {
        SolverKind::Aco
    }

    fn minimize(&self, f: &mut dyn FnMut(&[f64]) -> Fitness, space: &SearchSpace, seed: u64) -> SolverResult {
        let n = space.dim();
        let k = self.config.archive.max(1);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut f = Counted::new(f);
        let mut archive: Vec<(Vec<f64>, Fitness)> = space
            .initial_population(k, &mut rng)
            .into_iter()
            .map(|x| {
                let fit = f.eval(&x);
                (x, fit)
            })
            .collect();
        archive.sort_by_key(|a| a.1);
        let cum = self.cumulative_weights(k);
        let total = cum[k - 1];
        let mut tracker = self.stop.tracker(archive[0].1);
        let mut iterations = 0;
        for _ in 0..self.config.iterations {
            let mut ants = Vec::with_capacity(self.config.ants);
            for _ in 0..self.config.ants {
                let u = rng.random::<f64>() * total;
                let l = cum.iter().position(|&c| u < c).unwrap_or(k - 1);
                let guide = &archive[l].0;
                let x: Vec<f64> = (0..n)
                    .map(|i| {
                        let spread = if k > 1 {
                            archive.iter().map(|(s, _)| (s[i] - guide[i]).abs()).sum::<f64>() / (k - 1) as f64
                        } else {
                            space.width(i)
                        };
                        let sigma = self.config.evaporation * spread;
                        space.clamp(i, guide[i] + sigma * rng.sample::<f64, _>(StandardNormal))
                    })
                    .collect();
                let fit = f.eval(&x);
                ants.push((x, fit));
            }
            archive.extend(ants);
            archive.sort_by_key(|a| a.1);
            archive.truncate(k);
            iterations += 1;
            if tracker.observe(archive[0].1) {
                break;
            }
        }
        let (best, fitness) = archive.swap_remove(0);
        SolverResult { best, fitness, iterations, evaluations: f.count }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::tests as common;

    #[test]
    fn finds_quadratic_minimum() {
        common::finds_quadratic_minimum(&Aco::default(), 0.05);
    }

    #[test]
    fn respects_bounds_straddling_pi() {
        common::respects_bounds_straddling_pi(&Aco::default(), 3e-2);
    }

    #[test]
    fn deterministic_per_seed() {
        common::deterministic_per_seed(&Aco::default());
    }

    #[test]
    fn prefers_feasible() {
        common::prefers_feasible(&Aco::default());
    }

    #[test]
    fn rank_weights_favour_the_elite() {
        let aco = Aco::default();
        let cum = aco.cumulative_weights(40);
        // With q = 0.25 the best quarter (10 of 40) carries about 68 % of the weight (±1 σ of the kernel).
        let share = cum[9] / cum[39];
        assert!(share > 0.6 && share < 0.8, "{share}");
    }
}
