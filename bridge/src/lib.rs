//! # uavloc-bridge — the MAVLink bridge of uavloc
//!
//! Command in → one guided position target per UAV, streamed to its autopilot over MAVLink 2
//! (`SET_POSITION_TARGET_GLOBAL_INT`); the autopilots' `HEARTBEAT`, `GLOBAL_POSITION_INT` and `ATTITUDE`
//! → the swarm's state out ([`protocol::SwarmState`] on `<domain>/swarm`). The pure parts: what one
//! autopilot link knows and whether it may be commanded ([`link`]), a command as targets ([`target`]);
//! the MAVLink connections ([`mav`]); the handler on the node runtime ([`process`]).
//!
//! Units: metres, seconds, radians in the plane (counter-clockwise from east); MAVLink's own units
//! (degE7, mm, cm/s, radians clockwise from north) only at the edge, in [`mav`] and [`target`].

/// The role name (node name suffix, `uavloc process bridge`).
pub const ROLE: &str = "bridge";

pub mod args;
pub mod link;
pub mod mav;
pub mod process;
pub mod summary;
pub mod target;
