//! The `monitor` process: subscribes to all four topics of a domain and its control topic, rebuilds the
//! run record ([`Assembler`]), shows one status line per step, logs every event as JSON lines, and writes
//! the record (and CSVs and plots) when the last step is in.
//!
//! A handler on the node runtime ([`runtime::node`]: one `WaitSet` over the topics' listeners) that drains
//! every subscriber on each wake-up — woken by a message, or, while a run streams, every [`DRAIN_EVERY`]
//! ([`Node::drain_every`]: the monitor is off the control loop); every message is validated first
//! ([`RejectionCounter`]), invalid ones are counted, logged and ignored.
//!
//! The JSON-lines log (`--log FILE`) has one object per line with `t_ns` (monotonic clock, the stamps'
//! clock) and `event`:
//! - `start` (domain, steps, seed, source, scenario: its [`model::Scenario::fingerprint`]) or `resume`
//!   (domain, steps recorded in the log; a log whose `start` names another run is refused, exit 2);
//!   `message` (kind, step, seq, age_us: publish → received here);
//! - `rejected` (kind, reason, detail); `planner` (a new planner instance: instance, solver, objective, step);
//! - `hello` / `take_over` (a process joined or took over: role, instance, detail, step);
//! - `step` (the step's record, its truth, its latencies in µs and planner; `command_missed: true` when
//!   the step's command did not reach emitter-sim in time — real-time mode — and the UAVs kept their
//!   headings: the record then has `active_constraints: ["command_missed"]`, `objective_value` null);
//!   `command_missed` (step) for such a step; `estimate_stale: true` when the step's command was the
//!   planner's hold (no fresh estimate within its `--estimate-deadline-ms`; the record then has
//!   `active_constraints: ["estimate_stale"]`), and an `estimate_stale` (step) event; `end` (complete,
//!   steps, rejected, ignored, missed_commands, stale_steps);
//! - `front_end_left` (step: the first step not recorded) with `--source external`, when the front end
//!   left the measurement topic before the last step.
//!
//! `uavloc launch` appends `restart` events (role, attempt, exit, backoff_ms) to the same file: every line
//! is written with one `write` on a file opened for appending.
//!
//! The status line of a step (stderr, unless `--quiet`): step, CRLB at the truth, RMSE, estimate error,
//! the hops measurement→estimator and estimate→planner, the planning time, the whole cycle, the active
//! planner and the rejected-message count; `COMMAND MISSED` for a step flown without its command,
//! `ESTIMATE STALE` for a step whose command was the planner's hold.
//!
//! A step is recorded when the truth of the next one is in: only emitter-sim knows whether a command
//! reached the world in time (see [`crate::assemble`]).
//!
//! # Restarts
//!
//! With `--resume` (what `uavloc launch` passes to a restarted monitor) it appends to its `--log` instead
//! of truncating it, reads back the steps recorded there, and announces itself on the control topic
//! ([`ControlKind::Hello`]) and asks for a replay ([`ControlKind::Replay`]) from the first step it lacks:
//! emitter-sim replays the run from there (the estimator estimates the
//! steps again from the states the messages carry, the planner plans the same estimates again), so the
//! record is complete again. The latency statistics of the summary cover the steps this instance saw.
//!
//! The monitor is also one of the holders of the estimator's state ([`runtime::recovery`]): it keeps the
//! state after every step (from the step's estimate or its command's echo; the last 4 096 steps), writes
//! it with the step in its log (`state`: the [`protocol::StateEcho`]'s bytes in hex, read back on
//! `--resume`), and answers an estimator's request for one ([`ControlKind::State`]; logged as
//! `state_request`) on `<domain>/state`, at once or as soon as it has it. A message it lacks (a newer
//! step is [`STALL_STEPS`] ahead, or an estimator waits [`STATE_GRACE`] for the state after a step it
//! has not recorded) it asks emitter-sim to replay (`replay_request`: step, and newest or state).
//!
//! With `--source external` there is no truth (an external front end publishes the measurements): steps
//! complete without one and the truth-based fields stay absent ([`crate::assemble`]); no replay is asked
//! for (nobody could answer). A front end that leaves the measurement topic before the last step ends the
//! run after [`FRONT_END_GRACE`] unless one comes back (exit code 3). With `--mcap FILE` every valid
//! message is recorded ([`crate::recording`]).
//!
//! It exits 0 after the last step, or 130 on SIGINT/SIGTERM or a [`ControlKind::Shutdown`] before it
//! (writing the partial record).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use clap::Args;
use model::load_scenario;
use protocol::services;
use protocol::{
    Command, Control, ControlKind, Estimate, EstimatorState, Measurement, MessageKind, RejectionCounter, Topic,
    TopicPublisher, TopicSubscriber, Truth, Waitable,
};
use runtime::recovery::StateStore;
use runtime::{Flow, Handler, IDLE_WAKEUP, Join, Node};
use serde_json::json;

use crate::assemble::Assembler;
pub use crate::front_end::FRONT_END_GRACE;
use crate::front_end::{FrontEnd, FrontEndWatch};
pub use crate::latency::{LatencyStat, LatencySummary};
use crate::record::RunRecord;
use crate::recording::{Recordable, Recorder};
use crate::runlog::EventLog;
pub use crate::runlog::{LoggedRun, read_log};
use crate::session::Session;
pub use crate::stamps::STAMPS_HEADER;
use crate::stamps::StampsCsv;

/// The role name (node name suffix, `uavloc process monitor`).
pub const ROLE: &str = "monitor";

/// Exit code when SIGINT/SIGTERM stopped the monitor before the last step.
pub use runtime::EXIT_INTERRUPTED;

/// When the step the monitor waits for is incomplete while a message of this many steps later is in, one of
/// its messages was lost: the monitor asks emitter-sim for a replay from it.
pub const STALL_STEPS: u64 = 3;

/// The monitor reports its progress ([`ControlKind::Progress`]: the first step it lacks) every this many
/// recorded steps, at least every [`IDLE_WAKEUP`] while it waits, and when an emitter-sim (re)joins: a
/// lock-step emitter-sim runs at most its `--monitor-window` steps ahead of it.
pub const PROGRESS_EVERY: u64 = 16;

/// How long the monitor waits for a replay it asked for (a message lost) before it asks again: longer than
/// emitter-sim's retry interval (1 s by default), which a running replay gets per step.
pub const REASK: std::time::Duration = std::time::Duration::from_secs(2);

/// How long an estimator may wait for the state after a step this monitor has not recorded before the
/// monitor takes the step's messages for lost and asks for a replay (they may be on their way).
pub const STATE_GRACE: std::time::Duration = std::time::Duration::from_secs(1);

/// While a run streams, the monitor takes its messages every this long (plus the kernel's timer slack,
/// ≤ 50 µs) instead of per message ([`Node::drain_every`]): it is off the control loop, which then has the
/// cores to itself between two drains. The subscriber buffers
/// ([`protocol::transport::SUBSCRIBER_BUFFER`] samples per topic) hold the ≈ 5 steps a lock-step run makes
/// meanwhile many times over.
pub const DRAIN_EVERY: std::time::Duration = std::time::Duration::from_micros(100);

/// What `monitor --help` shows after the flags.
pub const AFTER_HELP: &str = "\
The monitor subscribes to <domain>/measurement, /estimate, /command and /truth and needs the run's
--scenario, --steps and --seed (for the RMSE resamples and the record). Start it before emitter-sim.
It exits after the last step (or on Ctrl-C, writing what it has).

Examples:
  monitor --domain lab1 --log run.jsonl --record run.json
  monitor --domain lab1 --steps 6 --seed 3 --out runs/lab1 --quiet";

/// Flags of the monitor process (`monitor [FLAGS]` or `uavloc process monitor [FLAGS]`).
/// Also `Serialize`: [`runtime::flags::to_flags`] writes the command line of these flags.
#[derive(Args, serde::Serialize, Debug, Clone, PartialEq)]
pub struct MonitorArgs {
    /// The node (domain, link, quiet, supervised) and the run (scenario, steps, seed).
    #[command(flatten)]
    #[serde(flatten)]
    pub process: runtime::ProcessArgs,
    /// Where the measurements come from: simulator (emitter-sim, which also publishes the truth) or
    /// external (a front end outside uavloc; no truth: the columns that need one are absent, not zero).
    #[arg(long, value_name = "SOURCE", default_value = "simulator")]
    pub source: runtime::Source,
    /// Write the raw stamps of every recorded step to FILE as CSV (one row per step, CLOCK_MONOTONIC
    /// nanoseconds; 0 = missing): the chain's publish/receive stamps, when emitter-sim received the step's
    /// command (from the next step's messages) and when the monitor received each of the step's messages.
    /// What `uavloc bench latency` reads.
    #[arg(long, value_name = "FILE")]
    pub stamps: Option<PathBuf>,
    /// Write every event as one JSON object per line to FILE.
    #[arg(long, value_name = "FILE")]
    pub log: Option<PathBuf>,
    /// Record every message of the run to FILE as MCAP (JSON channels with JSON schemas: Foxglove and the
    /// Python `mcap` package open it; `uavloc replay FILE` runs the estimator and planner on it again).
    /// With --resume the messages already in FILE are kept.
    #[arg(long, value_name = "FILE")]
    pub mcap: Option<PathBuf>,
    /// Write the run record (the JSON of `uavloc simulate --json`) to FILE at the end.
    #[arg(long, value_name = "FILE")]
    pub record: Option<PathBuf>,
    /// Write trajectory.csv, steps.csv, run.json and the plots into DIR at the end.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Print the run record as JSON on stdout at the end.
    #[arg(long)]
    pub print_record: bool,
    /// A restart: append to --log instead of truncating it, take the steps recorded there, and have
    /// emitter-sim replay the rest of the run.
    #[arg(long)]
    pub resume: bool,
}

pub use runtime::ProcessError;

/// What the monitor saw, printed as its `summary` line.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct MonitorSummary {
    /// `"monitor"`.
    pub role: &'static str,
    /// Writing `--record` or `--out` at the end failed (the record itself still went to the supervisor).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub output_error: Option<String>,
    /// Whether every step up to the last one was recorded.
    pub complete: bool,
    /// Steps recorded.
    pub steps: u64,
    /// Valid messages received.
    pub accepted: u64,
    /// Invalid messages ignored.
    pub rejected: u64,
    /// Valid messages for steps already recorded or beyond the last one.
    pub ignored: u64,
    /// Distinct planner instances seen.
    pub planners: u64,
    /// Steps recorded whose command was missed (real-time mode).
    pub missed_commands: u64,
    /// Steps recorded whose command was the planner's hold (no fresh estimate within its deadline).
    pub stale_steps: u64,
    /// Latencies of the planned steps.
    pub latency: LatencySummary,
    /// Messages of the recorded steps that never reached the monitor as first published (measurement,
    /// estimate, command and truth of each step; the last step has no command): lost on the way (a full
    /// buffer) or never sent (its sender died first), the step then recorded from a copy sent again (a
    /// replay: no publish stamp). 0 when nothing was lost.
    pub missing_messages: u64,
    /// Replays this monitor asked for because a message was lost (see [`STALL_STEPS`]).
    pub replays_requested: u64,
    /// CPU time this process used, seconds.
    pub cpu_s: f64,
}

fn write_outputs(args: &MonitorArgs, run: &RunRecord) -> Result<(), ProcessError> {
    if let Some(path) = &args.record {
        let text = serde_json::to_string_pretty(run).map_err(|e| ProcessError::Failed(e.to_string()))?;
        std::fs::write(path, text + "\n")
            .map_err(|e| ProcessError::Failed(format!("--record {}: {e}", path.display())))?;
    }
    if let Some(dir) = &args.out {
        crate::export::write_run(run, dir)
            .map_err(|e| ProcessError::Failed(format!("--out {}: {e}", dir.display())))?;
    }
    Ok(())
}

/// The monitor's handler: the four data topics, the record being assembled, the progress reports and
/// the replay requests.
struct MonitorNode<'a> {
    session: Session,
    /// The last accepted sequence number of each data topic.
    last_seq: [Option<u64>; MessageKind::ALL.len()],
    truths: &'a TopicSubscriber<Truth>,
    measurements: &'a TopicSubscriber<Measurement>,
    estimates: &'a TopicSubscriber<Estimate>,
    commands: &'a TopicSubscriber<Command>,
    /// The answers to the estimator's state requests.
    state_answers: &'a TopicPublisher<EstimatorState>,
    /// The step a replay was last asked from because a message was lost, and when.
    replay_asked: Option<(u64, Instant)>,
    /// The step after which an estimator waits for a state this monitor lacks, and since when.
    state_waited: Option<(u64, Instant)>,
    progress_sent: Option<(u64, Instant)>,
    /// With an external source: the front end's presence.
    front_end: Option<FrontEndWatch>,
}

impl MonitorNode<'_> {
    /// Takes the messages waiting on `sub` into the session (`add`), each validated first.
    fn drain<T: Recordable>(
        &mut self,
        node: &mut Node,
        sub: &TopicSubscriber<T>,
        add: fn(&mut Session, T),
    ) -> Result<(), ProcessError> {
        let (batch, received_ns) = sub.receive_stamped()?;
        for msg in batch {
            self.session.arrived(&msg, received_ns);
            match node.counter().check(&msg, &mut self.last_seq[T::KIND.index()]) {
                Ok(()) => self.session.accept(msg, received_ns, add),
                Err(r) => self.session.rejected(T::KIND, &r, msg.header().seq),
            }
        }
        Ok(())
    }
}

impl Handler for MonitorNode<'_> {
    fn on_control(&mut self, _node: &mut Node, msg: &Control) -> Result<Flow, ProcessError> {
        self.session.heard(msg);
        self.session.flush_outputs()?;
        Ok(Flow::Continue)
    }

    fn on_wake(&mut self, node: &mut Node) -> Result<Flow, ProcessError> {
        self.take_messages(node)?;
        // A message of the step we wait for looks lost when newer steps are in and it is not. The drains
        // go topic by topic, so one published before the newest message seen may have come after its
        // topic was drained: a second look first.
        if self.session.lost_step(STALL_STEPS).is_some() {
            self.take_messages(node)?;
        }
        let session = &mut self.session;
        let next = session.assembler.next_step();
        if std::mem::take(&mut session.emitter_joined)
            || self.progress_sent.is_none_or(|(step, at)| next >= step + PROGRESS_EVERY || at.elapsed() >= IDLE_WAKEUP)
        {
            node.announce(ControlKind::Progress, next, "")?;
            self.progress_sent = Some((next, Instant::now()));
        }
        // An estimator waits for the state after a step not recorded here: the messages that carry it were
        // lost, and no later step comes while it waits — once that has lasted STATE_GRACE (they may be on
        // their way).
        let state_lost = match session.lacks_wanted_state() {
            None => {
                self.state_waited = None;
                None
            }
            Some((next, wanted)) => {
                if self.state_waited.is_none_or(|(w, _)| w != wanted) {
                    self.state_waited = Some((wanted, Instant::now()));
                }
                self.state_waited.filter(|(_, since)| since.elapsed() >= STATE_GRACE).map(|_| (next, wanted))
            }
        };
        // A message of the step we wait for was lost (e.g. overwritten in a full buffer while this monitor
        // was starved of CPU, or never sent while it was restarting) if newer steps are in and it is not, or
        // if an estimator waits for its state: ask emitter-sim to replay from it, as a restarted monitor
        // would — again every REASK while it does not come (a replay that found the estimator down is
        // dropped).
        let lost = match (session.lost_step(STALL_STEPS), state_lost) {
            (Some((next, newest)), _) => {
                Some((next, json!({"step": next, "newest": newest}), format!("step {newest} is in")))
            }
            (None, Some((next, wanted))) => Some((
                next,
                json!({"step": next, "state": wanted}),
                format!("an estimator waits for the state after step {wanted}"),
            )),
            (None, None) => None,
        };
        if let Some((next, event, why)) = lost
            && self.replay_asked.is_none_or(|(step, at)| step != next || at.elapsed() >= REASK)
        {
            self.replay_asked = Some((next, Instant::now()));
            session.summary.replays_requested += 1;
            session.log.write("replay_request", event);
            node.say(format_args!("a message of step {next} was lost ({why}); asking for a replay"));
            node.announce(ControlKind::Replay, next, "lost")?;
        }
        if !session.assembler.is_done() {
            self.watch_front_end(node, next)?;
        }
        self.session.flush_outputs()?;
        Ok(if self.session.assembler.is_done() { Flow::Stop } else { Flow::Continue })
    }
}

impl MonitorNode<'_> {
    /// Takes every message waiting on the four data topics into the session, answers the estimator's state
    /// requests it can, and records the steps completed.
    fn take_messages(&mut self, node: &mut Node) -> Result<(), ProcessError> {
        self.drain(node, self.truths, Session::add_truth)?;
        self.drain(node, self.measurements, Session::add_measurement)?;
        self.drain(node, self.estimates, Session::add_estimate)?;
        self.drain(node, self.commands, Session::add_command)?;
        for echo in self.session.states.take_answers() {
            let seq = node.next_seq();
            self.state_answers.send(&EstimatorState::new(echo, seq, node.instance()))?;
        }
        self.session.complete_steps(node.counter().total());
        // The lines of the steps recorded go out before the progress says so; a write error of the log or
        // the stamps ends the run at once, naming the file (disk full, …).
        self.session.flush_outputs()
    }

    /// With an external source: a front end that left the measurement topic before the last step ends the
    /// run after [`FRONT_END_GRACE`] unless one comes back ([`crate::front_end`]) — the launch would
    /// otherwise wait for ever.
    fn watch_front_end(&mut self, node: &mut Node, next: u64) -> Result<(), ProcessError> {
        let Some(watch) = &mut self.front_end else { return Ok(()) };
        let now = Instant::now();
        if watch.cleanup_due(now, next) {
            protocol::transport::cleanup_dead_nodes(node.link().node());
        }
        let pending = self.session.assembler.newest_pending_step().is_some();
        let last = self.session.assembler.last_step();
        match watch.observe(now, self.measurements.publisher_count()?, pending) {
            FrontEnd::Left => {
                self.session.log.write("front_end_left", json!({"step": next}));
                node.warn(format_args!(
                    "the front end left the measurement topic with step {next} of 0..={last} not recorded; waiting \
                     {FRONT_END_GRACE:?} for it to come back"
                ));
            }
            FrontEnd::GaveUp => {
                return Err(ProcessError::Unrecoverable(format!(
                    "the front end left the measurement topic {FRONT_END_GRACE:?} ago with step {next} of 0..={last} \
                     not recorded: the run cannot be completed (the {next} step(s) recorded are in the log)"
                )));
            }
            FrontEnd::NotSeen | FrontEnd::Present | FrontEnd::Away => {}
        }
        Ok(())
    }
}

/// Runs the monitor until the last step is recorded (or SIGINT/SIGTERM, or a shutdown); returns the run
/// record and the summary.
pub fn run(args: &MonitorArgs) -> Result<(RunRecord, MonitorSummary), ProcessError> {
    let scenario = load_scenario(args.process.run.scenario.as_deref(), args.process.run.steps, args.process.run.seed)
        .map_err(|e| ProcessError::Input(format!("--scenario: {e}")))?;
    // The outputs written at the end are checked now: a run is never recorded for nothing.
    if let Some(file) = &args.record {
        runtime::output::check_out_file("--record", file).map_err(ProcessError::Input)?;
    }
    if let Some(dir) = &args.out {
        runtime::output::check_out_dir("--out", dir).map_err(ProcessError::Input)?;
    }
    // No two outputs on one file (one would overwrite the other, or the log read back another's lines).
    let files = [
        ("--log", args.log.as_deref()),
        ("--stamps", args.stamps.as_deref()),
        ("--mcap", args.mcap.as_deref()),
        ("--record", args.record.as_deref()),
    ];
    runtime::output::check_distinct(&files, &[("--out", args.out.as_deref(), &crate::export::RUN_FILES)])
        .map_err(ProcessError::Input)?;
    let log = EventLog::open(args.log.as_deref(), args.resume)?;
    // With a log, the step records live there, not in memory (read back at the end); a restart takes the
    // steps its predecessor logged, and the estimator states they echoed.
    let mut states = StateStore::new();
    let (assembler, resumed) = match (&args.log, args.resume) {
        (Some(path), true) => {
            let LoggedRun { count, last, truth, names, states: logged, start, .. } = read_log(path, false);
            // Resuming another run's log would make one record of two runs.
            let differences = start.map(|s| {
                s.differences(scenario.steps as u64, scenario.seed, args.source.name(), &scenario.fingerprint())
            });
            if let Some(d) = differences.filter(|d| !d.is_empty()) {
                return Err(ProcessError::Input(format!(
                    "--log {}: the log of another run; this run has {}. Resuming would make one record of two \
                     runs: give this run's log, or start without --resume",
                    path.display(),
                    d.join(", ")
                )));
            }
            for echo in logged {
                states.keep(echo);
            }
            match Assembler::resume_forgetting(scenario.clone(), count, last.as_ref(), truth, names) {
                Some(a) => (a, Some(count)),
                None => (Assembler::new(scenario.clone()).forgetting(), Some(0)),
            }
        }
        (Some(_), false) => (Assembler::new(scenario.clone()).forgetting(), None),
        (None, _) => (Assembler::new(scenario.clone()), None),
    };
    let external = args.source == runtime::Source::External;
    let assembler = if external { assembler.without_truth() } else { assembler };
    let Some(mut node) = Node::open(ROLE, &args.process.node)? else {
        return Err(ProcessError::Interrupted);
    };
    node.set_run(scenario.run_id());
    node.drain_every(DRAIN_EVERY);
    let domain = node.domain().clone();
    let stamps = args.stamps.as_deref().map(|p| StampsCsv::create(p, resumed)).transpose()?;
    let recorder = match &args.mcap {
        Some(path) => {
            let metadata = crate::recording::run_metadata(&scenario, domain.as_str(), args.source.name());
            Some(Recorder::create(path, metadata, resumed.is_some()).map_err(ProcessError::Failed)?)
        }
        None => None,
    };
    let measurements = Topic::<Measurement>::subscriber(node.link(), &services::measurement(&domain))?;
    let estimates = Topic::<Estimate>::subscriber(node.link(), &services::estimate(&domain))?;
    let commands = Topic::<Command>::subscriber(node.link(), &services::command(&domain))?;
    let truths = Topic::<Truth>::subscriber(node.link(), &services::truth(&domain))?;
    let state_answers = Topic::<EstimatorState>::publisher(node.link(), &services::state(&domain))?;
    let mut monitor = MonitorNode {
        last_seq: [None; MessageKind::ALL.len()],
        session: Session::new(assembler, log, states, args.process.node.quiet).with_outputs(stamps, recorder),
        truths: &truths,
        measurements: &measurements,
        estimates: &estimates,
        commands: &commands,
        state_answers: &state_answers,
        replay_asked: None,
        state_waited: None,
        progress_sent: None,
        front_end: external.then(FrontEndWatch::default),
    };
    let session = &mut monitor.session;
    match resumed {
        None => session.log.write(
            "start",
            json!({
                "domain": domain.as_str(), "steps": scenario.steps, "seed": scenario.seed, "source": args.source,
                "scenario": scenario.fingerprint(),
            }),
        ),
        Some(n) => session.log.write("resume", json!({"domain": domain.as_str(), "steps_in_log": n})),
    }
    // "Replay the run for me from the first step I lack" (a no-op at the start of a launch).
    node.join(Join::Replay(session.assembler.next_step()), "")?;
    match resumed {
        None if external => node.say(format_args!(
            "domain {domain}, waiting for {} steps from an external front end: no truth, so CRLB at the truth, RMSE \
             and |ẑ−z| are absent",
            scenario.steps + 1
        )),
        None => {
            node.say(format_args!("domain {domain}, waiting for {} steps (seed {})", scenario.steps, scenario.seed))
        }
        Some(n) => node.say(format_args!("domain {domain}, resumed with {n} steps from the log")),
    }
    session.flush_outputs()?;
    if !session.assembler.is_done() {
        let inputs: [&dyn Waitable; 4] = [&truths, &measurements, &estimates, &commands];
        node.run(&inputs, &mut monitor)?;
    }
    let mut session = monitor.session;
    let counter = node.counter().clone();

    // What the last wake-up gathered (a run ended by a signal or a shutdown ends between two).
    session.flush_outputs()?;
    let mut run = session.assembler.record();
    if let Some(path) = &args.log {
        // The records are in the log (this instance's and its predecessors').
        run.steps = read_log(path, true).steps;
        if run.steps.len() as u64 != session.assembler.next_step() {
            return Err(ProcessError::Failed(format!(
                "--log {}: {} steps recorded, but the log has {} of them (was it changed during the run?)",
                path.display(),
                session.assembler.next_step(),
                run.steps.len()
            )));
        }
    }
    crate::metrics::annotate(&mut run);
    let mut summary = MonitorSummary {
        complete: session.assembler.is_done(),
        steps: run.steps.len() as u64,
        accepted: accepted_total(&counter),
        rejected: counter.total(),
        ignored: session.assembler.ignored(),
        latency: session.samples.summary(),
        cpu_s: runtime::cpu_seconds(),
        ..std::mem::take(&mut session.summary)
    };
    if let Some(csv) = session.stamps.take() {
        csv.finish()?;
    }
    let recorded = session.recorder.take().map_or(Ok(()), Recorder::finish);
    session.log.write(
        "end",
        json!({
            "complete": summary.complete, "steps": summary.steps, "rejected": summary.rejected,
            "ignored": summary.ignored, "missed_commands": summary.missed_commands,
            "stale_steps": summary.stale_steps,
        }),
    );
    session.log.flush();
    // The record is the run's result: a failure to write files from it does not lose it (it still goes
    // to the supervisor), it is reported.
    // Each output is tried whatever became of the others.
    let errors: Vec<String> =
        [recorded.err(), write_outputs(args, &run).err().map(|e| e.to_string())].into_iter().flatten().collect();
    if !errors.is_empty() {
        let e = errors.join("; ");
        eprintln!("error: monitor: {e}");
        summary.output_error = Some(e);
    }
    if !args.process.node.quiet {
        let l = &summary.latency;
        let p50 = |s: &Option<LatencyStat>| s.map_or("-".into(), |s| format!("{:.0} µs", s.p50_us));
        eprintln!(
            "monitor: {} of {} steps recorded, {}; median hops: command {}, measurement {}, estimate {}; median \
             cycle {}",
            summary.steps,
            scenario.steps + 1,
            counter,
            p50(&l.command_hop),
            p50(&l.measurement_hop),
            p50(&l.estimate_hop),
            p50(&l.cycle)
        );
    }
    Ok((run, summary))
}

/// Accepted messages of every kind.
fn accepted_total(counter: &RejectionCounter) -> u64 {
    protocol::MessageKind::ALL.iter().map(|k| counter.accepted(*k)).sum()
}

/// Runs the monitor and maps the outcome to an exit code (errors as one `error:` line on stderr); in
/// supervised mode the record and the summary go to stdout as `record {json}` and `summary {json}`.
pub fn main_with(args: &MonitorArgs) -> ExitCode {
    match run(args) {
        Ok((run, summary)) => {
            runtime::tell_record(args.process.node.supervised, &run);
            let summary_json = serde_json::to_value(&summary).unwrap_or_default();
            runtime::tell(args.process.node.supervised, &runtime::SupervisorLine::Summary(summary_json));
            if args.print_record {
                println!("{}", serde_json::to_string_pretty(&run).unwrap_or_default());
            }
            if summary.complete {
                ExitCode::SUCCESS
            } else {
                eprintln!("monitor: interrupted before the last step; the record is partial");
                ExitCode::from(EXIT_INTERRUPTED)
            }
        }
        Err(e) => {
            eprintln!("error: monitor: {e}");
            ExitCode::from(e.code())
        }
    }
}
