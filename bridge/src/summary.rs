//! What the bridge did: its `summary` line for the supervisor.

/// One UAV's link over the run.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct LinkSummary {
    /// The endpoint.
    pub endpoint: String,
    /// Guided targets sent.
    pub targets_sent: u64,
    /// Telemetry messages accepted.
    pub telemetry: u64,
    /// Telemetry refused (another system id, a bad value, a jump).
    pub rejected: u64,
    /// Times the link went quiet.
    pub quiet_periods: u64,
    /// Read errors of the connection.
    pub read_errors: u64,
}

/// What the bridge did, printed as its `summary` line.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct BridgeSummary {
    /// What every data process reports (role, instance, counts, CPU).
    #[serde(flatten)]
    pub node: runtime::NodeSummary,
    /// Per UAV, UAV0 first.
    pub links: Vec<LinkSummary>,
    /// Swarm states published.
    pub swarm_states: u64,
    /// The step of the last command flown.
    pub last_command_step: Option<u64>,
}
