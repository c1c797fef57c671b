//! The linearisation error of the range differences over a Gaussian cloud of emitter positions: the
//! second-order term of the expansion of `h` about `z`, for `δ ~ N(0, P)`,
//!
//! ```text
//! h_i(z + δ) ≈ h_i(z) + H_i δ + ½ δᵀ ∇²h_i δ
//! Cov(½ δᵀ∇²h_i δ, ½ δᵀ∇²h_j δ) = ½ tr(∇²h_i P ∇²h_j P)        (Gaussian fourth moments)
//! ∇²h_i = (I − e_i e_iᵀ)/r_i − (I − e₀e₀ᵀ)/r₀
//! ```
//!
//! with `e_i` the unit vector from UAV i to `z` and `r_i` its range. The update of a single range
//! difference counts it as noise ([`crate::fusion`]). Units: metres, m².

use nalgebra::{DMatrix, Matrix2, Vector2};

use crate::Sensors;
use crate::fim::Rays;

/// The second-order term `½ tr(∇²h_i P ∇²h_j P)` (m², (N−1)×(N−1)) of the range differences measured by
/// `sensors` about the position `z` with position covariance `p`: the covariance of what the
/// linearisation at `z` leaves out over `N(z, p)` (module docs). `None` when `z` is on a UAV.
pub fn linearisation_noise(sensors: &Sensors, z: &Vector2<f64>, p: &Matrix2<f64>) -> Option<DMatrix<f64>> {
    let rays = Rays::new(sensors, z).filter(|rays| rays.r[..rays.n].iter().all(|r| r.is_finite()))?;
    let h0 = rays.range_hessian(0);
    let hp: Vec<Matrix2<f64>> = (1..rays.n).map(|i| (rays.range_hessian(i) - h0) * p).collect();
    let m = hp.len();
    Some(DMatrix::from_fn(m, m, |i, j| 0.5 * (hp[i] * hp[j]).trace()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::NoiseModel;
    use crate::fusion::measure;
    use crate::rng::{Purpose, stream};
    use nalgebra::DVector;

    fn sensors(pts: &[[f64; 2]]) -> Sensors {
        Sensors::new(pts, NoiseModel::uniform(pts.len(), 28.7712).unwrap()).unwrap()
    }

    /// `½ tr(∇²h P ∇²h P)` is the covariance of the quadratic remainder `h(z + δ) − h(z) − H δ` over
    /// `δ ~ N(0, P)`: Monte Carlo with a prior small beside the ranges (third order negligible), two
    /// differences (the cross term too); and the Hessian inside it by central differences of `H`.
    #[test]
    fn the_linearisation_noise_is_the_variance_of_the_quadratic_remainder() {
        let s = sensors(&[[1500.0, 500.0], [10_000.0, 1500.0], [5000.0, 8500.0]]);
        let z = Vector2::new(25_000.0, 15_000.0);
        let p = Matrix2::new(9e5, 3e5, 3e5, 4e5);
        let want = linearisation_noise(&s, &z, &p).unwrap();
        let (h0, j0) = measure(&s, &z).unwrap();
        let l = p.cholesky().unwrap().l();
        let mut rng = stream(5, 0, Purpose::MeasurementNoise);
        let normal = rand_distr::StandardNormal;
        let n = 200_000;
        let (mut sum, mut sum2) = (DVector::<f64>::zeros(2), DMatrix::<f64>::zeros(2, 2));
        for _ in 0..n {
            let u = Vector2::new(
                rand_distr::Distribution::<f64>::sample(&normal, &mut rng),
                rand_distr::Distribution::<f64>::sample(&normal, &mut rng),
            );
            let delta = l * u;
            let (h, _) = measure(&s, &(z + delta)).unwrap();
            let r = h - &h0 - &j0 * DVector::from_column_slice(delta.as_slice());
            sum += &r;
            sum2 += &r * r.transpose();
        }
        let mean = &sum / n as f64;
        let cov = &sum2 / n as f64 - &mean * mean.transpose();
        for i in 0..2 {
            for j in 0..2 {
                let scale = (want[(i, i)] * want[(j, j)]).sqrt();
                assert!(
                    (cov[(i, j)] - want[(i, j)]).abs() < 0.05 * scale,
                    "({i},{j}): {} vs {}",
                    cov[(i, j)],
                    want[(i, j)]
                );
            }
        }
        // The Hessian of h_1 by central differences of its gradient (u_1 − u_0).
        let grad = |x: Vector2<f64>| {
            let (_, j) = measure(&s, &x).unwrap();
            Vector2::new(j[(0, 0)], j[(0, 1)])
        };
        let e = 1.0;
        let fd = Matrix2::from_columns(&[
            (grad(z + Vector2::new(e, 0.0)) - grad(z - Vector2::new(e, 0.0))) / (2.0 * e),
            (grad(z + Vector2::new(0.0, e)) - grad(z - Vector2::new(0.0, e))) / (2.0 * e),
        ]);
        let rays = Rays::new(&s, &z).unwrap();
        let analytic = rays.range_hessian(1) - rays.range_hessian(0);
        assert!((fd - analytic).norm() < 1e-6 * analytic.norm(), "{fd} vs {analytic}");
        let one = Sensors::heard(&[[1500.0, 500.0], [10_000.0, 1500.0]], NoiseModel::heard(&[28.7712; 2]).unwrap());
        let one = one.unwrap();
        let r1 = linearisation_noise(&one, &z, &p).unwrap();
        assert!((r1[(0, 0)] - 0.5 * (analytic * p * analytic * p).trace()).abs() < 1e-9 * r1[(0, 0)]);
    }
}
