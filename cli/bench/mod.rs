//! `uavloc bench`: latency of the process pipeline (per hop, per stage, end to end) over iceoryx2 and over
//! a Unix-domain-socket baseline, and the planner's compute time per objective and solver.

pub mod histogram;
pub mod planner;
pub mod plot;
pub mod sys;
