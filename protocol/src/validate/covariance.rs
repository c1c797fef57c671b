//! Whether a covariance received in a message is one the planner can take: symmetric positive
//! definite within the floats' limits, or positive semi-definite for a bias's covariance.

/// Relative tolerance on `|c01 − c10|` for a covariance to count as symmetric.
pub const SYMMETRY_TOLERANCE: f64 = 1e-9;

/// The smallest eigenvalue an estimate's covariance may have, m² (`tdoa::support::MIN_EIGENVALUE_M2`): the
/// floats' limit, not a physical one; at or above it the planner inverts the covariance.
pub const MIN_EIGENVALUE_M2: f64 = 1e-300;

/// Whether a finite 2×2 matrix is symmetric (within [`SYMMETRY_TOLERANCE`]) positive definite, as the
/// planner takes it (`tdoa::support::is_positive_definite`): positive variances with a finite sum, a
/// correlation `c01 / (√c00 √c11)` below 1 in magnitude, and the smallest eigenvalue at least
/// [`MIN_EIGENVALUE_M2`] (a covariance of σ 1e-155 m would have no inverse in floating point, and the
/// planner would refuse the step at every replay).
///
/// Overflow-safe: no determinant is formed (the smallest eigenvalue is `c00 c11 (1 − ρ²) / λ_max`).
pub fn is_symmetric_positive_definite(c: &[[f64; 2]; 2]) -> bool {
    let Some((a, b, d)) = symmetric_parts(c) else { return false };
    if !(a > 0.0 && d > 0.0 && (a + d).is_finite()) {
        return false;
    }
    let rho = b / a.sqrt() / d.sqrt();
    let lambda_max = 0.5 * (a + d) + (0.5 * (a - d)).hypot(b);
    rho.abs() < 1.0 && (a / lambda_max) * d * ((1.0 - rho) * (1.0 + rho)) >= MIN_EIGENVALUE_M2
}

/// Whether a finite 2×2 matrix is symmetric (within [`SYMMETRY_TOLERANCE`]) positive semi-definite (0
/// allowed): variances ≥ 0 and `|c01| ≤ √c00 √c11` within the same relative tolerance (a rank-one
/// `σ² s sᵀ` rounds either way).
pub fn is_positive_semi_definite(c: &[[f64; 2]; 2]) -> bool {
    let Some((a, b, d)) = symmetric_parts(c) else { return false };
    a >= 0.0 && d >= 0.0 && b.abs() <= a.sqrt() * d.sqrt() * (1.0 + SYMMETRY_TOLERANCE)
}

/// `(c00, (c01 + c10)/2, c11)` of a 2×2 matrix symmetric within [`SYMMETRY_TOLERANCE`] (relative to its
/// largest entry), `None` otherwise.
fn symmetric_parts(c: &[[f64; 2]; 2]) -> Option<(f64, f64, f64)> {
    let scale = c[0][0].abs().max(c[1][1].abs()).max(c[0][1].abs()).max(c[1][0].abs());
    let symmetric = (c[0][1] - c[1][0]).abs() <= SYMMETRY_TOLERANCE * scale;
    symmetric.then_some((c[0][0], 0.5 * (c[0][1] + c[1][0]), c[1][1]))
}
