//! Chan's closed-form TDOA estimator (paper Section 2, eqs. 10–30; Chan & Ho 1994) with the covariance
//! of its estimate — the uncertainty `M` that the planner uses.
//!
//! Units: metres, m². Everything is computed relative to the reference UAV `w_0`, so the estimator is
//! translation-equivariant exactly; its second step runs in a frame rotated so that the first-step
//! estimate lies on the diagonal, which makes it rotation-equivariant and keeps the step well defined
//! when the emitter is level with `w_0` on an axis.
//!
//! - N = 3: the first step has 2 equations in (x, y, r₀); x and y are linear in r₀ and r₀ solves a
//!   quadratic. Roots that give a negative range are dropped; if two remain, a prior picks the nearer,
//!   otherwise the result is flagged ambiguous with both candidates. Its covariance is `F⁻¹(ẑ)`, which
//!   is exact to first order for an exactly determined system.
//! - N ≥ 4: two-step WLS, the first step re-weighted with the estimated ranges (`W = (B Q B)⁻¹`,
//!   `B = diag(r_i)`), the second exploiting `r₀² = (x−x₀)² + (y−y₀)²`.

use nalgebra::{DMatrix, DVector, Matrix2, Matrix3, Rotation2, Vector2, Vector3};

use crate::fim::{crlb, inverse_spd};
use crate::{RangeDiffs, Sensors, TdoaError};

/// The result of one Chan solve.
#[derive(Debug, Clone, PartialEq)]
pub struct ChanSolution {
    /// Estimated emitter position ẑ, metres.
    pub position: Vector2<f64>,
    /// Covariance of ẑ, m² (the planner's `M`).
    pub covariance: Matrix2<f64>,
    /// Two physically valid solutions remained and no prior was given to choose between them.
    pub ambiguous: bool,
    /// All physically valid solutions (one, or two when ambiguous or resolved by the prior).
    pub candidates: Vec<Vector2<f64>>,
}

/// Solves for the emitter from range differences `d` (`d_i = r_i − r_0`, metres). `prior`, if given,
/// resolves the two-root ambiguity of the 3-UAV case (the root nearer to it wins).
pub fn chan(sensors: &Sensors, d: &RangeDiffs, prior: Option<Vector2<f64>>) -> Result<ChanSolution, TdoaError> {
    let n = sensors.len();
    if d.as_slice().len() != n - 1 {
        return Err(TdoaError::LengthMismatch {
            what: "range differences".into(),
            expected: n - 1,
            got: d.as_slice().len(),
        });
    }
    if let Some(p) = prior {
        crate::geometry::check_finite("prior x", p.x)?;
        crate::geometry::check_finite("prior y", p.y)?;
    }
    if n == 3 { chan3(sensors, d, prior) } else { chan_wls(sensors, d) }
}

fn scale_of(sensors: &Sensors) -> f64 {
    let w0 = sensors.positions()[0];
    sensors.positions().iter().map(|w| (w - w0).norm()).fold(0.0, f64::max)
}

fn covariance_at(sensors: &Sensors, z: &Vector2<f64>) -> Result<Matrix2<f64>, TdoaError> {
    crlb(sensors, z).map(|c| c.bound).map_err(|e| match e {
        TdoaError::Degenerate(msg) => TdoaError::Degenerate(format!("at the estimate ({:.1}, {:.1}): {msg}", z.x, z.y)),
        other => other,
    })
}

fn chan3(sensors: &Sensors, d: &RangeDiffs, prior: Option<Vector2<f64>>) -> Result<ChanSolution, TdoaError> {
    let w = sensors.positions();
    let d = d.as_slice();
    let w1 = w[1] - w[0];
    let w2 = w[2] - w[0];
    let a_mat = Matrix2::new(2.0 * w1.x, 2.0 * w1.y, 2.0 * w2.x, 2.0 * w2.y);
    let det = a_mat.determinant();
    if det.abs() <= 1e-9 * 4.0 * w1.norm() * w2.norm() {
        return Err(TdoaError::Degenerate("the 3 UAVs are collinear; TDOA cannot fix the emitter".into()));
    }
    let a_inv = a_mat.try_inverse().ok_or_else(|| TdoaError::Degenerate("the 3 UAVs are collinear".into()))?;
    let h = Vector2::new(w1.norm_squared() - d[0] * d[0], w2.norm_squared() - d[1] * d[1]);
    let b = Vector2::new(2.0 * d[0], 2.0 * d[1]);
    // z' = a − c r0 with |z'| = r0.
    let a = a_inv * h;
    let c = a_inv * b;
    let qa = c.norm_squared() - 1.0;
    let qb = -2.0 * a.dot(&c);
    let qc = a.norm_squared();
    let mut roots: Vec<f64> = Vec::with_capacity(2);
    if qa.abs() < 1e-12 {
        if qb.abs() > 0.0 {
            roots.push(-qc / qb);
        }
    } else {
        let disc = qb * qb - 4.0 * qa * qc;
        if disc < 0.0 {
            // Noise pushed the hyperbolas apart: take the closest real point (the vertex).
            roots.push(-qb / (2.0 * qa));
        } else {
            let q = -0.5 * (qb + qb.signum() * disc.sqrt());
            roots.push(q / qa);
            if q != 0.0 {
                roots.push(qc / q);
            }
        }
    }
    let tol = 1e-9 * scale_of(sensors);
    let mut candidates: Vec<Vector2<f64>> = Vec::with_capacity(2);
    for r0 in roots {
        let physical = r0.is_finite() && r0 >= -tol && d.iter().all(|di| r0 + di >= -tol);
        if physical {
            let z = w[0] + a - c * r0;
            if candidates.iter().all(|p| (p - z).norm() > 1e-6 * scale_of(sensors).max(1.0)) {
                candidates.push(z);
            }
        }
    }
    let (position, ambiguous) = match (candidates.len(), prior) {
        (0, _) => {
            return Err(TdoaError::NoSolution(
                "no emitter position gives non-negative ranges for these range differences".into(),
            ));
        }
        (1, _) => (candidates[0], false),
        (_, Some(p)) => {
            let best = if (candidates[0] - p).norm() <= (candidates[1] - p).norm() { 0 } else { 1 };
            (candidates[best], false)
        }
        (_, None) => (candidates[0], true),
    };
    let covariance = covariance_at(sensors, &position)?;
    Ok(ChanSolution { position, covariance, ambiguous, candidates })
}

fn chan_wls(sensors: &Sensors, d: &RangeDiffs) -> Result<ChanSolution, TdoaError> {
    let w = sensors.positions();
    let d = d.as_slice();
    let m = d.len();
    let q = sensors.noise().q();
    let q_inv = q.clone().try_inverse().ok_or_else(|| TdoaError::Degenerate("Q is singular".into()))?;
    let rel: Vec<Vector2<f64>> = w[1..].iter().map(|wi| wi - w[0]).collect();
    let g = DMatrix::from_fn(m, 3, |i, j| 2.0 * if j < 2 { rel[i][j] } else { d[i] });
    let h = DVector::from_fn(m, |i, _| rel[i].norm_squared() - d[i] * d[i]);
    let solve = |weight: &DMatrix<f64>| -> Result<(Vector3<f64>, Matrix3<f64>), TdoaError> {
        let gtw = g.transpose() * weight;
        let normal = &gtw * &g;
        let normal3 = Matrix3::from_fn(|i, j| normal[(i, j)]);
        let rcond = {
            let e = normal3.symmetric_eigenvalues();
            e.min() / e.max()
        };
        if !(rcond > 1e-14) {
            return Err(TdoaError::Degenerate("the UAVs are collinear; Chan's first step is rank deficient".into()));
        }
        let inv = normal3.try_inverse().ok_or_else(|| TdoaError::Degenerate("Chan's first step is singular".into()))?;
        let rhs = &gtw * &h;
        Ok((inv * Vector3::new(rhs[0], rhs[1], rhs[2]), inv))
    };
    // Step 1: first with W = Q⁻¹, then twice re-weighted with the estimated ranges.
    let (mut theta, mut inv) = solve(&q_inv)?;
    for _ in 0..2 {
        let z1 = Vector2::new(theta[0], theta[1]);
        let b_inv = DMatrix::from_fn(m, m, |i, j| if i == j { 1.0 / (z1 - rel[i]).norm().max(1e-9) } else { 0.0 });
        let weight = &b_inv * &q_inv * &b_inv;
        (theta, inv) = solve(&weight)?;
    }
    // cov(θ₁) = (Gᵀ (4BQB)⁻¹ G)⁻¹ = 4 (Gᵀ W G)⁻¹.
    let cov1 = inv * 4.0;
    let e = Vector2::new(theta[0], theta[1]);
    let r = e.norm();
    let step1 = |z: Vector2<f64>| -> Result<ChanSolution, TdoaError> {
        let position = w[0] + z;
        let covariance = covariance_at(sensors, &position)?;
        Ok(ChanSolution { position, covariance, ambiguous: false, candidates: vec![position] })
    };
    if !(r > 1e-9 * scale_of(sensors)) || theta[2] <= 0.0 {
        return step1(e);
    }
    // Step 2 in the frame where e lies on the diagonal.
    let rot = Rotation2::new(std::f64::consts::FRAC_PI_4 - e.y.atan2(e.x));
    let t = Matrix3::new(
        rot[(0, 0)],
        rot[(0, 1)],
        0.0, //
        rot[(1, 0)],
        rot[(1, 1)],
        0.0, //
        0.0,
        0.0,
        1.0,
    );
    let cov_t = t * cov1 * t.transpose();
    let er = rot * e;
    let b2 = Matrix3::from_diagonal(&Vector3::new(er.x, er.y, theta[2]));
    let psi2 = b2 * cov_t * b2 * 4.0;
    let g2 = nalgebra::Matrix3x2::new(1.0, 0.0, 0.0, 1.0, 1.0, 1.0);
    let h2 = Vector3::new(er.x * er.x, er.y * er.y, theta[2] * theta[2]);
    let Some(w2) = psi2.try_inverse() else { return step1(e) };
    let normal2 = g2.transpose() * w2 * g2;
    let Some(cov2) = inverse_spd(&Matrix2::from_fn(|i, j| 0.5 * (normal2[(i, j)] + normal2[(j, i)]))) else {
        return step1(e);
    };
    let theta2 = cov2 * (g2.transpose() * w2 * h2);
    if !(theta2.x > 0.0 && theta2.y > 0.0) {
        return step1(e);
    }
    let zr = Vector2::new(theta2.x.sqrt(), theta2.y.sqrt());
    let dinv = Matrix2::new(0.5 / zr.x, 0.0, 0.0, 0.5 / zr.y);
    let cov_zr = dinv * cov2 * dinv;
    let position = w[0] + rot.inverse() * zr;
    let rm = rot.matrix();
    let covariance = rm.transpose() * cov_zr * rm;
    if !(position.x.is_finite() && position.y.is_finite() && covariance.iter().all(|v| v.is_finite())) {
        return step1(e);
    }
    Ok(ChanSolution { position, covariance, ambiguous: false, candidates: vec![position] })
}
