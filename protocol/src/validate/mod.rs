//! What a receiver checks before trusting a message.
//!
//! Messages arrive as raw bytes from shared memory written by another process: the layout makes every bit
//! pattern a valid Rust value, but not a meaningful message. `validate(&self, last_seq)` checks, in order:
//!
//! 1. the header version equals the type's `VERSION` ([`Rejection::BadVersion`]);
//! 2. the UAV count is in `3..=8` ([`Rejection::BadCount`]; not for [`Truth`]);
//! 3. the estimate status is known ([`Rejection::UnknownStatus`]), so are a control message's kind and a
//!    truth's previous-command outcome ([`Rejection::UnknownKind`]), and the names are valid ASCII
//!    ([`Rejection::BadName`]);
//! 4. every *used* float is finite ([`Rejection::NotFinite`]): the first `count` entries of per-UAV arrays,
//!    the first `count − 1` range differences, and the scalars; a failed estimate's position and covariance
//!    are its standing estimate when it has one (then checked like a fix's) and all NaN otherwise;
//! 5. range sigmas are > 0 ([`Rejection::NonPositiveSigma`]) and an estimate's covariance is symmetric
//!    positive definite as the planner takes it ([`is_symmetric_positive_definite`]), alone and with its
//!    `bias_cov` ([`Rejection::NotPositiveDefinite`]; `bias_cov` itself positive semi-definite,
//!    [`Rejection::BadField`]); a measurement's positions, stated range σ
//!    and arrivals are within what the maths takes ([`SWARM_EXTENT_M`], [`MIN_SIGMA_M`]..[`MAX_SIGMA_M`],
//!    [`MAX_ARRIVAL_M`]; [`Rejection::BadField`]);
//! 6. the sequence number is strictly greater than that of the last *accepted* message of the stream
//!    ([`Rejection::Stale`]; a repeat or a step back).
//!
//! A *stream* is what one receiver hears on one topic; `last_seq` is the last accepted sequence number of it.
//! A second publisher on the same topic (e.g. a planner taking over) must continue the numbering above the
//! last one it saw, or receivers must reset `last_seq` when they see a new instance id; otherwise its
//! messages are rejected as stale.
//!
//! Unused array entries and the `reserved` fields are ignored. [`RejectionCounter::check`] runs the
//! validation, tracks the last accepted sequence number and counts rejections per type and kind.

use thiserror::Error;

use crate::messages::{
    Command, Control, ControlKind, Estimate, EstimateStatus, FLAG_SILENT, Measurement, SwarmState, Truth,
};
use crate::{MAX_UAVS, MIN_UAVS};

mod counter;

pub use counter::RejectionCounter;

/// Why a received message was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum Rejection {
    /// The header version is not the receiver's.
    #[error("version {got} (expected {expected})")]
    BadVersion {
        /// The receiver's version.
        expected: u32,
        /// The message's version.
        got: u32,
    },
    /// The UAV count is outside `3..=8`.
    #[error("UAV count {count} outside {MIN_UAVS}..={MAX_UAVS}")]
    BadCount {
        /// The message's count.
        count: u32,
    },
    /// A used float is NaN or infinite.
    #[error("{field} is not finite")]
    NotFinite {
        /// Which field.
        field: &'static str,
    },
    /// A range sigma is ≤ 0.
    #[error("range sigma of UAV {index} is not positive")]
    NonPositiveSigma {
        /// Which UAV.
        index: usize,
    },
    /// The covariance is not symmetric positive definite.
    #[error("covariance is not symmetric positive definite")]
    NotPositiveDefinite,
    /// The estimate status is not one of [`EstimateStatus`].
    #[error("unknown estimate status {status}")]
    UnknownStatus {
        /// The wire value.
        status: u8,
    },
    /// The sequence number does not exceed the last accepted one.
    #[error("stale: seq {seq} after {last}")]
    Stale {
        /// The message's sequence number.
        seq: u64,
        /// The last accepted sequence number.
        last: u64,
    },
    /// A name is not valid ASCII (see [`Name16`](crate::Name16)).
    #[error("{field} is not a valid name")]
    BadName {
        /// Which name.
        field: &'static str,
    },
    /// The message belongs to another run than the receiver's ([`Header::run`](crate::Header::run)): a
    /// process of another scenario in the domain (it is told to leave on the control topic).
    #[error("of another run (tag {got:#010x}, this run's {expected:#010x})")]
    OtherRun {
        /// The receiver's run tag.
        expected: u32,
        /// The message's.
        got: u32,
    },
    /// A measurement from a second source while the run's source is still there
    /// ([`SourceLock`](crate::SourceLock)): one measurement source per run, never two mixed.
    #[error("a second measurement source (publisher {got:032x}) while the run's source ({current:032x}) is there")]
    SecondSource {
        /// The run's source (its publisher id).
        current: u128,
        /// The refused publisher.
        got: u128,
    },
    /// A copy of a step already accepted, with other data ([`StepDigests`](crate::StepDigests)): the
    /// pipeline estimates, plans and records the first copy only.
    #[error("a different copy of step {step}, already measured")]
    Conflict {
        /// The step.
        step: u64,
    },
    /// An enumerated field has an unknown value: a control message's kind (not one of [`ControlKind`]),
    /// a truth's `previous_command` (not one of [`CommandOutcome`](crate::CommandOutcome)).
    #[error("unknown {field} {kind}")]
    UnknownKind {
        /// Which field (`"control kind"`, `"previous_command"`).
        field: &'static str,
        /// The wire value.
        kind: u32,
    },
    /// A field out of its range: a negative GNSS or clock σ, a heard mask with bits beyond the swarm,
    /// an unknown flag, a silent step that claims arrivals, or a measurement's value beyond what the
    /// maths takes (a position beyond the plane's extent, a stated range σ outside 1e-6..1e7 m, an
    /// arrival too far from its epoch to keep its precision).
    #[error("{field} out of range")]
    BadField {
        /// Which field.
        field: &'static str,
    },
}

impl Rejection {
    /// All kind strings, in [`kind_index`](Self::kind_index) order.
    pub const KINDS: [&'static str; 13] = [
        "bad_version",
        "bad_count",
        "not_finite",
        "non_positive_sigma",
        "not_positive_definite",
        "unknown_status",
        "stale",
        "bad_name",
        "unknown_kind",
        "other_run",
        "second_source",
        "conflict",
        "bad_field",
    ];

    /// Stable snake_case name of the reason (for logs and counters).
    pub fn kind(&self) -> &'static str {
        Self::KINDS[self.kind_index()]
    }

    /// Position of [`kind`](Self::kind) in [`KINDS`](Self::KINDS).
    pub fn kind_index(&self) -> usize {
        match self {
            Rejection::BadVersion { .. } => 0,
            Rejection::BadCount { .. } => 1,
            Rejection::NotFinite { .. } => 2,
            Rejection::NonPositiveSigma { .. } => 3,
            Rejection::NotPositiveDefinite => 4,
            Rejection::UnknownStatus { .. } => 5,
            Rejection::Stale { .. } => 6,
            Rejection::BadName { .. } => 7,
            Rejection::UnknownKind { .. } => 8,
            Rejection::OtherRun { .. } => 9,
            Rejection::SecondSource { .. } => 10,
            Rejection::Conflict { .. } => 11,
            Rejection::BadField { .. } => 12,
        }
    }
}

fn check_version(expected: u32, got: u32) -> Result<(), Rejection> {
    if got == expected { Ok(()) } else { Err(Rejection::BadVersion { expected, got }) }
}

/// Checks the count and returns it as a usable length.
fn check_count(count: u32) -> Result<usize, Rejection> {
    let n = count as usize;
    if (MIN_UAVS..=MAX_UAVS).contains(&n) { Ok(n) } else { Err(Rejection::BadCount { count }) }
}

fn check_finite<'a>(field: &'static str, values: impl IntoIterator<Item = &'a f64>) -> Result<(), Rejection> {
    if values.into_iter().all(|v| v.is_finite()) { Ok(()) } else { Err(Rejection::NotFinite { field }) }
}

fn check_seq(seq: u64, last_seq: Option<u64>) -> Result<(), Rejection> {
    match last_seq {
        Some(last) if seq <= last => Err(Rejection::Stale { seq, last }),
        _ => Ok(()),
    }
}

/// Relative tolerance on `|c01 − c10|` for a covariance to count as symmetric.
pub const SYMMETRY_TOLERANCE: f64 = 1e-9;

/// The smallest eigenvalue an estimate's covariance may have, m² (`tdoa::support::MIN_EIGENVALUE_M2`): the
/// floats' limit, not a physical one; at or above it the planner inverts the covariance.
pub const MIN_EIGENVALUE_M2: f64 = 1e-300;

/// Whether a finite 2×2 matrix is symmetric (within [`SYMMETRY_TOLERANCE`]) positive definite, as the
/// planner takes it (`tdoa::support::is_positive_definite`): positive variances with a finite sum, a
/// correlation `c01 / (√c00 √c11)` below 1 in magnitude, and the smallest eigenvalue at least
/// [`MIN_EIGENVALUE_M2`] (a covariance of σ 1e-155 m would have no inverse in floating point, and the
/// planner would refuse the step at every replay).
///
/// Overflow-safe: no determinant is formed (the smallest eigenvalue is `c00 c11 (1 − ρ²) / λ_max`).
pub fn is_symmetric_positive_definite(c: &[[f64; 2]; 2]) -> bool {
    let Some((a, b, d)) = symmetric_parts(c) else { return false };
    if !(a > 0.0 && d > 0.0 && (a + d).is_finite()) {
        return false;
    }
    let rho = b / a.sqrt() / d.sqrt();
    let lambda_max = 0.5 * (a + d) + (0.5 * (a - d)).hypot(b);
    rho.abs() < 1.0 && (a / lambda_max) * d * ((1.0 - rho) * (1.0 + rho)) >= MIN_EIGENVALUE_M2
}

/// Whether a finite 2×2 matrix is symmetric (within [`SYMMETRY_TOLERANCE`]) positive semi-definite (0
/// allowed): variances ≥ 0 and `|c01| ≤ √c00 √c11` within the same relative tolerance (a rank-one
/// `σ² s sᵀ` rounds either way).
pub fn is_positive_semi_definite(c: &[[f64; 2]; 2]) -> bool {
    let Some((a, b, d)) = symmetric_parts(c) else { return false };
    a >= 0.0 && d >= 0.0 && b.abs() <= a.sqrt() * d.sqrt() * (1.0 + SYMMETRY_TOLERANCE)
}

/// `(c00, (c01 + c10)/2, c11)` of a 2×2 matrix symmetric within [`SYMMETRY_TOLERANCE`] (relative to its
/// largest entry), `None` otherwise.
fn symmetric_parts(c: &[[f64; 2]; 2]) -> Option<(f64, f64, f64)> {
    let scale = c[0][0].abs().max(c[1][1].abs()).max(c[0][1].abs()).max(c[1][0].abs());
    let symmetric = (c[0][1] - c[1][0]).abs() <= SYMMETRY_TOLERANCE * scale;
    symmetric.then_some((c[0][0], 0.5 * (c[0][1] + c[1][0]), c[1][1]))
}

impl Measurement {
    /// Checks the measurement; see the [module docs](crate::validate).
    pub fn validate(&self, last_seq: Option<u64>) -> Result<(), Rejection> {
        check_version(Self::VERSION, self.header.version)?;
        let n = check_count(self.count)?;
        check_finite("uavs", self.uavs[..n].iter().flatten())?;
        let heard = (0..n).filter(|&i| self.heard & (1u8 << i) != 0).map(|i| &self.arrivals[i]);
        check_finite("arrivals", heard)?;
        check_finite("sigmas", &self.sigmas[..n])?;
        check_finite("headings", &self.headings[..n])?;
        let sensor_sigmas = [
            ("position_sigmas", &self.position_sigmas),
            ("position_bias_sigmas", &self.position_bias_sigmas),
            ("clock_sigmas_ns", &self.clock_sigmas_ns),
            ("clock_bias_sigmas_ns", &self.clock_bias_sigmas_ns),
        ];
        // Every used float is checked for finiteness before any range check.
        for (field, v) in sensor_sigmas {
            check_finite(field, &v[..n])?;
        }
        if let Some(index) = self.sigmas[..n].iter().position(|&s| s <= 0.0) {
            return Err(Rejection::NonPositiveSigma { index });
        }
        for (field, v) in sensor_sigmas {
            if v[..n].iter().any(|s| *s < 0.0) {
                return Err(Rejection::BadField { field });
            }
        }
        // Positions within the plane model's extent; each UAV's stated range σ (its range σ with its GNSS
        // and clock σ) within what the maths takes; arrivals near enough to their epoch that their
        // differences keep their precision. A value beyond these would pass every later check and then
        // fail the estimator or the planner at every replay of the step (a step never commanded).
        if self.uavs[..n].iter().flatten().any(|c| c.abs() > SWARM_EXTENT_M) {
            return Err(Rejection::BadField { field: "uavs (beyond ±1e7 m)" });
        }
        if self.stated_sigmas().0.iter().any(|s| !(MIN_SIGMA_M..=MAX_SIGMA_M).contains(s)) {
            return Err(Rejection::BadField { field: "stated range σ (sigmas with GNSS and clock σ, 1e-6..1e7 m)" });
        }
        if (0..n).any(|i| self.has_heard(i) && self.arrivals[i].abs() > MAX_ARRIVAL_M) {
            return Err(Rejection::BadField { field: "arrivals (more than 1e14 m from their epoch)" });
        }
        // Bits beyond the swarm, unknown flags, or a silent step that says it heard something.
        let beyond = n < 8 && self.heard >> n != 0;
        if beyond || self.flags & !FLAG_SILENT != 0 || (self.is_silent() && self.heard != 0) {
            return Err(Rejection::BadField { field: "heard/flags" });
        }
        check_seq(self.header.seq, last_seq)
    }
}

impl Estimate {
    /// Checks the estimate; see the [module docs](crate::validate).
    pub fn validate(&self, last_seq: Option<u64>) -> Result<(), Rejection> {
        check_version(Self::VERSION, self.header.version)?;
        let n = check_count(self.count)?;
        let status = EstimateStatus::from_u8(self.status).ok_or(Rejection::UnknownStatus { status: self.status })?;
        check_finite("uavs", self.uavs[..n].iter().flatten())?;
        check_finite("headings", &self.headings[..n])?;
        check_finite("bias_cov", self.bias_cov.iter().flatten())?;
        // A failed estimate carries the standing estimate, or none (all NaN).
        let positioned = status != EstimateStatus::Failed || self.position.iter().any(|v| v.is_finite());
        if positioned {
            ESTIMATE_FIELDS.check_estimate(&self.position, &self.covariance)?;
        }
        ESTIMATE_FIELDS.check_posterior(&self.extra())?;
        check_held(&self.held)?;
        // The σ it was made from: stated (every one finite and > 0) or not (all 0).
        let sigmas = &self.sigmas[..n];
        if sigmas.iter().any(|v| *v != 0.0) {
            check_finite("sigmas", sigmas)?;
            if let Some(index) = sigmas.iter().position(|v| *v <= 0.0) {
                return Err(Rejection::NonPositiveSigma { index });
            }
            // The planner plans with them: within what the maths takes, as a measurement's.
            if sigmas.iter().any(|s| !(MIN_SIGMA_M..=MAX_SIGMA_M).contains(s)) {
                return Err(Rejection::BadField { field: "sigmas (1e-6..1e7 m)" });
            }
        }
        // The covariance of the flight-long biases, S Σ_β Sᵀ: symmetric positive semi-definite; and what
        // the planner plans with, the two together, a covariance it takes.
        if !is_positive_semi_definite(&self.bias_cov) {
            return Err(Rejection::BadField { field: "bias_cov (not symmetric positive semi-definite)" });
        }
        if positioned && !self.plan_from().is_some_and(|(_, total)| is_symmetric_positive_definite(&total)) {
            return Err(Rejection::NotPositiveDefinite);
        }
        check_seq(self.header.seq, last_seq)
    }
}

impl Command {
    /// Checks the command; see the [module docs](crate::validate).
    pub fn validate(&self, last_seq: Option<u64>) -> Result<(), Rejection> {
        check_version(Self::VERSION, self.header.version)?;
        let n = check_count(self.count)?;
        if !self.solver.is_valid() {
            return Err(Rejection::BadName { field: "solver" });
        }
        if !self.objective_name.is_valid() {
            return Err(Rejection::BadName { field: "objective_name" });
        }
        check_finite("objective", [&self.objective])?;
        check_finite("headings", &self.headings[..n])?;
        check_finite("waypoints", self.waypoints[..n].iter().flatten())?;
        self.state.validate()?;
        check_seq(self.header.seq, last_seq)
    }
}

impl crate::messages::EstimatorState {
    /// Checks the state message: a state ([`crate::StateEcho::STATE`] or [`crate::StateEcho::EMPTY`]), checked as the
    /// command that echoed it (its own `step` is the step it is after).
    pub fn validate(&self, last_seq: Option<u64>) -> Result<(), Rejection> {
        check_version(Self::VERSION, self.header.version)?;
        self.state.validate()?;
        if self.state.decode().is_none() {
            return Err(Rejection::UnknownKind { field: "state kind", kind: u32::from(self.state.kind) });
        }
        check_seq(self.header.seq, last_seq)
    }
}

impl crate::messages::StateEcho {
    /// Checks an echoed estimator state as [`Estimate::validate`] checks the estimate it came from.
    pub fn validate(&self) -> Result<(), Rejection> {
        if self.kind > Self::EMPTY {
            return Err(Rejection::UnknownKind { field: "state kind", kind: u32::from(self.kind) });
        }
        if self.kind == Self::EMPTY {
            return check_held(&self.held);
        }
        if self.kind != Self::STATE {
            return Ok(());
        }
        STATE_FIELDS.check_estimate(&self.position, &self.covariance)?;
        STATE_FIELDS.check_posterior(&self.extra())
    }
}

/// The bursts an estimator state holds for its first fix: at most [`crate::MAX_HELD_BURSTS`], each of
/// a swarm of 3..=8 UAVs heard by two distinct ones of them (ascending), with finite positions and
/// range difference, positive σ and a persistent part within it.
fn check_held(h: &crate::HeldBursts) -> Result<(), Rejection> {
    if usize::from(h.count) > crate::MAX_HELD_BURSTS {
        return Err(Rejection::BadField { field: "held count" });
    }
    for b in h.as_slice() {
        let n = check_count(u32::from(b.count))?;
        let [i, j] = b.uavs;
        if i >= j || usize::from(j) >= n {
            return Err(Rejection::BadField { field: "held uavs" });
        }
        check_finite("held positions", b.positions.iter().flatten())?;
        check_finite("held arrival_diff", [&b.arrival_diff])?;
        check_sigmas("held sigmas", &b.sigmas, &b.bias_sigmas)?;
    }
    Ok(())
}

/// The σ of a burst's arrivals and their persistent parts (metres): finite, each σ positive and its
/// persistent part within 0–σ.
fn check_sigmas(field: &'static str, sigmas: &[f64], bias_sigmas: &[f64]) -> Result<(), Rejection> {
    check_finite(field, sigmas.iter().chain(bias_sigmas))?;
    if sigmas.iter().zip(bias_sigmas).any(|(s, p)| *s <= 0.0 || !(0.0..=*s).contains(p)) {
        return Err(Rejection::BadField { field });
    }
    Ok(())
}

/// The names a rejection gives the fields of an estimator state, in the message that carries it.
struct StateFields {
    position: &'static str,
    covariance: &'static str,
    estimator: &'static str,
    model: &'static str,
    velocity: &'static str,
    cross_cov: &'static str,
    velocity_cov: &'static str,
    bias_sensitivity: &'static str,
    alternative: &'static str,
}

const ESTIMATE_FIELDS: StateFields = StateFields {
    position: "position",
    covariance: "covariance",
    estimator: "estimator",
    model: "model",
    velocity: "velocity",
    cross_cov: "cross_cov",
    velocity_cov: "velocity_cov",
    bias_sensitivity: "bias_sensitivity",
    alternative: "alternative",
};

const STATE_FIELDS: StateFields = StateFields {
    position: "state position",
    covariance: "state covariance",
    estimator: "state estimator",
    model: "state model",
    velocity: "state velocity",
    cross_cov: "state cross_cov",
    velocity_cov: "state velocity_cov",
    bias_sensitivity: "state bias_sensitivity",
    alternative: "state alternative",
};

impl StateFields {
    /// A position and its covariance: finite, the covariance symmetric positive definite.
    fn check_estimate(&self, position: &[f64; 2], covariance: &[[f64; 2]; 2]) -> Result<(), Rejection> {
        check_finite(self.position, position)?;
        check_finite(self.covariance, covariance.iter().flatten())?;
        if !is_symmetric_positive_definite(covariance) {
            return Err(Rejection::NotPositiveDefinite);
        }
        Ok(())
    }

    /// The posterior beyond the position: a known estimator and model, a finite bias sensitivity, and
    /// for the constant-velocity model a finite velocity block.
    fn check_posterior(&self, x: &crate::PosteriorExtra) -> Result<(), Rejection> {
        check_finite(self.bias_sensitivity, x.bias_sensitivity.iter().flatten())?;
        match x.alternative {
            0 => {}
            1 => {
                check_finite(self.alternative, &x.alt_mean)?;
                check_finite(self.alternative, x.alt_cov.iter().flatten())?;
                check_finite(self.alternative, x.alt_bias_sensitivity.iter().flatten())?;
            }
            kind => return Err(Rejection::UnknownKind { field: self.alternative, kind: u32::from(kind) }),
        }
        if x.estimator > 1 {
            return Err(Rejection::UnknownKind { field: self.estimator, kind: u32::from(x.estimator) });
        }
        if x.model > 1 {
            return Err(Rejection::UnknownKind { field: self.model, kind: u32::from(x.model) });
        }
        if x.model == 1 {
            check_finite(self.velocity, &x.velocity)?;
            check_finite(self.cross_cov, x.cross_cov.iter().flatten())?;
            check_finite(self.velocity_cov, x.velocity_cov.iter().flatten())?;
        }
        check_window(&x.window)
    }
}

/// A track's window: `open` 0 or 1; open, a finite summary and at most [`crate::MAX_WINDOW_BURSTS`]
/// bursts, each of a swarm of 3..=8 UAVs with two or more of them kept, finite positions, finite
/// arrivals where kept, positive σ and a persistent part within it.
fn check_window(w: &crate::TrackWindow) -> Result<(), Rejection> {
    match w.open {
        0 => return Ok(()),
        1 => {}
        kind => return Err(Rejection::UnknownKind { field: "window open", kind: u32::from(kind) }),
    }
    if usize::from(w.count) > crate::MAX_WINDOW_BURSTS {
        return Err(Rejection::BadField { field: "window count" });
    }
    check_finite("window base", w.base_matrix.iter().flatten().chain(&w.base_vector))?;
    for b in w.as_slice() {
        let n = check_count(u32::from(b.count))?;
        if (n < MAX_UAVS && b.heard >> n != 0) || b.heard.count_ones() < 2 {
            return Err(Rejection::BadField { field: "window heard" });
        }
        check_finite("window positions", b.positions[..n].iter().flatten())?;
        check_finite("window arrivals", (0..n).filter(|i| b.heard & (1 << i) != 0).map(|i| &b.arrivals[i]))?;
        check_sigmas("window sigmas", &b.sigmas[..n], &b.bias_sigmas[..n])?;
    }
    Ok(())
}

impl Truth {
    /// Checks the truth; see the [module docs](crate::validate).
    pub fn validate(&self, last_seq: Option<u64>) -> Result<(), Rejection> {
        check_version(Self::VERSION, self.header.version)?;
        if self.previous_command().is_none() {
            return Err(Rejection::UnknownKind { field: "previous_command", kind: self.previous_command });
        }
        check_finite("position", &self.position)?;
        if self.multipath > 0xff {
            return Err(Rejection::UnknownKind { field: "multipath", kind: self.multipath });
        }
        check_seq(self.header.seq, last_seq)
    }
}

/// The largest coordinate of a swarm position, metres: the maths' plane extent (`tdoa::MAX_EXTENT_M`).
pub const SWARM_EXTENT_M: f64 = 1.0e7;

/// The smallest stated range σ of an arrival, metres (`tdoa::MIN_SIGMA_M`).
pub const MIN_SIGMA_M: f64 = 1.0e-6;

/// The largest stated range σ of an arrival — its range σ with its GNSS and clock σ — metres: the plane
/// extent, the largest σ the maths takes (`tdoa::MAX_EXTENT_M`).
pub const MAX_SIGMA_M: f64 = SWARM_EXTENT_M;

/// The largest arrival `c·(t_i − t_epoch)` a measurement may carry, metres (≈ 3.9 days after the epoch):
/// up to it a difference of two arrivals keeps a precision of 1.6 cm (one unit in the last place of an
/// f64 near 1e14 m); an epoch years back (the Unix epoch: ≈ 5e17 m, 64 m per unit) would quietly cost
/// the range differences tens of metres. Take an epoch near the burst.
pub const MAX_ARRIVAL_M: f64 = 1.0e14;

impl SwarmState {
    /// Checks the swarm state; see the [module docs](crate::validate): the count, the link states, and
    /// for every UAV with a fix finite values, a position within the plane's extent and a
    /// latitude/longitude in range.
    pub fn validate(&self, last_seq: Option<u64>) -> Result<(), Rejection> {
        check_version(Self::VERSION, self.header.version)?;
        let n = check_count(self.count)?;
        for i in 0..n {
            if self.link_of(i).is_none() {
                return Err(Rejection::UnknownKind { field: "link", kind: self.link[i] });
            }
            if !self.has_fix(i) {
                continue;
            }
            check_finite("positions", &self.positions[i])?;
            check_finite("lat_lon_deg", &self.lat_lon_deg[i])?;
            check_finite("velocities", &self.velocities[i])?;
            check_finite("headings", [&self.headings[i], &self.altitude_m[i]])?;
            let [lat, lon] = self.lat_lon_deg[i];
            if self.positions[i].iter().any(|v| v.abs() > SWARM_EXTENT_M) || lat.abs() > 90.0 || lon.abs() > 180.0 {
                return Err(Rejection::NotFinite { field: "positions (out of range)" });
            }
        }
        check_seq(self.header.seq, last_seq)
    }
}

impl Control {
    /// Checks the control message; see the [module docs](crate::validate). The detail may be empty.
    pub fn validate(&self, last_seq: Option<u64>) -> Result<(), Rejection> {
        check_version(Self::VERSION, self.header.version)?;
        ControlKind::from_u32(self.kind).ok_or(Rejection::UnknownKind { field: "control kind", kind: self.kind })?;
        if !self.role.is_valid() {
            return Err(Rejection::BadName { field: "role" });
        }
        if self.detail.bytes != [0; 16] && !self.detail.is_valid() {
            return Err(Rejection::BadName { field: "detail" });
        }
        check_seq(self.header.seq, last_seq)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::messages::{Fix, MessageKind, PlanInfo};

    const UAVS: [[f64; 2]; 4] = [[0.0, 0.0], [1000.0, 0.0], [0.0, 1000.0], [1000.0, 1000.0]];

    fn measurement() -> Measurement {
        Measurement::new(3, 10, &UAVS, &[10.0, -5.0, 2.5], &[3.0; 4], &[0.1, 0.2, 0.3, 0.4]).unwrap()
    }

    fn estimate() -> Estimate {
        let fix = Fix::Ok { position: [500.0, 400.0], covariance: [[4.0, 1.0], [1.0, 9.0]] };
        Estimate::new(3, 10, 42, &UAVS, &[0.1, 0.2, 0.3, 0.4], fix).unwrap()
    }

    fn command() -> Command {
        Command::new(
            3,
            10,
            7,
            &PlanInfo {
                headings: &[0.5; 4],
                waypoints: &UAVS,
                objective: 12.5,
                solver: "pso",
                objective_name: "trace-crlb",
                plan_time_us: 120,
                active_constraints: 0,
                violated_constraints: 0,
            },
        )
        .unwrap()
    }

    fn truth() -> Truth {
        Truth::new(3, 10, [480.0, 410.0])
    }

    #[test]
    fn accepts_good_messages() {
        for last in [None, Some(0), Some(9)] {
            assert_eq!(measurement().validate(last), Ok(()));
            assert_eq!(estimate().validate(last), Ok(()));
            assert_eq!(command().validate(last), Ok(()));
            assert_eq!(truth().validate(last), Ok(()));
        }
        let ambiguous = Fix::Ambiguous { position: [1.0, 2.0], covariance: [[1.0, 0.0], [0.0, 1.0]] };
        assert_eq!(Estimate::new(0, 0, 1, &UAVS[..3], &[0.0; 3], ambiguous).unwrap().validate(None), Ok(()));
        let failed = Estimate::new(0, 0, 1, &UAVS[..3], &[0.0; 3], Fix::Failed).unwrap();
        assert!(failed.position[0].is_nan());
        assert_eq!(failed.validate(None), Ok(()), "a failed estimate's NaN position is not used");
        assert_eq!(failed.plan_from(), None, "no standing estimate yet");
        // A failed estimate that carries the standing estimate: it must be a valid one.
        let standing = failed.with_standing(Some(([5.0, 6.0], [[4.0, 1.0], [1.0, 3.0]])));
        assert_eq!(standing.validate(None), Ok(()));
        assert_eq!(standing.plan_from(), Some(([5.0, 6.0], [[4.0, 1.0], [1.0, 3.0]])));
        let bad = failed.with_standing(Some(([5.0, 6.0], [[1.0, 3.0], [3.0, 1.0]])));
        assert_eq!(bad.validate(None), Err(Rejection::NotPositiveDefinite));
        let mut half = failed;
        half.position[0] = 1.0;
        assert!(half.validate(None).is_err(), "a half-NaN standing estimate is rejected");
        let usable = Estimate::new(0, 0, 1, &UAVS[..3], &[0.0; 3], ambiguous).unwrap();
        assert_eq!(usable.with_standing(Some(([0.0; 2], [[1.0, 0.0], [0.0, 1.0]]))), usable, "only a failed one");
        let mut eight = [[0.0; 2]; 8];
        for (i, p) in eight.iter_mut().enumerate() {
            *p = [i as f64, 1.0];
        }
        assert_eq!(Measurement::new(0, 0, &eight, &[1.0; 7], &[1.0; 8], &[0.0; 8]).unwrap().validate(None), Ok(()));
    }

    #[test]
    fn ignores_unused_entries() {
        let mut m = measurement();
        m.uavs[7] = [f64::NAN; 2];
        m.arrivals[6] = f64::INFINITY;
        m.sigmas[5] = -1.0;
        m.headings[4] = f64::NAN;
        m.reserved = [7, 7];
        assert_eq!(m.validate(None), Ok(()));
    }

    #[test]
    fn rejects_bad_version() {
        let mut m = measurement();
        m.header.version = 1;
        assert_eq!(m.validate(None), Err(Rejection::BadVersion { expected: 2, got: 1 }));
        let mut e = estimate();
        e.header.version = 0;
        assert_eq!(e.validate(None).unwrap_err().kind(), "bad_version");
        let mut c = command();
        c.header.version = u32::MAX;
        assert_eq!(c.validate(None).unwrap_err().kind(), "bad_version");
        let mut t = truth();
        t.header.version = 9;
        assert_eq!(t.validate(None).unwrap_err().kind(), "bad_version");
    }

    #[test]
    fn rejects_bad_count() {
        for count in [0, 1, 2, 9, 1000, u32::MAX] {
            let mut m = measurement();
            m.count = count;
            assert_eq!(m.validate(None), Err(Rejection::BadCount { count }));
            let mut e = estimate();
            e.count = count;
            assert_eq!(e.validate(None), Err(Rejection::BadCount { count }));
            let mut c = command();
            c.count = count;
            assert_eq!(c.validate(None), Err(Rejection::BadCount { count }));
            assert!(m.len() <= MAX_UAVS && m.arrivals().len() <= MAX_UAVS, "accessors clamp");
        }
    }

    #[test]
    fn rejects_not_finite() {
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let cases = [
                ("uavs", with(measurement(), |m| m.uavs[3][1] = bad).validate(None)),
                ("arrivals", with(measurement(), |m| m.arrivals[2] = bad).validate(None)),
                ("sigmas", with(measurement(), |m| m.sigmas[0] = bad).validate(None)),
                ("headings", with(measurement(), |m| m.headings[1] = bad).validate(None)),
                ("uavs", with(estimate(), |e| e.uavs[0][0] = bad).validate(None)),
                ("headings", with(estimate(), |e| e.headings[3] = bad).validate(None)),
                ("position", with(estimate(), |e| e.position[1] = bad).validate(None)),
                ("covariance", with(estimate(), |e| e.covariance[1][0] = bad).validate(None)),
                ("objective", with(command(), |c| c.objective = bad).validate(None)),
                ("headings", with(command(), |c| c.headings[2] = bad).validate(None)),
                ("waypoints", with(command(), |c| c.waypoints[3][0] = bad).validate(None)),
                ("position", with(truth(), |t| t.position[0] = bad).validate(None)),
            ];
            for (field, case) in cases {
                assert_eq!(case, Err(Rejection::NotFinite { field }), "{field} = {bad}");
            }
        }
    }

    #[test]
    fn rejects_non_positive_sigma() {
        for s in [0.0, -0.0, -1.0, -f64::MIN_POSITIVE] {
            let m = with(measurement(), |m| m.sigmas[2] = s);
            assert_eq!(m.validate(None), Err(Rejection::NonPositiveSigma { index: 2 }));
        }
        assert_eq!(with(measurement(), |m| m.sigmas[0] = MIN_SIGMA_M).validate(None), Ok(()));
    }

    /// Values every later check would pass, but the estimator or the planner could not use — so that the
    /// step would never be commanded: refused at the wire, with the field named.
    #[test]
    fn rejects_what_the_maths_cannot_take() {
        let field = |m: Measurement| match m.validate(None) {
            Err(Rejection::BadField { field }) => field.split(' ').next().unwrap_or_default().to_string(),
            other => format!("{other:?}"),
        };
        // Each UAV's stated σ (range σ with GNSS and clock σ) within 1e-6..1e7 m.
        assert_eq!(field(with(measurement(), |m| m.sigmas[0] = f64::MIN_POSITIVE)), "stated");
        assert_eq!(field(with(measurement(), |m| m.sigmas[1] = 1.0001e7)), "stated");
        assert_eq!(with(measurement(), |m| m.sigmas[1] = MAX_SIGMA_M).validate(None), Ok(()));
        // A clock σ of 1e12 ns is 3e11 m of range; a GNSS σ of 1e8 m; the squares of 1e200 overflow.
        assert_eq!(field(with(measurement(), |m| m.clock_sigmas_ns[0] = 1.0e12)), "stated");
        assert_eq!(field(with(measurement(), |m| m.clock_bias_sigmas_ns[3] = 1.0e12)), "stated");
        assert_eq!(field(with(measurement(), |m| m.position_sigmas[2] = 1.0e8)), "stated");
        assert_eq!(field(with(measurement(), |m| m.position_bias_sigmas[1] = 1.0e200)), "stated");
        assert_eq!(with(measurement(), |m| m.clock_sigmas_ns[0] = 1.0e5).validate(None), Ok(()));
        // A GNSS σ beside a tiny range σ lifts the stated σ into range.
        let lifted = with(measurement(), |m| {
            m.sigmas[0] = 1.0e-9;
            m.position_sigmas[0] = 1.0;
        });
        assert_eq!(lifted.validate(None), Ok(()));
        // Positions within the plane's extent.
        assert_eq!(field(with(measurement(), |m| m.uavs[1][0] = 1.0e9)), "uavs");
        assert_eq!(field(with(measurement(), |m| m.uavs[3][1] = -SWARM_EXTENT_M * 1.0001)), "uavs");
        assert_eq!(with(measurement(), |m| m.uavs[3][1] = -SWARM_EXTENT_M).validate(None), Ok(()));
        // Arrivals near their epoch; only the heard ones count.
        assert_eq!(field(with(measurement(), |m| m.arrivals[2] = 5.0e17)), "arrivals");
        assert_eq!(field(with(measurement(), |m| m.arrivals[0] = -1.0e300)), "arrivals");
        assert_eq!(with(measurement(), |m| m.arrivals[2] = MAX_ARRIVAL_M).validate(None), Ok(()));
        // An estimate's stated σ, which the planner plans with, the same.
        let stated = |s: f64| {
            let mut e = estimate();
            e.sigmas[..4].fill(30.0);
            e.sigmas[1] = s;
            e.validate(None)
        };
        assert_eq!(stated(30.0), Ok(()));
        assert_eq!(stated(MAX_SIGMA_M), Ok(()));
        assert!(matches!(stated(1.0e8), Err(Rejection::BadField { .. })));
        assert!(matches!(stated(1.0e-9), Err(Rejection::BadField { .. })));
        let unheard = with(measurement(), |m| {
            m.heard &= !(1 << 2);
            m.arrivals[2] = 5.0e17;
        });
        assert_eq!(unheard.validate(None), Ok(()));
    }

    #[test]
    fn rejects_not_positive_definite() {
        for cov in [
            [[0.0, 0.0], [0.0, 1.0]],
            [[-1.0, 0.0], [0.0, 1.0]],
            [[1.0, 0.0], [0.0, -1.0]],
            [[1.0, 1.0], [1.0, 1.0]],                               // singular
            [[1.0, 2.0], [2.0, 1.0]],                               // indefinite
            [[4.0, 1.0], [1.1, 9.0]],                               // not symmetric
            [[1e300, 1e300], [1e300, 1e300]],                       // singular, where the determinant would overflow
            [[1e-310, 0.0], [0.0, 1e-310]],                         // subnormal variances: no inverse in floating point
            [[1e-307, -9.9999999e-308], [-9.9999999e-308, 1e-307]], // an inverse beyond the floats
            [[1e308, 0.0], [0.0, 1e308]],                           // a trace beyond the floats
        ] {
            let e = with(estimate(), |e| e.covariance = cov);
            assert_eq!(e.validate(None), Err(Rejection::NotPositiveDefinite), "{cov:?}");
        }
        for cov in [
            [[1e300, 0.0], [0.0, 1e300]],
            [[1e-300, 0.0], [0.0, 1e-300]],
            [[4.0, 1.0], [1.0 + 1e-12, 9.0]],
            [[2.0, -1.999], [-1.999, 2.0]],
        ] {
            assert!(is_symmetric_positive_definite(&cov), "{cov:?}");
        }
    }

    /// What the planner plans with — the covariance plus the biases' `bias_cov` — must be a covariance
    /// it takes: a `bias_cov` that is not positive semi-definite, or a sum beyond the floats, is refused.
    #[test]
    fn the_covariance_planned_with_is_one_the_planner_takes() {
        let field = |e: Estimate| e.validate(None).map_err(|r| r.kind());
        assert_eq!(field(with(estimate(), |e| e.bias_cov = [[4.0, 2.0], [2.0, 1.0]])), Ok(())); // rank one
        assert_eq!(field(with(estimate(), |e| e.bias_cov = [[0.0; 2]; 2])), Ok(()));
        for bad in [[[-1.0, 0.0], [0.0, 1.0]], [[1.0, 2.0], [2.0, 1.0]], [[1.0, 0.5], [0.4, 1.0]]] {
            assert_eq!(field(with(estimate(), |e| e.bias_cov = bad)), Err("bad_field"), "{bad:?}");
        }
        let huge = with(estimate(), |e| {
            e.covariance = [[1e308, 0.0], [0.0, 1.0]];
            e.bias_cov = [[1e308, 0.0], [0.0, 0.0]];
        });
        assert_eq!(field(huge), Err("not_positive_definite"));
    }

    #[test]
    fn checks_the_fused_state_fields() {
        assert_eq!(with(estimate(), |e| e.status = 3).fix().map(|f| f.status()), Some(EstimateStatus::Rejected));
        assert_eq!(with(estimate(), |e| e.status = 3).validate(None), Ok(()));
        assert_eq!(
            with(estimate(), |e| e.estimator = 2).validate(None),
            Err(Rejection::UnknownKind { field: "estimator", kind: 2 })
        );
        assert_eq!(
            with(estimate(), |e| e.model = 7).validate(None),
            Err(Rejection::UnknownKind { field: "model", kind: 7 })
        );
        let cv = |e: &mut Estimate| {
            e.estimator = 1;
            e.model = 1;
        };
        assert_eq!(with(estimate(), cv).validate(None), Ok(()));
        assert_eq!(
            with(estimate(), |e| {
                cv(e);
                e.velocity[1] = f64::NAN;
            })
            .validate(None),
            Err(Rejection::NotFinite { field: "velocity" })
        );
    }

    #[test]
    fn rejects_unknown_status() {
        for status in [5u8, 6, 128, 255] {
            let e = with(estimate(), |e| e.status = status);
            assert_eq!(e.validate(None), Err(Rejection::UnknownStatus { status }));
            assert_eq!(e.fix(), None);
        }
    }

    #[test]
    fn checks_the_previous_command_of_a_truth() {
        use crate::messages::CommandOutcome;
        assert_eq!(truth().previous_command(), Some(CommandOutcome::None));
        for outcome in [CommandOutcome::None, CommandOutcome::Flown, CommandOutcome::Missed] {
            let t = truth().with_previous_command(outcome);
            assert_eq!((t.validate(None), t.previous_command()), (Ok(()), Some(outcome)));
            assert_eq!(CommandOutcome::from_u32(outcome as u32), Some(outcome));
        }
        assert_eq!(CommandOutcome::Missed.name(), "missed");
        for bad in [3u32, 17, u32::MAX] {
            let t = with(truth(), |t| t.previous_command = bad);
            assert_eq!(t.validate(None), Err(Rejection::UnknownKind { field: "previous_command", kind: bad }));
            assert_eq!(t.previous_command(), None);
        }
        // The multipath mask: one bit per UAV (at most 8).
        assert_eq!(with(truth(), |t| t.multipath = 0b101).validate(None), Ok(()));
        assert_eq!(
            with(truth(), |t| t.multipath = 0x100).validate(None),
            Err(Rejection::UnknownKind { field: "multipath", kind: 0x100 })
        );
    }

    #[test]
    fn rejects_stale() {
        assert_eq!(measurement().validate(Some(10)), Err(Rejection::Stale { seq: 10, last: 10 }));
        assert_eq!(estimate().validate(Some(11)), Err(Rejection::Stale { seq: 10, last: 11 }));
        assert_eq!(command().validate(Some(u64::MAX)), Err(Rejection::Stale { seq: 10, last: u64::MAX }));
        assert_eq!(truth().validate(Some(10)).unwrap_err().kind(), "stale");
    }

    #[test]
    fn the_echoed_state_is_the_estimate_planned_from_and_is_checked_like_it() {
        use crate::messages::{EchoedState, StateEcho};
        // A usable estimate: its fix and posterior fields.
        let e = estimate().with_extra(&crate::PosteriorExtra {
            estimator: 1,
            model: 1,
            rejected_run: 2,
            confirmed: 3,
            drop_uavs: 0b100,
            drop_run: 2,
            velocity: [1.0, -2.0],
            cross_cov: [[0.1, 0.2], [0.3, 0.4]],
            velocity_cov: [[5.0, 0.5], [0.5, 6.0]],
            bias_sensitivity: [[0.5; crate::MAX_UAVS]; 4],
            alternative: 1,
            alt_mean: [1.0, 2.0, 0.0, 0.0],
            alt_cov: [[4.0, 0.0, 0.0, 0.0], [0.0, 4.0, 0.0, 0.0], [0.0; 4], [0.0; 4]],
            alt_bias_sensitivity: [[0.25; crate::MAX_UAVS]; 4],
            window: crate::TrackWindow {
                open: 1,
                count: 1,
                base_matrix: [[1e-4, 0.0], [0.0, 2e-4]],
                base_vector: [2.5, 3.0],
                bursts: [crate::WindowBurst {
                    step: 2,
                    count: 4,
                    heard: 0b1011,
                    positions: [[1000.0, 2000.0]; crate::MAX_UAVS],
                    arrivals: [5.0, 7.0, 0.0, 9.0, 0.0, 0.0, 0.0, 0.0],
                    sigmas: [30.0; crate::MAX_UAVS],
                    bias_sigmas: [0.0; crate::MAX_UAVS],
                    ..crate::WindowBurst::default()
                }; crate::MAX_WINDOW_BURSTS],
                ..crate::TrackWindow::default()
            },
        });
        let c = command().with_state_of(&e);
        assert_eq!(c.validate(None), Ok(()));
        match c.state.decode() {
            Some(EchoedState::State { step, estimate: (p, m), extra }) => {
                assert_eq!((step, p, m), (3, e.position, e.covariance));
                assert_eq!(extra, e.extra());
            }
            other => panic!("{other:?}"),
        }
        // A failed one: its standing estimate, or no state yet.
        let failed = Estimate::new(4, 11, 42, &UAVS, &[0.1; 4], Fix::Failed).unwrap();
        let standing = failed.with_standing(Some(([7.0, 8.0], [[2.0, 0.0], [0.0, 2.0]])));
        assert!(matches!(
            StateEcho::of(&standing).unwrap().decode(),
            Some(EchoedState::State { step: 4, estimate: ([7.0, 8.0], _), .. })
        ));
        assert_eq!(
            StateEcho::of(&failed).unwrap().decode(),
            Some(EchoedState::Empty { step: 4, held: crate::HeldBursts::default() })
        );
        // A hold echoes nothing; a bad echo is rejected with the command.
        assert_eq!(command().state.decode(), None);
        assert_eq!(command().validate(None), Ok(()));
        let bad = |f: fn(&mut StateEcho)| with(c, |c| f(&mut c.state)).validate(None).unwrap_err().kind();
        assert_eq!(bad(|s| s.position[1] = f64::NAN), "not_finite");
        assert_eq!(bad(|s| s.covariance[1][1] = -1.0), "not_positive_definite");
        assert_eq!(bad(|s| s.kind = 3), "unknown_kind");
        assert_eq!(bad(|s| s.velocity_cov[0][0] = f64::INFINITY), "not_finite");
        assert_eq!(bad(|s| s.bias_sensitivity[3][7] = f64::NAN), "not_finite");
        assert_eq!(bad(|s| s.alt_cov[2][1] = f64::NAN), "not_finite");
        // The window: its summary, each burst's arrivals where kept, its σ, its mask and count.
        assert_eq!(bad(|s| s.window.base_vector[1] = f64::NAN), "not_finite");
        assert_eq!(bad(|s| s.window.bursts[0].arrivals[3] = f64::NAN), "not_finite");
        assert_eq!(bad(|s| s.window.bursts[0].sigmas[2] = 0.0), "bad_field");
        assert_eq!(bad(|s| s.window.bursts[0].heard = 0b1_0000), "bad_field");
        assert_eq!(bad(|s| s.window.count = 9), "bad_field");
        assert_eq!(bad(|s| s.window.open = 2), "unknown_kind");
        // An arrival not kept is not read, and a closed window not at all.
        assert_eq!(with(c, |c| c.state.window.bursts[0].arrivals[2] = f64::NAN).validate(None), Ok(()));
        assert_eq!(
            with(c, |c| {
                c.state.window.open = 0;
                c.state.window.count = 200
            })
            .validate(None),
            Ok(())
        );
        assert_eq!(bad(|s| s.alternative = 2), "unknown_kind");

        // The monitor's answer to a state request carries the echo, checked the same way; a hold is no
        // state to send.
        let answer = crate::EstimatorState::new(c.state, 7, 1);
        assert_eq!((answer.header.step, answer.validate(Some(6))), (3, Ok(())));
        assert_eq!(answer.validate(Some(7)).unwrap_err().kind(), "stale");
        assert_eq!(
            crate::EstimatorState::new(command().state, 7, 1).validate(None).unwrap_err().kind(),
            "unknown_kind"
        );
        let mut bad_answer = answer;
        bad_answer.state.covariance[0][0] = f64::NAN;
        assert_eq!(bad_answer.validate(None).unwrap_err().kind(), "not_finite");
    }

    #[test]
    fn checks_control_messages() {
        let c = Control::new(ControlKind::Hello, 0, 5, 9, 100, "planner", "ga/analytical").unwrap();
        assert_eq!(c.validate(Some(4)), Ok(()));
        assert_eq!((c.kind(), c.role(), c.detail()), (Some(ControlKind::Hello), Some("planner"), "ga/analytical"));
        // A planner's `solver/objective` longer than the field is cut, not refused (it stopped the
        // planner of `--solver gradient` and of `--objective posterior-cubature` at start).
        let long = Control::new(ControlKind::Hello, 0, 1, 7, 1, "planner", "gradient/posterior-cubature").unwrap();
        assert_eq!((long.validate(None), long.detail()), (Ok(()), "gradient/posteri"));
        let plain = Control::new(ControlKind::Shutdown, 0, 5, 9, 100, "launcher", "").unwrap();
        assert_eq!((plain.validate(None), plain.detail()), (Ok(()), ""));
        assert_eq!(c.validate(Some(5)).unwrap_err().kind(), "stale");
        assert_eq!(with(c, |c| c.kind = 5).validate(None), Ok(()), "5 is a status (v3)");
        assert_eq!(with(c, |c| c.kind = 6).validate(None), Ok(()), "6 asks for a state (v4)");
        assert_eq!(with(c, |c| c.kind = 7).validate(None), Ok(()), "7 tells a process of another run to leave (v5)");
        assert_eq!(
            with(c, |c| c.kind = 8).validate(None),
            Err(Rejection::UnknownKind { field: "control kind", kind: 8 })
        );
        // Any run: a fingerprint, or 0 for a sender without a scenario.
        assert_eq!((c.run, c.with_run(u64::MAX).validate(None)), (0, Ok(())));
        assert_eq!(with(c, |c| c.role.bytes = [0; 16]).validate(None), Err(Rejection::BadName { field: "role" }));
        assert_eq!(with(c, |c| c.detail.bytes[0] = 0x80).validate(None).unwrap_err().kind(), "bad_name");
        assert_eq!(with(c, |c| c.header.version = 1).validate(None).unwrap_err().kind(), "bad_version");
        let replay = Control::new(ControlKind::Replay, ControlKind::IN_FLIGHT, 6, 9, 100, "planner", "").unwrap();
        assert_eq!((replay.validate(None), replay.kind()), (Ok(()), Some(ControlKind::Replay)));
    }

    #[test]
    fn rejects_bad_name() {
        let c = with(command(), |c| c.solver.bytes = [0; 16]);
        assert_eq!(c.validate(None), Err(Rejection::BadName { field: "solver" }));
        let c = with(command(), |c| c.objective_name.bytes[0] = 0xC3);
        assert_eq!(c.validate(None), Err(Rejection::BadName { field: "objective_name" }));
        let c = with(command(), |c| c.solver.bytes[15] = b'\n');
        assert_eq!(c.validate(None).unwrap_err().kind(), "bad_name");
    }

    #[test]
    fn a_receiver_that_knows_its_run_rejects_data_of_another_run_and_moves_nothing() {
        let mut counter = RejectionCounter::new();
        let of_run = |run: u32, seq: u64| with(truth(), |t| (t.header.run, t.header.seq) = (run, seq));
        // No run known: any run is accepted.
        let mut last = None;
        assert_eq!(counter.check(&of_run(0xAB, 5), &mut last), Ok(()));
        counter.set_run(0x1234);
        // Another run (with a newer sequence number) is rejected before its number is looked at: the
        // stream's last accepted number stays.
        let r = counter.check(&of_run(0x9999, u64::MAX), &mut last).unwrap_err();
        assert_eq!((r, r.kind()), (Rejection::OtherRun { expected: 0x1234, got: 0x9999 }, "other_run"));
        assert_eq!(last, Some(5));
        // This run, and no run stated (a foreign front end), are accepted.
        assert_eq!(counter.check(&of_run(0x1234, 6), &mut last), Ok(()));
        assert_eq!(counter.check(&of_run(0, 7), &mut last), Ok(()));
        assert_eq!(last, Some(7));
        assert_eq!(counter.count(MessageKind::Truth, "other_run"), 1);
        // Control messages state their run themselves (how another run is told to leave): exempt.
        let mut c = Control::new(ControlKind::Hello, 0, 1, 7, 1, "planner", "").unwrap();
        c.header.run = 0x9999;
        assert_eq!(counter.check(&c, &mut None), Ok(()));
        // adopt_run takes a run only while none is known.
        let mut fresh = RejectionCounter::new();
        fresh.adopt_run(0);
        fresh.adopt_run(0x77);
        fresh.adopt_run(0x88);
        assert_eq!(fresh.run(), 0x77);
    }

    #[test]
    fn run_tags_are_never_zero_for_a_run() {
        assert_eq!(crate::run_tag(0), 0);
        assert_eq!(crate::run_tag(0xFFFF_FFFF_FFFF_FFFF), 1);
        assert_eq!(crate::run_tag(0x0000_0001_0000_0001), 1);
        assert_eq!(crate::run_tag(0x1234_5678_0000_0000), 0x1234_5678);
    }

    #[test]
    fn kinds_are_stable_and_distinct() {
        let all = [
            Rejection::BadVersion { expected: 1, got: 2 },
            Rejection::BadCount { count: 0 },
            Rejection::NotFinite { field: "x" },
            Rejection::NonPositiveSigma { index: 0 },
            Rejection::NotPositiveDefinite,
            Rejection::UnknownStatus { status: 9 },
            Rejection::Stale { seq: 1, last: 2 },
            Rejection::BadName { field: "solver" },
            Rejection::UnknownKind { field: "control kind", kind: 7 },
            Rejection::OtherRun { expected: 1, got: 2 },
        ];
        for (i, r) in all.iter().enumerate() {
            assert_eq!(r.kind_index(), i);
            assert_eq!(r.kind(), Rejection::KINDS[i]);
            assert!(!r.to_string().is_empty());
        }
    }

    #[test]
    fn counter_tracks_seq_and_counts() {
        let mut counter = RejectionCounter::new();
        assert_eq!(counter.to_string(), "rejected 0");
        let mut last = None;
        assert!(counter.check(&measurement(), &mut last).is_ok());
        assert_eq!(last, Some(10));
        assert_eq!(counter.check(&measurement(), &mut last), Err(Rejection::Stale { seq: 10, last: 10 }));
        let mut next = measurement();
        next.header.seq = 11;
        next.count = 1;
        assert_eq!(counter.check(&next, &mut last).unwrap_err().kind(), "bad_count");
        assert_eq!(last, Some(10), "a rejected message does not advance the stream");
        next.count = 4;
        assert!(counter.check(&next, &mut last).is_ok());
        assert_eq!(last, Some(11));
        let mut cmd_last = None;
        let bad = with(command(), |c| c.objective = f64::NAN);
        assert!(counter.check(&bad, &mut cmd_last).is_err());
        assert_eq!(cmd_last, None);

        assert_eq!(counter.accepted(MessageKind::Measurement), 2);
        assert_eq!(counter.rejected(MessageKind::Measurement), 2);
        assert_eq!(counter.count(MessageKind::Measurement, "stale"), 1);
        assert_eq!(counter.count(MessageKind::Command, "not_finite"), 1);
        assert_eq!(counter.count(MessageKind::Command, "no_such_kind"), 0);
        assert_eq!(counter.total(), 3);
        assert_eq!(counter.to_string(), "rejected 3 (measurement: bad_count 1, stale 1; command: not_finite 1)");
    }

    fn with<T>(mut msg: T, f: impl FnOnce(&mut T)) -> T {
        f(&mut msg);
        msg
    }
}
