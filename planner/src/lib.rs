//! # uavloc-planner — the planner process of uavloc
//!
//! Estimate in → [`planning::plan_step`] → command out over iceoryx2 ([`process`]), with the
//! estimate deadline and the hold of a late step ([`staleness`]), a plan and a hold as the wire's
//! commands ([`wire`]), the command line ([`args`]) and the `summary` line ([`summary`]). The planning
//! itself is the library crate `uavloc-planning`.
//!
//! Units: metres, seconds, radians.

/// The role name (node name suffix, `uavloc process planner`).
pub const ROLE: &str = "planner";

pub mod args;
pub mod process;
pub mod staleness;
pub mod summary;
pub mod wire;
