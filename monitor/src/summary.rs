//! What the monitor saw: its `summary` line for the supervisor and its closing status line.

use protocol::RejectionCounter;

use crate::latency::{LatencyStat, LatencySummary};

/// What the monitor saw, printed as its `summary` line.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct MonitorSummary {
    /// `"monitor"`.
    pub role: &'static str,
    /// Writing `--record` or `--out` at the end failed (the record itself still went to the supervisor).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub output_error: Option<String>,
    /// Whether every step up to the last one was recorded.
    pub complete: bool,
    /// Steps recorded.
    pub steps: u64,
    /// Valid messages received.
    pub accepted: u64,
    /// Invalid messages ignored.
    pub rejected: u64,
    /// Valid messages for steps already recorded or beyond the last one.
    pub ignored: u64,
    /// Distinct planner instances seen.
    pub planners: u64,
    /// Steps recorded whose command was missed (real-time mode).
    pub missed_commands: u64,
    /// Steps recorded whose command was the planner's hold (no fresh estimate within its deadline).
    pub stale_steps: u64,
    /// Steps recorded whose command said that no certified plan existed (logged as `uncertified`).
    pub uncertified_steps: u64,
    /// Latencies of the planned steps.
    pub latency: LatencySummary,
    /// Messages of the recorded steps that never reached the monitor as first published (measurement,
    /// estimate, command and truth of each step; the last step has no command): lost on the way (a full
    /// buffer) or never sent (its sender died first), the step then recorded from a copy sent again (a
    /// replay: no publish stamp). 0 when nothing was lost.
    pub missing_messages: u64,
    /// Replays this monitor asked for because a message was lost (see [`runtime::recovery::Lost`]).
    pub replays_requested: u64,
    /// CPU time this process used, seconds.
    pub cpu_s: f64,
}

impl MonitorSummary {
    /// The closing status line: steps recorded of `steps` (the run's 0..=N), the rejections, the median
    /// hops and cycle.
    pub fn closing_line(&self, steps: u64, counter: &RejectionCounter) -> String {
        let l = &self.latency;
        let p50 = |s: &Option<LatencyStat>| s.map_or("-".into(), |s| format!("{:.0} µs", s.p50_us));
        format!(
            "{} of {steps} steps recorded, {counter}; median hops: command {}, measurement {}, estimate {}; median \
             cycle {}",
            self.steps,
            p50(&l.command_hop),
            p50(&l.measurement_hop),
            p50(&l.estimate_hop),
            p50(&l.cycle)
        )
    }
}
