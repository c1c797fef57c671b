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
//!   `B = diag(r_i)`), the second exploiting `r₀² = (x−x₀)² + (y−y₀)²`. Where the first step's columns
//!   are dependent (a rectangle with the emitter on an axis of symmetry), the three-UAV solution over
//!   all equations (`dependent_first_step`).

// Negated comparisons are deliberate here: `!(a > b)` also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use nalgebra::{DMatrix, DVector, Matrix2, Matrix3, Rotation2, Vector2, Vector3};

use crate::fim::crlb;
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
    if n < 3 {
        return Err(TdoaError::UavCount { got: n, min: 3, max: crate::MAX_UAVS });
    }
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
    let candidates = on_the_circle(sensors, d, a_inv * h, a_inv * b);
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

/// The emitter positions `w₀ + z'` with `z' = a − c·r₀` and `|z'| = r₀` (eqs. 16–19: the position linear
/// in the reference range, which solves a quadratic), keeping the roots that give no negative range
/// for the range differences `d` (at most two, distinct).
fn on_the_circle(sensors: &Sensors, d: &[f64], a: Vector2<f64>, c: Vector2<f64>) -> Vec<Vector2<f64>> {
    let w = sensors.positions();
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
    candidates
}

/// Least squares `min |A x − b|` by SVD after column equilibration; returns x and `(AᵀA)⁻¹`, or an
/// error when A is rank deficient (reciprocal condition below 1e-12).
fn lstsq(a: DMatrix<f64>, b: &DVector<f64>, what: &str) -> Result<(DVector<f64>, DMatrix<f64>), TdoaError> {
    let n = a.ncols();
    let scale = DVector::from_fn(n, |j, _| 1.0 / a.column(j).norm().max(f64::MIN_POSITIVE));
    let a_s = a * DMatrix::from_diagonal(&scale);
    let svd = a_s.svd(true, true);
    let (smax, smin) = (svd.singular_values.max(), svd.singular_values.min());
    if !(smin > 1e-12 * smax) {
        return Err(TdoaError::Degenerate(format!("{what} is rank deficient")));
    }
    let x_s = svd.solve(b, 0.0).map_err(|e| TdoaError::Degenerate(format!("{what}: {e}")))?;
    let v_t = svd.v_t.as_ref().ok_or_else(|| TdoaError::Degenerate(format!("{what}: no SVD")))?;
    let inv_s2 = DMatrix::from_diagonal(&svd.singular_values.map(|s| 1.0 / (s * s)));
    let d = DMatrix::from_diagonal(&scale);
    let cov = &d * v_t.transpose() * inv_s2 * v_t * &d;
    Ok((x_s.component_mul(&scale), cov))
}

fn chan_wls(sensors: &Sensors, d: &RangeDiffs) -> Result<ChanSolution, TdoaError> {
    let w = sensors.positions();
    let spread = scale_of(sensors);
    let far = w.iter().max_by(|a, b| (*a - w[0]).norm().total_cmp(&(*b - w[0]).norm())).map(|p| p - w[0]);
    if let Some(dir) = far.map(|v| v / v.norm()) {
        let off = w.iter().map(|p| ((p - w[0]).x * dir.y - (p - w[0]).y * dir.x).abs()).fold(0.0, f64::max);
        if off <= 1e-9 * spread {
            return Err(TdoaError::Degenerate("all UAVs lie on one line; TDOA cannot fix the emitter".into()));
        }
    }
    let d = d.as_slice();
    let m = d.len();
    let q_chol =
        sensors.noise().q().cholesky().ok_or_else(|| TdoaError::Degenerate("Q is not positive definite".into()))?;
    let rel = relative_positions(sensors);
    let (g, h) = first_step_system(&rel, d);
    // Step 1: whiten the error ψ ≈ −2 B n (cov 4 B Q B) with C⁻¹ B⁻¹, Q = C Cᵀ. First B = I (W = Q⁻¹),
    // then twice with the estimated ranges B = diag(r_i).
    let step1 = |ranges: &[f64]| -> Result<(Vector3<f64>, DMatrix<f64>), TdoaError> {
        let b_inv = DMatrix::from_fn(m, m, |i, j| if i == j { 1.0 / ranges[i] } else { 0.0 });
        let a = q_chol.l().solve_lower_triangular(&(&b_inv * &g)).expect("Cholesky factor is invertible");
        let rhs = q_chol.l().solve_lower_triangular(&(&b_inv * &h)).expect("Cholesky factor is invertible");
        let (theta, _) = lstsq(a.clone(), &rhs, "Chan's first step")?;
        Ok((Vector3::new(theta[0], theta[1], theta[2]), a))
    };
    let mut ranges = vec![1.0; m];
    // A first step whose three columns are dependent (the UAVs are not collinear, checked above): the
    // position linear in r₀, as with three UAVs.
    let rank_deficient = |e: TdoaError| match e {
        TdoaError::Degenerate(_) => dependent_first_step(sensors, d, &g, &h),
        other => Err(other),
    };
    let (mut theta, mut a1) = match step1(&ranges) {
        Ok(first) => first,
        Err(e) => return rank_deficient(e),
    };
    for _ in 0..2 {
        let z1 = Vector2::new(theta[0], theta[1]);
        for (i, r) in ranges.iter_mut().enumerate() {
            *r = (z1 - rel[i]).norm().max(1e-9);
        }
        (theta, a1) = match step1(&ranges) {
            Ok(next) => next,
            Err(e) => return rank_deficient(e),
        };
    }
    let e = Vector2::new(theta[0], theta[1]);
    let r = e.norm();
    let fallback = |z: Vector2<f64>| -> Result<ChanSolution, TdoaError> {
        let position = w[0] + z;
        let covariance = covariance_at(sensors, &position)?;
        Ok(ChanSolution { position, covariance, ambiguous: false, candidates: vec![position] })
    };
    if !(r > 1e-9 * spread) || theta[2] <= 0.0 {
        return fallback(e);
    }
    // Step 2, in the frame where e lies on the diagonal: h₂ = G₂ θ₂ + ψ₂ with
    // cov ψ₂ = (2B₂) cov(θ₁) (2B₂) and cov(θ₁) = 4 (A₁ᵀA₁)⁻¹, so ψ₂ is whitened by M = A₁ Tᵀ (2B₂)⁻¹ / 2.
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
    let er = rot * e;
    let b2_inv = Matrix3::from_diagonal(&Vector3::new(0.5 / er.x, 0.5 / er.y, 0.5 / theta[2]));
    let tt = DMatrix::from_fn(3, 3, |i, j| t[(j, i)]);
    let whiten = &a1 * tt * DMatrix::from_fn(3, 3, |i, j| b2_inv[(i, j)]) * 0.5;
    let g2 = DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
    let h2 = DVector::from_row_slice(&[er.x * er.x, er.y * er.y, theta[2] * theta[2]]);
    let Ok((theta2, cov2)) = lstsq(&whiten * g2, &(&whiten * h2), "Chan's second step") else {
        return fallback(e);
    };
    if !(theta2[0] > 0.0 && theta2[1] > 0.0) {
        return fallback(e);
    }
    let zr = Vector2::new(theta2[0].sqrt(), theta2[1].sqrt());
    let dinv = Matrix2::new(0.5 / zr.x, 0.0, 0.0, 0.5 / zr.y);
    let cov_zr = dinv * Matrix2::from_fn(|i, j| cov2[(i, j)]) * dinv;
    let position = w[0] + rot.inverse() * zr;
    let rm = rot.matrix();
    let covariance = rm.transpose() * cov_zr * rm;
    if !(position.x.is_finite() && position.y.is_finite() && covariance.iter().all(|v| v.is_finite())) {
        return fallback(e);
    }
    Ok(ChanSolution { position, covariance, ambiguous: false, candidates: vec![position] })
}

/// Chan's first step when its three columns `[2(wᵢ − w₀), 2dᵢ]` are dependent although the UAVs are not
/// collinear: r₀ then cannot be told from the position by the linear system. It happens exactly where
/// the range differences are a combination of the baselines' — four UAVs on a parallelogram with
/// `r₀ + r₃ = r₁ + r₂`, e.g. a square with the emitter on one of its axes of symmetry — and there the
/// emitter is still fixed. As with three UAVs (eqs. 16–19): the position columns alone give
/// `z' = a − c·r₀` by least squares (weighted by `Q⁻¹`), `|z'| = r₀` gives at most two roots, and of
/// those the one whose range differences fit `d` best (in `Q`'s metric) is the estimate, with the
/// covariance `F⁻¹(ẑ)` of the three-UAV case.
fn dependent_first_step(
    sensors: &Sensors,
    d: &[f64],
    g: &DMatrix<f64>,
    h: &DVector<f64>,
) -> Result<ChanSolution, TdoaError> {
    let q_chol =
        sensors.noise().q().cholesky().ok_or_else(|| TdoaError::Degenerate("Q is not positive definite".into()))?;
    let whiten = |x: DMatrix<f64>| q_chol.l().solve_lower_triangular(&x).expect("Cholesky factor is invertible");
    let positions = whiten(g.columns(0, 2).into_owned());
    let rhs = whiten(DMatrix::from_fn(h.len(), 2, |i, j| if j == 0 { h[i] } else { g[(i, 2)] }));
    let (a, _) = lstsq(positions.clone(), &rhs.column(0).into_owned(), "the UAVs' baselines")?;
    let (c, _) = lstsq(positions, &rhs.column(1).into_owned(), "the UAVs' baselines")?;
    let candidates = on_the_circle(sensors, d, Vector2::new(a[0], a[1]), Vector2::new(c[0], c[1]));
    let best = candidates.iter().map(|z| (misfit(sensors, d, z), *z)).min_by(|a, b| a.0.total_cmp(&b.0));
    let (_, position) = best.ok_or_else(|| {
        TdoaError::NoSolution("no emitter position gives non-negative ranges for these range differences".into())
    })?;
    let covariance = covariance_at(sensors, &position)?;
    Ok(ChanSolution { position, covariance, ambiguous: false, candidates: vec![position] })
}

/// The maximum-likelihood emitter of one snapshot: for N ≥ 4, Gauss–Newton on the range differences
/// ([`crate::window::refit`]) from Chan's estimate and from the first step's position columns alone
/// (`dependent_first_step`: the three-UAV solution over all equations), the best fit of those and
/// Chan's own — with `F⁻¹(ẑ)` as its covariance, or Chan's `M` where Chan's estimate fits best; for
/// N = 3 (exactly determined) Chan's roots, which are the likelihood's maxima.
///
/// Chan's two-step WLS is efficient at small noise, but not near the set where its first step is rank
/// deficient: four UAVs on a rectangle with the emitter near its centre or on an axis of symmetry (a
/// 10 km square, σ = 28.8 m: RMSE 57× the CRLB at the centre, 120–200× on an axis 25 km out). For one
/// snapshot with no outlier handling of its own (`uavloc locate`); an estimator that finds reflected
/// arrivals by their residuals starts from [`chan`], whose failed estimate exposes an outlier that the
/// maximum likelihood would absorb.
pub fn maximum_likelihood(
    sensors: &Sensors,
    d: &RangeDiffs,
    prior: Option<Vector2<f64>>,
) -> Result<ChanSolution, TdoaError> {
    let solution = chan(sensors, d, prior)?;
    if sensors.len() < 4 {
        return Ok(solution);
    }
    let d = d.as_slice();
    let (g, h) = first_step_system(&relative_positions(sensors), d);
    let mut starts = vec![solution.position];
    if let Ok(dependent) = dependent_first_step(sensors, d, &g, &h) {
        starts.push(dependent.position);
    }
    let best = starts
        .iter()
        .filter_map(|start| crate::window::refit(&crate::window::Information::none(), &[(sensors, d)], start).ok())
        .map(|(position, _)| (misfit(sensors, d, &position), position))
        .min_by(|a, b| a.0.total_cmp(&b.0));
    match best {
        Some((fit, position)) if fit < misfit(sensors, d, &solution.position) => {
            let covariance = covariance_at(sensors, &position)?;
            Ok(ChanSolution { position, covariance, ambiguous: false, candidates: vec![position] })
        }
        _ => Ok(solution),
    }
}

/// The UAVs' positions relative to UAV0, `wᵢ − w₀` for i ≥ 1, metres.
fn relative_positions(sensors: &Sensors) -> Vec<Vector2<f64>> {
    let w = sensors.positions();
    w[1..].iter().map(|wi| wi - w[0]).collect()
}

/// Chan's first-step system `G θ = h`, `θ = (x', y', r₀)` relative to UAV0: rows `[2(wᵢ − w₀), 2dᵢ]`,
/// `hᵢ = |wᵢ − w₀|² − dᵢ²`, from `rel` = [`relative_positions`].
fn first_step_system(rel: &[Vector2<f64>], d: &[f64]) -> (DMatrix<f64>, DVector<f64>) {
    let g = DMatrix::from_fn(d.len(), 3, |i, j| 2.0 * if j < 2 { rel[i][j] } else { d[i] });
    let h = DVector::from_fn(d.len(), |i, _| rel[i].norm_squared() - d[i] * d[i]);
    (g, h)
}

/// How badly the emitter at `z` explains the range differences `d`: `rᵀ Q⁻¹ r` of their residuals
/// (−2 × the log-likelihood, up to a constant; `+∞` on a UAV) — the cost of one burst of the window.
fn misfit(sensors: &Sensors, d: &[f64], z: &Vector2<f64>) -> f64 {
    crate::window::burst_cost(&(sensors, d), z)
}
