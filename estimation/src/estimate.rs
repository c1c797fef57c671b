//! What the estimator gives for a step: the estimate with its covariance, how it came about, and the
//! fused state that the next step starts from — or why there is no estimate at all.

use nalgebra::{Matrix2, Vector2};
use tdoa::consider::BiasSensitivity;
use tdoa::{Posterior, TdoaError};
use thiserror::Error;

use crate::{HeldBurst, PendingRoot, TrackCounters, window};

/// How an estimate came about.
#[derive(Debug, Clone, PartialEq)]
pub enum EstimateStatus {
    /// Chan gave a unique solution (or the prior resolved the ambiguity); fused: the snapshot was fused.
    Ok,
    /// Two physically valid solutions and no prior to choose: `position` is the first candidate.
    Ambiguous,
    /// Fused only: the snapshot failed the χ² gate and was not fused; the estimate is the prediction.
    Rejected {
        /// The snapshot's normalised innovation squared.
        nis: f64,
        /// The gate it exceeded, `χ²_{N−1}(p_gate)`.
        threshold: f64,
    },
    /// Fused only: no burst heard by two UAVs at this step (the emitter silent, or the arrivals lost);
    /// the estimate is the posterior predicted to this step.
    Predicted,
    /// The step could not be estimated; `position` and `covariance` are the previous estimate.
    Failed {
        /// Why.
        reason: String,
    },
}

impl EstimateStatus {
    /// `ok`, `ambiguous`, `rejected` or `failed`.
    pub fn name(&self) -> &'static str {
        match self {
            EstimateStatus::Ok => "ok",
            EstimateStatus::Ambiguous => "ambiguous",
            EstimateStatus::Rejected { .. } => "rejected",
            EstimateStatus::Predicted => "predicted",
            EstimateStatus::Failed { .. } => "failed",
        }
    }
}

/// One estimate of the emitter.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimateOut {
    /// ẑ, metres.
    pub position: Vector2<f64>,
    /// Its covariance M, m² (snapshot: Chan's first-order covariance, `F⁻¹(ẑ)` for three UAVs; fused:
    /// the posterior's position block).
    pub covariance: Matrix2<f64>,
    /// How it came about.
    pub status: EstimateStatus,
    /// The physically valid solutions of this step's Chan solve (two when ambiguous or resolved by the
    /// prior; empty when Chan was not run or failed).
    pub candidates: Vec<Vector2<f64>>,
    /// Fused: the whole posterior after this step (velocity and cross-covariances included).
    pub posterior: Option<Posterior>,
    /// Fused: the snapshot's normalised innovation squared at the prediction (`None` for a Chan fix).
    pub nis: Option<f64>,
    /// Fused: the track's counters up to this one (rejections in a row, bursts fused whole, arrivals
    /// dropped burst after burst; see [`crate::track`]).
    pub track: TrackCounters,
    /// The UAVs whose arrival the step held (bit i: UAV i).
    pub heard: u8,
    /// The arrivals dropped as outliers (bit i: UAV i; see [`crate::outliers`]).
    pub outliers: u8,
    /// The consider covariance of the persistent GNSS and clock errors, `S Σ_β Sᵀ` of
    /// [`EstimateOut::sensitivity`], m² (zero without them; see [`tdoa::consider`]): not part of the
    /// fused state, added to it wherever the uncertainty of the emitter is used
    /// ([`EstimateOut::total_covariance`]).
    pub bias_cov: Matrix2<f64>,
    /// How the estimate depends on each UAV's flight-long range bias, `S = ∂(x̂ − x)/∂β`
    /// ([`tdoa::consider`]); `None` before any fix. Fused: part of the state the next step starts from.
    pub sensitivity: Option<BiasSensitivity>,
    /// Fused, after an ambiguous fix: the posterior of Chan's other root (with its bias sensitivity),
    /// pending until the next burst decides between the two — part of the state after this step.
    pub alternative: Option<PendingRoot>,
    /// Fused, before the first fix: the two-arrival bursts held for it (the estimator's whole state
    /// until then; empty once there is a fix).
    pub held: Vec<HeldBurst>,
    /// Fused, static emitter, one hypothesis: the track's window after the step ([`window`]; the
    /// estimator's state).
    pub window: Option<window::Window>,
}

impl EstimateOut {
    /// `covariance + bias_cov`: the uncertainty of the position, persistent errors included, m².
    pub fn total_covariance(&self) -> Matrix2<f64> {
        self.covariance + self.bias_cov
    }
}

/// Why no estimate at all could be given.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum EstimatorError {
    /// The step failed and there is no previous estimate to fall back on.
    #[error("no estimate: {0} (and no previous estimate to keep)")]
    NoEstimate(#[source] TdoaError),
    /// No estimate yet because no burst so far reached three UAVs (a silent emitter, lost arrivals):
    /// not a failure of the geometry — the next burst may give the first fix.
    #[error("no fix yet: this step's burst reached {heard} UAV(s), a first fix needs three")]
    NoFixYet {
        /// UAVs that heard this step's burst.
        heard: usize,
    },
}
