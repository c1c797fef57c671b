//! The planner's staleness deadline: when no fresh estimate of a step arrives within a deadline after the
//! step's measurement, the planner *holds* — the UAVs loiter on their backup circles ([`planning::hold`]:
//! the continuation the last certified plan kept safe; with `safety = "waypoints"` they hold course) —
//! and flags the command ([`protocol::Command::FLAG_HOLD`]) so that the monitor shows it.
//!
//! [`HoldTracker`] is the bookkeeping, a pure state machine over (step, time) events, without any IPC:
//! - [`HoldTracker::on_measurement`] starts the deadline of a step (only of the newest step: a replayed,
//!   older measurement starts none; a step 0 that differs from the first one seen starts a new run);
//! - [`HoldTracker::on_estimate`] says whether the step's estimate is fresh (its deadline is cancelled) or
//!   late (the step was held already and is answered with the hold it got);
//! - [`HoldTracker::due`] hands out the steps whose deadline passed, which are held from then on
//!   ([`crate::wire::hold_command`]: the hold as a command).

use std::collections::{BTreeMap, BTreeSet};
use std::time::{Duration, Instant};

use nalgebra::Vector2;

/// A step whose deadline passed: where the UAVs were and how they headed when it was measured.
#[derive(Debug, Clone, PartialEq)]
pub struct DueStep {
    /// The step.
    pub step: u64,
    /// UAV positions at the step's measurement, metres.
    pub positions: Vec<Vector2<f64>>,
    /// UAV headings at the step's measurement, radians.
    pub headings: Vec<f64>,
}

/// What an estimate is to the tracker.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Freshness {
    /// In time (or no deadline was running for its step): plan it as usual.
    Fresh,
    /// Its step was held already: answer with the hold, do not plan.
    Late,
}

/// Deadlines of the steps measured but not yet estimated, and the steps held (see the module docs).
#[derive(Debug, Clone)]
pub struct HoldTracker {
    deadline: Duration,
    window: u64,
    newest: Option<u64>,
    /// The content fingerprint of the step-0 measurement of the current run.
    first: Option<u64>,
    pending: BTreeMap<u64, (Instant, DueStep)>,
    held: BTreeSet<u64>,
}

impl HoldTracker {
    /// A tracker with `deadline` (measurement received → estimate received) that remembers the held steps
    /// of the last `window` steps.
    pub fn new(deadline: Duration, window: u64) -> Self {
        Self {
            deadline,
            window: window.max(1),
            newest: None,
            first: None,
            pending: BTreeMap::new(),
            held: BTreeSet::new(),
        }
    }

    /// The deadline.
    pub fn deadline(&self) -> Duration {
        self.deadline
    }

    /// A measurement of `step` (UAVs at `positions`, heading `headings`; `fingerprint` identifies its
    /// content, see [`fingerprint`]) was received at `now`. Starts the step's deadline if it is the newest
    /// step seen and `plannable` (below the run's last step, not answered yet).
    ///
    /// A step 0 whose content differs from the first step 0 seen starts a new run (the old deadlines and
    /// holds are void). The same step 0 again is a replay (a monitor or a restarted process asked for
    /// one, or a restarted emitter-sim flies the same run again): it starts nothing and keeps the holds,
    /// which the re-flown steps are answered with.
    pub fn on_measurement(
        &mut self,
        step: u64,
        now: Instant,
        positions: Vec<Vector2<f64>>,
        headings: Vec<f64>,
        fingerprint: u64,
        plannable: bool,
    ) {
        if step == 0 {
            if self.first.is_some_and(|f| f != fingerprint) {
                // A new run: the old deadlines are void.
                self.pending.clear();
                self.held.clear();
                self.newest = None;
            }
            self.first = Some(fingerprint);
        }
        if self.newest.is_some_and(|n| step <= n) {
            return; // a replay of a step seen before
        }
        self.newest = Some(step);
        if plannable && !self.held.contains(&step) {
            self.pending.insert(step, (now + self.deadline, DueStep { step, positions, headings }));
        }
    }

    /// An estimate of `step` arrived: [`Freshness::Late`] if the step was held, else its deadline stops.
    pub fn on_estimate(&mut self, step: u64) -> Freshness {
        if self.held.contains(&step) {
            return Freshness::Late;
        }
        self.pending.remove(&step);
        Freshness::Fresh
    }

    /// Whether `step` was held.
    pub fn is_held(&self, step: u64) -> bool {
        self.held.contains(&step)
    }

    /// The steps whose deadline is over at `now` (in step order); they count as held from now on.
    pub fn due(&mut self, now: Instant) -> Vec<DueStep> {
        let over: Vec<u64> = self.pending.iter().filter(|(_, (d, _))| *d <= now).map(|(k, _)| *k).collect();
        let mut out = Vec::with_capacity(over.len());
        for k in over {
            if let Some((_, due)) = self.pending.remove(&k) {
                self.held.insert(k);
                out.push(due);
            }
        }
        if let Some(&newest) = self.held.last() {
            let keep_from = newest.saturating_sub(self.window);
            self.held = self.held.split_off(&keep_from);
        }
        out
    }

    /// The earliest running deadline.
    pub fn next_deadline(&self) -> Option<Instant> {
        self.pending.values().map(|(d, _)| *d).min()
    }
}

/// A fingerprint of a measurement's content ([`protocol::measurement_digest`]: UAV positions, arrivals,
/// noise, headings; bit exact): a replay carries the content of the first publication, so it has the
/// same fingerprint.
pub fn fingerprint(m: &protocol::Measurement) -> u64 {
    protocol::measurement_digest(m)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn measure(t: &mut HoldTracker, step: u64, now: Instant) {
        t.on_measurement(step, now, vec![Vector2::new(step as f64, 0.0)], vec![0.5], 7, true);
    }

    #[test]
    fn a_step_without_estimate_is_due_after_the_deadline_and_then_held() {
        let t0 = Instant::now();
        let mut t = HoldTracker::new(Duration::from_millis(30), 100);
        measure(&mut t, 0, t0);
        assert_eq!(t.next_deadline(), Some(t0 + Duration::from_millis(30)));
        assert!(t.due(t0 + Duration::from_millis(29)).is_empty());
        let due = t.due(t0 + Duration::from_millis(30));
        assert_eq!(due.len(), 1);
        assert_eq!((due[0].step, due[0].headings.clone()), (0, vec![0.5]));
        assert!(t.is_held(0));
        assert_eq!(t.next_deadline(), None);
        // Its estimate comes late: answered with the hold.
        assert_eq!(t.on_estimate(0), Freshness::Late);
        assert!(t.due(t0 + Duration::from_secs(9)).is_empty(), "due once only");
    }

    #[test]
    fn a_fresh_estimate_cancels_the_deadline() {
        let t0 = Instant::now();
        let mut t = HoldTracker::new(Duration::from_millis(30), 100);
        measure(&mut t, 0, t0);
        assert_eq!(t.on_estimate(0), Freshness::Fresh);
        assert!(t.due(t0 + Duration::from_secs(1)).is_empty());
        assert!(!t.is_held(0));
    }

    #[test]
    fn replays_and_unplannable_steps_start_no_deadline() {
        let t0 = Instant::now();
        let mut t = HoldTracker::new(Duration::from_millis(10), 100);
        measure(&mut t, 0, t0);
        measure(&mut t, 1, t0);
        assert_eq!(t.on_estimate(0), Freshness::Fresh);
        assert_eq!(t.on_estimate(1), Freshness::Fresh);
        measure(&mut t, 1, t0); // replayed
        t.on_measurement(2, t0, vec![Vector2::zeros()], vec![0.0], 7, false); // the final step
        assert!(t.due(t0 + Duration::from_secs(1)).is_empty());
        // A step 0 with other content is a new run.
        t.on_measurement(0, t0, vec![Vector2::zeros()], vec![0.5], 8, true);
        assert_eq!(t.due(t0 + Duration::from_secs(1)).len(), 1);
    }

    #[test]
    fn a_replayed_step_0_keeps_the_run_its_deadlines_and_its_holds() {
        // A monitor that misses an estimate of step 0 asks for a replay from it while the estimator is frozen:
        // the replayed step 0 arrives between the live steps and must not restart the run.
        let t0 = Instant::now();
        let ms = Duration::from_millis;
        let mut t = HoldTracker::new(ms(30), 100);
        for k in 0..3 {
            measure(&mut t, k, t0 + ms(100 * k));
            if k < 2 {
                assert_eq!(t.on_estimate(k), Freshness::Fresh);
            }
        }
        assert_eq!(t.due(t0 + ms(230)).len(), 1, "step 2 held");
        measure(&mut t, 0, t0 + ms(240)); // the replay
        measure(&mut t, 3, t0 + ms(300));
        measure(&mut t, 0, t0 + ms(310)); // again
        let due: Vec<u64> = t.due(t0 + ms(330)).iter().map(|d| d.step).collect();
        assert_eq!(due, vec![3], "the live step still gets its deadline");
        assert!(t.is_held(2) && t.is_held(3));
        assert_eq!(t.on_estimate(0), Freshness::Fresh);
        assert_eq!(t.on_estimate(2), Freshness::Late);
    }

    #[test]
    fn the_fingerprint_tells_a_replay_from_other_content() {
        let m = |d: f64| {
            protocol::Measurement::new(0, 1, &[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], &[d, 2.0], &[1.0; 3], &[0.0; 3])
                .unwrap()
        };
        let mut replay = m(1.0);
        replay.header.seq = 99;
        assert_eq!(fingerprint(&m(1.0)), fingerprint(&replay));
        assert_ne!(fingerprint(&m(1.0)), fingerprint(&m(1.5)));
    }

    #[test]
    fn due_steps_come_in_step_order_and_the_held_set_is_bounded() {
        let t0 = Instant::now();
        let mut t = HoldTracker::new(Duration::from_millis(1), 4);
        for k in 0..20 {
            measure(&mut t, k, t0 + Duration::from_millis(20 - k));
        }
        let due: Vec<u64> = t.due(t0 + Duration::from_secs(1)).iter().map(|d| d.step).collect();
        assert_eq!(due, (0..20).collect::<Vec<_>>());
        assert!(t.is_held(19) && t.is_held(15) && !t.is_held(14), "only the last 4 (+1) are kept");
    }
}
