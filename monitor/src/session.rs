//! What the monitor keeps of the run it records: the record being assembled ([`Assembler`]), the event
//! log, the latency samples and stamps, the MCAP recording, the estimator states it holds
//! ([`runtime::recovery`]) and the counts of its summary. Messages in, log lines and completed steps out:
//! no IPC (the process's handler, [`crate::process`], receives and validates; this keeps).

use std::collections::HashMap;

use protocol::{
    Command, Control, ControlKind, Estimate, Measurement, Message, MessageKind, Rejection, StateEcho, Truth, now_ns,
};
use runtime::ProcessError;
use runtime::recovery::StateStore;
use serde_json::json;

use crate::assemble::{Assembler, CompletedStep, PlannerInfo};
use crate::latency::LatencySamples;
use crate::runlog::EventLog;
use crate::stamps::StampsCsv;
use crate::status::status_line;
use crate::summary::MonitorSummary;
use record::record::StepRecord;
use record::recording::{Recordable, Recorder};

/// The monitor gives the CPU away between two steps it records while fewer than this many steps are
/// waiting behind them; further behind (a CPU hog beside it takes whole time slices for each yield) it
/// records without pause until it has caught up, long before its subscriber buffers (64 messages a topic)
/// could overflow.
pub(crate) const KEEP_UP_STEPS: u64 = 8;

fn us(ns: Option<u64>) -> Option<f64> {
    ns.map(|v| v as f64 / 1e3)
}

/// The log line of a completed step (`"event": "step"`), serialised as it is: one line per step, so no
/// `serde_json::Value` tree is built for it.
#[derive(serde::Serialize)]
struct StepLine<'a> {
    step: u64,
    record: &'a StepRecord,
    latency_us: LatencyUs,
    planner: Option<&'a PlannerInfo>,
    truth: Option<[f64; 2]>,
    command_missed: bool,
    estimate_stale: bool,
    state: Option<String>,
}

/// The log line of a valid message (`"event": "message"`), one per message: serialised as it is.
#[derive(serde::Serialize)]
struct MessageLine {
    kind: &'static str,
    step: u64,
    seq: u64,
    age_us: Option<f64>,
}

/// The latencies of a step's chain, µs (`null`: not measured).
#[derive(serde::Serialize)]
struct LatencyUs {
    command_hop: Option<f64>,
    emitter: Option<f64>,
    measurement_hop: Option<f64>,
    estimator: Option<f64>,
    estimate_hop: Option<f64>,
    planner: Option<f64>,
    end_to_end: Option<f64>,
    cycle: Option<f64>,
}

/// What the monitor keeps of the run it records, between wake-ups.
pub(crate) struct Session {
    pub(crate) assembler: Assembler,
    pub(crate) log: EventLog,
    pub(crate) samples: LatencySamples,
    pub(crate) planner: Option<PlannerInfo>,
    /// The counts of the summary (filled in as the run goes).
    pub(crate) summary: MonitorSummary,
    pub(crate) quiet: bool,
    /// When the monitor first received each (kind, step) of the steps not yet recorded.
    pub(crate) received: HashMap<(MessageKind, u64), u64>,
    pub(crate) stamps: Option<StampsCsv>,
    /// An emitter-sim (re)joined since the last progress report.
    pub(crate) emitter_joined: bool,
    /// `--mcap`: every valid message, as received.
    pub(crate) recorder: Option<Recorder>,
    /// The estimator states the commands echoed, and the ones an estimator asked for
    /// ([`runtime::recovery`]).
    pub(crate) states: StateStore,
    /// The rate of rejection lines in the log and on stderr ([`runtime::LogBudget`]).
    pub(crate) rejections_logged: runtime::LogBudget,
}

impl Session {
    /// The session of a run recorded by `assembler` into `log`, holding `states` (a restarted monitor's,
    /// read back from its log); `quiet`: no status lines.
    pub(crate) fn new(assembler: Assembler, log: EventLog, states: StateStore, quiet: bool) -> Self {
        Self {
            assembler,
            log,
            samples: LatencySamples::default(),
            planner: None,
            summary: MonitorSummary { role: crate::ROLE, ..MonitorSummary::default() },
            quiet,
            received: HashMap::new(),
            stamps: None,
            emitter_joined: false,
            recorder: None,
            states,
            rejections_logged: runtime::LogBudget::default(),
        }
    }

    /// With the stamps CSV (`--stamps`) and the MCAP recording (`--mcap`).
    pub(crate) fn with_outputs(self, stamps: Option<StampsCsv>, recorder: Option<Recorder>) -> Self {
        Self { stamps, recorder, ..self }
    }

    /// A message as it arrived (before validation): the first receive time of its (kind, step) is kept
    /// for the stamps and the count of missing messages — of steps still to be recorded only (a message of
    /// a step already recorded, seen again or late, is never accounted, and its entry stayed for the rest
    /// of the run: 30 000 entries and +2 MiB of private memory over 40 000 steps of a loaded machine). A
    /// copy sent again (a replay, an answer given again: no publish stamp) is not a first arrival.
    pub(crate) fn arrived<T: Message>(&mut self, msg: &T, received_ns: u64) {
        if msg.header().stamps.published_ns != 0 && msg.header().step >= self.assembler.next_step() {
            self.received.entry((T::KIND, msg.header().step)).or_insert(received_ns);
        }
    }

    /// The rejections left out of the log since its last `rejected` line, said once at the end of the run
    /// (so that the `rejected` and `rejected_unlogged` lines add up to the node's count).
    pub(crate) fn log_unlogged_rejections(&mut self) {
        let unlogged = std::mem::take(&mut self.rejections_logged).unlogged();
        if unlogged > 0 {
            self.log.write("rejected_unlogged", json!({"count": unlogged}));
        }
    }

    /// A message that failed validation: logged within the budget of [`runtime::LogBudget`] (it is
    /// counted by the node, exactly).
    pub(crate) fn rejected(&mut self, kind: MessageKind, r: &Rejection, seq: u64) {
        if !self.admit_rejection_line() {
            return;
        }
        self.log
            .write("rejected", json!({"kind": kind.name(), "reason": r.kind(), "detail": r.to_string(), "seq": seq}));
        if !self.quiet {
            protocol::log_line!("monitor: rejected a {kind}: {r}");
        }
    }

    /// Whether a rejection's line may be written now, within the budget of [`runtime::LogBudget`]: a
    /// flood is summarised (a `rejected_unlogged` line with the lines left out before this one is written
    /// first); the counts stay exact.
    fn admit_rejection_line(&mut self) -> bool {
        let runtime::Admit::Log { unlogged } = self.rejections_logged.admit(std::time::Instant::now()) else {
            return false;
        };
        if unlogged > 0 {
            self.log.write("rejected_unlogged", json!({"count": unlogged}));
        }
        true
    }

    /// A valid message: recorded (`--mcap`), logged, and added to the run (`add`, one of
    /// [`Session::add_truth`], … ).
    pub(crate) fn accept<T: Recordable>(&mut self, msg: T, received_ns: u64, add: fn(&mut Session, T)) {
        if let Some(r) = &mut self.recorder {
            r.record(&msg, received_ns);
        }
        let h = msg.header();
        let line =
            MessageLine { kind: T::KIND.name(), step: h.step, seq: h.seq, age_us: us(h.stamps.age_ns(received_ns)) };
        self.log.write("message", &line);
        add(self, msg);
    }

    /// The step a message looks lost of, and the newest step in: the next step to record lacks a message
    /// while a step `stall_steps` or more later has some in (lock-step runs never get that far ahead
    /// otherwise). Only with a truth source: an external front end cannot replay.
    pub(crate) fn lost_step(&self, stall_steps: u64) -> Option<(u64, u64)> {
        let next = self.assembler.next_step();
        let newest = self.assembler.newest_pending_step()?;
        (newest >= next + stall_steps && !self.assembler.is_done() && self.assembler.has_truth())
            .then_some((next, newest))
    }

    /// The first step this monitor lacks, and the step after which an estimator waits for the state, when
    /// that step is not recorded here either: the messages that carry the state were lost (or sent while
    /// this monitor restarted). No later step comes while the estimator waits, so [`Session::lost_step`]
    /// never sees it; only a replay from the first step lacking makes them again. Only with a truth
    /// source, as there.
    pub(crate) fn lacks_wanted_state(&self) -> Option<(u64, u64)> {
        let next = self.assembler.next_step();
        let wanted = self.states.first_wanted_from(next)?;
        (!self.assembler.is_done() && self.assembler.has_truth()).then_some((next, wanted))
    }

    /// Adds a truth to the run.
    pub(crate) fn add_truth(&mut self, t: Truth) {
        self.assembler.add_truth(t);
    }

    /// Adds a measurement to the run. One of a step beyond the run's last (a front end that numbers its
    /// steps otherwise, or runs longer than the launch) can never be recorded: said, as a rejection is
    /// (floods summarised), and counted with the messages ignored.
    pub(crate) fn add_measurement(&mut self, m: Measurement) {
        let (step, last) = (m.header.step, self.assembler.last_step());
        if self.assembler.add_measurement(m) || step <= last || !self.admit_rejection_line() {
            return;
        }
        self.log.write("beyond_last_step", json!({"kind": "measurement", "step": step, "last": last}));
        if !self.quiet {
            protocol::log_line!(
                "monitor: ignored the measurement of step {step}: this run's steps are 0..={last} (launch --steps {last})"
            );
        }
    }

    /// Adds an estimate to the run and keeps the state after its step, which it carries whole (it also
    /// covers a step the planner held on, whose command echoes none).
    pub(crate) fn add_estimate(&mut self, e: Estimate) {
        if let Some(echo) = StateEcho::of(&e) {
            self.states.keep(echo);
        }
        self.assembler.add_estimate(e);
    }

    /// Adds a command to the run and keeps the state it echoes.
    pub(crate) fn add_command(&mut self, c: Command) {
        self.states.keep(c.state);
        self.assembler.add_command(c);
    }

    /// Writes the stamps rows and log lines gathered since the last call (the rows first: a monitor
    /// killed between the two has a row of a step its log lacks, which its successor drops), then
    /// reports a write error of the log, the recording or the stamps (disk full, …), naming the file.
    pub(crate) fn flush_outputs(&mut self) -> Result<(), ProcessError> {
        if let Some(stamps) = &mut self.stamps {
            stamps.flush();
        }
        self.log.flush();
        self.log.check()?;
        if let Some(r) = &self.recorder {
            r.check().map_err(ProcessError::Failed)?;
        }
        if let Some(stamps) = &self.stamps {
            stamps.check()?;
        }
        Ok(())
    }

    /// Logs and shows who joined or took over.
    pub(crate) fn heard(&mut self, c: &Control) {
        if let Some(r) = &mut self.recorder {
            r.record(c, now_ns());
        }
        if c.kind() == Some(ControlKind::State) {
            self.states.want(c.header.step);
            self.log.write(
                "state_request",
                json!({"role": c.role().unwrap_or("?"), "instance": c.instance, "step": c.header.step}),
            );
            return;
        }
        if c.kind() == Some(ControlKind::Status) {
            self.log.write(
                "status",
                json!({"role": c.role().unwrap_or("?"), "instance": c.instance, "rejected": c.header.step}),
            );
            return;
        }
        let Some(kind) =
            c.kind().filter(|k| matches!(k, ControlKind::Hello | ControlKind::TakeOver | ControlKind::Replay))
        else {
            return;
        };
        let role = c.role().unwrap_or("?");
        // A (re)started emitter-sim learns where this monitor is (see `Progress`).
        self.emitter_joined |= kind == ControlKind::Hello && role == "emitter-sim";
        self.log.write(
            kind.name(),
            json!({"role": role, "instance": c.instance, "detail": c.detail(), "step": c.header.step}),
        );
        if !self.quiet {
            let what = match kind {
                ControlKind::Hello => "joined",
                ControlKind::Replay => "asks for a replay",
                _ => "takes over",
            };
            let sep = if c.detail().is_empty() { "" } else { ", " };
            let step = match c.header.step {
                ControlKind::IN_FLIGHT => "the step in flight".to_string(),
                k => format!("step {k}"),
            };
            let article = if role.starts_with(['a', 'e', 'i', 'o', 'u']) { "an" } else { "a" };
            protocol::log_line!(
                "monitor: {article} {role} {what} (instance {:#x}{sep}{}), {step}",
                c.instance,
                c.detail()
            );
        }
    }

    /// Records every step that is complete now: logs it (with the state after it), shows its status line,
    /// counts its missing messages and writes its stamps row; `rejected`: the messages rejected so far.
    ///
    /// One step at a time, giving the CPU away between two while it keeps up ([`KEEP_UP_STEPS`]): the
    /// monitor drains several steps at once ([`runtime::Node::drain_every`]), and a process of the
    /// control loop waiting for this core then runs between them instead of after all of them.
    pub(crate) fn complete_steps(&mut self, rejected: u64) {
        let mut first = true;
        while let Some(done) = self.assembler.complete_next() {
            // The recording holds every message of a step before its log line says it is recorded.
            if let (Some(r), true) = (&mut self.recorder, std::mem::take(&mut first)) {
                r.flush();
            }
            self.record_step(done, rejected);
            if self.assembler.newest_pending_step().is_none_or(|n| n < self.assembler.next_step() + KEEP_UP_STEPS) {
                std::thread::yield_now();
            }
        }
    }

    /// Logs a completed step (with the state after it), shows its status line, counts its missing
    /// messages and writes its stamps row.
    fn record_step(&mut self, done: CompletedStep, rejected: u64) {
        self.account(&done);
        if let Some(p) = &done.planner
            && self.planner.as_ref() != Some(p)
        {
            self.summary.planners += 1;
            self.log.write(
                "planner",
                json!({"instance": p.instance, "solver": p.solver, "objective": p.objective, "step": done.record.step}),
            );
            if !self.quiet && self.planner.is_some() {
                protocol::log_line!(
                    "monitor: planner switched to {}/{} (instance {:#x})",
                    p.solver,
                    p.objective,
                    p.instance
                );
            }
            self.planner = Some(p.clone());
        }
        if done.planner.is_some() {
            self.samples.add(&done.latencies);
        }
        let l = &done.latencies;
        let line = StepLine {
            step: done.record.step,
            record: &done.record,
            latency_us: LatencyUs {
                command_hop: us(l.trigger_hop_ns),
                emitter: us(l.emitter_ns),
                measurement_hop: us(l.measurement_hop_ns),
                estimator: us(l.estimator_ns),
                estimate_hop: us(l.estimate_hop_ns),
                planner: us(l.planner_ns),
                end_to_end: us(l.end_to_end_ns),
                cycle: us(l.cycle_ns),
            },
            planner: done.planner.as_ref(),
            truth: done.truth,
            command_missed: done.missed,
            estimate_stale: done.held,
            state: self.states.echo(done.record.step).map(|e| crate::runlog::state_to_hex(&e)),
        };
        self.log.write("step", &line);
        if done.missed {
            self.summary.missed_commands += 1;
            self.log.write("command_missed", json!({"step": done.record.step}));
        }
        if done.held {
            self.summary.stale_steps += 1;
            self.log.write("estimate_stale", json!({"step": done.record.step}));
        }
        if done.record.safety.is_some_and(|s| s.certified == Some(false)) {
            self.summary.uncertified_steps += 1;
            self.log.write("uncertified", json!({"step": done.record.step}));
        }
        if !self.quiet {
            protocol::log_line!("{}", status_line(&done, self.assembler.last_step(), rejected));
        }
    }

    /// Counts the step's messages that never arrived and writes its stamps row; forgets its receive times.
    fn account(&mut self, done: &CompletedStep) {
        let k = done.record.step;
        let last = k == self.assembler.last_step();
        let mut rx = [0u64; 4];
        for (i, kind) in [MessageKind::Measurement, MessageKind::Estimate, MessageKind::Command, MessageKind::Truth]
            .into_iter()
            .enumerate()
        {
            match self.received.remove(&(kind, k)) {
                Some(t) => rx[i] = t,
                None if kind == MessageKind::Command && (last || done.missed) => {}
                None if kind == MessageKind::Truth && !self.assembler.has_truth() => {}
                None => self.summary.missing_messages += 1,
            }
        }
        if let Some(csv) = &mut self.stamps {
            csv.row(k, &done.chain, done.command_received_ns, rx);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assemble::tests::{command, estimate, flown, measurement, ok, scenario, truth};
    use crate::runlog::state_to_hex;

    /// As first published (a copy sent again carries no publish stamp).
    fn stamped<T: Message>(mut m: T) -> T {
        m.header_mut().stamps.published_ns = 1;
        m
    }

    fn deliver<T: Recordable>(s: &mut Session, msg: T, add: fn(&mut Session, T)) {
        s.arrived(&msg, 5);
        s.accept(msg, 5, add);
    }

    /// A quiet session of a run of `steps` steps without a log file.
    fn unlogged(steps: usize) -> Session {
        Session::new(Assembler::new(scenario(steps)), EventLog::open(None, false).unwrap(), StateStore::new(), true)
    }

    fn request(step: u64) -> Control {
        Control::new(ControlKind::State, step, 1, 42, 1, "estimator", "").unwrap()
    }

    /// What the monitor saw in a CI run that asked for a needless replay: its drains go topic by topic,
    /// so step 4's truth — published before step 4's measurement — came after the truths were drained
    /// while measurements up to step 5 and commands up to 6 were in. The step looks lost until the truth
    /// is taken too (the monitor's second look, `MonitorNode::take_messages`).
    #[test]
    fn a_step_looks_lost_only_while_a_message_of_it_is_missing() {
        let mut s = unlogged(8);
        deliver(&mut s, stamped(truth(0)), Session::add_truth);
        for k in 1..=3 {
            deliver(&mut s, stamped(flown(k)), Session::add_truth);
        }
        for k in 0..=5 {
            deliver(&mut s, stamped(measurement(k)), Session::add_measurement);
            deliver(&mut s, stamped(estimate(k, ok(25_000.0))), Session::add_estimate);
        }
        for k in 0..=6 {
            deliver(&mut s, stamped(command(k, 4.0, 0)), Session::add_command);
        }
        s.complete_steps(0);
        assert_eq!(s.assembler.next_step(), 3, "step 3 waits for the truth of step 4");
        assert_eq!(s.lost_step(STALL), Some((3, 6)));
        assert_eq!(s.lost_step(STALL + 1), None, "not that far ahead");
        deliver(&mut s, stamped(flown(4)), Session::add_truth);
        s.complete_steps(0);
        assert_eq!(s.assembler.next_step(), 4);
        assert_eq!(s.lost_step(STALL), None, "nothing lost once the truth is in");
    }

    const STALL: u64 = 3;

    /// What the monitor saw in a long kill storm that stalled for emitter-sim's 60 s command timeout: the
    /// estimator, restarted, waited for the state after step 396, whose estimate and command the monitor
    /// (restarted just before) never got; no later step could come, so nothing looked lost. A state an
    /// estimator waits for, of a step this monitor has not recorded, is a lost message of that step.
    #[test]
    fn a_state_wanted_of_a_step_not_recorded_means_its_messages_are_lost() {
        let mut s = unlogged(8);
        deliver(&mut s, stamped(truth(0)), Session::add_truth);
        for k in 0..=2 {
            deliver(&mut s, stamped(measurement(k)), Session::add_measurement);
            deliver(&mut s, stamped(estimate(k, ok(25_000.0))), Session::add_estimate);
            deliver(&mut s, stamped(command(k, 4.0, 0)), Session::add_command);
            deliver(&mut s, stamped(flown(k + 1)), Session::add_truth);
        }
        deliver(&mut s, stamped(measurement(3)), Session::add_measurement);
        s.complete_steps(0);
        assert_eq!(s.assembler.next_step(), 3);
        // A state it has (step 1) or that comes with a step it recorded is answered, not a loss.
        s.heard(&request(1));
        assert_eq!(s.states.take_answers().len(), 1);
        assert_eq!(s.lacks_wanted_state(), None);
        // The state after step 3: its estimate and command never came, and step 4 cannot come without it.
        s.heard(&request(3));
        assert!(s.states.take_answers().is_empty());
        assert_eq!(s.lost_step(STALL), None, "no later step is in");
        assert_eq!(s.lacks_wanted_state(), Some((3, 3)));
        // A replay brings them: answered, nothing lacking any more.
        deliver(&mut s, estimate(3, ok(25_000.0)), Session::add_estimate);
        assert_eq!(s.states.take_answers().len(), 1);
        assert_eq!(s.lacks_wanted_state(), None);
    }

    #[test]
    fn a_session_logs_each_step_with_its_state_counts_what_never_came_and_answers_state_requests() {
        let (dir, path) = crate::runlog::tests::scratch_log("session");
        let log = EventLog::open(Some(&path), false).unwrap();
        let mut s = Session::new(Assembler::new(scenario(2)), log, StateStore::new(), true);

        // An estimator asks for the state after step 1 before the monitor has it: answered once it comes.
        s.heard(&request(1));
        assert!(s.states.take_answers().is_empty());
        for k in 0..=2 {
            deliver(&mut s, stamped(measurement(k)), Session::add_measurement);
            deliver(&mut s, stamped(if k == 0 { truth(0) } else { flown(k) }), Session::add_truth);
            if k == 1 {
                // Step 1's estimate is a replay (no stamps): it is not a first arrival.
                deliver(&mut s, estimate(1, ok(25_000.0)), Session::add_estimate);
            } else {
                deliver(&mut s, stamped(estimate(k, ok(25_000.0))), Session::add_estimate);
            }
            if k < 2 {
                deliver(&mut s, stamped(command(k, 4.0, 0)), Session::add_command);
            }
        }
        let answers = s.states.take_answers();
        assert_eq!(answers.iter().map(|e| e.step).collect::<Vec<_>>(), vec![1]);
        assert_eq!(Some(answers[0]), StateEcho::of(&estimate(1, ok(25_000.0))));
        // Asked again after it is known: answered at once.
        s.heard(&request(0));
        assert_eq!(s.states.take_answers().len(), 1);

        s.complete_steps(0);
        assert!(s.assembler.is_done());
        assert_eq!(s.summary.missing_messages, 1, "step 1's estimate never came as first published");
        assert_eq!(s.summary.planners, 1);
        assert!(s.received.is_empty(), "the receive times of recorded steps are forgotten");
        s.flush_outputs().unwrap();
        drop(s);

        let text = std::fs::read_to_string(&path).unwrap();
        let events: Vec<serde_json::Value> = text.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
        let steps: Vec<&serde_json::Value> = events.iter().filter(|e| e["event"] == "step").collect();
        assert_eq!(steps.len(), 3);
        for (k, e) in steps.iter().enumerate() {
            assert_eq!(e["step"], k as u64);
            let echo = StateEcho::of(&estimate(k as u64, ok(25_000.0))).unwrap();
            assert_eq!(e["state"], state_to_hex(&echo), "step {k}");
        }
        assert_eq!(events.iter().filter(|e| e["event"] == "state_request").count(), 2);
        assert_eq!(events.iter().filter(|e| e["event"] == "message").count(), 11);
        std::fs::remove_dir_all(&dir).ok();
    }
}
