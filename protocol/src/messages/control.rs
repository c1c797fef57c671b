//! The control topic's message: who joins, asks for a replay, takes over, stops.

use super::*;

wire_enum! {
    /// What a [`Control`] message says.
    pub enum ControlKind : u32, decoded by from_u32 {
        /// A process instance (re)joined the pipeline, e.g. restarted after a crash (`header.step`: 0). Only
        /// that: what it needs to see again it asks for with [`ControlKind::Replay`].
        Hello = 0, "hello";
        /// A new instance of `role` takes over from step `header.step` (a swap): the running one handles the
        /// steps before it and then exits.
        TakeOver = 1, "take_over";
        /// Every process of the domain stops (the run is over or was interrupted).
        Shutdown = 2, "shutdown";
        /// How far the sender has got: `header.step` is the first step it lacks (the monitor: the next step to
        /// record). A lock-step emitter-sim does not run more than `--monitor-window` steps ahead of the
        /// monitor's progress, and replays from it when it stalls.
        Progress = 3, "progress";
        /// Publish the run again from step `header.step` (v2): a restarted monitor asks from its first step
        /// not in its log, a monitor that lost a message from that step, a restarted estimator or planner
        /// (which keep no state) for [`ControlKind::IN_FLIGHT`], the step in flight whose message its
        /// predecessor may have taken with it. emitter-sim replays from there.
        Replay = 4, "replay";
        /// The sender's count of messages it rejected so far is `header.step` (v3; sent when it changes, so
        /// that the monitor logs it and the live view shows every process's rejections during the run).
        Status = 5, "status";
        /// Send the estimator's state after step `header.step` (v4): an estimator asks when it is to estimate
        /// a step whose predecessor's state it has neither made nor seen echoed (it was restarted, or the world
        /// was rewound further back than it remembers); the monitor, which keeps the state every command
        /// echoed, answers with an [`EstimatorState`] on `<domain>/state`.
        State = 6, "state";
        /// The sender's domain runs another scenario than the process of instance `header.step`, which joined
        /// after it (v5; the sender's own run is in [`Control::run`]): that process leaves (exit code 2), so
        /// that no run is made of two scenarios. Every other receiver ignores it.
        Run = 7, "run";
    }
}

impl ControlKind {
    /// The step of a [`ControlKind::Replay`] that asks for the step in flight only (the newest one
    /// published).
    pub const IN_FLIGHT: u64 = u64::MAX;
}

/// Any process → every process of the domain (the `control` topic): who joins, who takes over, stop.
///
/// Many processes publish on this topic, each with its own sequence numbers: a receiver tracks the last
/// accepted sequence number per `instance`.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("uavloc::Control/v5")]
#[repr(C)]
pub struct Control {
    /// Common header; `step` depends on the kind (see [`ControlKind`]).
    pub header: Header,
    /// Instance id of the sender (as in [`Estimate::instance`] / [`Command::planner_instance`]).
    pub instance: u64,
    /// When the sender started ([`now_ns`]): orders two instances of one role (the later one is newer).
    pub started_ns: u64,
    /// [`ControlKind`] as `u32`.
    pub kind: u32,
    /// Explicit padding; 0 when sent.
    pub reserved: u32,
    /// The run the sender belongs to (v5): its scenario's fingerprint (`model::Scenario::run_id`), 0 for a
    /// sender without a scenario (the estimator, the launcher, `swap`). Processes of one domain must run
    /// one scenario: see [`ControlKind::Run`].
    pub run: u64,
    /// The sender's role: `emitter-sim`, `estimator`, `planner`, `monitor`, `launcher`, `swap`.
    pub role: Name16,
    /// Free detail for humans and the monitor, e.g. `ga/analytical` for a planner (may be empty).
    pub detail: Name16,
}

impl_message!(Control, MessageKind::Control, 5, "uavloc::Control/v5");

impl Control {
    /// This message with the sender's run ([`Control::run`]).
    pub fn with_run(self, run: u64) -> Self {
        Control { run, ..self }
    }

    /// A control message of `kind` from `role` (`detail` may be empty; beyond 16 characters it is cut).
    pub fn new(
        kind: ControlKind,
        step: u64,
        seq: u64,
        instance: u64,
        started_ns: u64,
        role: &str,
        detail: &str,
    ) -> Result<Self, ProtocolError> {
        Ok(Control {
            header: Header::new(Self::VERSION, step, seq),
            instance,
            started_ns,
            kind: kind as u32,
            reserved: 0,
            run: 0,
            role: Name16::new("role", role)?,
            detail: if detail.is_empty() { Name16::default() } else { Name16::new("detail", Self::cut(detail))? },
        })
    }

    /// `detail` cut to the 16 bytes the field holds (at a character boundary): it is free text for
    /// humans, and a planner's `solver/objective` (e.g. `pso/posterior-cubature`) may be longer.
    fn cut(detail: &str) -> &str {
        let mut end = detail.len().min(16);
        while !detail.is_char_boundary(end) {
            end -= 1;
        }
        &detail[..end]
    }

    /// The decoded kind (`None` for an unknown wire value).
    pub fn kind(&self) -> Option<ControlKind> {
        ControlKind::from_u32(self.kind)
    }

    /// The sender's role (`None` if the bytes are not a valid name).
    pub fn role(&self) -> Option<&str> {
        self.role.as_str()
    }

    /// The detail (empty when none or invalid).
    pub fn detail(&self) -> &str {
        self.detail.as_str().unwrap_or("")
    }
}
