//! Why a received message was rejected: one reason per kind, each with a stable snake_case name for
//! logs and counters.

use thiserror::Error;

use crate::{MAX_UAVS, MIN_UAVS};

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
    /// The estimate status is not one of [`EstimateStatus`](crate::messages::EstimateStatus).
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
    /// An enumerated field has an unknown value: a control message's kind (not one of
    /// [`ControlKind`](crate::messages::ControlKind)), a truth's `previous_command` (not one of
    /// [`CommandOutcome`](crate::CommandOutcome)).
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
