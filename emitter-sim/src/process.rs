//! The `emitter-sim` process in lock-step mode: the world publishes the truth and a noisy measurement of
//! step k, waits for the planner's command for step k, flies it, and goes on with k + 1.
//!
//! Per step k = 0, 1, …, `steps − 1`:
//! 1. publish the [`Truth`] of step k (monitor only), then the [`Measurement`] of step k: UAV positions,
//!    noisy range differences ([`World::measure`], drawn from the stream (seed, k) — the numbers of
//!    `uavloc simulate`), range σ and current headings; from step 1 on it carries the stamps of the
//!    command that triggered it;
//! 2. wait for a valid [`Command`] with `step == k` (invalid ones are counted and ignored, commands for
//!    other steps are ignored);
//! 3. [`World::apply`] its headings (a command the world refuses, e.g. with the wrong UAV count, counts
//!    as rejected and the wait goes on).
//!
//! After the last planned step it publishes the truth and measurement of step `steps` (recorded by the
//! monitor, not planned) and exits 0.
//!
//! # Replays: how the pipeline survives a restarted process
//!
//! emitter-sim keeps the truth and measurement of every step it published. It *replays* steps `from..=k`
//! — publishes them again, same step, same data, new sequence numbers, one step at a time, each after the
//! command of the previous one came back (that command is not applied: the world is already past it) —
//! when
//! - a process announces itself on the control topic ([`ControlKind::Hello`]: an estimator or planner
//!   restarted after a crash asks for step 0, since their state is rebuilt from the whole run; a
//!   restarted monitor asks for the first step missing from its log), or
//! - the command of step k has not come `--retry-interval-ms` after the step was (re)published: a
//!   process died or lost the message; everything is replayed from step 0.
//!
//! The estimator and the planner answer a message they have seen before with the answer they gave
//! before, so a replay costs a hop per step and changes nothing; a process that lost its state rebuilds
//! exactly the state it had. It gives up (exit 1) when the command of a step has not come after
//! `--command-timeout-s` in all.
//!
//! A restarted emitter-sim starts from step 0: the world is deterministic, so it publishes exactly the
//! measurements of its predecessor, the estimator and planner answer them from what they kept, and the run
//! fast-forwards to where it was.
//!
//! Before step 0 it waits until the pipeline is connected — at least `--min-subscribers` subscribers on
//! the measurement topic and a publisher (the planner) on the command topic — because a message
//! published before its subscriber exists is lost (the topics keep no history). SIGINT/SIGTERM, or a
//! [`ControlKind::Shutdown`], stop it cleanly (exit code 130).

use std::io::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::Args;
use iceoryx2::prelude::*;
use planner::process::load_scenario;
use protocol::control::instance_id_at;
use protocol::services::{self, Domain};
use protocol::transport::{TopicPublisher, wait_any};
use protocol::{
    Command, ControlChannel, ControlKind, Measurement, Message, RejectionCounter, Stamps, Topic, TopicSubscriber,
    TransportError, Truth, now_ns,
};

use crate::World;

/// The role name (node name suffix, `uavloc process emitter-sim`).
pub const ROLE: &str = "emitter-sim";

/// Exit code when SIGINT/SIGTERM stopped the run before its end.
pub const EXIT_INTERRUPTED: u8 = 130;

/// How long one blocking wait lasts at most before the loop re-checks for a termination request that
/// arrived between two waits (a signal during a wait interrupts it at once).
pub const IDLE_WAKEUP: Duration = Duration::from_secs(1);

/// How often the start-up wait re-checks whether the pipeline is connected.
pub const CONNECT_POLL: Duration = Duration::from_millis(2);

/// What `emitter-sim --help` shows after the flags.
pub const AFTER_HELP: &str = "\
emitter-sim publishes <domain>/truth and <domain>/measurement and subscribes to <domain>/command, in
lock-step: the next step starts as soon as the command for the current one arrives. Start estimator,
planner (and monitor) first, with the same --domain, --scenario, --steps and --seed; emitter-sim waits
until they are connected, runs steps 0..N (the last one is measured, not planned) and exits 0.

Examples:
  emitter-sim --domain lab1
  emitter-sim --domain lab1 --scenario scenarios/nominal.toml --steps 6 --seed 3 --min-subscribers 2";

/// Flags of the emitter-sim process (`emitter-sim [FLAGS]` or `uavloc process emitter-sim [FLAGS]`).
#[derive(Args, Debug, Clone, PartialEq)]
pub struct EmitterSimArgs {
    /// Pipeline domain: prefix of every service name (default: $UAVLOC_DOMAIN, else "uavloc").
    #[arg(long, value_name = "NAME")]
    pub domain: Option<String>,
    /// Scenario TOML file (default: the paper's nominal case).
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<PathBuf>,
    /// Planning steps (default: the scenario's); steps 0..N are measured, 0..N−1 planned.
    #[arg(long, value_name = "N")]
    pub steps: Option<usize>,
    /// Run seed (default: the scenario's): the measurement noise of step k is drawn from (seed, k).
    #[arg(long, value_name = "N")]
    pub seed: Option<u64>,
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
    /// Busy-poll this many microseconds for the command before blocking (0: block at once).
    #[arg(long, value_name = "US", default_value_t = 0)]
    pub spin_us: u64,
    /// Wait this many milliseconds before each step after step 0 (slows a run down for a demo or a test;
    /// the results do not change). 0: lock-step at full speed.
    #[arg(long, value_name = "MS", default_value_t = 0)]
    pub step_delay_ms: u64,
    /// Print nothing but errors.
    #[arg(long)]
    pub quiet: bool,
    /// Under a launcher: print `ready` on stdout once connected, and `summary {json}` at exit.
    #[arg(long, hide = true)]
    pub supervised: bool,
}

/// Why the process stopped before the end of the run.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ProcessError {
    /// Bad flags or scenario (exit code 2).
    Input(String),
    /// A runtime failure: iceoryx2, a missing command, a geometry the world cannot measure (exit code 1).
    Failed(String),
    /// SIGINT/SIGTERM (exit code 130).
    Interrupted,
}

impl ProcessError {
    /// The exit code: 2 bad input, 1 runtime failure, 130 interrupted.
    pub fn code(&self) -> u8 {
        match self {
            ProcessError::Input(_) => 2,
            ProcessError::Failed(_) => 1,
            ProcessError::Interrupted => EXIT_INTERRUPTED,
        }
    }
}

impl std::fmt::Display for ProcessError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ProcessError::Input(m) | ProcessError::Failed(m) => f.write_str(m),
            ProcessError::Interrupted => f.write_str("interrupted by a signal"),
        }
    }
}

impl From<TransportError> for ProcessError {
    fn from(e: TransportError) -> Self {
        match e {
            TransportError::Interrupted => ProcessError::Interrupted,
            e => ProcessError::Failed(e.to_string()),
        }
    }
}

/// What emitter-sim did, printed as its `summary` line.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct EmitterSummary {
    /// `"emitter-sim"`.
    pub role: &'static str,
    /// Steps flown (commands applied).
    pub steps: u64,
    /// Measurements published.
    pub measurements: u64,
    /// Valid commands received (any step).
    pub accepted: u64,
    /// Invalid commands ignored (failed validation, or refused by the world).
    pub rejected: u64,
    /// Valid commands for another step than the one waited for (also the answers to replayed steps).
    pub ignored: u64,
    /// Replays (see the module docs).
    pub replays: u64,
    /// Replays because a step's command was late.
    pub retries: u64,
}

fn announce(supervised: bool, line: &str) {
    if supervised {
        let mut out = std::io::stdout().lock();
        let _ = writeln!(out, "{line}");
        let _ = out.flush();
    }
}

fn interrupted(node: &Node<ipc::Service>) -> bool {
    node.wait(Duration::ZERO).is_err()
}

fn open_pubsub<T: Message>(
    node: &Node<ipc::Service>,
    name: &str,
) -> Result<iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, T, ()>, ProcessError> {
    let service = ServiceName::new(name).map_err(|e| ProcessError::Failed(format!("service {name:?}: {e:?}")))?;
    node.service_builder(&service)
        .publish_subscribe::<T>()
        .open()
        .map_err(|e| ProcessError::Failed(format!("opening {name:?}: {e:?}")))
}

/// Waits until the measurement topic has `min_subscribers` subscribers and the command topic a
/// publisher, re-checking the services' participant counts every [`CONNECT_POLL`].
fn wait_for_pipeline(node: &Node<ipc::Service>, domain: &Domain, args: &EmitterSimArgs) -> Result<(), ProcessError> {
    let start = Instant::now();
    let measurement = open_pubsub::<Measurement>(node, &services::measurement(domain))?;
    let command = open_pubsub::<Command>(node, &services::command(domain))?;
    loop {
        let subscribers = measurement.dynamic_config().number_of_subscribers();
        let planners = command.dynamic_config().number_of_publishers();
        if subscribers >= args.min_subscribers && planners >= 1 {
            return Ok(());
        }
        if start.elapsed().as_secs_f64() > args.connect_timeout_s {
            return Err(ProcessError::Failed(format!(
                "the pipeline did not connect within {} s ({subscribers} of {} measurement subscribers, {planners} \
                 planner(s)); start estimator and planner with --domain {domain}",
                args.connect_timeout_s, args.min_subscribers
            )));
        }
        if node.wait(CONNECT_POLL).is_err() {
            return Err(ProcessError::Interrupted);
        }
    }
}

/// The ports and the state of the lock-step loop.
struct Sim<'a> {
    args: &'a EmitterSimArgs,
    node: &'a Node<ipc::Service>,
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
    /// The truth and measurement of every step published so far, as first published.
    sent: Vec<(Truth, Measurement)>,
    /// The command applied for the step being waited for, with its receive time.
    applied: Option<(Command, u64)>,
    /// The first step a process that joined asked to see again.
    replay_from: Option<u64>,
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

    /// Publishes step `j` again (new sequence number, no stamps: its latencies mean nothing).
    fn send_again(&mut self, j: u64) -> Result<(), ProcessError> {
        let (mut truth, mut measurement) = self.sent[j as usize];
        truth.header.stamps = Stamps::default();
        measurement.header.stamps = Stamps::default();
        self.send(truth, measurement)
    }

    /// Waits at most `timeout` for a command or a control message.
    fn wait(&self, timeout: Duration) -> Result<(), ProcessError> {
        let ready = || Ok(self.commands.has_samples()? || self.control.subscriber().has_samples()?);
        wait_any(self.waitset, Duration::from_micros(self.args.spin_us), timeout, ready)?;
        if interrupted(self.node) {
            return Err(ProcessError::Interrupted);
        }
        Ok(())
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
            match c.kind() {
                Some(ControlKind::Shutdown) => return Err(ProcessError::Interrupted),
                Some(ControlKind::Hello) if matches!(c.role(), Some("estimator" | "planner" | "monitor")) => {
                    let from = c.header.step;
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

    /// Handles the commands received: applies the first valid one for step `k` (once); returns whether
    /// one for step `answered` (a replayed step) came.
    fn drain_commands(&mut self, k: u64, answered: Option<u64>) -> Result<bool, ProcessError> {
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
            if step == k && self.applied.is_none() {
                if let Err(e) = self.world.apply(cmd.headings()) {
                    self.summary.rejected += 1;
                    eprintln!("emitter-sim: step {k}: refused a command: {e}");
                    continue;
                }
                self.applied = Some((cmd, received_ns));
                continue;
            }
            answer |= Some(step) == answered;
            self.summary.ignored += 1;
        }
        Ok(answer)
    }

    /// Replays steps `from..=k` (see the module docs); a step whose command does not come back within the
    /// retry interval ends the replay early (the next retry starts over).
    fn replay(&mut self, from: u64, k: u64) -> Result<(), ProcessError> {
        self.summary.replays += 1;
        let retry = Duration::from_millis(self.args.retry_interval_ms);
        for j in from..k {
            self.send_again(j)?;
            let deadline = Instant::now() + retry;
            loop {
                let now = Instant::now();
                if now >= deadline {
                    eprintln!("emitter-sim: replay: no command for step {j} within {retry:?}; retrying later");
                    return Ok(());
                }
                self.wait((deadline - now).min(IDLE_WAKEUP))?;
                self.drain_control()?;
                if self.drain_commands(k, Some(j))? {
                    break;
                }
            }
        }
        self.send_again(k)
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
                eprintln!("emitter-sim: step {k}: no command after {retry:?}; replaying the run from step 0");
                self.summary.retries += 1;
                self.replay_from = Some(0);
            }
            if let Some(from) = self.replay_from.take() {
                self.replay(from.min(k), k)?;
                published = Instant::now();
                continue;
            }
            self.wait((timeout - (now - start)).min(retry - (now - published)).min(IDLE_WAKEUP))?;
            self.drain_control()?;
            self.drain_commands(k, None)?;
        }
    }
}

/// Runs the lock-step loop to its end.
pub fn run(args: &EmitterSimArgs) -> Result<EmitterSummary, ProcessError> {
    protocol::transport::quiet_logs();
    let domain = Domain::resolve(args.domain.as_deref()).map_err(|e| ProcessError::Input(e.to_string()))?;
    let scenario = load_scenario(args.scenario.as_deref(), args.steps, args.seed)
        .map_err(|e| ProcessError::Input(format!("--scenario: {e}")))?;
    if !(args.command_timeout_s > 0.0 && args.command_timeout_s.is_finite()) {
        return Err(ProcessError::Input(format!("--command-timeout-s must be > 0, got {}", args.command_timeout_s)));
    }
    if !(args.connect_timeout_s >= 0.0 && args.connect_timeout_s.is_finite()) {
        return Err(ProcessError::Input(format!("--connect-timeout-s must be ≥ 0, got {}", args.connect_timeout_s)));
    }
    if args.retry_interval_ms == 0 {
        return Err(ProcessError::Input("--retry-interval-ms must be > 0".into()));
    }
    let world = World::from_scenario(&scenario).map_err(|e| ProcessError::Input(format!("scenario: {e}")))?;
    let node = protocol::node(&services::node_name(&domain, ROLE))?;
    // The first wait installs iceoryx2's SIGINT/SIGTERM handler, so a signal ends the run cleanly.
    if interrupted(&node) {
        return Err(ProcessError::Interrupted);
    }
    let started_ns = now_ns();
    let instance = instance_id_at(started_ns);
    let truths = Topic::<Truth>::publisher(&node, &services::truth(&domain))?;
    let measurements = Topic::<Measurement>::publisher(&node, &services::measurement(&domain))?;
    let commands = Topic::<Command>::subscriber(&node, &services::command(&domain))?;
    let control = ControlChannel::open(&node, &domain, ROLE, instance, started_ns)?;
    let waitset = protocol::transport::waitset()?;
    let attach_failed = |e| ProcessError::Failed(format!("attaching to the WaitSet: {e:?}"));
    let _guards = [
        waitset.attach_notification(&commands).map_err(attach_failed)?,
        waitset.attach_notification(control.subscriber()).map_err(attach_failed)?,
    ];
    wait_for_pipeline(&node, &domain, args)?;
    control.send(ControlKind::Hello, 0, "")?;
    announce(args.supervised, "ready");
    if !args.quiet {
        eprintln!(
            "emitter-sim: domain {domain}, {} steps, seed {}, {} UAVs, emitter at ({}, {}) m",
            scenario.steps,
            scenario.seed,
            scenario.uav_count(),
            scenario.emitter[0],
            scenario.emitter[1]
        );
    }

    let mut sim = Sim {
        args,
        node: &node,
        waitset: &waitset,
        truths: &truths,
        measurements: &measurements,
        commands: &commands,
        control: &control,
        world,
        summary: EmitterSummary { role: ROLE, ..EmitterSummary::default() },
        counter: RejectionCounter::new(),
        last_seq: None,
        // Sequence numbers start at the monotonic clock: a restarted emitter-sim continues above its
        // predecessor.
        seq: now_ns(),
        sent: Vec::new(),
        applied: None,
        replay_from: None,
    };
    // The processes that were there before us need no replay.
    sim.drain_control()?;
    sim.replay_from = None;
    let sigmas = scenario.range_sigmas();
    let truth = sim.world.truth();
    let mut trigger: Option<(Command, u64)> = None;
    let step_delay = Duration::from_millis(args.step_delay_ms);
    for k in 0..=scenario.steps as u64 {
        if k > 0 && !step_delay.is_zero() && node.wait(step_delay).is_err() {
            return Err(ProcessError::Interrupted);
        }
        let meas = sim.world.measure().map_err(|e| ProcessError::Failed(format!("step {k}: measurement: {e}")))?;
        let uavs: Vec<[f64; 2]> = meas.uavs.iter().map(|p| [p.x, p.y]).collect();
        let mut message = Measurement::new(k, 0, &uavs, meas.range_diffs.as_slice(), &sigmas, sim.world.headings())
            .map_err(|e| ProcessError::Failed(format!("step {k}: measurement: {e}")))?;
        if let Some((cmd, received_ns)) = &trigger {
            message = message.carrying(cmd, *received_ns);
        }
        let truth = Truth::new(k, 0, [truth.x, truth.y]);
        sim.sent.push((truth, message));
        sim.send(truth, message)?;
        if k == scenario.steps as u64 {
            break; // the final measurement is recorded, not planned
        }
        trigger = Some(sim.wait_for_command(k, &domain)?);
        sim.summary.steps += 1;
    }
    let summary = sim.summary;
    if !args.quiet {
        eprintln!(
            "emitter-sim: done: {} steps, {} measurements, {}, {} ignored, {} replays ({} retries)",
            summary.steps, summary.measurements, sim.counter, summary.ignored, summary.replays, summary.retries
        );
    }
    Ok(summary)
}

/// Runs emitter-sim and maps the outcome to an exit code (errors as one `error:` line on stderr); in
/// supervised mode the summary goes to stdout as `summary {json}`.
pub fn main_with(args: &EmitterSimArgs) -> ExitCode {
    match run(args) {
        Ok(summary) => {
            announce(args.supervised, &format!("summary {}", serde_json::to_string(&summary).unwrap_or_default()));
            ExitCode::SUCCESS
        }
        Err(ProcessError::Interrupted) => {
            eprintln!("emitter-sim: stopped by a signal before the end of the run");
            ExitCode::from(EXIT_INTERRUPTED)
        }
        Err(e) => {
            eprintln!("error: emitter-sim: {e}");
            ExitCode::from(e.code())
        }
    }
}
