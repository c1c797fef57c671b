//! A static emitter's track re-linearised over its last bursts: part of the estimator's state on the
//! wire (`estimation::window`).

use super::*;

/// Bursts a [`TrackWindow`] holds raw: the newest the estimator keeps.
pub const MAX_WINDOW_BURSTS: usize = 8;

/// One burst of a track's window: the arrivals the estimator kept of it, with the geometry and σ they
/// were fused with.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend, serde::Serialize, serde::Deserialize)]
#[type_name("uavloc::WindowBurst/v1")]
#[repr(C)]
pub struct WindowBurst {
    /// The step of the burst.
    pub step: u64,
    /// Number of UAVs N of the swarm (3..=8).
    pub count: u8,
    /// The UAVs whose arrivals were kept (bit i: UAV i; two or more).
    pub heard: u8,
    /// Explicit padding; 0 when sent.
    pub reserved: [u8; 6],
    /// The UAVs' reported positions at the burst, metres (the first `count`).
    pub positions: [[f64; 2]; MAX_UAVS],
    /// The arrivals (a common offset), metres; read for the UAVs kept only.
    pub arrivals: [f64; MAX_UAVS],
    /// The σ each arrival was fused with, metres.
    pub sigmas: [f64; MAX_UAVS],
    /// Their persistent part, metres.
    pub bias_sigmas: [f64; MAX_UAVS],
}

/// The window of a fused track of a static emitter: the older bursts summarised in information form,
/// the newest kept raw. `open` 0: no window (the estimator closes it where two hypotheses are pending,
/// for a moving emitter and for the snapshot estimator).
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend, serde::Serialize, serde::Deserialize)]
#[type_name("uavloc::TrackWindow/v1")]
#[repr(C)]
pub struct TrackWindow {
    /// 1 when the track has a window, 0 otherwise.
    pub open: u8,
    /// How many of `bursts` hold one (0..=[`MAX_WINDOW_BURSTS`]).
    pub count: u8,
    /// Explicit padding; 0 when sent.
    pub reserved: [u8; 6],
    /// `Λ` of the summary, m⁻², row-major.
    pub base_matrix: [[f64; 2]; 2],
    /// `η = Λ x_b` of the summary, m⁻¹.
    pub base_vector: [f64; 2],
    /// The raw bursts, oldest first.
    pub bursts: [WindowBurst; MAX_WINDOW_BURSTS],
}

impl TrackWindow {
    /// The bursts held (none for a `count` beyond the capacity: validation refuses it).
    pub fn as_slice(&self) -> &[WindowBurst] {
        self.bursts.get(..self.count as usize).unwrap_or(&[])
    }
}

// SAFETY: repr(C) of u64, u8 arrays and f64 arrays without implicit padding (336 bytes; see
// `layout_is_stable`): every bit pattern is a value.
unsafe impl AnyBitPattern for WindowBurst {}
// SAFETY: repr(C) of two u8, six u8, f64 arrays and an array of `WindowBurst` without implicit padding
// (2 744 bytes).
unsafe impl AnyBitPattern for TrackWindow {}
