//! The two ends of `uavloc bench ipc`: a payload of N bytes from one process to another and a small
//! acknowledgement back, over iceoryx2 (the payload written in place in a loaned shared-memory sample —
//! zero-copy — and a notification to wake the receiver) or over a Unix stream socket (the payload written
//! into a buffer and through the kernel into the receiver's buffer).
//!
//! A payload starts with a 16-byte header: the sequence number and the send time (CLOCK_MONOTONIC, ns)
//! taken once the payload is written, right before it is handed to the transport; the rest is filled by
//! the sender. The receiver answers each payload with an [`Ack`]: the sequence number, the send time, its
//! receive time and the CPU time it has used so far. One payload in flight at a time. The ends either
//! block ([`Waiting::Block`]: the iceoryx2 ends on a listener, the socket ends in `read`) or busy-poll
//! ([`Waiting::Spin`]: the iceoryx2 ends look into the subscriber's queue, the socket ends `read` a
//! non-blocking socket, yielding the CPU between looks) — the transports' own cost, without a kernel
//! wake-up.

use std::io::{Read as _, Write as _};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::Path;
use std::time::Duration;

use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;

use protocol::messages::{cpu_ns, now_ns};
use protocol::transport::{IpcNode, TransportError, failed};

/// Bytes of a payload's header (sequence number, send time).
pub const HEADER: usize = 16;

/// The sequence number that tells the receiver to stop.
pub const STOP: u64 = u64::MAX;

/// How long an end waits for the other before it gives up.
pub const PATIENCE: Duration = Duration::from_secs(10);

/// How both ends of a sweep wait for the other's next message.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Waiting {
    /// Block in the kernel until woken (a notification, or data on the socket).
    #[default]
    Block,
    /// Busy-poll, yielding the CPU between polls (the pipeline's `--wait spin`); the iceoryx2 sender
    /// still notifies, as the pipeline's does (a bit set in shared memory once the last wake-up is
    /// unconsumed).
    Spin,
}

/// Looks for a sample with `receive` until it returns `Some`, calling `wait` with the time left between
/// looks, for at most [`PATIENCE`]: only reaching the deadline is a timeout (a wait that returns early
/// without a sample — a signal, a spurious or stale wake-up — is not).
fn look_until<T>(
    what: &'static str,
    name: &str,
    mut receive: impl FnMut() -> Result<Option<T>, TransportError>,
    mut wait: impl FnMut(std::time::Duration) -> Result<(), TransportError>,
) -> Result<T, TransportError> {
    let deadline = std::time::Instant::now() + PATIENCE;
    loop {
        if let Some(v) = receive()? {
            return Ok(v);
        }
        let left = deadline.saturating_duration_since(std::time::Instant::now());
        if left.is_zero() {
            return Err(timeout(what, name));
        }
        wait(left)?;
    }
}

/// Polls `ready` until it returns `Some`, yielding the CPU between polls; a timeout after [`PATIENCE`].
fn spin<T>(
    what: &'static str,
    name: &str,
    ready: impl FnMut() -> Result<Option<T>, TransportError>,
) -> Result<T, TransportError> {
    look_until(what, name, ready, |_| {
        std::thread::yield_now();
        Ok(())
    })
}

/// The receiver's answer to one payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ack {
    /// The payload's sequence number.
    pub seq: u64,
    /// When the sender handed it to the transport, ns (CLOCK_MONOTONIC).
    pub sent_ns: u64,
    /// When the receiver had it, ns (CLOCK_MONOTONIC).
    pub received_ns: u64,
    /// The receiver's CPU time so far, ns.
    pub cpu_ns: u64,
}

impl Ack {
    fn to_words(self) -> [u64; 4] {
        [self.seq, self.sent_ns, self.received_ns, self.cpu_ns]
    }

    fn from_words(w: [u64; 4]) -> Self {
        Ack { seq: w[0], sent_ns: w[1], received_ns: w[2], cpu_ns: w[3] }
    }
}

/// Writes a payload of `buf.len()` bytes: the body filled with `seq`'s low byte, then the header.
fn fill(buf: &mut [u8], seq: u64) {
    buf[HEADER..].fill(seq as u8);
    buf[..8].copy_from_slice(&seq.to_le_bytes());
    buf[8..HEADER].copy_from_slice(&now_ns().to_le_bytes());
}

/// The header of a payload: (sequence number, send time).
fn header(buf: &[u8]) -> (u64, u64) {
    let word = |i: usize| u64::from_le_bytes(buf[i..i + 8].try_into().unwrap_or([0; 8]));
    (word(0), word(8))
}

/// The sending end.
pub trait Sender {
    /// Sends a payload of `size` bytes (≥ [`HEADER`]) numbered `seq`.
    fn send(&mut self, seq: u64, size: usize) -> Result<(), TransportError>;
    /// Waits for the next acknowledgement (at most [`PATIENCE`]).
    fn ack(&mut self) -> Result<Ack, TransportError>;
}

/// The receiving end.
pub trait Receiver {
    /// Waits for the next payload and acknowledges it; `false` once told to stop.
    fn echo(&mut self) -> Result<bool, TransportError>;
}

fn timeout(what: &'static str, name: &str) -> TransportError {
    TransportError::Failed { op: what, service: name.into(), detail: format!("nothing within {PATIENCE:?}") }
}

// ---------------------------------------------------------------------------------------------------------
// iceoryx2
// ---------------------------------------------------------------------------------------------------------

/// The services of a sweep named `name`: `<name>/data` (`[u8]` payloads) and `<name>/ack`, each with an
/// event service of the same name.
struct IoxServices {
    data: Publisher<ipc::Service, [u8], ()>,
    notifier: Notifier<ipc::Service>,
    acks: Subscriber<ipc::Service, [u64; 4], ()>,
    listener: Listener<ipc::Service>,
}

fn service(name: &str) -> Result<ServiceName, TransportError> {
    ServiceName::new(name).map_err(|e| TransportError::BadName {
        what: "service",
        name: name.to_owned(),
        detail: format!("{e:?}"),
    })
}

/// The builder of the pub/sub service `name` of a sweep: one sample in flight and a spare, no history.
fn sweep_service<T: core::fmt::Debug + IceoryxSend + ?Sized>(
    node: &IpcNode,
    name: &str,
) -> Result<iceoryx2::service::builder::publish_subscribe::Builder<T, (), ipc::Service>, TransportError> {
    Ok(node.service_builder(&service(name)?).publish_subscribe::<T>().subscriber_max_buffer_size(2).history_size(0))
}

fn event_pair(
    node: &IpcNode,
    out: &str,
    inbound: &str,
) -> Result<(Notifier<ipc::Service>, Listener<ipc::Service>), TransportError> {
    let open = |n: &str| {
        node.service_builder(&service(n)?).event().open_or_create().map_err(|e| failed("opening event service", n, e))
    };
    let notifier = open(out)?.notifier_builder().create().map_err(|e| failed("creating notifier", out, e))?;
    let listener = open(inbound)?.listener_builder().create().map_err(|e| failed("creating listener", inbound, e))?;
    Ok((notifier, listener))
}

/// The sending end over iceoryx2 (payloads up to `max_size` bytes).
pub struct IoxSender {
    name: String,
    ports: IoxServices,
    waiting: Waiting,
}

impl IoxSender {
    /// Creates the sending end of sweep `name`, waiting for acknowledgements as `waiting` says.
    pub fn create(node: &IpcNode, name: &str, max_size: usize, waiting: Waiting) -> Result<Self, TransportError> {
        let (data_name, ack_name) = (protocol::services::sweep_data(name), protocol::services::sweep_ack(name));
        let data = sweep_service::<[u8]>(node, &data_name)?
            .open_or_create()
            .map_err(|e| failed("opening pub/sub service", &data_name, e))?
            .publisher_builder()
            .initial_max_slice_len(max_size)
            .create()
            .map_err(|e| failed("creating publisher", &data_name, e))?;
        let acks = sweep_service::<[u64; 4]>(node, &ack_name)?
            .open_or_create()
            .map_err(|e| failed("opening pub/sub service", &ack_name, e))?
            .subscriber_builder()
            .buffer_size(2)
            .create()
            .map_err(|e| failed("creating subscriber", &ack_name, e))?;
        let (notifier, listener) = event_pair(node, &data_name, &ack_name)?;
        Ok(IoxSender { name: name.to_owned(), ports: IoxServices { data, notifier, acks, listener }, waiting })
    }
}

impl Sender for IoxSender {
    fn send(&mut self, seq: u64, size: usize) -> Result<(), TransportError> {
        let p = &self.ports;
        let mut sample = p.data.loan_slice_uninit(size).map_err(|e| failed("loaning a sample", &self.name, e))?;
        // Written in place, in shared memory: the receiver maps the same pages.
        let bytes = sample.payload_mut();
        for b in bytes[HEADER..].iter_mut() {
            b.write(seq as u8);
        }
        for (b, v) in bytes[..8].iter_mut().zip(seq.to_le_bytes()) {
            b.write(v);
        }
        for (b, v) in bytes[8..HEADER].iter_mut().zip(now_ns().to_le_bytes()) {
            b.write(v);
        }
        // SAFETY: every byte was written just above.
        let sample = unsafe { sample.assume_init() };
        sample.send().map_err(|e| failed("sending a sample", &self.name, e))?;
        p.notifier.notify().map_err(|e| failed("notifying", &self.name, e))?;
        Ok(())
    }

    fn ack(&mut self) -> Result<Ack, TransportError> {
        let (p, name) = (&self.ports, &self.name);
        let receive = || {
            let sample = p.acks.receive().map_err(|e| failed("receiving an ack", name, e))?;
            Ok(sample.map(|s| Ack::from_words(*s.payload())))
        };
        wait_for(self.waiting, &p.listener, "waiting for an ack", name, receive)
    }
}

/// The receiving end over iceoryx2.
pub struct IoxReceiver {
    name: String,
    data: Subscriber<ipc::Service, [u8], ()>,
    acks: Publisher<ipc::Service, [u64; 4], ()>,
    notifier: Notifier<ipc::Service>,
    listener: Listener<ipc::Service>,
    waiting: Waiting,
}

impl IoxReceiver {
    /// Creates the receiving end of sweep `name` (waiting for payloads as `waiting` says) and says it is
    /// there (an ack numbered [`STOP`]).
    pub fn create(node: &IpcNode, name: &str, waiting: Waiting) -> Result<Self, TransportError> {
        let (data_name, ack_name) = (protocol::services::sweep_data(name), protocol::services::sweep_ack(name));
        let data = sweep_service::<[u8]>(node, &data_name)?
            .open_or_create()
            .map_err(|e| failed("opening pub/sub service", &data_name, e))?
            .subscriber_builder()
            .buffer_size(2)
            .create()
            .map_err(|e| failed("creating subscriber", &data_name, e))?;
        let acks = sweep_service::<[u64; 4]>(node, &ack_name)?
            .open_or_create()
            .map_err(|e| failed("opening pub/sub service", &ack_name, e))?
            .publisher_builder()
            .create()
            .map_err(|e| failed("creating publisher", &ack_name, e))?;
        let (notifier, listener) = event_pair(node, &ack_name, &data_name)?;
        let r = IoxReceiver { name: name.to_owned(), data, acks, notifier, listener, waiting };
        r.answer(Ack { seq: STOP, sent_ns: 0, received_ns: now_ns(), cpu_ns: cpu_ns() })?;
        Ok(r)
    }

    fn answer(&self, ack: Ack) -> Result<(), TransportError> {
        self.acks.send_copy(ack.to_words()).map_err(|e| failed("sending an ack", &self.name, e))?;
        self.notifier.notify().map_err(|e| failed("notifying", &self.name, e))?;
        Ok(())
    }
}

impl Receiver for IoxReceiver {
    fn echo(&mut self) -> Result<bool, TransportError> {
        let (data, name) = (&self.data, &self.name);
        let receive = || {
            let sample = data.receive().map_err(|e| failed("receiving", name, e))?;
            Ok(sample.map(|sample| {
                let received_ns = now_ns();
                let (seq, sent_ns) = header(sample.payload());
                (seq, sent_ns, received_ns)
            }))
        };
        let (seq, sent_ns, received_ns) =
            wait_for(self.waiting, &self.listener, "waiting for a payload", name, receive)?;
        if seq == STOP {
            return Ok(false);
        }
        self.answer(Ack { seq, sent_ns, received_ns, cpu_ns: cpu_ns() })?;
        Ok(true)
    }
}

/// Looks for a sample with `receive` until it comes, as `waiting` says: polling ([`spin`]) or blocking on
/// `listener` between looks ([`block`]).
fn wait_for<T>(
    waiting: Waiting,
    listener: &iceoryx2::port::listener::Listener<ipc::Service>,
    what: &'static str,
    name: &str,
    receive: impl FnMut() -> Result<Option<T>, TransportError>,
) -> Result<T, TransportError> {
    match waiting {
        Waiting::Spin => spin(what, name, receive),
        Waiting::Block => block(listener, what, name, receive),
    }
}

/// Looks for a sample with `receive`, blocking on `listener` between looks, for at most [`PATIENCE`]
/// ([`look_until`]).
fn block<T>(
    listener: &iceoryx2::port::listener::Listener<ipc::Service>,
    what: &'static str,
    name: &str,
    receive: impl FnMut() -> Result<Option<T>, TransportError>,
) -> Result<T, TransportError> {
    look_until(what, name, receive, |left| {
        listener.timed_wait(|_| {}, left).map(|_| ()).map_err(|e| failed(what, name, e))
    })
}

/// Waits until a receiver has connected to `sender` (its readiness ack, numbered [`STOP`], came).
pub fn wait_ready(sender: &mut dyn Sender) -> Result<(), TransportError> {
    match sender.ack()? {
        Ack { seq: STOP, .. } => Ok(()),
        other => Err(TransportError::Failed {
            op: "connecting",
            service: "sweep".into(),
            detail: format!("expected the receiver's readiness, got ack {}", other.seq),
        }),
    }
}

// ---------------------------------------------------------------------------------------------------------
// Unix stream socket
// ---------------------------------------------------------------------------------------------------------

fn io<'a>(op: &'static str, path: &'a Path) -> impl Fn(std::io::Error) -> TransportError + 'a {
    move |e| TransportError::Failed { op, service: path.display().to_string(), detail: e.to_string() }
}

/// Moves `len` bytes with `step` (one read or write from offset `done`, returning how many bytes it moved),
/// again while the socket would block (a non-blocking socket: busy-polling, yielding the CPU) for at most
/// [`PATIENCE`]; stops early when a step moves nothing (the end of the stream). How many bytes moved.
fn transfer(
    len: usize,
    op: &'static str,
    path: &Path,
    mut step: impl FnMut(usize) -> std::io::Result<usize>,
) -> Result<usize, TransportError> {
    let mut done = 0;
    let deadline = std::time::Instant::now() + PATIENCE;
    while done < len {
        match step(done) {
            Ok(0) => break,
            Ok(n) => done += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock && std::time::Instant::now() < deadline => {
                std::thread::yield_now();
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                return Err(timeout(op, &path.display().to_string()));
            }
            Err(e) => return Err(io(op, path)(e)),
        }
    }
    Ok(done)
}

/// Reads exactly `buf.len()` bytes from a stream, blocking or (non-blocking socket) busy-polling for them;
/// `Ok(false)` at the end of the stream before the first byte.
fn read_full(stream: &mut UnixStream, buf: &mut [u8], op: &'static str, path: &Path) -> Result<bool, TransportError> {
    let len = buf.len();
    match transfer(len, op, path, |done| stream.read(&mut buf[done..]))? {
        0 if len > 0 => Ok(false),
        n if n == len => Ok(true),
        _ => Err(io(op, path)(std::io::ErrorKind::UnexpectedEof.into())),
    }
}

/// Writes all of `buf` to a stream, blocking or (non-blocking socket, a payload larger than its buffer)
/// busy-polling until the other end has read enough.
fn write_full(stream: &mut UnixStream, buf: &[u8], op: &'static str, path: &Path) -> Result<(), TransportError> {
    if transfer(buf.len(), op, path, |done| stream.write(&buf[done..]))? == buf.len() {
        Ok(())
    } else {
        Err(io(op, path)(std::io::ErrorKind::WriteZero.into()))
    }
}

/// The sending end over a Unix stream socket: a length (u64) then the payload; a 32-byte ack back.
pub struct SocketSender {
    stream: UnixStream,
    buf: Vec<u8>,
    path: std::path::PathBuf,
}

impl SocketSender {
    /// Listens at `path` (a fresh path in a private directory) for one receiver, at most [`PATIENCE`];
    /// waits for acknowledgements as `waiting` says.
    pub fn accept(
        listener: &UnixListener,
        path: &Path,
        max_size: usize,
        waiting: Waiting,
    ) -> Result<Self, TransportError> {
        listener.set_nonblocking(true).map_err(io("listening", path))?;
        let start = std::time::Instant::now();
        let stream = loop {
            match listener.accept() {
                Ok((s, _)) => break s,
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock && start.elapsed() < PATIENCE => {
                    std::thread::sleep(Duration::from_millis(1));
                }
                Err(e) => return Err(io("accepting", path)(e)),
            }
        };
        stream.set_nonblocking(waiting == Waiting::Spin).map_err(io("accepting", path))?;
        stream.set_read_timeout(Some(PATIENCE)).map_err(io("accepting", path))?;
        Ok(SocketSender { stream, buf: vec![0; max_size.max(HEADER)], path: path.to_path_buf() })
    }
}

impl Sender for SocketSender {
    fn send(&mut self, seq: u64, size: usize) -> Result<(), TransportError> {
        let payload = &mut self.buf[..size];
        fill(payload, seq);
        write_full(&mut self.stream, &(size as u64).to_le_bytes(), "sending", &self.path)?;
        write_full(&mut self.stream, payload, "sending", &self.path)
    }

    fn ack(&mut self) -> Result<Ack, TransportError> {
        let mut raw = [0u8; 32];
        if !read_full(&mut self.stream, &mut raw, "receiving an ack", &self.path)? {
            return Err(io("receiving an ack", &self.path)(std::io::ErrorKind::UnexpectedEof.into()));
        }
        let word = |i: usize| u64::from_le_bytes(raw[i * 8..i * 8 + 8].try_into().unwrap_or([0; 8]));
        Ok(Ack::from_words([word(0), word(1), word(2), word(3)]))
    }
}

/// The receiving end over a Unix stream socket.
pub struct SocketReceiver {
    stream: UnixStream,
    buf: Vec<u8>,
    path: std::path::PathBuf,
}

impl SocketReceiver {
    /// Connects to the sender listening at `path` (waiting for payloads as `waiting` says) and says it is
    /// there.
    pub fn connect(path: &Path, max_size: usize, waiting: Waiting) -> Result<Self, TransportError> {
        let stream = UnixStream::connect(path).map_err(io("connecting", path))?;
        stream.set_read_timeout(Some(PATIENCE)).map_err(io("connecting", path))?;
        stream.set_nonblocking(waiting == Waiting::Spin).map_err(io("connecting", path))?;
        let mut r = SocketReceiver { stream, buf: vec![0; max_size.max(HEADER)], path: path.to_path_buf() };
        r.answer(Ack { seq: STOP, sent_ns: 0, received_ns: now_ns(), cpu_ns: cpu_ns() })?;
        Ok(r)
    }

    fn answer(&mut self, ack: Ack) -> Result<(), TransportError> {
        let mut raw = [0u8; 32];
        for (i, w) in ack.to_words().iter().enumerate() {
            raw[i * 8..i * 8 + 8].copy_from_slice(&w.to_le_bytes());
        }
        write_full(&mut self.stream, &raw, "sending an ack", &self.path)
    }
}

impl Receiver for SocketReceiver {
    fn echo(&mut self) -> Result<bool, TransportError> {
        let mut len = [0u8; 8];
        if !read_full(&mut self.stream, &mut len, "receiving", &self.path)? {
            return Ok(false);
        }
        let len = u64::from_le_bytes(len) as usize;
        if len < HEADER || len > self.buf.len() {
            return Err(TransportError::Failed {
                op: "receiving",
                service: self.path.display().to_string(),
                detail: format!("a payload of {len} bytes (expected {HEADER}..={})", self.buf.len()),
            });
        }
        if !read_full(&mut self.stream, &mut self.buf[..len], "receiving", &self.path)? {
            return Err(io("receiving", &self.path)(std::io::ErrorKind::UnexpectedEof.into()));
        }
        let received_ns = now_ns();
        let (seq, sent_ns) = header(&self.buf[..len]);
        if seq == STOP {
            return Ok(false);
        }
        self.answer(Ack { seq, sent_ns, received_ns, cpu_ns: cpu_ns() })?;
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_payload_carries_its_header_and_body() {
        let mut buf = vec![0u8; 64];
        let before = now_ns();
        fill(&mut buf, 0x1_02);
        let (seq, sent) = header(&buf);
        assert_eq!(seq, 0x102);
        assert!(sent >= before && sent <= now_ns());
        assert!(buf[HEADER..].iter().all(|&b| b == 0x02));
        let ack = Ack { seq: 1, sent_ns: 2, received_ns: 3, cpu_ns: 4 };
        assert_eq!(Ack::from_words(ack.to_words()), ack);
    }

    #[test]
    fn the_socket_ends_echo_each_payload_and_stop() {
        for waiting in [Waiting::Block, Waiting::Spin] {
            socket_echo(waiting);
        }
    }

    fn socket_echo(waiting: Waiting) {
        let dir = std::env::temp_dir().join(format!("uavloc-sweep-test-{}-{waiting:?}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("s.sock");
        let listener = UnixListener::bind(&path).unwrap();
        let p = path.clone();
        let echo = std::thread::spawn(move || {
            let mut r = SocketReceiver::connect(&p, 1 << 20, waiting).unwrap();
            let mut n = 0;
            while r.echo().unwrap() {
                n += 1;
            }
            n
        });
        let mut s = SocketSender::accept(&listener, &path, 1 << 20, waiting).unwrap();
        wait_ready(&mut s).unwrap();
        // The last payload is larger than a socket's buffer: written and read in parts.
        for (seq, size) in [100, 101, 4096, 65_536, 1 << 20].into_iter().enumerate() {
            let seq = seq as u64;
            s.send(seq, size).unwrap();
            let ack = s.ack().unwrap();
            assert_eq!(ack.seq, seq);
            assert!(ack.received_ns >= ack.sent_ns && ack.cpu_ns > 0);
        }
        s.send(STOP, HEADER).unwrap();
        assert_eq!(echo.join().unwrap(), 5);
        std::fs::remove_dir_all(&dir).ok();
    }
}
