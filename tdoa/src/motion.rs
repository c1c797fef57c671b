//! The emitter's motion model between two snapshots: what the sequential estimator predicts with and
//! what the posterior CRLB recursion assumes.
//!
//! - `static` (the paper): the state is the position `z = (x, y)`, m; nothing moves between snapshots.
//! - `constant_velocity`: the state is `(x, y, vx, vy)` (m, m/s), `x_{k+1} = Φ x_k + w_k` with
//!   `Φ = [[I, Δt·I], [0, I]]` and discrete white-noise acceleration (Bar-Shalom, Li & Kirubarajan 2001,
//!   §6.3.3): `w_k = Γ a_k`, `Γ = [Δt²/2 · I; Δt · I]`, `a_k ~ N(0, σ_a² I)`, so
//!   `Q_p = σ_a² [[Δt⁴/4 I, Δt³/2 I], [Δt³/2 I, Δt² I]]` (σ_a in m/s², Δt in s).
//!
//! The velocity is unobserved by one snapshot: the filter starts it at 0 with standard deviation
//! `velocity_prior_sigma` (m/s) per axis, and the CRLB recursion starts from the same prior information.

use std::fmt;
use std::str::FromStr;

use nalgebra::Matrix4;

use crate::{MAX_EXTENT_M, TdoaError};

/// Which emitter motion model the estimator assumes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EmitterModel {
    /// A fixed emitter (the paper): state `(x, y)`.
    #[default]
    Static,
    /// Constant velocity with white-acceleration noise: state `(x, y, vx, vy)`.
    ConstantVelocity,
}

impl EmitterModel {
    /// Both models.
    pub const ALL: [EmitterModel; 2] = [EmitterModel::Static, EmitterModel::ConstantVelocity];

    /// `static` or `constant_velocity`.
    pub fn name(self) -> &'static str {
        match self {
            EmitterModel::Static => "static",
            EmitterModel::ConstantVelocity => "constant_velocity",
        }
    }

    /// State dimension: 2 or 4.
    pub fn dim(self) -> usize {
        match self {
            EmitterModel::Static => 2,
            EmitterModel::ConstantVelocity => 4,
        }
    }

    /// The wire code (0 static, 1 constant velocity).
    pub fn code(self) -> u8 {
        match self {
            EmitterModel::Static => 0,
            EmitterModel::ConstantVelocity => 1,
        }
    }

    /// Decodes [`code`](Self::code).
    pub fn from_code(code: u8) -> Option<Self> {
        match code {
            0 => Some(EmitterModel::Static),
            1 => Some(EmitterModel::ConstantVelocity),
            _ => None,
        }
    }
}

impl fmt::Display for EmitterModel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for EmitterModel {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "static" => Ok(EmitterModel::Static),
            "constant_velocity" | "cv" => Ok(EmitterModel::ConstantVelocity),
            _ => Err(format!("unknown emitter model '{s}' (expected static or constant_velocity)")),
        }
    }
}

/// The motion model with its parameters, validated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dynamics {
    model: EmitterModel,
    dt: f64,
    accel_sigma: f64,
    velocity_prior_sigma: f64,
}

impl Dynamics {
    /// A static emitter.
    pub fn fixed() -> Self {
        Self { model: EmitterModel::Static, dt: 1.0, accel_sigma: 0.0, velocity_prior_sigma: 1.0 }
    }

    /// `model` with snapshot interval `dt` (s, > 0), process noise `accel_sigma` (m/s², ≥ 0) and the
    /// velocity prior's standard deviation `velocity_prior_sigma` (m/s, > 0). The last two matter only
    /// for `constant_velocity`. Errors name the parameter.
    pub fn new(model: EmitterModel, dt: f64, accel_sigma: f64, velocity_prior_sigma: f64) -> Result<Self, TdoaError> {
        let check = |what: &str, v: f64, zero_ok: bool| {
            if !v.is_finite() {
                Err(TdoaError::NotFinite { what: what.into(), value: v })
            } else if v < 0.0 || (!zero_ok && v == 0.0) {
                Err(TdoaError::NonPositive { what: what.into(), value: v })
            } else {
                Ok(())
            }
        };
        check("the snapshot interval dt (s)", dt, false)?;
        check("process_noise_accel (m/s²)", accel_sigma, true)?;
        check("velocity_prior_sigma (m/s)", velocity_prior_sigma, false)?;
        // The lengths they make over one interval stay within the model's (their squares enter P and Q).
        let within = |what: &str, length: f64| {
            if length <= MAX_EXTENT_M {
                Ok(())
            } else {
                Err(TdoaError::OutOfRange { what: what.into(), value: length, min: 0.0, max: MAX_EXTENT_M })
            }
        };
        within("velocity_prior_sigma × dt (m)", velocity_prior_sigma * dt)?;
        within("process_noise_accel × dt² (m)", accel_sigma * dt * dt)?;
        Ok(Self { model, dt, accel_sigma, velocity_prior_sigma })
    }

    /// The model.
    pub fn model(&self) -> EmitterModel {
        self.model
    }

    /// Snapshot interval Δt, s.
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// Process noise σ_a, m/s².
    pub fn accel_sigma(&self) -> f64 {
        self.accel_sigma
    }

    /// The velocity prior's σ per axis, m/s.
    pub fn velocity_prior_sigma(&self) -> f64 {
        self.velocity_prior_sigma
    }

    /// `Φ` over `steps` intervals (4×4; the static model uses its top-left 2×2 block = I).
    pub fn transition(&self, steps: u64) -> Matrix4<f64> {
        let mut phi = Matrix4::identity();
        if self.model == EmitterModel::ConstantVelocity {
            let t = self.dt * steps as f64;
            phi[(0, 2)] = t;
            phi[(1, 3)] = t;
        }
        phi
    }

    /// `Q_p` accumulated over `steps` intervals (zero for the static model): the sum over the intervals
    /// of `Φ^{j} Γ Γᵀ Φ^{jᵀ}` σ_a².
    pub fn process_noise(&self, steps: u64) -> Matrix4<f64> {
        let mut q = Matrix4::zeros();
        if self.model != EmitterModel::ConstantVelocity || self.accel_sigma == 0.0 {
            return q;
        }
        let dt = self.dt;
        let s2 = self.accel_sigma * self.accel_sigma;
        let mut one = Matrix4::zeros();
        for a in 0..2 {
            one[(a, a)] = dt.powi(4) / 4.0 * s2;
            one[(a, a + 2)] = dt.powi(3) / 2.0 * s2;
            one[(a + 2, a)] = dt.powi(3) / 2.0 * s2;
            one[(a + 2, a + 2)] = dt * dt * s2;
        }
        let phi = self.transition(1);
        for _ in 0..steps {
            q = phi * q * phi.transpose() + one;
        }
        q
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_velocity_matrices() {
        let d = Dynamics::new(EmitterModel::ConstantVelocity, 10.0, 0.5, 20.0).unwrap();
        let phi = d.transition(3);
        assert_eq!(phi[(0, 2)], 30.0);
        assert_eq!(phi[(1, 3)], 30.0);
        // One interval: the textbook DWNA matrix.
        let q = d.process_noise(1);
        assert!((q[(0, 0)] - 0.25 * 10f64.powi(4) / 4.0).abs() < 1e-12);
        assert!((q[(0, 2)] - 0.25 * 1000.0 / 2.0).abs() < 1e-12);
        assert!((q[(2, 2)] - 0.25 * 100.0).abs() < 1e-12);
        // Two intervals accumulate as Φ Q Φᵀ + Q, symmetric.
        let q2 = d.process_noise(2);
        let expected = d.transition(1) * q * d.transition(1).transpose() + q;
        assert!((q2 - expected).norm() < 1e-9);
        assert!((q2 - q2.transpose()).norm() == 0.0);
        // The static model neither moves nor diffuses.
        assert_eq!(Dynamics::fixed().transition(5), Matrix4::identity());
        assert_eq!(Dynamics::fixed().process_noise(5), Matrix4::zeros());
    }

    #[test]
    fn bad_parameters_name_themselves() {
        let e = Dynamics::new(EmitterModel::ConstantVelocity, 10.0, -1.0, 20.0).unwrap_err();
        assert!(e.to_string().contains("process_noise_accel"), "{e}");
        let e = Dynamics::new(EmitterModel::ConstantVelocity, 10.0, f64::NAN, 20.0).unwrap_err();
        assert!(e.to_string().contains("process_noise_accel"), "{e}");
        assert!(Dynamics::new(EmitterModel::Static, 0.0, 0.0, 1.0).is_err());
        // Finite, but lengths beyond the model's over one interval (their squares would overflow P).
        let e = Dynamics::new(EmitterModel::ConstantVelocity, 10.0, 0.05, 1e300).unwrap_err();
        assert!(matches!(e, TdoaError::OutOfRange { .. }) && e.to_string().contains("velocity_prior_sigma"), "{e}");
        let e = Dynamics::new(EmitterModel::ConstantVelocity, 1e200, 0.05, 1e-300).unwrap_err();
        assert!(e.to_string().contains("process_noise_accel"), "{e}");
        assert!(Dynamics::new(EmitterModel::ConstantVelocity, 10.0, 1e5, 1e6).is_ok());
        assert_eq!("cv".parse::<EmitterModel>(), Ok(EmitterModel::ConstantVelocity));
        assert!("moving".parse::<EmitterModel>().is_err());
    }
}
