//! Fixed-layout message types.
//!
//! Every message is `#[repr(C)]` plain old data: integers, `f64`s and byte arrays only (no `bool`, no Rust
//! enum, no pointer), with all padding spelled out as `reserved` fields, so that **any** bit pattern is a
//! valid value of the type. That is what makes receiving from shared memory sound, and what lets the tests
//! build messages from random bytes. A receiver must still call `validate` before trusting the content.
//!
//! Each type pins its iceoryx2 identity with `#[type_name("uavloc::<Name>/v<N>")]`; a process built with a
//! different layout or version fails to open the service (`IncompatibleTypes`) instead of misreading it.
//! Changing a layout means bumping both the type name and the `VERSION` constant.
//!
//! Per-UAV arrays have room for [`MAX_UAVS`] entries; only the first `count` are used (the range differences:
//! the first `count − 1`). The accessors return slices of exactly the used length.

use core::fmt;
use core::mem::size_of;

use iceoryx2::prelude::ZeroCopySend;

use crate::transport::{Link, PublishPort, SubscribePort, TransportError};
use crate::validate::Rejection;
use crate::{MAX_UAVS, MIN_UAVS, ProtocolError};

/// The current `CLOCK_MONOTONIC` time in nanoseconds: the same clock in every process of the machine, so
/// stamps taken in different processes can be subtracted. Never 0 in practice (0 means "not stamped").
pub fn now_ns() -> u64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `ts` is a valid, writable `timespec` for the duration of the call; `CLOCK_MONOTONIC` is
    // supported on every platform iceoryx2 runs on. The call writes only `ts`.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    assert_eq!(rc, 0, "clock_gettime(CLOCK_MONOTONIC) failed");
    (ts.tv_sec as u64).wrapping_mul(1_000_000_000).wrapping_add(ts.tv_nsec as u64)
}

/// The CPU time this process has used so far (user + system, all threads), nanoseconds (`getrusage`,
/// microsecond resolution).
pub fn cpu_ns() -> u64 {
    // SAFETY: `usage` is a valid, writable rusage; RUSAGE_SELF is always supported. On failure (never in
    // practice) the zeroed struct gives 0.
    let mut usage: libc::rusage = unsafe { core::mem::zeroed() };
    unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) };
    let ns = |t: libc::timeval| t.tv_sec as u64 * 1_000_000_000 + t.tv_usec as u64 * 1000;
    ns(usage.ru_utime) + ns(usage.ru_stime)
}

/// Which message type; indexes per-type tables (e.g. in [`RejectionCounter`](crate::RejectionCounter)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum MessageKind {
    /// [`Measurement`].
    Measurement,
    /// [`Estimate`].
    Estimate,
    /// [`Command`].
    Command,
    /// [`Truth`].
    Truth,
    /// [`Control`].
    Control,
    /// [`EstimatorState`].
    State,
}

impl MessageKind {
    /// All kinds, in index order.
    pub const ALL: [MessageKind; 6] = [
        MessageKind::Measurement,
        MessageKind::Estimate,
        MessageKind::Command,
        MessageKind::Truth,
        MessageKind::Control,
        MessageKind::State,
    ];

    /// Stable lower-case name (`"measurement"`, …).
    pub fn name(self) -> &'static str {
        match self {
            MessageKind::Measurement => "measurement",
            MessageKind::Estimate => "estimate",
            MessageKind::Command => "command",
            MessageKind::Truth => "truth",
            MessageKind::Control => "control",
            MessageKind::State => "state",
        }
    }

    /// Position in [`MessageKind::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }
}

impl fmt::Display for MessageKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Monotonic timestamps ([`now_ns`]) of one planning step's chain; 0 means "not stamped / not applicable".
///
/// The chain of step k: the command of step k−1 (the *trigger*) reaches emitter-sim, which moves the UAVs
/// and publishes the measurement; the estimator receives it and publishes the estimate; the planner receives
/// that and publishes the command. Each message carries the stamps of everything upstream of it, so the
/// monitor (or anyone) can compute [`Latencies`] from the last message alone.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, ZeroCopySend)]
#[type_name("uavloc::Stamps/v1")]
#[repr(C)]
pub struct Stamps {
    /// Publish time of the message that carries these stamps (set by [`TopicPublisher::send`](crate::TopicPublisher::send)).
    pub published_ns: u64,
    /// Publish time of the command that triggered this step (0 at the first step).
    pub trigger_command_published_ns: u64,
    /// When emitter-sim received that command.
    pub trigger_command_received_ns: u64,
    /// When the measurement of this step was published.
    pub measurement_published_ns: u64,
    /// When the estimator received it.
    pub measurement_received_ns: u64,
    /// When the estimate was published.
    pub estimate_published_ns: u64,
    /// When the planner received it.
    pub estimate_received_ns: u64,
    /// When the command of this step was published.
    pub command_published_ns: u64,
}

impl Stamps {
    /// Records that a message of `kind` is published at `t`: sets [`published_ns`](Self::published_ns) and the
    /// kind's own slot (a [`Truth`] has none).
    pub fn mark_published(&mut self, kind: MessageKind, t: u64) {
        self.published_ns = t;
        match kind {
            MessageKind::Measurement => self.measurement_published_ns = t,
            MessageKind::Estimate => self.estimate_published_ns = t,
            MessageKind::Command => self.command_published_ns = t,
            MessageKind::Truth | MessageKind::Control | MessageKind::State => {}
        }
    }

    /// The stamps for a message made from an upstream message of `kind` with stamps `upstream`, received at
    /// `received_ns`. A measurement or estimate carries its chain forward (adding the receive time); a
    /// command starts the chain of the next step (only the trigger stamps survive). `published_ns` and the
    /// downstream slots are cleared: they are set when the new message is sent.
    pub fn carried_from(kind: MessageKind, upstream: &Stamps, received_ns: u64) -> Stamps {
        match kind {
            MessageKind::Measurement => Stamps {
                published_ns: 0,
                measurement_received_ns: received_ns,
                estimate_published_ns: 0,
                estimate_received_ns: 0,
                command_published_ns: 0,
                ..*upstream
            },
            MessageKind::Estimate => {
                Stamps { published_ns: 0, estimate_received_ns: received_ns, command_published_ns: 0, ..*upstream }
            }
            MessageKind::Command => Stamps {
                trigger_command_published_ns: upstream.command_published_ns,
                trigger_command_received_ns: received_ns,
                ..Stamps::default()
            },
            MessageKind::Truth | MessageKind::Control | MessageKind::State => Stamps { published_ns: 0, ..*upstream },
        }
    }

    /// Per-hop and end-to-end latencies of the chain (each `None` when a stamp is missing).
    pub fn latencies(&self) -> Latencies {
        Latencies {
            trigger_hop_ns: span_ns(self.trigger_command_published_ns, self.trigger_command_received_ns),
            emitter_ns: span_ns(self.trigger_command_received_ns, self.measurement_published_ns),
            measurement_hop_ns: span_ns(self.measurement_published_ns, self.measurement_received_ns),
            estimator_ns: span_ns(self.measurement_received_ns, self.estimate_published_ns),
            estimate_hop_ns: span_ns(self.estimate_published_ns, self.estimate_received_ns),
            planner_ns: span_ns(self.estimate_received_ns, self.command_published_ns),
            end_to_end_ns: span_ns(self.measurement_published_ns, self.command_published_ns),
            cycle_ns: span_ns(self.trigger_command_published_ns, self.command_published_ns),
        }
    }

    /// Time from this message's publication to `now` (e.g. `now_ns()` right after receiving it).
    pub fn age_ns(&self, now: u64) -> Option<u64> {
        span_ns(self.published_ns, now)
    }
}

/// `end − start` when both are stamped (non-zero) and in order.
pub fn span_ns(start: u64, end: u64) -> Option<u64> {
    (start != 0 && end != 0 && end >= start).then(|| end - start)
}

/// Latencies derived from [`Stamps`], nanoseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Latencies {
    /// Trigger command: published → received by emitter-sim.
    pub trigger_hop_ns: Option<u64>,
    /// emitter-sim: command received → measurement published.
    pub emitter_ns: Option<u64>,
    /// Measurement: published → received by the estimator.
    pub measurement_hop_ns: Option<u64>,
    /// Estimator: measurement received → estimate published.
    pub estimator_ns: Option<u64>,
    /// Estimate: published → received by the planner.
    pub estimate_hop_ns: Option<u64>,
    /// Planner: estimate received → command published.
    pub planner_ns: Option<u64>,
    /// Measurement published → command published (the estimator + planner pipeline).
    pub end_to_end_ns: Option<u64>,
    /// Trigger command published → this step's command published (one whole closed-loop cycle).
    pub cycle_ns: Option<u64>,
}

/// Common header of every message.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, ZeroCopySend)]
#[type_name("uavloc::Header/v1")]
#[repr(C)]
pub struct Header {
    /// Layout version of the message type (its `VERSION`).
    pub version: u32,
    /// The sender's run ([`run_tag`] of its scenario's fingerprint); 0: not stated (a process without a
    /// scenario that did not carry one forward, a foreign front end). A receiver that knows its run rejects
    /// a message of another one ([`crate::Rejection::OtherRun`]); 0 is accepted by
    /// everyone. (The field was explicit padding, sent as 0, before: old senders state no run.)
    pub run: u32,
    /// Planning step (0-based).
    pub step: u64,
    /// Sequence number of this publisher's stream; strictly increasing.
    pub seq: u64,
    /// Monotonic stamps of this step's chain.
    pub stamps: Stamps,
}

impl Header {
    /// A header with no stamps.
    pub fn new(version: u32, step: u64, seq: u64) -> Self {
        Header { version, run: 0, step, seq, stamps: Stamps::default() }
    }
}

/// The 32-bit tag of a run (its scenario's 64-bit fingerprint, `model::Scenario::run_id`) that a message
/// header carries ([`Header::run`]): the two halves folded together, never 0 (0 states no run).
pub fn run_tag(run: u64) -> u32 {
    match (run ^ (run >> 32)) as u32 {
        0 if run != 0 => 1,
        tag => tag,
    }
}

/// Types for which every bit pattern of `size_of::<Self>()` bytes is a valid value, so a message can be read
/// from raw bytes (a datagram of the socket transport, random bytes in a property test) without undefined
/// behaviour. Reading is sound; trusting the content still needs `validate`.
///
/// # Safety
/// Implement only for `#[repr(C)]` types made of integers, floats and arrays of them (no `bool`, enum,
/// reference or pointer), whose padding is explicit fields (checked by `layout_has_no_implicit_padding`).
pub unsafe trait AnyBitPattern: Copy + 'static {
    /// The value whose bytes are `bytes`; `None` unless `bytes.len() == size_of::<Self>()`.
    fn from_bytes(bytes: &[u8]) -> Option<Self> {
        if bytes.len() != size_of::<Self>() {
            return None;
        }
        // SAFETY: the length is checked above; `read_unaligned` has no alignment requirement; by the
        // trait's contract every bit pattern is a valid `Self`.
        Some(unsafe { core::ptr::read_unaligned(bytes.as_ptr().cast::<Self>()) })
    }

    /// The bytes of the value (its in-memory representation, no serialisation).
    fn as_bytes(&self) -> &[u8] {
        // SAFETY: `self` is a valid, initialised `Self` of `size_of::<Self>()` bytes with no implicit padding
        // (trait contract), so all its bytes are initialised; the slice borrows `self`.
        unsafe { core::slice::from_raw_parts((self as *const Self).cast::<u8>(), size_of::<Self>()) }
    }
}

/// What every message type offers, so that transport and validation can be generic.
pub trait Message: AnyBitPattern + ZeroCopySend + fmt::Debug + Copy + Send + 'static {
    /// Which type this is.
    const KIND: MessageKind;
    /// Layout version (also in the pinned type name).
    const VERSION: u32;
    /// The pinned iceoryx2 type name (the `#[type_name]` attribute; a test keeps them equal).
    const TYPE_NAME: &'static str;

    /// The header.
    fn header(&self) -> &Header;

    /// The header, mutably.
    fn header_mut(&mut self) -> &mut Header;

    /// Checks the message; see [`crate::validate`].
    fn validate(&self, last_seq: Option<u64>) -> Result<(), Rejection>;

    /// Carries the stamps of `upstream`, received at `received_ns`, into this message
    /// (see [`Stamps::carried_from`]).
    fn carrying<U: Message>(mut self, upstream: &U, received_ns: u64) -> Self {
        self.header_mut().stamps = Stamps::carried_from(U::KIND, &upstream.header().stamps, received_ns);
        // The run goes down the chain (the estimator knows none of its own).
        self.header_mut().run = upstream.header().run;
        self
    }

    /// The transport's sending port for this type; use [`Topic::publisher`](crate::Topic::publisher).
    ///
    /// Implemented per message type in this crate (non-generic), so the iceoryx2 and socket port code is
    /// compiled once, here, and not again in every crate that opens a topic (it is most of a process
    /// crate's machine code otherwise: build time).
    #[doc(hidden)]
    fn publish_port(link: &Link, name: &str) -> Result<Box<dyn PublishPort<Self>>, TransportError>;

    /// The transport's receiving port for this type; use [`Topic::subscriber`](crate::Topic::subscriber).
    /// Implemented per type here, as [`Message::publish_port`].
    #[doc(hidden)]
    fn subscribe_port(link: &Link, name: &str) -> Result<Box<dyn SubscribePort<Self>>, TransportError>;
}

macro_rules! impl_message {
    ($ty:ident, $kind:expr, $version:expr, $name:expr) => {
        impl $ty {
            /// Layout version; bump together with the type name.
            pub const VERSION: u32 = $version;
        }

        // SAFETY: every message type is repr(C) of u8/u32/u64/f64 (arrays) and byte-array names, with its
        // padding spelled out as `reserved` fields (see the module docs and `layout_has_no_implicit_padding`).
        unsafe impl AnyBitPattern for $ty {}

        impl Message for $ty {
            const KIND: MessageKind = $kind;
            const VERSION: u32 = $version;
            const TYPE_NAME: &'static str = $name;

            fn header(&self) -> &Header {
                &self.header
            }

            fn header_mut(&mut self) -> &mut Header {
                &mut self.header
            }

            fn validate(&self, last_seq: Option<u64>) -> Result<(), Rejection> {
                $ty::validate(self, last_seq)
            }

            fn publish_port(link: &Link, name: &str) -> Result<Box<dyn PublishPort<Self>>, TransportError> {
                crate::transport::open_publish_port(link, name)
            }

            fn subscribe_port(link: &Link, name: &str) -> Result<Box<dyn SubscribePort<Self>>, TransportError> {
                crate::transport::open_subscribe_port(link, name)
            }
        }
    };
}

/// Checks a UAV count for a constructor.
fn check_count(n: usize) -> Result<usize, ProtocolError> {
    if (MIN_UAVS..=MAX_UAVS).contains(&n) { Ok(n) } else { Err(ProtocolError::BadCount(n)) }
}

fn check_len(field: &'static str, expected: usize, got: usize) -> Result<(), ProtocolError> {
    if expected == got { Ok(()) } else { Err(ProtocolError::LengthMismatch { field, expected, got }) }
}

/// The used length of per-UAV arrays for a raw `count` (clamped so accessors never panic on bad input).
fn used(count: u32) -> usize {
    (count as usize).min(MAX_UAVS)
}

/// A fixed 16-byte ASCII name, NUL-padded (e.g. a solver or objective name).
///
/// Valid when it has 1 to 16 printable ASCII characters (0x20..=0x7E) followed only by NULs.
#[derive(Clone, Copy, Default, PartialEq, Eq, Hash, ZeroCopySend)]
#[type_name("uavloc::Name16/v1")]
#[repr(C)]
pub struct Name16 {
    /// The raw bytes.
    pub bytes: [u8; 16],
}

impl Name16 {
    /// Capacity in bytes.
    pub const CAPACITY: usize = 16;

    /// Encodes `name` (1 to 16 printable ASCII characters).
    pub fn new(field: &'static str, name: &str) -> Result<Self, ProtocolError> {
        let b = name.as_bytes();
        if b.is_empty() || b.len() > Self::CAPACITY || !b.iter().all(|c| (0x20..=0x7E).contains(c)) {
            return Err(ProtocolError::BadName { field, name: name.to_owned() });
        }
        let mut bytes = [0u8; 16];
        bytes[..b.len()].copy_from_slice(b);
        Ok(Name16 { bytes })
    }

    /// Whether the bytes form a valid name.
    pub fn is_valid(&self) -> bool {
        self.as_str().is_some()
    }

    /// The name, or `None` if the bytes are not a valid name.
    pub fn as_str(&self) -> Option<&str> {
        let len = self.bytes.iter().position(|&c| c == 0).unwrap_or(Self::CAPACITY);
        let (text, pad) = self.bytes.split_at(len);
        if len == 0 || !text.iter().all(|c| (0x20..=0x7E).contains(c)) || pad.iter().any(|&c| c != 0) {
            return None;
        }
        // Printable ASCII is valid UTF-8.
        core::str::from_utf8(text).ok()
    }
}

impl fmt::Debug for Name16 {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.as_str() {
            Some(s) => write!(f, "Name16({s:?})"),
            None => write!(f, "Name16(invalid {:?})", self.bytes),
        }
    }
}

// ---------------------------------------------------------------------------------------------------------
// Measurement
// ---------------------------------------------------------------------------------------------------------

/// emitter-sim → estimator: the UAV geometry and the noisy range differences of one step.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("uavloc::Measurement/v1")]
#[repr(C)]
pub struct Measurement {
    /// Common header.
    pub header: Header,
    /// Number of UAVs N (3..=8).
    pub count: u32,
    /// Explicit padding; 0 when sent.
    pub reserved: u32,
    /// UAV positions (metres) at the measurement time; `uavs[0]` is the reference.
    pub uavs: [[f64; 2]; MAX_UAVS],
    /// Range differences `d_i = r_i − r_0`, i = 1..N−1 (metres); `diffs[i − 1]` belongs to UAV i.
    pub diffs: [f64; MAX_UAVS - 1],
    /// Per-UAV range noise standard deviation (metres, > 0).
    pub sigmas: [f64; MAX_UAVS],
    /// Current UAV headings (radians).
    pub headings: [f64; MAX_UAVS],
}

impl_message!(Measurement, MessageKind::Measurement, 1, "uavloc::Measurement/v1");

impl Measurement {
    /// A measurement of `uavs.len()` UAVs; `diffs` must have one entry fewer, `sigmas` and `headings` one
    /// per UAV. Content (finiteness, σ > 0) is checked by [`validate`](Self::validate), not here.
    pub fn new(
        step: u64,
        seq: u64,
        uavs: &[[f64; 2]],
        diffs: &[f64],
        sigmas: &[f64],
        headings: &[f64],
    ) -> Result<Self, ProtocolError> {
        let n = check_count(uavs.len())?;
        check_len("diffs", n - 1, diffs.len())?;
        check_len("sigmas", n, sigmas.len())?;
        check_len("headings", n, headings.len())?;
        let mut m = Measurement {
            header: Header::new(Self::VERSION, step, seq),
            count: n as u32,
            reserved: 0,
            uavs: [[0.0; 2]; MAX_UAVS],
            diffs: [0.0; MAX_UAVS - 1],
            sigmas: [0.0; MAX_UAVS],
            headings: [0.0; MAX_UAVS],
        };
        m.uavs[..n].copy_from_slice(uavs);
        m.diffs[..n - 1].copy_from_slice(diffs);
        m.sigmas[..n].copy_from_slice(sigmas);
        m.headings[..n].copy_from_slice(headings);
        Ok(m)
    }

    /// Number of UAVs in use (clamped to [`MAX_UAVS`]).
    pub fn len(&self) -> usize {
        used(self.count)
    }

    /// Whether no UAV is in use (never true for a valid message).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// UAV positions in use.
    pub fn uavs(&self) -> &[[f64; 2]] {
        &self.uavs[..self.len()]
    }

    /// Range differences in use (`count − 1` of them).
    pub fn diffs(&self) -> &[f64] {
        &self.diffs[..self.len().saturating_sub(1)]
    }

    /// Range sigmas in use.
    pub fn sigmas(&self) -> &[f64] {
        &self.sigmas[..self.len()]
    }

    /// Headings in use.
    pub fn headings(&self) -> &[f64] {
        &self.headings[..self.len()]
    }
}

// ---------------------------------------------------------------------------------------------------------
// Estimate
// ---------------------------------------------------------------------------------------------------------

/// Outcome of an estimation, as carried in [`Estimate::status`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum EstimateStatus {
    /// A unique, usable fix.
    Ok = 0,
    /// A usable fix chosen among several candidates (e.g. Chan's two roots).
    Ambiguous = 1,
    /// No fix of this step; position and covariance are the standing (last usable) estimate, NaN when
    /// there is none yet.
    Failed = 2,
    /// A usable estimate whose snapshot failed the fused estimator's χ² gate and was not fused: the
    /// position and covariance are the posterior predicted to this step.
    Rejected = 3,
}

impl EstimateStatus {
    /// Decodes the wire value.
    pub fn from_u8(v: u8) -> Option<Self> {
        match v {
            0 => Some(EstimateStatus::Ok),
            1 => Some(EstimateStatus::Ambiguous),
            2 => Some(EstimateStatus::Failed),
            3 => Some(EstimateStatus::Rejected),
            _ => None,
        }
    }

    /// Stable lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            EstimateStatus::Ok => "ok",
            EstimateStatus::Ambiguous => "ambiguous",
            EstimateStatus::Failed => "failed",
            EstimateStatus::Rejected => "rejected",
        }
    }

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
}

impl Fix {
    /// The wire status.
    pub fn status(&self) -> EstimateStatus {
        match self {
            Fix::Ok { .. } => EstimateStatus::Ok,
            Fix::Ambiguous { .. } => EstimateStatus::Ambiguous,
            Fix::Failed => EstimateStatus::Failed,
            Fix::Rejected { .. } => EstimateStatus::Rejected,
        }
    }

    /// The position and covariance of a usable fix.
    pub fn usable(&self) -> Option<([f64; 2], [[f64; 2]; 2])> {
        match *self {
            Fix::Ok { position, covariance }
            | Fix::Ambiguous { position, covariance }
            | Fix::Rejected { position, covariance } => Some((position, covariance)),
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
    /// Velocity estimate, m/s.
    pub velocity: [f64; 2],
    /// Position–velocity cross-covariance (rows: x, y; columns: vx, vy), m²/s.
    pub cross_cov: [[f64; 2]; 2],
    /// Velocity covariance, m²/s².
    pub velocity_cov: [[f64; 2]; 2],
}

/// The fused posterior's fields beyond the position, as every message that carries an estimator state
/// lays them out (`estimator`, `model`, `rejected_run`, `velocity`, `cross_cov`, `velocity_cov`): one
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
                    velocity: self.velocity,
                    cross_cov: self.cross_cov,
                    velocity_cov: self.velocity_cov,
                }
            }

            /// Sets the fused estimator's state beyond the position.
            fn set_extra(&mut self, extra: &PosteriorExtra) {
                self.estimator = extra.estimator;
                self.model = extra.model;
                self.rejected_run = extra.rejected_run;
                self.velocity = extra.velocity;
                self.cross_cov = extra.cross_cov;
                self.velocity_cov = extra.velocity_cov;
            }
        }
    };
}

impl_posterior_fields!(Estimate);
impl_posterior_fields!(StateEcho);

/// estimator → planner, monitor: the emitter estimate and the geometry it was computed for.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("uavloc::Estimate/v4")]
#[repr(C)]
pub struct Estimate {
    /// Common header (step of the measurement it was made from).
    pub header: Header,
    /// Id of the estimator process instance (e.g. pid and start time), to tell restarts apart.
    pub instance: u64,
    /// Number of UAVs N (3..=8).
    pub count: u32,
    /// [`EstimateStatus`] as `u8` (0 ok, 1 ambiguous, 2 failed, 3 rejected).
    pub status: u8,
    /// The estimator: 0 snapshot (Chan per step), 1 fused (the posterior of every snapshot so far).
    pub estimator: u8,
    /// The fused estimator's emitter model: 0 static, 1 constant velocity (0 for snapshot).
    pub model: u8,
    /// Fused: snapshots rejected in a row up to this one (the estimator restarts from Chan after a few,
    /// see `uavloc-estimator`); 0 otherwise.
    pub rejected_run: u8,
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
    /// is the run's. All 0: not stated (the scenario's σ is used).
    pub sigmas: [f64; MAX_UAVS],
}

impl_message!(Estimate, MessageKind::Estimate, 4, "uavloc::Estimate/v4");

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
            position,
            covariance,
            uavs: [[0.0; 2]; MAX_UAVS],
            headings: [0.0; MAX_UAVS],
            velocity: [0.0; 2],
            cross_cov: [[0.0; 2]; 2],
            velocity_cov: [[0.0; 2]; 2],
            sigmas: [0.0; MAX_UAVS],
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
        e.sigmas[..n].copy_from_slice(measurement.sigmas());
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
    /// failed one, `None` for a failed one without (no usable estimate yet) or an unknown status.
    pub fn plan_from(&self) -> Option<([f64; 2], [[f64; 2]; 2])> {
        match self.status()? {
            EstimateStatus::Failed if !self.position.iter().all(|v| v.is_finite()) => None,
            _ => Some((self.position, self.covariance)),
        }
    }

    /// Number of UAVs in use (clamped to [`MAX_UAVS`]).
    pub fn len(&self) -> usize {
        used(self.count)
    }

    /// Whether no UAV is in use (never true for a valid message).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// UAV positions in use.
    pub fn uavs(&self) -> &[[f64; 2]] {
        &self.uavs[..self.len()]
    }

    /// Headings in use.
    pub fn headings(&self) -> &[f64] {
        &self.headings[..self.len()]
    }

    /// The decoded status (`None` for an unknown wire value).
    pub fn status(&self) -> Option<EstimateStatus> {
        EstimateStatus::from_u8(self.status)
    }

    /// The fix (`None` for an unknown status).
    pub fn fix(&self) -> Option<Fix> {
        let (position, covariance) = (self.position, self.covariance);
        Some(match self.status()? {
            EstimateStatus::Ok => Fix::Ok { position, covariance },
            EstimateStatus::Ambiguous => Fix::Ambiguous { position, covariance },
            EstimateStatus::Failed => Fix::Failed,
            EstimateStatus::Rejected => Fix::Rejected { position, covariance },
        })
    }
}

// ---------------------------------------------------------------------------------------------------------
// Command
// ---------------------------------------------------------------------------------------------------------

/// The planner's output for one step: what goes into [`Command::new`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanInfo<'a> {
    /// Commanded headings, radians (one per UAV).
    pub headings: &'a [f64],
    /// The waypoints these headings lead to, metres (one per UAV).
    pub waypoints: &'a [[f64; 2]],
    /// The criterion value at the waypoints.
    pub objective: f64,
    /// Solver name (1 to 16 printable ASCII characters, e.g. `"pso"`).
    pub solver: &'a str,
    /// Objective name (1 to 16 printable ASCII characters, e.g. `"trace-crlb"`).
    pub objective_name: &'a str,
    /// Planning time, microseconds.
    pub plan_time_us: u64,
    /// Bitmask of violated or binding constraints (bit meanings defined by the planner).
    pub active_constraints: u64,
    /// The same bits for the constraints among them that are violated (not merely binding).
    pub violated_constraints: u64,
}

/// planner → emitter-sim, monitor: the headings to fly for the next step.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("uavloc::Command/v4")]
#[repr(C)]
pub struct Command {
    /// Common header (step of the estimate it was planned from).
    pub header: Header,
    /// Id of the planner process instance that made it.
    pub planner_instance: u64,
    /// Planning time, microseconds.
    pub plan_time_us: u64,
    /// Bitmask of violated or binding constraints.
    pub active_constraints: u64,
    /// The same bits for the active constraints that are violated (the others are binding).
    pub violated_constraints: u64,
    /// Number of UAVs N (3..=8).
    pub count: u32,
    /// What kind of command this is: 0 a plan; [`Command::FLAG_HOLD`] a hold (see there); a plan's safety
    /// certificate in [`Command::FLAG_CERTIFIED`] / [`Command::FLAG_UNCERTIFIED`]. Unknown bits are
    /// ignored.
    pub flags: u32,
    /// Criterion value at the waypoints.
    pub objective: f64,
    /// Commanded headings, radians.
    pub headings: [f64; MAX_UAVS],
    /// Waypoints, metres.
    pub waypoints: [[f64; 2]; MAX_UAVS],
    /// Solver name.
    pub solver: Name16,
    /// Objective name.
    pub objective_name: Name16,
    /// The estimator's state after the step this command was planned from, echoed from that estimate
    /// (v4): where a restarted, rewound or replayed-to estimator finds it (see [`StateEcho`]).
    pub state: StateEcho,
}

impl_message!(Command, MessageKind::Command, 4, "uavloc::Command/v4");

/// The estimator's state after step `step` as an [`Estimate`] carries it — the estimate the step is
/// planned from ([`Estimate::plan_from`]: the fix, or a failed step's standing estimate) and the fused
/// posterior beyond the position — echoed in the [`Command`] planned from it. With it an estimator
/// continues the chain at step `step + 1` exactly as the one that made the estimate would have
/// (`uavloc-estimator`), so no estimator keeps its answers or needs a checkpoint to answer a replay.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("uavloc::StateEcho/v1")]
#[repr(C)]
pub struct StateEcho {
    /// The step of the estimate.
    pub step: u64,
    /// [`StateEcho::NONE`] (a hold: planned from no estimate), [`StateEcho::STATE`] (position, covariance
    /// and the posterior fields hold the state) or [`StateEcho::EMPTY`] (the estimator had no usable
    /// estimate yet after `step`).
    pub kind: u8,
    /// As [`Estimate::estimator`].
    pub estimator: u8,
    /// As [`Estimate::model`].
    pub model: u8,
    /// As [`Estimate::rejected_run`].
    pub rejected_run: u8,
    /// Explicit padding; 0 when sent.
    pub reserved: u32,
    /// The estimate, metres.
    pub position: [f64; 2],
    /// Its covariance, m², row-major.
    pub covariance: [[f64; 2]; 2],
    /// As [`Estimate::velocity`], m/s.
    pub velocity: [f64; 2],
    /// As [`Estimate::cross_cov`], m²/s.
    pub cross_cov: [[f64; 2]; 2],
    /// As [`Estimate::velocity_cov`], m²/s².
    pub velocity_cov: [[f64; 2]; 2],
}

// SAFETY: repr(C) of u64, four u8, u32 and f64 arrays, without implicit padding (144 bytes, see
// `layout_is_stable`): every bit pattern is a value.
unsafe impl AnyBitPattern for StateEcho {}

/// What a [`StateEcho`] says, decoded.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum EchoedState {
    /// The estimator's state after `step`: the estimate and the posterior beyond the position.
    State {
        /// The step.
        step: u64,
        /// Position (m) and covariance (m²).
        estimate: ([f64; 2], [[f64; 2]; 2]),
        /// The fused posterior beyond the position.
        extra: PosteriorExtra,
    },
    /// After `step` the estimator had no usable estimate yet.
    Empty {
        /// The step.
        step: u64,
    },
}

impl EchoedState {
    /// The step the state is after.
    pub fn step(&self) -> u64 {
        match *self {
            EchoedState::State { step, .. } | EchoedState::Empty { step } => step,
        }
    }
}

impl StateEcho {
    /// [`StateEcho::kind`]: no state (a hold).
    pub const NONE: u8 = 0;
    /// [`StateEcho::kind`]: the state is in the fields.
    pub const STATE: u8 = 1;
    /// [`StateEcho::kind`]: no usable estimate yet after `step`.
    pub const EMPTY: u8 = 2;

    /// The state an estimate carries (see the type's docs); `None` for an unknown status.
    pub fn of(e: &Estimate) -> Option<Self> {
        e.status()?;
        let mut echo = StateEcho { step: e.header.step, ..StateEcho::default() };
        match e.plan_from() {
            Some((position, covariance)) => {
                echo.kind = Self::STATE;
                echo.position = position;
                echo.covariance = covariance;
                echo.set_extra(&e.extra());
            }
            None => echo.kind = Self::EMPTY,
        }
        Some(echo)
    }

    /// The decoded state (`None` for a hold or an unknown kind).
    pub fn decode(&self) -> Option<EchoedState> {
        match self.kind {
            Self::STATE => Some(EchoedState::State {
                step: self.step,
                estimate: (self.position, self.covariance),
                extra: self.extra(),
            }),
            Self::EMPTY => Some(EchoedState::Empty { step: self.step }),
            _ => None,
        }
    }
}

impl Command {
    /// [`Command::flags`] bit: a *hold*, not a plan — no fresh estimate of the step reached the planner
    /// within its deadline (`planner --estimate-deadline-ms`), so it commands the UAVs' current headings
    /// (they fly straight on); `objective` is then −1 (no value) and `plan_time_us` 0.
    pub const FLAG_HOLD: u32 = 1;

    /// [`Command::flags`] bit: the plan carries a safety certificate (the planner's `safety =
    /// "certified"`: spacing and standoff hold along the arcs, with a backup manoeuvre for ever).
    pub const FLAG_CERTIFIED: u32 = 2;

    /// [`Command::flags`] bit: the planner certifies its plans but found no certified plan this step (an
    /// unsafe start, or the estimate moved the standing backup's margins away): the plan is the one with
    /// the largest minimum margin. Neither bit: a hold, or a planner that keeps the constraints at the
    /// waypoints only (`safety = "waypoints"`).
    pub const FLAG_UNCERTIFIED: u32 = 4;

    /// The safety certificate's word on this command: `Some(true)` certified, `Some(false)` no certified
    /// plan existed, `None` not certified by design (a hold, or `safety = "waypoints"`).
    pub fn certified(&self) -> Option<bool> {
        if self.flags & Self::FLAG_CERTIFIED != 0 {
            Some(true)
        } else if self.flags & Self::FLAG_UNCERTIFIED != 0 {
            Some(false)
        } else {
            None
        }
    }

    /// This command with the estimator state `estimate` carries echoed ([`StateEcho::of`]).
    pub fn with_state_of(mut self, estimate: &Estimate) -> Self {
        self.state = StateEcho::of(estimate).unwrap_or_default();
        self
    }

    /// Whether this is a hold ([`Command::FLAG_HOLD`]).
    pub fn is_hold(&self) -> bool {
        self.flags & Self::FLAG_HOLD != 0
    }

    /// A command for `plan.headings.len()` UAVs.
    pub fn new(step: u64, seq: u64, planner_instance: u64, plan: &PlanInfo<'_>) -> Result<Self, ProtocolError> {
        let n = check_count(plan.headings.len())?;
        check_len("waypoints", n, plan.waypoints.len())?;
        let mut c = Command {
            header: Header::new(Self::VERSION, step, seq),
            planner_instance,
            plan_time_us: plan.plan_time_us,
            active_constraints: plan.active_constraints,
            violated_constraints: plan.violated_constraints,
            count: n as u32,
            flags: 0,
            objective: plan.objective,
            headings: [0.0; MAX_UAVS],
            waypoints: [[0.0; 2]; MAX_UAVS],
            solver: Name16::new("solver", plan.solver)?,
            objective_name: Name16::new("objective_name", plan.objective_name)?,
            state: StateEcho::default(),
        };
        c.headings[..n].copy_from_slice(plan.headings);
        c.waypoints[..n].copy_from_slice(plan.waypoints);
        Ok(c)
    }

    /// The command planned from `estimate` (received at `received_ns`): same step, stamps carried forward,
    /// the estimator's state echoed ([`Command::with_state_of`]).
    pub fn from_estimate(
        estimate: &Estimate,
        received_ns: u64,
        seq: u64,
        planner_instance: u64,
        plan: &PlanInfo<'_>,
    ) -> Result<Self, ProtocolError> {
        Ok(Command::new(estimate.header.step, seq, planner_instance, plan)?
            .carrying(estimate, received_ns)
            .with_state_of(estimate))
    }

    /// Number of UAVs in use (clamped to [`MAX_UAVS`]).
    pub fn len(&self) -> usize {
        used(self.count)
    }

    /// Whether no UAV is in use (never true for a valid message).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Headings in use.
    pub fn headings(&self) -> &[f64] {
        &self.headings[..self.len()]
    }

    /// Waypoints in use.
    pub fn waypoints(&self) -> &[[f64; 2]] {
        &self.waypoints[..self.len()]
    }

    /// Sets the solver name.
    pub fn set_solver(&mut self, name: &str) -> Result<(), ProtocolError> {
        self.solver = Name16::new("solver", name)?;
        Ok(())
    }

    /// The solver name (`None` if the bytes are not a valid name).
    pub fn solver(&self) -> Option<&str> {
        self.solver.as_str()
    }

    /// Sets the objective name.
    pub fn set_objective_name(&mut self, name: &str) -> Result<(), ProtocolError> {
        self.objective_name = Name16::new("objective_name", name)?;
        Ok(())
    }

    /// The objective name (`None` if the bytes are not a valid name).
    pub fn objective_name(&self) -> Option<&str> {
        self.objective_name.as_str()
    }
}

// ---------------------------------------------------------------------------------------------------------
// Truth
// ---------------------------------------------------------------------------------------------------------

/// What the world did with the command of the step before (carried by [`Truth::previous_command`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum CommandOutcome {
    /// No step before (step 0), or not stated.
    None = 0,
    /// The command of step k − 1 was flown.
    Flown = 1,
    /// No command for step k − 1 arrived before step k was due (emitter-sim's real-time mode): the UAVs
    /// flew straight on at their headings, and a command that came later was not applied.
    Missed = 2,
}

impl CommandOutcome {
    /// Decodes the wire value.
    pub fn from_u32(v: u32) -> Option<Self> {
        match v {
            0 => Some(CommandOutcome::None),
            1 => Some(CommandOutcome::Flown),
            2 => Some(CommandOutcome::Missed),
            _ => None,
        }
    }

    /// Stable lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            CommandOutcome::None => "none",
            CommandOutcome::Flown => "flown",
            CommandOutcome::Missed => "missed",
        }
    }
}

/// emitter-sim → monitor only: the true emitter position of a step (never seen by estimator or planner),
/// and what the world did in the interval before it — whether the command of the step before was flown or
/// missed ([`CommandOutcome`]). Only emitter-sim knows the latter for sure: in real-time mode a command
/// may reach the monitor and still be too late for the world.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("uavloc::Truth/v2")]
#[repr(C)]
pub struct Truth {
    /// Common header (step of the measurement it belongs to).
    pub header: Header,
    /// True emitter position, metres.
    pub position: [f64; 2],
    /// [`CommandOutcome`] of the command of step `header.step − 1`, as `u32`.
    pub previous_command: u32,
    /// Explicit padding; 0 when sent.
    pub reserved: u32,
}

impl_message!(Truth, MessageKind::Truth, 2, "uavloc::Truth/v2");

impl Truth {
    /// The truth of `step` (previous command: [`CommandOutcome::None`]).
    pub fn new(step: u64, seq: u64, position: [f64; 2]) -> Self {
        Truth {
            header: Header::new(Self::VERSION, step, seq),
            position,
            previous_command: CommandOutcome::None as u32,
            reserved: 0,
        }
    }

    /// The same truth, saying what became of the command of the step before.
    pub fn with_previous_command(mut self, outcome: CommandOutcome) -> Self {
        self.previous_command = outcome as u32;
        self
    }

    /// The decoded outcome of the previous step's command (`None` for an unknown wire value).
    pub fn previous_command(&self) -> Option<CommandOutcome> {
        CommandOutcome::from_u32(self.previous_command)
    }
}

// ---------------------------------------------------------------------------------------------------------
// EstimatorState
// ---------------------------------------------------------------------------------------------------------

/// Monitor → estimator (the `state` topic): the estimator's state after step `header.step`, as the command
/// of that step echoed it ([`Command::state`]), in answer to a [`ControlKind::State`] request. This is how
/// an estimator that keeps no file — restarted, or asked to estimate again a step older than the echoes it
/// remembers — goes on from the state before the step it is given, bit for bit as its predecessor would.
/// Internal to uavloc: a foreign front end neither sends nor reads it.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("uavloc::EstimatorState/v1")]
#[repr(C)]
pub struct EstimatorState {
    /// Common header; `step` is the step the state is after.
    pub header: Header,
    /// Instance id of the sender.
    pub instance: u64,
    /// The state ([`StateEcho::STATE`] or [`StateEcho::EMPTY`], of step `header.step`).
    pub state: StateEcho,
}

impl_message!(EstimatorState, MessageKind::State, 1, "uavloc::EstimatorState/v1");

impl EstimatorState {
    /// The state `state` (of its step) sent by instance `instance` with sequence number `seq`.
    pub fn new(state: StateEcho, seq: u64, instance: u64) -> Self {
        EstimatorState { header: Header::new(Self::VERSION, state.step, seq), instance, state }
    }
}

// ---------------------------------------------------------------------------------------------------------
// Control
// ---------------------------------------------------------------------------------------------------------

/// What a [`Control`] message says.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum ControlKind {
    /// A process instance (re)joined the pipeline, e.g. restarted after a crash (`header.step`: 0). Only
    /// that: what it needs to see again it asks for with [`ControlKind::Replay`].
    Hello = 0,
    /// A new instance of `role` takes over from step `header.step` (a swap): the running one handles the
    /// steps before it and then exits.
    TakeOver = 1,
    /// Every process of the domain stops (the run is over or was interrupted).
    Shutdown = 2,
    /// How far the sender has got: `header.step` is the first step it lacks (the monitor: the next step to
    /// record). A lock-step emitter-sim does not run more than `--monitor-window` steps ahead of the
    /// monitor's progress, and replays from it when it stalls.
    Progress = 3,
    /// Publish the run again from step `header.step` (v2): a restarted monitor asks from its first step
    /// not in its log, a monitor that lost a message from that step, a restarted estimator or planner
    /// (which keep no state) for [`ControlKind::IN_FLIGHT`], the step in flight whose message its
    /// predecessor may have taken with it. emitter-sim replays from there.
    Replay = 4,
    /// The sender's count of messages it rejected so far is `header.step` (v3; sent when it changes, so
    /// that the monitor logs it and the live view shows every process's rejections during the run).
    Status = 5,
    /// Send the estimator's state after step `header.step` (v4): an estimator asks when it is to estimate
    /// a step whose predecessor's state it has neither made nor seen echoed (it was restarted, or the world
    /// was rewound further back than it remembers); the monitor, which keeps the state every command
    /// echoed, answers with an [`EstimatorState`] on `<domain>/state`.
    State = 6,
    /// The sender's domain runs another scenario than the process of instance `header.step`, which joined
    /// after it (v5; the sender's own run is in [`Control::run`]): that process leaves (exit code 2), so
    /// that no run is made of two scenarios. Every other receiver ignores it.
    Run = 7,
}

impl ControlKind {
    /// The step of a [`ControlKind::Replay`] that asks for the step in flight only (the newest one
    /// published).
    pub const IN_FLIGHT: u64 = u64::MAX;

    /// Decodes the wire value.
    pub fn from_u32(v: u32) -> Option<Self> {
        match v {
            0 => Some(ControlKind::Hello),
            1 => Some(ControlKind::TakeOver),
            2 => Some(ControlKind::Shutdown),
            3 => Some(ControlKind::Progress),
            4 => Some(ControlKind::Replay),
            5 => Some(ControlKind::Status),
            6 => Some(ControlKind::State),
            7 => Some(ControlKind::Run),
            _ => None,
        }
    }

    /// Stable lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            ControlKind::Hello => "hello",
            ControlKind::TakeOver => "take_over",
            ControlKind::Shutdown => "shutdown",
            ControlKind::Progress => "progress",
            ControlKind::Replay => "replay",
            ControlKind::Status => "status",
            ControlKind::State => "state",
            ControlKind::Run => "run",
        }
    }
}

/// Any process → every process of the domain (the `control` topic): who joins, who takes over, stop.
///
/// Many processes publish on this topic, each with its own sequence numbers: a receiver tracks the last
/// accepted sequence number per `instance`.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("uavloc::Control/v5")]
#[repr(C)]
pub struct Control {
    /// Common header; `step` depends on the kind (see [`ControlKind`]).
    pub header: Header,
    /// Instance id of the sender (as in [`Estimate::instance`] / [`Command::planner_instance`]).
    pub instance: u64,
    /// When the sender started ([`now_ns`]): orders two instances of one role (the later one is newer).
    pub started_ns: u64,
    /// [`ControlKind`] as `u32`.
    pub kind: u32,
    /// Explicit padding; 0 when sent.
    pub reserved: u32,
    /// The run the sender belongs to (v5): its scenario's fingerprint (`model::Scenario::run_id`), 0 for a
    /// sender without a scenario (the estimator, the launcher, `swap`). Processes of one domain must run
    /// one scenario: see [`ControlKind::Run`].
    pub run: u64,
    /// The sender's role: `emitter-sim`, `estimator`, `planner`, `monitor`, `launcher`, `swap`.
    pub role: Name16,
    /// Free detail for humans and the monitor, e.g. `ga/analytical` for a planner (may be empty).
    pub detail: Name16,
}

impl_message!(Control, MessageKind::Control, 5, "uavloc::Control/v5");

impl Control {
    /// This message with the sender's run ([`Control::run`]).
    pub fn with_run(self, run: u64) -> Self {
        Control { run, ..self }
    }

    /// A control message of `kind` from `role` (`detail` may be empty; beyond 16 characters it is cut).
    pub fn new(
        kind: ControlKind,
        step: u64,
        seq: u64,
        instance: u64,
        started_ns: u64,
        role: &str,
        detail: &str,
    ) -> Result<Self, ProtocolError> {
        Ok(Control {
            header: Header::new(Self::VERSION, step, seq),
            instance,
            started_ns,
            kind: kind as u32,
            reserved: 0,
            run: 0,
            role: Name16::new("role", role)?,
            detail: if detail.is_empty() { Name16::default() } else { Name16::new("detail", Self::cut(detail))? },
        })
    }

    /// `detail` cut to the 16 bytes the field holds (at a character boundary): it is free text for
    /// humans, and a planner's `solver/objective` (e.g. `pso/posterior-cubature`) may be longer.
    fn cut(detail: &str) -> &str {
        let mut end = detail.len().min(16);
        while !detail.is_char_boundary(end) {
            end -= 1;
        }
        &detail[..end]
    }

    /// The decoded kind (`None` for an unknown wire value).
    pub fn kind(&self) -> Option<ControlKind> {
        ControlKind::from_u32(self.kind)
    }

    /// The sender's role (`None` if the bytes are not a valid name).
    pub fn role(&self) -> Option<&str> {
        self.role.as_str()
    }

    /// The detail (empty when none or invalid).
    pub fn detail(&self) -> &str {
        self.detail.as_str().unwrap_or("")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_is_stable() {
        use core::mem::{align_of, size_of};
        // Changing any of these changes the wire format: bump the type names and VERSION constants.
        assert_eq!((size_of::<Stamps>(), align_of::<Stamps>()), (64, 8));
        assert_eq!((size_of::<Header>(), align_of::<Header>()), (88, 8));
        assert_eq!((size_of::<Name16>(), align_of::<Name16>()), (16, 1));
        assert_eq!((size_of::<Measurement>(), align_of::<Measurement>()), (408, 8));
        assert_eq!((size_of::<Estimate>(), align_of::<Estimate>()), (488, 8));
        assert_eq!((size_of::<Command>(), align_of::<Command>()), (504, 8));
        assert_eq!((size_of::<StateEcho>(), align_of::<StateEcho>()), (144, 8));
        assert_eq!((size_of::<Truth>(), align_of::<Truth>()), (112, 8));
        assert_eq!((size_of::<Control>(), align_of::<Control>()), (152, 8));
        assert_eq!((size_of::<EstimatorState>(), align_of::<EstimatorState>()), (240, 8));
    }

    #[test]
    fn layout_has_no_implicit_padding() {
        use core::mem::{offset_of, size_of};
        // Every byte belongs to a field: offsets are contiguous.
        assert_eq!(offset_of!(Header, stamps) + size_of::<Stamps>(), size_of::<Header>());
        assert_eq!(offset_of!(Header, step), 8);
        assert_eq!(offset_of!(Measurement, headings) + 8 * MAX_UAVS, size_of::<Measurement>());
        assert_eq!(offset_of!(Measurement, uavs), 96);
        assert_eq!(offset_of!(Estimate, position), 88 + 8 + 8);
        assert_eq!(offset_of!(Estimate, headings) + 8 * MAX_UAVS, offset_of!(Estimate, velocity));
        assert_eq!(offset_of!(Estimate, velocity_cov) + 32, offset_of!(Estimate, sigmas));
        assert_eq!(offset_of!(Estimate, sigmas) + 8 * MAX_UAVS, size_of::<Estimate>());
        assert_eq!(offset_of!(Estimate, rejected_run) + 1, offset_of!(Estimate, position));
        assert_eq!(offset_of!(Command, objective), 88 + 40);
        assert_eq!(offset_of!(Command, objective_name) + 16, offset_of!(Command, state));
        assert_eq!(offset_of!(Command, state) + size_of::<StateEcho>(), size_of::<Command>());
        assert_eq!(offset_of!(StateEcho, reserved) + 4, offset_of!(StateEcho, position));
        assert_eq!(offset_of!(StateEcho, velocity_cov) + 32, size_of::<StateEcho>());
        assert_eq!(offset_of!(Truth, position) + 16, offset_of!(Truth, previous_command));
        assert_eq!(offset_of!(Truth, reserved) + 4, size_of::<Truth>());
        assert_eq!(offset_of!(Control, run), 88 + 24);
        assert_eq!(offset_of!(Control, role), 88 + 32);
        assert_eq!(offset_of!(Control, detail) + 16, size_of::<Control>());
    }

    #[test]
    fn type_names_are_pinned_and_versioned() {
        fn check<T: Message>() {
            // SAFETY: `type_name` is an `unsafe fn` of the ZeroCopySend trait only because implementors must
            // keep it unique; calling it has no preconditions.
            let pinned = unsafe { <T as ZeroCopySend>::type_name() };
            assert_eq!(pinned, T::TYPE_NAME);
            assert!(pinned.starts_with("uavloc::"), "{pinned}");
            assert!(pinned.ends_with(&format!("/v{}", T::VERSION)), "{pinned} vs version {}", T::VERSION);
        }
        check::<Measurement>();
        check::<Estimate>();
        check::<Command>();
        check::<Truth>();
        check::<Control>();
    }

    #[test]
    fn constructors_check_shapes() {
        let uavs = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
        assert!(Measurement::new(0, 0, &uavs, &[1.0, 2.0], &[1.0; 3], &[0.0; 3]).is_ok());
        assert_eq!(Measurement::new(0, 0, &uavs[..2], &[1.0], &[1.0; 2], &[0.0; 2]), Err(ProtocolError::BadCount(2)));
        assert_eq!(
            Measurement::new(0, 0, &uavs, &[1.0; 3], &[1.0; 3], &[0.0; 3]),
            Err(ProtocolError::LengthMismatch { field: "diffs", expected: 2, got: 3 })
        );
        assert!(matches!(
            Estimate::new(0, 0, 0, &[[0.0; 2]; 9], &[0.0; 9], Fix::Failed),
            Err(ProtocolError::BadCount(9))
        ));
        let plan = PlanInfo {
            headings: &[0.0; 3],
            waypoints: &uavs,
            objective: 1.0,
            solver: "a-solver-name-too-long",
            objective_name: "trace",
            plan_time_us: 0,
            active_constraints: 0,
            violated_constraints: 0,
        };
        assert!(matches!(Command::new(0, 0, 0, &plan), Err(ProtocolError::BadName { field: "solver", .. })));
    }

    #[test]
    fn names_round_trip_and_reject_bad_bytes() {
        let n = Name16::new("x", "trace-crlb").unwrap();
        assert_eq!(n.as_str(), Some("trace-crlb"));
        assert_eq!(Name16::new("x", "0123456789abcdef").unwrap().as_str(), Some("0123456789abcdef"));
        assert!(Name16::new("x", "").is_err());
        assert!(Name16::new("x", "ümlaut").is_err());
        assert!(Name16::new("x", "tab\there").is_err());
        assert_eq!(Name16::default().as_str(), None);
        let mut gap = n;
        gap.bytes[12] = b'x'; // a byte after the NUL terminator
        assert_eq!(gap.as_str(), None);
    }

    #[test]
    fn stamps_carry_forward_and_give_latencies() {
        let uavs = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
        let mut cmd0 = Command::new(
            0,
            1,
            7,
            &PlanInfo {
                headings: &[0.0; 3],
                waypoints: &uavs,
                objective: 1.0,
                solver: "pso",
                objective_name: "trace",
                plan_time_us: 5,
                active_constraints: 0,
                violated_constraints: 0,
            },
        )
        .unwrap();
        cmd0.header.stamps.mark_published(MessageKind::Command, 100);
        let mut m = Measurement::new(1, 1, &uavs, &[1.0, 2.0], &[1.0; 3], &[0.0; 3]).unwrap().carrying(&cmd0, 110);
        m.header.stamps.mark_published(MessageKind::Measurement, 150);
        let mut e = Estimate::from_measurement(
            &m,
            160,
            1,
            9,
            Fix::Ok { position: [1.0, 2.0], covariance: [[1.0, 0.0], [0.0, 1.0]] },
        )
        .unwrap();
        assert_eq!(e.header.step, 1);
        assert_eq!(e.uavs(), m.uavs());
        e.header.stamps.mark_published(MessageKind::Estimate, 200);
        let mut c = Command::from_estimate(&e, 210, 2, 7, &cmd0_plan(&uavs)).unwrap();
        c.header.stamps.mark_published(MessageKind::Command, 300);
        let l = c.header.stamps.latencies();
        assert_eq!(
            l,
            Latencies {
                trigger_hop_ns: Some(10),
                emitter_ns: Some(40),
                measurement_hop_ns: Some(10),
                estimator_ns: Some(40),
                estimate_hop_ns: Some(10),
                planner_ns: Some(90),
                end_to_end_ns: Some(150),
                cycle_ns: Some(200),
            }
        );
        assert_eq!(c.header.stamps.age_ns(305), Some(5));
        // The next measurement starts a new chain.
        let next = Measurement::new(2, 2, &uavs, &[1.0, 2.0], &[1.0; 3], &[0.0; 3]).unwrap().carrying(&c, 320);
        assert_eq!(
            next.header.stamps,
            Stamps { trigger_command_published_ns: 300, trigger_command_received_ns: 320, ..Stamps::default() }
        );
        assert_eq!(Stamps::default().latencies(), Latencies::default());
        assert_eq!(span_ns(5, 3), None);
    }

    fn cmd0_plan(uavs: &[[f64; 2]]) -> PlanInfo<'_> {
        PlanInfo {
            headings: &[0.1, 0.2, 0.3],
            waypoints: uavs,
            objective: 2.0,
            solver: "pso",
            objective_name: "trace",
            plan_time_us: 80,
            active_constraints: 0b101,
            violated_constraints: 0,
        }
    }

    #[test]
    fn now_ns_is_monotonic_and_nonzero() {
        let a = now_ns();
        let b = now_ns();
        assert!(a > 0 && b >= a);
    }
}
