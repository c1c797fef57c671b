//! The `estimator` process: receive a [`Measurement`] → [`estimation::Estimator::estimate`] → publish an [`Estimate`].
//!
//! A handler on the node runtime ([`runtime::node`]: one event loop over the measurement and control
//! topics in a `WaitSet`, optionally busy-polling for `--spin-us` first). It needs no scenario: the UAV
//! positions, range differences and their σ all come with the measurement (σ gives the noise model of eq. 19, exactly the
//! one the world drew the noise with). The estimate carries the measurement's UAV geometry and stamps
//! forward ([`Estimate::from_measurement`]).
//!
//! - A step-0 measurement starts a new run (or the run replayed from its start): the estimator forgets its
//!   prior (as `uavloc simulate` starts with a fresh [`estimation::Estimator`]).
//! - The estimate of step k goes on from the state after step k − 1, which the messages carry
//!   ([`crate::chain`]): the estimator reads the command topic (without waking for it) for the states the
//!   commands echo. A step whose predecessor's state it has not seen is held (`out_of_chain`) while it
//!   asks for that state ([`ControlKind::State`]; [`runtime::recovery::StateRequests`]: again every
//!   500 ms while unanswered, a replay from step 0 instead when no monitor has been in the domain for 4 s);
//!   the monitor answers on `<domain>/state` ([`protocol::EstimatorState`]). A step seen again is
//!   estimated again (`resent`).
//!   At start-up the estimator announces itself on the control topic
//!   ([`ControlKind::Hello`]) and asks for a replay of the step in flight ([`ControlKind::IN_FLIGHT`]),
//!   whose measurement its predecessor may have taken with it.
//! - When Chan fails the library keeps its previous estimate; on the wire that is a `failed` estimate
//!   carrying that standing estimate (v3), which the planner plans from and the monitor records — the
//!   numbers of `uavloc simulate`, with no fallback state in either.
//! - Invalid measurements are counted (per rejection kind) and ignored. The estimator takes the run of the
//!   first measurement that states one ([`protocol::Header::run`]; its estimates carry it on) and rejects
//!   messages of another run from then on (`other_run`).
//! - SIGINT/SIGTERM, or a [`ControlKind::Shutdown`] on the control topic, end the loop cleanly (exit 0).
//!
//! # Swapping estimators (`--takeover`, what `uavloc swap estimator` starts)
//!
//! An estimator started with `--takeover` joins a running pipeline without a replay: it listens to the
//! running estimator's estimates too, and the first usable one (ok or ambiguous, step k) *is* that
//! estimator's state after step k ([`estimation::Estimator::resume`]). It then announces [`ControlKind::TakeOver`]
//! from step k + 1 (and prints `takeover {"from_step": k + 1}` when supervised); the running estimator
//! estimates every step before k + 1 and exits (exit 0, `handed_over_at` in its summary); the new one
//! estimates from k + 1 on — exactly what the old one would have. If the running estimator dies before
//! that (killed in the first moments of a swap), the new one goes on as a restarted estimator would: it
//! answers the steps the old one left (kept, or asked again) and asks for the states it lacks.

use std::collections::HashMap;
use std::process::ExitCode;
use std::time::Instant;

use protocol::services;
use protocol::{
    Command, ControlKind, Estimate, EstimateStatus as WireStatus, EstimatorState, Fix, Measurement, MeasurementGate,
    Topic, TopicPublisher, TopicSubscriber, Waitable,
};
use runtime::recovery::{Ask, StateRequests};
use runtime::{Flow, Handler, Join, Node, ProcessError};

use crate::args::EstimatorArgs;
use crate::chain::{Answer, StepEstimator};
use crate::summary::EstimatorSummary;
use estimation::EstimatorConfig;

/// How often an estimator started with --takeover looks whether the running estimator is still there.
const LOOK_FOR_PREDECESSOR: std::time::Duration = std::time::Duration::from_millis(200);

pub use crate::ROLE;

/// The estimator's handler: its ports, its state and the bookkeeping of a swap.
struct EstimatorNode<'a> {
    args: &'a EstimatorArgs,
    config: EstimatorConfig,
    measurements: &'a TopicSubscriber<Measurement>,
    /// The measurements the monitor gives again with an external front end
    /// ([`services::measurement_replay`]).
    replays: &'a TopicSubscriber<Measurement>,
    /// The planner's commands, for the states they echo (read on every wake-up, never waited on).
    commands: &'a TopicSubscriber<Command>,
    command_seq: Option<u64>,
    /// The monitor's answers to this estimator's state requests.
    states: &'a TopicSubscriber<EstimatorState>,
    state_seq: Option<u64>,
    estimates: &'a TopicPublisher<Estimate>,
    /// With --takeover: the running estimator's estimates (its state to take over), and the last sequence
    /// number of each of its instances.
    predecessor: Option<&'a TopicSubscriber<Estimate>>,
    predecessor_seq: HashMap<u64, Option<u64>>,
    /// One measurement source per run, one measurement per step ([`protocol::source`]).
    gate: MeasurementGate,
    state: StepEstimator,
    /// With --takeover: the step this estimator takes over from.
    from_step: Option<u64>,
    /// With --takeover: the running estimator died before this one took over; this one goes on as a
    /// restarted estimator would (it asks for the step in flight and for the states it lacks).
    orphaned: bool,
    /// With --takeover, until it takes over: the measurements the running estimator was to answer, kept
    /// for the case that it dies first; and when to look next whether it is still there.
    skipped: Vec<(Measurement, u64)>,
    next_look: Instant,
    /// The requests for the states it lacks.
    asks: StateRequests,
    summary: EstimatorSummary,
}

impl EstimatorNode<'_> {
    /// With --takeover: the first usable estimate of the running estimator (step k) is its state after
    /// step k; this one takes over from k + 1.
    fn follow_predecessor(&mut self, node: &mut Node) -> Result<(), ProcessError> {
        let Some(p) = self.predecessor else { return Ok(()) };
        for e in p.receive_all()? {
            if e.instance == node.instance() || self.from_step.is_some() {
                continue;
            }
            let last = self.predecessor_seq.entry(e.instance).or_default();
            if let Err(r) = node.counter().check(&e, last) {
                node.summary().rejected += 1;
                node.warn(format_args!("rejected an estimate of the running estimator: {r}"));
                continue;
            }
            // Answered by the running estimator: no longer to be kept for the case that it dies.
            self.skipped.retain(|(m, _)| m.header.step > e.header.step);
            if e.status().is_some_and(WireStatus::is_usable) {
                let f = e.header.step + 1;
                self.state = StepEstimator::resume(self.config, e.header.step, e.position, e.covariance, &e.extra());
                self.from_step = Some(f);
                node.take_over(f, "")?;
            }
        }
        Ok(())
    }

    /// With --takeover, before taking over: when the running estimator is gone (killed in the first
    /// moments of a swap), this one takes over from the oldest step it left unanswered — the measurements
    /// it kept, or the step in flight given again — as a restarted estimator would: the states it lacks
    /// it asks for.
    fn adopt_if_orphaned(&mut self, node: &mut Node) -> Result<(), ProcessError> {
        if !self.args.takeover || self.from_step.is_some() || self.orphaned || Instant::now() < self.next_look {
            return Ok(());
        }
        self.next_look = Instant::now() + LOOK_FOR_PREDECESSOR;
        if !node.other_instances()?.is_empty() {
            return Ok(());
        }
        node.warn(format_args!(
            "the running estimator is gone before the hand-over; going on from the steps it left, as a restarted \
             estimator"
        ));
        self.orphaned = true;
        node.announce(ControlKind::Replay, ControlKind::IN_FLIGHT, "")?;
        for (m, received_ns) in std::mem::take(&mut self.skipped) {
            self.answer(node, &m, received_ns)?;
        }
        Ok(())
    }

    /// Estimates `m` (received at `received_ns`); an orphaned take-over announces itself with its first.
    fn answer(&mut self, node: &mut Node, m: &Measurement, received_ns: u64) -> Result<(), ProcessError> {
        if self.orphaned && self.from_step.is_none() {
            self.from_step = Some(m.header.step);
            node.take_over(m.header.step, "")?;
        }
        let answer = self.state.handle(m, received_ns);
        self.publish(node, m, received_ns, answer)
    }

    /// The states the messages carry: the commands' echoes and the monitor's answers.
    fn take_states(&mut self, node: &mut Node) -> Result<(), ProcessError> {
        let (commands, _) = node.receive(self.commands, &mut self.command_seq, "a command")?;
        for c in &commands {
            self.state.remember(c.state);
        }
        // Sequence numbers start at the clock: a restarted monitor's number above its predecessor's.
        let (states, _) = node.receive(self.states, &mut self.state_seq, "a state")?;
        for s in &states {
            self.state.remember(s.state);
        }
        Ok(())
    }

    /// Publishes the estimate of `m` (received at `received_ns`) as `answer` says.
    fn publish(
        &mut self,
        node: &mut Node,
        m: &Measurement,
        received_ns: u64,
        answer: Answer,
    ) -> Result<(), ProcessError> {
        let step = m.header.step;
        let (reply, again) = match answer {
            Answer::New(reply) => (reply, false),
            Answer::Again(reply) => {
                node.summary().resent += 1;
                (reply, true)
            }
            Answer::OutOfChain => {
                self.summary.out_of_chain += 1;
                node.say(format_args!("step {step}: held until the state after step {} is known", step - 1));
                return Ok(());
            }
        };
        if reply.fix == Fix::Failed {
            self.summary.failed += 1;
            let stands = if reply.standing.is_some() { "the previous estimate stands" } else { "no earlier estimate" };
            node.warn(format_args!("step {step}: no fix ({stands})"));
        }
        let seq = node.next_seq();
        let estimate = reply
            .to_estimate(m, received_ns, seq, node.instance())
            .map_err(|e| ProcessError::failed_because(format!("step {step}: estimate"), e))?;
        // A step estimated again goes out as a copy: no publish stamp, so nobody times it as the step's.
        self.estimates.publish(&estimate, again)?;
        node.summary().published += 1;
        Ok(())
    }

    /// Asks for the state the oldest held measurement waits for, as [`StateRequests`] says: from the
    /// monitor (no publisher on the state topic: none there), or a replay from step 0 when none has been
    /// there for a while (else emitter-sim stops the run with an error naming the steps).
    fn ask(&mut self, node: &mut Node) -> Result<(), ProcessError> {
        let states = self.states;
        let alone = || Ok::<_, ProcessError>(states.publisher_count()? == 0);
        match self.asks.poll(Instant::now(), self.state.wanted(), alone)? {
            Some(Ask::State(step)) => node.announce(ControlKind::State, step, "")?,
            Some(Ask::ReplayFromStart(step)) => {
                node.warn(format_args!(
                    "no monitor to ask for the state after step {step}; asking for a replay from step 0"
                ));
                node.announce(ControlKind::Replay, 0, "no state")?;
            }
            None => {}
        }
        Ok(())
    }
}

impl Handler for EstimatorNode<'_> {
    fn on_wake(&mut self, node: &mut Node) -> Result<Flow, ProcessError> {
        // The measurements are taken (and stamped) first; the states that came before them are remembered
        // before any is answered.
        let (mut batch, received_ns) = node.receive_measurements(self.measurements, &mut self.gate)?;
        // With an external front end, the monitor gives again a step whose estimate was lost.
        batch.extend(node.receive_measurement_copies(self.replays, &mut self.gate)?.0);
        self.follow_predecessor(node)?;
        self.take_states(node)?;
        for (held, answer) in self.state.release() {
            self.publish(node, &held.measurement, held.received_ns, answer)?;
        }
        for m in batch {
            // The estimator has no scenario: it belongs to the run of its first measurement that states one
            // (commands, state answers and measurements of another run are rejected from then on).
            node.counter().adopt_run(m.header.run);
            if node.hands_over(m.header.step) {
                return Ok(Flow::Stop);
            }
            if self.args.takeover && self.from_step.is_none() && !self.orphaned {
                self.skipped.push((m, received_ns)); // the running estimator's step
                continue;
            }
            self.answer(node, &m, received_ns)?;
        }
        self.adopt_if_orphaned(node)?;
        self.ask(node)?;
        Ok(Flow::Continue)
    }

    fn deadline(&self) -> Option<Instant> {
        let waiting = self.args.takeover && self.from_step.is_none() && !self.orphaned;
        let look = waiting.then_some(self.next_look);
        [self.asks.deadline(), look].into_iter().flatten().min()
    }

    fn last_answered(&self) -> Option<u64> {
        self.state.last_step()
    }
}

/// Runs the estimator until SIGINT/SIGTERM, a shutdown request or a hand-over.
pub fn run(args: &EstimatorArgs) -> Result<EstimatorSummary, ProcessError> {
    let config = args.config()?;
    let Some(mut node) = Node::open(ROLE, &args.node)? else {
        return Ok(EstimatorSummary { node: runtime::NodeSummary::new(ROLE, 0), ..EstimatorSummary::default() });
    };
    let domain = node.domain().clone();
    let measurements = Topic::<Measurement>::subscriber(node.link(), &services::measurement(&domain))?;
    let replays = Topic::<Measurement>::subscriber(node.link(), &services::measurement_replay(&domain))?;
    let estimates = Topic::<Estimate>::publisher(node.link(), &services::estimate(&domain))?;
    let commands = Topic::<Command>::subscriber(node.link(), &services::command(&domain))?;
    let states = Topic::<EstimatorState>::subscriber(node.link(), &services::state(&domain))?;
    let predecessor =
        args.takeover.then(|| Topic::<Estimate>::subscriber(node.link(), &services::estimate(&domain))).transpose()?;
    node.join(if args.takeover { Join::TakeOver } else { Join::Replay(ControlKind::IN_FLIGHT) }, "")?;
    node.say(format_args!("domain {domain}, instance {:#x}", node.instance()));
    let mut handler = EstimatorNode {
        args,
        config,
        measurements: &measurements,
        replays: &replays,
        commands: &commands,
        command_seq: None,
        states: &states,
        state_seq: None,
        estimates: &estimates,
        predecessor: predecessor.as_ref(),
        predecessor_seq: HashMap::new(),
        gate: MeasurementGate::default(),
        state: StepEstimator::with_config(config),
        from_step: None,
        orphaned: false,
        skipped: Vec::new(),
        next_look: Instant::now() + LOOK_FOR_PREDECESSOR,
        asks: StateRequests::default(),
        summary: EstimatorSummary::default(),
    };
    let mut inputs: Vec<&dyn Waitable> = vec![&measurements, &replays, &states];
    if let Some(p) = &predecessor {
        inputs.push(p);
    }
    node.run(&inputs, &mut handler)?;
    let (published, resent) = (node.summary().published, node.summary().resent);
    let counts = node.counter().to_string();
    node.say(format_args!(
        "stopped after {published} estimates ({resent} sent again, {} held for a state; {counts})",
        handler.summary.out_of_chain
    ));
    Ok(EstimatorSummary { node: node.finish(), ..handler.summary })
}

/// Runs the estimator and maps the outcome to an exit code (errors as one `error:` line on stderr); in
/// supervised mode the summary goes to stdout as `summary {json}`.
pub fn main_with(args: &EstimatorArgs) -> ExitCode {
    runtime::exit_with(ROLE, args.node.supervised, run(args))
}
