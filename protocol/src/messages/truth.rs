//! emitter-sim → monitor: the true emitter of a step and what the world did with the command before it.

use super::*;

wire_enum! {
    /// What the world did with the command of the step before (carried by [`Truth::previous_command`]).
    pub enum CommandOutcome : u32, decoded by from_u32 {
        /// No step before (step 0), or not stated.
        None = 0, "none";
        /// The command of step k − 1 was flown.
        Flown = 1, "flown";
        /// No command for step k − 1 arrived before step k was due (emitter-sim's real-time mode): the UAVs
        /// flew the hold of a step without a plan (`planning::hold`: their backup circles, or straight on
        /// with the waypoint planner), and a command that came later was not applied.
        Missed = 2, "missed";
    }
}

/// emitter-sim → monitor only: the true emitter position of a step (never seen by estimator or planner),
/// what the world did in the interval before it — whether the command of the step before was flown or
/// missed ([`CommandOutcome`]) — and which of the step's arrivals came by a reflection (the world's
/// multipath truth, for the monitor's identification counts). Only emitter-sim knows these for sure: in
/// real-time mode a command may reach the monitor and still be too late for the world.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("uavloc::Truth/v3")]
#[repr(C)]
pub struct Truth {
    /// Common header (step of the measurement it belongs to).
    pub header: Header,
    /// True emitter position, metres.
    pub position: [f64; 2],
    /// [`CommandOutcome`] of the command of step `header.step − 1`, as `u32`.
    pub previous_command: u32,
    /// Bit i: UAV i's arrival of this step came by a reflection (late); 0 for a direct-path world.
    pub multipath: u32,
}

impl_message!(Truth, MessageKind::Truth, 3, "uavloc::Truth/v3");

impl Truth {
    /// The truth of `step` (previous command: [`CommandOutcome::None`]).
    pub fn new(step: u64, seq: u64, position: [f64; 2]) -> Self {
        Truth {
            header: Header::new(Self::VERSION, step, seq),
            position,
            previous_command: CommandOutcome::None as u32,
            multipath: 0,
        }
    }

    /// The same truth, saying which arrivals came by a reflection (bit i: UAV i).
    pub fn with_multipath(mut self, mask: u8) -> Self {
        self.multipath = u32::from(mask);
        self
    }

    /// The same truth, saying what became of the command of the step before.
    pub fn with_previous_command(mut self, outcome: CommandOutcome) -> Self {
        self.previous_command = outcome as u32;
        self
    }

    /// The decoded outcome of the previous step's command (`None` for an unknown wire value).
    pub fn previous_command(&self) -> Option<CommandOutcome> {
        CommandOutcome::from_u32(self.previous_command)
    }
}
