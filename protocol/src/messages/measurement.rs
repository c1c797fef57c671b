//! The sensor side: one step's UAV positions, range differences and their σ (emitter-sim or an external front end → estimator, planner, monitor).

use super::*;

/// emitter-sim → estimator: the UAV geometry and the noisy range differences of one step.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("uavloc::Measurement/v1")]
#[repr(C)]
pub struct Measurement {
    /// Common header.
    pub header: Header,
    /// Number of UAVs N (3..=8).
    pub count: u32,
    /// Explicit padding; 0 when sent.
    pub reserved: u32,
    /// UAV positions (metres) at the measurement time; `uavs[0]` is the reference.
    pub uavs: [[f64; 2]; MAX_UAVS],
    /// Range differences `d_i = r_i − r_0`, i = 1..N−1 (metres); `diffs[i − 1]` belongs to UAV i.
    pub diffs: [f64; MAX_UAVS - 1],
    /// Per-UAV range noise standard deviation (metres, > 0).
    pub sigmas: [f64; MAX_UAVS],
    /// Current UAV headings (radians).
    pub headings: [f64; MAX_UAVS],
}

impl_message!(Measurement, MessageKind::Measurement, 1, "uavloc::Measurement/v1");

impl_per_uav!(Measurement {
    /// UAV positions in use.
    uavs: [f64; 2],
    /// Range sigmas in use.
    sigmas: f64,
    /// Headings in use.
    headings: f64,
});

impl Measurement {
    /// A measurement of `uavs.len()` UAVs; `diffs` must have one entry fewer, `sigmas` and `headings` one
    /// per UAV. Content (finiteness, σ > 0) is checked by [`validate`](Self::validate), not here.
    pub fn new(
        step: u64,
        seq: u64,
        uavs: &[[f64; 2]],
        diffs: &[f64],
        sigmas: &[f64],
        headings: &[f64],
    ) -> Result<Self, ProtocolError> {
        let n = check_count(uavs.len())?;
        check_len("diffs", n - 1, diffs.len())?;
        check_len("sigmas", n, sigmas.len())?;
        check_len("headings", n, headings.len())?;
        let mut m = Measurement {
            header: Header::new(Self::VERSION, step, seq),
            count: n as u32,
            reserved: 0,
            uavs: [[0.0; 2]; MAX_UAVS],
            diffs: [0.0; MAX_UAVS - 1],
            sigmas: [0.0; MAX_UAVS],
            headings: [0.0; MAX_UAVS],
        };
        m.uavs[..n].copy_from_slice(uavs);
        m.diffs[..n - 1].copy_from_slice(diffs);
        m.sigmas[..n].copy_from_slice(sigmas);
        m.headings[..n].copy_from_slice(headings);
        Ok(m)
    }

    /// Range differences in use (`count − 1` of them).
    pub fn diffs(&self) -> &[f64] {
        &self.diffs[..self.len().saturating_sub(1)]
    }
}
