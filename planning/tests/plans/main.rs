//! The planner's solvers on recorded planning problems and random plans, in one test binary: the
//! constraints against their definitions, the waypoint planner's recorded plans bit for bit, and the
//! gradient solver against the paper's solvers, on the regression problems and on found cases of eight UAVs.

mod constraint_properties;
mod found_cases;
mod golden_plans;
mod gradient_quality;
mod problems;
