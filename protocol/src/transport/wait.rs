//! Waiting for the next message on several subscribers of either transport: busy-polling, then
//! blocking on one iceoryx2 `WaitSet` — consuming the wake-ups, looking at the buffers once more, then
//! blocking, in that order (see the [module docs](super)).

use core::fmt;
use core::time::Duration;
use std::time::Instant;

use iceoryx2::prelude::*;

use super::{TopicSubscriber, TransportError, failed};
use crate::messages::Message;

/// Busy-polls `ready` for up to `spin` (at least once), yielding the CPU between polls so that processes
/// sharing a core still run; whether it became ready.
pub(super) fn spin_until(
    spin: Duration,
    mut ready: impl FnMut() -> Result<bool, TransportError>,
) -> Result<bool, TransportError> {
    let start = Instant::now();
    loop {
        if ready()? {
            return Ok(true);
        }
        if start.elapsed() >= spin {
            return Ok(false);
        }
        std::thread::yield_now();
    }
}

/// Whether any of `inputs` has a message buffered (what a busy poll asks).
fn any_ready(inputs: &[&dyn Waitable]) -> Result<bool, TransportError> {
    for input in inputs {
        if input.has_samples()? {
            return Ok(true);
        }
    }
    Ok(false)
}

/// The step before a blocking wait on `inputs`: consumes their pending wake-ups, then looks once more for
/// a message (one that came meanwhile; its wake-up may have been among those consumed). `true`: do not
/// block. This order — consume, then check, then block — is what makes skipping the consumption while
/// polling safe (see the module docs).
pub(super) fn about_to_block(inputs: &[&dyn Waitable]) -> Result<bool, TransportError> {
    for input in inputs {
        input.consume_wakeups()?;
    }
    any_ready(inputs)
}

/// Waits on a `WaitSet` to which `inputs` are attached: busy-polls them for `spin` first, then blocks for
/// at most `timeout`. Returns `Ok(())` on any wake-up, a timeout or a signal other than SIGINT/SIGTERM
/// (the caller drains its subscribers either way), [`TransportError::Interrupted`] on SIGINT/SIGTERM.
pub fn wait_any(
    waitset: &WaitSet<ipc::Service>,
    spin: Duration,
    timeout: Duration,
    inputs: &[&dyn Waitable],
) -> Result<(), TransportError> {
    if spin_until(spin, || any_ready(inputs))? || timeout.is_zero() || about_to_block(inputs)? {
        return Ok(());
    }
    match waitset.wait_and_process_once_with_timeout(|_| CallbackProgression::Continue, timeout) {
        Ok(iceoryx2::waitset::WaitSetRunResult::TerminationRequest) => Err(TransportError::Interrupted),
        Ok(_) => Ok(()),
        Err(e) => Err(failed("waiting", "waitset", e)),
    }
}

/// Something a process waits on in its `WaitSet`: a subscriber of either transport (its file descriptor
/// wakes the wait) that says whether a message is waiting.
pub trait Waitable: SynchronousMultiplexing + fmt::Debug {
    /// Whether a message is waiting (a busy poll asks this).
    fn has_samples(&self) -> Result<bool, TransportError>;

    /// Consumes the pending wake-ups before a blocking wait ([`TopicSubscriber::consume_wakeups`]).
    fn consume_wakeups(&self) -> Result<(), TransportError>;
}

impl<T: Message> Waitable for TopicSubscriber<T> {
    fn has_samples(&self) -> Result<bool, TransportError> {
        TopicSubscriber::has_samples(self)
    }

    fn consume_wakeups(&self) -> Result<(), TransportError> {
        TopicSubscriber::consume_wakeups(self).map(|_| ())
    }
}

/// Busy-polls `inputs` for up to `spin` (at least once; the CPU is yielded between polls): whether a
/// message came. Over iceoryx2 it touches shared memory only (no system call but the yields; a socket
/// subscriber's poll is a `recv`), so a process that spins first and sets up its blocking wait (e.g.
/// attaches a deadline to its `WaitSet`) only when nothing came pays for that set-up only when it
/// blocks.
pub fn poll(spin: Duration, inputs: &[&dyn Waitable]) -> Result<bool, TransportError> {
    spin_until(spin, || any_ready(inputs))
}

/// Blocks on a `WaitSet` to which `inputs` are attached and whose deadlines are its own attachments (an
/// interval, a one-shot deadline) until a message, an attached deadline or a signal wakes it — unless a
/// message is already buffered (the wake-ups are consumed, then the buffers looked at once more: see
/// the module docs). Call it after [`poll`] found nothing. Errors as [`wait_any`].
pub fn wait_attached(waitset: &WaitSet<ipc::Service>, inputs: &[&dyn Waitable]) -> Result<(), TransportError> {
    if about_to_block(inputs)? {
        return Ok(());
    }
    match waitset.wait_and_process_once(|_| CallbackProgression::Continue) {
        Ok(iceoryx2::waitset::WaitSetRunResult::TerminationRequest) => Err(TransportError::Interrupted),
        Ok(_) => Ok(()),
        Err(e) => Err(failed("waiting", "waitset", e)),
    }
}

/// A `WaitSet` for the subscribers of one process (either transport).
pub fn waitset() -> Result<WaitSet<ipc::Service>, TransportError> {
    WaitSetBuilder::new().create::<ipc::Service>().map_err(|e| failed("creating", "waitset", e))
}

impl<T: Message> FileDescriptorBased for TopicSubscriber<T> {
    fn file_descriptor(&self) -> &FileDescriptor {
        self.port.file_descriptor()
    }
}

impl<T: Message> SynchronousMultiplexing for TopicSubscriber<T> {}
