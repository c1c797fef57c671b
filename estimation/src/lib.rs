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
use tdoa::fusion::{self, DEFAULT_GATE_PROBABILITY, Outcome, Posterior};
use tdoa::{Arrivals, Dynamics, NoiseModel, RangeDiffs, TdoaError};

pub mod outliers;
pub mod track;
pub mod window;

#[cfg(test)]
mod consistency_tests;
pub use outliers::OutlierPolicy;
use thiserror::Error;
pub use track::{CONFIRM_BURSTS, DEMOTE_DROP_RUN, DropStreak, REJECTED_RUN_RESTART, TrackCounters};

pub use tdoa::EmitterModel;
pub use tdoa::fusion::EstimatorKind;

/// How much larger (χ², one burst) the NIS of one of an ambiguous fix's two roots must be than the
/// other's for the burst to drop it: a likelihood ratio of `e^(9/2)` ≈ 90. Below it both roots stay
/// pending. (Decided by the smaller NIS alone, one of 200 random three-UAV runs kept the mirror root
/// 170 km out, whose NIS was 3.2 against the true root's 4.0, and flew its 120 steps on it.)
pub const RESOLVE_NIS_MARGIN: f64 = 9.0;

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
    /// dropped burst after burst; see [`track`]).
    pub track: TrackCounters,
    /// The UAVs whose arrival the step held (bit i: UAV i).
    pub heard: u8,
    /// The arrivals dropped as outliers (bit i: UAV i; see [`outliers`]).
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

/// A burst heard by two UAVs before the first fix, with its step: held for the first fix.
pub type HeldBurst = (u64, Arrivals);

/// The posterior of Chan's other root after an ambiguous fix, with its bias sensitivity: pending until
/// the next burst decides between the two roots.
pub type PendingRoot = (Posterior, Option<BiasSensitivity>);

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

/// `S Σ_β Sᵀ` (position block) of the sensitivity `s` with the burst's per-UAV bias σ; zero without.
fn bias_cov(s: Option<&BiasSensitivity>, a: &Arrivals) -> Matrix2<f64> {
    s.map_or_else(Matrix2::zeros, |s| s.position_covariance(a.bias_sigmas()))
}

/// What an [`Estimator`] is: its kind, the motion model and the gate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EstimatorConfig {
    /// Fused or snapshot.
    pub kind: EstimatorKind,
    /// The emitter's motion model (fused only).
    pub dynamics: Dynamics,
    /// The χ² gate `χ²_m(p_gate)` (fused only) for m range differences, index m, with the default
    /// [`DEFAULT_GATE_PROBABILITY`]: computed once here, because the quantile is an iterative inversion
    /// (≈ 1.4 µs) and every fused snapshot needs its gate.
    gates: [f64; tdoa::MAX_UAVS],
    /// What a burst that fails the gate costs: itself, or its outlying arrivals ([`OutlierPolicy`]).
    pub outliers: OutlierPolicy,
}

impl EstimatorConfig {
    /// The paper's per-step Chan.
    pub fn snapshot() -> Self {
        Self::new(EstimatorKind::Snapshot, Dynamics::fixed())
    }

    /// Fusion under `dynamics` with the default gate.
    pub fn fused(dynamics: Dynamics) -> Self {
        Self::new(EstimatorKind::Fused, dynamics)
    }

    /// `kind` under `dynamics` with the default gate.
    pub fn new(kind: EstimatorKind, dynamics: Dynamics) -> Self {
        let mut gates = [f64::INFINITY; tdoa::MAX_UAVS];
        for (m, gate) in gates.iter_mut().enumerate().skip(1) {
            *gate = fusion::gate_threshold(m, DEFAULT_GATE_PROBABILITY);
        }
        Self { kind, dynamics, gates, outliers: OutlierPolicy::default() }
    }

    /// This configuration with the outlier policy `outliers`.
    pub fn with_outliers(mut self, outliers: OutlierPolicy) -> Self {
        self.outliers = outliers;
        self
    }

    /// The gate of a snapshot of `m` range differences (`+∞`, no gate, outside 1..MAX_UAVS).
    pub fn gate(&self, m: usize) -> f64 {
        self.gates.get(m).copied().unwrap_or(f64::INFINITY)
    }
}

impl Default for EstimatorConfig {
    fn default() -> Self {
        Self::fused(Dynamics::fixed())
    }
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

/// The two-arrival bursts before the first fix an [`Estimator`] keeps for it (the newest).
pub const MAX_HELD_BURSTS: usize = 4;

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

    /// Fused, static emitter, one hypothesis: moves the track's window on with the burst `a` of `step`
    /// (the arrivals `out` kept) and makes `out`'s estimate the window's maximum a posteriori and its
    /// position covariance the window's Gauss–Newton covariance there (`(Λ_b + Σ JᵀQ⁻¹J)⁻¹` at the
    /// estimate: the covariance of the estimate reported, every burst linearised where the estimate is,
    /// not where the filter was when it came). A window of the fix's burst alone keeps the fix's own
    /// covariance (sigma points for three arrivals).
    ///
    /// A new fix opens a window: a fix of four or more arrivals (its outliers dropped) with its burst
    /// raw, after the two-arrival bursts `held` for it; a fix of three at its posterior (a lone, exactly
    /// determined fix re-linearised raw makes a worse estimate where the later bursts are poor: three
    /// UAVs at loss 0.3, the RMSE at step 5 828 → 1016 m). A fused burst with no window open opens one at
    /// the posterior; `predicted` is the posterior before the burst (a single range difference enters
    /// the window with the linearisation noise it was fused with over it). Other steps leave the window;
    /// a moving emitter or a failed refit close it.
    ///
    /// Two roots of one ambiguous fix: the window opens with the fix's burst raw — the same for either
    /// root — and takes every burst fused while both are pending without a refit; the burst that decides
    /// refits it from the root kept ([`Self::window_through_ambiguity`]). Two hypotheses of a restarted
    /// track (the old posterior pending beside a new fix) close it.
    fn relinearise(
        &mut self,
        step: u64,
        a: &Arrivals,
        out: &mut EstimateOut,
        predicted: Option<Posterior>,
        held: &[HeldBurst],
    ) {
        let Some(post) = out.posterior else { return };
        let fused_static = self.config.kind == EstimatorKind::Fused && post.model() == EmitterModel::Static;
        let kept = a.without_all(out.outliers);
        if fused_static && self.alternative.is_some() {
            self.window = self.window_through_ambiguity((step, kept), out, &post, predicted, held);
            return;
        }
        if !fused_static {
            self.window = None;
            return;
        }
        let next = match (&out.status, out.nis) {
            // A new fix of four or more arrivals (its outliers dropped, so redundant enough to have been
            // checked): its burst raw, after those held for it.
            (EstimateStatus::Ok, None) if kept.heard_count() >= 4 => Some(window::Window::raw(held, (step, kept))),
            // A fix of three: summarised as its posterior, whose covariance is the fix's own (sigma
            // points): a burst a reflection corrupted weighs no more than the filter lets it.
            (EstimateStatus::Ok | EstimateStatus::Ambiguous, None) => window::Window::from_posterior(&post),
            (EstimateStatus::Ok, Some(_)) => match (&self.window, predicted) {
                (Some(w), Some(pred)) => w.pushed(step, window::Window::kept_as_fused(kept, &pred), &post.position()),
                // No window open (a new track, two hypotheses before): it opens at this posterior.
                _ => window::Window::from_posterior(&post),
            },
            _ => return,
        };
        let refitted = next.and_then(|w| {
            let (x, c) = w.estimate(&post.position()).ok()?;
            let mut cov = post.cov();
            if w.holds_more_than_a_fix() {
                cov.fixed_view_mut::<2, 2>(0, 0).copy_from(&c);
            }
            let p = Posterior::new(post.model(), nalgebra::Vector4::new(x.x, x.y, 0.0, 0.0), cov).ok()?;
            Some((p, w))
        });
        match refitted {
            Some((p, w)) => {
                out.position = p.position();
                out.covariance = p.position_cov();
                out.posterior = Some(p);
                self.window = Some(w);
            }
            _ => self.window = None,
        }
    }

    /// The window while two roots of one ambiguous fix are pending: at the fix, its burst raw (the
    /// arrivals `kept`, those `out` did not drop; no summary, which would have to be of one root) after
    /// the two-arrival bursts `held` for it, raw too; a burst fused while both stay pending is pushed raw
    /// as in [`Self::relinearise`], not refitted (the estimate is the root the track is on, `post`).
    /// `None` for two hypotheses of a restarted track — its old window is of the old root only — or once
    /// a fold beyond [`window::WINDOW_BURSTS`] would need one root's estimate.
    ///
    /// Why: a lone three-arrival fix is an exactly determined, strongly curved solution; summarised
    /// as a Gaussian at one root it stays in the track's estimate for good. Kept raw, the burst that
    /// decides the roots re-linearises it at the estimate of the root kept. Measured on 1 600 runs of
    /// five UAVs at loss 0.3 and silence 0.3, the tracks that start on an ambiguous fix: mean NEES of
    /// steps 4–14 2.29 → 2.10, RMSE unchanged (EXPERIMENTS.md, the receiver study).
    fn window_through_ambiguity(
        &self,
        (step, kept): (u64, Arrivals),
        out: &EstimateOut,
        post: &Posterior,
        predicted: Option<Posterior>,
        held: &[HeldBurst],
    ) -> Option<window::Window> {
        match (&out.status, out.nis) {
            (EstimateStatus::Ambiguous, None) => Some(window::Window::raw(held, (step, kept))),
            // Both roots still pending after a fused burst: the burst joins the window raw.
            (EstimateStatus::Ok, Some(_)) => {
                let (w, pred) = (self.window.as_ref()?, predicted?);
                if w.bursts.len() >= window::WINDOW_BURSTS {
                    return None;
                }
                w.pushed(step, window::Window::kept_as_fused(kept, &pred), &post.position())
            }
            // A new fix beside the old track (a restart), or a step that fused nothing.
            (EstimateStatus::Ok, None) => None,
            _ => self.window.clone(),
        }
    }

    /// Whether the burst `a`, whose Chan fix is `fix`, vouches for that fix by itself: the arrivals the
    /// fix kept (its own outliers dropped) are four or more and their residual is within the gate
    /// (`χ²_{m−2}`, one or more degrees of freedom of redundancy).
    fn vouches_for_itself(&self, a: &Arrivals, fix: &EstimateOut) -> bool {
        let kept = a.without_all(fix.outliers);
        kept.heard_count() >= 4 && !outliers::shows_an_outlier(&kept, None, |m| self.config.gate(m))
    }

    /// The first fix's posterior `post` at `step` (bias sensitivity `s`) with the two-arrival bursts
    /// `held` of the steps before it fused in: each burst into the posterior carried back to its step
    /// (`Φ⁻¹`, no process noise; the static model stays as it is) and forward again — for the static
    /// model the posterior of the fix's burst and the held ones together, in any order. A held burst
    /// that fails the gate is left out.
    fn fold_held(
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

    /// After an ambiguous start: fuses the snapshot into both roots' posteriors. The track stays on the
    /// root it follows (`first`) unless the other's innovation is smaller by at least
    /// [`RESOLVE_NIS_MARGIN`] (the likelier root given both snapshots, decisively); the status is that
    /// of the update of the root kept. The other root is dropped only when the burst decides: three or
    /// more arrivals, and its NIS at least [`RESOLVE_NIS_MARGIN`] above the kept root's. Otherwise (a burst
    /// heard by two UAVs only — one range difference, a hyperbola that may pass near both roots — or
    /// two roots that both fit the burst, as the mirror root of three UAVs far away does for many steps)
    /// it is updated too and stays pending (returned beside the estimate), and the next burst chooses
    /// again: a near tie never locks the track onto the wrong root for good.
    fn resolve(
        &self,
        first: (&Posterior, &BiasSensitivity),
        other: (&Posterior, &BiasSensitivity),
        a: &Arrivals,
    ) -> Result<(EstimateOut, Option<PendingRoot>), TdoaError> {
        let nis = |o: &EstimateOut| match o.status {
            EstimateStatus::Rejected { nis, .. } => nis,
            _ => o.nis.unwrap_or(f64::INFINITY),
        };
        match (self.fuse(first.0, first.1, a), self.fuse(other.0, other.1, a)) {
            (Ok(x), Ok(y)) => {
                // The root the track follows (`first`) is kept until the other fits decisively better.
                let switch = nis(&y) + RESOLVE_NIS_MARGIN <= nis(&x);
                let (kept, other) = if switch { (y, x) } else { (x, y) };
                // (Two roots without a finite NIS give NaN: nothing to keep the other for.)
                let gap = nis(&other) - nis(&kept);
                let decides = a.heard_count() >= 3 && (gap.is_nan() || gap >= RESOLVE_NIS_MARGIN);
                let pending = if decides { None } else { other.posterior.map(|p| (p, other.sensitivity)) };
                Ok((kept, pending))
            }
            (Ok(x), Err(_)) => Ok((x, None)),
            (Err(_), Ok(y)) => Ok((y, None)),
            (Err(e), Err(_)) => Err(e),
        }
    }

    /// Chan's fix; fused and ambiguous, also the posterior of the other root (with its bias
    /// sensitivity).
    fn solve(&self, a: &Arrivals) -> Result<(EstimateOut, Option<PendingRoot>), TdoaError> {
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
}

#[cfg(test)]
mod tests {
    use super::*;
    use tdoa::{Sensors, chan};

    fn noise(n: usize) -> NoiseModel {
        NoiseModel::uniform(n, 28.7712).unwrap()
    }

    fn diffs(uavs: &[Vector2<f64>], z: Vector2<f64>) -> RangeDiffs {
        let r: Vec<f64> = uavs.iter().map(|w| (z - w).norm()).collect();
        RangeDiffs::from_slice(&r[1..].iter().map(|ri| ri - r[0]).collect::<Vec<_>>()).unwrap()
    }

    /// A static emitter's posterior at `z` (metres) with variance `var` (m²) on every axis.
    fn static_at(z: Vector2<f64>, var: f64) -> tdoa::Posterior {
        tdoa::Posterior::new(
            EmitterModel::Static,
            nalgebra::Vector4::new(z.x, z.y, 0.0, 0.0),
            nalgebra::Matrix4::identity() * var,
        )
        .unwrap()
    }

    fn nominal() -> Vec<Vector2<f64>> {
        vec![Vector2::new(1500.0, 500.0), Vector2::new(10000.0, 1500.0), Vector2::new(5000.0, 8500.0)]
    }

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
    fn fused_start_resolves_the_ambiguity_with_the_next_snapshot() {
        let (uavs, z, other) = ambiguous_case();
        let d = diffs(&uavs, z);
        // A second geometry, noise-free: it agrees with the truth, not with the other root.
        let moved: Vec<Vector2<f64>> = uavs.iter().map(|p| p + Vector2::new(500.0, 300.0)).collect();
        let d2 = diffs(&moved, z);
        let mut est = Estimator::with_config(EstimatorConfig::fused(Dynamics::fixed()));
        let first = est.estimate(0, &uavs, &d, &noise(3)).unwrap();
        assert_eq!(first.status, EstimateStatus::Ambiguous);
        assert!(est.alternative.is_some());
        let second = est.estimate(1, &moved, &d2, &noise(3)).unwrap();
        assert!((second.position - z).norm() < 1e-3, "picked {:?}, truth {z:?}, other {other:?}", second.position);
        assert_eq!(second.status, EstimateStatus::Ok);
        assert!(est.alternative.is_none());
    }

    #[test]
    fn a_near_tie_keeps_both_roots_until_a_burst_decides() {
        // UAVs that do not move: both roots fit every noise-free burst equally, so no burst decides and
        // the track stays on the root it started on, the other pending. (Decided by the smaller NIS
        // alone, the first such burst dropped one of them: a coin flip that can keep the mirror root for
        // good.) Then a burst from a geometry that tells them apart takes the track to the truth.
        let (uavs, z, other) = ambiguous_case();
        let d = diffs(&uavs, z);
        let mut est = Estimator::with_config(EstimatorConfig::fused(Dynamics::fixed()));
        let first = est.estimate(0, &uavs, &d, &noise(3)).unwrap();
        assert_eq!(first.status, EstimateStatus::Ambiguous);
        for step in 1..6 {
            let out = est.estimate(step, &uavs, &d, &noise(3)).unwrap();
            assert!(est.alternative.is_some(), "step {step}: a tie dropped a root");
            assert!((out.position - first.position).norm() < 1.0, "step {step}: the track jumped roots on a tie");
        }
        let moved: Vec<Vector2<f64>> = uavs.iter().map(|p| p + Vector2::new(500.0, 300.0)).collect();
        let decided = est.estimate(6, &moved, &diffs(&moved, z), &noise(3)).unwrap();
        assert!((decided.position - z).norm() < 1e-3, "picked {:?}, truth {z:?}, other {other:?}", decided.position);
        assert!(est.alternative.is_none());
    }

    #[test]
    fn a_burst_of_two_arrivals_leaves_both_roots_pending() {
        // One range difference is a hyperbola that may pass near both roots: it does not decide, the next
        // burst of three arrivals does.
        let (uavs, z, other) = ambiguous_case();
        let burst = |pos: &[Vector2<f64>], heard: u8| {
            let p: Vec<[f64; 2]> = pos.iter().map(|u| [u.x, u.y]).collect();
            let r: Vec<f64> = pos.iter().map(|u| (z - u).norm()).collect();
            Arrivals::new(&p, &r, heard, &[28.7712; 3], &[0.0; 3]).unwrap()
        };
        let mut est = Estimator::with_config(EstimatorConfig::fused(Dynamics::fixed()));
        let first = est.estimate_burst(0, &burst(&uavs, 0b111)).unwrap();
        assert_eq!(first.status, EstimateStatus::Ambiguous);
        let moved: Vec<Vector2<f64>> = uavs.iter().map(|p| p + Vector2::new(500.0, 300.0)).collect();
        est.estimate_burst(1, &burst(&moved, 0b011)).unwrap();
        let (pending, _) = est.alternative().expect("two arrivals do not decide");
        let roots = [est.posterior().unwrap().position(), pending.position()];
        assert!(roots.iter().any(|r| (r - z).norm() < 50.0), "{roots:?} vs truth {z:?}");
        assert!(roots.iter().any(|r| (r - other).norm() < 50.0), "{roots:?} vs other root {other:?}");
        let third = est.estimate_burst(2, &burst(&moved, 0b111)).unwrap();
        assert!(est.alternative().is_none());
        assert!((third.position - z).norm() < 1e-3, "picked {:?}, truth {z:?}", third.position);
    }

    #[test]
    fn a_redundant_fix_opens_a_raw_window_whose_covariance_is_reported() {
        // Five UAVs, noisy arrivals. The fix (five arrivals) opens a window of its burst alone and keeps
        // the fix's covariance; the next burst (UAV 3 lost) is refitted with it raw, and the covariance
        // reported is the inverse of both bursts' Fisher information at the estimate reported.
        let z = Vector2::new(25_000.0, 15_000.0);
        let start = [[1500.0, 500.0], [10_000.0, 1500.0], [5000.0, 8500.0], [-2000.0, 6000.0], [8000.0, -4000.0]];
        let offsets = [12.0, -35.0, 20.0, 41.0, -8.0];
        let burst = |shift: [f64; 2], heard: u8, k: usize| {
            let p: Vec<[f64; 2]> = start.iter().map(|u| [u[0] + shift[0], u[1] + shift[1]]).collect();
            let r: Vec<f64> = p
                .iter()
                .enumerate()
                .map(|(i, u)| (z - Vector2::new(u[0], u[1])).norm() + offsets[(i + k) % 5])
                .collect();
            Arrivals::new(&p, &r, heard, &[28.7712; 5], &[0.0; 5]).unwrap()
        };
        let mut est = Estimator::with_config(EstimatorConfig::fused(Dynamics::fixed()));
        let fix = est.estimate_burst(0, &burst([0.0, 0.0], 0b11111, 0)).unwrap();
        assert_eq!(fix.status, EstimateStatus::Ok);
        assert!(!est.window().unwrap().holds_more_than_a_fix(), "{:?}", est.window());
        assert_eq!(fix.covariance, fix.posterior.unwrap().position_cov());
        let second = burst([2000.0, 1500.0], 0b10111, 1);
        let out = est.estimate_burst(1, &second).unwrap();
        assert_eq!(out.status, EstimateStatus::Ok);
        let w = est.window().unwrap();
        assert_eq!((w.base, w.bursts.len()), (tdoa::window::Information::none(), 2));
        let (map, _) = w.estimate(&out.position).unwrap();
        assert!((map - out.position).norm() < 1e-6);
        let info = |a: &Arrivals| tdoa::fim::fim(&a.heard().unwrap().unwrap().sensors, &out.position).unwrap();
        let expected = (info(&burst([0.0, 0.0], 0b11111, 0)) + info(&second)).try_inverse().unwrap();
        assert!((out.covariance - expected).norm() < 1e-9 * expected.norm(), "{} vs {expected}", out.covariance);
        assert_eq!(out.covariance, out.posterior.unwrap().position_cov());
    }

    #[test]
    fn the_window_spans_an_ambiguity_raw_and_the_deciding_burst_refits_it() {
        // Noisy arrivals: the fix's burst enters the window raw (no summary of one root) and stays there
        // through a two-arrival burst that leaves both roots pending; the burst that decides refits the
        // three raw bursts, so the estimate is their maximum a posteriori — not the filter's mean, which
        // linearised the fix at Chan's root.
        let (uavs, z, other) = ambiguous_case();
        let noisy = [0.0, 23.0, -31.0];
        let burst = |pos: &[Vector2<f64>], heard: u8, k: usize| {
            let p: Vec<[f64; 2]> = pos.iter().map(|u| [u.x, u.y]).collect();
            let r: Vec<f64> = pos.iter().enumerate().map(|(i, u)| (z - u).norm() + noisy[(i + k) % 3]).collect();
            Arrivals::new(&p, &r, heard, &[28.7712; 3], &[0.0; 3]).unwrap()
        };
        let mut est = Estimator::with_config(EstimatorConfig::fused(Dynamics::fixed()));
        let first = est.estimate_burst(0, &burst(&uavs, 0b111, 0)).unwrap();
        assert_eq!(first.status, EstimateStatus::Ambiguous);
        let w = est.window().expect("a window opens on an ambiguous fix");
        assert_eq!((w.base, w.bursts.len()), (tdoa::window::Information::none(), 1));
        let moved: Vec<Vector2<f64>> = uavs.iter().map(|p| p + Vector2::new(500.0, 300.0)).collect();
        let pending = est.estimate_burst(1, &burst(&moved, 0b011, 1)).unwrap();
        assert!(est.alternative().is_some(), "two arrivals do not decide");
        assert_eq!(est.window().map(|w| w.bursts.len()), Some(2), "the pending burst joins the window");
        assert_eq!(pending.position, est.posterior().unwrap().position(), "no refit while both are pending");
        let far: Vec<Vector2<f64>> = uavs.iter().map(|p| p + Vector2::new(-900.0, 1400.0)).collect();
        let decided = est.estimate_burst(2, &burst(&far, 0b111, 2)).unwrap();
        assert!(est.alternative().is_none());
        let w = est.window().expect("the window goes on after the decision");
        assert_eq!(w.bursts.iter().map(|(k, _)| *k).collect::<Vec<_>>(), vec![0, 1, 2]);
        let (map, _) = w.estimate(&decided.position).unwrap();
        assert!((map - decided.position).norm() < 1e-6, "{map} vs {}", decided.position);
        assert!(
            (decided.position - z).norm() < (decided.position - other).norm(),
            "picked {:?}, truth {z:?}, other {other:?}",
            decided.position
        );
    }

    #[test]
    fn a_track_lost_on_the_wrong_root_restarts_with_both_roots_pending() {
        // Three UAVs, a tight posterior on the mirror root: bursts from a geometry that tells the roots
        // apart reject it; the restart's burst comes from a geometry where both roots fit, so Chan's fix is
        // ambiguous. Resolved by the lost track's position it would find the mirror root again; without a
        // prior both stay pending and the next telling burst takes the track to the truth.
        let (uavs, z, other) = ambiguous_case();
        let moved: Vec<Vector2<f64>> = uavs.iter().map(|p| p + Vector2::new(500.0, 300.0)).collect();
        let post = static_at(other, 100.0);
        let config = EstimatorConfig::fused(Dynamics::fixed());
        let mut est = Estimator::resume(config, 0, other, Matrix2::identity() * 100.0, Some(post));
        for k in 1..=2u64 {
            let out = est.estimate(k, &moved, &diffs(&moved, z), &noise(3)).unwrap();
            assert!(matches!(out.status, EstimateStatus::Rejected { .. }), "{:?}", out.status);
        }
        // The restart's burst: from a geometry where Chan's fix is ambiguous, its mirror root nearer the
        // lost track than the truth is, and the lost track rejected.
        let sensors_at =
            |pos: &[Vector2<f64>]| Sensors::new(&pos.iter().map(|u| [u.x, u.y]).collect::<Vec<_>>(), noise(3)).unwrap();
        let mirror_of = |pos: &[Vector2<f64>]| {
            let sol = chan(&sensors_at(pos), &diffs(pos, z), None).ok()?;
            let far = sol.candidates.iter().copied().find(|c| (c - z).norm() > 1000.0)?;
            (sol.ambiguous && sol.candidates.len() == 2).then_some(far)
        };
        let telling = (0..400)
            .map(|k| {
                let a = 0.37 * k as f64;
                let shift = Vector2::new(a.cos(), a.sin()) * (100.0 + 10.0 * k as f64);
                uavs.iter().map(|p| p + shift).collect::<Vec<_>>()
            })
            .find(|pos| {
                let rejected = tdoa::fusion::fuse(&post, &sensors_at(pos), &diffs(pos, z), config.gate(2))
                    .is_ok_and(|u| matches!(u.outcome, tdoa::fusion::Outcome::Rejected { .. }));
                rejected && mirror_of(pos).is_some_and(|m| (m - other).norm() < (z - other).norm())
            })
            .expect("a geometry whose mirror root lies nearer the lost track, which it rejects");
        let restart = est.estimate(3, &telling, &diffs(&telling, z), &noise(3)).unwrap();
        assert_eq!(restart.status, EstimateStatus::Ambiguous, "the restart chose a root: {:?}", restart.position);
        assert!(est.alternative.is_some());
        let next = est.estimate(4, &moved, &diffs(&moved, z), &noise(3)).unwrap();
        assert!((next.position - z).norm() < 1e-3, "picked {:?}, truth {z:?}, mirror {other:?}", next.position);
    }

    #[test]
    fn a_lost_posterior_restarts_from_chan_after_three_rejections() {
        // A posterior 5 km off with a tight covariance (e.g. a jump of the emitter): noise-free snapshots
        // of the truth are rejected twice, the third rejection in a row restarts from Chan (4 UAVs: unique).
        let z = Vector2::new(25000.0, 15000.0);
        let mut uavs = nominal();
        uavs.push(Vector2::new(0.0, 9000.0));
        let wrong = z + Vector2::new(5000.0, -3000.0);
        let post = static_at(wrong, 100.0);
        let mut est = Estimator::resume(
            EstimatorConfig::fused(Dynamics::fixed()),
            0,
            wrong,
            Matrix2::identity() * 100.0,
            Some(post),
        );
        let d = diffs(&uavs, z);
        for k in 1..=2u8 {
            let out = est.estimate(u64::from(k), &uavs, &d, &noise(4)).unwrap();
            assert!(matches!(out.status, EstimateStatus::Rejected { .. }), "{:?}", out.status);
            assert_eq!(out.track.rejected_run, k);
            assert_eq!(out.position, wrong, "a rejected snapshot leaves the posterior");
        }
        let restart = est.estimate(3, &uavs, &d, &noise(4)).unwrap();
        assert_eq!(restart.status, EstimateStatus::Ok);
        assert_eq!(restart.track.rejected_run, 0);
        assert!((restart.position - z).norm() < 1e-6);
        // Four arrivals whose own residual fits vouch for the fix: the lost track is not kept pending
        // (`a_good_track_restarted_by_reflected_bursts_is_kept_pending_and_wins_back`: three do not).
        assert!(restart.alternative.is_none(), "nothing kept pending beside a fix its own burst vouches for");
        // And it fuses from there.
        let next = est.estimate(4, &uavs, &d, &noise(4)).unwrap();
        assert_eq!((next.status, next.track.rejected_run), (EstimateStatus::Ok, 0));
        assert!((next.position - z).norm() < 1e-6);
        // The count rides the state: an estimator resumed with 2 rejections behind it restarts at the next.
        let mut resumed = Estimator::resume(
            EstimatorConfig::fused(Dynamics::fixed()),
            0,
            wrong,
            Matrix2::identity() * 100.0,
            Some(post),
        )
        .with_track(TrackCounters { rejected_run: 2, ..TrackCounters::default() });
        assert_eq!(resumed.estimate(1, &uavs, &d, &noise(4)).unwrap().track.rejected_run, 0);
    }

    #[test]
    fn a_static_track_s_estimate_is_the_map_of_its_fix_and_its_last_bursts() {
        // Three UAVs flying, each burst with its own range errors: after the first fix, the estimate of
        // every step is the maximum a posteriori of the fix's posterior and the raw bursts since,
        // computed here from scratch; beyond eight bursts the oldest leave the window for its summary.
        let z = Vector2::new(25_000.0, 15_000.0);
        let at = |k: f64| -> Vec<Vector2<f64>> {
            nominal()
                .iter()
                .enumerate()
                .map(|(i, p)| p + Vector2::new(350.0 * k, (120.0 + 90.0 * i as f64) * k))
                .collect()
        };
        let noisy = |k: usize| {
            let uavs = at(k as f64);
            let d = diffs(&uavs, z);
            let e = [[31.0, -12.0], [-25.0, 40.0], [8.0, -36.0], [-44.0, 17.0], [20.0, 29.0]][k % 5];
            (uavs, RangeDiffs::from_slice(&[d.as_slice()[0] + e[0], d.as_slice()[1] + e[1]]).unwrap())
        };
        let mut est = Estimator::with_config(EstimatorConfig::fused(Dynamics::fixed()));
        let (uavs0, d0) = noisy(0);
        let fix = est.estimate(0, &uavs0, &d0, &noise(3)).unwrap();
        let base = window::Window::from_posterior(&fix.posterior.unwrap()).unwrap().base;
        let mut raw: Vec<(Vec<Vector2<f64>>, RangeDiffs)> = Vec::new();
        for k in 1..=12 {
            let (uavs, d) = noisy(k);
            let out = est.estimate(k as u64, &uavs, &d, &noise(3)).unwrap();
            assert_eq!(out.status, EstimateStatus::Ok);
            raw.push((uavs, d));
            let w = est.window().expect("a static track has a window");
            assert_eq!(w.bursts.len(), k.min(window::WINDOW_BURSTS));
            if k <= window::WINDOW_BURSTS {
                assert_eq!(w.base, base, "nothing folded before the window is full");
                let sensors: Vec<tdoa::Sensors> = raw
                    .iter()
                    .map(|(u, _)| {
                        let pts: Vec<[f64; 2]> = u.iter().map(|p| [p.x, p.y]).collect();
                        tdoa::Sensors::new(&pts, noise(3)).unwrap()
                    })
                    .collect();
                let bursts: Vec<tdoa::window::Burst<'_>> =
                    sensors.iter().zip(&raw).map(|(s, (_, d))| (s, d.as_slice())).collect();
                let (map, cov) = tdoa::window::refit(&base, &bursts, &z).unwrap();
                assert!((out.position - map).norm() < 1e-3, "step {k}: {:?} vs the MAP {map:?}", out.position);
                assert!((out.covariance - cov).norm() < 1e-6 * cov.norm(), "step {k}: {} vs {cov}", out.covariance);
            } else {
                assert_ne!(w.base, base, "the oldest bursts are folded into the summary");
            }
            // The window's mean and covariance, in the estimate and the posterior the next step starts from.
            assert_eq!(out.covariance, out.posterior.unwrap().position_cov());
        }
        // A moving-emitter model keeps no window.
        let cv = Dynamics::new(EmitterModel::ConstantVelocity, 10.0, 0.05, 20.0).unwrap();
        let mut moving = Estimator::with_config(EstimatorConfig::fused(cv));
        for k in 0..3 {
            let (uavs, d) = noisy(k);
            moving.estimate(k as u64, &uavs, &d, &noise(3)).unwrap();
        }
        assert!(moving.window().is_none());
    }

    #[test]
    fn a_good_track_restarted_by_reflected_bursts_is_kept_pending_and_wins_back() {
        // Three UAVs, a confirmed track on the truth: three bursts in a row with two of their three
        // arrivals late (reflections of 500 and 800 m) are rejected, and the third restarts from its own
        // fix — which those reflections corrupted, and which three arrivals cannot show. The old track
        // stays pending beside it, and the next clean burst brings it back.
        let z = Vector2::new(25000.0, 15000.0);
        let uavs = nominal();
        let post = static_at(z, 25.0);
        let confirmed = TrackCounters { confirmed: CONFIRM_BURSTS, ..TrackCounters::default() };
        let resumed = || {
            Estimator::resume(EstimatorConfig::fused(Dynamics::fixed()), 0, z, Matrix2::identity() * 25.0, Some(post))
                .with_track(confirmed)
        };
        let clean = diffs(&uavs, z);
        let c = clean.as_slice();
        let late = RangeDiffs::from_slice(&[c[0] + 500.0, c[1] + 800.0]).unwrap();
        let mut est = resumed();
        for k in 1..=2u64 {
            let out = est.estimate(k, &uavs, &late, &noise(3)).unwrap();
            assert!(matches!(out.status, EstimateStatus::Rejected { .. }), "{:?}", out.status);
        }
        let restart = est.estimate(3, &uavs, &late, &noise(3)).unwrap();
        assert!((restart.position - z).norm() > 300.0, "the restart's fix is the corrupted burst's");
        let (pending, _) = restart.alternative.expect("the old track is kept pending");
        assert!((pending.position() - z).norm() < 1e-6);
        let back = est.estimate(4, &uavs, &clean, &noise(3)).unwrap();
        assert_eq!(back.status, EstimateStatus::Ok);
        assert!((back.position - z).norm() < 1.0, "the clean burst took the old track back: {:?}", back.position);
        assert!(back.alternative.is_none(), "a clean burst of three arrivals decides");
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

    #[test]
    fn a_confirmed_track_that_drops_the_same_uav_burst_after_burst_is_made_provisional_and_restarted() {
        // A confirmed track 3 km off on the hyperbola of UAVs 1 and 2 through the truth (inside the
        // triangle of the UAVs, where a burst sees 3 km clearly): every clean burst
        // fails its gate, and dropping UAV0's (direct) arrival makes the other two fit the wrong track.
        let z = Vector2::new(6000.0, 4000.0);
        let uavs = nominal();
        let rd12 = |w: Vector2<f64>| (w - uavs[1]).norm() - (w - uavs[2]).norm();
        let config = EstimatorConfig::fused(Dynamics::fixed());
        let track_at = |w: Vector2<f64>| {
            let post = static_at(w, 100.0);
            Estimator::resume(config, 0, w, Matrix2::identity() * 100.0, Some(post))
                .with_track(TrackCounters { confirmed: CONFIRM_BURSTS, ..TrackCounters::default() })
        };
        let d = diffs(&uavs, z);
        // The points 3 km from the truth on that hyperbola (bisection of rd12 around the circle); the one
        // whose first burst drops UAV0 is the wrong track of a corrupted first fix.
        let on_circle = |t: f64| z + Vector2::new(t.cos(), t.sin()) * 3000.0;
        let wrong = (0..360)
            .filter_map(|k| {
                let (mut lo, mut hi) = (k as f64 * 1f64.to_radians(), (k + 1) as f64 * 1f64.to_radians());
                let f = |t| rd12(on_circle(t)) - rd12(z);
                if f(lo) * f(hi) > 0.0 {
                    return None;
                }
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    if f(lo) * f(mid) <= 0.0 { hi = mid } else { lo = mid }
                }
                Some(on_circle(lo))
            })
            .find(|&w| track_at(w).estimate(1, &uavs, &d, &noise(3)).is_ok_and(|o| o.outliers == 0b001))
            .expect("a point of the hyperbola whose track drops UAV0");
        let mut est = track_at(wrong);
        for k in 1..DEMOTE_DROP_RUN {
            let out = est.estimate(u64::from(k), &uavs, &d, &noise(3)).unwrap();
            assert_eq!((out.status.clone(), out.outliers), (EstimateStatus::Ok, 0b001), "burst {k}");
            assert_eq!(
                (out.track.confirmed, out.track.drop_streak),
                (CONFIRM_BURSTS, DropStreak { uavs: 0b001, run: k })
            );
            assert!((out.position - wrong).norm() < 50.0, "the wrong track holds: {:?}", out.position);
        }
        let demoted = est.estimate(u64::from(DEMOTE_DROP_RUN), &uavs, &d, &noise(3)).unwrap();
        assert_eq!((demoted.track.confirmed, demoted.track.drop_streak), (0, DropStreak::default()));
        // Provisional, it drops no arrival: rejected, then restarted from Chan of the clean burst.
        let mut k = u64::from(DEMOTE_DROP_RUN);
        for run in 1..REJECTED_RUN_RESTART {
            k += 1;
            let out = est.estimate(k, &uavs, &d, &noise(3)).unwrap();
            assert!(matches!(out.status, EstimateStatus::Rejected { .. }), "{:?}", out.status);
            assert_eq!(out.track.rejected_run, run);
        }
        let restart = est.estimate(k + 1, &uavs, &d, &noise(3)).unwrap();
        let near = |p: Vector2<f64>| (p - z).norm() < 1e-3;
        assert!(
            near(restart.position) || restart.alternative.is_some_and(|(p, _)| near(p.position())),
            "restarted at {:?} (alternative {:?}), truth {z:?}",
            restart.position,
            restart.alternative.map(|(p, _)| p.position())
        );
        // A resumed estimator carries the streak.
        let resumed = track_at(wrong);
        let streak = DropStreak { uavs: 0b001, run: DEMOTE_DROP_RUN - 1 };
        let resumed = resumed.clone().with_track(TrackCounters { drop_streak: streak, ..resumed.track() });
        let mut resumed = resumed;
        let out = resumed.estimate(1, &uavs, &d, &noise(3)).unwrap();
        assert_eq!(out.track.confirmed, 0, "the streak's last drop demotes the resumed track");
    }
}
