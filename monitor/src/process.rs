//! The `monitor` process: subscribes to all four topics of a domain and its control topic, rebuilds the
//! run record ([`crate::Assembler`]), shows one status line per step, logs every event as JSON lines, and writes
//! the record (and CSVs and plots) when the last step is in.
//!
//! A handler on the node runtime ([`runtime::node`]: one `WaitSet` over the topics' listeners) that drains
//! every subscriber on each wake-up — woken by a message, or, while a run streams, every [`DRAIN_EVERY`]
//! ([`Node::drain_every`]: the monitor is off the control loop); every message is validated first
//! ([`protocol::RejectionCounter`]), invalid ones are counted, logged and ignored.
//!
//! The JSON-lines log (`--log`, its events in [`crate::runlog`]) and the status lines (one per step on
//! stderr unless `--quiet`) show the run as it goes.
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
//! `state_request`) on `<domain>/state`, at once or as soon as it has it. A message it lacks
//! ([`runtime::recovery::Lost`]) it asks emitter-sim to replay (`replay_request`: step, and newest or
//! state).
//!
//! With `--source external` there is no truth (an external front end publishes the measurements): steps
//! complete without one and the truth-based fields stay absent ([`crate::assemble`]); no replay is asked
//! for (nobody could answer). A front end that leaves the measurement topic before the last step ends the
//! run after [`FRONT_END_GRACE`] unless one comes back (exit code 3). With `--mcap FILE` every valid
//! message is recorded ([`record::recording`]).
//!
//! It exits 0 after the last step, or 130 on SIGINT/SIGTERM or a [`ControlKind::Shutdown`] before it
//! (writing the partial record).

use std::process::ExitCode;
use std::time::Instant;

use model::load_scenario;
use protocol::services;
use protocol::{
    Command, Control, ControlKind, Estimate, EstimatorState, LinkState, Measurement, MeasurementGate, MessageKind,
    SwarmState, Topic, TopicPublisher, TopicSubscriber, Truth, Waitable,
};
use runtime::recovery::{Lost, LostMessages, STALL_STEPS, StalledStep};
use runtime::{Flow, Handler, IDLE_WAKEUP, Join, Node, ProcessError};
use serde_json::json;

use crate::args::MonitorArgs;
use crate::front_end::{FRONT_END_GRACE, FrontEnd, FrontEndWatch};
use crate::runlog::EventLog;
use crate::runlog::{read_log, resume};
use crate::session::Session;
use crate::stamps::StampsCsv;
use crate::summary::MonitorSummary;
use record::record::RunRecord;
use record::recording::{Recordable, Recorder};

pub use crate::ROLE;

/// Exit code when SIGINT/SIGTERM stopped the monitor before the last step.
pub use runtime::EXIT_INTERRUPTED;

/// The monitor reports its progress ([`ControlKind::Progress`]: the first step it lacks) every this many
/// recorded steps, at least every [`IDLE_WAKEUP`] while it waits, and when an emitter-sim (re)joins: a
/// lock-step emitter-sim runs at most its `--monitor-window` steps ahead of it.
pub const PROGRESS_EVERY: u64 = 16;

/// While a run streams, the monitor takes its messages every this long (plus the kernel's timer slack,
/// ≤ 50 µs) instead of per message ([`Node::drain_every`]): it is off the control loop, which then has the
/// cores to itself between two drains. The subscriber buffers
/// ([`protocol::transport::SUBSCRIBER_BUFFER`] samples per topic) hold the ≈ 5 steps a lock-step run makes
/// meanwhile many times over.
pub const DRAIN_EVERY: std::time::Duration = std::time::Duration::from_micros(100);

/// The monitor's handler: the four data topics, the record being assembled, the progress reports and
/// the replay requests.
struct MonitorNode<'a> {
    session: Session,
    /// The last accepted sequence number of each data topic.
    last_seq: [Option<u64>; MessageKind::ALL.len()],
    /// One measurement source per run, one measurement per step ([`protocol::source`]).
    gate: MeasurementGate,
    truths: &'a TopicSubscriber<Truth>,
    measurements: &'a TopicSubscriber<Measurement>,
    estimates: &'a TopicSubscriber<Estimate>,
    commands: &'a TopicSubscriber<Command>,
    /// The answers to the estimator's state requests.
    state_answers: &'a TopicPublisher<EstimatorState>,
    /// The replays asked for because a message was lost.
    lost: LostMessages,
    /// With an external front end: where the monitor gives a step's measurement again
    /// ([`services::measurement_replay`]), and when ([`StalledStep`]).
    replays: Option<&'a TopicPublisher<Measurement>>,
    stalled: StalledStep,
    progress_sent: Option<(u64, Instant)>,
    /// With an external source: the front end's presence.
    front_end: Option<FrontEndWatch>,
    /// With `--links`: the bridge's swarm states and each UAV's link state as last logged.
    links: Option<Links<'a>>,
}

/// The UAVs' links as the bridge reports them (`--links`).
struct Links<'a> {
    states: &'a TopicSubscriber<SwarmState>,
    last_seq: Option<u64>,
    logged: Vec<Option<LinkState>>,
}

impl Links<'_> {
    /// Logs every change of a UAV's link (`link` events) since the last one logged.
    fn take(&mut self, node: &mut Node, session: &mut Session) -> Result<(), ProcessError> {
        let (batch, _) = node.receive(self.states, &mut self.last_seq, "a swarm state")?;
        for s in batch {
            self.logged.resize(s.len(), None);
            for (i, logged) in self.logged.iter_mut().enumerate() {
                let Some(now) = s.link_of(i) else { continue };
                if *logged != Some(now) {
                    session.log.write("link", json!({"uav": i, "state": now.name(), "step": s.header.step}));
                    if *logged == Some(LinkState::Flying) || now == LinkState::Quiet {
                        node.say(format_args!("UAV {i}: link {} (step {})", now.name(), s.header.step));
                    }
                    *logged = Some(now);
                }
            }
        }
        Ok(())
    }
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

impl MonitorNode<'_> {
    /// [`drain`](Self::drain) for the measurements: each also through the gate (one source per run, one
    /// measurement per step: [`protocol::source`]), so the record holds the copy the estimator used.
    fn drain_measurements(&mut self, node: &mut Node) -> Result<(), ProcessError> {
        let sub = self.measurements;
        let (batch, origins, received_ns) = sub.receive_sourced()?;
        for (msg, origin) in batch.into_iter().zip(origins) {
            self.session.arrived(&msg, received_ns);
            match self.gate.check(node.counter(), &msg, origin, |s| sub.publisher_alive(s).unwrap_or(true)) {
                Ok(_) => self.session.accept(msg, received_ns, Session::add_measurement),
                // A refused publisher's first message is logged; its further ones are counted only.
                Err(r) => {
                    if self.gate.log_line(&r).is_some() {
                        self.session.rejected(MessageKind::Measurement, &r, msg.header.seq);
                    }
                }
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
        // A message of the step waited for was lost (a newer step is in, or an estimator waits for a state
        // not recorded here): ask emitter-sim to replay from it, as a restarted monitor would.
        let newer = session.lost_step(STALL_STEPS).map(|(_, newest)| newest);
        let wanted = session.lacks_wanted_state().map(|(_, wanted)| wanted);
        if let Some(lost) = self.lost.poll(Instant::now(), next, newer, wanted) {
            let (event, why) = match lost {
                Lost::NewerStep(newest) => (json!({"step": next, "newest": newest}), format!("step {newest} is in")),
                Lost::StateWanted(w) => {
                    (json!({"step": next, "state": w}), format!("an estimator waits for the state after step {w}"))
                }
            };
            session.summary.replays_requested += 1;
            session.log.write("replay_request", event);
            node.say(format_args!("a message of step {next} was lost ({why}); asking for a replay"));
            node.announce(ControlKind::Replay, next, "lost")?;
        }
        // With an external front end nobody else can replay: the step waited for holds its measurement
        // but its estimate or command was lost (a crashed estimator or planner) — give it again.
        if let Some(replays) = self.replays {
            let measurement = session.assembler.pending_measurement(next).copied();
            if self.stalled.poll(Instant::now(), next, measurement.is_some())
                && let Some(m) = measurement
            {
                session.summary.replays_requested += 1;
                session.log.write("replay_request", json!({"step": next, "measurement": "given again"}));
                node.say(format_args!("step {next} has its measurement but no estimate or command; giving it again"));
                replays.publish(&m, true)?;
            }
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
        if let Some(links) = self.links.as_mut() {
            links.take(node, &mut self.session)?;
        }
        self.drain(node, self.truths, Session::add_truth)?;
        self.drain_measurements(node)?;
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
        if let Some((missing, later)) = watch.gap_to_report(now, self.session.assembler.measurement_gap()) {
            self.session.log.write("measurement_gap", json!({"missing": missing, "later": later}));
            node.warn(format_args!(
                "step {later}'s measurement is in but step {missing}'s has not come: a front end publishes every \
                 step, in order (a silent one too, with flags = 1); the run waits for step {missing}"
            ));
        }
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

/// How a monitor's run ended with a record: complete, interrupted (partial), or failed.
#[derive(Debug)]
pub struct Outcome {
    /// The steps recorded.
    pub run: RunRecord,
    /// The monitor's counts.
    pub summary: MonitorSummary,
    /// Why the run could not go on (exit code 3: the front end left for good), with the steps recorded
    /// until then in `run`.
    pub failed: Option<ProcessError>,
}

/// Runs the monitor until the last step is recorded (or SIGINT/SIGTERM, or a shutdown, or a run that
/// cannot go on); returns the run record and the summary.
pub fn run(args: &MonitorArgs) -> Result<Outcome, ProcessError> {
    let scenario = load_scenario(args.process.run.scenario.as_deref(), args.process.run.steps, args.process.run.seed)
        .map_err(|e| ProcessError::input_because("--scenario", e))?;
    args.check_outputs()?;
    let log = EventLog::open(args.log.as_deref(), args.resume)?;
    let external = args.source == runtime::Source::External;
    let (assembler, states, resumed) = resume(args.log.as_deref(), args.resume, &scenario, args.source)?;
    let Some(mut node) = Node::open(ROLE, &args.process.node)? else {
        return Err(ProcessError::Interrupted);
    };
    node.set_run(scenario.run_id());
    node.drain_every(DRAIN_EVERY);
    let domain = node.domain().clone();
    let stamps = args.stamps.as_deref().map(|p| StampsCsv::create(p, resumed)).transpose()?;
    let recorder = match &args.mcap {
        Some(path) => {
            let metadata = record::recording::run_metadata(&scenario, domain.as_str(), args.source.name());
            Some(Recorder::create(path, metadata, resumed.is_some()).map_err(ProcessError::Failed)?)
        }
        None => None,
    };
    let measurements = Topic::<Measurement>::subscriber(node.link(), &services::measurement(&domain))?;
    let estimates = Topic::<Estimate>::subscriber(node.link(), &services::estimate(&domain))?;
    let commands = Topic::<Command>::subscriber(node.link(), &services::command(&domain))?;
    let truths = Topic::<Truth>::subscriber(node.link(), &services::truth(&domain))?;
    let state_answers = Topic::<EstimatorState>::publisher(node.link(), &services::state(&domain))?;
    let replays = external
        .then(|| Topic::<Measurement>::publisher(node.link(), &services::measurement_replay(&domain)))
        .transpose()?;
    let swarm =
        args.links.then(|| Topic::<SwarmState>::subscriber(node.link(), &services::swarm(&domain))).transpose()?;
    let mut monitor = MonitorNode {
        last_seq: [None; MessageKind::ALL.len()],
        gate: MeasurementGate::default(),
        session: Session::new(assembler, log, states, args.process.node.quiet).with_outputs(stamps, recorder),
        truths: &truths,
        measurements: &measurements,
        estimates: &estimates,
        commands: &commands,
        state_answers: &state_answers,
        lost: LostMessages::default(),
        replays: replays.as_ref(),
        stalled: StalledStep::default(),
        progress_sent: None,
        front_end: external.then(FrontEndWatch::default),
        links: swarm.as_ref().map(|states| Links { states, last_seq: None, logged: Vec::new() }),
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
    // A run that cannot go on (the front end left for good) still gives the steps it recorded, as an
    // interrupted one does: the launcher prints them with the error (`"failed"`).
    let mut failed = None;
    if !session.assembler.is_done() {
        let mut inputs: Vec<&dyn Waitable> = vec![&truths, &measurements, &estimates, &commands];
        if let Some(s) = &swarm {
            inputs.push(s);
        }
        match node.run(&inputs, &mut monitor) {
            Ok(_) => {}
            Err(e) if e.code() == runtime::EXIT_UNRECOVERABLE => failed = Some(e),
            Err(e) => return Err(e),
        }
    }
    let mut session = monitor.session;
    let counter = node.counter().clone();

    // What the last wake-up gathered (a run ended by a signal or a shutdown ends between two).
    session.log_unlogged_rejections();
    session.flush_outputs()?;
    if session.assembler.is_done() {
        // Every step is recorded: what is left (the record from the log, the files) is the end's work.
        runtime::tell(args.process.node.supervised, &runtime::SupervisorLine::Finished);
    }
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
    record::metrics::annotate(&mut run);
    let mut summary = MonitorSummary {
        complete: session.assembler.is_done(),
        steps: run.steps.len() as u64,
        accepted: counter.accepted_total(),
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
            "stale_steps": summary.stale_steps, "uncertified_steps": summary.uncertified_steps,
        }),
    );
    session.log.flush();
    // The record is the run's result: a failure to write files from it does not lose it (it still goes
    // to the supervisor), it is reported.
    // Each output is tried whatever became of the others.
    let errors: Vec<String> =
        [recorded.err(), args.write_outputs(&run).err().map(|e| e.to_string())].into_iter().flatten().collect();
    if !errors.is_empty() {
        let e = errors.join("; ");
        protocol::log_line!("error: monitor: {e}");
        summary.output_error = Some(e);
    }
    if !args.process.node.quiet {
        protocol::log_line!("monitor: {}", summary.closing_line(scenario.steps as u64 + 1, &counter));
    }
    Ok(Outcome { run, summary, failed })
}

/// Runs the monitor and maps the outcome to an exit code (errors as one `error:` line on stderr); in
/// supervised mode the record and the summary go to stdout as `record {json}` and `summary {json}`.
pub fn main_with(args: &MonitorArgs) -> ExitCode {
    match run(args) {
        Ok(Outcome { run, summary, failed }) => {
            runtime::tell_record(args.process.node.supervised, &run);
            let summary_json = serde_json::to_value(&summary).unwrap_or_default();
            runtime::tell(args.process.node.supervised, &runtime::SupervisorLine::Summary(summary_json));
            if args.print_record {
                println!("{}", serde_json::to_string_pretty(&run).unwrap_or_default());
            }
            if let Some(e) = failed {
                runtime::fail("monitor", args.process.node.supervised, &e)
            } else if summary.complete {
                ExitCode::SUCCESS
            } else {
                protocol::log_line!("monitor: interrupted before the last step; the record is partial");
                ExitCode::from(EXIT_INTERRUPTED)
            }
        }
        Err(e) => runtime::fail("monitor", args.process.node.supervised, &e),
    }
}
