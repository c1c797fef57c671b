//! What the estimator did: its `summary` line for the supervisor.

/// What the estimator did, printed as its `summary` line.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct EstimatorSummary {
    /// What every data process reports (role, instance, counts, hand-over, CPU).
    #[serde(flatten)]
    pub node: runtime::NodeSummary,
    /// Estimates published as `failed` (Chan failed; the previous estimate stands).
    pub failed: u64,
    /// Measurements held because the state after the step before them was not known (see
    /// [`crate::process`]); each is estimated once the state comes.
    pub out_of_chain: u64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_summary_keeps_its_flat_keys() {
        // The launcher reads `rejected` and `handed_over_at` from every summary line, whatever the role.
        let mut s = EstimatorSummary { node: runtime::NodeSummary::new(crate::ROLE, 7), ..EstimatorSummary::default() };
        s.node.rejected = 2;
        s.node.handed_over_at = Some(9);
        s.failed = 1;
        let v = serde_json::to_value(&s).unwrap();
        assert_eq!(v["role"], "estimator");
        assert_eq!(
            (v["rejected"].as_u64(), v["handed_over_at"].as_u64(), v["failed"].as_u64()),
            (Some(2), Some(9), Some(1))
        );
        assert!(v.get("node").is_none());
    }
}
