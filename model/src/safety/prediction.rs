//! The emitter as the planner predicts it over the step and beyond: where it is expected and a bound
//! on the standard deviation of that prediction along every direction.

use nalgebra::{Matrix2, Vector2};

/// The emitter as the planner predicts it over the interval and beyond: ẑ at the plan's start moving
/// at the estimated velocity, with a bound on the standard deviation of the predicted position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EmitterPrediction {
    /// ẑ at the plan's start, metres.
    pub position: Vector2<f64>,
    /// Estimated velocity, m/s (0 for a static model).
    pub velocity: Vector2<f64>,
    /// `sqrt(λ_max(P))` of the position covariance P, metres.
    pub sigma_position: f64,
    /// `sqrt(λ_max(V))` of the velocity covariance V, m/s (0 for a static model).
    pub sigma_velocity: f64,
    /// White-acceleration process noise q, m/s² (0 for a static model).
    pub accel_noise: f64,
}

/// `sqrt(λ_max)` of a symmetric 2×2 matrix (0 for a non-positive one; NaN stays NaN).
pub fn sqrt_lambda_max(m: &Matrix2<f64>) -> f64 {
    let (_, lambda) = tdoa::fim::sym_eigenvalues(m);
    if lambda.is_nan() { f64::NAN } else { lambda.max(0.0).sqrt() }
}

impl EmitterPrediction {
    /// A static emitter at `position` with covariance `cov` (m²).
    pub fn fixed(position: Vector2<f64>, cov: &Matrix2<f64>) -> Self {
        Self {
            position,
            velocity: Vector2::zeros(),
            sigma_position: sqrt_lambda_max(cov),
            sigma_velocity: 0.0,
            accel_noise: 0.0,
        }
    }

    /// A constant-velocity emitter: position `position` (cov `cov`), velocity `velocity` (cov
    /// `velocity_cov`, m²/s²), white-acceleration noise `accel_noise` (m/s²).
    pub fn moving(
        position: Vector2<f64>,
        cov: &Matrix2<f64>,
        velocity: Vector2<f64>,
        velocity_cov: &Matrix2<f64>,
        accel_noise: f64,
    ) -> Self {
        Self {
            position,
            velocity,
            sigma_position: sqrt_lambda_max(cov),
            sigma_velocity: sqrt_lambda_max(velocity_cov),
            accel_noise: accel_noise.max(0.0),
        }
    }

    /// Whether the prediction moves or grows with time.
    pub fn is_static(&self) -> bool {
        self.velocity == Vector2::zeros() && self.sigma_velocity == 0.0 && self.accel_noise == 0.0
    }

    /// ẑ(τ) = ẑ + v̂·τ, metres, τ seconds after the plan's start.
    pub fn at(&self, tau: f64) -> Vector2<f64> {
        self.position + self.velocity * tau
    }

    /// A bound on the standard deviation of the predicted position along any direction at τ ≥ 0:
    /// the error is `e_p + τ·e_v + w(τ)` (position, velocity, integrated white acceleration with
    /// variance `q²τ³/3` per axis), and the standard deviation of a sum is at most the sum of theirs:
    /// `σ̄(τ) = σ_p + τ·σ_v + q·sqrt(τ³/3)`, metres — increasing in τ, whatever the cross-covariance.
    pub fn sigma_bound(&self, tau: f64) -> f64 {
        let tau = tau.max(0.0);
        self.sigma_position + tau * self.sigma_velocity + self.accel_noise * (tau * tau * tau / 3.0).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::Lcg;

    #[test]
    fn sigma_bound_covers_the_predicted_covariance() {
        // A random joint covariance of position and velocity [[P, C], [Cᵀ, V]] and q:
        // sqrt(λ_max(P(τ))) ≤ σ̄(τ), with P(τ) = P + τ(C + Cᵀ) + τ²V + q²τ³/3·I.
        let mut r = Lcg(31);
        for _ in 0..500 {
            let a = nalgebra::Matrix4::from_fn(|_, _| (r.next() - 0.5) * 100.0);
            let joint = a * a.transpose();
            let p = joint.fixed_view::<2, 2>(0, 0).into_owned();
            let c = joint.fixed_view::<2, 2>(0, 2).into_owned();
            let v = joint.fixed_view::<2, 2>(2, 2).into_owned();
            let q = r.next();
            let e = EmitterPrediction::moving(Vector2::zeros(), &p, Vector2::zeros(), &v, q);
            for tau in [0.0, 0.01, 1.0, 10.0, 100.0, 1000.0] {
                let pt =
                    p + (c + c.transpose()) * tau + v * tau * tau + Matrix2::identity() * q * q * tau.powi(3) / 3.0;
                assert!(sqrt_lambda_max(&pt) <= e.sigma_bound(tau) * (1.0 + 1e-12) + 1e-9, "τ {tau}");
            }
        }
    }
}
