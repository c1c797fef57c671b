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

use crate::messages::{
    Command, Control, ControlKind, Estimate, EstimateStatus, FLAG_SILENT, Measurement, SwarmState, Truth,
};
use crate::{MAX_UAVS, MIN_UAVS};

mod counter;
mod covariance;
mod rejection;

pub use counter::RejectionCounter;
pub use covariance::{
    MIN_EIGENVALUE_M2, SYMMETRY_TOLERANCE, is_positive_semi_definite, is_symmetric_positive_definite,
};
pub use rejection::Rejection;

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
mod tests;
