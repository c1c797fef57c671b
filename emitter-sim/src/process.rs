//! The `emitter-sim` process in lock-step mode: the world publishes the truth and a noisy measurement of
//! step k, waits for the planner's command for step k, flies it, and goes on with k + 1.
//!
//! Per step k = 0, 1, …, `steps − 1`:
//! 1. publish the [`Truth`] of step k (monitor only), then the [`Measurement`] of step k: UAV positions,
//!    noisy range differences ([`World::measure`], drawn from the stream (seed, k) — the numbers of
//!    `uavloc simulate`), range σ and current headings; from step 1 on it carries the stamps of the
//!    command that triggered it;
//! 2. wait for a valid [`Command`] with `step == k` (invalid ones are counted and ignored, commands for
//!    other steps are ignored), at most `--command-timeout-s`: without one the process exits with an
//!    error (code 1) naming the step;
//! 3. [`World::apply`] its headings (a command the world refuses, e.g. with the wrong UAV count, counts
//!    as rejected and the wait goes on).
//!
//! After the last planned step it publishes the truth and measurement of step `steps` (recorded by the
//! monitor, not planned) and exits 0.
//!
//! Before step 0 it waits until the pipeline is connected — at least `--min-subscribers` subscribers on
//! the measurement topic and a publisher (the planner) on the command topic — because a message
//! published before its subscriber exists is lost (the topics keep no history). SIGINT/SIGTERM stop it
//! cleanly (exit code 130).

use std::io::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::Args;
use iceoryx2::prelude::*;
use planner::process::load_scenario;
use protocol::services::{self, Domain};
use protocol::{
    Command, Measurement, Message, RejectionCounter, Topic, TopicSubscriber, TransportError, Truth, now_ns,
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
    /// Valid commands for another step than the one waited for.
    pub ignored: u64,
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

/// Blocks (after busy-polling `spin`) for at most `timeout`; `Interrupted` on SIGINT/SIGTERM.
fn next_batch<T: protocol::Message>(
    node: &Node<ipc::Service>,
    sub: &TopicSubscriber<T>,
    spin: Duration,
    timeout: Duration,
) -> Result<Vec<T>, ProcessError> {
    if interrupted(node) {
        return Err(ProcessError::Interrupted);
    }
    match sub.wait(spin, timeout) {
        Ok(batch) => Ok(batch),
        // A signal interrupted the wait: stop if it was SIGINT/SIGTERM, else carry on.
        Err(TransportError::Interrupted) => {
            if interrupted(node) {
                Err(ProcessError::Interrupted)
            } else {
                Ok(Vec::new())
            }
        }
        Err(e) => Err(e.into()),
    }
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
    let mut world = World::from_scenario(&scenario).map_err(|e| ProcessError::Input(format!("scenario: {e}")))?;
    let node = protocol::node(&services::node_name(&domain, ROLE))?;
    // The first wait installs iceoryx2's SIGINT/SIGTERM handler, so a signal ends the run cleanly.
    if interrupted(&node) {
        return Err(ProcessError::Interrupted);
    }
    let truths = Topic::<Truth>::publisher(&node, &services::truth(&domain))?;
    let measurements = Topic::<Measurement>::publisher(&node, &services::measurement(&domain))?;
    let commands = Topic::<Command>::subscriber(&node, &services::command(&domain))?;
    wait_for_pipeline(&node, &domain, args)?;
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

    let mut summary = EmitterSummary { role: ROLE, ..EmitterSummary::default() };
    let sigmas = scenario.range_sigmas();
    let truth = world.truth();
    let spin = Duration::from_micros(args.spin_us);
    let timeout = Duration::from_secs_f64(args.command_timeout_s);
    let mut counter = RejectionCounter::new();
    let mut last_seq = None;
    // Sequence numbers start at the monotonic clock: a restarted emitter-sim continues above its predecessor.
    let mut seq = now_ns();
    let mut trigger: Option<(Command, u64)> = None;
    let step_delay = Duration::from_millis(args.step_delay_ms);
    for k in 0..=scenario.steps as u64 {
        if k > 0 && !step_delay.is_zero() && node.wait(step_delay).is_err() {
            return Err(ProcessError::Interrupted);
        }
        let meas = world.measure().map_err(|e| ProcessError::Failed(format!("step {k}: measurement: {e}")))?;
        let uavs: Vec<[f64; 2]> = meas.uavs.iter().map(|p| [p.x, p.y]).collect();
        seq += 1;
        let mut message = Measurement::new(k, seq, &uavs, meas.range_diffs.as_slice(), &sigmas, world.headings())
            .map_err(|e| ProcessError::Failed(format!("step {k}: measurement: {e}")))?;
        if let Some((cmd, received_ns)) = &trigger {
            message = message.carrying(cmd, *received_ns);
        }
        truths.send(&Truth::new(k, seq, [truth.x, truth.y]))?;
        measurements.send(&message)?;
        summary.measurements += 1;
        if k == scenario.steps as u64 {
            break; // the final measurement is recorded, not planned
        }

        // Wait for the command of step k.
        let deadline = Instant::now() + timeout;
        let command = 'wait: loop {
            let now = Instant::now();
            if now >= deadline {
                return Err(ProcessError::Failed(format!(
                    "step {k}: no command within {} s (is a planner running with --domain {domain}?)",
                    args.command_timeout_s
                )));
            }
            let batch = next_batch(&node, &commands, spin, (deadline - now).min(IDLE_WAKEUP))?;
            let received_ns = now_ns();
            // Every message of the batch is checked and counted, also after the one that is applied.
            let mut applied = None;
            for cmd in batch {
                if let Err(r) = counter.check(&cmd, &mut last_seq) {
                    summary.rejected += 1;
                    eprintln!("emitter-sim: rejected a command: {r}");
                    continue;
                }
                summary.accepted += 1;
                if cmd.header.step != k || applied.is_some() {
                    summary.ignored += 1;
                    continue;
                }
                if let Err(e) = world.apply(cmd.headings()) {
                    summary.rejected += 1;
                    eprintln!("emitter-sim: step {k}: refused a command: {e}");
                    continue;
                }
                applied = Some((cmd, received_ns));
            }
            if let Some(applied) = applied {
                break 'wait applied;
            }
        };
        trigger = Some(command);
        summary.steps += 1;
    }
    if !args.quiet {
        eprintln!(
            "emitter-sim: done: {} steps, {} measurements, {counter}, {} ignored",
            summary.steps, summary.measurements, summary.ignored
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
