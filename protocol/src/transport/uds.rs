//! The Unix-domain-socket transport: the baseline a user would otherwise write, for `uavloc bench compare`.
//!
//! Each message goes out as one datagram (`SOCK_DGRAM`, `AF_UNIX`) holding exactly the bytes of its
//! `#[repr(C)]` struct ([`AnyBitPattern::as_bytes`](crate::messages::AnyBitPattern::as_bytes)) — no serialisation, as with iceoryx2, but copied
//! through the kernel once per subscriber instead of shared.
//!
//! Layout on disk: `$UAVLOC_UDS_DIR` (default `/tmp/uavloc-uds-<uid>`, created with mode 0700 and refused
//! if another user owns it or others can enter it) holds one directory per topic, named by a hash of the
//! service name (socket paths are limited to 108 bytes, domains may have 64 characters), with
//! - `s.<pid>.<n>`: a subscriber's bound socket (its receive queue is the subscriber's buffer);
//! - `p.<pid>.<n>`: a publisher's bound socket (only so publishers can be counted);
//! - `gen`: an 8-byte shared counter bumped whenever a subscriber comes or goes. A publisher re-reads the
//!   directory only when the counter moved (one atomic load per send, no system call), then `sendto`s
//!   each subscriber.
//!
//! A subscriber's queue holds the kernel's `net.unix.max_dgram_qlen` datagrams (often only 10). When it is
//! full, `sendto` blocks — backpressure, as with the blocking socket a user would write — for at most
//! [`SEND_TIMEOUT`]; then that subscriber misses the message, which is counted
//! ([`super::PublishPort::dropped`]) and reported once on stderr. (iceoryx2 never blocks the publisher: it
//! overwrites the subscriber's oldest sample instead.) A socket file whose
//! process died (`ECONNREFUSED`) is removed by the next publisher that finds it — the counterpart of
//! iceoryx2's dead-node cleanup. Wake-ups need no second channel: the socket becomes readable.

use core::cell::{Cell, RefCell};
use core::marker::PhantomData;
use core::mem::size_of;
use core::sync::atomic::{AtomicU64, Ordering};
use core::time::Duration;
use std::collections::VecDeque;
use std::io;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};
use std::os::unix::ffi::OsStrExt;
use std::os::unix::fs::{DirBuilderExt, MetadataExt, OpenOptionsExt};
use std::path::{Path, PathBuf};

use iceoryx2::prelude::FileDescriptor;

use super::{PublishPort, SubscribePort, TopicEvents, TransportError};
use crate::messages::{Message, now_ns};

/// Environment variable naming the directory of the socket files.
pub const UDS_DIR_ENV: &str = "UAVLOC_UDS_DIR";

/// How long a publisher waits for room in a full subscriber queue before dropping the message for it.
pub const SEND_TIMEOUT: Duration = Duration::from_millis(100);

/// Largest message the transport carries (bytes); every message type is smaller.
const MAX_MESSAGE: usize = 8192;

/// The directory of the socket files: `$UAVLOC_UDS_DIR`, else `/tmp/uavloc-uds-<uid>`.
pub fn base_dir() -> PathBuf {
    match std::env::var_os(UDS_DIR_ENV) {
        Some(d) if !d.is_empty() => PathBuf::from(d),
        // SAFETY: getuid has no preconditions and cannot fail.
        _ => std::env::temp_dir().join(format!("uavloc-uds-{}", unsafe { libc::getuid() })),
    }
}

/// Checks, before any topic is opened, that the socket directory ([`base_dir`]) can hold this transport's
/// sockets: it is (or can be created as) this user's private directory, and the longest socket path
/// under it fits a Unix socket address (107 bytes). The error names the directory and where it came from
/// (`UAVLOC_UDS_DIR` or the default), so a bad setting is reported as such — before, the first process
/// to open a topic failed with the topic's name and the system's error only.
pub fn check_socket_dir() -> Result<PathBuf, String> {
    let dir = base_dir();
    let source = match std::env::var_os(UDS_DIR_ENV) {
        Some(d) if !d.is_empty() => format!("{UDS_DIR_ENV}={}", dir.display()),
        _ => format!("the socket directory {} (set {UDS_DIR_ENV} to use another)", dir.display()),
    };
    // The longest socket path: <dir>/<16 hex digits>/<prefix>.<pid>.<counter>.
    let longest = topic_dir("").join(format!("s.{}.{}", i32::MAX, u32::MAX));
    let room = core::mem::size_of::<libc::sockaddr_un>() - core::mem::offset_of!(libc::sockaddr_un, sun_path) - 1;
    let len = longest.as_os_str().len();
    if len > room {
        return Err(format!(
            "{source}: a socket path under it takes up to {len} bytes, more than the {room} a Unix socket address \
             holds; choose a shorter directory"
        ));
    }
    private_dir(&dir, "the socket directory").map_err(|e| match e {
        TransportError::Failed { op, detail, .. } => format!("{source}: {op}: {detail}"),
        e => format!("{source}: {e}"),
    })?;
    Ok(dir)
}

/// The directory of topic `name` (a 64-bit FNV-1a hash of the name under [`base_dir`]).
pub fn topic_dir(name: &str) -> PathBuf {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in name.bytes() {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    base_dir().join(format!("{h:016x}"))
}

fn io_failed(op: &'static str, service: &str, e: io::Error) -> TransportError {
    TransportError::Failed { op, service: service.to_owned(), detail: e.to_string() }
}

/// Creates `dir` with mode 0700 if needed; refuses one owned by another user or open to others.
///
/// The mode is set again after the creation: the process's umask applies to it, and iceoryx2 sets the
/// umask for a moment while it binds a socket (`iceoryx2-bb-posix`'s `UnixDatagramSocket`), so a
/// directory created by another thread at that moment came out 0600 — without the search bit.
fn private_dir(dir: &Path, service: &str) -> Result<(), TransportError> {
    match std::fs::DirBuilder::new().recursive(true).mode(0o700).create(dir) {
        Ok(()) => {}
        Err(e) => return Err(io_failed("creating the socket directory", service, e)),
    }
    let mut meta = std::fs::metadata(dir).map_err(|e| io_failed("checking the socket directory", service, e))?;
    // SAFETY: getuid has no preconditions and cannot fail.
    if meta.is_dir()
        && meta.uid() == unsafe { libc::getuid() }
        && meta.mode() & 0o777 != 0o700
        && meta.mode() & 0o077 == 0
    {
        use std::os::unix::fs::PermissionsExt as _;
        std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o700))
            .map_err(|e| io_failed("setting the socket directory's mode", service, e))?;
        meta = std::fs::metadata(dir).map_err(|e| io_failed("checking the socket directory", service, e))?;
    }
    // SAFETY: getuid has no preconditions and cannot fail.
    let uid = unsafe { libc::getuid() };
    if !meta.is_dir() || meta.uid() != uid || meta.mode() & 0o077 != 0 {
        return Err(TransportError::Failed {
            op: "checking the socket directory",
            service: service.to_owned(),
            detail: format!(
                "{} must be a directory of user {uid} with mode 0700 (it has owner {} and mode {:o})",
                dir.display(),
                meta.uid(),
                meta.mode() & 0o7777
            ),
        });
    }
    Ok(())
}

/// Prepares the topic's directory (and the base directory) for `service`.
fn topic(service: &str) -> Result<PathBuf, TransportError> {
    private_dir(&base_dir(), service)?;
    let dir = topic_dir(service);
    private_dir(&dir, service)?;
    Ok(dir)
}

/// A unique socket file name for this process: `<prefix>.<pid>.<n>`.
fn socket_name(prefix: char) -> String {
    static NEXT: AtomicU64 = AtomicU64::new(0);
    format!("{prefix}.{}.{}", std::process::id(), NEXT.fetch_add(1, Ordering::Relaxed))
}

/// The pid in a socket file name `<prefix>.<pid>.<n>`.
fn pid_of(file: &str) -> Option<i32> {
    file.split('.').nth(1)?.parse().ok()
}

fn alive(pid: i32) -> bool {
    // SAFETY: kill with signal 0 only checks whether the process exists and may be signalled.
    unsafe { libc::kill(pid, 0) == 0 || io::Error::last_os_error().raw_os_error() == Some(libc::EPERM) }
}

/// Live socket files of `dir` whose names start with `prefix.`.
fn live_sockets(dir: &Path, prefix: char, service: &str) -> Result<usize, TransportError> {
    let entries = std::fs::read_dir(dir).map_err(|e| io_failed("listing the socket directory", service, e))?;
    Ok(entries
        .filter_map(Result::ok)
        .filter_map(|e| e.file_name().to_str().map(str::to_owned))
        .filter(|n| n.starts_with(prefix) && n[1..].starts_with('.') && pid_of(n).is_some_and(alive))
        .count())
}

/// A `sockaddr_un` for `path`.
#[derive(Clone, Copy)]
struct Addr {
    sun: libc::sockaddr_un,
    len: libc::socklen_t,
}

impl Addr {
    fn new(path: &Path, service: &str) -> Result<Self, TransportError> {
        // SAFETY: sockaddr_un is plain old data; all zeroes is a valid (empty) value.
        let mut sun: libc::sockaddr_un = unsafe { core::mem::zeroed() };
        sun.sun_family = libc::AF_UNIX as libc::sa_family_t;
        let bytes = path.as_os_str().as_bytes();
        if bytes.len() >= sun.sun_path.len() {
            return Err(TransportError::Failed {
                op: "naming a socket",
                service: service.to_owned(),
                detail: format!("path {} is longer than {} bytes", path.display(), sun.sun_path.len() - 1),
            });
        }
        for (d, s) in sun.sun_path.iter_mut().zip(bytes) {
            *d = *s as libc::c_char;
        }
        let len = (core::mem::offset_of!(libc::sockaddr_un, sun_path) + bytes.len() + 1) as libc::socklen_t;
        Ok(Addr { sun, len })
    }

    fn as_ptr(&self) -> *const libc::sockaddr {
        (&self.sun as *const libc::sockaddr_un).cast()
    }
}

/// A datagram socket bound to `path` (non-blocking, close-on-exec).
fn bound_socket(path: &Path, service: &str) -> Result<OwnedFd, TransportError> {
    // SAFETY: socket has no memory preconditions; the result is checked.
    let fd = unsafe { libc::socket(libc::AF_UNIX, libc::SOCK_DGRAM | libc::SOCK_NONBLOCK | libc::SOCK_CLOEXEC, 0) };
    if fd < 0 {
        return Err(io_failed("creating a socket", service, io::Error::last_os_error()));
    }
    // SAFETY: `fd` is a fresh descriptor owned by nobody else.
    let fd = unsafe { OwnedFd::from_raw_fd(fd) };
    let addr = Addr::new(path, service)?;
    // SAFETY: `addr` is a valid sockaddr_un of `addr.len` bytes; the fd is valid.
    if unsafe { libc::bind(fd.as_raw_fd(), addr.as_ptr(), addr.len) } != 0 {
        return Err(io_failed("binding a socket", service, io::Error::last_os_error()));
    }
    Ok(fd)
}

/// Makes `fd` blocking, with `timeout` on sends.
fn set_blocking_with_timeout(fd: &OwnedFd, timeout: Duration, service: &str) -> Result<(), TransportError> {
    let raw = fd.as_raw_fd();
    // SAFETY: fcntl on a valid fd with integer arguments.
    let ok = unsafe {
        let flags = libc::fcntl(raw, libc::F_GETFL);
        flags >= 0 && libc::fcntl(raw, libc::F_SETFL, flags & !libc::O_NONBLOCK) == 0
    };
    let tv = libc::timeval {
        tv_sec: timeout.as_secs() as libc::time_t,
        tv_usec: timeout.subsec_micros() as libc::suseconds_t,
    };
    // SAFETY: a valid timeval of the size given; a valid fd.
    let ok = ok
        && unsafe {
            libc::setsockopt(
                raw,
                libc::SOL_SOCKET,
                libc::SO_SNDTIMEO,
                (&tv as *const libc::timeval).cast(),
                size_of::<libc::timeval>() as libc::socklen_t,
            )
        } == 0;
    if ok { Ok(()) } else { Err(io_failed("configuring a socket", service, io::Error::last_os_error())) }
}

/// The topic's shared subscriber-generation counter (`generation`, 8 bytes, mapped shared).
struct Generation {
    ptr: *mut AtomicU64,
}

impl Generation {
    fn open(dir: &Path, service: &str) -> Result<Self, TransportError> {
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .mode(0o600)
            .open(dir.join("gen"))
            .map_err(|e| io_failed("opening the subscriber counter", service, e))?;
        // Growing an 8-byte file to 8 bytes is a no-op; a new (empty) one becomes 8 zero bytes.
        if file.metadata().map_err(|e| io_failed("opening the subscriber counter", service, e))?.len() < 8 {
            file.set_len(8).map_err(|e| io_failed("sizing the subscriber counter", service, e))?;
        }
        // SAFETY: mapping 8 bytes of a file we opened read-write; the result is checked. The mapping stays
        // valid after the file is closed and is unmapped in Drop.
        let ptr = unsafe {
            libc::mmap(
                core::ptr::null_mut(),
                8,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_SHARED,
                file.as_raw_fd(),
                0,
            )
        };
        if ptr == libc::MAP_FAILED {
            return Err(io_failed("mapping the subscriber counter", service, io::Error::last_os_error()));
        }
        Ok(Generation { ptr: ptr.cast() })
    }

    fn get(&self) -> &AtomicU64 {
        // SAFETY: `ptr` points to 8 mapped, page-aligned bytes for the lifetime of `self`; AtomicU64 has the
        // size and alignment of u64, and every process touches them only atomically.
        unsafe { &*self.ptr }
    }

    fn load(&self) -> u64 {
        self.get().load(Ordering::SeqCst)
    }

    fn bump(&self) {
        self.get().fetch_add(1, Ordering::SeqCst);
    }
}

impl Drop for Generation {
    fn drop(&mut self) {
        // SAFETY: unmapping exactly the mapping made in `open`.
        unsafe { libc::munmap(self.ptr.cast(), 8) };
    }
}

/// The subscribers a publisher sends to, as of generation `generation`.
#[derive(Default)]
struct Peers {
    generation: Option<u64>,
    list: Vec<(PathBuf, Addr)>,
}

/// A publisher: an unconnected datagram socket that `sendto`s each subscriber.
pub struct UdsPublisher<T: Message> {
    name: String,
    dir: PathBuf,
    path: PathBuf,
    fd: OwnedFd,
    generation: Generation,
    peers: RefCell<Peers>,
    dropped: Cell<u64>,
    _type: PhantomData<T>,
}

impl<T: Message> core::fmt::Debug for UdsPublisher<T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("UdsPublisher").field("name", &self.name).field("path", &self.path).finish_non_exhaustive()
    }
}

impl<T: Message> UdsPublisher<T> {
    /// Opens (or creates) the topic `name` and adds a publisher to it.
    pub fn create(name: &str) -> Result<Self, TransportError> {
        const { assert!(size_of::<T>() < MAX_MESSAGE) };
        let dir = topic(name)?;
        let generation = Generation::open(&dir, name)?;
        let path = dir.join(socket_name('p'));
        let fd = bound_socket(&path, name)?;
        set_blocking_with_timeout(&fd, SEND_TIMEOUT, name)?;
        Ok(UdsPublisher {
            name: name.to_owned(),
            dir,
            path,
            fd,
            generation,
            peers: RefCell::new(Peers::default()),
            dropped: Cell::new(0),
            _type: PhantomData,
        })
    }

    fn rescan(&self, peers: &mut Peers) -> Result<(), TransportError> {
        let generation = self.generation.load();
        let entries =
            std::fs::read_dir(&self.dir).map_err(|e| io_failed("listing the socket directory", &self.name, e))?;
        peers.list.clear();
        for entry in entries.filter_map(Result::ok) {
            let file = entry.file_name();
            if file.as_bytes().starts_with(b"s.") {
                let path = entry.path();
                let addr = Addr::new(&path, &self.name)?;
                peers.list.push((path, addr));
            }
        }
        peers.generation = Some(generation);
        Ok(())
    }
}

impl<T: Message> PublishPort<T> for UdsPublisher<T> {
    fn deliver(&self, msg: &T, stamp: &mut dyn FnMut(&mut T)) -> Result<usize, TransportError> {
        let mut peers = self.peers.borrow_mut();
        if peers.generation != Some(self.generation.load()) {
            self.rescan(&mut peers)?;
        }
        let mut msg = *msg;
        stamp(&mut msg);
        let bytes = msg.as_bytes();
        let mut delivered = 0;
        let mut stale = Vec::new();
        for (i, (_, addr)) in peers.list.iter().enumerate() {
            loop {
                // SAFETY: `bytes` is a valid buffer of its length; `addr` a valid sockaddr_un; the fd is open.
                let rc = unsafe {
                    libc::sendto(
                        self.fd.as_raw_fd(),
                        bytes.as_ptr().cast(),
                        bytes.len(),
                        libc::MSG_NOSIGNAL,
                        addr.as_ptr(),
                        addr.len,
                    )
                };
                if rc >= 0 {
                    delivered += 1;
                    break;
                }
                let e = io::Error::last_os_error();
                match e.raw_os_error() {
                    Some(libc::EINTR) => continue,
                    Some(libc::EAGAIN) => {
                        if self.dropped.get() == 0 {
                            crate::log_line!(
                                "warning: {}: a subscriber's queue stayed full for {} ms; dropping the message for it",
                                self.name,
                                SEND_TIMEOUT.as_millis()
                            );
                        }
                        self.dropped.set(self.dropped.get() + 1);
                    }
                    Some(libc::ECONNREFUSED | libc::ENOENT) => stale.push(i),
                    _ => return Err(io_failed("sending a datagram", &self.name, e)),
                }
                break;
            }
        }
        if !stale.is_empty() {
            // Nobody listens there any more (its process died): remove the file, tell the other publishers.
            for &i in stale.iter().rev() {
                let (path, _) = peers.list.remove(i);
                let _ = std::fs::remove_file(path);
            }
            self.generation.bump();
            peers.generation = Some(self.generation.load());
        }
        Ok(delivered)
    }

    fn subscriber_count(&self) -> Result<usize, TransportError> {
        live_sockets(&self.dir, 's', &self.name)
    }

    fn publisher_count(&self) -> Result<usize, TransportError> {
        live_sockets(&self.dir, 'p', &self.name)
    }

    fn dropped(&self) -> u64 {
        self.dropped.get()
    }
}

impl<T: Message> Drop for UdsPublisher<T> {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

/// A subscriber: a bound datagram socket; its receive queue is the subscriber's buffer.
pub struct UdsSubscriber<T: Message> {
    name: String,
    dir: PathBuf,
    path: PathBuf,
    fd: OwnedFd,
    descriptor: FileDescriptor,
    generation: Generation,
    /// Messages a poll took from the socket ([`SubscribePort::has_samples`]), each with when it was
    /// taken (its in-hand stamp, [`TopicEvents::in_hand_ns`]).
    pending: RefCell<VecDeque<(T, u64)>>,
}

impl<T: Message> core::fmt::Debug for UdsSubscriber<T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("UdsSubscriber").field("name", &self.name).field("path", &self.path).finish_non_exhaustive()
    }
}

/// What one non-blocking receive found.
enum Received<T> {
    Message(T),
    /// A datagram of the wrong size (dropped).
    Malformed,
    Empty,
}

impl<T: Message> UdsSubscriber<T> {
    /// Opens (or creates) the topic `name` and adds a subscriber to it.
    pub fn create(name: &str) -> Result<Self, TransportError> {
        const { assert!(size_of::<T>() < MAX_MESSAGE) };
        let dir = topic(name)?;
        let generation = Generation::open(&dir, name)?;
        let path = dir.join(socket_name('s'));
        let fd = bound_socket(&path, name)?;
        let descriptor = FileDescriptor::non_owning_new(fd.as_raw_fd()).ok_or_else(|| TransportError::Failed {
            op: "wrapping a socket",
            service: name.to_owned(),
            detail: "invalid file descriptor".into(),
        })?;
        generation.bump(); // publishers re-read the directory before their next send
        Ok(UdsSubscriber {
            name: name.to_owned(),
            dir,
            path,
            fd,
            descriptor,
            generation,
            pending: RefCell::new(VecDeque::new()),
        })
    }

    fn try_receive(&self) -> Result<Received<T>, TransportError> {
        let mut buf = [0u8; MAX_MESSAGE];
        loop {
            // SAFETY: `buf` is a writable buffer of its length; the fd is open. MSG_TRUNC makes the result
            // the datagram's real length, so an oversized one is recognised.
            let n = unsafe {
                libc::recv(
                    self.fd.as_raw_fd(),
                    buf.as_mut_ptr().cast(),
                    buf.len(),
                    libc::MSG_DONTWAIT | libc::MSG_TRUNC,
                )
            };
            if n >= 0 {
                let n = n as usize;
                return Ok(match (n <= buf.len()).then(|| T::from_bytes(&buf[..n])).flatten() {
                    Some(msg) => Received::Message(msg),
                    None => Received::Malformed,
                });
            }
            let e = io::Error::last_os_error();
            match e.raw_os_error() {
                Some(libc::EINTR) => continue,
                Some(libc::EAGAIN) => return Ok(Received::Empty),
                _ => return Err(io_failed("receiving", &self.name, e)),
            }
        }
    }
}

impl<T: Message> SubscribePort<T> for UdsSubscriber<T> {
    fn receive_sourced(&self, out: &mut Vec<T>, origins: &mut Vec<u128>) -> Result<TopicEvents, TransportError> {
        let before = out.len();
        let events = self.receive_into(out)?;
        origins.resize(origins.len() + out.len() - before, 0);
        Ok(events)
    }

    fn publisher_alive(&self, _origin: u128) -> Result<bool, TransportError> {
        Ok(true)
    }

    fn receive_into(&self, out: &mut Vec<T>) -> Result<TopicEvents, TransportError> {
        let mut events = TopicEvents::default();
        let mut pending = self.pending.borrow_mut();
        events.samples += pending.len() as u64;
        for (m, in_hand_ns) in pending.drain(..) {
            events.in_hand_ns = in_hand_ns;
            out.push(m);
        }
        loop {
            match self.try_receive()? {
                Received::Message(m) => {
                    events.in_hand_ns = now_ns();
                    events.samples += 1;
                    out.push(m);
                }
                Received::Malformed => events.other += 1,
                Received::Empty => return Ok(events),
            }
        }
    }

    fn consume_wakeups(&self) -> Result<TopicEvents, TransportError> {
        // The datagrams are the wake-ups: nothing to consume apart from them.
        Ok(TopicEvents::default())
    }

    fn has_samples(&self) -> Result<bool, TransportError> {
        let mut pending = self.pending.borrow_mut();
        if !pending.is_empty() {
            return Ok(true);
        }
        loop {
            match self.try_receive()? {
                Received::Message(m) => {
                    pending.push_back((m, now_ns()));
                    return Ok(true);
                }
                Received::Malformed => continue,
                Received::Empty => return Ok(false),
            }
        }
    }

    fn block(&self, timeout: Duration) -> Result<(), TransportError> {
        if !self.pending.borrow().is_empty() {
            return Ok(());
        }
        let mut pfd = libc::pollfd { fd: self.fd.as_raw_fd(), events: libc::POLLIN, revents: 0 };
        let ts = libc::timespec {
            tv_sec: timeout.as_secs().min(i64::MAX as u64) as libc::time_t,
            tv_nsec: timeout.subsec_nanos() as libc::c_long,
        };
        // SAFETY: one valid pollfd; a valid timespec; no signal mask change.
        let rc = unsafe { libc::ppoll(&mut pfd, 1, &ts, core::ptr::null()) };
        if rc < 0 {
            let e = io::Error::last_os_error();
            // A signal: return, the caller checks for a termination request.
            if e.raw_os_error() != Some(libc::EINTR) {
                return Err(io_failed("waiting", &self.name, e));
            }
        }
        Ok(())
    }

    fn file_descriptor(&self) -> &FileDescriptor {
        &self.descriptor
    }

    fn publisher_count(&self) -> Result<usize, TransportError> {
        live_sockets(&self.dir, 'p', &self.name)
    }
}

impl<T: Message> Drop for UdsSubscriber<T> {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
        self.generation.bump();
    }
}

/// Removes the socket files of dead processes (and empty topic directories) under [`base_dir`]; returns
/// how many files were removed. What a launcher calls after a crash, like iceoryx2's dead-node cleanup.
pub fn cleanup_stale() -> usize {
    let Ok(topics) = std::fs::read_dir(base_dir()) else { return 0 };
    let mut removed = 0;
    for topic in topics.filter_map(Result::ok) {
        let Ok(files) = std::fs::read_dir(topic.path()) else { continue };
        for f in files.filter_map(Result::ok) {
            let name = f.file_name();
            let Some(name) = name.to_str() else { continue };
            if (name.starts_with("s.") || name.starts_with("p.")) && pid_of(name).is_some_and(|p| !alive(p)) {
                removed += usize::from(std::fs::remove_file(f.path()).is_ok());
            }
        }
    }
    removed
}
