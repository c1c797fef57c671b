//! # uavloc-estimator — the estimator process of uavloc
//!
//! Measurement in → [`estimation::Estimator::estimate`] → estimate out over iceoryx2 ([`process`]);
//! [`chain`] is the estimator as a function of the messages it receives (the chain of states from step
//! to step, and the wire form of the library's output), [`args`] its command line, [`summary`] its
//! `summary` line. The estimation itself is the library crate `uavloc-estimation`.
//!
//! Units: metres (positions), m² (covariance), m/s (velocity).

/// The role name (node name suffix, `uavloc process estimator`).
pub const ROLE: &str = "estimator";

pub mod args;
pub mod chain;
pub mod process;
pub mod summary;
