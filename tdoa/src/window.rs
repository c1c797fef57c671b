//! The estimate of a static emitter re-linearised over the last bursts: the maximum a posteriori of a
//! Gaussian summary of the older bursts and the raw range differences of the recent ones.
//!
//! A recursive filter linearises each burst once, at the estimate of its time. While the posterior is
//! wide and bent (a few range differences at long range), that estimate is off, and the error of the
//! linearisation stays in every later mean: the filter's estimate is not the maximum a posteriori of
//! the bursts it has fused. Keeping the last bursts raw and minimising
//!
//! `C(x) = (x − x_b)ᵀ Λ_b (x − x_b) + Σ_j (d_j − h_j(x))ᵀ Q_j⁻¹ (d_j − h_j(x))`
//!
//! (Gauss–Newton, `h_j` the range differences of burst j, `Λ_b` and `x_b` the older bursts' summary in
//! information form, which may be singular or empty) re-linearises them at every step; a burst that
//! leaves the window is folded into the summary linearised at the estimate of that time, when many more
//! bursts have narrowed it ([`Information::with_burst`]).
//!
//! Pure functions over plain data.

use nalgebra::{Matrix2, Vector2};

use crate::fusion::{halving_step, measure};
use crate::{Sensors, TdoaError};

/// A Gaussian summary of bursts in information form: `Λ` (m⁻²) and `η = Λ x_b` (m⁻¹); `Λ` may be
/// singular (one range difference carries information along one direction only) or zero (nothing).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Information {
    /// `Λ`, m⁻².
    pub matrix: Matrix2<f64>,
    /// `η = Λ x_b`, m⁻¹.
    pub vector: Vector2<f64>,
}

/// One burst of the window: the geometry (with its noise) and its range differences to its first UAV.
pub type Burst<'a> = (&'a Sensors, &'a [f64]);

/// The residual `d − h(z)`, the Jacobian rows of `h` and `Q⁻¹` of one burst at `z`.
fn linearised(burst: &Burst<'_>, z: &Vector2<f64>) -> Option<(nalgebra::DVector<f64>, nalgebra::DMatrix<f64>)> {
    let (sensors, d) = burst;
    let (h, jac) = measure(sensors, z)?;
    let r = nalgebra::DVector::from_column_slice(d) - h;
    Some((r, jac))
}

/// `Jᵀ Q⁻¹ J` and `Jᵀ Q⁻¹ r` of one burst at `z`.
fn normal_terms(burst: &Burst<'_>, z: &Vector2<f64>) -> Option<(Matrix2<f64>, Vector2<f64>)> {
    let (r, jac) = linearised(burst, z)?;
    let noise = burst.0.noise();
    let m = r.len();
    let (mut a, mut b) = (Matrix2::zeros(), Vector2::zeros());
    for i in 0..m {
        for j in 0..m {
            let w = noise.q_inv(i, j);
            let (gi, gj) = (Vector2::new(jac[(i, 0)], jac[(i, 1)]), Vector2::new(jac[(j, 0)], jac[(j, 1)]));
            a += w * gi * gj.transpose();
            b += w * gi * r[j];
        }
    }
    Some((a, b))
}

/// `Σ rᵀ Q⁻¹ r` of one burst at `z` (`+∞` on a UAV).
pub(crate) fn burst_cost(burst: &Burst<'_>, z: &Vector2<f64>) -> f64 {
    let Some((r, _)) = linearised(burst, z) else { return f64::INFINITY };
    burst.0.noise().quadratic_form(r.as_slice())
}

impl Information {
    /// Nothing known.
    pub fn none() -> Self {
        Self::default()
    }

    /// This summary with `burst` folded in, linearised at `at` (metres): `Λ + JᵀQ⁻¹J` and
    /// `η + JᵀQ⁻¹(J at + d − h(at))`. `None` when `at` is on a UAV.
    pub fn with_burst(&self, burst: &Burst<'_>, at: &Vector2<f64>) -> Option<Self> {
        let (a, b) = normal_terms(burst, at)?;
        Some(Self { matrix: self.matrix + a, vector: self.vector + a * at + b })
    }

    /// `(x − x_b)ᵀ Λ (x − x_b)` up to a constant: `xᵀΛx − 2ηᵀx`.
    fn cost(&self, x: &Vector2<f64>) -> f64 {
        (x.transpose() * self.matrix * x)[(0, 0)] - 2.0 * self.vector.dot(x)
    }
}

/// The iterations of [`refit`] at most.
pub const MAX_ITERATIONS: usize = 20;

/// [`refit`] stops when a step moves the estimate less than this, metres.
pub const STEP_TOLERANCE_M: f64 = 1e-6;

/// The maximum a posteriori of `base` and the raw `bursts`, by Gauss–Newton with a halving line search
/// from `start` (metres), and the inverse of the Gauss–Newton Hessian there (m², the Laplace
/// covariance). Errors when the information is singular (too few range differences), the estimate
/// reaches a UAV, or nothing is finite.
pub fn refit(
    base: &Information,
    bursts: &[Burst<'_>],
    start: &Vector2<f64>,
) -> Result<(Vector2<f64>, Matrix2<f64>), TdoaError> {
    let singular = || TdoaError::Degenerate("the re-linearised information is singular".into());
    let on_uav = || TdoaError::Degenerate("the emitter estimate is on a UAV".into());
    let cost = |x: &Vector2<f64>| base.cost(x) + bursts.iter().map(|b| burst_cost(b, x)).sum::<f64>();
    let normal = |x: &Vector2<f64>| -> Result<(Matrix2<f64>, Vector2<f64>), TdoaError> {
        let mut a = base.matrix;
        let mut g = base.vector - base.matrix * x;
        for b in bursts {
            let (ab, gb) = normal_terms(b, x).ok_or_else(on_uav)?;
            a += ab;
            g += gb;
        }
        Ok((a, g))
    };
    let mut x = *start;
    let mut c = cost(&x);
    if !c.is_finite() {
        return Err(on_uav());
    }
    for _ in 0..MAX_ITERATIONS {
        let (a, g) = normal(&x)?;
        let step = a.cholesky().ok_or_else(singular)?.solve(&g);
        let Some((next, cc)) = halving_step(c, |alpha| x + step * alpha, cost) else { break };
        let moved = (next - x).norm();
        x = next;
        c = cc;
        if moved < STEP_TOLERANCE_M {
            break;
        }
    }
    let (a, _) = normal(&x)?;
    let cov = a.try_inverse().ok_or_else(singular)?;
    if x.iter().chain(cov.iter()).any(|v| !v.is_finite()) {
        return Err(TdoaError::Degenerate("the re-linearised estimate is not finite".into()));
    }
    Ok((x, 0.5 * (cov + cov.transpose())))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{NoiseModel, Sensors};

    fn sensors(pts: &[[f64; 2]], sigma: f64) -> Sensors {
        Sensors::new(pts, NoiseModel::uniform(pts.len(), sigma).unwrap()).unwrap()
    }

    fn exact(s: &Sensors, z: &Vector2<f64>) -> Vec<f64> {
        s.range_differences(z).as_slice().to_vec()
    }

    #[test]
    fn noise_free_bursts_refit_to_the_truth_from_far_off() {
        let z = Vector2::new(25_000.0, 15_000.0);
        let a = sensors(&[[1500.0, 500.0], [10_000.0, 1500.0], [5000.0, 8500.0]], 28.7712);
        let b = sensors(&[[3500.0, 900.0], [11_000.0, 3500.0], [4000.0, 9500.0]], 28.7712);
        let (da, db) = (exact(&a, &z), exact(&b, &z));
        let bursts = [(&a, da.as_slice()), (&b, db.as_slice())];
        let (x, cov) = refit(&Information::none(), &bursts, &(z + Vector2::new(3000.0, -2000.0))).unwrap();
        assert!((x - z).norm() < 1e-6, "{:?}", x - z);
        // The covariance is the inverse of the two bursts' Fisher information at the truth.
        let f = crate::fim::fim(&a, &z).unwrap() + crate::fim::fim(&b, &z).unwrap();
        let expected = f.try_inverse().unwrap();
        assert!((cov - expected).norm() < 1e-9 * expected.norm(), "{cov} vs {expected}");
    }

    #[test]
    fn a_burst_folded_at_the_optimum_leaves_the_optimum_and_the_hessian_in_place() {
        // Noisy differences: the summary of one burst linearised at the joint optimum, refitted with the
        // other burst raw, gives the same optimum (the gradient of the folded quadratic at it is the
        // burst's) and the same Gauss–Newton covariance.
        let z = Vector2::new(25_000.0, 15_000.0);
        let a = sensors(&[[1500.0, 500.0], [10_000.0, 1500.0], [5000.0, 8500.0], [-2000.0, 6000.0]], 28.7712);
        let b = sensors(&[[3500.0, 900.0], [11_000.0, 3500.0], [4000.0, 9500.0]], 28.7712);
        let mut da = exact(&a, &z);
        let mut db = exact(&b, &z);
        da[0] += 31.0;
        da[2] -= 17.0;
        db[1] += 40.0;
        let both = [(&a, da.as_slice()), (&b, db.as_slice())];
        let (x, cov) = refit(&Information::none(), &both, &z).unwrap();
        let folded = Information::none().with_burst(&(&a, da.as_slice()), &x).unwrap();
        let (y, cov_y) = refit(&folded, &[(&b, db.as_slice())], &z).unwrap();
        assert!((x - y).norm() < 1e-4, "{x} vs {y}");
        assert!((cov - cov_y).norm() < 1e-6 * cov.norm());
    }

    #[test]
    fn the_gradient_is_the_cost_s_by_finite_differences() {
        let z = Vector2::new(20_000.0, 12_000.0);
        let a = sensors(&[[1500.0, 500.0], [10_000.0, 1500.0], [5000.0, 8500.0]], 20.0);
        let mut d = exact(&a, &z);
        d[0] += 50.0;
        let burst = (&a, d.as_slice());
        let x = z + Vector2::new(700.0, -300.0);
        let (_, g) = normal_terms(&burst, &x).unwrap();
        let h = 1e-3;
        for k in 0..2 {
            let mut e = Vector2::zeros();
            e[k] = h;
            let fd = -(burst_cost(&burst, &(x + e)) - burst_cost(&burst, &(x - e))) / (4.0 * h);
            assert!((fd - g[k]).abs() < 1e-6 * g.norm().max(1e-12), "{k}: {fd} vs {}", g[k]);
        }
    }

    #[test]
    fn too_little_information_is_an_error_not_a_number() {
        // One range difference: a hyperbola, no point.
        let pts = [[1500.0, 500.0], [10_000.0, 1500.0], [5000.0, 8500.0]];
        let a = crate::Arrivals::new(&pts, &[0.0, 1000.0, 0.0], 0b011, &[20.0; 3], &[0.0; 3]).unwrap();
        let h = a.heard().unwrap().unwrap();
        let e = refit(&Information::none(), &[(&h.sensors, h.diffs.as_slice())], &Vector2::new(20_000.0, 12_000.0));
        assert!(matches!(e, Err(TdoaError::Degenerate(_))), "{e:?}");
    }
}
