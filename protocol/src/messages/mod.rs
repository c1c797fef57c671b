//! Fixed-layout message types, one file per type (`measurement`, `estimate`, `command`, `truth`,
//! `state`, `control`); here what they share: the header and its stamps, the message trait, the names.
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
    /// [`SwarmState`].
    Swarm,
}

impl MessageKind {
    /// All kinds, in index order.
    pub const ALL: [MessageKind; 7] = [
        MessageKind::Measurement,
        MessageKind::Estimate,
        MessageKind::Command,
        MessageKind::Truth,
        MessageKind::Control,
        MessageKind::State,
        MessageKind::Swarm,
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
            MessageKind::Swarm => "swarm",
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
            MessageKind::Truth | MessageKind::Control | MessageKind::State | MessageKind::Swarm => {}
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
            MessageKind::Truth | MessageKind::Control | MessageKind::State | MessageKind::Swarm => {
                Stamps { published_ns: 0, ..*upstream }
            }
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

/// The per-UAV arrays of a message, each used up to `count` ([`used`]): `len`, `is_empty` and one
/// accessor per array, from one definition.
macro_rules! impl_per_uav {
    ($ty:ident { $( $(#[$doc:meta])* $field:ident: $elem:ty ),* $(,)? }) => {
        impl $ty {
            /// Number of UAVs in use (clamped to [`MAX_UAVS`]).
            pub fn len(&self) -> usize {
                used(self.count)
            }

            /// Whether no UAV is in use (never true for a valid message).
            pub fn is_empty(&self) -> bool {
                self.len() == 0
            }

            $(
                $(#[$doc])*
                pub fn $field(&self) -> &[$elem] {
                    &self.$field[..self.len()]
                }
            )*
        }
    };
}

/// An enum carried on the wire as an integer, from one definition: the enum (`#[repr]` of the wire
/// integer), its decoder (`None` for a value no variant has), its stable lower-case names and the list
/// of its variants in wire order.
macro_rules! wire_enum {
    (
        $(#[$meta:meta])*
        pub enum $name:ident : $repr:ident, decoded by $decode:ident {
            $( $(#[$vmeta:meta])* $variant:ident = $value:literal, $label:literal; )+
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        #[repr($repr)]
        pub enum $name {
            $( $(#[$vmeta])* $variant = $value, )+
        }

        impl $name {
            /// Every variant, in wire order.
            pub const VARIANTS: &'static [$name] = &[$($name::$variant),+];

            /// Decodes the wire value.
            pub fn $decode(v: $repr) -> Option<Self> {
                match v {
                    $( $value => Some($name::$variant), )+
                    _ => None,
                }
            }

            /// Stable lower-case name.
            pub fn name(self) -> &'static str {
                match self {
                    $( $name::$variant => $label, )+
                }
            }
        }
    };
}

mod command;
mod control;
mod estimate;
mod held;
mod measurement;
mod state;
mod swarm;
mod truth;
mod window;

pub use command::*;
pub use control::*;
pub use estimate::*;
pub use held::*;
pub use measurement::*;
pub use state::*;
pub use swarm::*;
pub use truth::*;
pub use window::*;

#[cfg(test)]
mod tests;
