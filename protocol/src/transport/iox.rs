//! The iceoryx2 transport: a topic is a publish/subscribe service (zero-copy shared memory) plus a
//! companion event service of the same name whose notifications wake the subscribers up.

use core::cell::RefCell;
use core::mem::MaybeUninit;
use core::time::Duration;

use iceoryx2::node::NodeView;
use iceoryx2::port::listener::{Listener, ListenerWaitError};
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::sample_mut_uninit::SampleMutUninit;
use iceoryx2::service::port_factory::{event, publish_subscribe};

use super::{
    HISTORY, IpcNode, MAX_PUBLISHERS, MAX_SUBSCRIBERS, PublishPort, SUBSCRIBER_BUFFER, SubscribePort, TopicEvents,
    TransportError, event_id, failed,
};
use crate::messages::{Message, now_ns};

fn service_name(name: &str) -> Result<ServiceName, TransportError> {
    ServiceName::new(name).map_err(|e| TransportError::BadName {
        what: "service",
        name: name.to_owned(),
        detail: format!("{e:?}"),
    })
}

/// The two services of a topic.
struct Services<T: Message> {
    pubsub: publish_subscribe::PortFactory<ipc::Service, T, ()>,
    event: event::PortFactory<ipc::Service>,
}

fn open<T: Message>(node: &IpcNode, name: &str) -> Result<Services<T>, TransportError> {
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
    Ok(Services { pubsub, event: open_event(node, &service, name)? })
}

/// The event service of the topic `name` (service name `service`): the same for every payload type,
/// so compiled once.
fn open_event(
    node: &IpcNode,
    service: &ServiceName,
    name: &str,
) -> Result<event::PortFactory<ipc::Service>, TransportError> {
    node.service_builder(service)
        .event()
        .max_notifiers(MAX_PUBLISHERS)
        .max_listeners(MAX_SUBSCRIBERS)
        .event_id_max_value(event_id::MAX)
        .notifier_created_event(EventId::new(event_id::PUBLISHER_CREATED))
        .notifier_dropped_event(EventId::new(event_id::PUBLISHER_DROPPED))
        .notifier_dead_event(EventId::new(event_id::PUBLISHER_DEAD))
        .open_or_create()
        .map_err(|e| failed("opening event service", name, e))
}

/// The largest event id the event service of the topic `name` takes, as iceoryx2 keeps it in the
/// service's static configuration — what every process that opens the topic, a foreign client with
/// iceoryx2's defaults included, finds ([`event_id::MAX`] for a topic this crate created). Opens (or
/// creates) the service on `node`.
pub fn event_id_limit(node: &IpcNode, name: &str) -> Result<usize, TransportError> {
    let service = service_name(name)?;
    Ok(open_event(node, &service, name)?.static_config().event_id_max_value())
}

/// A publisher and the notifier that wakes its subscribers.
///
/// It keeps the sample of its next message loaned (its `spare`): loaning takes back the samples
/// the subscribers have released (one look into every connection's return queue, lines the subscribers
/// wrote last) and allocates a chunk, ≈ 0.3–0.5 µs of the hop on this kind of VM. Done right after a send,
/// it runs while the receivers work, so the next message is only written and delivered.
pub struct IoxPublisher<T: Message> {
    /// The sample the next message is written into (`None` until the first send, or when a loan failed:
    /// the send then loans and reports the error). Declared first: dropped before the publisher.
    spare: RefCell<Option<SampleMutUninit<ipc::Service, MaybeUninit<T>, ()>>>,
    name: String,
    pubsub: publish_subscribe::PortFactory<ipc::Service, T, ()>,
    publisher: Publisher<ipc::Service, T, ()>,
    notifier: Notifier<ipc::Service>,
}

impl<T: Message> core::fmt::Debug for IoxPublisher<T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("IoxPublisher").field("name", &self.name).finish_non_exhaustive()
    }
}

impl<T: Message> IoxPublisher<T> {
    /// Opens (or creates) the topic `name` and adds a publisher to it.
    pub fn create(node: &IpcNode, name: &str) -> Result<Self, TransportError> {
        let services = open::<T>(node, name)?;
        let publisher =
            services.pubsub.publisher_builder().create().map_err(|e| failed("creating publisher", name, e))?;
        let notifier = services.event.notifier_builder().create().map_err(|e| failed("creating notifier", name, e))?;
        Ok(IoxPublisher {
            spare: RefCell::new(None),
            name: name.to_owned(),
            pubsub: services.pubsub,
            publisher,
            notifier,
        })
    }
}

impl<T: Message> PublishPort<T> for IoxPublisher<T> {
    fn deliver(&self, msg: &T, stamp: &mut dyn FnMut(&mut T)) -> Result<usize, TransportError> {
        let spare = self.spare.borrow_mut().take();
        let sample = match spare {
            Some(sample) => sample,
            None => self.publisher.loan_uninit().map_err(|e| failed("loaning sample", &self.name, e))?,
        };
        // Written in place in the shared memory (the lines of a recycled sample come back from the core
        // that read it last), then stamped and sent.
        let mut sample = sample.write_payload(*msg);
        stamp(sample.payload_mut());
        let subscribers = sample.send().map_err(|e| failed("sending sample", &self.name, e))?;
        self.notifier
            .notify_with_custom_event_id(EventId::new(event_id::SAMPLE))
            .map_err(|e| failed("notifying", &self.name, e))?;
        // The next message's sample, off the hot path (a failure shows at the next send's own loan).
        *self.spare.borrow_mut() = self.publisher.loan_uninit().ok();
        Ok(subscribers)
    }

    fn subscriber_count(&self) -> Result<usize, TransportError> {
        Ok(self.pubsub.dynamic_config().number_of_subscribers())
    }

    fn publisher_count(&self) -> Result<usize, TransportError> {
        Ok(self.pubsub.dynamic_config().number_of_publishers())
    }
}

/// A subscriber and the listener that wakes it.
pub struct IoxSubscriber<T: Message> {
    name: String,
    pubsub: publish_subscribe::PortFactory<ipc::Service, T, ()>,
    subscriber: Subscriber<ipc::Service, T, ()>,
    listener: Listener<ipc::Service>,
    config: iceoryx2::config::Config,
}

impl<T: Message> core::fmt::Debug for IoxSubscriber<T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("IoxSubscriber").field("name", &self.name).finish_non_exhaustive()
    }
}

impl<T: Message> IoxSubscriber<T> {
    /// Opens (or creates) the topic `name` and adds a subscriber to it.
    pub fn create(node: &IpcNode, name: &str) -> Result<Self, TransportError> {
        let services = open::<T>(node, name)?;
        let subscriber = services
            .pubsub
            .subscriber_builder()
            .buffer_size(SUBSCRIBER_BUFFER)
            .create()
            .map_err(|e| failed("creating subscriber", name, e))?;
        let listener = services.event.listener_builder().create().map_err(|e| failed("creating listener", name, e))?;
        let config = node.config().clone();
        Ok(IoxSubscriber { name: name.to_owned(), pubsub: services.pubsub, subscriber, listener, config })
    }
}

impl<T: Message> SubscribePort<T> for IoxSubscriber<T> {
    fn receive_into(&self, out: &mut Vec<T>) -> Result<TopicEvents, TransportError> {
        // Shared memory only: the listener is left alone (see `consume_wakeups`).
        let mut events = TopicEvents::default();
        while let Some(sample) = self.subscriber.receive().map_err(|e| failed("receiving", &self.name, e))? {
            // In hand: the sample is ours to read in place; the copy below is this port's choice.
            events.in_hand_ns = now_ns();
            out.push(*sample.payload());
            events.samples += 1;
        }
        Ok(events)
    }

    fn receive_sourced(&self, out: &mut Vec<T>, origins: &mut Vec<u128>) -> Result<TopicEvents, TransportError> {
        let mut events = TopicEvents::default();
        while let Some(sample) = self.subscriber.receive().map_err(|e| failed("receiving", &self.name, e))? {
            events.in_hand_ns = now_ns();
            out.push(*sample.payload());
            origins.push(sample.origin().value());
            events.samples += 1;
        }
        Ok(events)
    }

    fn publisher_alive(&self, origin: u128) -> Result<bool, TransportError> {
        let mut node = None;
        self.pubsub.dynamic_config().list_publishers(|p| {
            if p.publisher_id.value() == origin {
                node = Some(p.node_id);
                CallbackProgression::Stop
            } else {
                CallbackProgression::Continue
            }
        });
        let Some(node) = node else { return Ok(false) };
        // Listed: alive unless its node is dead (killed, not yet cleaned up).
        let mut dead = false;
        Node::<ipc::Service>::list(&self.config, |state| {
            if let NodeState::Dead(view) = &state
                && *view.id() == node
            {
                dead = true;
                return CallbackProgression::Stop;
            }
            CallbackProgression::Continue
        })
        .map_err(|e| failed("listing nodes", &self.name, e))?;
        Ok(!dead)
    }

    fn consume_wakeups(&self) -> Result<TopicEvents, TransportError> {
        // Resets the listener's notification state to idle: the next notification is sent again.
        let mut events = TopicEvents::default();
        self.listener
            .try_wait(|activation| events.add(activation.id, activation.count))
            .map_err(|e| wait_error(e, &self.name))?;
        Ok(events)
    }

    fn has_samples(&self) -> Result<bool, TransportError> {
        self.subscriber.has_samples().map_err(|e| failed("polling", &self.name, e))
    }

    fn block(&self, timeout: Duration) -> Result<(), TransportError> {
        self.listener.timed_wait(|_| {}, timeout).map(|_| ()).map_err(|e| wait_error(e, &self.name))
    }

    fn file_descriptor(&self) -> &FileDescriptor {
        self.listener.file_descriptor()
    }

    fn publisher_count(&self) -> Result<usize, TransportError> {
        Ok(self.pubsub.dynamic_config().number_of_publishers())
    }
}

fn wait_error(e: ListenerWaitError, name: &str) -> TransportError {
    match e {
        ListenerWaitError::InterruptSignal => TransportError::Interrupted,
        e => failed("waiting", name, e),
    }
}
