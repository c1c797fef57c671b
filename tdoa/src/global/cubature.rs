//! `cubature` (beyond the paper): a deterministic 25-point rule for the truncated Gaussian — the 5×5
//! tensor Gauss–Hermite rule in the eigenbasis of `M` (exact for polynomials of degree ≤ 9 in each
//! whitened axis under the untruncated Gaussian), with nodes outside the square dropped and the
//! remaining weights renormalised.

use nalgebra::{SymmetricEigen, Vector2};

use super::{GlobalCrlb, Method, NodeRule, PreparedObjective, gauss_hermite};
use crate::Uncertainty;

/// Points per whitened axis (25 evaluations in all).
pub const CUBATURE_ORDER: usize = 5;

/// The 25-point Gauss–Hermite cubature of the global CRLB.
#[derive(Debug, Clone, Copy, Default)]
pub struct Cubature;

impl Cubature {
    /// The node rule for `unc`.
    pub fn rule(unc: &Uncertainty) -> NodeRule {
        let (x, w) = gauss_hermite(CUBATURE_ORDER);
        let eig = SymmetricEigen::new(unc.cov());
        let axes = [
            eig.eigenvectors.column(0) * eig.eigenvalues[0].max(0.0).sqrt(),
            eig.eigenvectors.column(1) * eig.eigenvalues[1].max(0.0).sqrt(),
        ];
        let mut points = Vec::with_capacity(x.len() * x.len());
        let mut weights = Vec::with_capacity(x.len() * x.len());
        for (xa, wa) in x.iter().zip(&w) {
            for (xb, wb) in x.iter().zip(&w) {
                let p: Vector2<f64> = unc.estimate() + axes[0] * *xa + axes[1] * *xb;
                if unc.contains(&p) {
                    points.push(p);
                    weights.push(wa * wb);
                }
            }
        }
        NodeRule::new(points, weights, false)
    }
}

impl GlobalCrlb for Cubature {
    fn method(&self) -> Method {
        Method::Cubature
    }
    fn estimates_integral(&self) -> bool {
        true
    }
    fn prepare(&self, unc: &Uncertainty) -> Box<dyn PreparedObjective> {
        Box::new(Self::rule(unc))
    }
}
