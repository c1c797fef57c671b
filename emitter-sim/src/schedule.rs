//! emitter-sim's schedule: a pure state machine over (event, time), without I/O.
//!
//! The process ([`crate::process`]) feeds it what happens — a command for a step ([`Schedule::wants`],
//! [`Schedule::applied`], [`Schedule::other_command`]), a process that joined and asks for a replay
//! ([`Schedule::joined`]), the monitor's progress ([`Schedule::heard`]) — and asks it what to do now
//! ([`Schedule::poll`]: publish a new step, publish a kept step again, fly the hold of a missed step,
//! finish, fail) and when to ask again ([`Schedule::deadline`]). Everything timed is here; the process
//! only measures, sends and applies.
//!
//! # Pacing
//!
//! One interface, two implementations ([`Pacing`]):
//! - **lock-step**: step k + 1 is published as soon as the command of step k is applied (after
//!   `--step-delay-ms`); the command of the current step is awaited up to the timeout (then the run
//!   fails), and when it has not come `retry` after the step was (re)published, it is published again
//!   (a process died or lost a message; every process can answer any step, see [`runtime::recovery`]). Before publishing
//!   step k it waits while the monitor lacks step k − window or older (backpressure), replaying to the
//!   monitor when it makes no progress for `retry` and failing after the timeout.
//! - **real time**: step k is due at t0 + (k − first)·interval (t0: the first publication), whatever came;
//!   the first command of step k applied before step k + 1 is due is flown, else the step is *missed*
//!   (the UAVs fly the hold, [`Action::Missed`]) and a command that comes later is counted late.
//!
//! # Replays
//!
//! A replay publishes kept steps `from..=to` again, one at a time, each after the command of the previous
//! one came back (that command is not applied). A step whose answer does not come within `retry` ends the
//! replay early: lock-step drops it (the next retry starts over from that step), real time sends that step again, and
//! after the last step (`--linger`) the replay starts over from that step. In
//! real time a replay pauses when the next step is due and goes on in the next interval, up to the step
//! current then. A request for a step older than the kept history fails the run.

use std::collections::BTreeSet;
use std::time::{Duration, Instant};

use runtime::recovery::HISTORY_STEPS;

use crate::backpressure::MonitorProgress;

/// How emitter-sim paces the run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pacing {
    /// The next step once the command of the current one is applied, after `step_delay`; the monitor may
    /// lag at most `window` steps (0: no backpressure).
    Lockstep {
        /// Wait this long before each step after the first.
        step_delay: Duration,
        /// `--monitor-window`.
        window: u64,
        /// A monitor is in the pipeline: until its first progress report it is taken to lack the first
        /// step, so the window holds from the start (a monitor starved of CPU while the run starts would
        /// otherwise fall behind without bound and lose messages from its full subscriber buffers).
        monitor_expected: bool,
    },
    /// Step k at t0 + (k − first)·`interval`.
    Realtime {
        /// The real time between two steps.
        interval: Duration,
    },
}

/// The schedule's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Config {
    /// The first step this instance publishes (0, or a snapshot's step after a restart).
    pub first: u64,
    /// The last step (`steps`: measured, not planned).
    pub last: u64,
    /// Lock-step or real time.
    pub pacing: Pacing,
    /// How long a (re)published step may go without its command before it is published again.
    pub retry: Duration,
    /// How long the command of a step (lock-step) or the monitor's progress may take in all.
    pub timeout: Duration,
    /// Stay after the last step and replay to whoever asks.
    pub linger: bool,
}

/// What the process does next.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Action {
    /// Measure and publish the new step.
    Publish(u64),
    /// Publish the kept step again.
    Republish(u64),
    /// Real time: the step's command missed it; fly the hold of a step without a plan
    /// ([`planning::hold::without_plan`]: the backup circles, or straight on with the paper's
    /// waypoint planner).
    Missed(u64),
    /// The run is over (the last step is published, and without `--linger`).
    Finished,
    /// The run cannot go on.
    Fail(String),
}

/// What a command that is not applied was.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Other {
    /// The answer to the replayed step awaited (not applied: the world is past it).
    Answer,
    /// Real time: a command for a missed step, after its time.
    Late,
    /// Any other step (a duplicate, a replay's stray answer).
    Ignored,
}

/// What the schedule counted (the process's summary takes them; its JSON keys are documented).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct Counts {
    /// Steps flown (intervals the UAVs flew: commands applied, plus missed steps in real-time mode).
    pub steps: u64,
    /// Replays started (see the module docs).
    pub replays: u64,
    /// Replays because a step's command (or the monitor's progress) was late.
    pub retries: u64,
    /// Real-time mode: steps whose command had not arrived when the next step was due (the UAVs kept
    /// their headings).
    pub missed_commands: u64,
    /// Real-time mode: commands that arrived for a missed step, after its time (ignored, not applied).
    pub late_commands: u64,
    /// Valid commands for another step than the one waited for (also the answers to replayed steps), but
    /// for missed steps (those are `late_commands`).
    pub ignored: u64,
    /// Real-time mode: the largest delay of a step's publication behind its schedule, microseconds.
    pub max_lag_us: u64,
}

/// A replay in progress.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Replay {
    /// The next step to publish again.
    next: u64,
    /// The last step (published again without waiting for its answer).
    to: u64,
    /// The step published again whose answer is awaited, and when.
    pending: Option<(u64, Instant)>,
    answered: bool,
}

/// Where the run is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// Step `k` is the next to publish (lock-step: from `ready`).
    Before { k: u64, ready: Instant },
    /// Step `k` is published; its command is awaited since `since`, last (re)published at `published`.
    Awaiting { k: u64, since: Instant, published: Instant, applied: bool },
    /// The last step is published.
    Done,
}

/// Lock-step backpressure: the monitor's first missing step as last seen, and since when.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Held {
    seen: u64,
    progressed: Instant,
    replayed: Instant,
}

/// The schedule (see the module docs).
#[derive(Debug, Clone)]
pub struct Schedule {
    cfg: Config,
    phase: Phase,
    /// The steps published by this instance: `first..published`.
    published: u64,
    t0: Option<Instant>,
    replay: Option<Replay>,
    /// A replay asked for and not started yet.
    requested: Option<u64>,
    /// Lock-step: the first step of a replay that stopped early without an answer (its requester still
    /// lacks it): the next retry starts over from there, not only from the step in flight.
    dropped: Option<u64>,
    monitor: MonitorProgress,
    held: Option<Held>,
    missed: BTreeSet<u64>,
    counts: Counts,
}

impl Schedule {
    /// The schedule of a run from `cfg.first`, starting at `now`.
    pub fn new(cfg: Config, now: Instant) -> Self {
        Self {
            cfg,
            phase: Phase::Before { k: cfg.first, ready: now },
            published: cfg.first,
            t0: None,
            replay: None,
            requested: None,
            dropped: None,
            monitor: match cfg.pacing {
                Pacing::Lockstep { monitor_expected: true, .. } => MonitorProgress::assumed(cfg.first),
                _ => MonitorProgress::default(),
            },
            held: None,
            missed: BTreeSet::new(),
            counts: Counts::default(),
        }
    }

    /// What was counted.
    pub fn counts(&self) -> Counts {
        self.counts
    }

    /// The oldest step kept for replays.
    pub fn kept_from(&self) -> u64 {
        self.published.saturating_sub(HISTORY_STEPS).max(self.cfg.first)
    }

    /// Whether a command for `step` is to be applied now (the step whose command the world waits for, no
    /// command applied yet). The process applies it and reports [`applied`](Self::applied), or counts it
    /// refused when the world refuses it.
    pub fn wants(&self, step: u64) -> bool {
        matches!(self.phase, Phase::Awaiting { k, applied: false, .. } if k == step)
    }

    /// The command of the awaited step was applied.
    pub fn applied(&mut self, step: u64) {
        if let Phase::Awaiting { k, applied, .. } = &mut self.phase
            && *k == step
        {
            *applied = true;
        }
    }

    /// A valid command that is not applied: what it was (counted).
    pub fn other_command(&mut self, step: u64) -> Other {
        if let Some(r) = &mut self.replay
            && r.pending.is_some_and(|(j, _)| j == step)
        {
            r.answered = true;
            self.counts.ignored += 1;
            Other::Answer
        } else if self.missed.contains(&step) {
            self.counts.late_commands += 1;
            Other::Late
        } else {
            self.counts.ignored += 1;
            Other::Ignored
        }
    }

    /// A process joined and asks to see the run again from step `from` ([`protocol::ControlKind::IN_FLIGHT`]:
    /// the newest step published). Nothing to replay for a step not published yet; an error for a step
    /// older than the history kept. Requests that came before the first publication are the pipeline's
    /// start: nothing to replay.
    pub fn joined(&mut self, from: u64) -> Result<Option<u64>, String> {
        if self.published == self.cfg.first {
            return Ok(None);
        }
        let from = if from == protocol::ControlKind::IN_FLIGHT { self.published - 1 } else { from };
        if from >= self.published {
            return Ok(None);
        }
        if from < self.kept_from() {
            return Err(format!(
                "a replay from step {from} was asked for, but only steps {}..={} are kept (the last {HISTORY_STEPS}); \
                 a process that lacks an older step cannot get it again in a run this long",
                self.kept_from(),
                self.published - 1
            ));
        }
        self.request(from);
        Ok(Some(from))
    }

    /// Takes a control message into account for the monitor's progress.
    pub fn heard(&mut self, c: &protocol::Control) {
        self.monitor.hear(c);
    }

    /// Real time: when step `k` is due.
    fn due(&self, k: u64) -> Option<Instant> {
        match (self.cfg.pacing, self.t0) {
            (Pacing::Realtime { interval }, Some(t0)) => Some(t0 + interval.mul_f64((k - self.cfg.first) as f64)),
            _ => None,
        }
    }

    /// Asks for a replay that must reach step `from` (merged with a request not started yet: the older
    /// start wins).
    fn request(&mut self, from: u64) {
        let start = self.replay_start(from);
        self.requested = Some(self.requested.map_or(start, |r| r.min(start)));
    }

    /// Where a replay that must reach step `k` starts: `k` itself (every process can answer any step: the
    /// estimator's state before it rides the messages, see [`runtime::recovery`]), or the oldest step kept.
    fn replay_start(&self, k: u64) -> u64 {
        k.max(self.kept_from())
    }

    /// The next instant [`poll`](Self::poll) has something to do without a new event.
    pub fn deadline(&self) -> Option<Instant> {
        let retry = self.cfg.retry;
        let replay = self.replay.and_then(|r| r.pending).map(|(_, sent)| sent + retry);
        let phase = match self.phase {
            Phase::Before { k, ready } => match self.cfg.pacing {
                Pacing::Realtime { .. } => self.due(k),
                Pacing::Lockstep { .. } => Some(match self.held {
                    Some(h) => (h.progressed + self.cfg.timeout).min(h.progressed.max(h.replayed) + retry),
                    None => ready,
                }),
            },
            Phase::Awaiting { k, since, published, .. } => match self.cfg.pacing {
                Pacing::Realtime { .. } => self.due(k + 1),
                Pacing::Lockstep { .. } => Some((since + self.cfg.timeout).min(published + retry)),
            },
            Phase::Done => None,
        };
        match (replay, phase) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// Everything to do at `now`, in order.
    pub fn poll(&mut self, now: Instant) -> Vec<Action> {
        let mut out = Vec::new();
        while let Some(action) = self.step(now) {
            let end = matches!(action, Action::Finished | Action::Fail(_));
            out.push(action);
            if end {
                break;
            }
        }
        out
    }

    /// One thing to do at `now`, if any.
    fn step(&mut self, now: Instant) -> Option<Action> {
        if let Some(a) = self.on_time(now) {
            return Some(a);
        }
        if let Some(a) = self.start_requested_replay(now).or_else(|| self.advance_replay(now)) {
            return Some(a);
        }
        if self.replay.is_some() {
            return None; // a replay in progress completes first
        }
        match self.phase {
            Phase::Before { k, ready } => self.before(k, ready, now),
            Phase::Awaiting { k, applied: true, .. } if !self.is_realtime() => {
                let delay = match self.cfg.pacing {
                    Pacing::Lockstep { step_delay, .. } => step_delay,
                    Pacing::Realtime { .. } => Duration::ZERO,
                };
                self.counts.steps += 1;
                self.phase = Phase::Before { k: k + 1, ready: now + delay };
                self.before(k + 1, now + delay, now)
            }
            Phase::Awaiting { k, since, published, .. } if !self.is_realtime() => {
                if now >= since + self.cfg.timeout {
                    return Some(Action::Fail(format!(
                        "step {k}: no command within {} s (is a planner running in this domain?)",
                        self.cfg.timeout.as_secs_f64()
                    )));
                }
                if now >= published + self.cfg.retry {
                    self.counts.retries += 1;
                    let from = self.dropped.take().map_or(k, |d| d.min(k));
                    self.request(from);
                    return self.start_requested_replay(now);
                }
                None
            }
            Phase::Awaiting { .. } => None,
            Phase::Done if !self.cfg.linger => Some(Action::Finished),
            Phase::Done => None,
        }
    }

    fn is_realtime(&self) -> bool {
        matches!(self.cfg.pacing, Pacing::Realtime { .. })
    }

    /// Real time: what the clock says comes first — the interval of the awaited step is over (flown, or
    /// missed: fly the hold; a replay in progress pauses), or the next step is due.
    fn on_time(&mut self, now: Instant) -> Option<Action> {
        if !self.is_realtime() {
            return None;
        }
        match self.phase {
            Phase::Awaiting { k, applied, .. } if self.due(k + 1).is_some_and(|d| now >= d) => {
                if let Some(r) = &mut self.replay {
                    r.pending = None;
                    r.answered = false;
                }
                self.phase = Phase::Before { k: k + 1, ready: now };
                self.counts.steps += 1;
                if applied {
                    return self.on_time(now);
                }
                self.missed.insert(k);
                self.missed = self.missed.split_off(&self.kept_from());
                self.counts.missed_commands += 1;
                Some(Action::Missed(k))
            }
            Phase::Before { k, ready } if self.due(k).is_none_or(|d| now >= d) => self.before(k, ready, now),
            _ => None,
        }
    }

    /// Step `k` is the next to publish: publishes it when it may go.
    fn before(&mut self, k: u64, ready: Instant, now: Instant) -> Option<Action> {
        match self.cfg.pacing {
            Pacing::Realtime { .. } => {
                if self.due(k).is_some_and(|d| now < d) {
                    return None;
                }
                self.t0.get_or_insert(now);
                if let Some(d) = self.due(k) {
                    self.counts.max_lag_us =
                        self.counts.max_lag_us.max(now.saturating_duration_since(d).as_micros() as u64);
                }
            }
            Pacing::Lockstep { window, .. } => {
                if now < ready {
                    return None;
                }
                if let Some(a) = self.backpressure(k, window, now) {
                    return a;
                }
            }
        }
        self.published = k + 1;
        self.phase = if k == self.cfg.last {
            Phase::Done
        } else {
            Phase::Awaiting { k, since: now, published: now, applied: false }
        };
        Some(Action::Publish(k))
    }

    /// Lock-step backpressure before step `k`: `Some` while it holds (the action to take, or none).
    fn backpressure(&mut self, k: u64, window: u64, now: Instant) -> Option<Option<Action>> {
        let held = k > 0 && self.monitor.holds(k, window);
        let Some(next) = self.monitor.next().filter(|_| held) else {
            self.held = None;
            return None;
        };
        if self.replay.is_some() {
            return Some(None);
        }
        let h = self.held.get_or_insert(Held { seen: next, progressed: now, replayed: now });
        if h.seen != next {
            *h = Held { seen: next, progressed: now, replayed: h.replayed };
        }
        let h = *h;
        if now >= h.progressed + self.cfg.timeout {
            return Some(Some(Action::Fail(format!(
                "step {k}: the monitor has lacked step {next} for {} s, and emitter-sim runs at most --monitor-window \
                 {window} steps ahead of it (is the monitor running? --monitor-window 0 runs without it)",
                self.cfg.timeout.as_secs_f64()
            ))));
        }
        if self.requested.is_none() && now >= h.progressed.max(h.replayed) + self.cfg.retry {
            self.counts.retries += 1;
            let from = self.dropped.take().map_or(next, |d| d.min(next));
            self.request(from.min(k - 1));
        }
        Some(self.start_requested_replay(now))
    }

    /// The last step a replay may reach now: the newest published.
    fn replay_end(&self) -> Option<u64> {
        self.published.checked_sub(1).filter(|_| self.published > self.cfg.first)
    }

    /// Starts the replay asked for, if any and none is running. In real time a request merges into the
    /// running replay (it goes back to the earlier step); otherwise it waits until the running one is
    /// complete — going back at every request would start a long replay over and over, and a monitor
    /// that asks once per step it lacks would get one step per replay.
    fn start_requested_replay(&mut self, now: Instant) -> Option<Action> {
        let from = self.requested?;
        let to = self.replay_end()?;
        let realtime = self.is_realtime();
        match &mut self.replay {
            Some(_) if !realtime => None,
            Some(r) => {
                if from < r.next {
                    r.next = from;
                    r.pending = None;
                }
                r.to = to;
                self.requested = None;
                self.counts.replays += 1;
                None
            }
            None => {
                self.requested = None;
                self.counts.replays += 1;
                self.replay = Some(Replay { next: from.min(to), to, pending: None, answered: false });
                if let Some(h) = &mut self.held {
                    h.replayed = now;
                }
                self.advance_replay(now)
            }
        }
    }

    /// Moves the replay in progress on (see the module docs).
    fn advance_replay(&mut self, now: Instant) -> Option<Action> {
        let mut r = self.replay?;
        let realtime = self.is_realtime();
        if realtime {
            // Up to the step current now.
            r.to = r.to.max(self.replay_end()?);
        }
        if let Some((j, sent)) = r.pending {
            if r.answered {
                r.next = j + 1;
                r.pending = None;
                r.answered = false;
            } else if now >= sent + self.cfg.retry {
                // No answer: the replay stops early at j.
                r.pending = None;
                self.replay = None;
                self.ended_early(j, now, realtime.then_some(r));
                return self.advance_replay(now).or_else(|| self.start_requested_replay(now));
            } else {
                self.replay = Some(r);
                return None;
            }
        }
        if r.next >= r.to {
            // The last step of the replay: no answer awaited.
            self.replay = None;
            self.replayed(now);
            return Some(Action::Republish(r.to));
        }
        let j = r.next;
        r.pending = Some((j, now));
        self.replay = Some(r);
        Some(Action::Republish(j))
    }

    /// A replay stopped at `j` without an answer: real time sends `j` again (`resume`), after the last
    /// step the replay starts over from `j`, lock-step drops it (the next retry starts over from `j`).
    fn ended_early(&mut self, j: u64, now: Instant, resume: Option<Replay>) {
        if let Some(r) = resume {
            self.replay = Some(Replay { next: j, pending: None, answered: false, ..r });
            return;
        }
        if self.phase == Phase::Done {
            self.counts.retries += 1;
            self.request(j);
        } else {
            self.dropped = Some(self.dropped.map_or(j, |d| d.min(j)));
        }
        self.replayed(now);
    }

    /// A lock-step replay ended: the retry timers start again.
    fn replayed(&mut self, now: Instant) {
        if let Phase::Awaiting { published, .. } = &mut self.phase
            && matches!(self.cfg.pacing, Pacing::Lockstep { .. })
        {
            *published = now;
        }
        if let Some(h) = &mut self.held {
            h.replayed = now;
        }
    }

    /// Whether the last step is published and nothing is left to do but replays (`--linger`).
    pub fn is_done(&self) -> bool {
        self.phase == Phase::Done
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::{Control, ControlKind};

    const RETRY: Duration = Duration::from_millis(100);
    const TIMEOUT: Duration = Duration::from_secs(2);

    fn ms(t0: Instant, m: u64) -> Instant {
        t0 + Duration::from_millis(m)
    }

    fn lockstep(last: u64, linger: bool, window: u64) -> Config {
        Config {
            first: 0,
            last,
            pacing: Pacing::Lockstep { step_delay: Duration::ZERO, window, monitor_expected: false },
            retry: RETRY,
            timeout: TIMEOUT,
            linger,
        }
    }

    fn progress(step: u64) -> Control {
        Control::new(ControlKind::Progress, step, 1, 7, 100, "monitor", "").unwrap()
    }

    /// Applies the awaited command of `k` at `now` and returns what follows.
    fn answer(s: &mut Schedule, k: u64, now: Instant) -> Vec<Action> {
        assert!(s.wants(k), "step {k} is awaited");
        s.applied(k);
        s.poll(now)
    }

    #[test]
    fn lockstep_runs_each_step_after_its_command_and_finishes() {
        let t0 = Instant::now();
        let mut s = Schedule::new(lockstep(3, false, 0), t0);
        assert_eq!(s.poll(t0), vec![Action::Publish(0)]);
        assert!(!s.wants(1) && s.wants(0));
        assert_eq!(s.poll(ms(t0, 50)), vec![], "waiting for the command");
        assert_eq!(s.deadline(), Some(ms(t0, 100)), "the retry is the next deadline");
        assert_eq!(answer(&mut s, 0, ms(t0, 60)), vec![Action::Publish(1)]);
        assert_eq!(answer(&mut s, 1, ms(t0, 70)), vec![Action::Publish(2)]);
        assert_eq!(answer(&mut s, 2, ms(t0, 80)), vec![Action::Publish(3), Action::Finished]);
        assert!(s.is_done());
        assert_eq!(s.counts().steps, 3);
    }

    #[test]
    fn the_step_delay_paces_lockstep() {
        let t0 = Instant::now();
        let cfg = Config {
            pacing: Pacing::Lockstep { step_delay: Duration::from_millis(30), window: 0, monitor_expected: false },
            ..lockstep(2, false, 0)
        };
        let mut s = Schedule::new(cfg, t0);
        assert_eq!(s.poll(t0), vec![Action::Publish(0)]);
        assert_eq!(answer(&mut s, 0, ms(t0, 10)), vec![]);
        assert_eq!(s.deadline(), Some(ms(t0, 40)));
        assert_eq!(s.poll(ms(t0, 39)), vec![]);
        assert_eq!(s.poll(ms(t0, 40)), vec![Action::Publish(1)]);
    }

    #[test]
    fn a_late_command_replays_the_step_in_flight_and_times_out() {
        let t0 = Instant::now();
        let mut s = Schedule::new(lockstep(10, false, 0), t0);
        s.poll(t0);
        for k in 0..3 {
            answer(&mut s, k, ms(t0, k));
        }
        // Step 3 is published at 2 ms; no command by 102 ms: step 3 again — only it: every process can
        // answer any step (the estimator's state before it rides the messages).
        assert_eq!(s.poll(ms(t0, 102)), vec![Action::Republish(3)]);
        assert_eq!((s.counts().retries, s.counts().replays), (1, 1));
        assert_eq!(s.other_command(2), Other::Ignored);
        // No answer again: the next retry comes a retry interval after the replay.
        assert_eq!(s.poll(ms(t0, 201)), vec![]);
        assert_eq!(s.poll(ms(t0, 202)), vec![Action::Republish(3)]);
        assert_eq!(s.counts().retries, 2);
        assert!(matches!(s.poll(ms(t0, 2002))[..], [Action::Fail(ref m)] if m.contains("step 3: no command")));
    }

    #[test]
    fn the_command_applied_during_a_replay_goes_on_after_it() {
        let t0 = Instant::now();
        let mut s = Schedule::new(lockstep(10, false, 0), t0);
        s.poll(t0);
        answer(&mut s, 0, t0);
        answer(&mut s, 1, t0);
        assert_eq!(s.joined(0), Ok(Some(0)));
        assert_eq!(s.poll(ms(t0, 1)), vec![Action::Republish(0)]);
        // The awaited command of step 2 comes meanwhile: applied, but the replay completes first.
        s.applied(2);
        assert_eq!(s.poll(ms(t0, 2)), vec![]);
        s.other_command(0);
        assert_eq!(s.poll(ms(t0, 3)), vec![Action::Republish(1)]);
        s.other_command(1);
        assert_eq!(s.poll(ms(t0, 4)), vec![Action::Republish(2), Action::Publish(3)]);
    }

    #[test]
    fn a_request_during_a_lockstep_replay_waits_for_it_instead_of_restarting_it() {
        // The long kill storm: a monitor that lacked a step asked for a replay from a step below it (the
        // snapshot step, as it did then) once per step it lacked; each request sent the running replay back to that step, so the
        // monitor got one step per replay and the run crawled into the command timeout.
        let t0 = Instant::now();
        let mut s = Schedule::new(lockstep(10, false, 0), t0);
        s.poll(t0);
        for k in 0..5 {
            answer(&mut s, k, t0);
        }
        assert_eq!(s.joined(0), Ok(Some(0)));
        assert_eq!(s.poll(ms(t0, 1)), vec![Action::Republish(0)]);
        s.other_command(0);
        assert_eq!(s.poll(ms(t0, 2)), vec![Action::Republish(1)]);
        assert_eq!(s.joined(0), Ok(Some(0)), "asked again meanwhile");
        s.other_command(1);
        assert_eq!(s.poll(ms(t0, 3)), vec![Action::Republish(2)], "the running replay goes on");
        for j in 2..4 {
            s.other_command(j);
            assert_eq!(s.poll(ms(t0, 4 + j)), vec![Action::Republish(j + 1)]);
        }
        s.other_command(4);
        assert_eq!(s.poll(ms(t0, 9)), vec![Action::Republish(5), Action::Republish(0)], "then the next one");
        assert_eq!(s.counts().replays, 2);
    }

    #[test]
    fn a_requested_replay_that_got_no_answer_is_started_over_by_the_next_retry() {
        // Found by the long kill storm: a restarted monitor asked for a replay from the first step it
        // lacked while the estimator was down; the replay got no answer and was dropped, and the next
        // retry republished only the step in flight — which the restarted estimator held, waiting for a
        // state only that replay would bring the monitor. The run stalled into the command timeout.
        let t0 = Instant::now();
        let mut s = Schedule::new(lockstep(10, false, 0), t0);
        s.poll(t0);
        for k in 0..5 {
            answer(&mut s, k, t0);
        }
        assert_eq!(s.joined(2), Ok(Some(2)), "the monitor asks from step 2");
        assert_eq!(s.poll(ms(t0, 1)), vec![Action::Republish(2)]);
        // No answer (the estimator is down): the replay stops early; the next retry starts it over from
        // step 2, not from the step in flight.
        let (at, next) = (2..400).find_map(|t| s.poll(ms(t0, t)).first().map(|a| (t, a.clone()))).unwrap();
        assert_eq!(next, Action::Republish(2), "at {at} ms");
        // Answered this time: the replay goes on to the step in flight, and then only that step is retried.
        for j in 2..5 {
            s.other_command(j);
            assert_eq!(s.poll(ms(t0, at + j)), vec![Action::Republish(j + 1)]);
        }
        let (_, again) = (at + 5..at + 400).find_map(|t| s.poll(ms(t0, t)).first().map(|a| (t, a.clone()))).unwrap();
        assert_eq!(again, Action::Republish(5));
    }

    #[test]
    fn joins_replay_what_they_ask_for_and_no_more() {
        let t0 = Instant::now();
        let mut s = Schedule::new(lockstep(10, false, 0), t0);
        assert_eq!(s.joined(0), Ok(None), "before the first publication: the pipeline's start");
        s.poll(t0);
        answer(&mut s, 0, t0);
        answer(&mut s, 1, t0);
        assert_eq!(s.joined(3), Ok(None), "a step not published yet");
        assert_eq!(s.joined(ControlKind::IN_FLIGHT), Ok(Some(2)), "the planner: the step in flight");
        assert_eq!(s.poll(ms(t0, 1)), vec![Action::Republish(2)]);
        assert_eq!(s.counts().replays, 1);
    }

    #[test]
    fn a_request_older_than_the_history_fails_the_run() {
        let t0 = Instant::now();
        let mut s = Schedule::new(lockstep(HISTORY_STEPS + 10, false, 0), t0);
        s.poll(t0);
        for k in 0..HISTORY_STEPS + 5 {
            answer(&mut s, k, t0);
        }
        assert_eq!(s.kept_from(), 6);
        let e = s.joined(5).unwrap_err();
        assert!(e.contains("from step 5") && e.contains("6..=4101"), "{e}");
        assert_eq!(s.joined(6), Ok(Some(6)));
    }

    #[test]
    fn an_expected_monitor_holds_the_window_before_its_first_report() {
        // Found by a flaky `bench compare`: the monitor, starved of CPU while the run started, had
        // sent no progress yet, emitter-sim ran on without bound, and the monitor's full subscriber
        // buffers dropped the oldest steps' messages (recovered by a replay, but lost the first time).
        let t0 = Instant::now();
        let cfg = |monitor_expected| Config {
            pacing: Pacing::Lockstep { step_delay: Duration::ZERO, window: 4, monitor_expected },
            first: 10,
            ..lockstep(100, false, 4)
        };
        let mut expected = Schedule::new(cfg(true), t0);
        assert_eq!(expected.poll(t0), vec![Action::Publish(10)]);
        for k in 10..13 {
            assert_eq!(answer(&mut expected, k, t0), vec![Action::Publish(k + 1)], "step {k}");
        }
        assert_eq!(answer(&mut expected, 13, t0), vec![], "step 14 waits for a monitor that lacks step 10");
        // Its first report replaces the assumption.
        expected.heard(&progress(12));
        assert_eq!(expected.poll(t0), vec![Action::Publish(14)]);
        // Without a monitor expected, nothing holds before a report.
        let mut free = Schedule::new(cfg(false), t0);
        free.poll(t0);
        for k in 10..20 {
            assert_eq!(answer(&mut free, k, t0), vec![Action::Publish(k + 1)], "step {k}");
        }
    }

    #[test]
    fn backpressure_holds_replays_to_the_monitor_and_gives_up() {
        let t0 = Instant::now();
        let mut s = Schedule::new(lockstep(100, false, 4), t0);
        s.poll(t0);
        s.heard(&progress(0));
        for k in 0..3 {
            answer(&mut s, k, t0);
        }
        // Step 4 may not go while the monitor lacks step 0 (window 4).
        assert_eq!(answer(&mut s, 3, t0), vec![]);
        assert_eq!(s.poll(ms(t0, 99)), vec![]);
        // No progress for the retry interval: replay to the monitor from the step it lacks (0) to step 3.
        assert_eq!(s.poll(ms(t0, 100)), vec![Action::Republish(0)]);
        s.other_command(0);
        assert_eq!(s.poll(ms(t0, 101)), vec![Action::Republish(1)]);
        s.other_command(1);
        assert_eq!(s.poll(ms(t0, 102)), vec![Action::Republish(2)]);
        s.other_command(2);
        assert_eq!(s.poll(ms(t0, 103)), vec![Action::Republish(3)]);
        // The monitor catches up: step 4 goes.
        s.heard(&progress(2));
        assert_eq!(s.poll(ms(t0, 104)), vec![Action::Publish(4)]);
        // It stops making progress for the whole timeout: the run fails naming the monitor.
        for k in 4..6 {
            answer(&mut s, k, ms(t0, 105));
        }
        let end = ms(t0, 105) + TIMEOUT;
        let mut failed: Vec<Action> = (0..40).flat_map(|i| s.poll(ms(t0, 105 + 100 * i))).collect();
        failed.extend(s.poll(end));
        assert!(
            matches!(failed.last(), Some(Action::Fail(m)) if m.contains("monitor has lacked step 2")),
            "{failed:?}"
        );
    }

    #[test]
    fn linger_replays_after_the_last_step_and_starts_over_when_an_answer_is_missing() {
        let t0 = Instant::now();
        let mut s = Schedule::new(lockstep(2, true, 0), t0);
        s.poll(t0);
        answer(&mut s, 0, t0);
        assert_eq!(answer(&mut s, 1, t0), vec![Action::Publish(2)], "no Finished: it lingers");
        assert!(s.is_done());
        assert_eq!(s.joined(1), Ok(Some(1)));
        assert_eq!(s.poll(ms(t0, 1)), vec![Action::Republish(1)]);
        // No answer: the replay starts over from the step that got none.
        assert_eq!(s.poll(ms(t0, 101)), vec![Action::Republish(1)]);
        assert_eq!(s.counts().retries, 1);
        s.other_command(1);
        assert_eq!(s.poll(ms(t0, 103)), vec![Action::Republish(2)]);
        assert_eq!(s.poll(ms(t0, 10_000)), vec![], "nothing left to do");
    }

    fn realtime(last: u64) -> Config {
        Config {
            first: 0,
            last,
            pacing: Pacing::Realtime { interval: Duration::from_millis(100) },
            retry: Duration::from_millis(30),
            timeout: TIMEOUT,
            linger: false,
        }
    }

    #[test]
    fn realtime_keeps_the_clock_flies_missed_steps_straight_and_counts_late_commands() {
        let t0 = Instant::now();
        let mut s = Schedule::new(realtime(3), t0);
        assert_eq!(s.poll(t0), vec![Action::Publish(0)]);
        // The command comes in time, but the next step waits for its time.
        assert_eq!(answer(&mut s, 0, ms(t0, 10)), vec![]);
        assert_eq!(s.deadline(), Some(ms(t0, 100)));
        assert_eq!(s.poll(ms(t0, 103)), vec![Action::Publish(1)]);
        assert_eq!(s.counts().max_lag_us, 3000);
        // No command for step 1: missed at 200 ms, step 2 goes at once.
        assert_eq!(s.poll(ms(t0, 200)), vec![Action::Missed(1), Action::Publish(2)]);
        assert_eq!(s.other_command(1), Other::Late);
        assert_eq!((s.counts().missed_commands, s.counts().late_commands), (1, 1));
        s.applied(2);
        assert_eq!(s.poll(ms(t0, 300)), vec![Action::Publish(3), Action::Finished]);
        assert_eq!(s.counts().steps, 3);
    }

    #[test]
    fn a_realtime_replay_pauses_when_a_step_is_due_and_goes_on_up_to_the_current_step() {
        let t0 = Instant::now();
        let mut s = Schedule::new(realtime(10), t0);
        s.poll(t0);
        answer(&mut s, 0, ms(t0, 1));
        assert_eq!(s.poll(ms(t0, 100)), vec![Action::Publish(1)]);
        assert_eq!(s.joined(0), Ok(Some(0)));
        assert_eq!(s.poll(ms(t0, 150)), vec![Action::Republish(0)]);
        // No answer within the retry interval: step 0 is sent again.
        assert_eq!(s.poll(ms(t0, 180)), vec![Action::Republish(0)]);
        // Step 2 is due: step 1 missed, step 2 published, then the replay goes on (step 0 again).
        assert_eq!(s.poll(ms(t0, 200)), vec![Action::Missed(1), Action::Publish(2), Action::Republish(0)]);
        s.other_command(0);
        assert_eq!(s.poll(ms(t0, 201)), vec![Action::Republish(1)]);
        s.other_command(1);
        assert_eq!(s.poll(ms(t0, 202)), vec![Action::Republish(2)], "up to the step current now");
    }
}
