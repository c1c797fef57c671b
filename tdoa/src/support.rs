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

/// The smallest eigenvalue a covariance may have, m²: the floats' limit, not a physical one (a σ of
/// 1e-150 m); at or above it `M⁻¹` is finite.
pub const MIN_EIGENVALUE_M2: f64 = 1e-300;

/// `M⁻¹` of a covariance `m` that [`is_positive_definite`], 1/m²; `None` for any other. Where the
/// determinant is a normal float, the direct inverse (bit for bit nalgebra's); where it under- or
/// overflows (σ of 1e-160 m or 1e160 m), from the correlation form `M = D R D`, `D = diag(√m00, √m11)`:
/// `M⁻¹ = D⁻¹ R⁻¹ D⁻¹`, no product of two variances formed.
pub fn covariance_inverse(m: &Matrix2<f64>) -> Option<Matrix2<f64>> {
    if !is_positive_definite(m) {
        return None;
    }
    let finite = |inv: &Matrix2<f64>| inv.iter().all(|v| v.is_finite());
    if let Some(inv) = m.determinant().is_normal().then(|| m.try_inverse()).flatten().filter(finite) {
        return Some(inv);
    }
    let (a, b, d) = (m[(0, 0)], 0.5 * (m[(0, 1)] + m[(1, 0)]), m[(1, 1)]);
    let (sa, sd) = (a.sqrt(), d.sqrt());
    let rho = b / sa / sd;
    let k = (1.0 - rho) * (1.0 + rho);
    let off = -rho / sa / sd / k;
    Some(Matrix2::new(1.0 / a / k, off, off, 1.0 / d / k)).filter(finite)
}

/// Whether the symmetric 2×2 `m` (m²) is a covariance the planner takes, as the wire's messages test it
/// (`protocol::validate::is_symmetric_positive_definite`): positive variances with a finite sum, a
/// correlation `m01 / (√m00 √m11)` below 1 in magnitude, and the smallest eigenvalue at least
/// [`MIN_EIGENVALUE_M2`] — computed as `m00 m11 (1 − ρ²) / λ_max` in an order that neither over- nor
/// underflows, not as a difference of eigenvalues (which cancels beyond a condition number of 1e16).
pub fn is_positive_definite(m: &Matrix2<f64>) -> bool {
    let (a, b, d) = (m[(0, 0)], 0.5 * (m[(0, 1)] + m[(1, 0)]), m[(1, 1)]);
    if !(a > 0.0 && d > 0.0 && (a + d).is_finite()) {
        return false;
    }
    let rho = b / a.sqrt() / d.sqrt();
    let lambda_max = 0.5 * (a + d) + (0.5 * (a - d)).hypot(b);
    rho.abs() < 1.0 && (a / lambda_max) * d * ((1.0 - rho) * (1.0 + rho)) >= MIN_EIGENVALUE_M2
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
        if !is_positive_definite(&sym) {
            return Err(not_pd());
        }
        let cov_inv = covariance_inverse(&sym).ok_or_else(not_pd)?;
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

    /// The direct inverse bit for bit where the determinant is a normal float; from the correlation form
    /// where it under- or overflows, with `M M⁻¹ = I` to rounding; nothing below the smallest eigenvalue
    /// or for an infinite variance.
    #[test]
    fn covariance_inverse_reaches_the_edges_of_the_floats() {
        let m = Matrix2::new(4.0e4, 1.2e4, 1.2e4, 9.0e4);
        assert_eq!(covariance_inverse(&m), m.try_inverse());
        for scale in [1e-300, 1e-200, 1e-160, 1e160, 1e200, 1e300] {
            let m = Matrix2::new(4.0, 1.2, 1.2, 9.0) * scale;
            let inv = covariance_inverse(&m).unwrap_or_else(|| panic!("{scale:e}"));
            assert!((m * inv - Matrix2::identity()).norm() < 1e-12, "{scale:e}");
        }
        assert_eq!(covariance_inverse(&(Matrix2::identity() * 1e-310)), None);
        assert_eq!(covariance_inverse(&Matrix2::new(f64::INFINITY, 0.0, 0.0, 1.0)), None);
        // Every covariance the wire's test takes, over the floats' whole range of variances and
        // correlations, makes the uncertainty the planner builds.
        let mut taken = 0;
        for ea in (-307..=307).step_by(11) {
            for ed in (-307..=307).step_by(13) {
                for rho in [-0.999_999_9, -0.5, 0.0, 0.3, 0.999_999_9] {
                    let (a, d) = (10f64.powi(ea), 10f64.powi(ed));
                    let b = rho * a.sqrt() * d.sqrt();
                    let m = Matrix2::new(a, b, b, d);
                    if is_positive_definite(&m) {
                        taken += 1;
                        let u = Uncertainty::new(Vector2::zeros(), m, 1.0);
                        assert!(u.is_ok(), "{m:?}: {u:?}");
                    }
                }
            }
        }
        assert!(taken > 10_000, "{taken}");
    }
}
