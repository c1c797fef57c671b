//! Monitor → estimator: an estimator state it asked for.

use super::*;

/// Monitor → estimator (the `state` topic): the estimator's state after step `header.step`, as the command
/// of that step echoed it ([`Command::state`]), in answer to a [`ControlKind::State`] request. This is how
/// an estimator that keeps no file — restarted, or asked to estimate again a step older than the echoes it
/// remembers — goes on from the state before the step it is given, bit for bit as its predecessor would.
/// Internal to uavloc: a foreign front end neither sends nor reads it.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("uavloc::EstimatorState/v5")]
#[repr(C)]
pub struct EstimatorState {
    /// Common header; `step` is the step the state is after.
    pub header: Header,
    /// Instance id of the sender.
    pub instance: u64,
    /// The state ([`StateEcho::STATE`] or [`StateEcho::EMPTY`], of step `header.step`).
    pub state: StateEcho,
}

impl_message!(EstimatorState, MessageKind::State, 5, "uavloc::EstimatorState/v5");

impl EstimatorState {
    /// The state `state` (of its step) sent by instance `instance` with sequence number `seq`.
    pub fn new(state: StateEcho, seq: u64, instance: u64) -> Self {
        EstimatorState { header: Header::new(Self::VERSION, state.step, seq), instance, state }
    }
}
