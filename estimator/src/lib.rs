//! # uavloc-estimator — Chan's TDOA estimator with memory
//!
//! [`Estimator`] wraps `tdoa::chan` (paper Section 2, eqs. 10–30) for a run: the previous estimate is
//! the prior that resolves the two-root ambiguity of the three-UAV case, and when a solve fails the
//! previous estimate is kept and reported as [`EstimateStatus::Failed`]. The output never holds a NaN.
//!
//! [`process`] is the estimator process: measurement in → [`Estimator::estimate`] → estimate out over
//! iceoryx2.
//!
//! Units: metres (positions), m² (covariance).

pub mod process;

use nalgebra::{Matrix2, Vector2};
use tdoa::{NoiseModel, RangeDiffs, Sensors, TdoaError, chan};
use thiserror::Error;

/// How an estimate came about.
#[derive(Debug, Clone, PartialEq)]
pub enum EstimateStatus {
    /// Chan gave a unique solution (or the prior resolved the ambiguity).
    Ok,
    /// Two physically valid solutions and no prior to choose: `position` is the first candidate.
    Ambiguous,
    /// Chan failed; `position` and `covariance` are the previous estimate.
    Failed {
        /// Why Chan failed.
        reason: String,
    },
}

/// One estimate of the emitter.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimateOut {
    /// ẑ, metres.
    pub position: Vector2<f64>,
    /// Its covariance M, m² (Chan's first-order covariance, `F⁻¹(ẑ)` for three UAVs).
    pub covariance: Matrix2<f64>,
    /// How it came about.
    pub status: EstimateStatus,
    /// The physically valid solutions of this solve (two when ambiguous or resolved by the prior;
    /// empty when the solve failed).
    pub candidates: Vec<Vector2<f64>>,
}

/// Why no estimate at all could be given.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum EstimatorError {
    /// Chan failed and there is no previous estimate to fall back on.
    #[error("no estimate: {0} (and no previous estimate to keep)")]
    NoEstimate(#[source] TdoaError),
}

/// Chan's estimator with the previous estimate as prior.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Estimator {
    prior: Option<Vector2<f64>>,
    previous: Option<(Vector2<f64>, Matrix2<f64>)>,
}

impl Estimator {
    /// An estimator with no prior: the first three-UAV solve may be ambiguous.
    pub fn new() -> Self {
        Self::default()
    }

    /// An estimator whose first solve uses `prior` (metres) to resolve the three-UAV ambiguity.
    pub fn with_prior(prior: Vector2<f64>) -> Self {
        Self { prior: prior.iter().all(|v| v.is_finite()).then_some(prior), previous: None }
    }

    /// An estimator that continues after an estimate `position` with covariance `covariance` (e.g. one
    /// taking over from another process): the same state as the estimator that produced it.
    pub fn resume(position: Vector2<f64>, covariance: Matrix2<f64>) -> Self {
        Self { prior: None, previous: Some((position, covariance)) }
    }

    /// The prior of the next solve: the previous estimate, else the initial prior.
    pub fn prior(&self) -> Option<Vector2<f64>> {
        self.previous.map(|(p, _)| p).or(self.prior)
    }

    /// The previous estimate and its covariance.
    pub fn previous(&self) -> Option<(Vector2<f64>, Matrix2<f64>)> {
        self.previous
    }

    /// Estimates the emitter from range differences `d` (`d_i = r_i − r_0`, metres) measured by UAVs at
    /// `uavs` (metres, index 0 the reference) with range noise `noise`.
    ///
    /// On success the estimate becomes the prior of the next call (an ambiguous one too: its first
    /// candidate). On failure the previous estimate is returned with [`EstimateStatus::Failed`]; only
    /// when there is none is the result an error.
    pub fn estimate(
        &mut self,
        uavs: &[Vector2<f64>],
        d: &RangeDiffs,
        noise: &NoiseModel,
    ) -> Result<EstimateOut, EstimatorError> {
        match self.solve(uavs, d, noise) {
            Ok(out) => {
                self.previous = Some((out.position, out.covariance));
                Ok(out)
            }
            Err(e) => match self.previous {
                Some((position, covariance)) => Ok(EstimateOut {
                    position,
                    covariance,
                    status: EstimateStatus::Failed { reason: e.to_string() },
                    candidates: Vec::new(),
                }),
                None => Err(EstimatorError::NoEstimate(e)),
            },
        }
    }

    fn solve(&self, uavs: &[Vector2<f64>], d: &RangeDiffs, noise: &NoiseModel) -> Result<EstimateOut, TdoaError> {
        let pts: Vec<[f64; 2]> = uavs.iter().map(|p| [p.x, p.y]).collect();
        let sensors = Sensors::new(&pts, noise.clone())?;
        let sol = chan(&sensors, d, self.prior())?;
        let finite = sol.position.iter().chain(sol.covariance.iter()).all(|v| v.is_finite());
        if !finite {
            return Err(TdoaError::Degenerate("Chan returned a non-finite estimate or covariance".into()));
        }
        let status = if sol.ambiguous { EstimateStatus::Ambiguous } else { EstimateStatus::Ok };
        Ok(EstimateOut { position: sol.position, covariance: sol.covariance, status, candidates: sol.candidates })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise(n: usize) -> NoiseModel {
        NoiseModel::uniform(n, 28.7712).unwrap()
    }

    fn diffs(uavs: &[Vector2<f64>], z: Vector2<f64>) -> RangeDiffs {
        let r: Vec<f64> = uavs.iter().map(|w| (z - w).norm()).collect();
        RangeDiffs::from_slice(&r[1..].iter().map(|ri| ri - r[0]).collect::<Vec<_>>()).unwrap()
    }

    fn nominal() -> Vec<Vector2<f64>> {
        vec![Vector2::new(1500.0, 500.0), Vector2::new(10000.0, 1500.0), Vector2::new(5000.0, 8500.0)]
    }

    #[test]
    fn noise_free_three_and_four_uavs() {
        let z = Vector2::new(25000.0, 15000.0);
        let uavs = nominal();
        let mut est = Estimator::with_prior(Vector2::new(20000.0, 20000.0));
        let out = est.estimate(&uavs, &diffs(&uavs, z), &noise(3)).unwrap();
        assert!((out.position - z).norm() < 1e-6, "{}", (out.position - z).norm());
        assert_eq!(out.status, EstimateStatus::Ok);
        assert!(out.covariance.iter().all(|v| v.is_finite()));
        let mut uavs4 = uavs.clone();
        uavs4.push(Vector2::new(0.0, 9000.0));
        let out = Estimator::new().estimate(&uavs4, &diffs(&uavs4, z), &noise(4)).unwrap();
        assert!((out.position - z).norm() < 1e-6, "{}", (out.position - z).norm());
        assert_eq!(out.status, EstimateStatus::Ok);
    }

    /// A noise-free 3-UAV case where both roots are physical.
    fn ambiguous_case() -> (Vec<Vector2<f64>>, Vector2<f64>, Vector2<f64>) {
        let uavs = vec![Vector2::new(0.0, 0.0), Vector2::new(4000.0, 0.0), Vector2::new(0.0, 4000.0)];
        let sensors = Sensors::new(&[[0.0, 0.0], [4000.0, 0.0], [0.0, 4000.0]], noise(3)).unwrap();
        for i in -20..=20 {
            for j in -20..=20 {
                let z = Vector2::new(1000.0 * i as f64 + 137.0, 1000.0 * j as f64 + 71.0);
                if let Ok(sol) = chan(&sensors, &diffs(&uavs, z), None)
                    && sol.ambiguous
                    && sol.candidates.len() == 2
                {
                    let other =
                        if (sol.candidates[0] - z).norm() < 1e-3 { sol.candidates[1] } else { sol.candidates[0] };
                    if (other - z).norm() > 1000.0 {
                        return (uavs, z, other);
                    }
                }
            }
        }
        panic!("no ambiguous geometry found");
    }

    #[test]
    fn prior_resolves_the_three_uav_ambiguity() {
        let (uavs, z, other) = ambiguous_case();
        let d = diffs(&uavs, z);
        // No prior: ambiguous, both roots offered.
        let out = Estimator::new().estimate(&uavs, &d, &noise(3)).unwrap();
        assert_eq!(out.status, EstimateStatus::Ambiguous);
        assert_eq!(out.candidates.len(), 2);
        assert!(out.candidates.iter().any(|c| (c - z).norm() < 1e-6));
        // A prior near the truth picks the truth; one near the other root picks that root.
        let near = |p: Vector2<f64>| p + Vector2::new(150.0, -90.0);
        let out = Estimator::with_prior(near(z)).estimate(&uavs, &d, &noise(3)).unwrap();
        assert_eq!(out.status, EstimateStatus::Ok);
        assert!((out.position - z).norm() < 1e-6);
        let out = Estimator::with_prior(near(other)).estimate(&uavs, &d, &noise(3)).unwrap();
        assert!((out.position - other).norm() < 1e-6);
        // The previous estimate is the prior of the next solve.
        let mut est = Estimator::with_prior(near(z));
        est.estimate(&uavs, &d, &noise(3)).unwrap();
        let again = est.estimate(&uavs, &d, &noise(3)).unwrap();
        assert_eq!(again.status, EstimateStatus::Ok);
        assert!((again.position - z).norm() < 1e-6);
    }

    #[test]
    fn failure_keeps_the_previous_estimate() {
        let z = Vector2::new(25000.0, 15000.0);
        let uavs = nominal();
        let mut est = Estimator::new();
        let first = est.estimate(&uavs, &diffs(&uavs, z), &noise(3)).unwrap();
        // Collinear UAVs: Chan cannot solve.
        let line = vec![Vector2::new(0.0, 0.0), Vector2::new(1000.0, 0.0), Vector2::new(2000.0, 0.0)];
        let out = est.estimate(&line, &diffs(&line, z), &noise(3)).unwrap();
        assert!(matches!(out.status, EstimateStatus::Failed { ref reason } if !reason.is_empty()));
        assert_eq!(out.position, first.position);
        assert_eq!(out.covariance, first.covariance);
        assert!(out.position.iter().chain(out.covariance.iter()).all(|v| v.is_finite()));
        // Coincident UAVs and a wrong count fail the same way.
        let twin = vec![uavs[0], uavs[0], uavs[2]];
        assert!(matches!(
            est.estimate(&twin, &diffs(&uavs, z), &noise(3)).unwrap().status,
            EstimateStatus::Failed { .. }
        ));
        assert!(matches!(
            est.estimate(&uavs[..2], &diffs(&uavs, z), &noise(3)).unwrap().status,
            EstimateStatus::Failed { .. }
        ));
        // With no previous estimate the failure is an error.
        assert!(matches!(
            Estimator::new().estimate(&line, &diffs(&line, z), &noise(3)),
            Err(EstimatorError::NoEstimate(_))
        ));
    }
}
