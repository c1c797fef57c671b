//! The `emitter-sim` process: the world publishes the truth and a noisy measurement of step k, takes the
//! planner's command for step k, flies it, and goes on with k + 1 — in lock-step or in real time.
//!
//! A thin shell: the timing — when to publish, replay, retry, give up, fly the hold of a missed step —
//! is the pure state machine [`crate::schedule`]; the event loop is the node runtime's
//! ([`runtime::node`]). The shell measures ([`World::measure`]: noise from the stream (seed, k), the
//! numbers of `uavloc simulate`), publishes, keeps what it published and applies commands
//! ([`World::apply`]).
//!
//! Two paces (`--mode`, see [`crate::args::Mode`] and the `--help`): **lockstep** (the next step once
//! the command for the current one arrives: the exact reproduction of `uavloc simulate`) and **realtime**
//! (step k at `t0 + k·dt/X`; a command that comes after the next step is due is *missed*, the UAVs keep
//! their headings and the truth of step k + 1 tells the monitor: [`CommandOutcome::Missed`]).
//!
//! Per step: publish the [`Truth`] (with the outcome of the previous step's command) and the
//! [`Measurement`] (UAV positions, noisy range differences, σ, current headings, the stamps of the
//! command flown before it); then wait for a valid [`Command`] of the step (invalid ones are counted and
//! ignored, so are commands the world refuses). After the last planned step it publishes step `steps`
//! (recorded, not planned) and exits 0 (with `--linger` it stays and replays to whoever asks until a
//! shutdown).
//!
//! # Recovery
//!
//! It keeps the truth and measurement of the last [`HISTORY_STEPS`] steps and replays them (same data,
//! new sequence numbers) when a process asks ([`ControlKind::Replay`]: a restarted estimator or planner the
//! step in flight, a restarted monitor from its first step missing) or a
//! command is late (see [`crate::schedule`]). A restarted emitter-sim starts from the older of the two
//! world snapshots in its `--checkpoint` file (the world before a snapshot step s, written once the
//! command of step s came back; see [`runtime::recovery`]), else from step 0: the world is
//! deterministic, so it publishes exactly the measurements of its predecessor and the run fast-forwards.
//! It never carries the estimator's state: that rides the estimates and commands.
//!
//! Before step 0 it waits until the pipeline is connected — at least `--min-subscribers` subscribers on
//! the measurement topic and a publisher (the planner) on the command topic — because a message
//! published before its subscriber exists is lost. SIGINT/SIGTERM, or a [`ControlKind::Shutdown`], stop
//! it (exit code 130; 0 once lingering after the last step).

use std::collections::VecDeque;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use model::load_scenario;
use nalgebra::Vector2;
use protocol::services::{self, Domain};
use protocol::transport::{Link, TopicPublisher};
use protocol::{
    Command, CommandOutcome, Control, ControlKind, LinkState, Measurement, Message, Stamps, SwarmState, Topic,
    TopicSubscriber, Truth,
};
use runtime::recovery::{self, EMITTER_SNAPSHOTS, HISTORY_STEPS};
use runtime::{Ended, Flow, Handler, Join, Node, ProcessError, SupervisorLine};

use crate::args::{EmitterSimArgs, UavSource};
use crate::checkpoint::{self, Start};
use crate::schedule::{Action, Config, Other, Pacing, Schedule};
use crate::summary::EmitterSummary;
use model::world::{Snapshot, World};

pub use crate::ROLE;

/// Exit code when SIGINT/SIGTERM stopped the run before its end.
pub use runtime::EXIT_INTERRUPTED;

/// How often the start-up wait re-checks whether the pipeline is connected.
pub const CONNECT_POLL: Duration = Duration::from_millis(2);

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

/// `--uavs autopilots`: waits until the bridge reports every UAV flying guided with a fix (the world
/// measures from where they are), up to `timeout_s`.
fn wait_for_autopilots(node: &mut Node, swarm: &mut Swarm<'_>, n: usize, timeout_s: f64) -> Result<(), ProcessError> {
    let start = Instant::now();
    node.say(format_args!("waiting for the bridge to report all {n} UAVs flying guided"));
    loop {
        swarm.take(node)?;
        if swarm.all_flying(n) {
            return Ok(());
        }
        if start.elapsed().as_secs_f64() > timeout_s {
            let said =
                swarm.newest.map_or("no swarm state at all (is the bridge running in this domain?)".to_string(), |s| {
                    (0..s.len())
                        .map(|i| format!("UAV {i} {}", s.link_of(i).map_or("?", LinkState::name)))
                        .collect::<Vec<_>>()
                        .join(", ")
                });
            return Err(ProcessError::Failed(format!(
                "the autopilots were not all flying within {timeout_s} s (--connect-timeout-s): {said}"
            )));
        }
        node.link().sleep(CONNECT_POLL * 10)?;
    }
}

/// The world's shell on the node runtime: the ports, the world, what was published, and the schedule.
struct EmitterNode<'a> {
    args: &'a EmitterSimArgs,
    truths: &'a TopicPublisher<Truth>,
    measurements: &'a TopicPublisher<Measurement>,
    commands: &'a TopicSubscriber<Command>,
    world: World,
    sigmas: Vec<f64>,
    schedule: Schedule,
    last_seq: Option<u64>,
    /// The truth and measurement of the last [`HISTORY_STEPS`] steps published, as first published.
    sent: VecDeque<(Truth, Measurement)>,
    /// The command flown in the interval before the next step, with its receive time.
    trigger: Option<(Command, u64)>,
    /// What became of the previous step's command.
    previous: CommandOutcome,
    /// The world snapshots kept (`--checkpoint`), and the one of the step awaiting its command.
    snapshots: Vec<(Snapshot, bool)>,
    before: Option<(Snapshot, bool)>,
    /// Measurements published (replays included).
    sent_count: u64,
    /// The scenario's fingerprint, written with the snapshots.
    fingerprint: String,
    /// The scenario: its limits and safety mode make the hold of a missed step.
    scenario: model::Scenario,
    /// `--uavs autopilots`: the bridge's swarm states, the newest one and the steps' UAVs not heard for a
    /// quiet link.
    swarm: Option<Swarm<'a>>,
}

/// The UAVs as the autopilots report them (`--uavs autopilots`).
struct Swarm<'a> {
    states: &'a TopicSubscriber<SwarmState>,
    last_seq: Option<u64>,
    newest: Option<SwarmState>,
    /// UAV-steps not heard because their fix was stale or their link quiet.
    unheard: u64,
    /// The UAVs' speed (the scenario's), m/s, times the time scale: metres flown per wall second.
    speed_per_real_s: f64,
    /// Each UAV's newest fix seen (its time, position and heading): kept across bridge restarts, whose
    /// first swarm states have no fix yet.
    last_fix: Vec<Option<(u64, [f64; 2], f64)>>,
}

impl Swarm<'_> {
    /// Takes the swarm states waiting (each checked; a bad one counted and logged by the node).
    fn take(&mut self, node: &mut Node) -> Result<(), ProcessError> {
        let (batch, _) = node.receive(self.states, &mut self.last_seq, "a swarm state")?;
        for s in &batch {
            self.last_fix.resize(s.len(), None);
            for (i, kept) in self.last_fix.iter_mut().enumerate() {
                if s.has_fix(i) && kept.is_none_or(|(t, _, _)| s.fix_ns[i] >= t) {
                    *kept = Some((s.fix_ns[i], s.positions[i], s.headings[i]));
                }
            }
        }
        if let Some(s) = batch.into_iter().last() {
            self.newest = Some(s);
        }
        Ok(())
    }

    /// Whether every UAV of `n` flies guided with a fix.
    fn all_flying(&self, n: usize) -> bool {
        self.newest
            .is_some_and(|s| s.len() == n && (0..n).all(|i| s.has_fix(i) && s.link_of(i) == Some(LinkState::Flying)))
    }

    /// Puts the world's UAVs where their newest fixes put them (kept across bridge restarts); a UAV
    /// without a fix younger than `fix_timeout` is not heard this step. Returns, per UAV not heard, how far
    /// it may be from the position reported (its speed times its fix's age), metres.
    fn place(&mut self, world: &mut World, fix_timeout: Duration, k: u64) -> Result<Vec<Option<f64>>, ProcessError> {
        let n = world.positions().len();
        let now = protocol::now_ns();
        let mut unheard = 0u8;
        let mut reach = vec![None; n];
        let mut positions = Vec::with_capacity(n);
        let mut headings = Vec::with_capacity(n);
        for (i, reach) in reach.iter_mut().enumerate() {
            let Some((fix_ns, at, heading)) = self.last_fix.get(i).copied().flatten() else {
                return Err(ProcessError::Failed(format!("step {k}: the bridge never reported UAV {i}'s position")));
            };
            let age_ns = now.saturating_sub(fix_ns);
            // Heard with a fresh fix whatever the link's mode: the arrival can be timed and placed (whether
            // it may be commanded is the bridge's business).
            if age_ns > fix_timeout.as_nanos() as u64 {
                unheard |= 1 << i;
                *reach = Some(self.speed_per_real_s * age_ns as f64 * 1e-9);
            }
            positions.push(at);
            headings.push(heading);
        }
        world
            .place(&positions, &headings, unheard)
            .map_err(|e| ProcessError::failed_because(format!("step {k}: the swarm state"), e))?;
        self.unheard += u64::from(unheard.count_ones());
        Ok(reach)
    }
}

impl EmitterNode<'_> {
    /// Publishes the truth and measurement of a step (`again`: a replay, without publish stamps).
    fn send(
        &mut self,
        node: &mut Node,
        mut truth: Truth,
        mut measurement: Measurement,
        again: bool,
    ) -> Result<(), ProcessError> {
        let seq = node.next_seq();
        truth.header.seq = seq;
        measurement.header.seq = seq;
        self.truths.publish(&truth, again)?;
        self.measurements.publish(&measurement, again)?;
        self.sent_count += 1;
        Ok(())
    }

    /// Measures and publishes step `k`, keeping it for replays.
    fn publish(&mut self, node: &mut Node, k: u64) -> Result<(), ProcessError> {
        if self.args.checkpoint.is_some() && recovery::is_snapshot_step(k) {
            self.before = Some((self.world.snapshot(), self.previous == CommandOutcome::Missed));
        }
        let mut reach = Vec::new();
        if let Some(swarm) = self.swarm.as_mut() {
            swarm.take(node)?;
            reach = swarm.place(&mut self.world, Duration::from_millis(self.args.fix_timeout_ms), k)?;
            let who: Vec<String> = reach
                .iter()
                .enumerate()
                .filter_map(|(i, r)| r.map(|r| format!("UAV {i} (within {r:.0} m of its last fix)")))
                .collect();
            if !who.is_empty() {
                node.warn(format_args!("step {k}: no fresh fix of {}: not heard", who.join(", ")));
            }
        }
        // A geometry the world cannot measure (two UAVs on top of each other: a collision) is where the
        // run ends; a restart would fly into it again.
        let meas = self.world.measure().map_err(|e| {
            ProcessError::unrecoverable_because(
                format!("step {k}: measurement"),
                e,
                "; the run cannot go on (exit code 3)",
            )
        })?;
        let mut message = wire_measurement(k, &meas, &self.sigmas, self.world.headings(), self.world.receiver())
            .map_err(|e| ProcessError::failed_because(format!("step {k}: measurement"), e))?;
        // A UAV not heard for a quiet link is stated with the position σ of its reach: the planner's safety
        // margins then cover where it may be (planner --stated-position-margins).
        for (i, r) in reach.iter().enumerate() {
            if let Some(r) = r {
                let sigma = model::safety::position_sigma_of_reach(*r);
                message.position_sigmas[i] = message.position_sigmas[i].max(sigma);
            }
        }
        let z = self.world.truth();
        let mut truth =
            Truth::new(k, 0, [z.x, z.y]).with_previous_command(self.previous).with_multipath(meas.multipath);
        if let Some((cmd, received_ns)) = &self.trigger {
            message = message.carrying(cmd, *received_ns);
            // The monitor learns from the truth when the previous step's command reached the world.
            truth = truth.carrying(cmd, *received_ns);
        }
        // Forget first, then add: the ring never outgrows its capacity.
        if self.sent.len() as u64 >= HISTORY_STEPS {
            self.sent.pop_front();
        }
        self.sent.push_back((truth, message));
        self.send(node, truth, message, false)
    }

    /// Publishes kept step `j` again (new sequence number, no stamps: a replay times nothing, and a receiver
    /// tells it from the first publication by its publish stamp, 0).
    fn publish_again(&mut self, node: &mut Node, j: u64) -> Result<(), ProcessError> {
        let base = self.schedule.kept_from();
        let (mut truth, mut measurement) =
            j.checked_sub(base).and_then(|i| self.sent.get(i as usize).copied()).ok_or_else(|| {
                ProcessError::Failed(format!("step {j} is not kept for a replay (kept: from step {base})"))
            })?;
        truth.header.stamps = Stamps::default();
        measurement.header.stamps = Stamps::default();
        self.send(node, truth, measurement, true)
    }

    /// The command of the awaited step: flown (and the world before a snapshot step saved once its
    /// command came back).
    fn apply(&mut self, node: &mut Node, cmd: Command, received_ns: u64) {
        let step = cmd.header.step;
        if let Err(e) = self.world.apply(cmd.headings()) {
            node.summary().rejected += 1;
            node.warn(format_args!("step {step}: refused a command: {e}"));
            return;
        }
        self.schedule.applied(step);
        self.trigger = Some((cmd, received_ns));
        self.previous = CommandOutcome::Flown;
        if let (Some(path), Some(snapshot)) = (&self.args.checkpoint, self.before.take())
            && self.snapshots.last().is_none_or(|(s, _)| s.step < snapshot.0.step)
        {
            recovery::push_kept(&mut self.snapshots, snapshot, EMITTER_SNAPSHOTS);
            if let Err(e) = checkpoint::save(path, node.domain(), &self.fingerprint, &self.snapshots) {
                node.warn(format_args!("{e}"));
            }
        }
    }

    /// The hold flown for missed step `k` ([`planning::hold::without_plan`]), from the UAV positions its
    /// measurement reported (what the planner and the monitor see) and the headings: the measurement as
    /// published, or where it is no longer kept (a restarted process), measured again — the world at step
    /// `k` measures the same. `None` when the world is no longer at step `k`.
    fn missed_hold(&self, k: u64) -> Option<planning::hold::Hold> {
        let positions: Vec<Vector2<f64>> = match self.sent.iter().rev().find(|(_, m)| m.header.step == k) {
            Some((_, m)) => tdoa::points_from_arrays(m.uavs()),
            None => self.world.measure().ok().filter(|m| m.step == k)?.uavs,
        };
        Some(planning::hold::without_plan(&positions, self.world.headings(), &self.scenario))
    }

    /// Does what the schedule says.
    fn act(&mut self, node: &mut Node, action: Action) -> Result<Flow, ProcessError> {
        match action {
            Action::Publish(k) => {
                self.publish(node, k)?;
                if self.schedule.is_done() && self.args.linger {
                    runtime::tell(self.args.process.node.supervised, &SupervisorLine::Finished);
                }
            }
            Action::Republish(j) => self.publish_again(node, j)?,
            Action::Missed(k) => {
                // No command in time: the hold of a step without a plan, from the positions the step's
                // measurement reported (what the planner and the monitor see).
                let hold = self.missed_hold(k).ok_or_else(|| {
                    ProcessError::Failed(format!("step {k}: missed, but the world is no longer at that step"))
                })?;
                let loiters = hold.loiters(self.world.headings());
                self.world.apply(&hold.headings).map_err(|e| ProcessError::failed_because(format!("step {k}"), e))?;
                self.trigger = None;
                self.before = None;
                self.previous = CommandOutcome::Missed;
                let what = if loiters { "the UAVs loiter on their backup circles" } else { "the UAVs fly straight on" };
                node.say(format_args!("step {k}: no command before step {} was due; {what}", k + 1));
            }
            Action::Finished => return Ok(Flow::Stop),
            Action::Fail(why) => return Err(ProcessError::Failed(why)),
        }
        Ok(Flow::Continue)
    }
}

impl Handler for EmitterNode<'_> {
    fn on_wake(&mut self, node: &mut Node) -> Result<Flow, ProcessError> {
        if let Some(swarm) = self.swarm.as_mut() {
            swarm.take(node)?;
        }
        // Every message is checked and counted, also after the one that is applied.
        let (batch, received_ns) = node.receive(self.commands, &mut self.last_seq, "a command")?;
        for cmd in batch {
            let step = cmd.header.step;
            if self.schedule.wants(step) {
                self.apply(node, cmd, received_ns);
            } else if self.schedule.other_command(step) == Other::Late {
                node.say(format_args!("ignored a late command for step {step} (missed)"));
            }
        }
        for action in self.schedule.poll(Instant::now()) {
            if self.act(node, action)? == Flow::Stop {
                return Ok(Flow::Stop);
            }
        }
        Ok(Flow::Continue)
    }

    fn on_control(&mut self, node: &mut Node, c: &Control) -> Result<Flow, ProcessError> {
        self.schedule.heard(c);
        if c.kind() == Some(ControlKind::Replay)
            && let Some(role) = c.role().filter(|r| matches!(*r, "estimator" | "planner" | "monitor"))
        {
            match self.schedule.joined(c.header.step) {
                Ok(Some(from)) => {
                    node.say(format_args!("a {role} joined (instance {:#x}); replaying from step {from}", c.instance))
                }
                Ok(None) => {}
                Err(e) => {
                    return Err(ProcessError::failed_because(format!("a {role} (instance {:#x})", c.instance), e));
                }
            }
        }
        Ok(Flow::Continue)
    }

    fn deadline(&self) -> Option<Instant> {
        self.schedule.deadline()
    }
}

/// Runs the world to the end of the run.
pub fn run(args: &EmitterSimArgs) -> Result<EmitterSummary, ProcessError> {
    args.check().map_err(ProcessError::Input)?;
    let domain = Domain::resolve_named(args.process.node.domain.as_deref()).map_err(ProcessError::Input)?;
    let scenario = load_scenario(args.process.run.scenario.as_deref(), args.process.run.steps, args.process.run.seed)
        .map_err(|e| ProcessError::input_because("--scenario", e))?;
    let pacing = args.pacing(scenario.dt, scenario.steps).map_err(ProcessError::Input)?;
    let Start { world, step: start_step, missed: start_missed, snapshots } =
        checkpoint::start(args.checkpoint.as_deref(), &domain, &scenario)?;
    let fingerprint = scenario.fingerprint();
    let Some(mut node) = Node::open(ROLE, &args.process.node)? else {
        return Err(ProcessError::Interrupted);
    };
    node.set_run(scenario.run_id());
    let truths = Topic::<Truth>::publisher(node.link(), &services::truth(&domain))?;
    let measurements = Topic::<Measurement>::publisher(node.link(), &services::measurement(&domain))?;
    let commands = Topic::<Command>::subscriber(node.link(), &services::command(&domain))?;
    wait_for_pipeline(node.link(), &measurements, &commands, &domain, args)?;
    let swarm_states = (args.uavs == UavSource::Autopilots)
        .then(|| Topic::<SwarmState>::subscriber(node.link(), &services::swarm(&domain)))
        .transpose()?;
    let speed_per_real_s = scenario.speed * args.time_scale.unwrap_or(1.0);
    let mut swarm = swarm_states.as_ref().map(|states| Swarm {
        states,
        last_seq: None,
        newest: None,
        unheard: 0,
        speed_per_real_s,
        last_fix: Vec::new(),
    });
    if let Some(swarm) = swarm.as_mut() {
        wait_for_autopilots(&mut node, swarm, scenario.uav_count(), args.connect_timeout_s)?;
    }
    node.join(Join::Hello, "")?;
    if start_step > 0 {
        node.say(format_args!("resumed from the snapshot of step {start_step}"));
    }
    let pace = match pacing {
        Pacing::Lockstep { .. } => "lock-step".to_string(),
        Pacing::Realtime { interval } => {
            format!("realtime ×{} ({:.3} s per step)", args.time_scale.unwrap_or(1.0), interval.as_secs_f64())
        }
    };
    node.say(format_args!(
        "domain {domain}, {} steps, seed {}, {} UAVs, emitter at ({}, {}) m, {pace}",
        scenario.steps,
        scenario.seed,
        scenario.uav_count(),
        scenario.emitter[0],
        scenario.emitter[1]
    ));
    let config = Config {
        first: start_step,
        last: scenario.steps as u64,
        pacing,
        retry: Duration::from_millis(args.retry_interval_ms),
        timeout: Duration::from_secs_f64(args.command_timeout_s),
        linger: args.linger,
    };
    let mut world = EmitterNode {
        args,
        truths: &truths,
        measurements: &measurements,
        commands: &commands,
        world,
        sigmas: scenario.range_sigmas(),
        schedule: Schedule::new(config, Instant::now()),
        last_seq: None,
        sent: VecDeque::with_capacity(HISTORY_STEPS as usize),
        trigger: None,
        previous: match (start_step, start_missed) {
            (0, _) => CommandOutcome::None,
            (_, false) => CommandOutcome::Flown,
            (_, true) => CommandOutcome::Missed,
        },
        snapshots,
        before: None,
        sent_count: 0,
        fingerprint,
        swarm,
        scenario: scenario.clone(),
    };
    let mut inputs: Vec<&dyn protocol::Waitable> = vec![&commands];
    if let Some(s) = &swarm_states {
        inputs.push(s);
    }
    let ended = node.run(&inputs, &mut world)?;
    if matches!(ended, Ended::Interrupted | Ended::Shutdown) && !world.schedule.is_done() {
        return Err(ProcessError::Interrupted);
    }
    let node_summary = node.finish();
    let summary = EmitterSummary {
        role: ROLE,
        mode: args.mode.name(),
        counts: world.schedule.counts(),
        measurements: world.sent_count,
        accepted: node_summary.accepted,
        rejected: node_summary.rejected,
        started_at: start_step,
        cpu_s: node_summary.cpu_s,
        unheard_uav_steps: world.swarm.as_ref().map(|s| s.unheard),
    };
    if !args.process.node.quiet {
        protocol::log_line!("{}", summary.closing_lines().trim_end());
    }
    Ok(summary)
}

/// Runs emitter-sim and maps the outcome to an exit code (errors as one `error:` line on stderr); in
/// supervised mode the summary goes to stdout as `summary {json}`.
pub fn main_with(args: &EmitterSimArgs) -> ExitCode {
    runtime::exit_with(ROLE, args.process.node.supervised, run(args))
}

/// The wire form of the world's measurement `meas` of step `k`: the arrivals heard, a silent step's flag,
/// the range σ `sigmas` and the receiver model's GNSS and clock σ.
pub fn wire_measurement(
    k: u64,
    meas: &model::world::Measurement,
    sigmas: &[f64],
    headings: &[f64],
    receiver: &model::ReceiverModel,
) -> Result<Measurement, protocol::ProtocolError> {
    let uavs: Vec<[f64; 2]> = meas.uavs.iter().map(|p| [p.x, p.y]).collect();
    let arrivals: Vec<f64> = (0..uavs.len()).map(|i| meas.arrivals.arrival(i).unwrap_or(0.0)).collect();
    let mut m = if meas.silent {
        Measurement::silent(k, 0, &uavs, sigmas, headings)?
    } else {
        Measurement::heard(k, 0, &uavs, meas.arrivals.heard_mask(), &arrivals, sigmas, headings)?
    };
    if !receiver.is_perfect() {
        m = m.with_sensor_errors(
            [receiver.gnss_sigma_m, receiver.gnss_bias_sigma_m],
            [receiver.clock_sigma_ns, receiver.clock_bias_sigma_ns],
        );
    }
    Ok(m)
}
