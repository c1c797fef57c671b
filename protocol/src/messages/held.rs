//! The bursts an estimator holds before its first fix: part of its state on the wire.

use super::*;

/// Bursts an [`Estimate`] (and the [`StateEcho`] of it) can hold: the newest the estimator keeps.
pub const MAX_HELD_BURSTS: usize = 4;

/// A burst heard by two UAVs only, before the estimator's first fix: one range difference, no fix on
/// its own, fused into the first fix when it comes. The estimator keeps the newest
/// [`MAX_HELD_BURSTS`]; they are its whole state until then, so they travel in every [`Estimate`] of
/// those steps and in the echo of it ([`StateEcho`]), and an estimator restarted before the first fix
/// goes on from them bit for bit.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend, serde::Serialize, serde::Deserialize)]
#[type_name("uavloc::HeldBurst/v1")]
#[repr(C)]
pub struct HeldBurst {
    /// The step of the burst.
    pub step: u64,
    /// Number of UAVs N of the swarm (3..=8).
    pub count: u8,
    /// The two UAVs that heard it (ascending; the first is the reference).
    pub uavs: [u8; 2],
    /// Explicit padding; 0 when sent.
    pub reserved: [u8; 5],
    /// Their reported positions at the burst, metres.
    pub positions: [[f64; 2]; 2],
    /// `a[uavs[1]] − a[uavs[0]]`: the range difference of the burst, metres.
    pub arrival_diff: f64,
    /// Their stated σ (range noise with GNSS and clock errors), metres.
    pub sigmas: [f64; 2],
    /// The persistent part of it, metres.
    pub bias_sigmas: [f64; 2],
}

/// The held bursts of an estimator state (`count` of `bursts`, oldest first; the rest zeros).
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend, serde::Serialize, serde::Deserialize)]
#[type_name("uavloc::HeldBursts/v1")]
#[repr(C)]
pub struct HeldBursts {
    /// How many of `bursts` hold one (0..=[`MAX_HELD_BURSTS`]).
    pub count: u8,
    /// Explicit padding; 0 when sent.
    pub reserved: [u8; 7],
    /// The bursts, oldest first.
    pub bursts: [HeldBurst; MAX_HELD_BURSTS],
}

impl HeldBursts {
    /// At most [`MAX_HELD_BURSTS`] bursts (the newest are kept).
    pub fn new(bursts: &[HeldBurst]) -> Self {
        let kept = &bursts[bursts.len().saturating_sub(MAX_HELD_BURSTS)..];
        let mut h = HeldBursts { count: kept.len() as u8, ..HeldBursts::default() };
        h.bursts[..kept.len()].copy_from_slice(kept);
        h
    }

    /// The bursts held (none for a `count` beyond the capacity: validation refuses it).
    pub fn as_slice(&self) -> &[HeldBurst] {
        self.bursts.get(..self.count as usize).unwrap_or(&[])
    }
}

// SAFETY: repr(C) of u64, u8 arrays and f64 arrays without implicit padding (88 bytes; see
// `layout_is_stable`): every bit pattern is a value.
unsafe impl AnyBitPattern for HeldBurst {}
// SAFETY: repr(C) of a u8, seven u8 and an array of `HeldBurst` without implicit padding (360 bytes).
unsafe impl AnyBitPattern for HeldBursts {}
