//! `quadrature`: deterministic composite tensor Gauss–Legendre over the square support, refined by
//! doubling the panel count until two levels agree — the ground truth for the other methods.
//! Also the Gauss rules (Golub–Welsch) used here and by `cubature`.

use nalgebra::{DMatrix, SymmetricEigen, Vector2};

use super::{GlobalCrlb, GlobalValue, Method, NodeRule, PreparedObjective};
use crate::{Sensors, Uncertainty};

/// Gauss rule from the Jacobi matrix with zero diagonal and the given off-diagonal (Golub–Welsch);
/// weights sum to `mass`.
fn golub_welsch(n: usize, off: impl Fn(usize) -> f64, mass: f64) -> (Vec<f64>, Vec<f64>) {
    let jac = DMatrix::from_fn(n, n, |i, j| if i + 1 == j || j + 1 == i { off(i.max(j)) } else { 0.0 });
    let eig = SymmetricEigen::new(jac);
    let mut pairs: Vec<(f64, f64)> =
        (0..n).map(|k| (eig.eigenvalues[k], mass * eig.eigenvectors[(0, k)].powi(2))).collect();
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    pairs.into_iter().unzip()
}

/// n-point Gauss–Legendre nodes and weights on [−1, 1].
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    golub_welsch(n, |k| k as f64 / ((4 * k * k - 1) as f64).sqrt(), 2.0)
}

/// n-point Gauss–Hermite nodes and weights for the standard normal density (probabilists'),
/// weights summing to 1.
pub fn gauss_hermite(n: usize) -> (Vec<f64>, Vec<f64>) {
    golub_welsch(n, |k| (k as f64).sqrt(), 1.0)
}

/// Adaptive composite Gauss–Legendre: `order`-point rules on P×P panels, P = 2, 4, 8, … until the
/// relative change between levels is below `rel_tol` or P reaches `max_panels`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quadrature {
    /// Points per panel and axis.
    pub order: usize,
    /// Stop when |I_P − I_{P/2}| ≤ rel_tol·|I_P|.
    pub rel_tol: f64,
    /// Largest panel count per axis.
    pub max_panels: usize,
}

impl Default for Quadrature {
    fn default() -> Self {
        Self { order: 8, rel_tol: 1e-9, max_panels: 64 }
    }
}

impl Quadrature {
    /// The tensor rule with `panels`×`panels` panels over the support of `unc`, Gaussian-weighted.
    pub fn rule(&self, unc: &Uncertainty, panels: usize) -> NodeRule {
        let (x, w) = gauss_legendre(self.order);
        let (lo, _) = unc.bounds();
        let h = unc.side() / panels as f64;
        let mut axis = Vec::with_capacity(panels * self.order);
        for p in 0..panels {
            for (xi, wi) in x.iter().zip(&w) {
                axis.push((lo.x - unc.estimate().x + h * (p as f64 + 0.5 * (xi + 1.0)), 0.5 * h * wi));
            }
        }
        let mut points = Vec::with_capacity(axis.len() * axis.len());
        let mut weights = Vec::with_capacity(axis.len() * axis.len());
        for &(dx, wx) in &axis {
            for &(dy, wy) in &axis {
                let p = unc.estimate() + Vector2::new(dx, dy);
                points.push(p);
                weights.push(wx * wy * unc.density(&p));
            }
        }
        NodeRule::new(points, weights, false)
    }
}

struct Prepared {
    quad: Quadrature,
    unc: Uncertainty,
}

impl PreparedObjective for Prepared {
    fn evaluate(&self, sensors: &Sensors) -> GlobalValue {
        let mut panels = 2;
        let mut prev = self.quad.rule(&self.unc, 1).evaluate(sensors);
        let mut evaluations = prev.evaluations;
        loop {
            let cur = self.quad.rule(&self.unc, panels).evaluate(sensors);
            evaluations += cur.evaluations;
            let converged = (cur.trace_m2 - prev.trace_m2).abs() <= self.quad.rel_tol * cur.trace_m2.abs();
            if converged || !cur.trace_m2.is_finite() || panels >= self.quad.max_panels {
                // Not converged at the finest level: report the estimated error as the standard error.
                let stderr_m2 = (!converged).then(|| (cur.trace_m2 - prev.trace_m2).abs());
                return GlobalValue { trace_m2: cur.trace_m2, stderr_m2, evaluations, effective_samples: None };
            }
            prev = cur;
            panels *= 2;
        }
    }
}

impl GlobalCrlb for Quadrature {
    fn method(&self) -> Method {
        Method::Quadrature
    }
    fn estimates_integral(&self) -> bool {
        true
    }
    fn prepare(&self, unc: &Uncertainty) -> Box<dyn PreparedObjective> {
        Box::new(Prepared { quad: *self, unc: *unc })
    }
}
