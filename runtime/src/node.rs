//! The node runtime: one event loop that every uavloc process runs its handler on.
//!
//! A process opens a [`Node`] (its link, domain, instance id, control channel, counters and summary),
//! makes its topics on the node's link, and hands [`Node::run`] the subscribers to wait on and a
//! [`Handler`]. The loop waits in one iceoryx2 `WaitSet` — the subscribers and the control topic as
//! notification attachments, the idle wake-up ([`IDLE_WAKEUP`]) as an interval attachment and the
//! handler's next deadline ([`Handler::deadline`]) as a one-shot interval attachment — busy-polling first
//! as the `--wait` policy says; the deadline is attached only when the wait is about to block (attaching
//! costs iceoryx2 four system calls, which a message caught by the busy poll never pays). An observer
//! off the control loop (the monitor, [`Node::drain_every`]) instead sleeps a fixed period between
//! wake-ups while messages stream in. Per wake-up it
//!
//! 1. reads the control topic: a rejected message is counted and logged, a shutdown ends the loop
//!    ([`Ended::Shutdown`]), a take-over by a newer instance of the same role sets the hand-over step,
//!    anything else goes to [`Handler::on_control`];
//! 2. calls [`Handler::on_wake`], which drains its inputs ([`Node::receive`] validates and counts) and
//!    publishes its answers; a polling process then yields its core once (a process it just sent to on
//!    the same core runs at once);
//! 3. ends the loop with [`Ended::HandedOver`] once the handler has answered every step before the
//!    hand-over step, and with [`Ended::Interrupted`] on SIGINT/SIGTERM (a blocking wait or a drain's
//!    sleep ends on the signal at once; a polling loop checks for it after each wake-up).
//!
//! The take-over side of a swap is [`Node::take_over`]; the hand-over side is [`Node::hands_over`] (a
//! handler asks it before answering a step). Joining the domain ([`Node::join`], as a [`Join`] policy
//! says; then `ready` to the supervisor) and the exit codes are the node's too ([`crate::exit`],
//! [`crate::supervisor`]), so no process repeats them.

use std::fmt;
use std::rc::Rc;
use std::time::{Duration, Instant};

use protocol::control::{instance_id_at, is_newer};
use protocol::services::{self, Domain};
use protocol::{
    Admitted, Control, ControlChannel, ControlKind, Link, Measurement, MeasurementGate, Message, RejectionCounter,
    TopicSubscriber, TransportError, WaitMode, WaitPolicy, Waitable, now_ns,
};

use crate::{NodeArgs, NodeSummary, ProcessError, SupervisorLine};

/// The longest a wait lasts without a message or a deadline (an interval attachment): the loop then
/// re-checks for a termination request that arrived between two waits (a signal during a wait
/// interrupts it at once).
pub const IDLE_WAKEUP: Duration = Duration::from_secs(1);

/// What a handler tells the loop after a wake-up or a control message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flow {
    /// Wait for the next wake-up.
    Continue,
    /// End the loop ([`Ended::Stopped`], or [`Ended::HandedOver`] after [`Node::hands_over`]).
    Stop,
}

/// Why [`Node::run`] returned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ended {
    /// SIGINT/SIGTERM.
    Interrupted,
    /// A shutdown on the control topic.
    Shutdown,
    /// A newer instance took over from this step; this one answered every step before it.
    HandedOver(u64),
    /// The handler said [`Flow::Stop`].
    Stopped,
}

/// How a process joins its domain ([`Node::join`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Join {
    /// A hello, and a request to replay from this step ([`ControlKind::IN_FLIGHT`]: the step in flight,
    /// whose message a predecessor may have taken with it; the monitor: the first step it lacks). At the
    /// start of a launch nobody answers it (emitter-sim is not there yet).
    Replay(u64),
    /// A hello only (emitter-sim, which is the one that replays).
    Hello,
    /// Nothing yet: a swapped-in process announces its take-over once it knows the step
    /// ([`Node::take_over`]).
    TakeOver,
}

/// A process's part of the event loop: messages in, messages out.
pub trait Handler {
    /// Handles one wake-up: drains the inputs, publishes the answers.
    fn on_wake(&mut self, node: &mut Node) -> Result<Flow, ProcessError>;

    /// A valid control message the runtime does not act on itself (hello, progress, an older instance's
    /// take-over, …).
    fn on_control(&mut self, _node: &mut Node, _msg: &Control) -> Result<Flow, ProcessError> {
        Ok(Flow::Continue)
    }

    /// When to be woken without a message (e.g. a staleness deadline); `None`: only by messages.
    fn deadline(&self) -> Option<Instant> {
        None
    }

    /// The last step this handler answered (the hand-over waits for the step before the take-over).
    fn last_answered(&self) -> Option<u64> {
        None
    }
}

/// One process on the pipeline: its link, domain, identity, control channel, counters and summary.
#[derive(Debug)]
pub struct Node {
    link: Link,
    domain: Domain,
    control: Rc<ControlChannel>,
    policy: WaitPolicy,
    supervised: bool,
    quiet: bool,
    counter: RejectionCounter,
    summary: NodeSummary,
    seq: u64,
    handover: Option<u64>,
    /// The rejection count last announced ([`ControlKind::Status`]).
    rejected_reported: u64,
    /// The instances of another run this one told to leave ([`ControlKind::Run`]).
    told_to_leave: Vec<u64>,
    /// An observer's drain period ([`Node::drain_every`]).
    drain_every: Option<Duration>,
    /// The process whose end stops this one (`--watch-pid`), and when it was last looked at.
    watched: Option<Watched>,
    /// The rate of rejection lines ([`crate::LogBudget`]).
    log_budget: crate::LogBudget,
}

/// Logs a rejection line of `role` on stderr within `budget` (a flood is summarised, the counts stay
/// exact: see [`crate::LogBudget`]).
fn log_rejection(budget: &mut crate::LogBudget, role: &str, line: impl FnOnce() -> String) {
    if let crate::Admit::Log { unlogged } = budget.admit(Instant::now()) {
        if unlogged > 0 {
            protocol::log_line!("{role}: … and {unlogged} more rejected messages, counted but not logged (a flood)");
        }
        protocol::log_line!("{role}: {}", line());
    }
}

/// A process watched for its end (`--watch-pid`): through a pidfd (immune to the pid's reuse), else
/// `kill(pid, 0)`.
#[derive(Debug)]
struct Watched {
    pid: u32,
    pidfd: Option<std::os::fd::OwnedFd>,
    looked: Option<Instant>,
}

impl Watched {
    fn open(pid: u32) -> Self {
        // SAFETY: pidfd_open(2) takes a pid and flags and returns a new descriptor or −1; nothing is
        // borrowed. The descriptor is owned from here.
        let fd = unsafe { libc::syscall(libc::SYS_pidfd_open, pid as libc::pid_t, 0) };
        let pidfd = (fd >= 0).then(|| {
            // SAFETY: `fd` is a descriptor pidfd_open just returned, owned by nobody else.
            unsafe { <std::os::fd::OwnedFd as std::os::fd::FromRawFd>::from_raw_fd(fd as i32) }
        });
        Watched { pid, pidfd, looked: None }
    }

    /// Whether the watched process has ended — looked at no more than once per [`IDLE_WAKEUP`] (a
    /// system call, kept off the per-message path).
    fn ended(&mut self, now: Instant) -> bool {
        if self.looked.is_some_and(|at| now.saturating_duration_since(at) < IDLE_WAKEUP) {
            return false;
        }
        self.looked = Some(now);
        match &self.pidfd {
            Some(fd) => {
                let mut p = libc::pollfd { fd: std::os::fd::AsRawFd::as_raw_fd(fd), events: libc::POLLIN, revents: 0 };
                // SAFETY: one valid pollfd, a zero timeout.
                unsafe { libc::poll(&mut p, 1, 0) > 0 && p.revents & libc::POLLIN != 0 }
            }
            None => {
                // SAFETY: kill(2) with signal 0 only checks that the process exists.
                let gone = unsafe { libc::kill(self.pid as libc::pid_t, 0) } != 0;
                gone && std::io::Error::last_os_error().raw_os_error() == Some(libc::ESRCH)
            }
        }
    }
}

/// What a wait (or a drain's sleep) means for the loop: SIGINT/SIGTERM ends it, another error fails it.
fn ended_by(waited: Result<(), TransportError>) -> Result<Option<Ended>, ProcessError> {
    match waited {
        Ok(()) => Ok(None),
        Err(TransportError::Interrupted) => Ok(Some(Ended::Interrupted)),
        Err(e) => Err(e.into()),
    }
}

impl Node {
    /// Opens the node of `role` in the domain of `args` (default: `$UAVLOC_DOMAIN`, else `uavloc`) on
    /// its link; `Ok(None)` when SIGINT/SIGTERM came while it opened (the process then ends cleanly).
    pub fn open(role: &'static str, args: &NodeArgs) -> Result<Option<Self>, ProcessError> {
        let NodeArgs { domain, link, quiet, supervised, watch_pid } = args;
        protocol::transport::quiet_logs();
        let domain = Domain::resolve_named(domain.as_deref()).map_err(ProcessError::Input)?;
        let opened = Link::open(link.transport, &services::node_name(&domain, role))?;
        // The first wait installs iceoryx2's SIGINT/SIGTERM handler, so a signal ends the loop cleanly.
        if opened.interrupted() {
            return Ok(None);
        }
        let started_ns = now_ns();
        let instance = instance_id_at(started_ns);
        let control = Rc::new(ControlChannel::open(&opened, &domain, role, instance, started_ns)?);
        Ok(Some(Self {
            link: opened,
            domain,
            control,
            policy: link.policy(),
            supervised: *supervised,
            quiet: *quiet,
            counter: RejectionCounter::new(),
            summary: NodeSummary::new(role, instance),
            // Sequence numbers start at the monotonic clock: a restarted process numbers above its
            // predecessor.
            seq: started_ns,
            handover: None,
            rejected_reported: 0,
            told_to_leave: Vec::new(),
            drain_every: None,
            watched: watch_pid.map(Watched::open),
            log_budget: crate::LogBudget::default(),
        }))
    }

    /// Makes this node an observer off the control loop: while messages stream in it sleeps `period`
    /// between wake-ups and then takes everything that came, instead of being woken (or busy-polling) per
    /// message; once a period brings nothing it waits as its `--wait` policy says again. So it no longer
    /// competes with the loop for a core message by message (a drain takes one for a burst instead), and
    /// its senders never pay a wake-up for it (an iceoryx2 listener that is not about to block costs its
    /// notifiers no system call): what the monitor does. `period` must leave the subscriber buffers room
    /// for what comes meanwhile.
    pub fn drain_every(&mut self, period: Duration) {
        self.drain_every = Some(period);
    }

    /// The link (to create topics on).
    pub fn link(&self) -> &Link {
        &self.link
    }

    /// The domain.
    pub fn domain(&self) -> &Domain {
        &self.domain
    }

    /// The role.
    pub fn role(&self) -> &'static str {
        self.summary.role
    }

    /// This instance's id.
    pub fn instance(&self) -> u64 {
        self.summary.instance
    }

    /// Whether `--quiet` is off.
    pub fn verbose(&self) -> bool {
        !self.quiet
    }

    /// Whether a supervisor reads this process's stdout.
    pub fn supervised(&self) -> bool {
        self.supervised
    }

    /// The wait policy (`--wait`, `--spin-us`).
    pub fn policy(&self) -> WaitPolicy {
        self.policy
    }

    /// The control channel.
    pub fn control(&self) -> &ControlChannel {
        &self.control
    }

    /// The validation counters of every message received.
    pub fn counter(&mut self) -> &mut RejectionCounter {
        &mut self.counter
    }

    /// What this node did (the counts every data process reports).
    pub fn summary(&mut self) -> &mut NodeSummary {
        &mut self.summary
    }

    /// Sets the run this process belongs to: its scenario's fingerprint (`model::Scenario::run_id`), before
    /// it opens its topics and joins. Every message it sends carries it (a control message in full, a data
    /// message as its header's [`protocol::run_tag`]); it refuses to run beside a process of another run
    /// ([`ControlKind::Run`]), and rejects data messages of another run (`other_run`) — also those a
    /// process of another run that joined while its role was absent sends before it is told to leave.
    pub fn set_run(&mut self, run: u64) {
        self.control.set_run(run);
        // The data messages carry the run too (the topics are opened after this) and those of another run
        // are rejected.
        let tag = protocol::run_tag(run);
        self.link.set_run(tag);
        self.counter.set_run(tag);
    }

    /// Publishes a control message of `kind` (e.g. a hello from `step`).
    pub fn announce(&self, kind: ControlKind, step: u64, detail: &str) -> Result<(), ProcessError> {
        Ok(self.control.send(kind, step, detail)?)
    }

    /// Joins the domain as `how` says (`detail`: free text on the control messages, e.g. the planner's
    /// solver), then tells the supervisor this process is ready (its ports exist).
    pub fn join(&self, how: Join, detail: &str) -> Result<(), ProcessError> {
        if how != Join::TakeOver {
            self.refuse_a_second_instance()?;
        }
        match how {
            Join::Replay(from) => {
                self.announce(ControlKind::Hello, 0, detail)?;
                self.announce(ControlKind::Replay, from, detail)?;
            }
            Join::Hello => self.announce(ControlKind::Hello, 0, detail)?,
            Join::TakeOver => {}
        }
        crate::tell(self.supervised, &SupervisorLine::Ready);
        Ok(())
    }

    /// Refuses to join a domain where another process of this role is running ([`ProcessError::Input`],
    /// exit code 2): both would answer every step, and the one with the higher sequence numbers (the
    /// newer) would win silently. Replacing a running process is a take-over (`uavloc swap`). A process
    /// that crashed or was killed is no obstacle: its node is dead.
    fn refuse_a_second_instance(&self) -> Result<(), ProcessError> {
        match self.other_instances()?.first() {
            None => Ok(()),
            Some(pid) => Err(ProcessError::Input(format!(
                "a {role} is already running in domain {domain} (pid {pid}); two would both answer every step. \
                 Stop it or choose another --domain (a running planner or estimator is replaced with `uavloc \
                 swap`)",
                role = self.role(),
                domain = self.domain
            ))),
        }
    }

    /// The pids of the other live processes of this role in the domain (a killed one's node is dead, not
    /// listed): the instance a take-over waits for, or the one a second instance would double.
    pub fn other_instances(&self) -> Result<Vec<u32>, ProcessError> {
        let name = services::node_name(&self.domain, self.role());
        let listed = protocol::resources::list(&self.domain).map_err(ProcessError::Failed)?;
        Ok(listed.alive_pids(&name).into_iter().filter(|p| *p != std::process::id()).collect())
    }

    /// Logs a line on stderr, prefixed with the role, unless `--quiet`.
    pub fn say(&self, what: fmt::Arguments<'_>) {
        if !self.quiet {
            protocol::log_line!("{}: {what}", self.role());
        }
    }

    /// Logs a line on stderr, prefixed with the role, even with `--quiet` (a rejection, a failure).
    pub fn warn(&self, what: fmt::Arguments<'_>) {
        protocol::log_line!("{}: {what}", self.role());
    }

    /// The next sequence number of this instance's data messages.
    pub fn next_seq(&mut self) -> u64 {
        self.seq += 1;
        self.seq
    }

    /// The valid messages waiting on `sub` (validated against `last_seq`, the last accepted sequence
    /// number of that topic) and when they were received (CLOCK_MONOTONIC ns); each rejected one is
    /// counted and logged ("rejected a `what`: …"), each accepted one counted.
    ///
    /// The receive time is when the last of them was in hand ([`TopicSubscriber::receive_stamped`]: an
    /// iceoryx2 sample once taken, before its payload is copied out; a datagram once received), not when
    /// the wake-up began: a message published in between (the wake-up was for one already taken) would
    /// otherwise be stamped as received before it was sent, and its latency sample lost.
    pub fn receive<T: Message>(
        &mut self,
        sub: &TopicSubscriber<T>,
        last_seq: &mut Option<u64>,
        what: &str,
    ) -> Result<(Vec<T>, u64), ProcessError> {
        self.receive_checked(sub, what, |counter, m| counter.check(m, last_seq))
    }

    /// The messages waiting on `sub` that pass `check` (which counts them in the node's counter) and when
    /// they were received; each rejected one is counted and logged ("rejected {what}: …", within the log
    /// budget), each accepted one counted.
    fn receive_checked<T: Message>(
        &mut self,
        sub: &TopicSubscriber<T>,
        what: &str,
        mut check: impl FnMut(&mut RejectionCounter, &T) -> Result<(), protocol::Rejection>,
    ) -> Result<(Vec<T>, u64), ProcessError> {
        let (mut out, received_ns) = sub.receive_stamped()?;
        out.retain(|m| match check(&mut self.counter, m) {
            Ok(()) => true,
            Err(r) => {
                self.summary.rejected += 1;
                log_rejection(&mut self.log_budget, self.summary.role, || format!("rejected {what}: {r}"));
                false
            }
        });
        self.summary.accepted += out.len() as u64;
        Ok((out, received_ns))
    }

    /// [`receive`](Self::receive) for the measurement topic: each message also through `gate` (one source
    /// per run, one measurement per step: [`protocol::source`]); a successor source is logged.
    pub fn receive_measurements(
        &mut self,
        sub: &TopicSubscriber<Measurement>,
        gate: &mut MeasurementGate,
    ) -> Result<(Vec<Measurement>, u64), ProcessError> {
        let (batch, origins, received_ns) = sub.receive_sourced()?;
        let mut out = Vec::with_capacity(batch.len());
        for (m, origin) in batch.into_iter().zip(origins) {
            match gate.check(&mut self.counter, &m, origin, |s| sub.publisher_alive(s).unwrap_or(true)) {
                Ok(admitted) => {
                    if let Admitted::Successor { .. } = admitted {
                        self.say(format_args!("a new measurement source took over at step {}", m.header.step));
                    }
                    out.push(m);
                }
                Err(r) => {
                    self.summary.rejected += 1;
                    if let Some(line) = gate.log_line(&r) {
                        log_rejection(&mut self.log_budget, self.summary.role, || line);
                    }
                }
            }
        }
        self.summary.accepted += out.len() as u64;
        Ok((out, received_ns))
    }

    /// The measurements the monitor gives again on `sub` ([`protocol::services::measurement_replay`]),
    /// each validated as a copy ([`MeasurementGate::check_copy`]).
    pub fn receive_measurement_copies(
        &mut self,
        sub: &TopicSubscriber<Measurement>,
        gate: &mut MeasurementGate,
    ) -> Result<(Vec<Measurement>, u64), ProcessError> {
        self.receive_checked(sub, "a measurement given again", |counter, m| gate.check_copy(counter, m))
    }

    /// Announces that this instance takes over from `from_step` (a swap): the control topic, the
    /// supervisor's `takeover` line, the summary and the log.
    pub fn take_over(&mut self, from_step: u64, detail: &str) -> Result<(), ProcessError> {
        self.summary.took_over_at = Some(from_step);
        self.control.send(ControlKind::TakeOver, from_step, detail)?;
        crate::tell(self.supervised, &SupervisorLine::TakeOver { from_step });
        self.say(format_args!("taking over from step {from_step}"));
        Ok(())
    }

    /// Whether a newer instance takes over at or before `step` (this one must not answer it); records the
    /// hand-over in the summary when so.
    pub fn hands_over(&mut self, step: u64) -> bool {
        match self.handover {
            Some(f) if step >= f => {
                self.summary.handed_over_at = Some(f);
                true
            }
            _ => false,
        }
    }

    /// Whether the hand-over is due: a newer instance takes over from `f` and this one answered `f − 1`.
    fn handover_due(&mut self, last_answered: Option<u64>) -> Option<u64> {
        let f = self.handover?;
        last_answered.is_some_and(|l| l + 1 >= f).then(|| {
            self.summary.handed_over_at = Some(f);
            f
        })
    }

    /// The control messages since the last wake-up; `Some` when one ends the loop.
    fn on_control(&mut self, handler: &mut dyn Handler) -> Result<Option<Ended>, ProcessError> {
        for msg in self.control.receive(&mut self.counter)? {
            let c = match msg {
                Ok(c) => c,
                Err(r) => {
                    self.summary.rejected += 1;
                    self.warn(format_args!("rejected a control message: {r}"));
                    continue;
                }
            };
            if self.of_another_run(&c)? {
                continue;
            }
            if c.kind() == Some(ControlKind::Shutdown) {
                return Ok(Some(Ended::Shutdown));
            }
            if is_newer(&c, ControlKind::TakeOver, self.role(), self.control.started_ns()) {
                let f = c.header.step;
                self.say(format_args!("a newer {} ({}) takes over from step {f}", self.role(), c.detail()));
                self.handover = Some(self.handover.map_or(f, |h| h.min(f)));
                continue;
            }
            if handler.on_control(self, &c)? == Flow::Stop {
                return Ok(Some(self.stopped()));
            }
        }
        Ok(None)
    }

    /// Whether `c` comes from a process of another run (both senders name their run, and the runs differ;
    /// see [`ControlKind::Run`]). One that joined before this one wins: this one leaves
    /// ([`ProcessError::Input`], exit code 2). One that joined after it is told once to leave, and its
    /// messages are ignored (`true`) — a replay it asks for, for one.
    fn of_another_run(&mut self, c: &Control) -> Result<bool, ProcessError> {
        let mine = self.control.run();
        if c.run == 0 || mine == 0 || c.run == mine {
            return Ok(false);
        }
        let theirs = c.role().unwrap_or("process");
        if c.started_ns < self.control.started_ns() {
            return Err(ProcessError::Input(format!(
                "domain {} runs another scenario: the {theirs} (instance {:#x}) that joined before this {} runs \
                 scenario {:016x}, this one {mine:016x}; give every process of a domain the same --scenario, --steps \
                 and --seed",
                self.domain,
                c.instance,
                self.role(),
                c.run
            )));
        }
        if !self.told_to_leave.contains(&c.instance) {
            self.told_to_leave.push(c.instance);
            self.warn(format_args!(
                "a {theirs} of another scenario ({:016x}, instance {:#x}) joined domain {}; told it to leave",
                c.run, c.instance, self.domain
            ));
            self.announce(ControlKind::Run, c.instance, "")?;
        }
        Ok(true)
    }

    /// Tells the domain how many messages this process has rejected, when that changed since it last
    /// did ([`ControlKind::Status`]: the monitor logs it, the live view shows it).
    fn report_rejections(&mut self) -> Result<(), ProcessError> {
        let total = self.counter.total();
        if total != self.rejected_reported {
            self.rejected_reported = total;
            self.announce(ControlKind::Status, total, "rejected")?;
        }
        Ok(())
    }

    fn stopped(&self) -> Ended {
        self.summary.handed_over_at.map_or(Ended::Stopped, Ended::HandedOver)
    }

    /// Runs `handler` over the wake-ups of `inputs` and the control topic until it stops, hands over, a
    /// shutdown comes or SIGINT/SIGTERM (see the module docs).
    pub fn run(&mut self, inputs: &[&dyn Waitable], handler: &mut dyn Handler) -> Result<Ended, ProcessError> {
        // The guards borrow this handle of the control channel (declared first, dropped last), so the
        // handler may use the node meanwhile.
        let control = Rc::clone(&self.control);
        let waitset = protocol::transport::waitset()?;
        let attach_failed = |e| ProcessError::failed_because("attaching to the WaitSet", e);
        let mut guards = Vec::with_capacity(inputs.len() + 2);
        for input in inputs {
            guards.push(waitset.attach_notification(*input).map_err(attach_failed)?);
        }
        guards.push(waitset.attach_notification(control.subscriber()).map_err(attach_failed)?);
        let _idle = waitset.attach_interval(IDLE_WAKEUP).map_err(attach_failed)?;
        let waited: Vec<&dyn Waitable> =
            inputs.iter().copied().chain(std::iter::once(control.subscriber() as &dyn Waitable)).collect();
        let policy = self.policy;
        // One wait as the `--wait` policy says: spin, then block until a message, the deadline (`left`
        // from now) or a signal. Only a wait that blocks sets up its deadline: attaching one costs
        // iceoryx2 four system calls (it reads the epoll capacity from /proc), which a message caught by
        // the spin never pays.
        let wait = |left: Option<Duration>| -> Result<Option<Ended>, ProcessError> {
            let (spin, block) = policy.split(left.unwrap_or(IDLE_WAKEUP).min(IDLE_WAKEUP));
            if protocol::poll(spin, &waited)? || block.is_zero() {
                return Ok(None);
            }
            // The deadline is a one-shot attachment of this wait (iceoryx2 rounds it up to whole
            // milliseconds; a message wakes the wait at once).
            let _deadline = match left {
                Some(left) => Some(
                    waitset
                        .attach_interval(left.saturating_sub(spin).max(Duration::from_micros(1)))
                        .map_err(attach_failed)?,
                ),
                None => None,
            };
            ended_by(protocol::wait_attached(&waitset, &waited))
        };
        // Whether messages are streaming in (an observer then drains every period instead of waiting).
        let mut streaming = false;
        loop {
            let left = handler.deadline().map(|d| d.saturating_duration_since(Instant::now()));
            if let (Some(period), true) = (self.drain_every, streaming) {
                if let Some(ended) = ended_by(self.link.sleep(left.map_or(period, |l| l.min(period))))? {
                    return Ok(ended);
                }
                streaming = protocol::poll(Duration::ZERO, &waited)?;
            } else {
                if let Some(ended) = wait(left)? {
                    return Ok(ended);
                }
                streaming = self.drain_every.is_some();
            }
            if let Some(ended) = self.on_control(handler)? {
                return Ok(ended);
            }
            if let Some(w) = &mut self.watched
                && w.ended(Instant::now())
            {
                let pid = w.pid;
                self.warn(format_args!("the launch that runs this domain (pid {pid}) has ended; stopping"));
                return Ok(Ended::Shutdown);
            }
            if let Some(f) = self.handover_due(handler.last_answered()) {
                return Ok(Ended::HandedOver(f));
            }
            if handler.on_wake(self)? == Flow::Stop {
                return Ok(self.stopped());
            }
            // A polling process hands its core over once it has handled the wake-up: a process it just sent
            // to that polls on the same core runs now, not after this one's bookkeeping and first poll (its
            // polls yield too; a blocking one was woken by the kernel).
            if policy.mode != WaitMode::Block {
                std::thread::yield_now();
            }
            self.report_rejections()?;
            if let Some(f) = self.handover_due(handler.last_answered()) {
                return Ok(Ended::HandedOver(f));
            }
            // SIGINT/SIGTERM: a blocking wait and a drain's sleep end on one at once; a polling wait is
            // checked here, after the messages it found (off their hop: the check takes a lock).
            if self.link.interrupted() {
                return Ok(Ended::Interrupted);
            }
        }
    }

    /// The summary at the end (CPU time filled in), with the hand-over logged.
    pub fn finish(mut self) -> NodeSummary {
        if let Some(f) = self.summary.handed_over_at {
            self.say(format_args!("handed over to the newer {} at step {f}", self.role()));
        }
        self.summary.cpu_s = crate::cpu_seconds();
        self.summary
    }
}
