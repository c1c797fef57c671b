//! # uavloc-emitter-sim — the emitter-sim process: the simulated world on the pipeline
//!
//! The world itself ([`model::world::World`]: the truth, the noisy TDOA measurement of each step, the
//! UAVs flown along the commanded headings) is the shared model's. This crate runs it in lock-step (or
//! in real time) with the pipeline over iceoryx2 ([`process`], [`schedule`]), checkpoints it
//! ([`checkpoint`]), keeps the measurements from outrunning the estimator ([`backpressure`]), and has its
//! command line ([`args`]) and `summary` line ([`summary`]).
//!
//! Units: metres, seconds, radians.

/// The role name (node name suffix, `uavloc process emitter-sim`).
pub const ROLE: &str = "emitter-sim";

pub mod args;
pub mod backpressure;
pub mod checkpoint;
pub mod process;
pub mod schedule;
pub mod summary;
