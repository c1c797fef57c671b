//! Lock-step backpressure: how far a lock-step emitter-sim may run ahead of the monitor.
//!
//! The monitor reports its progress on the control topic ([`ControlKind::Progress`]: the first step it
//! lacks). emitter-sim does not publish step k while the monitor lacks step k − window or an older one
//! (`--monitor-window`, [`runtime::recovery::MONITOR_WINDOW`] by default), so a monitor restarted again
//! and again stays within reach of a restarted emitter-sim's replays (see [`runtime::recovery`]).

use protocol::{Control, ControlKind};

/// The monitor's progress as emitter-sim last heard it.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct MonitorProgress {
    /// The reporting instance's start time (ns, monotonic clock) and the first step it lacks.
    latest: Option<(u64, u64)>,
}

impl MonitorProgress {
    /// Takes a (validated) control message into account: a progress report of a monitor instance at least
    /// as new as the one known replaces what was known (a restarted monitor's report counts even when it
    /// is lower; an older instance's is stale). Anything else says nothing about the monitor's progress —
    /// in particular its replay request (it may ask from the snapshot step below its progress).
    pub fn hear(&mut self, c: &Control) {
        if c.kind() == Some(ControlKind::Progress)
            && c.role() == Some("monitor")
            && self.latest.is_none_or(|(known, _)| c.started_ns >= known)
        {
            self.latest = Some((c.started_ns, c.header.step));
        }
    }

    /// A monitor that has not reported yet, taken to lack step `first`: any report of a real monitor
    /// replaces it (its start time is after 0).
    pub fn assumed(first: u64) -> Self {
        Self { latest: Some((0, first)) }
    }

    /// The first step the monitor lacks, if a monitor has reported (or is assumed).
    pub fn next(&self) -> Option<u64> {
        self.latest.map(|(_, next)| next)
    }

    /// Whether step `k` must wait for the monitor: one has reported, and it lacks step k − `window` or an
    /// older one. `window` 0 turns the backpressure off.
    pub fn holds(&self, k: u64, window: u64) -> bool {
        window > 0 && self.next().is_some_and(|next| k >= next.saturating_add(window))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn control(kind: ControlKind, role: &str, started_ns: u64, step: u64) -> Control {
        Control::new(kind, step, 1, 42, started_ns, role, "").unwrap()
    }

    #[test]
    fn only_the_newest_monitors_progress_reports_count() {
        let mut p = MonitorProgress::default();
        assert!(!p.holds(10_000, 128), "no monitor heard of: no waiting");
        p.hear(&control(ControlKind::Progress, "planner", 5, 3));
        assert_eq!(p.next(), None, "another role");
        p.hear(&control(ControlKind::Progress, "monitor", 100, 984));
        assert_eq!(p.next(), Some(984));
        // The long kill storm: the same monitor asked for a replay from the snapshot step below its
        // progress (as it did then); taken for progress, it held emitter-sim back one step per retry
        // interval.
        p.hear(&control(ControlKind::Replay, "monitor", 100, 768));
        assert_eq!(p.next(), Some(984));
        p.hear(&control(ControlKind::Progress, "monitor", 100, 1000));
        assert_eq!(p.next(), Some(1000));
        p.hear(&control(ControlKind::Progress, "monitor", 50, 2000));
        assert_eq!(p.next(), Some(1000), "an older instance");
        p.hear(&control(ControlKind::Progress, "monitor", 200, 900));
        assert_eq!(p.next(), Some(900), "a restarted monitor, behind its predecessor");
    }

    #[test]
    fn the_window_holds_from_next_plus_window() {
        let mut p = MonitorProgress::default();
        p.hear(&control(ControlKind::Progress, "monitor", 1, 300));
        assert!(!p.holds(427, 128) && p.holds(428, 128) && p.holds(10_000, 128));
        assert!(!p.holds(10_000, 0), "window 0: off");
        p.hear(&control(ControlKind::Progress, "monitor", 1, u64::MAX));
        assert!(!p.holds(u64::MAX - 1, 128), "no overflow");
    }
}
