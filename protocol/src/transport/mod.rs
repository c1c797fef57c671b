//! Typed *topics* — one [`Message`] type per topic, publish/subscribe — over one of two transports behind
//! the same two traits ([`PublishPort`], [`SubscribePort`]):
//!
//! - [`TransportKind::Iceoryx2`] (the default, [`iox`]): zero-copy shared memory. A topic is a pub/sub
//!   service plus a companion event service of the same name that wakes subscribers up: `send` does
//!   `loan_uninit → write_payload → send` and then notifies; a subscriber owns a listener on the event
//!   service.
//! - [`TransportKind::Uds`] ([`uds`]): Unix-domain datagram sockets carrying the bytes of the same
//!   `#[repr(C)]` structs (no serialisation) — the baseline a user would otherwise write, for
//!   `uavloc bench compare`. The socket itself is the wake-up.
//!
//! Everything else is shared and identical for both: the publish stamp ([`TopicPublisher::send`]), the
//! spin-then-block waiting ([`TopicSubscriber::wait`], [`wait_any`] on one iceoryx2 `WaitSet` — both
//! kinds of subscriber expose a pollable file descriptor), the [`WaitMode`]s, the iceoryx2 node of the
//! process ([`Link`]: signal handling, dead-node cleanup), validation and counting in the callers.
//!
//! Service settings of the iceoryx2 transport (every process opens the topics through this module, so
//! they always agree): up to [`MAX_PUBLISHERS`] publishers (a second planner can attach during a swap),
//! [`MAX_SUBSCRIBERS`] subscribers, a subscriber buffer of [`SUBSCRIBER_BUFFER`] samples (oldest
//! overwritten when full), no history (a late subscriber waits for the next message). The event service
//! announces publisher lifecycle with the [`event_id`]s, so a subscriber learns when a publisher appears,
//! leaves or is found dead (after a dead-node cleanup, e.g. by [`node`] at start-up).
//!
//! # Wake-ups: a notification costs a system call only when the subscriber is about to block
//!
//! An iceoryx2 listener (0.10, `UnixDatagramShmCountingBitSet`) has a notification state in shared
//! memory: *idle*, *pending* or *notified*. A notifier sets the event's bit in shared memory and sends a
//! datagram to the listener's socket (one `sendto`) only when the state is idle, then marks it notified;
//! while it is notified, further notifications are bits in shared memory only. Consuming the wake-ups
//! (`Listener::try_wait`: read the socket empty, state back to idle) costs the listener one or two
//! `recvfrom`. So a subscriber here consumes its wake-ups only **just before it blocks**
//! ([`SubscribePort::consume_wakeups`]), never while it polls ([`SubscribePort::receive_into`] and
//! [`SubscribePort::has_samples`] touch shared memory only). A subscriber that keeps up by polling leaves
//! its state at *notified*, so a publisher's `send` is `loan → write → send → a bit set` without a system
//! call, and so is the receive.
//!
//! Race-free, because the blocking side always does, in this order (`about_to_block`):
//! 1. consume the wake-ups (state idle, socket empty);
//! 2. look at the sample buffers once more: a message there → do not block;
//! 3. block on the listeners' file descriptors (a `WaitSet`, or `Listener::timed_wait`).
//!
//! A publisher delivers the sample before it notifies. If its sample came too late for step 2, its
//! notification came after step 1, found the state idle (or pending: then the other notifier sends) and
//! sent a datagram, so step 3 wakes at once. If its notification was among those consumed in step 1, its
//! sample was delivered before that and step 2 sees it. The order matters:
//! `no_wake_up_is_lost_between_polling_and_blocking` (in the transport tests) fails with steps 1 and 2
//! swapped. Foreign clients (the official Python and C bindings) need nothing of this: it is iceoryx2's
//! own notification state, and a foreign listener that consumes its wake-ups at every wait is simply
//! notified every time, as before.
//!
//! All ports are single-threaded (iceoryx2's `ipc::Service` ports are not thread-safe): create nodes and
//! ports on the thread that uses them.

pub mod iox;
mod policy;
pub mod uds;
mod wait;

pub use policy::{TransportKind, WaitMode, WaitPolicy};
pub use wait::{Waitable, poll, wait_any, wait_attached, waitset};
use wait::{about_to_block, spin_until};

use core::fmt;
use core::marker::PhantomData;
use core::time::Duration;
use std::time::Instant;

use iceoryx2::node::CleanupState;
use iceoryx2::prelude::*;
use thiserror::Error;

use crate::messages::{Message, now_ns};

/// The node type of every uavloc process (inter-process iceoryx2 services).
pub type IpcNode = Node<ipc::Service>;

/// Most publishers per topic (the control topic has one per process, plus swapped-in instances and the
/// launcher).
pub const MAX_PUBLISHERS: usize = 8;
/// Most subscribers per topic.
pub const MAX_SUBSCRIBERS: usize = 16;
/// Samples a subscriber buffers before the oldest is overwritten.
pub const SUBSCRIBER_BUFFER: usize = 64;
/// Samples a late subscriber receives from before it connected.
pub const HISTORY: usize = 0;

/// Event ids on a topic's event service.
pub mod event_id {
    /// A sample was sent.
    pub const SAMPLE: usize = 1;
    /// A publisher (its notifier) was created.
    pub const PUBLISHER_CREATED: usize = 2;
    /// A publisher was dropped.
    pub const PUBLISHER_DROPPED: usize = 3;
    /// A publisher's process was found dead by a dead-node cleanup.
    pub const PUBLISHER_DEAD: usize = 4;
    /// The largest event id of a topic's event service (iceoryx2's `event_id_max_value`). A listener
    /// consuming its wake-ups visits one counter per id up to it: with iceoryx2's default, 255, that was
    /// 256 atomic swaps per listener and wait, most of the monitor's CPU in block mode.
    pub const MAX: usize = PUBLISHER_DEAD;
}

/// A transport failure.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum TransportError {
    /// A service or node name is not valid for iceoryx2.
    #[error("invalid {what} name {name:?}: {detail}")]
    BadName {
        /// `"service"` or `"node"`.
        what: &'static str,
        /// The name given.
        name: String,
        /// iceoryx2's reason.
        detail: String,
    },
    /// A transport operation failed (the detail is iceoryx2's error variant, e.g. `IncompatibleTypes`, or
    /// the operating system's error for the socket transport).
    #[error("{op} on {service:?} failed: {detail}")]
    Failed {
        /// What was attempted.
        op: &'static str,
        /// The service (or node) name.
        service: String,
        /// The underlying error.
        detail: String,
    },
    /// A blocking wait was interrupted by SIGINT/SIGTERM: shut down.
    #[error("interrupted by a signal")]
    Interrupted,
    /// The environment does not let the transport work: a bad setting (e.g. `UAVLOC_UDS_DIR`), reported
    /// as bad input.
    #[error("{0}")]
    Environment(String),
}

/// A transport operation `op` on `service` that failed with `e` (its debug form is the detail).
pub fn failed(op: &'static str, service: &str, e: impl fmt::Debug) -> TransportError {
    TransportError::Failed { op, service: service.to_owned(), detail: format!("{e:?}") }
}

/// Creates the iceoryx2 node of a process, named `name` (e.g. [`services::node_name`](crate::services::node_name)),
/// after removing the stale resources of dead nodes (processes killed without cleaning up).
///
/// The default configuration also cleans up dead nodes on node creation and service opening; the explicit
/// call makes the intent visible and runs it before any of our services are touched.
pub fn node(name: &str) -> Result<IpcNode, TransportError> {
    make_node(name, SignalHandlingMode::HandleTerminationRequests)
}

/// [`node`] for a process that handles SIGINT/SIGTERM itself (e.g. a launcher): iceoryx2 registers no
/// signal handler for it.
pub fn node_without_signal_handling(name: &str) -> Result<IpcNode, TransportError> {
    make_node(name, SignalHandlingMode::Disabled)
}

fn make_node(name: &str, signals: SignalHandlingMode) -> Result<IpcNode, TransportError> {
    let node_name = NodeName::new(name).map_err(|e| TransportError::BadName {
        what: "node",
        name: name.to_owned(),
        detail: format!("{e:?}"),
    })?;
    // SIGINT/SIGTERM are held back while the node is created and until iceoryx2's handler is installed
    // (at the node's first wait): a supervisor stopping a process that is just starting would otherwise
    // kill it inside the node's creation and leave a half-created node that iceoryx2 can neither list nor
    // clean. A signal that came meanwhile is delivered on unblocking, to the handler: the process then
    // ends cleanly at its first check.
    let handled = signals == SignalHandlingMode::HandleTerminationRequests;
    if handled {
        hang_up_as_termination();
    }
    let _held = handled.then(TerminationSignalsHeld::new);
    let node = NodeBuilder::new()
        .name(&node_name)
        .signal_handling_mode(signals)
        .create::<ipc::Service>()
        .map_err(|e| failed("creating node", name, e))?;
    if handled {
        let _ = node.wait(Duration::ZERO);
    }
    cleanup_dead_nodes(&node);
    Ok(node)
}

/// Takes SIGHUP — the hang-up of the terminal (an ssh session) a process was started from by hand — as a
/// request to terminate: its handler sends the process SIGTERM, which iceoryx2's handler turns into the
/// clean end every process has (the monitor writes its partial record; exit code 130). By default SIGHUP
/// killed the process on the spot, its record and its iceoryx2 resources left behind.
fn hang_up_as_termination() {
    extern "C" fn forward(_: libc::c_int) {
        // SAFETY: kill and getpid are async-signal-safe.
        unsafe {
            libc::kill(libc::getpid(), libc::SIGTERM);
        }
    }
    // SAFETY: `forward` makes only async-signal-safe calls; the sigaction struct is fully initialised
    // (zeroed, then handler and an empty mask) before the call.
    unsafe {
        let mut action: libc::sigaction = core::mem::zeroed();
        action.sa_sigaction = forward as extern "C" fn(libc::c_int) as libc::sighandler_t;
        libc::sigemptyset(&mut action.sa_mask);
        libc::sigaction(libc::SIGHUP, &action, core::ptr::null_mut());
    }
}

/// SIGINT and SIGTERM blocked for this thread while it lives (the previous mask restored on drop).
struct TerminationSignalsHeld(libc::sigset_t);

impl TerminationSignalsHeld {
    fn new() -> Self {
        // SAFETY: sigset_t is plain data, initialised by sigemptyset before use; pthread_sigmask gets valid
        // pointers to sets that live through the call.
        unsafe {
            let mut set: libc::sigset_t = core::mem::zeroed();
            let mut old: libc::sigset_t = core::mem::zeroed();
            libc::sigemptyset(&mut set);
            libc::sigaddset(&mut set, libc::SIGINT);
            libc::sigaddset(&mut set, libc::SIGTERM);
            libc::pthread_sigmask(libc::SIG_BLOCK, &set, &mut old);
            Self(old)
        }
    }
}

impl Drop for TerminationSignalsHeld {
    fn drop(&mut self) {
        // SAFETY: restores the mask saved in `new`; the pointer is valid for the call.
        unsafe {
            libc::pthread_sigmask(libc::SIG_SETMASK, &self.0, core::ptr::null_mut());
        }
    }
}

/// Sets iceoryx2's log level from `IOX2_LOG_LEVEL`, else to `Error`: hides the "No config file was loaded"
/// warning every process would print at start-up (iceoryx2 logs to stderr). Call once, before [`node`].
pub fn quiet_logs() {
    set_log_level_from_env_or(LogLevel::Error);
}

/// Removes the stale resources of all dead nodes now; returns how many were cleaned and how many failed
/// (e.g. being cleaned by another process, or insufficient permissions).
pub fn cleanup_dead_nodes(node: &IpcNode) -> CleanupState {
    node.try_cleanup_dead_nodes()
}

/// A process's attachment to the pipeline: its iceoryx2 node (identity, SIGINT/SIGTERM handling, dead-node
/// cleanup — the same for both transports) and the transport its topics use.
#[derive(Debug)]
pub struct Link {
    node: IpcNode,
    kind: TransportKind,
    /// The run tag the publishers opened from now on write into every message ([`Link::set_run`]).
    run: std::cell::Cell<u32>,
}

impl Link {
    /// Creates the process's node `name` (see [`node`]) for topics over `kind` (the socket transport's
    /// directory checked first: [`uds::check_socket_dir`]).
    pub fn open(kind: TransportKind, name: &str) -> Result<Self, TransportError> {
        if kind == TransportKind::Uds {
            uds::check_socket_dir().map_err(TransportError::Environment)?;
        }
        Ok(Link { node: node(name)?, kind, run: std::cell::Cell::new(0) })
    }

    /// [`open`](Self::open) for a process that handles SIGINT/SIGTERM itself (see
    /// [`node_without_signal_handling`]).
    pub fn open_without_signal_handling(kind: TransportKind, name: &str) -> Result<Self, TransportError> {
        Ok(Link { node: node_without_signal_handling(name)?, kind, run: std::cell::Cell::new(0) })
    }

    /// Sets the run tag ([`crate::run_tag`]) that the publishers opened on this link from now on write into
    /// the header of every message they send ([`Header::run`](crate::Header::run)); 0 (the default): they
    /// leave the message's own (a process without a scenario forwards its input's).
    pub fn set_run(&self, tag: u32) {
        self.run.set(tag);
    }

    /// The iceoryx2 node.
    pub fn node(&self) -> &IpcNode {
        &self.node
    }

    /// The transport of this link's topics.
    pub fn kind(&self) -> TransportKind {
        self.kind
    }

    /// Whether SIGINT/SIGTERM has been received (a non-blocking check).
    pub fn interrupted(&self) -> bool {
        matches!(self.node.wait(Duration::ZERO), Err(iceoryx2::node::NodeWaitFailure::TerminationRequest))
    }

    /// Sleeps for `d`; [`TransportError::Interrupted`] at once on SIGINT/SIGTERM. Any other signal that
    /// cuts the sleep short (EINTR: e.g. SIGCONT after a SIGSTOP, SIGCHLD) does not end it: the rest of
    /// `d` is slept. (iceoryx2 reports both as a failure of `Node::wait`; only SIGINT/SIGTERM set its
    /// termination request.)
    pub fn sleep(&self, d: Duration) -> Result<(), TransportError> {
        let until = Instant::now() + d;
        loop {
            match self.node.wait(until.saturating_duration_since(Instant::now())) {
                Ok(()) => return Ok(()),
                Err(iceoryx2::node::NodeWaitFailure::TerminationRequest) => return Err(TransportError::Interrupted),
                Err(iceoryx2::node::NodeWaitFailure::Interrupt) => {
                    if Instant::now() >= until {
                        return Ok(());
                    }
                }
            }
        }
    }
}

/// The sending half of a transport (implemented by [`iox::IoxPublisher`] and [`uds::UdsPublisher`]).
pub trait PublishPort<T: Message>: fmt::Debug {
    /// Delivers `msg` to every current subscriber and wakes them; returns how many it was delivered to.
    /// `stamp` marks the message as it leaves: once its bytes are in place (written into the loaned
    /// sample; for a socket, in the datagram's buffer), right before it is sent.
    fn deliver(&self, msg: &T, stamp: &mut dyn FnMut(&mut T)) -> Result<usize, TransportError>;

    /// How many subscribers the topic has now (for start-up checks).
    fn subscriber_count(&self) -> Result<usize, TransportError>;

    /// How many publishers the topic has now, this one included.
    fn publisher_count(&self) -> Result<usize, TransportError>;

    /// Messages that could not be delivered to some subscriber (its buffer full) and were dropped; 0 for
    /// transports that overwrite the oldest instead (counted by the receivers' sequence checks then).
    fn dropped(&self) -> u64 {
        0
    }
}

/// The receiving half of a transport (implemented by [`iox::IoxSubscriber`] and [`uds::UdsSubscriber`]).
/// Its file descriptor becomes readable when messages (or events) are pending, so a `WaitSet` can wait on
/// several subscribers of either kind.
pub trait SubscribePort<T: Message>: fmt::Debug {
    /// Appends every buffered message to `out` (oldest first); the wake-ups stay pending (see
    /// [`consume_wakeups`](Self::consume_wakeups)). The events returned count the messages (and, socket
    /// transport, the malformed datagrams dropped).
    fn receive_into(&self, out: &mut Vec<T>) -> Result<TopicEvents, TransportError>;

    /// [`receive_into`](Self::receive_into), and each message's publisher into `origins` (iceoryx2: the
    /// sample's `UniquePublisherId`; the socket transport names none and gives 0).
    fn receive_sourced(&self, out: &mut Vec<T>, origins: &mut Vec<u128>) -> Result<TopicEvents, TransportError>;

    /// Whether the publisher `origin` (of [`receive_sourced`](Self::receive_sourced)) is still on the
    /// topic and its process alive (iceoryx2: listed, and its node not dead; the socket transport: always).
    fn publisher_alive(&self, origin: u128) -> Result<bool, TransportError>;

    /// Consumes the pending wake-ups (and lifecycle events) before a blocking wait: a subscriber that only
    /// polls never calls it, so that its publishers' notifications coalesce into the one still pending
    /// and cost them no system call (see the module docs).
    fn consume_wakeups(&self) -> Result<TopicEvents, TransportError>;

    /// Whether messages are buffered (cheap: what a busy-poll calls).
    fn has_samples(&self) -> Result<bool, TransportError>;

    /// Blocks until a wake-up or `timeout`; [`TransportError::Interrupted`] on SIGINT/SIGTERM.
    fn block(&self, timeout: Duration) -> Result<(), TransportError>;

    /// The file descriptor a `WaitSet` waits on.
    fn file_descriptor(&self) -> &FileDescriptor;

    /// How many publishers the topic has now (for start-up checks).
    fn publisher_count(&self) -> Result<usize, TransportError>;
}

/// Entry point: `Topic::<Measurement>::publisher(&link, &services::measurement(&domain))`.
pub struct Topic<T: Message>(PhantomData<T>);

impl<T: Message> Topic<T> {
    /// Opens (or creates) the topic `name` on the link's transport and adds a publisher to it.
    pub fn publisher(link: &Link, name: &str) -> Result<TopicPublisher<T>, TransportError> {
        Ok(TopicPublisher { name: name.to_owned(), port: T::publish_port(link, name)?, run: link.run.get() })
    }

    /// Opens (or creates) the topic `name` on the link's transport and adds a subscriber to it.
    pub fn subscriber(link: &Link, name: &str) -> Result<TopicSubscriber<T>, TransportError> {
        Ok(TopicSubscriber { name: name.to_owned(), port: T::subscribe_port(link, name)? })
    }
}

/// The sending port of `link`'s transport for `T` (called only by the per-type [`Message::publish_port`]).
pub(crate) fn open_publish_port<T: Message>(
    link: &Link,
    name: &str,
) -> Result<Box<dyn PublishPort<T>>, TransportError> {
    Ok(match link.kind {
        TransportKind::Iceoryx2 => Box::new(iox::IoxPublisher::create(&link.node, name)?),
        TransportKind::Uds => Box::new(uds::UdsPublisher::create(name)?),
    })
}

/// The receiving port of `link`'s transport for `T` (called only by the per-type
/// [`Message::subscribe_port`]).
pub(crate) fn open_subscribe_port<T: Message>(
    link: &Link,
    name: &str,
) -> Result<Box<dyn SubscribePort<T>>, TransportError> {
    Ok(match link.kind {
        TransportKind::Iceoryx2 => Box::new(iox::IoxSubscriber::create(&link.node, name)?),
        TransportKind::Uds => Box::new(uds::UdsSubscriber::create(name)?),
    })
}

/// What [`TopicPublisher::send`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Sent {
    /// The publish stamp written into the message (`header.stamps.published_ns` and the kind's own slot).
    pub published_ns: u64,
    /// Subscribers the sample was delivered to.
    pub subscribers: usize,
}

/// The sending end of a topic.
#[derive(Debug)]
pub struct TopicPublisher<T: Message> {
    name: String,
    port: Box<dyn PublishPort<T>>,
    /// The run tag written into every message sent (0: the message's own is kept).
    run: u32,
}

impl<T: Message> TopicPublisher<T> {
    /// Stamps `msg` with the publish time ([`Stamps::mark_published`](crate::Stamps::mark_published)) and
    /// the link's run (if it has one: [`Link::set_run`]), delivers it to the subscribers and wakes them.
    pub fn send(&self, msg: &T) -> Result<Sent, TransportError> {
        let msg = self.of_this_run(msg);
        let mut published_ns = 0;
        // Stamped once written in place, right before it is sent (iceoryx2: in the loaned sample).
        let subscribers = self.port.deliver(&msg, &mut |m: &mut T| {
            published_ns = now_ns();
            m.header_mut().stamps.mark_published(T::KIND, published_ns);
        })?;
        Ok(Sent { published_ns, subscribers })
    }

    /// Delivers a copy of a message sent before (a replay, or an answer given again) with its publish
    /// stamps cleared ([`Stamps::mark_published`](crate::Stamps::mark_published) with 0): a receiver
    /// tells it from a first publication (`published_ns` 0), and no copy is timed as the step's.
    /// [`Sent::published_ns`] is 0.
    pub fn resend(&self, msg: &T) -> Result<Sent, TransportError> {
        let msg = self.of_this_run(msg);
        let subscribers = self.port.deliver(&msg, &mut |m: &mut T| m.header_mut().stamps.mark_published(T::KIND, 0))?;
        Ok(Sent { published_ns: 0, subscribers })
    }

    /// [`send`](Self::send)s `msg`, or [`resend`](Self::resend)s it when it is a `copy` of a message sent
    /// before.
    pub fn publish(&self, msg: &T, copy: bool) -> Result<Sent, TransportError> {
        if copy { self.resend(msg) } else { self.send(msg) }
    }

    /// `msg` with this publisher's run in its header (unchanged when the publisher has none).
    fn of_this_run(&self, msg: &T) -> T {
        let mut msg = *msg;
        if self.run != 0 {
            msg.header_mut().run = self.run;
        }
        msg
    }

    /// The topic's service name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Subscribers of the topic now.
    pub fn subscriber_count(&self) -> Result<usize, TransportError> {
        self.port.subscriber_count()
    }

    /// Publishers of the topic now (this one included).
    pub fn publisher_count(&self) -> Result<usize, TransportError> {
        self.port.publisher_count()
    }

    /// Messages dropped for a full subscriber buffer (socket transport; see [`PublishPort::dropped`]).
    pub fn dropped(&self) -> u64 {
        self.port.dropped()
    }
}

/// Events seen on a topic's event service while draining it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TopicEvents {
    /// Sample notifications.
    pub samples: u64,
    /// Publishers created.
    pub publishers_created: u64,
    /// Publishers dropped.
    pub publishers_dropped: u64,
    /// Publishers found dead.
    pub publishers_dead: u64,
    /// Any other event id (socket transport: datagrams of the wrong size, dropped).
    pub other: u64,
    /// When the last message received was taken from the transport (CLOCK_MONOTONIC ns; 0: none): an
    /// iceoryx2 sample once it is the receiver's to read in place (before its payload is copied out), a
    /// datagram once `recv` returned it (also when a poll took it, [`TopicSubscriber::has_samples`]). A
    /// hop ends here.
    pub in_hand_ns: u64,
}

impl TopicEvents {
    pub(crate) fn add(&mut self, id: EventId, count: u64) {
        let slot = match id.as_value() {
            event_id::SAMPLE => &mut self.samples,
            event_id::PUBLISHER_CREATED => &mut self.publishers_created,
            event_id::PUBLISHER_DROPPED => &mut self.publishers_dropped,
            event_id::PUBLISHER_DEAD => &mut self.publishers_dead,
            _ => &mut self.other,
        };
        *slot += count;
    }
}

/// The receiving end of a topic; attach it to a `WaitSet` with `attach_notification(&subscriber)`.
#[derive(Debug)]
pub struct TopicSubscriber<T: Message> {
    name: String,
    port: Box<dyn SubscribePort<T>>,
}

impl<T: Message> TopicSubscriber<T> {
    /// Appends every buffered message to `out` (oldest first); returns what it received (the wake-ups
    /// stay pending: [`consume_wakeups`](Self::consume_wakeups)). Messages are copied out of the transport
    /// and not validated.
    pub fn receive_into(&self, out: &mut Vec<T>) -> Result<TopicEvents, TransportError> {
        self.port.receive_into(out)
    }

    /// Returns every buffered message (oldest first; possibly none) and when the last of them was in hand
    /// ([`TopicEvents::in_hand_ns`]; the time of the call when there is none): the receive stamp of
    /// the batch, which no message in it was published after.
    pub fn receive_stamped(&self) -> Result<(Vec<T>, u64), TransportError> {
        let mut out = Vec::new();
        let events = self.receive_into(&mut out)?;
        Ok((out, if events.in_hand_ns == 0 { now_ns() } else { events.in_hand_ns }))
    }

    /// [`receive_stamped`](Self::receive_stamped), and each message's publisher
    /// ([`SubscribePort::receive_sourced`]).
    pub fn receive_sourced(&self) -> Result<(Vec<T>, Vec<u128>, u64), TransportError> {
        let (mut out, mut origins) = (Vec::new(), Vec::new());
        let events = self.port.receive_sourced(&mut out, &mut origins)?;
        Ok((out, origins, if events.in_hand_ns == 0 { now_ns() } else { events.in_hand_ns }))
    }

    /// Whether the publisher `origin` is still on the topic, its process alive
    /// ([`SubscribePort::publisher_alive`]).
    pub fn publisher_alive(&self, origin: u128) -> Result<bool, TransportError> {
        self.port.publisher_alive(origin)
    }

    /// Returns every buffered message (oldest first; possibly none).
    pub fn receive_all(&self) -> Result<Vec<T>, TransportError> {
        let mut out = Vec::new();
        self.receive_into(&mut out)?;
        Ok(out)
    }

    /// Consumes the pending wake-ups and lifecycle events (publishers created, dropped, found dead); a
    /// wait calls it just before it blocks (the module docs say why only then).
    pub fn consume_wakeups(&self) -> Result<TopicEvents, TransportError> {
        self.port.consume_wakeups()
    }

    /// Waits up to `spin + timeout` for messages: busy-polls for `spin` (cheap when the next message is due
    /// within microseconds; the CPU is yielded between polls), then — wake-ups consumed and the buffer
    /// checked once more — blocks for `timeout`; returns whatever is buffered then (possibly nothing, e.g.
    /// on a timeout or a lifecycle event). [`TransportError::Interrupted`] on SIGINT/SIGTERM.
    pub fn wait(&self, spin: Duration, timeout: Duration) -> Result<Vec<T>, TransportError> {
        if !spin_until(spin, || self.has_samples())? && !timeout.is_zero() && !about_to_block(&[self])? {
            self.port.block(timeout)?;
        }
        self.receive_all()
    }

    /// Whether messages are buffered.
    pub fn has_samples(&self) -> Result<bool, TransportError> {
        self.port.has_samples()
    }

    /// Publishers of the topic now.
    pub fn publisher_count(&self) -> Result<usize, TransportError> {
        self.port.publisher_count()
    }

    /// The topic's service name.
    pub fn name(&self) -> &str {
        &self.name
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wait_modes_split_a_wait() {
        let t = Duration::from_millis(10);
        let s = Duration::from_micros(200);
        assert_eq!(WaitMode::Block.split(s, t), (Duration::ZERO, t));
        assert_eq!(WaitMode::Spin.split(s, t), (t, Duration::ZERO));
        assert_eq!(WaitMode::SpinThenBlock.split(s, t), (s, t - s));
        assert_eq!(WaitMode::SpinThenBlock.split(t * 2, t), (t, Duration::ZERO));
    }

    #[test]
    fn names_round_trip() {
        for k in TransportKind::ALL {
            assert_eq!(k.name().parse::<TransportKind>(), Ok(k));
        }
        for m in WaitMode::ALL {
            assert_eq!(m.name().parse::<WaitMode>(), Ok(m));
        }
        assert!("tcp".parse::<TransportKind>().unwrap_err().contains("iceoryx2 or uds"));
        assert!("busy".parse::<WaitMode>().unwrap_err().contains("spin-then-block"));
    }
}
