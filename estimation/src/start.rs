//! The first fix of a fused track (or the only one of the snapshot estimator): Chan's solution of a
//! burst, its outlying arrivals dropped per the [`crate::OutlierPolicy`], with the covariance the track
//! starts from — the fix's sigma-point covariance for an exactly determined fix of three arrivals,
//! Chan's WLS covariance for four or more — and the two-arrival bursts held before it fused in.

use nalgebra::{Matrix2, Vector2};
use tdoa::consider::BiasSensitivity;
use tdoa::{Arrivals, Posterior, TdoaError};

use crate::{EstimateOut, EstimateStatus, Estimator, EstimatorKind, PendingRoot, TrackCounters, outliers};

/// A burst heard by two UAVs before the first fix, with its step: held for the first fix.
pub type HeldBurst = (u64, Arrivals);

/// The two-arrival bursts before the first fix an [`Estimator`] keeps for it (the newest).
pub const MAX_HELD_BURSTS: usize = 4;

impl Estimator {
    /// Chan's fix; fused and ambiguous, also the posterior of the other root (with its bias
    /// sensitivity).
    pub(crate) fn solve(&self, a: &Arrivals) -> Result<(EstimateOut, Option<PendingRoot>), TdoaError> {
        let config = self.config;
        let (mut sol, heard, dropped) = outliers::chan_burst(a, self.prior(), |m| config.gate(m), config.outliers)?;
        let finite = sol.position.iter().chain(sol.covariance.iter()).all(|v| v.is_finite());
        if !finite {
            return Err(TdoaError::Degenerate("Chan returned a non-finite estimate or covariance".into()));
        }
        // A track started from an exactly determined fix (three arrivals: no redundancy, Chan's
        // covariance is the CRLB at the fix) takes the fix's sigma-point covariance: the CRLB at the fix
        // is overconfident where the geometry bends within the noise (tdoa::sigma_points). A fix of four
        // or more arrivals keeps Chan's WLS covariance (measured consistent; with the sigma points, five
        // UAVs at 15 % multipath flew more runs with a NEES above 1 000 — a reflection the burst's
        // residual does not show biases the fix, and the points' spread does not see the bias). The
        // snapshot estimator keeps Chan's covariance (the paper's M).
        let within_extent = |z: &Vector2<f64>, p: Matrix2<f64>| -> Result<Matrix2<f64>, TdoaError> {
            let reference = heard.sensors.positions()[0];
            if (z - reference).norm() > tdoa::MAX_EXTENT_M || p.trace().sqrt() > tdoa::MAX_EXTENT_M {
                return Err(TdoaError::NoSolution(format!(
                    "the fix ({:.0}, {:.0}) ± {:.0} m lies beyond the plane model's extent ({} m)",
                    z.x,
                    z.y,
                    p.trace().sqrt(),
                    tdoa::MAX_EXTENT_M
                )));
            }
            Ok(p)
        };
        let fix_covariance = |z: &Vector2<f64>| -> Result<Matrix2<f64>, TdoaError> {
            within_extent(z, tdoa::sigma_points::fix_covariance(&heard.sensors, &heard.diffs, z)?)
        };
        if self.config.kind == EstimatorKind::Fused {
            let exact = heard.sensors.len() == 3;
            sol.covariance =
                if exact { fix_covariance(&sol.position)? } else { within_extent(&sol.position, sol.covariance)? };
        }
        let status = if sol.ambiguous { EstimateStatus::Ambiguous } else { EstimateStatus::Ok };
        let (posterior, other) = match self.config.kind {
            EstimatorKind::Fused => {
                let other = match (sol.ambiguous, sol.candidates.as_slice()) {
                    (true, [_, second]) => fix_covariance(second).ok().and_then(|covariance| {
                        let alt = tdoa::ChanSolution { position: *second, covariance, ..sol.clone() };
                        let s = BiasSensitivity::of_fix(&heard, second);
                        Posterior::from_chan(&alt, &self.config.dynamics).ok().map(|p| (p, s))
                    }),
                    _ => None,
                };
                (Some(Posterior::from_chan(&sol, &self.config.dynamics)?), other)
            }
            EstimatorKind::Snapshot => (None, None),
        };
        let out = EstimateOut {
            position: sol.position,
            covariance: sol.covariance,
            status,
            candidates: sol.candidates,
            posterior,
            nis: None,
            track: TrackCounters::default(),
            heard: a.heard_mask(),
            outliers: dropped,
            bias_cov: Matrix2::zeros(),
            sensitivity: BiasSensitivity::of_fix(&heard, &sol.position),
            alternative: None,
            held: Vec::new(),
            window: None,
        };
        Ok((out, other))
    }

    /// The first fix's posterior `post` at `step` (bias sensitivity `s`) with the two-arrival bursts
    /// `held` of the steps before it fused in: each burst into the posterior carried back to its step
    /// (`Φ⁻¹`, no process noise; the static model stays as it is) and forward again — for the static
    /// model the posterior of the fix's burst and the held ones together, in any order. A held burst
    /// that fails the gate is left out.
    pub(crate) fn fold_held(
        &self,
        mut post: Posterior,
        mut s: Option<BiasSensitivity>,
        step: u64,
        held: &[HeldBurst],
    ) -> (Posterior, Option<BiasSensitivity>) {
        let dynamics = self.config.dynamics;
        for (j, b) in held {
            let phi = dynamics.transition(step.saturating_sub(*j));
            let Some(back) = phi.try_inverse() else { continue };
            let s_back = s.unwrap_or(BiasSensitivity::zero()).transformed(&back);
            let Ok(out) = self.fuse(&post.transformed(&back), &s_back, b) else { continue };
            if let (EstimateStatus::Ok, Some(p)) = (&out.status, out.posterior) {
                post = p.transformed(&phi);
                s = out.sensitivity.map(|x| x.transformed(&phi));
            }
        }
        (post, s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::*;
    use crate::*;
    use tdoa::Dynamics;

    #[test]
    fn noise_free_three_and_four_uavs() {
        let z = Vector2::new(25000.0, 15000.0);
        let uavs = nominal();
        let mut est = Estimator::with_prior(Vector2::new(20000.0, 20000.0));
        let out = est.estimate(0, &uavs, &diffs(&uavs, z), &noise(3)).unwrap();
        assert!((out.position - z).norm() < 1e-6, "{}", (out.position - z).norm());
        assert_eq!(out.status, EstimateStatus::Ok);
        assert!(out.covariance.iter().all(|v| v.is_finite()));
        let mut uavs4 = uavs.clone();
        uavs4.push(Vector2::new(0.0, 9000.0));
        let out = Estimator::new().estimate(0, &uavs4, &diffs(&uavs4, z), &noise(4)).unwrap();
        assert!((out.position - z).norm() < 1e-6, "{}", (out.position - z).norm());
        assert_eq!(out.status, EstimateStatus::Ok);
    }

    #[test]
    fn prior_resolves_the_three_uav_ambiguity() {
        let (uavs, z, other) = ambiguous_case();
        let d = diffs(&uavs, z);
        // No prior: ambiguous, both roots offered.
        let out = Estimator::new().estimate(0, &uavs, &d, &noise(3)).unwrap();
        assert_eq!(out.status, EstimateStatus::Ambiguous);
        assert_eq!(out.candidates.len(), 2);
        assert!(out.candidates.iter().any(|c| (c - z).norm() < 1e-6));
        // A prior near the truth picks the truth; one near the other root picks that root.
        let near = |p: Vector2<f64>| p + Vector2::new(150.0, -90.0);
        let out = Estimator::with_prior(near(z)).estimate(0, &uavs, &d, &noise(3)).unwrap();
        assert_eq!(out.status, EstimateStatus::Ok);
        assert!((out.position - z).norm() < 1e-6);
        let out = Estimator::with_prior(near(other)).estimate(0, &uavs, &d, &noise(3)).unwrap();
        assert!((out.position - other).norm() < 1e-6);
        // The previous estimate is the prior of the next solve.
        let mut est = Estimator::with_prior(near(z));
        est.estimate(0, &uavs, &d, &noise(3)).unwrap();
        let again = est.estimate(0, &uavs, &d, &noise(3)).unwrap();
        assert_eq!(again.status, EstimateStatus::Ok);
        assert!((again.position - z).norm() < 1e-6);
    }

    #[test]
    fn two_arrival_bursts_before_the_first_fix_are_fused_into_it() {
        // Noise-free, static: the bursts held (each one difference of another UAV pair, at other
        // positions) leave the fix exact and add their information to it.
        let z = Vector2::new(25_000.0, 15_000.0);
        let at = |k: f64| {
            vec![
                Vector2::new(1500.0 + 400.0 * k, 500.0),
                Vector2::new(10_000.0, 1500.0 + 300.0 * k),
                Vector2::new(5000.0 - 200.0 * k, 8500.0),
            ]
        };
        let burst = |k: f64, mask: u8| {
            let uavs = at(k);
            let pts: Vec<[f64; 2]> = uavs.iter().map(|p| [p.x, p.y]).collect();
            let arrivals: Vec<f64> = uavs.iter().map(|p| (p - z).norm()).collect();
            Arrivals::new(&pts, &arrivals, mask, &[28.7712; 3], &[0.0; 3]).unwrap()
        };
        let mut with = Estimator::with_config(EstimatorConfig::fused(Dynamics::fixed()));
        let mut without = Estimator::with_config(EstimatorConfig::fused(Dynamics::fixed()));
        for (k, mask) in [(0.0, 0b011u8), (1.0, 0b110), (2.0, 0b101)] {
            assert!(matches!(
                with.estimate_burst(k as u64, &burst(k, mask)),
                Err(EstimatorError::NoFixYet { heard: 2 })
            ));
        }
        assert_eq!(with.held().len(), 3);
        let a = with.estimate_burst(3, &burst(3.0, 0b111)).unwrap();
        let b = without.estimate_burst(3, &burst(3.0, 0b111)).unwrap();
        assert!(with.held().is_empty());
        assert!((a.position - z).norm() < 1e-3, "{:?}", a.position);
        assert!(
            a.covariance.trace() < 0.9 * b.covariance.trace(),
            "{} vs {}",
            a.covariance.trace(),
            b.covariance.trace()
        );
        // The information adds: the fix's own information plus each burst's (one difference, at z).
        let info = |k: f64, mask: u8| {
            let h = burst(k, mask).heard().unwrap().unwrap();
            tdoa::fim::fim(&h.sensors, &z).unwrap()
        };
        let total = b.covariance.try_inverse().unwrap() + info(0.0, 0b011) + info(1.0, 0b110) + info(2.0, 0b101);
        let bound = total.try_inverse().unwrap();
        // A single range difference is fused with its linearisation noise on top (tdoa::fusion): never
        // more information than the bursts hold, and close to it.
        let min_eig = |m: Matrix2<f64>| {
            let (a, b) = tdoa::fim::sym_eigenvalues(&m);
            a.min(b)
        };
        assert!(min_eig(a.covariance - bound) > -1e-6 * bound.norm(), "{} below the bound {}", a.covariance, bound);
        assert!(min_eig(b.covariance - a.covariance) > 0.0, "{} not below the fix's {}", a.covariance, b.covariance);
        assert!(a.covariance.trace() < 1.05 * bound.trace(), "{} vs {}", a.covariance, bound);
    }
}
