//! # uavloc-estimation — the run's estimator: sequential fusion, or Chan per snapshot
//!
//! [`Estimator`] turns each step's TDOA snapshot into the estimate the planner and the user see. Two
//! kinds ([`EstimatorKind`], scenario key `estimator`):
//!
//! - `fused` (default): the posterior of the emitter's state given **every** snapshot so far
//!   ([`tdoa::fusion`]: an iterated EKF on the raw range differences, χ²-gated), started from Chan's fix
//!   of the first snapshot that has one. When that fix is ambiguous (three UAVs, two physical roots, no
//!   prior), both roots are carried to the next snapshot, fused into each, and the root with the smaller
//!   innovation is kept (the first snapshots together decide; a process that takes over from the
//!   published estimate in between continues with the root reported). A snapshot whose innovation
//!   fails the gate is not fused and is reported as [`EstimateStatus::Rejected`] (the posterior is then the prediction). Emitter models
//!   `static` and `constant_velocity` ([`tdoa::motion`]).
//! - `snapshot` (the paper, Section 2, eqs. 10–30): Chan's fix of each snapshot alone; the previous
//!   estimate is the prior that resolves the two-root ambiguity of the three-UAV case.
//!
//! When a step cannot be estimated the previous estimate is kept and reported as
//! [`EstimateStatus::Failed`]. The output never holds a NaN.
//!
//! Pure functions over plain data, no IPC: the estimator process (crate `uavloc-estimator`) and the
//! in-process closed loop (crate `uavloc-closed-loop`) both run an [`Estimator`].
//!
//! Units: metres (positions), m² (covariance), m/s (velocity).

use nalgebra::{Matrix2, Vector2};
use tdoa::consider::BiasSensitivity;
use tdoa::fusion::{Outcome, Posterior};
use tdoa::{Arrivals, NoiseModel, RangeDiffs, TdoaError};

mod config;
mod estimate;
mod hypotheses;
pub mod outliers;
mod start;
pub mod track;
pub mod window;

pub use config::EstimatorConfig;
pub use estimate::{EstimateOut, EstimateStatus, EstimatorError};
pub use hypotheses::{PendingRoot, RESOLVE_NIS_MARGIN};
pub use start::{HeldBurst, MAX_HELD_BURSTS};

#[cfg(test)]
mod consistency_tests;
#[cfg(test)]
mod test_support;
pub use outliers::OutlierPolicy;
pub use track::{CONFIRM_BURSTS, DEMOTE_DROP_RUN, DropStreak, REJECTED_RUN_RESTART, TrackCounters};

pub use tdoa::EmitterModel;
pub use tdoa::fusion::EstimatorKind;

/// `S Σ_β Sᵀ` (position block) of the sensitivity `s` with the burst's per-UAV bias σ; zero without.
fn bias_cov(s: Option<&BiasSensitivity>, a: &Arrivals) -> Matrix2<f64> {
    s.map_or_else(Matrix2::zeros, |s| s.position_covariance(a.bias_sigmas()))
}

/// The estimator of one run.
#[derive(Debug, Clone, PartialEq)]
pub struct Estimator {
    config: EstimatorConfig,
    prior: Option<Vector2<f64>>,
    previous: Option<(Vector2<f64>, Matrix2<f64>)>,
    posterior: Option<Posterior>,
    /// Fused, after an ambiguous start: the posterior of Chan's other root (and its bias sensitivity),
    /// until the next snapshot decides between the two.
    alternative: Option<PendingRoot>,
    /// Fused: the track's counters ([`track`]).
    track: TrackCounters,
    last_step: Option<u64>,
    /// Fused: the posterior's dependence on the flight-long biases ([`tdoa::consider`]).
    sensitivity: Option<BiasSensitivity>,
    /// Fused, before the first fix: the bursts heard by two UAVs only (one range difference each, no
    /// fix on their own), with their steps, fused into the first fix when it comes (the newest
    /// [`MAX_HELD_BURSTS`]).
    held: Vec<HeldBurst>,
    /// Fused, static emitter, one hypothesis: the track's last bursts kept raw ([`window`]).
    window: Option<window::Window>,
}

impl Default for Estimator {
    fn default() -> Self {
        Self::snapshot()
    }
}

impl Estimator {
    /// A fresh estimator of `config`.
    pub fn with_config(config: EstimatorConfig) -> Self {
        Self {
            config,
            prior: None,
            previous: None,
            posterior: None,
            alternative: None,
            track: TrackCounters::default(),
            last_step: None,
            sensitivity: None,
            held: Vec::new(),
            window: None,
        }
    }

    /// A fresh snapshot (paper) estimator with no prior: the first three-UAV solve may be ambiguous.
    pub fn snapshot() -> Self {
        Self::with_config(EstimatorConfig::snapshot())
    }

    /// A fresh snapshot estimator (the paper's; kept name).
    pub fn new() -> Self {
        Self::snapshot()
    }

    /// A snapshot estimator whose first solve uses `prior` (metres) to resolve the three-UAV ambiguity.
    pub fn with_prior(prior: Vector2<f64>) -> Self {
        let mut e = Self::snapshot();
        e.prior = prior.iter().all(|v| v.is_finite()).then_some(prior);
        e
    }

    /// An estimator of `config` that continues after its estimate of step `step` (e.g. one taking over
    /// from another process, or rebuilt from a published estimate): position, covariance and, fused,
    /// the whole posterior. The same state as the estimator that produced them.
    pub fn resume(
        config: EstimatorConfig,
        step: u64,
        position: Vector2<f64>,
        covariance: Matrix2<f64>,
        posterior: Option<Posterior>,
    ) -> Self {
        let posterior = if config.kind == EstimatorKind::Fused { posterior } else { None };
        Self {
            config,
            prior: None,
            previous: Some((position, covariance)),
            posterior,
            alternative: None,
            track: TrackCounters::default(),
            last_step: Some(step),
            sensitivity: None,
            held: Vec::new(),
            window: None,
        }
    }

    /// This estimator with the posterior's bias sensitivity `s` behind it (the state of an estimate's
    /// `sensitivity`; `None`: no dependence yet).
    pub fn with_sensitivity(mut self, s: Option<BiasSensitivity>) -> Self {
        self.sensitivity = s;
        self
    }

    /// Fused: the posterior's dependence on the flight-long biases (see [`EstimateOut::sensitivity`]).
    pub fn sensitivity(&self) -> Option<BiasSensitivity> {
        self.sensitivity
    }

    /// This estimator with the pending second root `alt` behind it (the state of an estimate's
    /// `alternative`; fused only).
    pub fn with_alternative(mut self, alt: Option<PendingRoot>) -> Self {
        if self.config.kind == EstimatorKind::Fused {
            self.alternative = alt;
        }
        self
    }

    /// Fused, after an ambiguous fix: the pending second root (see [`EstimateOut::alternative`]).
    pub fn alternative(&self) -> Option<PendingRoot> {
        self.alternative
    }

    /// This estimator with the track counters `t` behind it (the state of an estimate's `track`;
    /// `confirmed` clamped to [`CONFIRM_BURSTS`]).
    pub fn with_track(mut self, t: TrackCounters) -> Self {
        self.track = t.clamped();
        self
    }

    /// This estimator with the two-arrival bursts `held` kept for its first fix (the state of an
    /// estimate's `held`; fused only, the newest [`MAX_HELD_BURSTS`]).
    pub fn with_held(mut self, held: &[HeldBurst]) -> Self {
        if self.config.kind == EstimatorKind::Fused {
            self.held = held[held.len().saturating_sub(MAX_HELD_BURSTS)..].to_vec();
        }
        self
    }

    /// This estimator with the track's window `w` (the state of an estimate's `window`; fused, static
    /// emitter).
    pub fn with_window(mut self, w: Option<window::Window>) -> Self {
        self.window = if self.config.kind == EstimatorKind::Fused { w } else { None };
        self
    }

    /// Fused, static emitter: the track's window.
    pub fn window(&self) -> Option<&window::Window> {
        self.window.as_ref()
    }

    /// Fused, before the first fix: the two-arrival bursts held for it.
    pub fn held(&self) -> &[HeldBurst] {
        &self.held
    }

    /// Fused: the track's counters ([`track`]).
    pub fn track(&self) -> TrackCounters {
        self.track
    }

    /// The configuration.
    pub fn config(&self) -> &EstimatorConfig {
        &self.config
    }

    /// The prior of the next Chan solve: the previous estimate, else the initial prior.
    pub fn prior(&self) -> Option<Vector2<f64>> {
        self.previous.map(|(p, _)| p).or(self.prior)
    }

    /// The previous estimate and its covariance.
    pub fn previous(&self) -> Option<(Vector2<f64>, Matrix2<f64>)> {
        self.previous
    }

    /// Fused: the posterior after the last step.
    pub fn posterior(&self) -> Option<Posterior> {
        self.posterior
    }

    /// The last step estimated.
    pub fn last_step(&self) -> Option<u64> {
        self.last_step
    }

    /// Estimates the emitter at `step` from range differences `d` (`d_i = r_i − r_0`, metres) measured
    /// by UAVs at `uavs` (metres, index 0 the reference) with range noise `noise`: a burst every UAV
    /// heard ([`estimate_burst`](Self::estimate_burst) of [`Arrivals::all`]).
    pub fn estimate(
        &mut self,
        step: u64,
        uavs: &[Vector2<f64>],
        d: &RangeDiffs,
        noise: &NoiseModel,
    ) -> Result<EstimateOut, EstimatorError> {
        let pts: Vec<[f64; 2]> = uavs.iter().map(|p| [p.x, p.y]).collect();
        match Arrivals::all(&pts, d, noise) {
            Ok(a) => self.estimate_burst(step, &a),
            Err(e) => self.failed(step, e),
        }
    }

    /// Estimates the emitter at `step` from the burst `a`: the arrivals of the UAVs that heard it (any
    /// two or more; fewer, and the estimate is the posterior predicted to this step, status
    /// [`EstimateStatus::Predicted`]). Steps are snapshot intervals: the constant-velocity model
    /// predicts over `step − last step` of them. Outlying arrivals are dropped per the configured
    /// [`OutlierPolicy`].
    ///
    /// On failure the previous estimate is returned with [`EstimateStatus::Failed`]; only when there is
    /// none is the result an error.
    pub fn estimate_burst(&mut self, step: u64, a: &Arrivals) -> Result<EstimateOut, EstimatorError> {
        if a.heard_count() < 2 {
            return self.silent(step, a);
        }
        if a.heard_count() < 3 && self.posterior.is_none() && self.previous.is_none() {
            // Two arrivals and nothing to fuse them into: kept for the first fix, which they then refine.
            if self.config.kind == EstimatorKind::Fused {
                if self.held.len() == MAX_HELD_BURSTS {
                    self.held.remove(0);
                }
                self.held.push((step, *a));
            }
            return self.silent(step, a);
        }
        let posterior_before = self.posterior;
        // The bursts held for a first fix, which a window opened on an ambiguous fix keeps raw.
        let held_before: Vec<HeldBurst> = if self.posterior.is_none() { self.held.clone() } else { Vec::new() };
        let elapsed = self.last_step.map_or(0, |l| step.saturating_sub(l));
        let dynamics = self.config.dynamics;
        let predicted_s =
            |s: Option<BiasSensitivity>| s.map_or(BiasSensitivity::zero(), |s| s.predict(&dynamics, elapsed));
        let s_pred = predicted_s(self.sensitivity);
        let result = match (self.config.kind, self.posterior, self.alternative.take()) {
            (EstimatorKind::Fused, Some(post), Some((other, other_s))) => {
                let resolved = self.resolve(
                    (&post.predict(&dynamics, elapsed), &s_pred),
                    (&other.predict(&dynamics, elapsed), &predicted_s(other_s)),
                    a,
                );
                resolved.map(|(out, pending)| {
                    self.alternative = pending;
                    out
                })
            }
            (EstimatorKind::Fused, Some(post), None) => self.fuse(&post.predict(&dynamics, elapsed), &s_pred, a),
            _ => self.solve(a).map(|(out, other)| {
                let held = std::mem::take(&mut self.held);
                self.alternative = other.map(|(p, s)| self.fold_held(p, s, step, &held));
                match out.posterior {
                    Some(p) if !held.is_empty() => {
                        let (p, s) = self.fold_held(p, out.sensitivity, step, &held);
                        EstimateOut {
                            position: p.position(),
                            covariance: p.position_cov(),
                            posterior: Some(p),
                            sensitivity: s,
                            ..out
                        }
                    }
                    _ => out,
                }
            }),
        };
        self.last_step = Some(step);
        // Too many rejections in a row: the posterior has lost the emitter; start again from Chan as at the
        // start, without a prior — the lost posterior's position would pick the root nearest the track
        // that was just refuted (a wrong root, found again): an ambiguous fix keeps both roots pending
        // until a burst decides.
        let result = match result {
            Ok(out) if matches!(out.status, EstimateStatus::Rejected { .. }) => {
                if self.track.rejected() {
                    self.prior = None;
                    self.previous = None;
                    match self.solve(a) {
                        // A burst that cannot vouch for itself (three arrivals: no redundancy; or one
                        // whose own residual shows an outlier) restarts the track but keeps the old one
                        // pending beside it, where the fix has one root and nothing else is pending: it is
                        // the burst the track rejected, and where arrivals come by reflections it is as
                        // likely to be corrupted as the track to be lost. The next bursts decide between
                        // the two (`resolve`), so a reflection cannot throw a good track away for good.
                        Ok((fresh, None))
                            if self.alternative.is_none()
                                && out.posterior.is_some()
                                && !self.vouches_for_itself(a, &fresh) =>
                        {
                            self.alternative = out.posterior.map(|p| (p, out.sensitivity));
                            self.track = TrackCounters::default();
                            Ok(fresh)
                        }
                        Ok((fresh, other)) => {
                            self.alternative = other;
                            self.track = TrackCounters::default();
                            Ok(fresh)
                        }
                        Err(_) => Ok(out),
                    }
                } else {
                    Ok(out)
                }
            }
            Ok(out) if out.posterior.is_some() => {
                // A fused burst with nothing dropped confirms the track; a new Chan fix starts one.
                self.track.fused(out.nis.is_none(), a.heard_mask(), out.outliers);
                Ok(out)
            }
            other => other,
        }
        .map(|mut out| {
            out.track = self.track;
            out.heard = a.heard_mask();
            out.bias_cov = bias_cov(out.sensitivity.as_ref(), a);
            out
        });
        match result {
            Ok(mut out) => {
                self.relinearise(step, a, &mut out, posterior_before, &held_before);
                out.window = self.window.clone();
                self.previous = Some((out.position, out.covariance));
                if out.posterior.is_some() {
                    self.posterior = out.posterior;
                    self.sensitivity = out.sensitivity;
                }
                out.alternative = self.alternative();
                Ok(out)
            }
            Err(e) => {
                // Fused: the state moves on as predicted (unchanged for a static emitter).
                if let Some(post) = self.posterior {
                    self.posterior = Some(post.predict(&self.config.dynamics, elapsed));
                    self.sensitivity = self.sensitivity.map(|s| s.predict(&self.config.dynamics, elapsed));
                }
                self.keep_previous(e.to_string(), a.heard_mask()).ok_or(EstimatorError::NoEstimate(e))
            }
        }
    }

    /// The previous estimate, reported as failed for `reason`; `None` when there is none.
    fn keep_previous(&self, reason: String, heard: u8) -> Option<EstimateOut> {
        let (position, covariance) = self.previous?;
        Some(EstimateOut {
            position,
            covariance,
            status: EstimateStatus::Failed { reason },
            candidates: Vec::new(),
            posterior: None,
            nis: None,
            track: self.track,
            heard,
            outliers: 0,
            bias_cov: Matrix2::zeros(),
            sensitivity: self.sensitivity,
            alternative: self.alternative(),
            held: self.held.clone(),
            window: self.window.clone(),
        })
    }

    /// A step whose input could not even be formed into a burst (e.g. a bad geometry).
    fn failed(&mut self, step: u64, e: TdoaError) -> Result<EstimateOut, EstimatorError> {
        let elapsed = self.last_step.map_or(0, |l| step.saturating_sub(l));
        self.last_step = Some(step);
        if let Some(post) = self.posterior {
            self.posterior = Some(post.predict(&self.config.dynamics, elapsed));
            self.sensitivity = self.sensitivity.map(|s| s.predict(&self.config.dynamics, elapsed));
        }
        self.keep_previous(e.to_string(), 0).ok_or(EstimatorError::NoEstimate(e))
    }

    /// A step without a burst heard by two UAVs: the fused posterior predicted to it (status
    /// `predicted`; a pending second root is predicted with it); without a posterior, the previous
    /// estimate kept (status `failed`).
    fn silent(&mut self, step: u64, a: &Arrivals) -> Result<EstimateOut, EstimatorError> {
        let elapsed = self.last_step.map_or(0, |l| step.saturating_sub(l));
        self.last_step = Some(step);
        let dynamics = self.config.dynamics;
        self.alternative =
            self.alternative.map(|(o, s)| (o.predict(&dynamics, elapsed), s.map(|s| s.predict(&dynamics, elapsed))));
        match (self.config.kind, self.posterior) {
            (EstimatorKind::Fused, Some(post)) => {
                let pred = post.predict(&dynamics, elapsed);
                self.posterior = Some(pred);
                self.sensitivity = self.sensitivity.map(|s| s.predict(&dynamics, elapsed));
                self.previous = Some((pred.position(), pred.position_cov()));
                Ok(EstimateOut {
                    position: pred.position(),
                    covariance: pred.position_cov(),
                    status: EstimateStatus::Predicted,
                    candidates: Vec::new(),
                    posterior: Some(pred),
                    nis: None,
                    track: self.track,
                    heard: a.heard_mask(),
                    outliers: 0,
                    bias_cov: bias_cov(self.sensitivity.as_ref(), a),
                    sensitivity: self.sensitivity,
                    alternative: self.alternative(),
                    held: Vec::new(),
                    window: self.window.clone(),
                })
            }
            _ => {
                let reason =
                    format!("no burst heard by enough UAVs ({} heard) and no posterior to predict", a.heard_count());
                self.keep_previous(reason, a.heard_mask()).ok_or(EstimatorError::NoFixYet { heard: a.heard_count() })
            }
        }
    }

    /// Fuses `a` into the prediction `predicted`, whose bias sensitivity is `s_pred`.
    fn fuse(&self, predicted: &Posterior, s_pred: &BiasSensitivity, a: &Arrivals) -> Result<EstimateOut, TdoaError> {
        let config = self.config;
        // A provisional track drops only the arrivals the burst itself shows to be outliers (see
        // CONFIRM_BURSTS), never the ones that merely disagree with the track.
        let provisional = self.track.provisional();
        let policy = if provisional { OutlierPolicy::Snapshot } else { config.outliers };
        let mut up = outliers::fuse_burst(predicted, a, |m| config.gate(m), policy)?;
        if provisional
            && config.outliers == OutlierPolicy::Arrival
            && matches!(up.update.outcome, Outcome::Rejected { .. })
        {
            let gate = |m| config.gate(m);
            let rescued = match outliers::fuse_self_checked(predicted, a, gate)? {
                Some(checked) => Some(checked),
                None if outliers::shows_an_outlier(a, Some(predicted.position()), gate) => {
                    outliers::fuse_without_late(predicted, a, gate, 0, (a.heard_count() - 1) / 2)?
                }
                None => None,
            };
            if let Some(rescued) = rescued {
                up = rescued;
            }
        }
        let (status, nis) = match up.update.outcome {
            Outcome::Fused { nis, .. } => (EstimateStatus::Ok, nis),
            Outcome::Rejected { nis, threshold } => (EstimateStatus::Rejected { nis, threshold }, nis),
        };
        let post = up.update.posterior;
        // The arrivals fused: those heard less those dropped.
        let used = a.without_all(up.dropped);
        let sensitivity = match status {
            EstimateStatus::Ok => used.heard()?.and_then(|h| {
                let q = tdoa::fusion::update_noise(predicted, &h.sensors)?;
                s_pred.after_update_with(&predicted.cov(), predicted.model().dim(), &h, &post.position(), &q)
            }),
            _ => Some(*s_pred),
        };
        Ok(EstimateOut {
            position: post.position(),
            covariance: post.position_cov(),
            status,
            candidates: Vec::new(),
            posterior: Some(post),
            nis: Some(nis),
            track: TrackCounters::default(),
            heard: a.heard_mask(),
            outliers: up.dropped,
            bias_cov: Matrix2::zeros(),
            sensitivity,
            alternative: None,
            held: Vec::new(),
            // The window after the step is the estimator's to set (`estimate_burst`).
            window: None,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::*;

    #[test]
    fn failure_keeps_the_previous_estimate() {
        let z = Vector2::new(25000.0, 15000.0);
        let uavs = nominal();
        let mut est = Estimator::new();
        let first = est.estimate(0, &uavs, &diffs(&uavs, z), &noise(3)).unwrap();
        // Collinear UAVs: Chan cannot solve.
        let line = vec![Vector2::new(0.0, 0.0), Vector2::new(1000.0, 0.0), Vector2::new(2000.0, 0.0)];
        let out = est.estimate(1, &line, &diffs(&line, z), &noise(3)).unwrap();
        assert!(matches!(out.status, EstimateStatus::Failed { ref reason } if !reason.is_empty()));
        assert_eq!(out.position, first.position);
        assert_eq!(out.covariance, first.covariance);
        assert!(out.position.iter().chain(out.covariance.iter()).all(|v| v.is_finite()));
        // Coincident UAVs and a wrong count fail the same way.
        let twin = vec![uavs[0], uavs[0], uavs[2]];
        assert!(matches!(
            est.estimate(2, &twin, &diffs(&uavs, z), &noise(3)).unwrap().status,
            EstimateStatus::Failed { .. }
        ));
        assert!(matches!(
            est.estimate(0, &uavs[..2], &diffs(&uavs, z), &noise(3)).unwrap().status,
            EstimateStatus::Failed { .. }
        ));
        // With no previous estimate the failure is an error.
        assert!(matches!(
            Estimator::new().estimate(0, &line, &diffs(&line, z), &noise(3)),
            Err(EstimatorError::NoEstimate(_))
        ));
    }
}
