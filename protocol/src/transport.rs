//! A typed wrapper of iceoryx2 for one *topic*: a publish/subscribe service carrying one [`Message`] type,
//! plus a companion event service of the same name that wakes subscribers up.
//!
//! iceoryx2 subscribers have no wake-up of their own. [`TopicPublisher::send`] therefore does
//! `loan_uninit → write_payload → send` on the pub/sub service and then notifies the event service;
//! [`TopicSubscriber`] owns a listener on that event service, can be attached to a `WaitSet` directly (it
//! implements `SynchronousMultiplexing` through its listener) and drains all pending samples with
//! [`receive_all`](TopicSubscriber::receive_all) on each wake-up.
//!
//! Service settings (every process opens the topics through this module, so they always agree):
//! up to [`MAX_PUBLISHERS`] publishers (a second planner can attach during a swap), [`MAX_SUBSCRIBERS`]
//! subscribers, a subscriber buffer of [`SUBSCRIBER_BUFFER`] samples (oldest overwritten when full), no
//! history (a late subscriber waits for the next message). The event service announces publisher
//! lifecycle with the [`event_id`]s, so a subscriber learns when a publisher appears, leaves or is found
//! dead (after a dead-node cleanup, e.g. by [`node`] at start-up).
//!
//! All ports use `ipc::Service` (inter-process, not thread-safe): create nodes and ports on the thread that
//! uses them.

use core::fmt;
use core::marker::PhantomData;
use core::time::Duration;
use std::time::Instant;

use iceoryx2::node::CleanupState;
use iceoryx2::port::listener::{Listener, ListenerWaitError};
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
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
pub const SUBSCRIBER_BUFFER: usize = 16;
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
    /// An iceoryx2 operation failed (the detail is iceoryx2's error variant, e.g. `IncompatibleTypes`).
    #[error("{op} on {service:?} failed: {detail}")]
    Failed {
        /// What was attempted.
        op: &'static str,
        /// The service (or node) name.
        service: String,
        /// iceoryx2's error.
        detail: String,
    },
    /// A blocking wait was interrupted by SIGINT/SIGTERM: shut down.
    #[error("interrupted by a signal")]
    Interrupted,
}

fn failed(op: &'static str, service: &str, e: impl fmt::Debug) -> TransportError {
    TransportError::Failed { op, service: service.to_owned(), detail: format!("{e:?}") }
}

/// Creates the iceoryx2 node of a process, named `name` (e.g. [`services::node_name`](crate::services::node_name)),
/// after removing the stale resources of dead nodes (processes killed without cleaning up).
///
/// The default configuration also cleans up dead nodes on node creation and service opening; the explicit
/// call makes the intent visible and runs it before any of our services are touched.
pub fn node(name: &str) -> Result<Node<ipc::Service>, TransportError> {
    let node_name = NodeName::new(name).map_err(|e| TransportError::BadName {
        what: "node",
        name: name.to_owned(),
        detail: format!("{e:?}"),
    })?;
    let node =
        NodeBuilder::new().name(&node_name).create::<ipc::Service>().map_err(|e| failed("creating node", name, e))?;
    cleanup_dead_nodes(&node);
    Ok(node)
}

/// [`node`] for a process that handles SIGINT/SIGTERM itself (e.g. a launcher): iceoryx2 registers no
/// signal handler for it.
pub fn node_without_signal_handling(name: &str) -> Result<Node<ipc::Service>, TransportError> {
    let node_name = NodeName::new(name).map_err(|e| TransportError::BadName {
        what: "node",
        name: name.to_owned(),
        detail: format!("{e:?}"),
    })?;
    let node = NodeBuilder::new()
        .name(&node_name)
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(|e| failed("creating node", name, e))?;
    cleanup_dead_nodes(&node);
    Ok(node)
}

/// Sets iceoryx2's log level from `IOX2_LOG_LEVEL`, else to `Error`: hides the "No config file was loaded"
/// warning every process would print at start-up (iceoryx2 logs to stderr). Call once, before [`node`].
pub fn quiet_logs() {
    set_log_level_from_env_or(LogLevel::Error);
}

/// Removes the stale resources of all dead nodes now; returns how many were cleaned and how many failed
/// (e.g. being cleaned by another process, or insufficient permissions).
pub fn cleanup_dead_nodes(node: &Node<ipc::Service>) -> CleanupState {
    node.try_cleanup_dead_nodes()
}

fn service_name(name: &str) -> Result<ServiceName, TransportError> {
    ServiceName::new(name).map_err(|e| TransportError::BadName {
        what: "service",
        name: name.to_owned(),
        detail: format!("{e:?}"),
    })
}

/// The two services of a topic.
struct Services<T: Message> {
    pubsub: iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, T, ()>,
    event: iceoryx2::service::port_factory::event::PortFactory<ipc::Service>,
}

/// Entry point: `Topic::<Measurement>::publisher(&node, &services::measurement(&domain))`.
pub struct Topic<T: Message>(PhantomData<T>);

impl<T: Message> Topic<T> {
    fn open(node: &Node<ipc::Service>, name: &str) -> Result<Services<T>, TransportError> {
        let service = service_name(name)?;
        let pubsub = node
            .service_builder(&service)
            .publish_subscribe::<T>()
            .max_publishers(MAX_PUBLISHERS)
            .max_subscribers(MAX_SUBSCRIBERS)
            .subscriber_max_buffer_size(SUBSCRIBER_BUFFER)
            .history_size(HISTORY)
            .enable_safe_overflow(true)
            .open_or_create()
            .map_err(|e| failed("opening pub/sub service", name, e))?;
        let event = node
            .service_builder(&service)
            .event()
            .max_notifiers(MAX_PUBLISHERS)
            .max_listeners(MAX_SUBSCRIBERS)
            .notifier_created_event(EventId::new(event_id::PUBLISHER_CREATED))
            .notifier_dropped_event(EventId::new(event_id::PUBLISHER_DROPPED))
            .notifier_dead_event(EventId::new(event_id::PUBLISHER_DEAD))
            .open_or_create()
            .map_err(|e| failed("opening event service", name, e))?;
        Ok(Services { pubsub, event })
    }

    /// Opens (or creates) the topic `name` and adds a publisher to it.
    pub fn publisher(node: &Node<ipc::Service>, name: &str) -> Result<TopicPublisher<T>, TransportError> {
        let services = Self::open(node, name)?;
        let publisher =
            services.pubsub.publisher_builder().create().map_err(|e| failed("creating publisher", name, e))?;
        let notifier = services.event.notifier_builder().create().map_err(|e| failed("creating notifier", name, e))?;
        Ok(TopicPublisher { name: name.to_owned(), publisher, notifier })
    }

    /// Opens (or creates) the topic `name` and adds a subscriber to it.
    pub fn subscriber(node: &Node<ipc::Service>, name: &str) -> Result<TopicSubscriber<T>, TransportError> {
        let services = Self::open(node, name)?;
        let subscriber = services
            .pubsub
            .subscriber_builder()
            .buffer_size(SUBSCRIBER_BUFFER)
            .create()
            .map_err(|e| failed("creating subscriber", name, e))?;
        let listener = services.event.listener_builder().create().map_err(|e| failed("creating listener", name, e))?;
        Ok(TopicSubscriber { name: name.to_owned(), subscriber, listener })
    }
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
    publisher: Publisher<ipc::Service, T, ()>,
    notifier: Notifier<ipc::Service>,
}

impl<T: Message> TopicPublisher<T> {
    /// Stamps `msg` with the publish time ([`Stamps::mark_published`](crate::Stamps::mark_published)),
    /// writes it into a loaned shared-memory sample, sends it and wakes the subscribers.
    pub fn send(&self, msg: &T) -> Result<Sent, TransportError> {
        let sample = self.publisher.loan_uninit().map_err(|e| failed("loaning sample", &self.name, e))?;
        let mut msg = *msg;
        let published_ns = now_ns();
        msg.header_mut().stamps.mark_published(T::KIND, published_ns);
        let sample = sample.write_payload(msg);
        let subscribers = sample.send().map_err(|e| failed("sending sample", &self.name, e))?;
        self.notifier
            .notify_with_custom_event_id(EventId::new(event_id::SAMPLE))
            .map_err(|e| failed("notifying", &self.name, e))?;
        Ok(Sent { published_ns, subscribers })
    }

    /// The topic's service name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The underlying iceoryx2 publisher.
    pub fn publisher(&self) -> &Publisher<ipc::Service, T, ()> {
        &self.publisher
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
    /// Any other event id.
    pub other: u64,
}

impl TopicEvents {
    fn add(&mut self, id: EventId, count: u64) {
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
    subscriber: Subscriber<ipc::Service, T, ()>,
    listener: Listener<ipc::Service>,
}

impl<T: Message> TopicSubscriber<T> {
    /// Consumes the pending wake-ups, then appends every buffered message to `out` (oldest first).
    /// Returns the events consumed. Messages are copied out of shared memory and not validated.
    pub fn receive_into(&self, out: &mut Vec<T>) -> Result<TopicEvents, TransportError> {
        // Wake-ups first, samples second: a notification that arrives meanwhile then leads to one spurious
        // wake-up at worst, never to a sample left behind without a wake-up.
        let mut events = TopicEvents::default();
        self.listener
            .try_wait(|activation| events.add(activation.id, activation.count))
            .map_err(|e| wait_error(e, &self.name))?;
        while let Some(sample) = self.subscriber.receive().map_err(|e| failed("receiving", &self.name, e))? {
            out.push(*sample.payload());
        }
        Ok(events)
    }

    /// Consumes the pending wake-ups and returns every buffered message (oldest first; possibly none).
    pub fn receive_all(&self) -> Result<Vec<T>, TransportError> {
        let mut out = Vec::new();
        self.receive_into(&mut out)?;
        Ok(out)
    }

    /// Waits up to `spin + timeout` for messages: busy-polls for `spin` (cheap when the next message is due
    /// within microseconds), then blocks on the listener for `timeout`; returns whatever is buffered then
    /// (possibly nothing, e.g. on a timeout or a lifecycle event). [`TransportError::Interrupted`] on
    /// SIGINT/SIGTERM.
    pub fn wait(&self, spin: Duration, timeout: Duration) -> Result<Vec<T>, TransportError> {
        let start = Instant::now();
        loop {
            if self.has_samples()? {
                return self.receive_all();
            }
            if start.elapsed() >= spin {
                break;
            }
            core::hint::spin_loop();
        }
        if !timeout.is_zero() {
            // The events are consumed again (and counted) by receive_all; here they only wake us.
            self.listener.timed_wait(|_| {}, timeout).map_err(|e| wait_error(e, &self.name))?;
        }
        self.receive_all()
    }

    /// Whether messages are buffered.
    pub fn has_samples(&self) -> Result<bool, TransportError> {
        self.subscriber.has_samples().map_err(|e| failed("polling", &self.name, e))
    }

    /// The topic's service name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The listener that wakes this subscriber (what a `WaitSet` waits on).
    pub fn listener(&self) -> &Listener<ipc::Service> {
        &self.listener
    }

    /// The underlying iceoryx2 subscriber.
    pub fn subscriber(&self) -> &Subscriber<ipc::Service, T, ()> {
        &self.subscriber
    }
}

/// Waits on a `WaitSet` (to which several topics' subscribers are attached): busy-polls `ready` for `spin`
/// first, then blocks for at most `timeout`. Returns `Ok(())` on any wake-up, a timeout or a signal other
/// than SIGINT/SIGTERM (the caller drains its subscribers either way), [`TransportError::Interrupted`] on
/// SIGINT/SIGTERM.
pub fn wait_any(
    waitset: &WaitSet<ipc::Service>,
    spin: Duration,
    timeout: Duration,
    mut ready: impl FnMut() -> Result<bool, TransportError>,
) -> Result<(), TransportError> {
    let start = Instant::now();
    loop {
        if ready()? {
            return Ok(());
        }
        if start.elapsed() >= spin {
            break;
        }
        core::hint::spin_loop();
    }
    if timeout.is_zero() {
        return Ok(());
    }
    match waitset.wait_and_process_once_with_timeout(|_| CallbackProgression::Continue, timeout) {
        Ok(iceoryx2::waitset::WaitSetRunResult::TerminationRequest) => Err(TransportError::Interrupted),
        Ok(_) => Ok(()),
        Err(e) => Err(failed("waiting", "waitset", e)),
    }
}

/// A `WaitSet` for the subscribers of one process.
pub fn waitset() -> Result<WaitSet<ipc::Service>, TransportError> {
    WaitSetBuilder::new().create::<ipc::Service>().map_err(|e| failed("creating", "waitset", e))
}

fn wait_error(e: ListenerWaitError, name: &str) -> TransportError {
    match e {
        ListenerWaitError::InterruptSignal => TransportError::Interrupted,
        e => failed("waiting", name, e),
    }
}

impl<T: Message> FileDescriptorBased for TopicSubscriber<T> {
    fn file_descriptor(&self) -> &FileDescriptor {
        self.listener.file_descriptor()
    }
}

impl<T: Message> SynchronousMultiplexing for TopicSubscriber<T> {}
