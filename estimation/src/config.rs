//! What an estimator is: its kind (fused or per-snapshot Chan), the emitter's motion model, the χ²
//! gate and the outlier policy.

use tdoa::Dynamics;
use tdoa::fusion::{self, DEFAULT_GATE_PROBABILITY};

use crate::{EstimatorKind, OutlierPolicy};

/// What an [`crate::Estimator`] is: its kind, the motion model and the gate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EstimatorConfig {
    /// Fused or snapshot.
    pub kind: EstimatorKind,
    /// The emitter's motion model (fused only).
    pub dynamics: Dynamics,
    /// The χ² gate `χ²_m(p_gate)` (fused only) for m range differences, index m, with the default
    /// [`DEFAULT_GATE_PROBABILITY`]: computed once here, because the quantile is an iterative inversion
    /// (≈ 1.4 µs) and every fused snapshot needs its gate.
    gates: [f64; tdoa::MAX_UAVS],
    /// What a burst that fails the gate costs: itself, or its outlying arrivals ([`OutlierPolicy`]).
    pub outliers: OutlierPolicy,
}

impl EstimatorConfig {
    /// The paper's per-step Chan.
    pub fn snapshot() -> Self {
        Self::new(EstimatorKind::Snapshot, Dynamics::fixed())
    }

    /// Fusion under `dynamics` with the default gate.
    pub fn fused(dynamics: Dynamics) -> Self {
        Self::new(EstimatorKind::Fused, dynamics)
    }

    /// `kind` under `dynamics` with the default gate.
    pub fn new(kind: EstimatorKind, dynamics: Dynamics) -> Self {
        let mut gates = [f64::INFINITY; tdoa::MAX_UAVS];
        for (m, gate) in gates.iter_mut().enumerate().skip(1) {
            *gate = fusion::gate_threshold(m, DEFAULT_GATE_PROBABILITY);
        }
        Self { kind, dynamics, gates, outliers: OutlierPolicy::default() }
    }

    /// This configuration with the outlier policy `outliers`.
    pub fn with_outliers(mut self, outliers: OutlierPolicy) -> Self {
        self.outliers = outliers;
        self
    }

    /// The gate of a snapshot of `m` range differences (`+∞`, no gate, outside 1..MAX_UAVS).
    pub fn gate(&self, m: usize) -> f64 {
        self.gates.get(m).copied().unwrap_or(f64::INFINITY)
    }
}

impl Default for EstimatorConfig {
    fn default() -> Self {
        Self::fused(Dynamics::fixed())
    }
}
