//! The `estimator` process: receive a [`Measurement`] → [`Estimator::estimate`] → publish an [`Estimate`].
//!
//! A handler on the node runtime ([`runtime::node`]: one event loop over the measurement and control
//! topics in a `WaitSet`, optionally busy-polling for `--spin-us` first). It needs no scenario: the UAV positions, range
//! differences and their σ all come with the measurement (σ gives the noise model of eq. 19, exactly the
//! one the world drew the noise with). The estimate carries the measurement's UAV geometry and stamps
//! forward ([`Estimate::from_measurement`]).
//!
//! - A step-0 measurement starts a new run (or the run replayed from its start): the estimator forgets its
//!   prior (as `uavloc simulate` starts with a fresh [`Estimator`]).
//! - The estimate of step k depends on the state after step k − 1 (the fused posterior, or the previous
//!   estimate as the prior that resolves Chan's two-root ambiguity). The estimator keeps no file and no
//!   answer: it continues its own chain (step k right after step k − 1, or step 0), and for any other step
//!   it takes the state after k − 1 from the messages ([`runtime::recovery`]). Every command echoes the
//!   state of the estimate it was planned from ([`protocol::StateEcho`]); the estimator reads the command
//!   topic (without waking for it) and keeps those states ([`StateStore`]). A step seen again — a replay
//!   for a restarted monitor, a world rewound to an older emitter-sim snapshot — is estimated again from
//!   the state before it, bit for bit the estimate it had (`resent` counts them). A step whose
//!   predecessor's state it has neither made nor seen echoed (after its own restart, or a world rewound
//!   further back than it remembers) is held (`out_of_chain` counts them) while it asks for that state
//!   ([`ControlKind::State`], again every [`STATE_RETRY`] while unanswered); the monitor, which keeps every
//!   echoed state, answers on `<domain>/state` ([`protocol::EstimatorState`]), and the held steps are
//!   estimated then, in step order. With no monitor in the domain for [`NO_HOLDER_FALLBACK`] (a
//!   pipeline run without one) it asks for a replay from step 0 instead, which brings every state again
//!   while emitter-sim keeps step 0.
//!   At start-up the estimator announces itself on the control topic
//!   ([`ControlKind::Hello`]) and asks for a replay of the step in flight ([`ControlKind::IN_FLIGHT`]),
//!   whose measurement its predecessor may have taken with it.
//! - When Chan fails the library keeps its previous estimate; on the wire that is a `failed` estimate
//!   carrying that standing estimate (v3), which the planner plans from and the monitor records — the
//!   numbers of `uavloc simulate`, with no fallback state in either.
//! - Invalid measurements are counted (per rejection kind) and ignored.
//! - SIGINT/SIGTERM, or a [`ControlKind::Shutdown`] on the control topic, end the loop cleanly (exit 0).
//!
//! # Swapping estimators (`--takeover`, what `uavloc swap estimator` starts)
//!
//! An estimator started with `--takeover` joins a running pipeline without a replay: it listens to the
//! running estimator's estimates too, and the first usable one (ok or ambiguous, step k) *is* that
//! estimator's state after step k ([`Estimator::resume`]). It then announces [`ControlKind::TakeOver`]
//! from step k + 1 (and prints `takeover {"from_step": k + 1}` when supervised); the running estimator
//! estimates every step before k + 1 and exits (exit 0, `handed_over_at` in its summary); the new one
//! estimates from k + 1 on — exactly what the old one would have.

use std::collections::{BTreeMap, HashMap};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::Args;
use nalgebra::{Matrix4, Vector2, Vector4};
use protocol::services;
use protocol::{
    Command, ControlKind, EchoedState, Estimate, EstimateStatus as WireStatus, EstimatorState, Fix, Measurement,
    PosteriorExtra, StateEcho, Topic, TopicPublisher, TopicSubscriber, Waitable,
};
use runtime::recovery::StateStore;
use runtime::{Flow, Handler, Node};
use tdoa::{Dynamics, NoiseModel, Posterior, RangeDiffs};

use crate::{EmitterModel, EstimateStatus, Estimator, EstimatorConfig, EstimatorKind};

/// The role name (node name suffix, `uavloc process estimator`).
pub const ROLE: &str = "estimator";

/// What `estimator --help` shows after the flags.
pub const AFTER_HELP: &str = "\
The estimator subscribes to <domain>/measurement and publishes <domain>/estimate. It needs no scenario:
positions, range differences and their sigmas come with each measurement. It keeps no file: the state
each step goes on from rides the messages (every command on <domain>/command echoes it); a step whose
predecessor's state it has not seen (after a restart) is held while it asks the monitor for that state
(answered on <domain>/state).

Examples:
  estimator --domain lab1
  UAVLOC_DOMAIN=lab1 estimator --spin-us 50";

/// Flags of the estimator process (`estimator [FLAGS]` or `uavloc process estimator [FLAGS]`).
/// Also `Serialize`: [`runtime::flags::to_flags`] writes the command line of these flags.
#[derive(Args, serde::Serialize, Debug, Clone, PartialEq)]
pub struct EstimatorArgs {
    /// The node: domain, link (transport and waiting), quiet, supervised.
    #[command(flatten)]
    #[serde(flatten)]
    pub node: runtime::NodeArgs,
    /// Take over from the running estimator at the next step (see `uavloc swap estimator`).
    #[arg(long)]
    pub takeover: bool,
    /// The estimator: fused (the posterior of every measurement so far, χ²-gated) or snapshot (the
    /// paper's Chan fix of each measurement alone).
    #[arg(long, value_name = "KIND", default_value = "fused")]
    #[serde(serialize_with = "runtime::flags::display")]
    pub estimator: EstimatorKind,
    /// The fused estimator's emitter model: static or constant_velocity.
    #[arg(long, value_name = "MODEL", default_value = "static")]
    #[serde(serialize_with = "runtime::flags::display")]
    pub emitter_model: EmitterModel,
    /// constant_velocity: white-acceleration process noise σ_a, m/s² (≥ 0).
    #[arg(long, value_name = "M/S2", default_value_t = 0.05)]
    #[serde(serialize_with = "runtime::flags::finite")]
    pub process_noise_accel: f64,
    /// constant_velocity: σ per axis of the initial velocity (0 ± this), m/s (> 0).
    #[arg(long, value_name = "M/S", default_value_t = 20.0)]
    #[serde(serialize_with = "runtime::flags::finite")]
    pub velocity_prior_sigma: f64,
    /// constant_velocity: the time between two steps' measurements, s (the scenario's dt).
    #[arg(long, value_name = "S", default_value_t = 10.0)]
    #[serde(serialize_with = "runtime::flags::finite")]
    pub interval_s: f64,
}

pub use runtime::ProcessError;

/// What the estimator did, printed as its `summary` line.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct EstimatorSummary {
    /// What every data process reports (role, instance, counts, hand-over, CPU).
    #[serde(flatten)]
    pub node: runtime::NodeSummary,
    /// Estimates published as `failed` (Chan failed; the previous estimate stands).
    pub failed: u64,
    /// Measurements held because the state after the step before them was not known (see the module
    /// docs); each is estimated once the state comes.
    pub out_of_chain: u64,
}

impl EstimatorArgs {
    /// The estimator configuration of the flags; errors name the flag.
    pub fn config(&self) -> Result<EstimatorConfig, ProcessError> {
        let dynamics =
            Dynamics::new(self.emitter_model, self.interval_s, self.process_noise_accel, self.velocity_prior_sigma)
                .map_err(|e| {
                    let flag = match &e {
                        e if e.to_string().contains("process_noise_accel") => "--process-noise-accel",
                        e if e.to_string().contains("velocity_prior") => "--velocity-prior-sigma",
                        _ => "--interval-s",
                    };
                    ProcessError::Input(format!("{flag}: {e}"))
                })?;
        Ok(EstimatorConfig::new(self.estimator, dynamics))
    }
}

/// The wire form of the fused posterior beyond the position.
pub fn extra_of(posterior: Option<&Posterior>, rejected_run: u8) -> PosteriorExtra {
    let Some(p) = posterior else { return PosteriorExtra::default() };
    let mut extra = PosteriorExtra { estimator: 1, model: p.model().code(), rejected_run, ..PosteriorExtra::default() };
    if p.model() == EmitterModel::ConstantVelocity {
        let (m, c) = (p.mean(), p.cov());
        extra.velocity = [m[2], m[3]];
        extra.cross_cov = [[c[(0, 2)], c[(0, 3)]], [c[(1, 2)], c[(1, 3)]]];
        extra.velocity_cov = [[c[(2, 2)], c[(2, 3)]], [c[(3, 2)], c[(3, 3)]]];
    }
    extra
}

/// The fused posterior of a usable estimate (`position`, `covariance`, `extra`); `None` for a snapshot
/// estimate or numbers that do not form a posterior.
pub fn posterior_of(position: &[f64; 2], covariance: &[[f64; 2]; 2], extra: &PosteriorExtra) -> Option<Posterior> {
    if extra.estimator != 1 {
        return None;
    }
    let model = EmitterModel::from_code(extra.model)?;
    let mean = Vector4::new(position[0], position[1], extra.velocity[0], extra.velocity[1]);
    let (c, x, v) = (covariance, extra.cross_cov, extra.velocity_cov);
    let cov = Matrix4::new(
        c[0][0], c[0][1], x[0][0], x[0][1], //
        c[1][0], c[1][1], x[1][0], x[1][1], //
        x[0][0], x[1][0], v[0][0], v[0][1], //
        x[0][1], x[1][1], v[1][0], v[1][1],
    );
    Posterior::new(model, mean, cov).ok()
}

/// Measurements held for the state before them (the newest are kept beyond).
pub const MAX_HELD: usize = 64;

/// How long an unanswered request for a state waits before it is asked again (the monitor may have been
/// restarting).
pub const STATE_RETRY: Duration = Duration::from_millis(500);

/// How long a held step waits with no monitor in the domain before the estimator asks for a replay from
/// step 0 instead (longer than a launcher's restart of the monitor: 1.6 s at most, and its start).
pub const NO_HOLDER_FALLBACK: Duration = Duration::from_secs(4);

/// Where the estimator's chain is: the library estimator and the last step it estimated.
#[derive(Debug, Default)]
struct Chain {
    estimator: Estimator,
    last_step: Option<u64>,
}

impl Chain {
    /// A fresh estimator of `config`, before any step.
    fn fresh(config: EstimatorConfig) -> Self {
        Self { estimator: Estimator::with_config(config), last_step: None }
    }

    /// The chain of an estimator of `config` after `step`, as `state` says it was.
    fn from_echo(config: EstimatorConfig, state: &EchoedState) -> Self {
        match *state {
            EchoedState::State { step, estimate: (position, covariance), extra } => {
                let (z, m) = tdoa::estimate_from_arrays(&position, &covariance);
                let posterior = posterior_of(&position, &covariance, &extra);
                let estimator = Estimator::resume(config, step, z, m, posterior).with_rejected_run(extra.rejected_run);
                Self { estimator, last_step: Some(step) }
            }
            EchoedState::Empty { step } => Self { last_step: Some(step), ..Self::fresh(config) },
        }
    }
}

/// A measurement held until the state before it is known, with the time it was received.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Held {
    /// The measurement.
    pub measurement: Measurement,
    /// When it was received ([`protocol::now_ns`]).
    pub received_ns: u64,
}

/// The estimator's per-run state: its chain, the states after earlier steps that the messages carried
/// (each command echoes the state it was planned from, [`protocol::StateEcho`]; the monitor sends the ones
/// asked for), and the measurements held for a state not yet known. A step seen again — a replay, or a
/// world rewound to an older snapshot — is estimated again from the state before it, giving the same
/// estimate bit for bit. No answer is kept.
#[derive(Debug, Default)]
pub struct StepEstimator {
    config: EstimatorConfig,
    chain: Chain,
    states: StateStore,
    held: BTreeMap<u64, Held>,
    /// The highest step estimated (a step at or below it is estimated again).
    highest: Option<u64>,
}

/// The estimate of one step as it goes on the wire: the fix, the fused state beyond the position, and
/// for a failed fix the standing estimate (the last usable one, what the step is planned from).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reply {
    /// The fix of this step.
    pub fix: Fix,
    /// The fused posterior beyond the position.
    pub extra: PosteriorExtra,
    /// Failed: the standing estimate (position, covariance), if any.
    pub standing: Option<([f64; 2], [[f64; 2]; 2])>,
}

impl Reply {
    /// The wire estimate of measurement `m` with this answer (received at `received_ns`, sequence number
    /// `seq`, from estimator instance `instance`): the fix, the fused state and the standing estimate.
    pub fn to_estimate(
        &self,
        m: &Measurement,
        received_ns: u64,
        seq: u64,
        instance: u64,
    ) -> Result<Estimate, protocol::ProtocolError> {
        Ok(Estimate::from_measurement(m, received_ns, seq, instance, self.fix)?
            .with_extra(&self.extra)
            .with_standing(self.standing))
    }
}

/// What [`StepEstimator::handle`] did with a measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Answer {
    /// A step estimated for the first time.
    New(Reply),
    /// A step estimated again (a replay, a rewound world), from the state before it.
    Again(Reply),
    /// Not estimated yet: the state after the step before it is not known; the measurement is held
    /// until it is (see [`StepEstimator::wanted`]).
    OutOfChain,
}

impl StepEstimator {
    /// A fresh state of a snapshot estimator.
    pub fn new() -> Self {
        Self::default()
    }

    /// A fresh state of an estimator of `config`.
    pub fn with_config(config: EstimatorConfig) -> Self {
        Self { config, chain: Chain::fresh(config), ..Self::default() }
    }

    /// The state of an estimator of `config` whose estimate of `step` was `position` with `covariance`
    /// and the fused state `extra` (taking over from it): the next step it estimates is `step + 1`.
    pub fn resume(
        config: EstimatorConfig,
        step: u64,
        position: [f64; 2],
        covariance: [[f64; 2]; 2],
        extra: &PosteriorExtra,
    ) -> Self {
        let state = EchoedState::State { step, estimate: (position, covariance), extra: *extra };
        Self { config, chain: Chain::from_echo(config, &state), highest: Some(step), ..Self::default() }
    }

    /// The last step estimated.
    pub fn last_step(&self) -> Option<u64> {
        self.chain.last_step
    }

    /// Keeps a state a message carried (a command's echo, the monitor's answer; the first one per step).
    pub fn remember(&mut self, state: StateEcho) {
        self.states.keep(state);
    }

    /// The step whose state the oldest held measurement waits for (to ask for it), if any.
    pub fn wanted(&self) -> Option<u64> {
        self.held.keys().next().map(|&k| k - 1)
    }

    /// The answer to a (validated) measurement received at `received_ns`; see the module docs. An
    /// out-of-chain measurement is held.
    pub fn handle(&mut self, m: &Measurement, received_ns: u64) -> Answer {
        let step = m.header.step;
        let again = self.highest.is_some_and(|h| step <= h);
        if step == 0 {
            // A new run (or the run replayed from its start).
            self.chain = Chain::fresh(self.config);
        } else if self.chain.last_step != Some(step - 1) {
            match self.states.get(step - 1) {
                Some(state) => self.chain = Chain::from_echo(self.config, &state),
                None => {
                    self.held.insert(step, Held { measurement: *m, received_ns });
                    while self.held.len() > MAX_HELD {
                        self.held.pop_first();
                    }
                    return Answer::OutOfChain;
                }
            }
        }
        self.held.remove(&step);
        let reply = estimate_measurement(&mut self.chain.estimator, m);
        self.chain.last_step = Some(step);
        self.highest = self.highest.max(Some(step));
        if again { Answer::Again(reply) } else { Answer::New(reply) }
    }

    /// The held measurements whose predecessor's state is known now, estimated in step order (each with
    /// its answer); the others stay held.
    pub fn release(&mut self) -> Vec<(Held, Answer)> {
        let mut out = Vec::new();
        let steps: Vec<u64> = self.held.keys().copied().collect();
        for step in steps {
            let known = self.chain.last_step == Some(step - 1) || self.states.get(step - 1).is_some();
            if let Some(h) = known.then(|| self.held.remove(&step)).flatten() {
                let answer = self.handle(&h.measurement, h.received_ns);
                out.push((h, answer));
            }
        }
        out
    }
}

/// The estimate of one measurement as it goes on the wire (`Fix::Failed` when the step could not be
/// estimated; it then carries the standing estimate the library keeps, if any).
pub fn estimate_measurement(estimator: &mut Estimator, m: &Measurement) -> Reply {
    let uavs: Vec<Vector2<f64>> = m.uavs().iter().map(|p| Vector2::new(p[0], p[1])).collect();
    let outcome = match (NoiseModel::from_range_sigmas(m.sigmas()), RangeDiffs::from_slice(m.diffs())) {
        (Ok(noise), Ok(diffs)) => estimator.estimate(m.header.step, &uavs, &diffs, &noise).ok(),
        _ => None,
    };
    match outcome {
        Some(out) => reply_of(&out),
        // The standing estimate and the posterior beyond it: the state the next step goes on from.
        None => Reply {
            fix: Fix::Failed,
            extra: extra_of(estimator.posterior().as_ref(), estimator.rejected_run()),
            standing: estimator.previous().map(|(p, c)| tdoa::estimate_to_arrays(&p, &c)),
        },
    }
}

/// The wire form of the library estimator's output.
pub fn reply_of(out: &crate::EstimateOut) -> Reply {
    let (position, covariance) = tdoa::estimate_to_arrays(&out.position, &out.covariance);
    let fix = match out.status {
        EstimateStatus::Ok => Fix::Ok { position, covariance },
        EstimateStatus::Ambiguous => Fix::Ambiguous { position, covariance },
        EstimateStatus::Rejected { .. } => Fix::Rejected { position, covariance },
        EstimateStatus::Failed { .. } => {
            // The library returned its previous estimate: the standing one.
            return Reply {
                fix: Fix::Failed,
                extra: extra_of(out.posterior.as_ref(), out.rejected_run),
                standing: Some((position, covariance)),
            };
        }
    };
    Reply { fix, extra: extra_of(out.posterior.as_ref(), out.rejected_run), standing: None }
}

/// The estimator's handler: its ports, its state and the bookkeeping of a swap.
struct EstimatorNode<'a> {
    args: &'a EstimatorArgs,
    config: EstimatorConfig,
    measurements: &'a TopicSubscriber<Measurement>,
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
    last_seq: Option<u64>,
    state: StepEstimator,
    /// With --takeover: the step this estimator takes over from.
    from_step: Option<u64>,
    /// The last state asked for, and when.
    asked: Option<(u64, Instant)>,
    /// Since when no monitor has been there to ask (no publisher on the state topic).
    no_holder_since: Option<Instant>,
    /// The held step for which, with no monitor to ask, a replay from step 0 was asked.
    asked_from_start: Option<u64>,
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
            if e.status().is_some_and(WireStatus::is_usable) {
                let f = e.header.step + 1;
                self.state = StepEstimator::resume(self.config, e.header.step, e.position, e.covariance, &e.extra());
                self.from_step = Some(f);
                node.take_over(f, "")?;
            }
        }
        Ok(())
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
        let reply = match answer {
            Answer::New(reply) => reply,
            Answer::Again(reply) => {
                node.summary().resent += 1;
                reply
            }
            Answer::OutOfChain => {
                self.summary.out_of_chain += 1;
                node.say(format_args!("step {step}: held until the state after step {} is known", step - 1));
                return Ok(());
            }
        };
        if reply.fix == Fix::Failed {
            self.summary.failed += 1;
            node.warn(format_args!("step {step}: no fix (the previous estimate stands)"));
        }
        let seq = node.next_seq();
        let estimate = reply
            .to_estimate(m, received_ns, seq, node.instance())
            .map_err(|e| ProcessError::Failed(format!("step {step}: estimate: {e}")))?;
        self.estimates.send(&estimate)?;
        node.summary().published += 1;
        Ok(())
    }

    /// Asks for the state the oldest held measurement waits for (again after [`STATE_RETRY`]).
    fn ask(&mut self, node: &mut Node) -> Result<(), ProcessError> {
        let Some(step) = self.state.wanted() else {
            self.asked = None;
            return Ok(());
        };
        if self.asked.is_none_or(|(s, at)| s != step || at.elapsed() >= STATE_RETRY) {
            let now = Instant::now();
            let alone = self.states.publisher_count()? == 0;
            self.no_holder_since = if alone { Some(self.no_holder_since.unwrap_or(now)) } else { None };
            if self.no_holder_since.is_some_and(|t| now - t >= NO_HOLDER_FALLBACK)
                && self.asked_from_start != Some(step)
            {
                // No monitor holds the states (a pipeline run without one; a restarting monitor is back
                // well within the wait): the run from its start brings every state again — if
                // emitter-sim still keeps step 0 (else it stops the run with an error naming the steps).
                node.warn(format_args!(
                    "no monitor to ask for the state after step {step}; asking for a replay from step 0"
                ));
                node.announce(ControlKind::Replay, 0, "no state")?;
                self.asked_from_start = Some(step);
            } else {
                node.announce(ControlKind::State, step, "")?;
            }
            self.asked = Some((step, Instant::now()));
        }
        Ok(())
    }
}

impl Handler for EstimatorNode<'_> {
    fn on_wake(&mut self, node: &mut Node) -> Result<Flow, ProcessError> {
        self.follow_predecessor(node)?;
        self.take_states(node)?;
        for (held, answer) in self.state.release() {
            self.publish(node, &held.measurement, held.received_ns, answer)?;
        }
        let (batch, received_ns) = node.receive(self.measurements, &mut self.last_seq, "a measurement")?;
        for m in batch {
            if node.hands_over(m.header.step) {
                return Ok(Flow::Stop);
            }
            if self.args.takeover && self.from_step.is_none() {
                continue; // the running estimator's step
            }
            let answer = self.state.handle(&m, received_ns);
            self.publish(node, &m, received_ns, answer)?;
        }
        self.ask(node)?;
        Ok(Flow::Continue)
    }

    fn deadline(&self) -> Option<Instant> {
        self.asked.map(|(_, at)| at + STATE_RETRY)
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
    let estimates = Topic::<Estimate>::publisher(node.link(), &services::estimate(&domain))?;
    let commands = Topic::<Command>::subscriber(node.link(), &services::command(&domain))?;
    let states = Topic::<EstimatorState>::subscriber(node.link(), &services::state(&domain))?;
    let predecessor =
        args.takeover.then(|| Topic::<Estimate>::subscriber(node.link(), &services::estimate(&domain))).transpose()?;
    if !args.takeover {
        // "Replay the step in flight for me" (a no-op at the start of a launch: emitter-sim is not there).
        node.announce(ControlKind::Hello, 0, "")?;
        node.announce(ControlKind::Replay, ControlKind::IN_FLIGHT, "")?;
    }
    node.ready();
    node.say(format_args!("domain {domain}, instance {:#x}", node.instance()));
    let mut handler = EstimatorNode {
        args,
        config,
        measurements: &measurements,
        commands: &commands,
        command_seq: None,
        states: &states,
        state_seq: None,
        estimates: &estimates,
        predecessor: predecessor.as_ref(),
        predecessor_seq: HashMap::new(),
        last_seq: None,
        state: StepEstimator::with_config(config),
        from_step: None,
        asked: None,
        no_holder_since: None,
        asked_from_start: None,
        summary: EstimatorSummary::default(),
    };
    let mut inputs: Vec<&dyn Waitable> = vec![&measurements, &states];
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Noisy-free measurements of a fixed emitter by three UAVs flying east, one per step.
    fn measurement(step: u64) -> Measurement {
        let z = Vector2::new(25_000.0, 15_000.0);
        let t = step as f64 * 500.0;
        let uavs = [[1500.0 + t, 500.0], [10_000.0 + t, 1500.0], [5000.0 + t, 8500.0]];
        let r = |p: [f64; 2]| (Vector2::new(p[0], p[1]) - z).norm();
        // A small deterministic "noise" so that the prior matters and the estimates differ per step.
        let e = |i: u64| ((step * 7 + i * 3) % 11) as f64 - 5.0;
        let diffs = [r(uavs[1]) - r(uavs[0]) + e(1), r(uavs[2]) - r(uavs[0]) + e(2)];
        Measurement::new(step, step + 1, &uavs, &diffs, &[28.7712; 3], &[0.0; 3]).unwrap()
    }

    #[test]
    fn the_summary_keeps_its_flat_keys() {
        // The launcher reads `rejected` and `handed_over_at` from every summary line, whatever the role.
        let mut s = EstimatorSummary { node: runtime::NodeSummary::new(ROLE, 7), ..EstimatorSummary::default() };
        s.node.rejected = 2;
        s.node.handed_over_at = Some(9);
        s.failed = 1;
        let v = serde_json::to_value(&s).unwrap();
        assert_eq!(v["role"], "estimator");
        assert_eq!(
            (v["rejected"].as_u64(), v["handed_over_at"].as_u64(), v["failed"].as_u64()),
            (Some(2), Some(9), Some(1))
        );
        assert!(v.get("node").is_none());
    }

    #[test]
    fn flags_round_trip() {
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            args: EstimatorArgs,
        }
        use clap::Parser as _;
        let a = EstimatorArgs {
            node: runtime::NodeArgs { domain: Some("lab".into()), quiet: true, ..runtime::NodeArgs::default() },
            takeover: true,
            estimator: EstimatorKind::Snapshot,
            emitter_model: EmitterModel::ConstantVelocity,
            process_noise_accel: 0.1 + 0.2,
            velocity_prior_sigma: 7.5,
            interval_s: 1.0 / 3.0,
        };
        let flags = runtime::flags::to_flags(&a).unwrap();
        let back = Cli::try_parse_from(std::iter::once("estimator".to_string()).chain(flags)).unwrap().args;
        assert_eq!(back, a);
    }

    #[test]
    fn steps_seen_again_are_estimated_again_from_the_states_the_messages_carry() {
        let cv = Dynamics::new(EmitterModel::ConstantVelocity, 10.0, 0.05, 20.0).unwrap();
        for config in
            [EstimatorConfig::snapshot(), EstimatorConfig::fused(Dynamics::fixed()), EstimatorConfig::fused(cv)]
        {
            echo_case(config);
        }
    }

    fn reply(a: Answer) -> Reply {
        match a {
            Answer::New(r) | Answer::Again(r) => r,
            Answer::OutOfChain => panic!("out of chain"),
        }
    }

    /// Replays, restarts and rewinds of one estimator configuration give the undisturbed estimates bit for
    /// bit, with no answer and no file kept: every step seen again is estimated again from the state before
    /// it, which a command echoed or the monitor sent (fused: the posterior, velocity block included).
    fn echo_case(config: EstimatorConfig) {
        let label = format!("{:?}", config.kind);
        let mut straight = StepEstimator::with_config(config);
        let (mut reference, mut echoes) = (Vec::new(), Vec::new());
        for k in 0..=12 {
            let answer = straight.handle(&measurement(k), k);
            assert!(matches!(answer, Answer::New(..)), "{label} step {k}");
            let r = reply(answer);
            if config.kind == EstimatorKind::Fused && k > 0 {
                assert_eq!(r.extra.estimator, 1, "{label} step {k}");
            }
            // What the planner's command of step k echoes.
            let estimate = r.to_estimate(&measurement(k), 0, k + 1, 1).unwrap();
            echoes.push(protocol::StateEcho::of(&estimate).unwrap());
            reference.push(r);
        }

        // A replay of steps 5..=12 to an estimator that saw every command: the same estimates again.
        let mut live = StepEstimator::with_config(config);
        for k in 0..=12 {
            live.handle(&measurement(k), k);
            live.remember(echoes[k as usize]);
        }
        for k in 5..=12 {
            let answer = live.handle(&measurement(k), k);
            assert!(matches!(answer, Answer::Again(..)), "{label} step {k}");
            assert_eq!(reply(answer), reference[k as usize], "{label} step {k} replayed");
        }
        assert_eq!(live.wanted(), None);

        // Restarted (a fresh state, no file): the step in flight is held until the state before it comes.
        let mut restarted = StepEstimator::with_config(config);
        assert_eq!(restarted.handle(&measurement(8), 80), Answer::OutOfChain, "{label}");
        assert_eq!(restarted.handle(&measurement(9), 90), Answer::OutOfChain, "{label}");
        assert_eq!(restarted.wanted(), Some(7));
        assert!(restarted.release().is_empty(), "{label}: nothing known yet");
        restarted.remember(echoes[7]);
        let released = restarted.release();
        assert_eq!(
            released.iter().map(|(h, _)| (h.measurement.header.step, h.received_ns)).collect::<Vec<_>>(),
            vec![(8, 80), (9, 90)]
        );
        for (h, answer) in released {
            let k = h.measurement.header.step;
            assert_eq!(reply(answer), reference[k as usize], "{label} step {k} after the restart");
        }
        assert_eq!(restarted.wanted(), None);
        // … then the world rewound to step 4 (an older emitter-sim snapshot, before anything this instance
        // saw): held until the monitor sends the state after step 3, then every estimate as the
        // undisturbed one past step 12.
        assert_eq!(restarted.handle(&measurement(4), 4), Answer::OutOfChain, "{label}");
        assert_eq!(restarted.wanted(), Some(3));
        restarted.remember(echoes[3]);
        assert_eq!(reply(restarted.release()[0].1), reference[4], "{label} step 4 rewound");
        for k in 5..=12 {
            assert_eq!(reply(restarted.handle(&measurement(k), k)), reference[k as usize], "{label} step {k} rewound");
        }
        assert_eq!(restarted.last_step(), Some(12));

        // Held measurements are bounded: the newest are kept.
        let mut bare = StepEstimator::with_config(config);
        for k in 1..=MAX_HELD as u64 + 10 {
            assert_eq!(bare.handle(&measurement(100 + 2 * k), k), Answer::OutOfChain);
        }
        assert_eq!(bare.wanted(), Some(100 + 2 * 11 - 1));
    }
}
