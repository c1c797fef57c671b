//! The posterior CRLB along a run: the bound on the mean squared error of any estimator of the emitter's
//! state from every snapshot so far, evaluated at the true states.
//!
//! - `static`: the information accumulates, `J_k = Σ_{j≤k} F_j(z)` (eq. 48 per snapshot), and
//!   `PCRLB_k = sqrt(tr J_k⁻¹)` — the bound of every unbiased estimator from snapshots 0..k (no prior:
//!   the fused estimator starts from snapshot 0 alone).
//! - `constant_velocity`: Tichavský, Muravchik & Nehorai (1998), for linear Gaussian dynamics in the
//!   information-filter form `J_{k+1} = (Φ J_k⁻¹ Φᵀ + Q_p)⁻¹ + Hᵀ Q⁻¹ H`, with `Hᵀ Q⁻¹ H =
//!   blockdiag(F_{k+1}(z_{k+1}), 0)` and `J_0 = blockdiag(F_0(z_0), I/σ_v0²)` (the estimator's velocity
//!   prior). The reported bound is the position block: `sqrt(tr [J_k⁻¹]_pos)`.
//!
//! Units: `J` in 1/m² (position) and s²/m² (velocity); the bound in metres.

use nalgebra::{Matrix2, Matrix4};

use crate::motion::{Dynamics, EmitterModel};

/// The running information matrix of one run.
#[derive(Debug, Clone, PartialEq)]
pub struct InformationBound {
    dynamics: Dynamics,
    info: Option<Matrix4<f64>>,
}

impl InformationBound {
    /// Before the first snapshot.
    pub fn new(dynamics: Dynamics) -> Self {
        Self { dynamics, info: None }
    }

    /// Adds the next snapshot's FIM at the true position (`None`: a geometry with no information, e.g.
    /// the emitter on a UAV) after `steps` intervals (1 for consecutive snapshots), and returns the bound
    /// (m; `+∞` while the information is singular).
    pub fn add(&mut self, fim: Option<Matrix2<f64>>, steps: u64) -> f64 {
        let mut f = Matrix4::zeros();
        if let Some(fim) = fim.filter(|m| m.iter().all(|v| v.is_finite())) {
            f.fixed_view_mut::<2, 2>(0, 0).copy_from(&fim);
        }
        let model = self.dynamics.model();
        let next = match (self.info, model) {
            (None, EmitterModel::Static) => f,
            (None, EmitterModel::ConstantVelocity) => {
                let v = 1.0 / self.dynamics.velocity_prior_sigma().powi(2);
                f[(2, 2)] = v;
                f[(3, 3)] = v;
                f
            }
            (Some(j), EmitterModel::Static) => j + f,
            (Some(j), EmitterModel::ConstantVelocity) => {
                let phi = self.dynamics.transition(steps);
                match j.try_inverse() {
                    Some(p) => {
                        let pred = phi * p * phi.transpose() + self.dynamics.process_noise(steps);
                        match pred.try_inverse() {
                            Some(jp) => jp + f,
                            None => j + f,
                        }
                    }
                    None => j + f,
                }
            }
        };
        let next = 0.5 * (next + next.transpose());
        self.info = Some(next);
        self.bound()
    }

    /// The current bound, metres (`+∞` before any information or while it is singular).
    pub fn bound(&self) -> f64 {
        let Some(j) = self.info else { return f64::INFINITY };
        let n = self.dynamics.model().dim();
        let inv = match n {
            2 => crate::fim::inverse_spd(&j.fixed_view::<2, 2>(0, 0).into_owned()).map(|m| m.trace()),
            _ => j.try_inverse().map(|m| m[(0, 0)] + m[(1, 1)]),
        };
        inv.filter(|t| t.is_finite() && *t >= 0.0).map_or(f64::INFINITY, f64::sqrt)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn static_bound_is_the_inverse_of_the_summed_information() {
        let f1 = Matrix2::new(2e-4, 1e-5, 1e-5, 1e-6);
        let f2 = Matrix2::new(1e-6, -2e-5, -2e-5, 3e-4);
        let mut b = InformationBound::new(Dynamics::fixed());
        assert_eq!(b.bound(), f64::INFINITY);
        let one = b.add(Some(f1), 1);
        assert!((one - f1.try_inverse().unwrap().trace().sqrt()).abs() < 1e-9);
        let two = b.add(Some(f2), 1);
        assert!((two - (f1 + f2).try_inverse().unwrap().trace().sqrt()).abs() < 1e-9);
        // No information: unchanged.
        assert_eq!(b.add(None, 1), two);
    }

    #[test]
    fn constant_velocity_recursion_equals_the_batch_information_without_process_noise() {
        // With σ_a = 0 the states are x_k = Φ^k x_0, so the bound on x_k is the batch FIM of x_0
        // mapped through Φ^k: J_k = Φ^{-kᵀ} (J_0 + Σ_j Φ^{jᵀ} Hᵀ F_j H Φ^j) Φ^{-k}.
        let d = Dynamics::new(EmitterModel::ConstantVelocity, 10.0, 0.0, 20.0).unwrap();
        let fims = [
            Matrix2::new(2e-4, 1e-5, 1e-5, 1e-6),
            Matrix2::new(1e-6, -2e-5, -2e-5, 3e-4),
            Matrix2::new(5e-5, 0.0, 0.0, 5e-5),
            Matrix2::new(1e-4, 3e-5, 3e-5, 2e-5),
        ];
        let mut rec = InformationBound::new(d);
        let mut batch = Matrix4::zeros();
        batch[(2, 2)] = 1.0 / 400.0;
        batch[(3, 3)] = 1.0 / 400.0;
        for (k, f) in fims.iter().enumerate() {
            let got = rec.add(Some(*f), 1);
            let phi = d.transition(k as u64);
            let mut hf = Matrix4::zeros();
            hf.fixed_view_mut::<2, 2>(0, 0).copy_from(f);
            batch += phi.transpose() * hf * phi;
            let cov_k = phi * batch.try_inverse().unwrap() * phi.transpose();
            let expected = (cov_k[(0, 0)] + cov_k[(1, 1)]).sqrt();
            assert!((got - expected).abs() < 1e-6 * expected, "step {k}: {got} vs {expected}");
        }
        // Process noise only loosens the bound.
        let mut noisy = InformationBound::new(Dynamics::new(EmitterModel::ConstantVelocity, 10.0, 1.0, 20.0).unwrap());
        let mut last = 0.0;
        for f in &fims {
            last = noisy.add(Some(*f), 1);
        }
        assert!(last > rec.bound());
    }
}
