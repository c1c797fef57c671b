//! What emitter-sim did: its `summary` line for the supervisor and its closing status lines.

use crate::schedule::Counts;

/// What emitter-sim did, printed as its `summary` line.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct EmitterSummary {
    /// `"emitter-sim"`.
    pub role: &'static str,
    /// `"lockstep"` or `"realtime"`.
    pub mode: &'static str,
    /// What the schedule counted: steps, replays, retries, missed_commands, late_commands, ignored,
    /// max_lag_us ([`Counts`]).
    #[serde(flatten)]
    pub counts: Counts,
    /// Measurements published.
    pub measurements: u64,
    /// Valid commands received (any step).
    pub accepted: u64,
    /// Invalid commands ignored (failed validation, or refused by the world).
    pub rejected: u64,
    /// The step this instance started from (0, or a snapshot after a restart).
    pub started_at: u64,
    /// CPU time this process used, seconds.
    pub cpu_s: f64,
    /// `--uavs autopilots`: UAV-steps not heard because the UAV's fix was stale (a quiet link).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unheard_uav_steps: Option<u64>,
}

impl EmitterSummary {
    /// The closing status lines (stderr unless `--quiet`): steps, measurements, rejections, replays; in
    /// realtime mode also the missed and late commands and the largest lag behind the schedule.
    pub fn closing_lines(&self) -> String {
        let c = &self.counts;
        let mut text = format!(
            "emitter-sim: done: {} steps, {} measurements, rejected {}, {} ignored, {} replays ({} retries)\n",
            c.steps, self.measurements, self.rejected, c.ignored, c.replays, c.retries
        );
        if self.mode == crate::args::Mode::Realtime.name() {
            text += &format!(
                "emitter-sim: realtime: {} missed commands, {} late commands ignored, largest lag behind the \
                 schedule {} µs\n",
                c.missed_commands, c.late_commands, c.max_lag_us
            );
        }
        text
    }
}
