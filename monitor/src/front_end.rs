//! With `--source external`: whether the front end that publishes the measurements is still there.
//!
//! A front end that leaves the measurement topic before the last step (its process ended, or died)
//! would leave the run waiting for ever. The monitor therefore ends such a run [`FRONT_END_GRACE`]
//! after the front end left, unless one comes back. A front end counts as *seen* once it has published
//! on the topic or a step of it is in (the monitor may first wake after a quick front end has gone, e.g.
//! when it was starved of CPU). A front end killed with SIGKILL stays registered until its dead node is
//! cleaned up, which the monitor does once a second while no step completes ([`FrontEndWatch::cleanup_due`]).
//!
//! Pure: the clock and the topic's publisher count come in, the verdict goes out; the process's handler
//! logs and acts on it.

use std::time::{Duration, Instant};

/// How long the monitor waits, once the front end has left the measurement topic before the last step,
/// for it (or another front end) to come back before it ends the run as one that cannot be completed
/// (exit code 3, the steps recorded are in the log).
pub const FRONT_END_GRACE: Duration = Duration::from_secs(5);

/// How long a step may wait before the dead nodes are cleaned up, and how often that is done.
pub const CLEANUP_EVERY: Duration = runtime::IDLE_WAKEUP;

/// How long the next step's measurement may be missing while a later one is in before the monitor says
/// so ([`FrontEndWatch::gap_to_report`]): a front end that skipped a step leaves the run waiting for it.
pub const GAP_REPORT_AFTER: Duration = Duration::from_secs(1);

/// What [`FrontEndWatch::observe`] found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrontEnd {
    /// No front end has been seen yet: nothing to wait for but it.
    NotSeen,
    /// A front end publishes on the measurement topic.
    Present,
    /// The front end has just left (the first observation without it).
    Left,
    /// It left less than [`FRONT_END_GRACE`] ago.
    Away,
    /// It left [`FRONT_END_GRACE`] ago or more: the run cannot be completed.
    GaveUp,
}

/// The monitor's view of the external front end across wake-ups.
#[derive(Debug, Default)]
pub struct FrontEndWatch {
    seen: bool,
    gone_since: Option<Instant>,
    cleaned_at: Option<Instant>,
    /// The next step to record, and since when it is.
    waiting: Option<(u64, Instant)>,
    /// The step whose measurement is missing while a later one is in, since when, and whether that was
    /// reported.
    gap: Option<(u64, Instant, bool)>,
}

impl FrontEndWatch {
    /// Whether to clean up the domain's dead nodes now (before counting the publishers): a front end has
    /// been seen, the next step to record (`next`) has been waited for [`CLEANUP_EVERY`] or longer, and
    /// the last clean-up is that long ago.
    pub fn cleanup_due(&mut self, now: Instant, next: u64) -> bool {
        if self.waiting.is_none_or(|(step, _)| step != next) {
            self.waiting = Some((next, now));
        }
        let stalled = self.waiting.is_some_and(|(_, since)| now - since >= CLEANUP_EVERY);
        let due = self.seen && stalled && self.cleaned_at.is_none_or(|at| now - at >= CLEANUP_EVERY);
        if due {
            self.cleaned_at = Some(now);
        }
        due
    }

    /// The gap to report at `now`, once per missing step: `gap` is the assembler's
    /// ([`crate::assemble::Assembler::measurement_gap`]: the missing step, the later step that is in),
    /// reported when it has lasted [`GAP_REPORT_AFTER`].
    pub fn gap_to_report(&mut self, now: Instant, gap: Option<(u64, u64)>) -> Option<(u64, u64)> {
        let Some((missing, later)) = gap else {
            self.gap = None;
            return None;
        };
        match self.gap {
            Some((step, since, reported)) if step == missing => {
                let due = !reported && now - since >= GAP_REPORT_AFTER;
                if due {
                    self.gap = Some((step, since, true));
                }
                due.then_some((missing, later))
            }
            _ => {
                self.gap = Some((missing, now, false));
                None
            }
        }
    }

    /// The verdict at `now`, given the publishers of the measurement topic and whether a step of the front
    /// end is pending (in, not yet recorded).
    pub fn observe(&mut self, now: Instant, publishers: usize, pending: bool) -> FrontEnd {
        self.seen |= pending;
        if publishers > 0 {
            self.seen = true;
            self.gone_since = None;
            return FrontEnd::Present;
        }
        if !self.seen {
            return FrontEnd::NotSeen;
        }
        match self.gone_since {
            None => {
                self.gone_since = Some(now);
                FrontEnd::Left
            }
            Some(since) if now - since >= FRONT_END_GRACE => FrontEnd::GaveUp,
            Some(_) => FrontEnd::Away,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(t0: Instant, ms: u64) -> Instant {
        t0 + Duration::from_millis(ms)
    }

    #[test]
    fn a_front_end_never_seen_is_waited_for_without_end() {
        let (t0, mut w) = (Instant::now(), FrontEndWatch::default());
        for s in 0..100 {
            assert!(!w.cleanup_due(at(t0, s * 1000), 0), "nothing to clean up before a front end was seen");
            assert_eq!(w.observe(at(t0, s * 1000), 0, false), FrontEnd::NotSeen);
        }
    }

    #[test]
    fn a_front_end_that_leaves_ends_the_run_after_the_grace_unless_one_comes_back() {
        let (t0, mut w) = (Instant::now(), FrontEndWatch::default());
        assert_eq!(w.observe(t0, 1, false), FrontEnd::Present);
        assert_eq!(w.observe(at(t0, 10), 0, false), FrontEnd::Left);
        assert_eq!(w.observe(at(t0, 20), 0, false), FrontEnd::Away, "left is said once");
        assert_eq!(w.observe(at(t0, 5009), 0, false), FrontEnd::Away);
        // One comes back within the grace: the clock starts again when it leaves again.
        assert_eq!(w.observe(at(t0, 5009), 1, false), FrontEnd::Present);
        assert_eq!(w.observe(at(t0, 6000), 0, false), FrontEnd::Left);
        assert_eq!(w.observe(at(t0, 10_999), 0, false), FrontEnd::Away);
        assert_eq!(w.observe(at(t0, 11_000), 0, false), FrontEnd::GaveUp);
    }

    #[test]
    fn a_front_end_gone_before_the_monitor_looked_counts_as_seen_by_its_steps() {
        let (t0, mut w) = (Instant::now(), FrontEndWatch::default());
        assert_eq!(w.observe(t0, 0, true), FrontEnd::Left);
        assert_eq!(w.observe(at(t0, 5000), 0, false), FrontEnd::GaveUp);
    }

    #[test]
    fn a_missing_step_with_a_later_one_in_is_reported_once_after_a_second() {
        let (t0, mut w) = (Instant::now(), FrontEndWatch::default());
        assert_eq!(w.gap_to_report(t0, None), None);
        assert_eq!(w.gap_to_report(t0, Some((2, 3))), None, "not at once: the step may be on its way");
        assert_eq!(w.gap_to_report(at(t0, 999), Some((2, 4))), None);
        assert_eq!(w.gap_to_report(at(t0, 1000), Some((2, 4))), Some((2, 4)));
        assert_eq!(w.gap_to_report(at(t0, 5000), Some((2, 5))), None, "once per missing step");
        // Step 2 came; step 6 is missing while 7 is in: a new gap, its own second.
        assert_eq!(w.gap_to_report(at(t0, 5100), Some((6, 7))), None);
        assert_eq!(w.gap_to_report(at(t0, 6099), Some((6, 7))), None);
        assert_eq!(w.gap_to_report(at(t0, 6100), Some((6, 7))), Some((6, 7)));
        // The gap closed and the same step goes missing again later (a replayed run): reported again.
        assert_eq!(w.gap_to_report(at(t0, 6200), None), None);
        assert_eq!(w.gap_to_report(at(t0, 6300), Some((6, 8))), None);
        assert_eq!(w.gap_to_report(at(t0, 7300), Some((6, 8))), Some((6, 8)));
    }

    #[test]
    fn dead_nodes_are_cleaned_once_a_second_while_a_seen_front_ends_step_does_not_come() {
        let (t0, mut w) = (Instant::now(), FrontEndWatch::default());
        assert!(!w.cleanup_due(t0, 3));
        assert_eq!(w.observe(t0, 1, false), FrontEnd::Present);
        assert!(!w.cleanup_due(at(t0, 999), 3), "step 3 waited for less than a second");
        assert!(w.cleanup_due(at(t0, 1000), 3));
        assert!(!w.cleanup_due(at(t0, 1500), 3), "at most once a second");
        assert!(w.cleanup_due(at(t0, 2000), 3));
        // Step 3 came: the wait for step 4 starts now.
        assert!(!w.cleanup_due(at(t0, 2100), 4));
        assert!(!w.cleanup_due(at(t0, 3099), 4));
        assert!(w.cleanup_due(at(t0, 3100), 4));
    }
}
