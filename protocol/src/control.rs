//! The control topic of a domain, as one process sees it: it announces itself ([`ControlKind::Hello`]),
//! asks for a replay ([`ControlKind::Replay`]),
//! hands over ([`ControlKind::TakeOver`]) or stops the domain ([`ControlKind::Shutdown`]), and hears what
//! the other processes say.
//!
//! Every process publishes on this topic, each with its own sequence numbers, so [`ControlChannel`]
//! validates what it receives against the last accepted sequence number *of the sender's instance*, and
//! drops its own messages.
//!
//! Instance ids ([`instance_id`]) are the pid in the high 32 bits and the start time's low bits below
//! (they tell restarts apart even when a pid is reused); [`Control::started_ns`] orders two instances of
//! one role (the later start is the newer instance).

use std::cell::{Cell, RefCell};
use std::collections::HashMap;

use crate::messages::{Control, ControlKind, now_ns};
use crate::services::{self, Domain};
use crate::transport::{Link, Topic, TopicPublisher, TopicSubscriber, TransportError};
use crate::validate::{Rejection, RejectionCounter};

/// A process instance id: the pid in the high 32 bits, the low 32 bits of `started_ns` below.
pub fn instance_id_at(started_ns: u64) -> u64 {
    (u64::from(std::process::id()) << 32) | (started_ns & 0xffff_ffff)
}

/// This process's instance id, taken now (see [`instance_id_at`]).
pub fn instance_id() -> u64 {
    instance_id_at(now_ns())
}

/// One process's end of the control topic.
#[derive(Debug)]
pub struct ControlChannel {
    role: String,
    instance: u64,
    started_ns: u64,
    /// The run this process belongs to ([`Control::run`]; 0: none).
    run: Cell<u64>,
    seq: Cell<u64>,
    publisher: TopicPublisher<Control>,
    subscriber: TopicSubscriber<Control>,
    last_seq: RefCell<HashMap<u64, Option<u64>>>,
}

impl ControlChannel {
    /// Opens the control topic of `domain` for a process of `role` (its instance id and start time).
    pub fn open(
        link: &Link,
        domain: &Domain,
        role: &str,
        instance: u64,
        started_ns: u64,
    ) -> Result<Self, TransportError> {
        let name = services::control(domain);
        Ok(Self {
            role: role.to_string(),
            instance,
            started_ns,
            run: Cell::new(0),
            // Sequence numbers start at the clock: a later instance numbers above an earlier one.
            seq: Cell::new(now_ns()),
            subscriber: Topic::<Control>::subscriber(link, &name)?,
            publisher: Topic::<Control>::publisher(link, &name)?,
            last_seq: RefCell::new(HashMap::new()),
        })
    }

    /// Publishes a control message of `kind` (see [`ControlKind`] for what `step` means).
    pub fn send(&self, kind: ControlKind, step: u64, detail: &str) -> Result<(), TransportError> {
        self.seq.set(self.seq.get() + 1);
        let msg = Control::new(kind, step, self.seq.get(), self.instance, self.started_ns, &self.role, detail)
            .map_err(|e| TransportError::Failed {
                op: "building a control message",
                service: self.publisher.name().into(),
                detail: e.to_string(),
            })?
            .with_run(self.run.get());
        self.publisher.send(&msg)?;
        Ok(())
    }

    /// The messages of the other instances received since the last call, validated (per sender instance)
    /// and counted in `counter`: `Err` for each rejected one.
    pub fn receive(&self, counter: &mut RejectionCounter) -> Result<Vec<Result<Control, Rejection>>, TransportError> {
        let mut out = Vec::new();
        // Nearly every wake-up is for data: a look at the buffer costs less than a receive.
        if !self.subscriber.has_samples()? {
            return Ok(out);
        }
        let mut last_seq = self.last_seq.borrow_mut();
        for msg in self.subscriber.receive_all()? {
            if msg.instance == self.instance {
                continue;
            }
            let last = last_seq.entry(msg.instance).or_default();
            out.push(counter.check(&msg, last).map(|()| msg));
        }
        Ok(out)
    }

    /// The subscriber (to attach to a `WaitSet`).
    pub fn subscriber(&self) -> &TopicSubscriber<Control> {
        &self.subscriber
    }

    /// Sets the run this process belongs to (every message it sends from now on carries it).
    pub fn set_run(&self, run: u64) {
        self.run.set(run);
    }

    /// The run this process belongs to (0: none).
    pub fn run(&self) -> u64 {
        self.run.get()
    }

    /// This instance's id.
    pub fn instance(&self) -> u64 {
        self.instance
    }

    /// When this instance started.
    pub fn started_ns(&self) -> u64 {
        self.started_ns
    }

    /// This process's role.
    pub fn role(&self) -> &str {
        &self.role
    }
}

/// Whether `msg` is a message of `kind` from another, newer instance of `role` than one started at
/// `started_ns` (e.g. the planner that replaces this one).
pub fn is_newer(msg: &Control, kind: ControlKind, role: &str, started_ns: u64) -> bool {
    msg.kind() == Some(kind) && msg.role() == Some(role) && msg.started_ns > started_ns
}
