//! The four roles of a launch and their restart policy, as data: which roles end the run by exiting 0,
//! which exits a restart would only repeat, and what a restarted instance is given.

use std::fmt;
use std::process::ExitStatus;

/// A child role of `uavloc launch` (the subcommand of `uavloc process`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Role {
    /// Records the run; exits 0 once it has the last step.
    Monitor,
    /// Plans each step; runs until stopped.
    Planner,
    /// Estimates each step; runs until stopped.
    Estimator,
    /// The MAVLink bridge to the UAVs' autopilots (with `--autopilot`); runs until stopped.
    Bridge,
    /// The world; prints `finished` after the last step (and lingers for replays).
    EmitterSim,
}

/// What a launch's restarts depend on besides the exit: where the measurements come from, and whether
/// aircraft fly (`--autopilot`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Recovery {
    /// emitter-sim or an external front end.
    pub source: runtime::Source,
    /// Real or simulated aircraft fly the commands through the MAVLink bridge.
    pub aircraft: bool,
}

/// What to do with a child that exited.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum RestartDecision {
    /// Its part of the run is done (or another instance took over): nothing to do.
    Done,
    /// A crash: start the role again (attempt n, from 1).
    Restart {
        /// The attempt number.
        attempt: u32,
    },
    /// A restart would only repeat the failure (bad input, an unrecoverable run) or the restarts are used
    /// up: the launch fails with this message.
    Fail(String),
}

impl Role {
    /// The start order: each role's subscriptions exist before the next one publishes.
    pub const START_ORDER: [Role; 5] = [Role::Monitor, Role::Planner, Role::Estimator, Role::Bridge, Role::EmitterSim];

    /// The roles a launch starts, in start order: the monitor, the planner and the estimator; emitter-sim
    /// unless the measurements come from an external front end; the bridge when aircraft fly
    /// (`autopilots`).
    pub fn started(source: runtime::Source, autopilots: bool) -> impl Iterator<Item = Role> {
        Self::START_ORDER.into_iter().filter(move |r| match r {
            Role::EmitterSim => source == runtime::Source::Simulator,
            Role::Bridge => autopilots,
            _ => true,
        })
    }

    /// The `uavloc process` subcommand and node-name suffix.
    pub fn name(self) -> &'static str {
        match self {
            Role::Monitor => "monitor",
            Role::Planner => "planner",
            Role::Estimator => "estimator",
            Role::Bridge => "bridge",
            Role::EmitterSim => "emitter-sim",
        }
    }

    /// Whether an exit with code 0 is this role's normal end (the monitor with the whole record,
    /// emitter-sim after the last step); the planner and the estimator run until stopped.
    pub fn ends_by_itself(self) -> bool {
        matches!(self, Role::Monitor | Role::EmitterSim)
    }

    /// The flag a restarted instance gets on top of the first one's (the monitor resumes its log; the
    /// bridge rejoins UAVs that have flown away from their starts).
    pub fn restart_flag(self) -> Option<&'static str> {
        match self {
            Role::Monitor => Some("--resume"),
            Role::Bridge => Some("--rejoin"),
            _ => None,
        }
    }

    /// The decision for an instance of this role that exited with `status` after `restarts_so_far`
    /// restarts of the role; `handed_over`: it left because a swapped-in instance took over.
    ///
    /// With an external front end (`source`) a crashed monitor is not restarted: the front end measures
    /// each step once, and the steps it publishes while the monitor is down cannot be replayed to the
    /// restarted one (emitter-sim would), so the record could never be whole — the launch fails at once,
    /// saying so. A crashed estimator or planner is restarted: the monitor gives the measurement of the
    /// step in flight again (`protocol::services::measurement_replay`).
    pub fn on_exit(
        self,
        status: ExitStatus,
        handed_over: bool,
        restarts_so_far: u32,
        max_restarts: u32,
        recovery: Recovery,
    ) -> RestartDecision {
        let source = recovery.source;
        if handed_over || (status.success() && self.ends_by_itself()) {
            return RestartDecision::Done;
        }
        let what = describe(status);
        // Shared memory exhausted: a restart would die the same way (and burn every restart in a second).
        if std::os::unix::process::ExitStatusExt::signal(&status) == Some(libc::SIGBUS) {
            return RestartDecision::Fail(format!(
                "the {self} process stopped unexpectedly ({what}); {}",
                super::shm::sigbus_reason()
            ));
        }
        // Bad input (2) and a run that cannot go on (3) would fail again the same way.
        if matches!(status.code(), Some(c) if c == 2 || c == i32::from(runtime::EXIT_UNRECOVERABLE)) {
            return RestartDecision::Fail(format!("the {self} process stopped unexpectedly ({what})"));
        }
        if recovery.aircraft && self == Role::EmitterSim {
            return RestartDecision::Fail(format!(
                "the emitter-sim process stopped unexpectedly ({what}); with aircraft (--autopilot) it is not \
                 restarted: the UAVs have flown on, so the steps already published cannot be measured again the \
                 same — the steps recorded so far are in the log; the aircraft keep their last target; start \
                 the launch again"
            ));
        }
        if source == runtime::Source::External && self == Role::Monitor {
            return RestartDecision::Fail(format!(
                "the monitor process stopped unexpectedly ({what}); with an external front end (--source external) \
                 a crashed monitor is not restarted: the steps published while it is down cannot be measured \
                 again, so its record could not be whole — the steps recorded so far are in the log; start the \
                 launch and the front end again"
            ));
        }
        let attempt = restarts_so_far + 1;
        if attempt > max_restarts {
            return RestartDecision::Fail(format!(
                "the {self} process stopped unexpectedly ({what}) after {restarts_so_far} restart(s)"
            ));
        }
        RestartDecision::Restart { attempt }
    }
}

impl fmt::Display for Role {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// `exit code N`, `signal N`.
pub fn describe(status: ExitStatus) -> String {
    match (status.code(), std::os::unix::process::ExitStatusExt::signal(&status)) {
        (Some(c), _) => format!("exit code {c}"),
        (None, Some(sig)) => format!("signal {sig}"),
        _ => "an unknown status".into(),
    }
}

#[cfg(test)]
mod tests {
    use std::os::unix::process::ExitStatusExt as _;

    use super::*;

    const SIM: Recovery = Recovery { source: runtime::Source::Simulator, aircraft: false };
    const EXTERNAL: Recovery = Recovery { source: runtime::Source::External, aircraft: false };
    const AIRCRAFT: Recovery = Recovery { source: runtime::Source::Simulator, aircraft: true };

    fn code(c: i32) -> ExitStatus {
        ExitStatus::from_raw(c << 8)
    }

    fn signal(s: i32) -> ExitStatus {
        ExitStatus::from_raw(s)
    }

    #[test]
    fn restart_policy() {
        // A normal end.
        assert_eq!(Role::Monitor.on_exit(code(0), false, 0, 5, SIM), RestartDecision::Done);
        assert_eq!(Role::EmitterSim.on_exit(code(0), false, 0, 5, SIM), RestartDecision::Done);
        // The planner and the estimator do not end by themselves: exit 0 is a crash…
        assert_eq!(Role::Planner.on_exit(code(0), false, 0, 5, SIM), RestartDecision::Restart { attempt: 1 });
        // … unless a swapped-in instance took over.
        assert_eq!(Role::Estimator.on_exit(code(0), true, 0, 5, SIM), RestartDecision::Done);
        // Crashes restart, up to the limit.
        assert_eq!(Role::Estimator.on_exit(signal(9), false, 2, 5, SIM), RestartDecision::Restart { attempt: 3 });
        // SIGBUS: shared memory exhausted — no restart, said so.
        let bus = Role::Planner.on_exit(signal(libc::SIGBUS), false, 0, 5, SIM);
        assert!(matches!(&bus, RestartDecision::Fail(m) if m.contains("shared memory is exhausted")), "{bus:?}");
        // With an external front end nobody can measure the steps published while the monitor is down:
        // its crash fails the launch at once, saying why; the estimator and the planner are restarted
        // (the monitor gives the step in flight again).
        let external = Role::Monitor.on_exit(signal(9), false, 0, 5, EXTERNAL);
        assert!(
            matches!(&external, RestartDecision::Fail(m) if m.contains("signal 9") && m.contains("not restarted")),
            "{external:?}"
        );
        for role in [Role::Estimator, Role::Planner] {
            let external = role.on_exit(signal(9), false, 0, 5, EXTERNAL);
            assert_eq!(external, RestartDecision::Restart { attempt: 1 }, "{role}");
        }
        assert_eq!(Role::Monitor.on_exit(code(0), false, 0, 5, EXTERNAL), RestartDecision::Done);
        assert_eq!(Role::Monitor.on_exit(code(1), false, 4, 5, SIM), RestartDecision::Restart { attempt: 5 });
        assert!(
            matches!(Role::Monitor.on_exit(code(1), false, 5, 5, SIM), RestartDecision::Fail(m) if m.contains("after 5 restart(s)"))
        );
        // With aircraft a crashed emitter-sim cannot measure the flown steps again: the launch fails, saying
        // why; the bridge and the others restart.
        let flying = Role::EmitterSim.on_exit(signal(9), false, 0, 5, AIRCRAFT);
        assert!(matches!(&flying, RestartDecision::Fail(m) if m.contains("--autopilot")), "{flying:?}");
        assert_eq!(Role::EmitterSim.on_exit(code(0), false, 0, 5, AIRCRAFT), RestartDecision::Done);
        for role in [Role::Bridge, Role::Planner, Role::Estimator, Role::Monitor] {
            assert_eq!(
                role.on_exit(signal(9), false, 0, 5, AIRCRAFT),
                RestartDecision::Restart { attempt: 1 },
                "{role}"
            );
        }
        // Failures that would repeat are not restarted.
        for c in [2, i32::from(runtime::EXIT_UNRECOVERABLE)] {
            assert!(
                matches!(Role::EmitterSim.on_exit(code(c), false, 0, 5, SIM), RestartDecision::Fail(m) if m.contains(&format!("exit code {c}")))
            );
        }
    }

    #[test]
    fn names_and_order() {
        assert_eq!(Role::START_ORDER.map(Role::name), ["monitor", "planner", "estimator", "bridge", "emitter-sim"]);
        let sim = Role::started(runtime::Source::Simulator, false).collect::<Vec<_>>();
        assert!(!sim.contains(&Role::Bridge) && sim.contains(&Role::EmitterSim));
        let flying = Role::started(runtime::Source::Simulator, true).collect::<Vec<_>>();
        assert_eq!(flying.iter().position(|r| *r == Role::Bridge), Some(3), "before emitter-sim, which waits for it");
        assert_eq!(Role::Monitor.restart_flag(), Some("--resume"));
        assert_eq!(Role::Bridge.restart_flag(), Some("--rejoin"));
    }
}
