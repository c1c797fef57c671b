//! The estimator's result of a step: status, position, covariance, and the fused posterior's state.

use super::*;

wire_enum! {
    /// Outcome of an estimation, as carried in [`Estimate::status`].
    pub enum EstimateStatus : u8, decoded by from_u8 {
        /// A unique, usable fix.
        Ok = 0, "ok";
        /// A usable fix chosen among several candidates (e.g. Chan's two roots).
        Ambiguous = 1, "ambiguous";
        /// No fix of this step; position and covariance are the standing (last usable) estimate, NaN when
        /// there is none yet.
        Failed = 2, "failed";
        /// A usable estimate whose snapshot failed the fused estimator's χ² gate and was not fused: the
        /// position and covariance are the posterior predicted to this step.
        Rejected = 3, "rejected";
        /// No burst heard by two UAVs at this step (a silent emitter, lost arrivals): the position and
        /// covariance are the fused posterior predicted to this step.
        Predicted = 4, "predicted";
    }
}

impl EstimateStatus {
    /// Whether the position and covariance are usable (every status but `failed`).
    pub fn is_usable(self) -> bool {
        self != EstimateStatus::Failed
    }
}

/// The estimator's result for one step: what goes into [`Estimate::new`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Fix {
    /// A unique fix with its covariance (m², symmetric positive definite).
    Ok {
        /// Estimated emitter position, metres.
        position: [f64; 2],
        /// Its covariance, m².
        covariance: [[f64; 2]; 2],
    },
    /// A fix chosen among several candidates.
    Ambiguous {
        /// Estimated emitter position, metres.
        position: [f64; 2],
        /// Its covariance, m².
        covariance: [[f64; 2]; 2],
    },
    /// No fix.
    Failed,
    /// The fused estimator's prediction: the snapshot failed its χ² gate.
    Rejected {
        /// Predicted emitter position, metres.
        position: [f64; 2],
        /// Its covariance, m².
        covariance: [[f64; 2]; 2],
    },
    /// The fused estimator's prediction: no burst heard by two UAVs.
    Predicted {
        /// Predicted emitter position, metres.
        position: [f64; 2],
        /// Its covariance, m².
        covariance: [[f64; 2]; 2],
    },
}

impl Fix {
    /// The wire status.
    pub fn status(&self) -> EstimateStatus {
        match self {
            Fix::Ok { .. } => EstimateStatus::Ok,
            Fix::Ambiguous { .. } => EstimateStatus::Ambiguous,
            Fix::Failed => EstimateStatus::Failed,
            Fix::Rejected { .. } => EstimateStatus::Rejected,
            Fix::Predicted { .. } => EstimateStatus::Predicted,
        }
    }

    /// The position and covariance of a usable fix.
    pub fn usable(&self) -> Option<([f64; 2], [[f64; 2]; 2])> {
        match *self {
            Fix::Ok { position, covariance }
            | Fix::Ambiguous { position, covariance }
            | Fix::Rejected { position, covariance }
            | Fix::Predicted { position, covariance } => Some((position, covariance)),
            Fix::Failed => None,
        }
    }
}

/// The fused estimator's state beyond the position, as carried in an [`Estimate`]: the velocity block
/// of the constant-velocity model (zeros for `static`). With the position and its covariance it is the
/// whole posterior, so any process can rebuild the estimator from the last estimate.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct PosteriorExtra {
    /// 0 snapshot (no posterior), 1 fused.
    pub estimator: u8,
    /// 0 static, 1 constant velocity.
    pub model: u8,
    /// Snapshots rejected in a row up to this estimate.
    #[serde(default)]
    pub rejected_run: u8,
    /// Bursts fused whole since the track started (saturating; a provisional track drops no outlier).
    #[serde(default)]
    pub confirmed: u8,
    /// The UAVs the track has dropped burst after burst (bit i: UAV i).
    #[serde(default)]
    pub drop_uavs: u8,
    /// How many bursts in a row dropped them.
    #[serde(default)]
    pub drop_run: u8,
    /// Velocity estimate, m/s.
    pub velocity: [f64; 2],
    /// Position–velocity cross-covariance (rows: x, y; columns: vx, vy), m²/s.
    pub cross_cov: [[f64; 2]; 2],
    /// Velocity covariance, m²/s².
    pub velocity_cov: [[f64; 2]; 2],
    /// How the estimate depends on each UAV's flight-long range bias, `S = ∂(x̂ − x)/∂β` (rows x, y, vx,
    /// vy; one column per UAV; zeros without a fix): the consider state `bias_cov = S Σ_β Sᵀ` comes from.
    #[serde(default)]
    pub bias_sensitivity: [[f64; MAX_UAVS]; 4],
    /// 1 when an ambiguous fix left the posterior of Chan's other root pending (the next burst decides
    /// between the two), its fields below; 0 otherwise.
    #[serde(default)]
    pub alternative: u8,
    /// The pending root's mean (x, y, vx, vy), m and m/s.
    #[serde(default)]
    pub alt_mean: [f64; 4],
    /// Its covariance, row-major over (x, y, vx, vy).
    #[serde(default)]
    pub alt_cov: [[f64; 4]; 4],
    /// Its bias sensitivity, as `bias_sensitivity`.
    #[serde(default)]
    pub alt_bias_sensitivity: [[f64; MAX_UAVS]; 4],
    /// A static emitter's track: its last bursts kept raw beside a summary of the older ones.
    #[serde(default)]
    pub window: TrackWindow,
}

/// The fused posterior's fields beyond the position, as every message that carries an estimator state
/// lays them out (`estimator`, `model`, `rejected_run`, `confirmed`, `drop_uavs`, `drop_run`, `velocity`, `cross_cov`,
/// `velocity_cov`, `bias_sensitivity`, the pending root's `alternative`, `alt_mean`, `alt_cov`,
/// `alt_bias_sensitivity`): one
/// mapping to and from [`PosteriorExtra`] for [`Estimate`] and [`StateEcho`].
macro_rules! impl_posterior_fields {
    ($ty:ident) => {
        impl $ty {
            /// The fused estimator's state beyond the position.
            pub fn extra(&self) -> PosteriorExtra {
                PosteriorExtra {
                    estimator: self.estimator,
                    model: self.model,
                    rejected_run: self.rejected_run,
                    confirmed: self.confirmed,
                    drop_uavs: self.drop_uavs,
                    drop_run: self.drop_run,
                    velocity: self.velocity,
                    cross_cov: self.cross_cov,
                    velocity_cov: self.velocity_cov,
                    bias_sensitivity: self.bias_sensitivity,
                    alternative: self.alternative,
                    alt_mean: self.alt_mean,
                    alt_cov: self.alt_cov,
                    alt_bias_sensitivity: self.alt_bias_sensitivity,
                    window: self.window,
                }
            }

            /// Sets the fused estimator's state beyond the position.
            pub(super) fn set_extra(&mut self, extra: &PosteriorExtra) {
                self.estimator = extra.estimator;
                self.model = extra.model;
                self.rejected_run = extra.rejected_run;
                self.confirmed = extra.confirmed;
                self.drop_uavs = extra.drop_uavs;
                self.drop_run = extra.drop_run;
                self.velocity = extra.velocity;
                self.cross_cov = extra.cross_cov;
                self.velocity_cov = extra.velocity_cov;
                self.bias_sensitivity = extra.bias_sensitivity;
                self.alternative = extra.alternative;
                self.alt_mean = extra.alt_mean;
                self.alt_cov = extra.alt_cov;
                self.alt_bias_sensitivity = extra.alt_bias_sensitivity;
                self.window = extra.window;
            }
        }
    };
}

impl_posterior_fields!(Estimate);
impl_posterior_fields!(StateEcho);

/// estimator → planner, monitor: the emitter estimate and the geometry it was computed for.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("uavloc::Estimate/v10")]
#[repr(C)]
pub struct Estimate {
    /// Common header (step of the measurement it was made from).
    pub header: Header,
    /// Id of the estimator process instance (e.g. pid and start time), to tell restarts apart.
    pub instance: u64,
    /// Number of UAVs N (3..=8).
    pub count: u32,
    /// [`EstimateStatus`] as `u8` (0 ok, 1 ambiguous, 2 failed, 3 rejected, 4 predicted).
    pub status: u8,
    /// The estimator: 0 snapshot (Chan per step), 1 fused (the posterior of every snapshot so far).
    pub estimator: u8,
    /// The fused estimator's emitter model: 0 static, 1 constant velocity (0 for snapshot).
    pub model: u8,
    /// Fused: snapshots rejected in a row up to this one (the estimator restarts from Chan after a few,
    /// see `uavloc-estimator`); 0 otherwise.
    pub rejected_run: u8,
    /// The UAVs whose arrival the measurement held (bit i: UAV i; v5).
    pub heard: u8,
    /// The arrivals the estimator dropped as outliers (bit i: UAV i; v5).
    pub outliers: u8,
    /// Fused: bursts fused whole since the track started (saturating at the estimator's confirmation
    /// count; until then the track is provisional and drops no outlying arrival; v5).
    pub confirmed: u8,
    /// Fused: 1 when the posterior of Chan's other root is pending after an ambiguous fix (v7; see
    /// `alt_mean`).
    pub alternative: u8,
    /// Fused: the UAVs whose arrival the track has dropped from every burst that heard them, `drop_run`
    /// bursts in a row (bit i: UAV i; v8): the same UAV dropped burst after burst makes a confirmed
    /// track provisional again (see `uavloc-estimation`).
    pub drop_uavs: u8,
    /// Fused: how many bursts in a row dropped `drop_uavs` (v8).
    pub drop_run: u8,
    /// Explicit padding; 0 when sent.
    pub reserved: [u8; 2],
    /// Estimated emitter position, metres. Failed: the *standing* estimate — the last usable one, which
    /// the estimator keeps and the next step is planned from — or NaN when there is none yet (v3; in v2 a
    /// failed estimate carried no position).
    pub position: [f64; 2],
    /// Its covariance, m², row-major (failed: the standing estimate's, or NaN).
    pub covariance: [[f64; 2]; 2],
    /// UAV positions the estimate was computed for, metres.
    pub uavs: [[f64; 2]; MAX_UAVS],
    /// UAV headings at that time, radians.
    pub headings: [f64; MAX_UAVS],
    /// Fused, constant velocity: the velocity estimate, m/s (0 otherwise).
    pub velocity: [f64; 2],
    /// Fused, constant velocity: position–velocity cross-covariance, m²/s (0 otherwise).
    pub cross_cov: [[f64; 2]; 2],
    /// Fused, constant velocity: velocity covariance, m²/s² (0 otherwise).
    pub velocity_cov: [[f64; 2]; 2],
    /// The range noise σ_i per UAV of the measurement it was made from, metres (v4): the noise every
    /// later stage uses (the planner's criterion, the monitor's bounds), so a front end's stated noise
    /// is the run's. All 0: not stated (the scenario's σ is used). From v5 the *stated* σ: range noise
    /// with the GNSS and clock errors (see `Measurement::stated_sigmas`).
    pub sigmas: [f64; MAX_UAVS],
    /// The consider covariance of the persistent GNSS and clock errors at the estimate, m² (v5; zero
    /// without them): not part of the fused state; [`Estimate::plan_from`] adds it. From v6
    /// `S Σ_β Sᵀ` of `bias_sensitivity`.
    pub bias_cov: [[f64; 2]; 2],
    /// How the estimate depends on each UAV's flight-long range bias, `S = ∂(x̂ − x)/∂β` (v6; rows x,
    /// y, vx, vy; one column per UAV; metres per metre, 1/s): part of the estimator's state.
    pub bias_sensitivity: [[f64; MAX_UAVS]; 4],
    /// Fused, `alternative` = 1: the pending root's mean (x, y, vx, vy; v7), m and m/s.
    pub alt_mean: [f64; 4],
    /// Its covariance (row-major over x, y, vx, vy; v7).
    pub alt_cov: [[f64; 4]; 4],
    /// Its bias sensitivity (v7), as `bias_sensitivity`.
    pub alt_bias_sensitivity: [[f64; MAX_UAVS]; 4],
    /// Fused, before the first fix: the bursts heard by two UAVs only that the estimator holds for it
    /// (v9; see [`HeldBurst`]); none otherwise.
    pub held: HeldBursts,
    /// Fused, static emitter: the track's window (v10; see [`TrackWindow`]); `open` 0 otherwise.
    pub window: TrackWindow,
}

impl_message!(Estimate, MessageKind::Estimate, 10, "uavloc::Estimate/v10");

impl_per_uav!(Estimate {
    /// UAV positions in use.
    uavs: [f64; 2],
    /// Headings in use.
    headings: f64,
});

impl Estimate {
    /// An estimate for `uavs.len()` UAVs (`headings` one per UAV).
    pub fn new(
        step: u64,
        seq: u64,
        instance: u64,
        uavs: &[[f64; 2]],
        headings: &[f64],
        fix: Fix,
    ) -> Result<Self, ProtocolError> {
        let n = check_count(uavs.len())?;
        check_len("headings", n, headings.len())?;
        let (position, covariance) = fix.usable().unwrap_or(([f64::NAN; 2], [[f64::NAN; 2]; 2]));
        let mut e = Estimate {
            header: Header::new(Self::VERSION, step, seq),
            instance,
            count: n as u32,
            status: fix.status() as u8,
            estimator: 0,
            model: 0,
            rejected_run: 0,
            heard: 0,
            outliers: 0,
            confirmed: 0,
            alternative: 0,
            drop_uavs: 0,
            drop_run: 0,
            reserved: [0; 2],
            position,
            covariance,
            uavs: [[0.0; 2]; MAX_UAVS],
            headings: [0.0; MAX_UAVS],
            velocity: [0.0; 2],
            cross_cov: [[0.0; 2]; 2],
            velocity_cov: [[0.0; 2]; 2],
            sigmas: [0.0; MAX_UAVS],
            bias_cov: [[0.0; 2]; 2],
            bias_sensitivity: [[0.0; MAX_UAVS]; 4],
            alt_mean: [0.0; 4],
            alt_cov: [[0.0; 4]; 4],
            alt_bias_sensitivity: [[0.0; MAX_UAVS]; 4],
            held: HeldBursts::default(),
            window: TrackWindow::default(),
        };
        e.uavs[..n].copy_from_slice(uavs);
        e.headings[..n].copy_from_slice(headings);
        Ok(e)
    }

    /// The range σ per UAV it was made from, metres; `None` when not stated (all 0).
    pub fn range_sigmas(&self) -> Option<&[f64]> {
        let s = &self.sigmas[..self.len()];
        s.iter().any(|v| *v != 0.0).then_some(s)
    }

    /// The estimate of `measurement` (received at `received_ns`): same step, same UAV geometry, the
    /// measurement's stamps carried forward.
    pub fn from_measurement(
        measurement: &Measurement,
        received_ns: u64,
        seq: u64,
        instance: u64,
        fix: Fix,
    ) -> Result<Self, ProtocolError> {
        let mut e =
            Estimate::new(measurement.header.step, seq, instance, measurement.uavs(), measurement.headings(), fix)?
                .carrying(measurement, received_ns);
        let n = e.len();
        e.sigmas[..n].copy_from_slice(&measurement.stated_sigmas().0);
        e.heard = measurement.heard;
        Ok(e)
    }

    /// This estimate with the fused estimator's state beyond the position.
    pub fn with_extra(mut self, extra: &PosteriorExtra) -> Self {
        self.set_extra(extra);
        self
    }

    /// A failed estimate carrying the standing estimate `standing` (the last usable one: what the step is
    /// planned from); no change to a usable one, nor without a standing estimate.
    pub fn with_standing(mut self, standing: Option<([f64; 2], [[f64; 2]; 2])>) -> Self {
        if let (Some(EstimateStatus::Failed), Some((position, covariance))) = (self.status(), standing) {
            self.position = position;
            self.covariance = covariance;
        }
        self
    }

    /// The estimate this step is planned from: the fix of a usable estimate, the standing estimate of a
    /// failed one, `None` for a failed one without (no usable estimate yet) or an unknown status. The
    /// covariance includes the persistent errors' [`bias_cov`](Self::bias_cov).
    pub fn plan_from(&self) -> Option<([f64; 2], [[f64; 2]; 2])> {
        let (position, c) = self.state_from()?;
        let b = &self.bias_cov;
        let total = [[c[0][0] + b[0][0], c[0][1] + b[0][1]], [c[1][0] + b[1][0], c[1][1] + b[1][1]]];
        Some((position, total))
    }

    /// The estimator's own state of this step, as [`plan_from`](Self::plan_from) picks it but with the
    /// fused covariance alone (without `bias_cov`, which the bias sensitivity carries): what a restarted
    /// estimator goes on from.
    pub fn state_from(&self) -> Option<([f64; 2], [[f64; 2]; 2])> {
        match self.status()? {
            EstimateStatus::Failed if !self.position.iter().all(|v| v.is_finite()) => None,
            _ => Some((self.position, self.covariance)),
        }
    }

    /// This estimate with the two-arrival bursts the estimator holds for its first fix.
    pub fn with_held(mut self, held: HeldBursts) -> Self {
        self.held = held;
        self
    }

    /// This estimate with the arrivals dropped as outliers `outliers` and the consider covariance
    /// `bias_cov` (m²).
    pub fn with_receiver(mut self, outliers: u8, bias_cov: [[f64; 2]; 2]) -> Self {
        self.outliers = outliers;
        self.bias_cov = bias_cov;
        self
    }

    /// The decoded status (`None` for an unknown wire value).
    pub fn status(&self) -> Option<EstimateStatus> {
        EstimateStatus::from_u8(self.status)
    }

    /// The estimator this estimate comes from, as far as it tells: `"fused"` when it carries a posterior
    /// (`estimator = 1`), `"snapshot"` when it has a usable fix without one, `None` for a step without a
    /// fix and without a posterior — a fused estimator before its first fix sends that too.
    pub fn estimator_name(&self) -> Option<&'static str> {
        if self.estimator == 1 {
            Some("fused")
        } else if self.status().is_some_and(EstimateStatus::is_usable) {
            Some("snapshot")
        } else {
            None
        }
    }

    /// The fix (`None` for an unknown status).
    pub fn fix(&self) -> Option<Fix> {
        let (position, covariance) = (self.position, self.covariance);
        Some(match self.status()? {
            EstimateStatus::Ok => Fix::Ok { position, covariance },
            EstimateStatus::Ambiguous => Fix::Ambiguous { position, covariance },
            EstimateStatus::Failed => Fix::Failed,
            EstimateStatus::Rejected => Fix::Rejected { position, covariance },
            EstimateStatus::Predicted => Fix::Predicted { position, covariance },
        })
    }
}
