//! The planner's command of a step: headings and waypoints, the safety certificate, and the estimator state it echoes.

use super::*;

/// The planner's output for one step: what goes into [`Command::new`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanInfo<'a> {
    /// Commanded headings, radians (one per UAV).
    pub headings: &'a [f64],
    /// The waypoints these headings lead to, metres (one per UAV).
    pub waypoints: &'a [[f64; 2]],
    /// The criterion value at the waypoints.
    pub objective: f64,
    /// Solver name (1 to 16 printable ASCII characters, e.g. `"pso"`).
    pub solver: &'a str,
    /// Objective name (1 to 16 printable ASCII characters, e.g. `"trace-crlb"`).
    pub objective_name: &'a str,
    /// Planning time, microseconds.
    pub plan_time_us: u64,
    /// Bitmask of violated or binding constraints (bit meanings defined by the planner).
    pub active_constraints: u64,
    /// The same bits for the constraints among them that are violated (not merely binding).
    pub violated_constraints: u64,
}

/// planner → emitter-sim, monitor: the headings to fly for the next step.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("uavloc::Command/v9")]
#[repr(C)]
pub struct Command {
    /// Common header (step of the estimate it was planned from).
    pub header: Header,
    /// Id of the planner process instance that made it.
    pub planner_instance: u64,
    /// Planning time, microseconds.
    pub plan_time_us: u64,
    /// Bitmask of violated or binding constraints.
    pub active_constraints: u64,
    /// The same bits for the active constraints that are violated (the others are binding).
    pub violated_constraints: u64,
    /// Number of UAVs N (3..=8).
    pub count: u32,
    /// What kind of command this is: 0 a plan; [`Command::FLAG_HOLD`] a hold (see there); a plan's safety
    /// certificate in [`Command::FLAG_CERTIFIED`] / [`Command::FLAG_UNCERTIFIED`]. Unknown bits are
    /// ignored.
    pub flags: u32,
    /// Criterion value at the waypoints.
    pub objective: f64,
    /// Commanded headings, radians.
    pub headings: [f64; MAX_UAVS],
    /// Waypoints, metres.
    pub waypoints: [[f64; 2]; MAX_UAVS],
    /// Solver name.
    pub solver: Name16,
    /// Objective name.
    pub objective_name: Name16,
    /// The estimator's state after the step this command was planned from, echoed from that estimate
    /// (v4; v5 with the bias sensitivity; v6 with a pending second root): where a restarted, rewound or replayed-to estimator finds it
    /// (see [`StateEcho`]).
    pub state: StateEcho,
}

impl_message!(Command, MessageKind::Command, 9, "uavloc::Command/v9");

impl_per_uav!(Command {
    /// Headings in use.
    headings: f64,
    /// Waypoints in use.
    waypoints: [f64; 2],
});

/// The estimator's state after step `step` as an [`Estimate`] carries it — the estimate the step is
/// planned from ([`Estimate::plan_from`]: the fix, or a failed step's standing estimate) and the fused
/// posterior beyond the position — echoed in the [`Command`] planned from it. With it an estimator
/// continues the chain at step `step + 1` exactly as the one that made the estimate would have
/// (`uavloc-estimator`), so no estimator keeps its answers or needs a checkpoint to answer a replay.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("uavloc::StateEcho/v6")]
#[repr(C)]
pub struct StateEcho {
    /// The step of the estimate.
    pub step: u64,
    /// [`StateEcho::NONE`] (a hold: planned from no estimate), [`StateEcho::STATE`] (position, covariance
    /// and the posterior fields hold the state) or [`StateEcho::EMPTY`] (the estimator had no usable
    /// estimate yet after `step`).
    pub kind: u8,
    /// As [`Estimate::estimator`].
    pub estimator: u8,
    /// As [`Estimate::model`].
    pub model: u8,
    /// As [`Estimate::rejected_run`].
    pub rejected_run: u8,
    /// As [`Estimate::confirmed`] (0, a provisional track, from a sender that does not state it).
    pub confirmed: u8,
    /// As [`Estimate::alternative`] (v3).
    pub alternative: u8,
    /// As [`Estimate::drop_uavs`] (v4).
    pub drop_uavs: u8,
    /// As [`Estimate::drop_run`] (v4).
    pub drop_run: u8,
    /// The estimate, metres.
    pub position: [f64; 2],
    /// Its covariance, m², row-major.
    pub covariance: [[f64; 2]; 2],
    /// As [`Estimate::velocity`], m/s.
    pub velocity: [f64; 2],
    /// As [`Estimate::cross_cov`], m²/s.
    pub cross_cov: [[f64; 2]; 2],
    /// As [`Estimate::velocity_cov`], m²/s².
    pub velocity_cov: [[f64; 2]; 2],
    /// As [`Estimate::bias_sensitivity`] (v2).
    pub bias_sensitivity: [[f64; MAX_UAVS]; 4],
    /// As [`Estimate::alt_mean`] (v3).
    pub alt_mean: [f64; 4],
    /// As [`Estimate::alt_cov`] (v3).
    pub alt_cov: [[f64; 4]; 4],
    /// As [`Estimate::alt_bias_sensitivity`] (v3).
    pub alt_bias_sensitivity: [[f64; MAX_UAVS]; 4],
    /// As [`Estimate::held`] (v5): with [`StateEcho::EMPTY`], the bursts the estimator holds for its
    /// first fix.
    pub held: HeldBursts,
    /// As [`Estimate::window`] (v6): with [`StateEcho::STATE`], the track's window.
    pub window: TrackWindow,
}

// SAFETY: repr(C) of u64, eight u8, f64 arrays, `HeldBursts` and `TrackWindow`, without implicit padding (3920 bytes, see
// `layout_is_stable`): every bit pattern is a value.
unsafe impl AnyBitPattern for StateEcho {}

/// What a [`StateEcho`] says, decoded. (A short-lived, `Copy` view of one message: the size of its
/// `State` variant is the message's own.)
#[derive(Debug, Clone, Copy, PartialEq)]
#[allow(clippy::large_enum_variant)]
pub enum EchoedState {
    /// The estimator's state after `step`: the estimate and the posterior beyond the position.
    State {
        /// The step.
        step: u64,
        /// Position (m) and covariance (m²).
        estimate: ([f64; 2], [[f64; 2]; 2]),
        /// The fused posterior beyond the position.
        extra: PosteriorExtra,
    },
    /// After `step` the estimator had no usable estimate yet.
    Empty {
        /// The step.
        step: u64,
        /// The bursts it holds for its first fix.
        held: HeldBursts,
    },
}

impl EchoedState {
    /// The step the state is after.
    pub fn step(&self) -> u64 {
        match *self {
            EchoedState::State { step, .. } | EchoedState::Empty { step, .. } => step,
        }
    }
}

impl StateEcho {
    /// [`StateEcho::kind`]: no state (a hold).
    pub const NONE: u8 = 0;
    /// [`StateEcho::kind`]: the state is in the fields.
    pub const STATE: u8 = 1;
    /// [`StateEcho::kind`]: no usable estimate yet after `step`.
    pub const EMPTY: u8 = 2;

    /// The state an estimate carries (see the type's docs); `None` for an unknown status.
    pub fn of(e: &Estimate) -> Option<Self> {
        e.status()?;
        let mut echo = StateEcho { step: e.header.step, ..StateEcho::default() };
        match e.state_from() {
            Some((position, covariance)) => {
                echo.kind = Self::STATE;
                echo.position = position;
                echo.covariance = covariance;
                echo.set_extra(&e.extra());
            }
            None => {
                echo.kind = Self::EMPTY;
                echo.held = e.held;
            }
        }
        Some(echo)
    }

    /// The decoded state (`None` for a hold or an unknown kind).
    pub fn decode(&self) -> Option<EchoedState> {
        match self.kind {
            Self::STATE => Some(EchoedState::State {
                step: self.step,
                estimate: (self.position, self.covariance),
                extra: self.extra(),
            }),
            Self::EMPTY => Some(EchoedState::Empty { step: self.step, held: self.held }),
            _ => None,
        }
    }
}

impl Command {
    /// [`Command::flags`] bit: a *hold*, not a plan; `objective` is then −1 (no value) and
    /// `plan_time_us` 0. No fresh estimate of the step reached the planner within its deadline
    /// (`planner --estimate-deadline-ms`), or there is none to plan from yet (no first fix): the UAVs
    /// loiter on their backup circles (`planning::hold`), with [`Command::FLAG_CERTIFIED`] or
    /// [`Command::FLAG_UNCERTIFIED`] for the spacing; with `safety = "waypoints"` they hold course
    /// (the current headings), neither safety bit set.
    pub const FLAG_HOLD: u32 = 1;

    /// [`Command::flags`] bit: the plan carries a safety certificate (the planner's `safety =
    /// "certified"`: spacing and standoff hold along the arcs, with a backup manoeuvre for ever).
    pub const FLAG_CERTIFIED: u32 = 2;

    /// [`Command::flags`] bit: the planner certifies its plans but found no certified plan this step (an
    /// unsafe start, or the estimate moved the standing backup's margins away): the plan is the one with
    /// the largest minimum margin. Neither bit: a planner that keeps the constraints at the waypoints
    /// only (`safety = "waypoints"`).
    pub const FLAG_UNCERTIFIED: u32 = 4;

    /// The safety certificate's word on this command: `Some(true)` certified, `Some(false)` no certified
    /// plan existed, `None` not certified by design (`safety = "waypoints"`).
    pub fn certified(&self) -> Option<bool> {
        if self.flags & Self::FLAG_CERTIFIED != 0 {
            Some(true)
        } else if self.flags & Self::FLAG_UNCERTIFIED != 0 {
            Some(false)
        } else {
            None
        }
    }

    /// This command with the estimator state `estimate` carries echoed ([`StateEcho::of`]).
    pub fn with_state_of(mut self, estimate: &Estimate) -> Self {
        self.state = StateEcho::of(estimate).unwrap_or_default();
        self
    }

    /// Whether this is a hold ([`Command::FLAG_HOLD`]).
    pub fn is_hold(&self) -> bool {
        self.flags & Self::FLAG_HOLD != 0
    }

    /// A command for `plan.headings.len()` UAVs.
    pub fn new(step: u64, seq: u64, planner_instance: u64, plan: &PlanInfo<'_>) -> Result<Self, ProtocolError> {
        let n = check_count(plan.headings.len())?;
        check_len("waypoints", n, plan.waypoints.len())?;
        let mut c = Command {
            header: Header::new(Self::VERSION, step, seq),
            planner_instance,
            plan_time_us: plan.plan_time_us,
            active_constraints: plan.active_constraints,
            violated_constraints: plan.violated_constraints,
            count: n as u32,
            flags: 0,
            objective: plan.objective,
            headings: [0.0; MAX_UAVS],
            waypoints: [[0.0; 2]; MAX_UAVS],
            solver: Name16::new("solver", plan.solver)?,
            objective_name: Name16::new("objective_name", plan.objective_name)?,
            state: StateEcho::default(),
        };
        c.headings[..n].copy_from_slice(plan.headings);
        c.waypoints[..n].copy_from_slice(plan.waypoints);
        Ok(c)
    }

    /// The command planned from `estimate` (received at `received_ns`): same step, stamps carried forward,
    /// the estimator's state echoed ([`Command::with_state_of`]).
    pub fn from_estimate(
        estimate: &Estimate,
        received_ns: u64,
        seq: u64,
        planner_instance: u64,
        plan: &PlanInfo<'_>,
    ) -> Result<Self, ProtocolError> {
        Ok(Command::new(estimate.header.step, seq, planner_instance, plan)?
            .carrying(estimate, received_ns)
            .with_state_of(estimate))
    }

    /// Sets the solver name.
    pub fn set_solver(&mut self, name: &str) -> Result<(), ProtocolError> {
        self.solver = Name16::new("solver", name)?;
        Ok(())
    }

    /// The solver name (`None` if the bytes are not a valid name).
    pub fn solver(&self) -> Option<&str> {
        self.solver.as_str()
    }

    /// Sets the objective name.
    pub fn set_objective_name(&mut self, name: &str) -> Result<(), ProtocolError> {
        self.objective_name = Name16::new("objective_name", name)?;
        Ok(())
    }

    /// The objective name (`None` if the bytes are not a valid name).
    pub fn objective_name(&self) -> Option<&str> {
        self.objective_name.as_str()
    }
}
