//! Recovery, in one place: what each process keeps so that a restarted one gets back into a run, and
//! what "step" means for it.
//!
//! **Step.** Everything here counts *steps of the run*: step k is the measurement of step k, the estimate
//! made from it, the command planned from that estimate and the truth of the world when it was measured.
//! "The state after step k" is the estimator's state once it has estimated step k — what the estimate of
//! step k carries and the command of step k echoes ([`protocol::StateEcho`]); the estimate of step k + 1 is
//! made from it. "Replay from step k" means: publish the measurements (and truths) of steps k, k + 1, …
//! again, one at a time, each after the previous command came back.
//!
//! **Who holds what.**
//! - emitter-sim keeps the truth and measurement of the last [`HISTORY_STEPS`] steps for replays, and the
//!   world's snapshot every [`SNAPSHOT_EVERY`] steps (at the *snapshot steps* s = 256, 512, …: the world
//!   before step s, written to its `--checkpoint` file once the command of step s has come back; the last
//!   [`EMITTER_SNAPSHOTS`] kept). A restarted emitter-sim flies on from its *older* snapshot (from step 0
//!   while it has fewer than two), re-publishing steps it had published before.
//! - The estimator and the planner keep no file and no answer: they are functions of the messages they
//!   receive. The planner plans from what each estimate carries. The estimator continues its own chain
//!   (step k right after step k − 1, or step 0); for any other step it needs the state after k − 1 and
//!   takes it from the messages: every command echoes the state it was planned from, the estimator reads
//!   the command topic and keeps those states ([`StateStore`], the last [`HISTORY_STEPS`] steps), and for
//!   an older one — after its own restart, or a world rewound further back — it asks
//!   ([`protocol::ControlKind::State`]) and the monitor answers ([`protocol::EstimatorState`]).
//! - The monitor keeps the state after every step in a [`StateStore`] too (from the step's estimate,
//!   which carries it whole, or its command's echo), and writes each one in its log with the step's
//!   record, so a restarted monitor has them again. So the states survive any one or two processes
//!   crashing at once: the estimator's in the commands (the planner's messages), the monitor's store and
//!   its log. With no monitor in the domain for a while (processes started by hand without one), a
//!   restarted estimator asks for a replay from step 0 instead, which brings every state again while
//!   emitter-sim keeps step 0.
//! - A restarted estimator or planner asks for a replay of the step in flight
//!   ([`protocol::ControlKind::IN_FLIGHT`]); a restarted monitor asks from the first step it lacks; a
//!   monitor that lost a message likewise; a lock-step emitter-sim whose command is late publishes the
//!   step in flight again — or, when a replay asked for stopped early without an answer (its answerer
//!   was down), that replay again from where it stopped. Any step can be replayed alone: the state before
//!   it is held (above).
//! - A lock-step emitter-sim does not publish step k while the monitor's progress (the first step it
//!   lacks, [`protocol::ControlKind::Progress`]) is k − [`MONITOR_WINDOW`] or less: a monitor restarted
//!   many times cannot fall further behind (the window is below [`SNAPSHOT_EVERY`], so the first step it
//!   lacks is always newer than the older snapshot a restarted emitter-sim flies on from).
//!
//! Nothing else grows with the run: the monitor writes each step to its log as it completes and keeps no
//! per-step record in memory when it has a log. A request outside what is kept (a monitor left more than
//! [`SNAPSHOT_EVERY`] steps behind with `--monitor-window 0` or in real-time mode) is refused with an
//! error naming the steps.
//!
//! The snapshot file is JSON, written to `FILE.tmp` and renamed over `FILE` (a reader never sees half a
//! file), and carries the role and domain it belongs to; a file of another role or domain is an error. It
//! survives a crash of the process (SIGKILL), not of the machine (no fsync).

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::time::{Duration, Instant};

use protocol::{EchoedState, StateEcho};
use serde::{Deserialize, Serialize, de::DeserializeOwned};

/// Steps emitter-sim keeps for replays, and a [`StateStore`] keeps echoed states for.
pub const HISTORY_STEPS: u64 = 4096;

/// Steps between two world snapshots.
pub const SNAPSHOT_EVERY: u64 = 256;

/// World snapshots emitter-sim keeps in its checkpoint file (it restarts from the oldest).
pub const EMITTER_SNAPSHOTS: usize = 2;

/// How many steps a lock-step emitter-sim may run ahead of the monitor's progress (the default of its
/// `--monitor-window`). Below the monitor's subscriber buffers
/// ([`SUBSCRIBER_BUFFER`](protocol::transport::SUBSCRIBER_BUFFER), 64 messages per topic), with room
/// for replayed copies: a monitor within the window never has a message pushed out of a full buffer. (It
/// was once 128: a monitor starved of CPU lost the oldest messages of its full buffers and
/// got them back only by a replay.)
pub const MONITOR_WINDOW: u64 = 48;

// A monitor within the window lacks no step older than a restarted emitter-sim's older snapshot.
const _: () = assert!(MONITOR_WINDOW < SNAPSHOT_EVERY);
// A monitor within the window has at most that many unread messages per topic: they fit its buffers.
const _: () = assert!(MONITOR_WINDOW <= protocol::transport::SUBSCRIBER_BUFFER as u64);

// Every rewind point and every replay request lie within the history.
const _: () = assert!((EMITTER_SNAPSHOTS as u64 + 3) * SNAPSHOT_EVERY < HISTORY_STEPS);

/// Whether `step` is a snapshot step (256, 512, …; step 0 needs none: it starts a run).
pub fn is_snapshot_step(step: u64) -> bool {
    step > 0 && step.is_multiple_of(SNAPSHOT_EVERY)
}

/// The newest snapshot step at or below `step` (0 if none).
pub fn snapshot_step_at_or_below(step: u64) -> u64 {
    step - step % SNAPSHOT_EVERY
}

/// Requests for states not yet known that a [`StateStore`] remembers (the oldest is forgotten beyond).
pub const MAX_WANTED: usize = 64;

/// The estimator states the commands echoed, by the step they are after (the first one per step; the
/// last [`HISTORY_STEPS`] steps), and the steps whose state was asked for before it was known. The
/// estimator keeps one to go on from any step it is given; the monitor keeps one to answer the
/// estimator's requests. Plain data, no I/O.
#[derive(Debug, Default, Clone)]
pub struct StateStore {
    states: BTreeMap<u64, StateEcho>,
    wanted: BTreeSet<u64>,
}

impl StateStore {
    /// An empty store.
    pub fn new() -> Self {
        Self::default()
    }

    /// Keeps `echo` (ignored unless it holds a state: a hold's echo has none).
    pub fn keep(&mut self, echo: StateEcho) {
        if echo.decode().is_none() {
            return;
        }
        self.states.entry(echo.step).or_insert(echo);
        while self.states.len() > HISTORY_STEPS as usize {
            self.states.pop_first();
        }
    }

    /// The state after `step`, if kept.
    pub fn get(&self, step: u64) -> Option<EchoedState> {
        self.states.get(&step).and_then(StateEcho::decode)
    }

    /// The echo of the state after `step`, if kept.
    pub fn echo(&self, step: u64) -> Option<StateEcho> {
        self.states.get(&step).copied()
    }

    /// How many states are kept.
    pub fn len(&self) -> usize {
        self.states.len()
    }

    /// Whether no state is kept.
    pub fn is_empty(&self) -> bool {
        self.states.is_empty()
    }

    /// Someone asked for the state after `step`: remembered until [`take_answers`](Self::take_answers)
    /// can give it (the last [`MAX_WANTED`] requests).
    pub fn want(&mut self, step: u64) {
        self.wanted.insert(step);
        while self.wanted.len() > MAX_WANTED {
            self.wanted.pop_first();
        }
    }

    /// The oldest step at or after `from` whose state was asked for and is not known yet.
    pub fn first_wanted_from(&self, from: u64) -> Option<u64> {
        self.wanted.range(from..).next().copied()
    }

    /// The states asked for that are known now, oldest first; they are no longer wanted.
    pub fn take_answers(&mut self) -> Vec<StateEcho> {
        let known: Vec<u64> = self.wanted.iter().copied().filter(|s| self.states.contains_key(s)).collect();
        known
            .into_iter()
            .map(|s| {
                self.wanted.remove(&s);
                self.states[&s]
            })
            .collect()
    }
}

/// When the step a monitor waits for is incomplete while a message of this many steps later is in, one of
/// its messages was lost: the monitor asks emitter-sim for a replay from it.
pub const STALL_STEPS: u64 = 3;

/// How long a monitor waits for a replay it asked for (a message lost) before it asks again: longer than
/// emitter-sim's retry interval (1 s by default), which a running replay gets per step.
pub const REASK: Duration = Duration::from_secs(2);

/// How long an estimator may wait for the state after a step the monitor has not recorded before the
/// monitor takes the step's messages for lost and asks for a replay (they may be on their way).
pub const STATE_GRACE: Duration = Duration::from_secs(1);

/// Why a monitor asks for a replay from the first step it lacks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Lost {
    /// A message of this step, [`STALL_STEPS`] or more later, is in while the step waited for is not: one
    /// of its messages was lost (overwritten in a full buffer while the monitor was starved of CPU, or
    /// never sent while it was restarting).
    NewerStep(u64),
    /// An estimator has waited [`STATE_GRACE`] for the state after this step, which the monitor has not
    /// recorded either: the messages that carry it were lost, and no later step comes while it waits.
    StateWanted(u64),
}

/// The monitor's requests for the replay of lost messages, a pure state machine over (time, what the
/// monitor lacks): it asks once a loss is certain, and again every [`REASK`] while the replay does not
/// come (a replay that found the estimator down is dropped).
#[derive(Debug, Clone, Default)]
pub struct LostMessages {
    /// The step after which an estimator waits for a state the monitor lacks, and since when.
    state_waited: Option<(u64, Instant)>,
    /// The step a replay was last asked from, and when.
    asked: Option<(u64, Instant)>,
}

impl LostMessages {
    /// At `now`, with `next` the first step the monitor lacks, `newer` a message in of a step at least
    /// [`STALL_STEPS`] later (if any) and `wanted` the step after which an estimator waits for a state the
    /// monitor lacks (if any): whether to ask for a replay from `next` now, and why.
    pub fn poll(&mut self, now: Instant, next: u64, newer: Option<u64>, wanted: Option<u64>) -> Option<Lost> {
        let since = |at: Instant| now.saturating_duration_since(at);
        let state = match wanted {
            None => {
                self.state_waited = None;
                None
            }
            Some(w) => {
                if self.state_waited.is_none_or(|(s, _)| s != w) {
                    self.state_waited = Some((w, now));
                }
                self.state_waited.filter(|(_, at)| since(*at) >= STATE_GRACE).map(|_| w)
            }
        };
        let why = match (newer, state) {
            (Some(newest), _) => Lost::NewerStep(newest),
            (None, Some(w)) => Lost::StateWanted(w),
            (None, None) => return None,
        };
        if self.asked.is_some_and(|(step, at)| step == next && since(at) < REASK) {
            return None;
        }
        self.asked = Some((next, now));
        Some(why)
    }
}

/// How long the step waited for may hold its measurement without its estimate or command before the
/// monitor of an external run gives the measurement again ([`StalledStep`]): far beyond a step's
/// estimate-and-plan time (milliseconds), well within a launcher's restart (50 ms to 1.6 s) and start.
pub const STALL_GRACE: Duration = Duration::from_secs(1);

/// With an external front end, which measures each step once: when the monitor gives the measurement of
/// the step it waits for again (on [`protocol::services::measurement_replay`]), a pure state machine over
/// (time, the step waited for, whether its measurement is in): once it has waited [`STALL_GRACE`] with
/// its measurement in — its estimate or command was lost with a crashed estimator or planner — and again
/// every [`REASK`] while the step does not complete. A copy is harmless: every process takes a step seen
/// again as a replay.
#[derive(Debug, Clone, Default)]
pub struct StalledStep {
    /// The step waited for with its measurement in, since when, and when it was last given again.
    waiting: Option<(u64, Instant, Option<Instant>)>,
}

impl StalledStep {
    /// At `now`, with `next` the step the monitor waits for and `measured` whether its measurement is in:
    /// whether to give that measurement again now.
    pub fn poll(&mut self, now: Instant, next: u64, measured: bool) -> bool {
        if !measured {
            self.waiting = None;
            return false;
        }
        let (step, since, given) = self.waiting.get_or_insert((next, now, None));
        if *step != next {
            *self = StalledStep { waiting: Some((next, now, None)) };
            return false;
        }
        let due = now.saturating_duration_since(*since) >= STALL_GRACE
            && given.is_none_or(|at| now.saturating_duration_since(at) >= REASK);
        if due {
            *given = Some(now);
        }
        due
    }
}

/// How long an estimator's unanswered request for a state waits before it is asked again (the monitor may
/// have been restarting).
pub const STATE_RETRY: Duration = Duration::from_millis(500);

/// How long a held step waits with no monitor in the domain before the estimator asks for a replay from
/// step 0 instead (longer than a launcher's restart of the monitor: 1.6 s at most, and its start).
pub const NO_HOLDER_FALLBACK: Duration = Duration::from_secs(4);

/// What an estimator asks for when it holds a measurement whose predecessor's state it lacks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ask {
    /// The state after this step ([`protocol::ControlKind::State`]), which the monitor answers.
    State(u64),
    /// No monitor has held the states for [`NO_HOLDER_FALLBACK`] (a pipeline run without one): a replay
    /// from step 0, which brings every state again while emitter-sim keeps step 0 (asked once per state
    /// wanted). The state after this step is wanted.
    ReplayFromStart(u64),
}

/// An estimator's requests for the states it lacks, a pure state machine over (time, the state wanted,
/// whether a monitor is there): asked at once, again every [`STATE_RETRY`] while unanswered.
#[derive(Debug, Clone, Default)]
pub struct StateRequests {
    /// The last state asked for, and when.
    asked: Option<(u64, Instant)>,
    /// Since when no monitor has been there to ask.
    no_holder_since: Option<Instant>,
    /// The state for which, with no monitor to ask, a replay from step 0 was asked.
    from_start: Option<u64>,
}

impl StateRequests {
    /// At `now`, with `wanted` the step whose state the oldest held measurement waits for (if any): what
    /// to ask for now. `alone` tells whether no monitor is there to answer; it is asked only when a request
    /// is due.
    pub fn poll<E>(
        &mut self,
        now: Instant,
        wanted: Option<u64>,
        alone: impl FnOnce() -> Result<bool, E>,
    ) -> Result<Option<Ask>, E> {
        let Some(step) = wanted else {
            self.asked = None;
            return Ok(None);
        };
        if self.asked.is_some_and(|(s, at)| s == step && now.saturating_duration_since(at) < STATE_RETRY) {
            return Ok(None);
        }
        self.no_holder_since = if alone()? { Some(self.no_holder_since.unwrap_or(now)) } else { None };
        self.asked = Some((step, now));
        let no_holder = self.no_holder_since.is_some_and(|t| now.saturating_duration_since(t) >= NO_HOLDER_FALLBACK);
        if no_holder && self.from_start != Some(step) {
            self.from_start = Some(step);
            return Ok(Some(Ask::ReplayFromStart(step)));
        }
        Ok(Some(Ask::State(step)))
    }

    /// When the request asked last is due again.
    pub fn deadline(&self) -> Option<Instant> {
        self.asked.map(|(_, at)| at + STATE_RETRY)
    }
}

/// Adds `item` to the kept `list` (oldest first), keeping at most `keep`.
pub fn push_kept<T>(list: &mut Vec<T>, item: T, keep: usize) {
    list.push(item);
    if list.len() > keep {
        list.drain(..list.len() - keep);
    }
}

#[derive(Serialize, Deserialize)]
struct Envelope<T> {
    role: String,
    domain: String,
    state: T,
}

/// Writes `state` of `role` in `domain` to `path` (atomically: a temporary file renamed over it).
pub fn save<T: Serialize>(path: &Path, role: &str, domain: &str, state: &T) -> Result<(), String> {
    let envelope = Envelope { role: role.to_string(), domain: domain.to_string(), state };
    let text = serde_json::to_string(&envelope).map_err(|e| format!("checkpoint {}: {e}", path.display()))?;
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    std::fs::write(&tmp, text)
        .and_then(|()| std::fs::rename(&tmp, path))
        .map_err(|e| format!("checkpoint {}: {e}", path.display()))
}

/// Reads the checkpoint of `role` in `domain` from `path`: `None` if there is none; an error if the file
/// cannot be read or parsed or belongs to another role or domain.
pub fn load<T: DeserializeOwned>(path: &Path, role: &str, domain: &str) -> Result<Option<T>, String> {
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(format!("checkpoint {}: {e}", path.display())),
    };
    let envelope: Envelope<T> =
        serde_json::from_str(&text).map_err(|e| format!("checkpoint {}: not a checkpoint: {e}", path.display()))?;
    if envelope.role != role || envelope.domain != domain {
        return Err(format!(
            "checkpoint {}: written by the {} of domain {}, not by the {role} of domain {domain}",
            path.display(),
            envelope.role,
            envelope.domain
        ));
    }
    Ok(Some(envelope.state))
}

#[cfg(test)]
mod tests {

    #[test]
    fn a_stalled_step_is_given_again_after_its_grace_then_every_reask() {
        let t0 = Instant::now();
        let at = |ms: u64| t0 + Duration::from_millis(ms);
        let mut s = StalledStep::default();
        // Nothing in: nothing to give.
        assert!(!s.poll(at(0), 4, false));
        // Step 4's measurement in, its estimate not: given once the grace is over, not before.
        assert!(!s.poll(at(10), 4, true));
        assert!(!s.poll(at(1009), 4, true));
        assert!(s.poll(at(1010), 4, true));
        assert!(!s.poll(at(2000), 4, true));
        assert!(s.poll(at(3010), 4, true));
        // The step completed, the next one waits: its own grace.
        assert!(!s.poll(at(3020), 5, true));
        assert!(!s.poll(at(4000), 5, true));
        assert!(s.poll(at(4020), 5, true));
        // Its measurement not in (the front end has not measured it yet): nothing, and the clock restarts.
        assert!(!s.poll(at(9000), 6, false));
        assert!(!s.poll(at(9001), 6, true));
    }

    use super::*;

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    struct State {
        step: u64,
        x: Option<[f64; 2]>,
    }

    #[test]
    fn a_saved_state_loads_back_bit_for_bit_and_only_for_its_role_and_domain() {
        let dir = std::env::temp_dir().join(format!("uavloc-ckpt-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("estimator.ckpt");
        assert_eq!(load::<State>(&path, "estimator", "d").unwrap(), None, "no file: no checkpoint");
        let s = State { step: 512, x: Some([0.1 + 0.2, -1e-300]) };
        save(&path, "estimator", "d", &s).unwrap();
        assert_eq!(load::<State>(&path, "estimator", "d").unwrap(), Some(s));
        assert!(!dir.join("estimator.ckpt.tmp").exists());
        let other = load::<State>(&path, "planner", "d").unwrap_err();
        assert!(other.contains("not by the planner"), "{other}");
        assert!(load::<State>(&path, "estimator", "e").is_err());
        std::fs::write(&path, "{\"role\": 3").unwrap();
        assert!(load::<State>(&path, "estimator", "d").unwrap_err().contains("not a checkpoint"));
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn snapshot_steps_are_the_multiples_of_the_interval() {
        assert!(!is_snapshot_step(0) && is_snapshot_step(SNAPSHOT_EVERY) && !is_snapshot_step(1));
        assert_eq!(snapshot_step_at_or_below(SNAPSHOT_EVERY + 7), SNAPSHOT_EVERY);
        assert_eq!(snapshot_step_at_or_below(5), 0);
        let mut kept = vec![1, 2];
        push_kept(&mut kept, 3, 2);
        assert_eq!(kept, vec![2, 3]);
    }

    fn echo(step: u64, kind: u8) -> StateEcho {
        StateEcho {
            step,
            kind,
            position: [step as f64, 1.0],
            covariance: [[4.0, 0.0], [0.0, 4.0]],
            ..StateEcho::default()
        }
    }

    #[test]
    fn a_state_store_keeps_the_first_state_per_step_and_answers_what_was_asked_once_known() {
        let mut store = StateStore::new();
        store.keep(echo(3, StateEcho::NONE)); // a hold: no state
        assert!(store.is_empty());
        store.keep(echo(3, StateEcho::STATE));
        let mut other = echo(3, StateEcho::STATE);
        other.position[1] = 9.0;
        store.keep(other); // the same step again (a replay): the first is kept
        assert_eq!(store.echo(3).unwrap().position, [3.0, 1.0]);
        assert_eq!(store.get(3), echo(3, StateEcho::STATE).decode());
        store.keep(echo(4, StateEcho::EMPTY));
        assert_eq!(store.get(4), Some(EchoedState::Empty { step: 4, held: protocol::HeldBursts::default() }));

        // Asked before it is known: answered once it is, once.
        store.want(7);
        store.want(3);
        assert_eq!(store.take_answers().iter().map(|e| e.step).collect::<Vec<_>>(), vec![3]);
        assert!(store.take_answers().is_empty());
        store.keep(echo(7, StateEcho::STATE));
        assert_eq!(store.take_answers().iter().map(|e| e.step).collect::<Vec<_>>(), vec![7]);

        // Bounded: the oldest states and requests are forgotten.
        for k in 10..10 + HISTORY_STEPS + 5 {
            store.keep(echo(k, StateEcho::STATE));
        }
        assert_eq!(store.len(), HISTORY_STEPS as usize);
        assert_eq!(store.get(14), None);
        assert!(store.get(15).is_some());
        for k in 0..MAX_WANTED as u64 + 3 {
            store.want(1_000_000 + k);
        }
        store.keep(echo(1_000_000, StateEcho::STATE));
        assert!(store.take_answers().is_empty(), "the oldest request was forgotten");
    }

    #[test]
    fn a_lost_message_is_asked_for_once_per_reask_and_a_wanted_state_after_its_grace() {
        let t0 = Instant::now();
        let at = |ms: u64| t0 + Duration::from_millis(ms);
        let mut lost = LostMessages::default();
        // Nothing lacking: nothing asked.
        assert_eq!(lost.poll(at(0), 5, None, None), None);
        // A newer step is in: asked at once, not again within REASK, again after it.
        assert_eq!(lost.poll(at(0), 5, Some(9), None), Some(Lost::NewerStep(9)));
        assert_eq!(lost.poll(at(1_999), 5, Some(9), None), None);
        assert_eq!(lost.poll(at(2_000), 5, Some(10), None), Some(Lost::NewerStep(10)));
        // Another step lacking is asked for at once.
        assert_eq!(lost.poll(at(2_001), 6, Some(10), None), Some(Lost::NewerStep(10)));
        // A state wanted: only once it has been wanted for STATE_GRACE (its messages may be on their way)…
        let mut lost = LostMessages::default();
        assert_eq!(lost.poll(at(0), 7, None, Some(6)), None);
        assert_eq!(lost.poll(at(999), 7, None, Some(6)), None);
        assert_eq!(lost.poll(at(1_000), 7, None, Some(6)), Some(Lost::StateWanted(6)));
        // … a wait that ended starts again from zero, as does one for another state.
        assert_eq!(lost.poll(at(1_500), 7, None, None), None);
        assert_eq!(lost.poll(at(1_600), 8, None, Some(7)), None);
        assert_eq!(lost.poll(at(2_599), 8, None, Some(7)), None);
        assert_eq!(lost.poll(at(2_600), 8, None, Some(7)), Some(Lost::StateWanted(7)));
        // A newer step in is the first reason; the same step is not asked again within REASK either way.
        assert_eq!(lost.poll(at(2_700), 8, Some(12), Some(7)), None);
        assert_eq!(lost.poll(at(4_600), 8, Some(12), Some(7)), Some(Lost::NewerStep(12)));
    }

    #[test]
    fn a_state_is_asked_for_every_retry_and_a_replay_from_the_start_once_no_monitor_has_been_there() {
        let t0 = Instant::now();
        let at = |ms: u64| t0 + Duration::from_millis(ms);
        let ok = |alone: bool| move || Ok::<bool, ()>(alone);
        let mut asks = StateRequests::default();
        assert_eq!(asks.poll(at(0), None, ok(false)), Ok(None));
        assert_eq!(asks.deadline(), None);
        // Asked at once, again after STATE_RETRY; `alone` is not even looked at in between.
        assert_eq!(asks.poll(at(0), Some(4), ok(false)), Ok(Some(Ask::State(4))));
        assert_eq!(asks.deadline(), Some(at(500)));
        assert_eq!(asks.poll(at(499), Some(4), || Err(())), Ok(None));
        assert_eq!(asks.poll(at(500), Some(4), ok(false)), Ok(Some(Ask::State(4))));
        // Another state wanted: asked at once.
        assert_eq!(asks.poll(at(501), Some(5), ok(false)), Ok(Some(Ask::State(5))));
        // No monitor: the state is still asked for until none has been there for NO_HOLDER_FALLBACK…
        assert_eq!(asks.poll(at(1_001), Some(5), ok(true)), Ok(Some(Ask::State(5))));
        assert_eq!(asks.poll(at(4_501), Some(5), ok(true)), Ok(Some(Ask::State(5))));
        assert_eq!(asks.poll(at(5_001), Some(5), ok(true)), Ok(Some(Ask::ReplayFromStart(5))));
        // … and the replay from the start is asked once per state wanted.
        assert_eq!(asks.poll(at(5_501), Some(5), ok(true)), Ok(Some(Ask::State(5))));
        assert_eq!(asks.poll(at(6_001), Some(6), ok(true)), Ok(Some(Ask::ReplayFromStart(6))));
        // A monitor back: the wait for one starts again from zero.
        assert_eq!(asks.poll(at(6_501), Some(7), ok(false)), Ok(Some(Ask::State(7))));
        assert_eq!(asks.poll(at(7_001), Some(8), ok(true)), Ok(Some(Ask::State(8))));
        // Nothing wanted any more: nothing due.
        assert_eq!(asks.poll(at(7_002), None, ok(true)), Ok(None));
        assert_eq!(asks.deadline(), None);
    }
}
