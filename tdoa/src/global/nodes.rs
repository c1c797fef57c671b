//! A fixed set of points with normalised weights: the common form of the `mc`, `quadrature`,
//! `cubature` (and `single`) rules, so that they differ only in how the nodes are chosen.

use nalgebra::Vector2;

use super::{GlobalValue, PreparedObjective};
use crate::Sensors;
use crate::fim::trace_crlb;

/// `Σ_k ω_k tr F⁻¹(p_k)` with `Σ_k ω_k = 1`.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeRule {
    points: Vec<Vector2<f64>>,
    weights: Vec<f64>,
    with_stderr: bool,
}

impl NodeRule {
    /// Builds a rule from points and non-negative raw weights (normalised here). Points of zero weight
    /// are dropped. `with_stderr` reports the self-normalised importance-sampling standard error
    /// `sqrt(Σ ω_k² (h_k − ĥ)²)`, meaningful when the points are random.
    pub fn new(points: Vec<Vector2<f64>>, raw_weights: Vec<f64>, with_stderr: bool) -> Self {
        let total: f64 = raw_weights.iter().sum();
        let (points, weights): (Vec<_>, Vec<_>) =
            points.into_iter().zip(raw_weights).filter(|(_, w)| *w > 0.0).map(|(p, w)| (p, w / total)).unzip();
        Self { points, weights, with_stderr }
    }

    /// The nodes, metres.
    pub fn points(&self) -> &[Vector2<f64>] {
        &self.points
    }

    /// The normalised weights.
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }

    /// Kish's effective sample size `1 / Σ ω_k²`.
    pub fn effective_sample_size(&self) -> f64 {
        1.0 / self.weights.iter().map(|w| w * w).sum::<f64>()
    }
}

impl PreparedObjective for NodeRule {
    fn evaluate(&self, sensors: &Sensors) -> GlobalValue {
        // One pass: Σω h, Σω² h, Σω² h², Σω²; then Σω²(h − ĥ)² = Σω²h² − 2ĥ Σω²h + ĥ² Σω².
        let (mut sum, mut s1, mut s2, mut s0) = (0.0, 0.0, 0.0, 0.0);
        for (p, w) in self.points.iter().zip(&self.weights) {
            let h = trace_crlb(sensors, p);
            sum += w * h;
            if self.with_stderr {
                let w2 = w * w;
                s0 += w2;
                s1 += w2 * h;
                s2 += w2 * h * h;
            }
        }
        let stderr_m2 = self.with_stderr.then(|| (s2 - 2.0 * sum * s1 + sum * sum * s0).max(0.0).sqrt());
        GlobalValue {
            trace_m2: sum,
            stderr_m2,
            evaluations: self.points.len(),
            effective_samples: self.with_stderr.then(|| self.effective_sample_size()),
        }
    }
}
