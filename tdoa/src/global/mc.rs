//! `mc`: Monte Carlo global CRLB (paper eq. 60).

use nalgebra::Vector2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use super::{GlobalCrlb, Method, NodeRule, PreparedObjective};
use crate::{TdoaError, Uncertainty};

/// How the Monte Carlo points are drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum McScheme {
    /// The paper's eq. 60: K points uniform in the square, self-normalised Gaussian weights.
    /// Its effective sample size is small when the square is wide relative to `M`.
    UniformWeighted,
    /// K points drawn from the truncated Gaussian itself (rejection outside the square), equal weights.
    TruncatedGaussian,
}

/// Monte Carlo estimate of the global CRLB with K samples from a seeded generator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MonteCarlo {
    samples: usize,
    seed: u64,
    scheme: McScheme,
}

impl MonteCarlo {
    /// K ≥ 2 samples, drawn from a ChaCha8 stream seeded with `seed`.
    pub fn new(samples: usize, seed: u64, scheme: McScheme) -> Result<Self, TdoaError> {
        if samples < 2 {
            return Err(TdoaError::NonPositive {
                what: "Monte Carlo samples − 1".into(), value: samples as f64 - 1.0
            });
        }
        if samples > crate::montecarlo::MAX_SAMPLES {
            return Err(TdoaError::OutOfRange {
                what: "Monte Carlo samples".into(),
                value: samples as f64,
                min: 2.0,
                max: crate::montecarlo::MAX_SAMPLES as f64,
            });
        }
        Ok(Self { samples, seed, scheme })
    }

    /// The node rule this method uses for `unc` (exposed for diagnostics such as the effective sample size).
    pub fn rule(&self, unc: &Uncertainty) -> NodeRule {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        let z = unc.estimate();
        let a = unc.side();
        let mut points = Vec::with_capacity(self.samples);
        let weights = match self.scheme {
            McScheme::UniformWeighted => {
                for _ in 0..self.samples {
                    let u = Vector2::new(rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5);
                    points.push(z + u * a);
                }
                points.iter().map(|p| unc.density(p)).collect()
            }
            McScheme::TruncatedGaussian => {
                let l = unc.cov().cholesky().map(|c| c.l()).unwrap_or_else(nalgebra::Matrix2::identity);
                // The support holds ≥ 99.7 % of the mass per axis for A ≥ 6 σ_t, so rejection is cheap;
                // the attempt cap only guards absurd inputs.
                let mut attempts = 0usize;
                while points.len() < self.samples && attempts < 1000 * self.samples {
                    attempts += 1;
                    let e = Vector2::new(rng.sample::<f64, _>(StandardNormal), rng.sample::<f64, _>(StandardNormal));
                    let p = z + l * e;
                    if unc.contains(&p) {
                        points.push(p);
                    }
                }
                vec![1.0; points.len()]
            }
        };
        NodeRule::new(points, weights, true)
    }
}

impl GlobalCrlb for MonteCarlo {
    fn method(&self) -> Method {
        Method::Mc
    }
    fn estimates_integral(&self) -> bool {
        true
    }
    fn prepare(&self, unc: &Uncertainty) -> Box<dyn PreparedObjective> {
        Box::new(self.rule(unc))
    }
}
