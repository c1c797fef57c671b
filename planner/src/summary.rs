//! What the planner did: its `summary` line for the supervisor.

/// What the planner did, printed as its `summary` line.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct PlannerSummary {
    /// What every data process reports (role, instance, counts, hand-over, CPU).
    #[serde(flatten)]
    pub node: runtime::NodeSummary,
    /// Steps held: no fresh estimate within `--estimate-deadline-ms`, the current headings commanded.
    pub held: u64,
    /// Estimates of held steps (arrived after the deadline; answered with the hold, not planned).
    pub late_estimates: u64,
}
