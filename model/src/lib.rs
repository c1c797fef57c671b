//! # uavloc-model — what every uavloc process shares about a run
//!
//! Plain data and pure functions that the world (emitter-sim), the planner and the monitor all need, so
//! that none of them depends on another (the crates point down to this one and to `tdoa`):
//!
//! - [`scenario`]: the run's settings from TOML ([`Scenario`]; default = the paper's Table 1 case) and
//!   the rule every process applies to `--scenario` / `--steps` / `--seed` ([`load_scenario`]);
//! - [`geo`]: the geographic frame (a WGS84 origin, the plane ↔ latitude/longitude);
//! - [`kinematics`]: fixed-speed circular-arc motion (eq. 54);
//! - [`solver_config`]: the solvers' settings as the scenario carries them;
//! - [`constraint`]: the four motion constraints by name and one active instance;
//! - [`active_mask`]: the active constraints as the wire bitmask of a `protocol::Command`;
//! - [`arc`]: the arc a UAV flies over one interval and certified minimum distances along it;
//! - [`backup`]: a UAV's backup manoeuvre (a circle, or flying away from a moving emitter) and its minima;
//! - [`safety`]: the safety certificate of a plan (spacing and standoff along the arcs, a backup for ever);
//! - [`world`]: the simulated world of a run (the truth, its noisy TDOA, the UAVs flown).
//!
//! Units: metres, seconds, radians (degrees only in TOML keys ending in `_deg`).

pub mod active_mask;
pub mod arc;
pub mod backup;
pub mod constraint;
pub mod geo;
pub mod kinematics;
pub mod receiver;
pub mod safety;
pub mod scenario;
pub mod solver_config;
#[cfg(test)]
mod testing;
pub mod world;

pub use constraint::{ActiveConstraint, ConstraintKind};
pub use kinematics::{bearing, next_position, turn_angle, turn_radius, wrap_angle};
pub use receiver::ReceiverModel;
pub use scenario::{PlannerTarget, RangeSigma, Scenario, ScenarioError, TargetMode, load_scenario};
pub use solver_config::{AcoConfig, EarlyStop, GaConfig, PsoConfig};
