//! The `emitter-sim` process: the world publishes the truth and a noisy measurement of step k, takes the
//! planner's command for step k, flies it, and goes on with k + 1 — in lock-step or in real time.
//!
//! # Modes (`--mode`)
//!
//! - **lockstep** (default): the next step starts as soon as the command for the current one arrives.
//!   Fast and deterministic: for benchmarks and tests, and the exact reproduction of `uavloc simulate`.
//! - **realtime**: the world keeps its own clock. Step k is published at `t0 + k·dt/X` (`dt` the
//!   scenario's interval, `X` = `--time-scale`; `t0` the publication of step 0 on the monotonic clock;
//!   each step is scheduled from t0, so delays do not accumulate). The command for step k is applied if
//!   it arrives before step k + 1 is due; otherwise the step is *missed*: the UAVs keep their headings
//!   (fly straight on, the arc kinematics with zero turn), the miss is counted (`missed_commands`) and
//!   logged, and the truth of step k + 1 tells the monitor ([`CommandOutcome::Missed`]). A command for a
//!   step whose time is over is ignored and counted (`late_commands`). Waiting is event-driven with the
//!   step's deadline as the timeout (iceoryx2 WaitSet; no busy loop). If every command arrives in time
//!   the run equals the lock-step one.
//!
//! Per step k = 0, 1, …, `steps − 1`:
//! 0. (lock-step, `--monitor-window N` > 0, once a monitor has reported its progress on the control topic
//!    — [`ControlKind::Progress`], the first step it lacks) wait while the monitor lacks step k − N or an
//!    older one, replaying to it from the checkpoint step at or below that step when it makes no progress
//!    for `--retry-interval-ms` (it is restarting, or lost a message); give up after
//!    `--command-timeout-s` without progress. So a monitor restarted again and again, or starved of CPU,
//!    stays within reach of a restarted emitter-sim's replays (see [`runtime::checkpoint`]);
//! 1. publish the [`Truth`] of step k (monitor only; with the outcome of step k − 1's command), then the
//!    [`Measurement`] of step k: UAV positions, noisy range differences ([`World::measure`], drawn from
//!    the stream (seed, k) — the numbers of `uavloc simulate`), range σ and current headings; it carries
//!    the stamps of the command flown in the interval before it;
//! 2. wait for a valid [`Command`] with `step == k` (invalid ones are counted and ignored, commands for
//!    other steps are ignored) — in real-time mode at most until step k + 1 is due;
//! 3. [`World::apply`] its headings (a command the world refuses, e.g. with the wrong UAV count, counts
//!    as rejected and the wait goes on) — in real-time mode, without a command, the current headings.
//!
//! After the last planned step it publishes the truth and measurement of step `steps` (recorded by the
//! monitor, not planned) and exits 0.
//!
//! # Replays: how the pipeline survives a restarted process
//!
//! emitter-sim keeps the truth and measurement of the last [`HISTORY_STEPS`] steps it published (older
//! ones are forgotten, so its memory does not grow with the run). It *replays* steps `from..=k`
//! — publishes them again, same step, same data, new sequence numbers, one step at a time, each after the
//! command of the previous one came back (that command is not applied: the world is already past it) —
//! when
//! - a process announces itself on the control topic ([`ControlKind::Hello`]: an estimator or planner
//!   restarted after a crash asks for the step after its checkpoint, or for step 0 without one, since
//!   their state is rebuilt from the run; a restarted monitor asks for the first step missing from its
//!   log), or
//! - (lock-step only) the command of step k has not come `--retry-interval-ms` after the step was
//!   (re)published: a process died or lost the message; the steps from the checkpoint step at or below k
//!   are replayed.
//!
//! A request for a step older than the history is refused: emitter-sim stops with an error naming the
//! steps (a process restarted without its checkpoint cannot rejoin a run longer than the history).
//!
//! The estimator and the planner answer a message they have seen before with the answer they gave
//! before, so a replay costs a hop per step and changes nothing; a process that lost its state rebuilds
//! exactly the state it had. In lock-step mode it gives up (exit 1) when the command of a step has not
//! come after `--command-timeout-s` in all. In real-time mode a replay runs between the scheduled steps:
//! it pauses when the next step is due and goes on after it (up to the step current by then), and a
//! replayed step that gets no answer within `--retry-interval-ms` is sent again.
//!
//! A restarted emitter-sim starts from the older of the two world snapshots in its `--checkpoint` file
//! (the world before a checkpoint step c, written once the command of step c came back; see
//! [`runtime::checkpoint`]; with fewer than two, the run is young and it starts from step 0), else from
//! step 0: the world is deterministic, so it publishes exactly the
//! measurements of its predecessor, the estimator and planner answer them from what they kept, and the run
//! fast-forwards to where it was. (In real-time mode it starts the schedule again at that step: the steps
//! are flown again at the real-time rate, and a run that had missed steps is flown anew from there.)
//!
//! Before step 0 it waits until the pipeline is connected — at least `--min-subscribers` subscribers on
//! the measurement topic and a publisher (the planner) on the command topic — because a message
//! published before its subscriber exists is lost (the topics keep no history). SIGINT/SIGTERM, or a
//! [`ControlKind::Shutdown`], stop it cleanly (exit code 130).

use std::collections::{BTreeSet, VecDeque};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::{Args, ValueEnum};
use iceoryx2::prelude::*;
use model::load_scenario;
use protocol::control::instance_id_at;
use protocol::services::{self, Domain};
use protocol::transport::{Link, TopicPublisher, WaitMode, wait_any};
use protocol::{
    Command, CommandOutcome, ControlChannel, ControlKind, Measurement, Message, RejectionCounter, Stamps, Topic,
    TopicSubscriber, Truth, now_ns,
};
use runtime::SupervisorLine;
use runtime::checkpoint::{self, EMITTER_SNAPSHOTS, HISTORY_STEPS};

use crate::backpressure::MonitorProgress;
use crate::{Snapshot, World};

/// The role name (node name suffix, `uavloc process emitter-sim`).
pub const ROLE: &str = "emitter-sim";

/// Exit code when SIGINT/SIGTERM stopped the run before its end.
pub use runtime::EXIT_INTERRUPTED;

/// How long one blocking wait lasts at most before the loop re-checks for a termination request that
/// arrived between two waits (a signal during a wait interrupts it at once).
pub const IDLE_WAKEUP: Duration = Duration::from_secs(1);

/// How often the start-up wait re-checks whether the pipeline is connected.
pub const CONNECT_POLL: Duration = Duration::from_millis(2);

/// What `emitter-sim --help` shows after the flags.
pub const AFTER_HELP: &str = "\
emitter-sim publishes <domain>/truth and <domain>/measurement and subscribes to <domain>/command. Start
estimator, planner (and monitor) first, with the same --domain, --scenario, --steps and --seed;
emitter-sim waits until they are connected, runs steps 0..N (the last one is measured, not planned) and
exits 0.

Modes:
  --mode lockstep   the next step as soon as the command for the current one arrives (default): for
                    benchmarks and tests, and the exact reproduction of `uavloc simulate`.
  --mode realtime   step k is published at t0 + k*dt/X with X = --time-scale (dt = the scenario's
                    interval, 10 s in the paper; --time-scale 100 runs it in 0.1 s). A command that has
                    not arrived when the next step is due is missed: the UAVs fly straight on at their
                    headings, the step is counted in missed_commands and logged, a later command for it
                    is ignored (late_commands). With every command in time the run equals lock-step.

Examples:
  emitter-sim --domain lab1
  emitter-sim --domain lab1 --scenario scenarios/nominal.toml --steps 6 --seed 3 --min-subscribers 2
  emitter-sim --domain lab1 --mode realtime --time-scale 100";

/// How emitter-sim paces the run (`--mode`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, ValueEnum)]
pub enum Mode {
    /// The next step as soon as the command for the current one arrives (benchmarks, tests, exact
    /// reproduction of `uavloc simulate`).
    #[default]
    Lockstep,
    /// Step k at t0 + k·dt/X (X = --time-scale); a command that is not there when the next step is due is
    /// missed (the UAVs keep their headings).
    Realtime,
}

impl Mode {
    /// `"lockstep"` or `"realtime"`.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Lockstep => "lockstep",
            Mode::Realtime => "realtime",
        }
    }
}

impl EmitterSimArgs {
    /// The command line of these flags (see [`runtime::flags`]).
    pub fn to_flags(&self) -> Vec<String> {
        runtime::Flags::new()
            .opt("--domain", self.domain.as_deref())
            .extend(self.run.to_flags())
            .float("--command-timeout-s", self.command_timeout_s)
            .value("--retry-interval-ms", self.retry_interval_ms)
            .float("--connect-timeout-s", self.connect_timeout_s)
            .value("--min-subscribers", self.min_subscribers)
            .extend(self.link.to_flags())
            .value("--step-delay-ms", self.step_delay_ms)
            .value("--mode", self.mode.name())
            .float("--time-scale", self.time_scale)
            .path("--checkpoint", self.checkpoint.as_deref())
            .switch("--quiet", self.quiet)
            .switch("--linger", self.linger)
            .value("--monitor-window", self.monitor_window)
            .switch("--supervised", self.supervised)
            .into_vec()
    }
}

/// Checks a `--time-scale` value: finite and > 0.
pub fn check_time_scale(x: f64) -> Result<(), String> {
    if x.is_finite() && x > 0.0 {
        Ok(())
    } else {
        Err(format!("--time-scale must be a finite number > 0 (simulated seconds per real second, e.g. 100), got {x}"))
    }
}

/// The real time between two steps in real-time mode, `dt / time_scale`; an error (for `--time-scale`)
/// if that, or the whole run of `steps` steps, is not a valid duration (a time scale so small that the run
/// would last for ages).
pub fn step_interval(dt: f64, time_scale: f64, steps: usize) -> Result<Duration, String> {
    let seconds = dt / time_scale;
    Duration::try_from_secs_f64(seconds * steps as f64)
        .ok()
        .filter(|total| Instant::now().checked_add(*total).is_some())
        .and_then(|_| Duration::try_from_secs_f64(seconds).ok())
        .ok_or_else(|| {
            format!(
                "--time-scale {time_scale:e}: a step of {dt} s would last {seconds:e} s in real time; choose a larger \
                 time scale"
            )
        })
}

/// Flags of the emitter-sim process (`emitter-sim [FLAGS]` or `uavloc process emitter-sim [FLAGS]`).
#[derive(Args, Debug, Clone, PartialEq)]
pub struct EmitterSimArgs {
    /// Pipeline domain: prefix of every service name (default: $UAVLOC_DOMAIN, else "uavloc").
    #[arg(long, value_name = "NAME")]
    pub domain: Option<String>,
    /// The run: scenario, steps, seed.
    #[command(flatten)]
    pub run: runtime::RunArgs,
    /// Give up (exit 1) when the command for a step has not arrived after this many seconds.
    #[arg(long, value_name = "S", default_value_t = 10.0)]
    pub command_timeout_s: f64,
    /// Replay the run from step 0 when the command for a step has not arrived this many milliseconds
    /// after the step was published (a process died or lost it).
    #[arg(long, value_name = "MS", default_value_t = 1000)]
    pub retry_interval_ms: u64,
    /// Give up (exit 1) when the pipeline is not connected after this many seconds.
    #[arg(long, value_name = "S", default_value_t = 60.0)]
    pub connect_timeout_s: f64,
    /// Subscribers the measurement topic needs before step 0 (estimator, plus 1 for a monitor).
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub min_subscribers: usize,
    /// Transport and waiting.
    #[command(flatten)]
    pub link: runtime::LinkArgs,
    /// Wait this many milliseconds before each step after step 0 (slows a lock-step run down for a demo or
    /// a test; the results do not change). 0: lock-step at full speed. Lock-step mode only.
    #[arg(long, value_name = "MS", default_value_t = 0)]
    pub step_delay_ms: u64,
    /// Pacing: lockstep (the next step as soon as the command arrives; benchmarks, tests, exact
    /// reproduction of `uavloc simulate`) or realtime (step k at t0 + k·dt/X; a late command is missed and
    /// the UAVs keep their headings).
    #[arg(long, value_enum, value_name = "MODE", default_value_t = Mode::Lockstep)]
    pub mode: Mode,
    /// Real-time mode: simulated seconds per real second, > 0. A step lasts dt/X real seconds (the paper's
    /// 10 s interval takes 0.1 s at --time-scale 100). Ignored in lock-step mode.
    #[arg(long, value_name = "X", default_value_t = 1.0, allow_negative_numbers = true)]
    pub time_scale: f64,
    /// Checkpoint file: a world snapshot is written there every 256 steps, and a start that finds it (a
    /// restart in the same run) flies on from the oldest snapshot kept instead of from step 0. Remove it
    /// before a new run. (`uavloc launch` gives each process one in a fresh directory per launch.)
    #[arg(long, value_name = "FILE")]
    pub checkpoint: Option<PathBuf>,
    /// Print nothing but errors.
    #[arg(long)]
    pub quiet: bool,
    /// After the last step, stay: replay the run to a process that asks (a monitor that fell behind or
    /// was restarted while the run ended) until SIGINT/SIGTERM or a shutdown on the control topic, which
    /// end it normally (exit code 0). `uavloc launch` passes it and stops emitter-sim once the monitor has
    /// the whole run.
    #[arg(long)]
    pub linger: bool,
    /// Lock-step mode: do not publish step k while the monitor lacks step k − N or an older one (its
    /// progress comes on the control topic); when it makes no progress for --retry-interval-ms, replay to
    /// it from the checkpoint step at or below the first step it lacks; give up (exit 1) after
    /// --command-timeout-s without progress. A monitor restarted again and again then stays within reach
    /// of a restarted emitter-sim's replays. Must be below 256 (the checkpoint interval). 0: never wait for
    /// the monitor. No effect before a monitor has announced itself, nor in real-time mode.
    #[arg(long, value_name = "N", default_value_t = checkpoint::MONITOR_WINDOW)]
    pub monitor_window: u64,
    /// Under a launcher: print `ready` on stdout once connected, `finished` after the last step (with
    /// --linger), and `summary {json}` at exit.
    #[arg(long, hide = true)]
    pub supervised: bool,
}

pub use runtime::ProcessError;

/// What emitter-sim did, printed as its `summary` line.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct EmitterSummary {
    /// `"emitter-sim"`.
    pub role: &'static str,
    /// `"lockstep"` or `"realtime"`.
    pub mode: &'static str,
    /// Steps flown (intervals the UAVs flew: commands applied, plus missed steps in real-time mode).
    pub steps: u64,
    /// Measurements published.
    pub measurements: u64,
    /// Valid commands received (any step).
    pub accepted: u64,
    /// Invalid commands ignored (failed validation, or refused by the world).
    pub rejected: u64,
    /// Valid commands for another step than the one waited for (also the answers to replayed steps), but
    /// for missed steps (those are `late_commands`).
    pub ignored: u64,
    /// Real-time mode: steps whose command had not arrived when the next step was due (the UAVs kept their
    /// headings).
    pub missed_commands: u64,
    /// Real-time mode: commands that arrived for a missed step, after its time (ignored, not applied).
    pub late_commands: u64,
    /// Real-time mode: the largest delay of a step's publication behind its schedule, microseconds.
    pub max_lag_us: u64,
    /// Replays (see the module docs).
    pub replays: u64,
    /// Replays because a step's command was late.
    pub retries: u64,
    /// The step this instance started from (0, or a checkpoint's snapshot after a restart).
    pub started_at: u64,
    /// CPU time this process used, seconds.
    pub cpu_s: f64,
}

/// What emitter-sim writes to its `--checkpoint` file: the last world snapshots (oldest first), each with
/// whether the command of the step before it was missed.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Saved {
    /// At most [`EMITTER_SNAPSHOTS`], one every [`checkpoint::CHECKPOINT_EVERY`] steps.
    pub snapshots: Vec<(Snapshot, bool)>,
}

/// Waits until the measurement topic has `min_subscribers` subscribers and the command topic a
/// publisher, re-checking the topics' participant counts every [`CONNECT_POLL`].
fn wait_for_pipeline(
    link: &Link,
    measurements: &TopicPublisher<Measurement>,
    commands: &TopicSubscriber<Command>,
    domain: &Domain,
    args: &EmitterSimArgs,
) -> Result<(), ProcessError> {
    let start = Instant::now();
    loop {
        let subscribers = measurements.subscriber_count()?;
        let planners = commands.publisher_count()?;
        if subscribers >= args.min_subscribers && planners >= 1 {
            return Ok(());
        }
        if start.elapsed().as_secs_f64() > args.connect_timeout_s {
            return Err(ProcessError::Failed(format!(
                "the pipeline did not connect within {} s ({subscribers} of {} measurement subscribers, {planners} \
                 planner(s)); start estimator and planner with --domain {domain} --transport {}",
                args.connect_timeout_s,
                args.min_subscribers,
                link.kind()
            )));
        }
        link.sleep(CONNECT_POLL)?;
    }
}

/// The ports and the state of the lock-step loop.
struct Sim<'a> {
    args: &'a EmitterSimArgs,
    link: &'a Link,
    waitset: &'a WaitSet<ipc::Service>,
    truths: &'a TopicPublisher<Truth>,
    measurements: &'a TopicPublisher<Measurement>,
    commands: &'a TopicSubscriber<Command>,
    control: &'a ControlChannel,
    world: World,
    summary: EmitterSummary,
    counter: RejectionCounter,
    last_seq: Option<u64>,
    seq: u64,
    /// The truth and measurement of the last [`HISTORY_STEPS`] steps published, as first published.
    sent: VecDeque<(Truth, Measurement)>,
    /// The step of `sent[0]`.
    sent_base: u64,
    /// The command applied for the step being waited for, with its receive time.
    applied: Option<(Command, u64)>,
    /// The first step a process that joined asked to see again.
    replay_from: Option<u64>,
    /// Real-time mode: the next step of a replay in progress (paused when a step came due).
    replay_next: Option<u64>,
    /// Real-time mode: the steps whose command was missed.
    missed: BTreeSet<u64>,
    /// The monitor's progress as last heard.
    monitor: MonitorProgress,
}

impl Sim<'_> {
    fn send(&mut self, mut truth: Truth, mut measurement: Measurement) -> Result<(), ProcessError> {
        self.seq += 1;
        truth.header.seq = self.seq;
        measurement.header.seq = self.seq;
        self.truths.send(&truth)?;
        self.measurements.send(&measurement)?;
        self.summary.measurements += 1;
        Ok(())
    }

    /// Keeps the first publication of a step for replays (forgetting the oldest beyond the history).
    fn keep(&mut self, truth: Truth, measurement: Measurement) {
        // Forget first, then add: the ring never outgrows its capacity (a growing VecDeque would double its
        // buffer and touch new pages for another 4096 steps).
        if self.sent.len() as u64 >= HISTORY_STEPS {
            self.sent.pop_front();
            self.sent_base += 1;
        }
        self.sent.push_back((truth, measurement));
        if let Some(&first) = self.missed.first()
            && first < self.sent_base
        {
            self.missed = self.missed.split_off(&self.sent_base);
        }
    }

    /// An error unless step `from` is still kept for replays.
    fn check_kept(&self, from: u64, who: &str) -> Result<(), ProcessError> {
        if from < self.sent_base {
            return Err(ProcessError::Failed(format!(
                "{who} asked for a replay from step {from}, but only steps {}..={} are kept (the last {HISTORY_STEPS}); \
                 a process restarted without its --checkpoint cannot rejoin a run this long",
                self.sent_base,
                self.sent_base + self.sent.len() as u64 - 1
            )));
        }
        Ok(())
    }

    /// Publishes step `j` again (new sequence number, no stamps: its latencies mean nothing).
    fn send_again(&mut self, j: u64) -> Result<(), ProcessError> {
        let i = j.checked_sub(self.sent_base).filter(|i| (*i as usize) < self.sent.len()).ok_or_else(|| {
            ProcessError::Failed(format!("step {j} is not kept for a replay (kept: from step {})", self.sent_base))
        })?;
        let (mut truth, mut measurement) = self.sent[i as usize];
        truth.header.stamps = Stamps::default();
        measurement.header.stamps = Stamps::default();
        self.send(truth, measurement)
    }

    /// Waits at most `timeout` for a command or a control message.
    fn wait(&self, timeout: Duration) -> Result<(), ProcessError> {
        let (spin, block) = self.args.link.policy().split(timeout);
        self.wait_spin(spin, block)
    }

    /// Waits for a command or a control message: busy-polls for `spin`, then blocks for at most `timeout`.
    fn wait_spin(&self, spin: Duration, timeout: Duration) -> Result<(), ProcessError> {
        let ready = || Ok(self.commands.has_samples()? || self.control.subscriber().has_samples()?);
        wait_any(self.waitset, spin, timeout, ready)?;
        if self.link.interrupted() {
            return Err(ProcessError::Interrupted);
        }
        Ok(())
    }

    /// Real-time mode: waits for a command or a control message until `deadline` at most (spinning no
    /// longer than `--spin-us`, and not past the deadline), or [`IDLE_WAKEUP`].
    fn wait_until(&self, deadline: Instant) -> Result<(), ProcessError> {
        let left = deadline.saturating_duration_since(Instant::now());
        let policy = self.args.link.policy();
        if policy.mode == WaitMode::Spin {
            return self.wait_spin(left.min(IDLE_WAKEUP), Duration::ZERO);
        }
        let (spin, _) = policy.split(left);
        // A zero timeout would return at once; iceoryx2 rounds a blocking wait up to whole milliseconds, so
        // a step goes out up to a millisecond (plus the wake-up latency) late — a command that arrives
        // meanwhile wakes the wait at once and is judged by its arrival — and the schedule does not drift:
        // every step is due at t0 + k·dt/X.
        self.wait_spin(spin, (left - spin).clamp(Duration::from_micros(1), IDLE_WAKEUP))
    }

    /// Handles the control messages: a (re)started estimator, planner or monitor asks for a replay; a
    /// shutdown stops the run.
    fn drain_control(&mut self) -> Result<(), ProcessError> {
        for msg in self.control.receive(&mut self.counter)? {
            let c = match msg {
                Ok(c) => c,
                Err(r) => {
                    self.summary.rejected += 1;
                    eprintln!("emitter-sim: rejected a control message: {r}");
                    continue;
                }
            };
            self.monitor.hear(&c);
            match c.kind() {
                Some(ControlKind::Shutdown) => return Err(ProcessError::Interrupted),
                Some(ControlKind::Hello) if matches!(c.role(), Some("estimator" | "planner" | "monitor")) => {
                    let published = self.sent_base + self.sent.len() as u64;
                    // A planner needs the step in flight only (the newest published).
                    let from = match c.header.step {
                        ControlKind::IN_FLIGHT => published.saturating_sub(1),
                        step => step,
                    };
                    // A request beyond the steps published is for the next step: nothing to replay yet.
                    if from >= published {
                        continue;
                    }
                    self.check_kept(from, &format!("a {} (instance {:#x})", c.role().unwrap_or("?"), c.instance))?;
                    if !self.args.quiet {
                        eprintln!(
                            "emitter-sim: a {} joined (instance {:#x}); replaying from step {from}",
                            c.role().unwrap_or("?"),
                            c.instance
                        );
                    }
                    self.replay_from = Some(self.replay_from.map_or(from, |f| f.min(from)));
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// Lock-step backpressure (`--monitor-window`): before step `k` is published, waits while a monitor's
    /// progress is `window` steps or more behind it (a monitor restarted again and again, or starved of
    /// CPU, would otherwise fall behind without bound, past what a restarted emitter-sim can replay). When
    /// the monitor makes no progress for the retry interval (it was restarted, or a message to it was
    /// lost), the steps from the checkpoint step at or below its first missing one are replayed. Fails
    /// after the command timeout without progress. No monitor heard of: no waiting.
    fn wait_for_monitor(&mut self, k: u64) -> Result<(), ProcessError> {
        let window = self.args.monitor_window;
        let Some(last) = k.checked_sub(1).filter(|_| window > 0) else { return Ok(()) };
        let timeout = Duration::from_secs_f64(self.args.command_timeout_s);
        let retry = Duration::from_millis(self.args.retry_interval_ms);
        let mut seen = None;
        let mut progressed = Instant::now();
        let mut replayed = progressed;
        loop {
            self.drain_control()?;
            let Some(next) = self.monitor.next().filter(|_| self.monitor.holds(k, window)) else { return Ok(()) };
            let now = Instant::now();
            if seen != Some(next) {
                seen = Some(next);
                progressed = now;
            }
            if now - progressed >= timeout {
                return Err(ProcessError::Failed(format!(
                    "step {k}: the monitor has lacked step {next} for {} s, and emitter-sim runs at most \
                     --monitor-window {window} steps ahead of it (is the monitor running? --monitor-window 0 runs \
                     without it)",
                    self.args.command_timeout_s
                )));
            }
            if self.replay_from.is_none() && now - progressed.max(replayed) >= retry {
                self.summary.retries += 1;
                self.replay_from = Some(self.replay_start(next.min(last)));
            }
            if let Some(from) = self.replay_from.take() {
                self.summary.replays += 1;
                // A replay that stops early is taken up by the next retry.
                let _ = self.replay(from.min(last), last, None, None)?;
                replayed = Instant::now();
                continue;
            }
            let limit =
                timeout.saturating_sub(now - progressed).min(retry.saturating_sub(now - progressed.max(replayed)));
            self.wait(limit.min(IDLE_WAKEUP))?;
            // No command is applied here: step k is not published yet (answers to replays are ignored).
            self.drain_commands(None, None)?;
        }
    }

    /// Handles the commands received: applies the first valid one for step `awaited` (once: the step
    /// whose command the world waits for, if any); returns whether one for step `answered` (a replayed
    /// step) came.
    fn drain_commands(&mut self, awaited: Option<u64>, answered: Option<u64>) -> Result<bool, ProcessError> {
        let batch = self.commands.receive_all()?;
        let received_ns = now_ns();
        let mut answer = false;
        // Every message of the batch is checked and counted, also after the one that is applied.
        for cmd in batch {
            if let Err(r) = self.counter.check(&cmd, &mut self.last_seq) {
                self.summary.rejected += 1;
                eprintln!("emitter-sim: rejected a command: {r}");
                continue;
            }
            self.summary.accepted += 1;
            let step = cmd.header.step;
            if Some(step) == awaited && self.applied.is_none() {
                if let Err(e) = self.world.apply(cmd.headings()) {
                    self.summary.rejected += 1;
                    eprintln!("emitter-sim: step {step}: refused a command: {e}");
                    continue;
                }
                self.applied = Some((cmd, received_ns));
                continue;
            }
            if Some(step) == answered {
                answer = true;
                self.summary.ignored += 1;
            } else if self.missed.contains(&step) {
                self.summary.late_commands += 1;
                if !self.args.quiet {
                    eprintln!("emitter-sim: ignored a late command for step {step} (missed)");
                }
            } else {
                self.summary.ignored += 1;
            }
        }
        Ok(answer)
    }

    /// Replays steps `from..=k` (see the module docs); meanwhile a command for step `awaited` (the step the
    /// world waits for, if any) is applied as it comes, and no other. A step whose command does not come
    /// back within the retry interval ends the replay early, and so does `deadline` (real-time mode: the
    /// next step is due); returns the step to go on from then (`None`: the replay is complete). A lock-step
    /// caller drops it (its next retry starts over from the checkpoint step at or below); a real-time
    /// caller goes on from there.
    fn replay(
        &mut self,
        from: u64,
        k: u64,
        awaited: Option<u64>,
        deadline: Option<Instant>,
    ) -> Result<Option<u64>, ProcessError> {
        let retry = Duration::from_millis(self.args.retry_interval_ms);
        let due = |now: Instant| deadline.is_some_and(|d| now >= d);
        for j in from..k {
            if due(Instant::now()) {
                return Ok(Some(j));
            }
            self.send_again(j)?;
            let until = Instant::now() + retry;
            loop {
                let now = Instant::now();
                if due(now) {
                    return Ok(Some(j));
                }
                if now >= until {
                    eprintln!("emitter-sim: replay: no command for step {j} within {retry:?}; retrying later");
                    return Ok(Some(j));
                }
                let limit = deadline.map_or(until, |d| d.min(until));
                self.wait((limit - now).min(IDLE_WAKEUP))?;
                if due(Instant::now()) {
                    return Ok(Some(j)); // what arrived now belongs to the next step's interval
                }
                self.drain_control()?;
                if self.drain_commands(awaited, Some(j))? {
                    break;
                }
            }
        }
        self.send_again(k)?;
        Ok(None)
    }

    /// Real-time mode: the interval of step `k`, until step k + 1 is due at `deadline`. Applies the first
    /// valid command for step `k` that arrives before the deadline (and keeps handling what comes until
    /// then: duplicates, late commands of missed steps, processes that join and get a replay). Returns
    /// the applied command with its receive time, or `None` (missed).
    fn run_interval(&mut self, k: u64, deadline: Instant) -> Result<Option<(Command, u64)>, ProcessError> {
        loop {
            if let Some(from) = self.replay_from.take() {
                self.summary.replays += 1;
                let from = from.min(k);
                self.replay_next = Some(self.replay_next.map_or(from, |j| j.min(from)));
            }
            if Instant::now() >= deadline {
                break;
            }
            if let Some(j) = self.replay_next.take() {
                self.replay_next = self.replay(j.min(k), k, Some(k), Some(deadline))?;
                continue;
            }
            self.wait_until(deadline)?;
            if Instant::now() >= deadline {
                break; // what arrived now belongs to the next step's interval
            }
            self.drain_control()?;
            self.drain_commands(Some(k), None)?;
        }
        Ok(self.applied.take())
    }

    /// Where a replay that must reach step `k` starts: the checkpoint step at or below it, where every
    /// process can answer from (also one restarted from its checkpoint), or the oldest step kept.
    fn replay_start(&self, k: u64) -> u64 {
        checkpoint::checkpoint_step_at_or_below(k).max(self.sent_base)
    }

    /// After the last step `last` (`--linger`): replays the run to whoever asks, until SIGINT/SIGTERM or a
    /// shutdown on the control topic, which end it normally.
    fn linger(&mut self, last: u64) -> Result<(), ProcessError> {
        let mut serve = || -> Result<(), ProcessError> {
            loop {
                if let Some(from) = self.replay_from.take() {
                    self.summary.replays += 1;
                    // A replay that stops early (the command of step j did not come back within the retry
                    // interval: a process is restarting) starts again from the checkpoint step at or
                    // below j, where every process can answer from (as the lock-step retry does).
                    if let Some(j) = self.replay(from.min(last), last, None, None)? {
                        self.summary.retries += 1;
                        self.replay_from = Some(self.replay_start(j));
                    }
                    continue;
                }
                self.wait(IDLE_WAKEUP)?;
                self.drain_control()?;
                self.drain_commands(None, None)?;
            }
        };
        match serve() {
            Err(ProcessError::Interrupted) => Ok(()),
            other => other,
        }
    }

    /// Waits for (and applies) the command of step `k`, replaying when a process joins or the command is
    /// late; fails after the command timeout.
    fn wait_for_command(&mut self, k: u64, domain: &Domain) -> Result<(Command, u64), ProcessError> {
        let start = Instant::now();
        let timeout = Duration::from_secs_f64(self.args.command_timeout_s);
        let retry = Duration::from_millis(self.args.retry_interval_ms);
        let mut published = start;
        loop {
            if let Some(applied) = self.applied.take() {
                return Ok(applied);
            }
            let now = Instant::now();
            if now - start >= timeout {
                return Err(ProcessError::Failed(format!(
                    "step {k}: no command within {} s (is a planner running with --domain {domain}?)",
                    self.args.command_timeout_s
                )));
            }
            if now - published >= retry {
                // From the checkpoint step at or below k: every process can answer from there, also one
                // restarted from its checkpoint (see runtime::checkpoint).
                let from = self.replay_start(k);
                eprintln!("emitter-sim: step {k}: no command after {retry:?}; replaying the run from step {from}");
                self.summary.retries += 1;
                self.replay_from = Some(from);
            }
            if let Some(from) = self.replay_from.take() {
                self.summary.replays += 1;
                // A replay that stops early is taken up by the next retry (from step 0).
                let _ = self.replay(from.min(k), k, Some(k), None)?;
                published = Instant::now();
                continue;
            }
            self.wait((timeout - (now - start)).min(retry - (now - published)).min(IDLE_WAKEUP))?;
            self.drain_control()?;
            self.drain_commands(Some(k), None)?;
        }
    }
}

/// Runs the lock-step loop to its end.
pub fn run(args: &EmitterSimArgs) -> Result<EmitterSummary, ProcessError> {
    protocol::transport::quiet_logs();
    check_time_scale(args.time_scale).map_err(ProcessError::Input)?;
    if args.mode == Mode::Realtime && args.step_delay_ms > 0 {
        return Err(ProcessError::Input(
            "--step-delay-ms applies to lock-step mode only; in realtime mode --time-scale sets the pace".into(),
        ));
    }
    let domain = Domain::resolve(args.domain.as_deref()).map_err(|e| ProcessError::Input(e.to_string()))?;
    let scenario = load_scenario(args.run.scenario.as_deref(), args.run.steps, args.run.seed)
        .map_err(|e| ProcessError::Input(format!("--scenario: {e}")))?;
    let interval = match args.mode {
        Mode::Lockstep => None,
        Mode::Realtime => {
            Some(step_interval(scenario.dt, args.time_scale, scenario.steps).map_err(ProcessError::Input)?)
        }
    };
    if !(args.command_timeout_s > 0.0 && args.command_timeout_s.is_finite()) {
        return Err(ProcessError::Input(format!("--command-timeout-s must be > 0, got {}", args.command_timeout_s)));
    }
    if !(args.connect_timeout_s >= 0.0 && args.connect_timeout_s.is_finite()) {
        return Err(ProcessError::Input(format!("--connect-timeout-s must be ≥ 0, got {}", args.connect_timeout_s)));
    }
    if args.monitor_window >= checkpoint::CHECKPOINT_EVERY {
        return Err(ProcessError::Input(format!(
            "--monitor-window must be below {} (the checkpoint interval; 0 turns it off), got {}",
            checkpoint::CHECKPOINT_EVERY,
            args.monitor_window
        )));
    }
    if args.retry_interval_ms == 0 {
        return Err(ProcessError::Input("--retry-interval-ms must be > 0".into()));
    }
    // A restart in the same run flies on from the oldest snapshot of its checkpoint.
    let saved = match &args.checkpoint {
        Some(path) => checkpoint::load::<Saved>(path, ROLE, domain.as_str())
            .map_err(|e| ProcessError::Input(format!("--checkpoint: {e}")))?,
        None => None,
    };
    let mut snapshots: Vec<(Snapshot, bool)> = saved.map(|s| s.snapshots).unwrap_or_default();
    // Only a full set goes far enough back for every other process's checkpoint (see runtime::checkpoint).
    let oldest = snapshots.first().filter(|_| snapshots.len() >= EMITTER_SNAPSHOTS);
    let (world, start_step, start_missed) = match oldest {
        Some((snapshot, missed)) => (
            World::restore(&scenario, snapshot).map_err(|e| {
                ProcessError::Input(format!("--checkpoint: a snapshot that does not fit the scenario: {e}"))
            })?,
            snapshot.step,
            *missed,
        ),
        None => (World::from_scenario(&scenario).map_err(|e| ProcessError::Input(format!("scenario: {e}")))?, 0, false),
    };
    if start_step > scenario.steps as u64 {
        return Err(ProcessError::Input(format!(
            "--checkpoint: its snapshot is of step {start_step}, beyond the run's {} steps",
            scenario.steps
        )));
    }
    let link = protocol::Link::open(args.link.transport, &services::node_name(&domain, ROLE))?;
    // The first wait installs iceoryx2's SIGINT/SIGTERM handler, so a signal ends the run cleanly.
    if link.interrupted() {
        return Err(ProcessError::Interrupted);
    }
    let started_ns = now_ns();
    let instance = instance_id_at(started_ns);
    let truths = Topic::<Truth>::publisher(&link, &services::truth(&domain))?;
    let measurements = Topic::<Measurement>::publisher(&link, &services::measurement(&domain))?;
    let commands = Topic::<Command>::subscriber(&link, &services::command(&domain))?;
    let control = ControlChannel::open(&link, &domain, ROLE, instance, started_ns)?;
    let waitset = protocol::transport::waitset()?;
    let attach_failed = |e| ProcessError::Failed(format!("attaching to the WaitSet: {e:?}"));
    let _guards = [
        waitset.attach_notification(&commands).map_err(attach_failed)?,
        waitset.attach_notification(control.subscriber()).map_err(attach_failed)?,
    ];
    wait_for_pipeline(&link, &measurements, &commands, &domain, args)?;
    control.send(ControlKind::Hello, 0, "")?;
    runtime::tell(args.supervised, &SupervisorLine::Ready);
    if !args.quiet && start_step > 0 {
        eprintln!("emitter-sim: resumed from the checkpoint's snapshot of step {start_step}");
    }
    if !args.quiet {
        let pace = match interval {
            None => "lock-step".to_string(),
            Some(i) => format!("realtime ×{} ({:.3} s per step)", args.time_scale, i.as_secs_f64()),
        };
        eprintln!(
            "emitter-sim: domain {domain}, {} steps, seed {}, {} UAVs, emitter at ({}, {}) m, {pace}",
            scenario.steps,
            scenario.seed,
            scenario.uav_count(),
            scenario.emitter[0],
            scenario.emitter[1]
        );
    }

    let mut sim = Sim {
        args,
        link: &link,
        waitset: &waitset,
        truths: &truths,
        measurements: &measurements,
        commands: &commands,
        control: &control,
        world,
        summary: EmitterSummary {
            role: ROLE,
            mode: args.mode.name(),
            started_at: start_step,
            ..EmitterSummary::default()
        },
        counter: RejectionCounter::new(),
        last_seq: None,
        // Sequence numbers start at the monotonic clock: a restarted emitter-sim continues above its
        // predecessor.
        seq: now_ns(),
        sent: VecDeque::with_capacity(HISTORY_STEPS as usize),
        sent_base: start_step,
        applied: None,
        replay_from: None,
        replay_next: None,
        missed: BTreeSet::new(),
        monitor: MonitorProgress::default(),
    };
    // The processes that were there before us need no replay.
    sim.drain_control()?;
    sim.replay_from = None;
    let sigmas = scenario.range_sigmas();
    let mut trigger: Option<(Command, u64)> = None;
    let mut previous = match (start_step, start_missed) {
        (0, _) => CommandOutcome::None,
        (_, false) => CommandOutcome::Flown,
        (_, true) => CommandOutcome::Missed,
    };
    let step_delay = Duration::from_millis(args.step_delay_ms);
    // Real-time mode: step k is due at t0 + (k − k0)·interval, t0 the publication of the first step k0.
    let mut t0: Option<Instant> = None;
    let due = |t0: Instant, k: u64| t0 + interval.unwrap_or_default().mul_f64((k - start_step) as f64);
    for k in start_step..=scenario.steps as u64 {
        if interval.is_none() && k > start_step && !step_delay.is_zero() && link.sleep(step_delay).is_err() {
            return Err(ProcessError::Interrupted);
        }
        if interval.is_none() {
            sim.wait_for_monitor(k)?;
        }
        let before = (args.checkpoint.is_some() && checkpoint::is_checkpoint_step(k))
            .then(|| (sim.world.snapshot(), previous == CommandOutcome::Missed));
        // A geometry the world cannot measure (two UAVs on top of each other: a collision) is where the
        // run ends; a restart would fly into it again.
        let meas = sim.world.measure().map_err(|e| {
            ProcessError::Unrecoverable(format!("step {k}: measurement: {e}; the run cannot go on (exit code 3)"))
        })?;
        let uavs: Vec<[f64; 2]> = meas.uavs.iter().map(|p| [p.x, p.y]).collect();
        let mut message = Measurement::new(k, 0, &uavs, meas.range_diffs.as_slice(), &sigmas, sim.world.headings())
            .map_err(|e| ProcessError::Failed(format!("step {k}: measurement: {e}")))?;
        let z = sim.world.truth();
        let mut truth = Truth::new(k, 0, [z.x, z.y]).with_previous_command(previous);
        if let Some((cmd, received_ns)) = &trigger {
            message = message.carrying(cmd, *received_ns);
            // The monitor learns from the truth when the previous step's command reached the world.
            truth = truth.carrying(cmd, *received_ns);
        }
        sim.keep(truth, message);
        if interval.is_some() {
            let now = Instant::now();
            let start = *t0.get_or_insert(now);
            let lag = now.saturating_duration_since(due(start, k));
            sim.summary.max_lag_us = sim.summary.max_lag_us.max(lag.as_micros() as u64);
        }
        sim.send(truth, message)?;
        if k == scenario.steps as u64 {
            break; // the final measurement is recorded, not planned
        }
        match t0 {
            None => {
                trigger = Some(sim.wait_for_command(k, &domain)?);
                previous = CommandOutcome::Flown;
            }
            Some(start) => match sim.run_interval(k, due(start, k + 1))? {
                Some(applied) => {
                    trigger = Some(applied);
                    previous = CommandOutcome::Flown;
                }
                None => {
                    // No command in time: fly straight on at the current headings (zero turn).
                    let keep = sim.world.headings().to_vec();
                    sim.world.apply(&keep).map_err(|e| ProcessError::Failed(format!("step {k}: {e}")))?;
                    sim.missed.insert(k);
                    sim.summary.missed_commands += 1;
                    if !args.quiet {
                        eprintln!(
                            "emitter-sim: step {k}: no command before step {} was due; the UAVs fly straight on",
                            k + 1
                        );
                    }
                    trigger = None;
                    previous = CommandOutcome::Missed;
                }
            },
        }
        sim.summary.steps += 1;
        // The world before a checkpoint step, once its command came back (the estimator and the planner
        // have checkpointed the step by then).
        if let (Some(path), Some(snapshot)) = (&args.checkpoint, before)
            && previous == CommandOutcome::Flown
            && snapshots.last().is_none_or(|(s, _)| s.step < snapshot.0.step)
        {
            checkpoint::push_kept(&mut snapshots, snapshot, EMITTER_SNAPSHOTS);
            let saved = Saved { snapshots: snapshots.clone() };
            if let Err(e) = checkpoint::save(path, ROLE, domain.as_str(), &saved) {
                eprintln!("emitter-sim: {e}");
            }
        }
    }
    if args.linger {
        runtime::tell(args.supervised, &SupervisorLine::Finished);
        sim.linger(scenario.steps as u64)?;
    }
    let mut summary = sim.summary;
    if !args.quiet {
        eprintln!(
            "emitter-sim: done: {} steps, {} measurements, {}, {} ignored, {} replays ({} retries)",
            summary.steps, summary.measurements, sim.counter, summary.ignored, summary.replays, summary.retries
        );
        if interval.is_some() {
            eprintln!(
                "emitter-sim: realtime: {} missed commands, {} late commands ignored, largest lag behind the \
                 schedule {} µs",
                summary.missed_commands, summary.late_commands, summary.max_lag_us
            );
        }
    }
    summary.cpu_s = runtime::cpu_seconds();
    Ok(summary)
}

/// Runs emitter-sim and maps the outcome to an exit code (errors as one `error:` line on stderr); in
/// supervised mode the summary goes to stdout as `summary {json}`.
pub fn main_with(args: &EmitterSimArgs) -> ExitCode {
    runtime::exit_with(ROLE, args.supervised, run(args))
}
