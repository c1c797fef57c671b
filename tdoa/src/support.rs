//! The target-position uncertainty: Gaussian `N(ẑ, M)` truncated to a square support of side `A`
//! centred on `ẑ` (paper eqs. 31–36).
//!
//! Units: metres (position, side), m² (covariance).

use nalgebra::{Matrix2, Vector2};

use crate::TdoaError;
use crate::fim::sym_eigenvalues;
use crate::geometry::check_finite;

/// ẑ and M from their plain-array form — how messages carry them: `[x, y]` in metres and
/// the row-major `[[m00, m01], [m10, m11]]` in m².
pub fn estimate_from_arrays(position: &[f64; 2], covariance: &[[f64; 2]; 2]) -> (Vector2<f64>, Matrix2<f64>) {
    (Vector2::new(position[0], position[1]), matrix_from_rows(covariance))
}

/// Points `[x, y]` (metres, as messages carry UAV positions) as vectors.
pub fn points_from_arrays(points: &[[f64; 2]]) -> Vec<Vector2<f64>> {
    points.iter().map(|p| Vector2::new(p[0], p[1])).collect()
}

/// A 2×2 matrix from its rows `[[m00, m01], [m10, m11]]` (the inverse of [`matrix_to_rows`]).
pub fn matrix_from_rows(m: &[[f64; 2]; 2]) -> Matrix2<f64> {
    Matrix2::new(m[0][0], m[0][1], m[1][0], m[1][1])
}

/// The plain-array form of ẑ and M (the inverse of [`estimate_from_arrays`]).
pub fn estimate_to_arrays(position: &Vector2<f64>, covariance: &Matrix2<f64>) -> ([f64; 2], [[f64; 2]; 2]) {
    ([position.x, position.y], matrix_to_rows(covariance))
}

/// A 2×2 matrix as its rows `[[m00, m01], [m10, m11]]`, the plain-array form of every matrix in
/// messages and records.
pub fn matrix_to_rows(m: &Matrix2<f64>) -> [[f64; 2]; 2] {
    [[m[(0, 0)], m[(0, 1)]], [m[(1, 0)], m[(1, 1)]]]
}

/// Our choice for the paper's unstated κ of eq. 36 (`A = min(A_max, A_min + κ r_avg)`):
/// 0.1 grows the support by 100 m per kilometre of mean UAV–target distance.
pub const DEFAULT_KAPPA: f64 = 0.1;

/// Side of the square support by eq. 36: `min(10 σ_t, 6 σ_t + κ r_avg)`, metres.
pub fn eq36_side(sigma_t: f64, r_avg: f64, kappa: f64) -> f64 {
    (10.0 * sigma_t).min(6.0 * sigma_t + kappa * r_avg)
}

/// A validated target-position uncertainty.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Uncertainty {
    estimate: Vector2<f64>,
    cov: Matrix2<f64>,
    cov_inv: Matrix2<f64>,
    side: f64,
}

impl Uncertainty {
    /// `ẑ` (m), `M` (m², symmetric positive definite) and the side `A` (m, > 0) of the support.
    pub fn new(estimate: Vector2<f64>, cov: Matrix2<f64>, side: f64) -> Result<Self, TdoaError> {
        check_finite("estimate x", estimate.x)?;
        check_finite("estimate y", estimate.y)?;
        for (name, v) in
            [("cov xx", cov[(0, 0)]), ("cov xy", cov[(0, 1)]), ("cov yx", cov[(1, 0)]), ("cov yy", cov[(1, 1)])]
        {
            check_finite(name, v)?;
        }
        check_finite("support side", side)?;
        if side <= 0.0 {
            return Err(TdoaError::NonPositive { what: "support side".into(), value: side });
        }
        let sym = 0.5 * (cov + cov.transpose());
        let not_pd = || TdoaError::CovarianceNotPositiveDefinite { xx: cov[(0, 0)], xy: cov[(0, 1)], yy: cov[(1, 1)] };
        if (cov[(0, 1)] - cov[(1, 0)]).abs() > 1e-9 * (cov[(0, 0)].abs() + cov[(1, 1)].abs()) {
            return Err(not_pd());
        }
        let (lo, _) = sym_eigenvalues(&sym);
        if lo <= 0.0 {
            return Err(not_pd());
        }
        let cov_inv = sym.try_inverse().ok_or_else(not_pd)?;
        Ok(Self { estimate, cov: sym, cov_inv, side })
    }

    /// As [`Uncertainty::new`] with the side from eq. 36, using `σ_t = sqrt(λ_max(M))` and the mean
    /// distance `r_avg` (m) from the UAVs to `ẑ`.
    pub fn with_eq36_side(
        estimate: Vector2<f64>,
        cov: Matrix2<f64>,
        r_avg: f64,
        kappa: f64,
    ) -> Result<Self, TdoaError> {
        let probe = Self::new(estimate, cov, 1.0)?;
        let side = eq36_side(probe.sigma_t(), r_avg, kappa);
        Self::new(estimate, cov, side)
    }

    /// `ẑ`, metres.
    pub fn estimate(&self) -> Vector2<f64> {
        self.estimate
    }

    /// `M`, m².
    pub fn cov(&self) -> Matrix2<f64> {
        self.cov
    }

    /// Side `A` of the square support, metres.
    pub fn side(&self) -> f64 {
        self.side
    }

    /// `σ_t = sqrt(λ_max(M))`, metres: the largest standard deviation of the target position.
    pub fn sigma_t(&self) -> f64 {
        sym_eigenvalues(&self.cov).1.sqrt()
    }

    /// Same support and centre with another covariance `cov` (m²).
    pub fn with_cov(&self, cov: Matrix2<f64>) -> Result<Self, TdoaError> {
        Self::new(self.estimate, cov, self.side)
    }

    /// Unnormalised Gaussian weight `exp(−½ (p − ẑ)ᵀ M⁻¹ (p − ẑ))` (eq. 31 up to its constant).
    #[inline]
    pub fn density(&self, p: &Vector2<f64>) -> f64 {
        let d = p - self.estimate;
        (-0.5 * d.dot(&(self.cov_inv * d))).exp()
    }

    /// Whether `p` lies in the square support Φ (eq. 32).
    #[inline]
    pub fn contains(&self, p: &Vector2<f64>) -> bool {
        let h = 0.5 * self.side;
        (p.x - self.estimate.x).abs() <= h && (p.y - self.estimate.y).abs() <= h
    }

    /// Lower-left and upper-right corners of the support, metres.
    pub fn bounds(&self) -> (Vector2<f64>, Vector2<f64>) {
        let h = Vector2::new(0.5 * self.side, 0.5 * self.side);
        (self.estimate - h, self.estimate + h)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn estimate_arrays_are_row_major_and_round_trip() {
        let (z, m) = estimate_from_arrays(&[1.0, 2.0], &[[3.0, 4.0], [5.0, 6.0]]);
        assert_eq!((z.x, z.y, m[(0, 1)], m[(1, 0)]), (1.0, 2.0, 4.0, 5.0));
        assert_eq!(estimate_to_arrays(&z, &m), ([1.0, 2.0], [[3.0, 4.0], [5.0, 6.0]]));
    }
}
