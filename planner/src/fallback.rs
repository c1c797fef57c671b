//! The estimate a step is planned from: the step's own estimate when it is usable (ok or ambiguous),
//! else the usable estimate of the latest step before it — the fallback of the estimator library, which
//! keeps its previous estimate when Chan fails, and what `uavloc simulate` plans from.
//!
//! "Latest" is in *step* order, not in arrival order: a replay from the middle of the run (a restarted
//! monitor or process asks for one, a monitor that missed a message asks for one while the estimator is
//! frozen) delivers old steps after newer ones. [`UsableEstimates`] keeps, for each step received, the
//! estimate that step plans from (bounded to the last `capacity` steps); a step without a received step
//! before it takes the newest of the checkpoints at or below it (a restarted planner, or a world rewound
//! to a checkpoint), each of which holds the estimate its step planned from.
//!
//! A replay re-delivers the same estimates in step order, so the values are the same again; a new run from
//! step 0 overwrites them in order, so no step looks at an older run's estimate.

use std::collections::BTreeMap;

use nalgebra::{Matrix2, Vector2};

/// A usable estimate: ẑ (metres) and its covariance M (m²).
pub type Usable = (Vector2<f64>, Matrix2<f64>);

/// The estimate each recent step plans from (see the module docs).
#[derive(Debug, Clone)]
pub struct UsableEstimates {
    capacity: usize,
    by_step: BTreeMap<u64, Usable>,
}

impl UsableEstimates {
    /// Remembers the last `capacity` (at least 1) steps.
    pub fn new(capacity: usize) -> Self {
        Self { capacity: capacity.max(1), by_step: BTreeMap::new() }
    }

    /// Records the estimate of `step` (`own`: `Some` when it is usable) and returns what the step plans
    /// from: `own`, else the value of the latest step before it — a step received, or one of
    /// `checkpoints` (`(step, what that step planned from)`, any order) at or below `step`, whichever is
    /// later. `None`: no usable estimate yet.
    pub fn record(
        &mut self,
        step: u64,
        own: Option<Usable>,
        checkpoints: impl IntoIterator<Item = (u64, Option<Usable>)>,
    ) -> Option<Usable> {
        let value = own.or_else(|| {
            let received = self.by_step.range(..step).next_back().map(|(&k, u)| (k, Some(*u)));
            let checkpoint = checkpoints.into_iter().filter(|(k, _)| *k <= step).max_by_key(|(k, _)| *k);
            // A checkpoint of `step` itself was written from the same estimates: what it holds is the
            // value of the steps before it, since this step's own estimate is not usable.
            match (received, checkpoint) {
                (Some(r), Some(c)) => (if c.0 >= r.0 { c } else { r }).1,
                (r, c) => r.or(c).and_then(|(_, u)| u),
            }
        });
        match value {
            Some(u) => {
                self.by_step.insert(step, u);
                while self.by_step.len() > self.capacity {
                    self.by_step.pop_first();
                }
            }
            // Nothing usable up to this step (any value of another run's step is void).
            None => {
                self.by_step.remove(&step);
            }
        }
        value
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn u(x: f64) -> Option<Usable> {
        Some((Vector2::new(x, 0.0), Matrix2::identity() * x))
    }

    fn none() -> Vec<(u64, Option<Usable>)> {
        Vec::new()
    }

    #[test]
    fn a_failed_step_plans_from_the_latest_usable_step_before_it() {
        let mut e = UsableEstimates::new(100);
        assert_eq!(e.record(0, None, none()), None, "no fix yet");
        assert_eq!(e.record(1, u(1.0), none()), u(1.0));
        assert_eq!(e.record(2, None, none()), u(1.0));
        assert_eq!(e.record(3, u(3.0), none()), u(3.0));
        assert_eq!(e.record(4, None, none()), u(3.0));
    }

    #[test]
    fn a_replay_from_the_middle_arriving_late_plans_from_step_order_not_arrival_order() {
        let mut e = UsableEstimates::new(100);
        for k in 0..10 {
            e.record(k, if k == 6 { None } else { u(k as f64) }, none());
        }
        // Steps 5.. replayed after step 9: step 6 (failed) still plans from step 5, not from step 9.
        assert_eq!(e.record(5, u(5.0), none()), u(5.0));
        assert_eq!(e.record(6, None, none()), u(5.0));
        // Only step 0 replayed (e.g. a stalled replay), then a live failed step 10: from step 9.
        assert_eq!(e.record(0, u(0.0), none()), u(0.0));
        assert_eq!(e.record(10, None, none()), u(9.0));
    }

    #[test]
    fn after_a_restart_the_checkpoint_stands_for_the_steps_before_it() {
        let mut e = UsableEstimates::new(100);
        let kept = [(256, u(7.0)), (512, u(8.0)), (768, u(9.0))];
        // Resumed at 768, its estimate failed: what the checkpoint holds.
        assert_eq!(e.record(768, None, kept), u(9.0));
        assert_eq!(e.record(769, None, kept), u(9.0));
        // The world rewound to 512 (an older snapshot): that checkpoint, not the newer steps.
        assert_eq!(e.record(512, None, kept), u(8.0));
        assert_eq!(e.record(513, u(1.5), kept), u(1.5));
        assert_eq!(e.record(514, None, kept), u(1.5));
        // A received step later than the checkpoint wins over it.
        assert_eq!(e.record(770, None, kept), u(9.0), "769 (from 768's checkpoint) is later than 514");
    }

    #[test]
    fn a_new_run_does_not_plan_from_the_old_runs_estimates() {
        let mut e = UsableEstimates::new(100);
        for k in 0..5 {
            e.record(k, u(k as f64), none());
        }
        assert_eq!(e.record(0, None, none()), None, "the new run's step 0 failed: no fix yet");
        assert_eq!(e.record(1, None, none()), None);
        assert_eq!(e.record(2, u(20.0), none()), u(20.0));
        assert_eq!(e.record(3, None, none()), u(20.0));
    }

    #[test]
    fn memory_is_bounded() {
        let mut e = UsableEstimates::new(4);
        for k in 0..100 {
            e.record(k, u(k as f64), none());
        }
        assert_eq!(e.by_step.len(), 4);
        assert_eq!(e.record(100, None, none()), u(99.0));
    }
}
