//! # uavloc-protocol — what the uavloc processes say to each other, and how
//!
//! The processes `emitter-sim → estimator → planner → monitor` exchange fixed-layout, versioned messages
//! over iceoryx2 publish/subscribe (zero-copy shared memory). This crate is the single place that defines:
//!
//! - [`messages`]: the `#[repr(C)]` plain-old-data message types ([`Measurement`], [`Estimate`],
//!   [`Command`], [`Truth`], and [`Control`] for process management) with a common [`Header`] (version, step, sequence number and the monotonic
//!   [`Stamps`] of every hop, so any receiver can compute per-hop and end-to-end latency);
//! - [`validate`](mod@validate): what a receiver must check before trusting a message ([`Rejection`]) and a
//!   [`RejectionCounter`] for the monitor;
//! - [`control`]: the control topic as one process sees it ([`ControlChannel`]: announce, take over,
//!   shut down; per-instance sequence numbers);
//! - [`services`]: every service name, under a [`Domain`] prefix (`--domain NAME` or `UAVLOC_DOMAIN`);
//! - [`transport`]: typed topics ([`Topic`], [`TopicPublisher`], [`TopicSubscriber`]) over iceoryx2 (a
//!   pub/sub service plus a companion event service of the same name, so subscribers can block in a
//!   `WaitSet`) or, as the benchmark baseline, Unix-domain datagram sockets ([`TransportKind`]), behind
//!   the same port traits; a process's [`Link`] (its node and transport) and [`WaitMode`]s.
//!
//! What a process does with them — its flags, exit codes, supervisor lines, recovery — is
//! `uavloc-runtime`'s; this crate has no command-line parser and writes no files.
//!
//! Conventions follow `uavloc-tdoa`: 2-D positions in metres, angles in radians, `uavs[0]` is the reference
//! UAV, range differences `d_i = r_i − r_0` for i = 1..N−1, 3 ≤ N ≤ [`MAX_UAVS`].

pub mod control;
pub mod messages;
pub mod resources;
pub mod services;
pub mod source;
pub mod stderr;
pub mod transport;
pub mod validate;

#[cfg(test)]
mod proptests;

use thiserror::Error;

pub use control::{ControlChannel, instance_id};
pub use messages::{
    Command, CommandOutcome, Control, ControlKind, EchoedState, Estimate, EstimateStatus, EstimatorState, Fix, Header,
    HeldBurst, HeldBursts, Latencies, LinkState, MAX_HELD_BURSTS, MAX_WINDOW_BURSTS, Measurement, Message, MessageKind,
    Name16, PlanInfo, PosteriorExtra, Stamps, StateEcho, SwarmState, TrackWindow, Truth, WindowBurst, cpu_ns, now_ns,
    run_tag,
};
pub use services::Domain;
pub use source::{Admitted, MeasurementGate, SourceLock, StepDigests, measurement_digest};
pub use transport::{
    Link, Sent, Topic, TopicEvents, TopicPublisher, TopicSubscriber, TransportError, TransportKind, WaitMode,
    WaitPolicy, Waitable, node, poll, wait_attached,
};
pub use validate::{Rejection, RejectionCounter};

/// Largest number of UAVs a message can carry (equals `tdoa::MAX_UAVS`; the two crates do not depend on
/// each other, so a crate using both should assert the equality).
pub const MAX_UAVS: usize = 8;

/// Smallest number of UAVs that makes a 2-D TDOA fix possible.
pub const MIN_UAVS: usize = 3;

/// Why a message could not be built, or a domain not accepted.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum ProtocolError {
    /// The UAV count is outside `MIN_UAVS..=MAX_UAVS`.
    #[error("need {MIN_UAVS} to {MAX_UAVS} UAVs, got {0}")]
    BadCount(usize),
    /// A per-UAV list does not have the expected length.
    #[error("{field}: expected {expected} values, got {got}")]
    LengthMismatch {
        /// Which list.
        field: &'static str,
        /// The length implied by the UAV count.
        expected: usize,
        /// The length given.
        got: usize,
    },
    /// A fixed-size name is empty, longer than 16 bytes or not printable ASCII.
    #[error("{field}: {name:?} is not a valid name (1 to 16 printable ASCII characters)")]
    BadName {
        /// Which name.
        field: &'static str,
        /// The name given.
        name: String,
    },
    /// A domain name is empty, too long or has characters other than `[A-Za-z0-9_-]`.
    #[error("invalid domain {domain:?}: {reason}")]
    BadDomain {
        /// The domain given.
        domain: String,
        /// What is wrong with it.
        reason: String,
    },
}
