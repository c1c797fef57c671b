//! The supervisor of a launch's children: spawning `uavloc process <role>`, reading their typed stdout
//! lines, restarting the ones that crash (by their [`Role`]'s policy), stopping them all.

use std::collections::BTreeMap;
use std::io::BufReader;
use std::os::unix::process::CommandExt as _;
use std::path::PathBuf;
use std::process::{Child, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::time::{Duration, Instant};

use protocol::resources;
use protocol::services::Domain;
use record::RunRecord;
use runtime::SupervisorLine;

use super::role::{Recovery, RestartDecision, Role, describe};
use super::signals;
use crate::error::CliError;

/// How often the launcher checks that a swapped-in process (not its child) is still there.
const SWAPPED_CHECK: Duration = Duration::from_millis(500);

/// How long a child may take to print `ready`.
const READY_TIMEOUT: Duration = Duration::from_secs(30);
/// How long the estimator and planner get to exit after SIGTERM before SIGKILL.
pub(super) const STOP_GRACE: Duration = Duration::from_secs(5);
/// How often the launcher looks at its children and signals when nothing else happens.
pub(super) const TICK: Duration = Duration::from_millis(50);
/// The wait before the first restart of a crashed process; it doubles with each further restart of the
/// same role, up to [`RESTART_BACKOFF_MAX`].
const RESTART_BACKOFF: Duration = Duration::from_millis(50);
/// The longest wait before a restart (reached at the 6th restart of a role), so that a process restarted
/// many times in a long run is not left out for seconds or minutes.
const RESTART_BACKOFF_MAX: Duration = Duration::from_millis(1600);

/// The wait before restart number `attempt` (1, 2, …) of a role: min(50 ms · 2^(attempt − 1), 1.6 s).
fn restart_backoff(attempt: u32) -> Duration {
    let factor = 2u32.checked_pow(attempt.saturating_sub(1)).unwrap_or(u32::MAX);
    RESTART_BACKOFF.saturating_mul(factor).min(RESTART_BACKOFF_MAX)
}

enum Event {
    /// A line or the run record of child `i`.
    Output(usize, Box<runtime::Output<RunRecord>>),
    Closed(usize),
}

pub(super) struct Proc {
    pub(super) role: Role,
    /// Its flags (a restart uses them again).
    pub(super) flags: Vec<String>,
    /// It crashed and was restarted (a newer entry of the same role took its place).
    pub(super) replaced: bool,
    pub(super) child: Child,
    ready: bool,
    /// Its stdout reached end of file (every line it printed has been handled).
    closed: bool,
    exit: Option<std::process::ExitStatus>,
    pub(super) summary: Option<serde_json::Value>,
    /// emitter-sim with `--linger`: it published the last step (and stays to serve replays).
    finished: bool,
    /// The error it told before exiting ([`SupervisorLine::Failed`]).
    failure: Option<String>,
}

impl Proc {
    /// It exited because a newer instance took over (`uavloc swap`): no restart.
    fn handed_over(&self) -> bool {
        self.exit.is_some_and(|s| s.success()) && self.summary.as_ref().is_some_and(|s| !s["handed_over_at"].is_null())
    }

    /// Its role's decision on its exit (`None` while it runs, once it was replaced, and until its last
    /// lines are all in — its summary, its record, the error it told: the exit may be reaped before its
    /// stdout is read to the end), given the role's `restarts` so far.
    fn decision(&self, restarts: u32, max_restarts: u32, recovery: Recovery) -> Option<RestartDecision> {
        let status = self.exit?;
        if self.replaced || !self.closed {
            return None;
        }
        match self.role.on_exit(status, self.handed_over(), restarts, max_restarts, recovery) {
            // Why, in its own words, after the launcher's.
            RestartDecision::Fail(why) if let Some(error) = &self.failure => {
                Some(RestartDecision::Fail(format!("{why}: {error}")))
            }
            decision => Some(decision),
        }
    }

    fn needs_restart(&self, recovery: Recovery) -> bool {
        matches!(self.decision(0, u32::MAX, recovery), Some(RestartDecision::Restart { .. }))
    }

    pub(super) fn describe_exit(&self) -> String {
        self.exit.map_or_else(|| "still running".into(), describe)
    }
}

/// How long the end of a run may take ([`Supervisor::wait_for_the_end`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct EndGrace {
    /// From emitter-sim's end until the monitor has recorded the last step (its `finished`).
    pub(super) record: Duration,
    /// From the monitor's `finished` until it has handed the run record over and exited: it reads the
    /// steps back from its log, annotates them and writes its files, work that grows with the run.
    pub(super) write: Duration,
}

impl EndGrace {
    /// `record` for the last step, and for the record's writing 30 s plus 1 ms per step (≈ 15 × the
    /// 60–70 µs per step it takes on 2 cores).
    pub(super) fn new(record: Duration, steps: usize) -> Self {
        Self { record, write: Duration::from_secs(30) + Duration::from_millis(steps as u64) }
    }
}

/// The running children and the lines they print on stdout.
pub(super) struct Supervisor {
    pub(super) procs: Vec<Proc>,
    tx: Sender<Event>,
    rx: Receiver<Event>,
    /// The monitor's run record (parsed as it streamed in), or what was wrong with it.
    pub(super) record: Option<Result<RunRecord, String>>,
    domain: Domain,
    /// The monitor's JSON-lines log, where restarts are written too.
    log: Option<PathBuf>,
    max_restarts: u32,
    /// Where the measurements come from: with an external front end a crash cannot be recovered
    /// ([`Role::on_exit`]).
    source: runtime::Source,
    /// Aircraft fly the commands (`--autopilot`): a crashed emitter-sim is not restarted
    /// ([`Role::on_exit`]).
    pub(super) aircraft: bool,
    pub(super) restarts: u64,
    /// CPU use of the idle children before the run (see [`LaunchArgs::idle_probe_ms`]).
    pub(super) idle_cpu: BTreeMap<String, f64>,
}

impl Supervisor {
    /// What the restarts depend on besides the exit.
    fn recovery(&self) -> Recovery {
        Recovery { source: self.source, aircraft: self.aircraft }
    }

    pub(super) fn new(domain: Domain, log: Option<PathBuf>, max_restarts: u32, source: runtime::Source) -> Self {
        let (tx, rx) = mpsc::channel();
        Self {
            procs: Vec::new(),
            tx,
            rx,
            record: None,
            domain,
            log,
            max_restarts,
            source,
            aircraft: false,
            restarts: 0,
            idle_cpu: BTreeMap::new(),
        }
    }

    /// The current instance of `role`.
    pub(super) fn index(&self, role: Role) -> usize {
        self.find(role).expect("a started role")
    }

    /// The current instance of `role`, if the launch started one.
    pub(super) fn find(&self, role: Role) -> Option<usize> {
        self.procs.iter().rposition(|p| p.role == role)
    }

    /// Starts `uavloc process <role> <flags> --supervised` with stdout piped to a reader thread.
    pub(super) fn spawn(&mut self, role: Role, flags: Vec<String>) -> Result<(), CliError> {
        let exe = std::env::current_exe().map_err(|e| CliError::failed_because("cannot find this executable", e))?;
        let mut command = std::process::Command::new(exe);
        command
            .arg("process")
            .arg(role.name())
            .args(flags.iter())
            .arg("--supervised")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .process_group(0);
        // SAFETY: the closure runs in the forked child before exec and only makes async-signal-safe system
        // calls (prctl, getppid, kill on itself); it allocates nothing and touches no lock.
        #[cfg(target_os = "linux")]
        unsafe {
            let parent = libc::getpid();
            command.pre_exec(move || {
                libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM);
                if libc::getppid() != parent {
                    // The launcher died between fork and prctl.
                    libc::kill(libc::getpid(), libc::SIGTERM);
                }
                Ok(())
            });
        }
        let mut child = command.spawn().map_err(|e| CliError::failed_because(format!("cannot start the {role}"), e))?;
        let stdout = child.stdout.take().expect("piped stdout");
        let index = self.procs.len();
        let tx = self.tx.clone();
        std::thread::spawn(move || {
            let mut reader = BufReader::new(stdout);
            while let Ok(Some(output)) = runtime::read_output(&mut reader) {
                if tx.send(Event::Output(index, Box::new(output))).is_err() {
                    return;
                }
            }
            let _ = tx.send(Event::Closed(index));
        });
        self.procs.push(Proc {
            role,
            flags,
            replaced: false,
            child,
            ready: false,
            closed: false,
            exit: None,
            summary: None,
            finished: false,
            failure: None,
        });
        Ok(())
    }

    fn handle(&mut self, event: Event) {
        match event {
            Event::Output(i, output) => {
                let p = &mut self.procs[i];
                match *output {
                    runtime::Output::Line(Some(SupervisorLine::Ready)) => p.ready = true,
                    runtime::Output::Line(Some(SupervisorLine::Finished)) => p.finished = true,
                    runtime::Output::Line(Some(SupervisorLine::Summary(v))) => p.summary = Some(v),
                    runtime::Output::Line(Some(SupervisorLine::Failed(why))) => p.failure = Some(why),
                    runtime::Output::Record(record) => self.record = Some(record),
                    runtime::Output::Line(_) => {}
                }
            }
            Event::Closed(i) => {
                // stdout closed: the child is exiting; reap it.
                self.procs[i].closed = true;
                if let Ok(status) = self.procs[i].child.wait() {
                    self.procs[i].exit = Some(status);
                }
            }
        }
    }

    /// Handles events for up to [`TICK`], reaps exited children, and reports a pending signal.
    fn pump(&mut self) -> Result<(), CliError> {
        match self.rx.recv_timeout(TICK) {
            Ok(event) => {
                self.handle(event);
                while let Ok(event) = self.rx.try_recv() {
                    self.handle(event);
                }
            }
            Err(RecvTimeoutError::Timeout | RecvTimeoutError::Disconnected) => {}
        }
        for p in &mut self.procs {
            if p.exit.is_none()
                && let Ok(Some(status)) = p.child.try_wait()
            {
                p.exit = Some(status);
            }
        }
        match signals::received() {
            None => Ok(()),
            Some(name) => Err(CliError::Failed(format!("interrupted by {name}; stopped every process"))),
        }
    }

    /// Fails if a child has exited although it should still run (`expected` lists the roles allowed to
    /// have finished, with exit code 0).
    fn check_exits(&self, finished_ok: &[Role]) -> Result<(), CliError> {
        for p in self.procs.iter().filter(|p| !p.replaced) {
            if let Some(status) = p.exit
                && !(finished_ok.contains(&p.role) && status.success())
            {
                return Err(CliError::Failed(format!(
                    "the {} process stopped unexpectedly ({})",
                    p.role,
                    p.describe_exit()
                )));
            }
        }
        Ok(())
    }

    /// Waits until `role` printed `ready`. A short run may be over by then: emitter-sim and the monitor
    /// ending with exit code 0 is no failure (their `ready` lines still come, they precede the exit).
    pub(super) fn wait_ready(&mut self, role: Role) -> Result<(), CliError> {
        self.until_ready(self.index(role), |sup, p| {
            sup.check_exits(&[Role::EmitterSim, Role::Monitor])?;
            if p.closed && !p.ready {
                return Err(CliError::Failed(format!(
                    "the {role} process ended ({}) before it got ready",
                    p.describe_exit()
                )));
            }
            Ok(false)
        })
    }

    /// Handles events until process `i` printed `ready`, or `stop` (given the supervisor and the process)
    /// says to stop waiting; fails after [`READY_TIMEOUT`].
    fn until_ready(&mut self, i: usize, stop: impl Fn(&Self, &Proc) -> Result<bool, CliError>) -> Result<(), CliError> {
        let deadline = Instant::now() + READY_TIMEOUT;
        while !self.procs[i].ready {
            self.pump()?;
            if stop(self, &self.procs[i])? {
                break;
            }
            if Instant::now() > deadline {
                let role = self.procs[i].role;
                // A restart's new instance: an earlier one of its role was replaced.
                let restarted = if self.procs[..i].iter().any(|q| q.role == role) { "restarted " } else { "" };
                return Err(CliError::Failed(format!(
                    "the {restarted}{role} process did not get ready within {READY_TIMEOUT:?}"
                )));
            }
        }
        Ok(())
    }

    /// The current instance of each role, as the live view lists them.
    pub(super) fn process_rows(&self) -> Vec<crate::live::ProcessRow> {
        let mut rows = Vec::new();
        for role in Role::START_ORDER {
            if let Some(i) = self.find(role) {
                let p = &self.procs[i];
                let restarts = self.procs.iter().filter(|q| q.role == role && q.replaced).count() as u64;
                rows.push(crate::live::ProcessRow {
                    role: role.to_string(),
                    pid: p.child.id(),
                    running: p.exit.is_none(),
                    restarts,
                });
            }
        }
        rows
    }

    /// Runs until emitter-sim and the monitor have finished, restarting the processes that crash; the
    /// monitor gets `grace.record` after emitter-sim's end (its `finished`, or its exit) to record the
    /// last step (its own `finished`), and then `grace.write` to build the run record from its log, write
    /// its files and hand the record over. A lingering emitter-sim (`--linger`) replays the run to a
    /// monitor that fell behind or was restarted while the run ended, and is stopped with the others
    /// afterwards.
    pub(super) fn wait_for_the_end(
        &mut self,
        grace: EndGrace,
        on_tick: &mut dyn FnMut(&Supervisor),
    ) -> Result<(), CliError> {
        let mut emitter_done_at = None;
        let mut monitor_done_at = None;
        let mut checked_swapped = Instant::now();
        loop {
            self.pump()?;
            on_tick(self);
            self.restart_crashed()?;
            if checked_swapped.elapsed() > SWAPPED_CHECK {
                checked_swapped = Instant::now();
                self.check_swapped_in()?;
            }
            let monitor = self.index(Role::Monitor);
            // Only a successful exit is the end: one that crashed while another process was being restarted
            // (after `restart_crashed` went past it) is restarted in the next round.
            let ended = |i: usize| self.procs[i].exit.is_some_and(|s| s.success());
            // Without emitter-sim (an external front end) the monitor's end is the run's.
            let Some(emitter) = self.find(Role::EmitterSim) else {
                if ended(monitor) {
                    return Ok(());
                }
                continue;
            };
            if ended(monitor) {
                return Ok(());
            }
            if self.procs[monitor].finished {
                // Timed per monitor process: one restarted after its predecessor's `finished` has its own.
                let since = match monitor_done_at {
                    Some((i, at)) if i == monitor => at,
                    _ => monitor_done_at.insert((monitor, Instant::now())).1,
                };
                if since.elapsed() > grace.write {
                    return Err(CliError::Failed(format!(
                        "the monitor recorded the last step but did not hand over the run record within {:?}",
                        grace.write
                    )));
                }
            } else if ended(emitter) || self.procs[emitter].finished {
                let since = *emitter_done_at.get_or_insert_with(Instant::now);
                if since.elapsed() > grace.record {
                    return Err(CliError::Failed(format!(
                        "the monitor did not record the last step within {:?} of the end of the run",
                        grace.record
                    )));
                }
            }
        }
    }

    /// A role whose child handed over to a process started by `uavloc swap` is served by a process that
    /// is not the launcher's child, so the launcher cannot restart it; if it is gone (its node is not
    /// alive: it crashed or was killed), the run fails at once with a message saying so — it would stall
    /// otherwise.
    fn check_swapped_in(&self) -> Result<(), CliError> {
        for role in [Role::Planner, Role::Estimator] {
            let current = &self.procs[self.index(role)];
            if current.exit.is_none() || !current.handed_over() {
                continue;
            }
            let node = protocol::services::node_name(&self.domain, role.name());
            let alive = resources::list(&self.domain).map_err(CliError::Failed)?.alive_nodes().any(|n| n == node);
            if !alive {
                return Err(CliError::Failed(format!(
                    "the {role} swapped in by `uavloc swap` is gone (it is not the launcher's child, so it is not \
                     restarted); stopping the run"
                )));
            }
        }
        Ok(())
    }

    /// Restarts every current process that exited although it should still run — all but emitter-sim and
    /// the monitor after a successful end. A process that exits with code 2 (bad input) or 3 (the run cannot
    /// go on, e.g. two UAVs collided), or has crashed
    /// `max_restarts` times fails the launch.
    fn restart_crashed(&mut self) -> Result<(), CliError> {
        for i in 0..self.procs.len() {
            let role = self.procs[i].role;
            let restarts = self.procs.iter().filter(|q| q.role == role && q.replaced).count() as u32;
            match self.procs[i].decision(restarts, self.max_restarts, self.recovery()) {
                None | Some(RestartDecision::Done) => {}
                Some(RestartDecision::Restart { .. }) if let Some(pid) = self.swapped_in(role) => {
                    self.leave_to_swapped_in(i, pid)?
                }
                Some(RestartDecision::Restart { attempt }) => self.restart(i, attempt)?,
                Some(RestartDecision::Fail(why)) => return Err(CliError::Failed(why)),
            }
        }
        Ok(())
    }

    /// A planner or estimator of the domain that is not one of this launch's children (swapped in by
    /// `uavloc swap`, alive): its pid. It goes on from the step its predecessor left (a planner plans it
    /// when it comes again; an estimator asks for it and for the state it lacks).
    fn swapped_in(&self, role: Role) -> Option<u32> {
        if !matches!(role, Role::Planner | Role::Estimator) {
            return None;
        }
        let name = protocol::services::node_name(&self.domain, role.name());
        let ours: Vec<u32> = self.procs.iter().map(|p| p.child.id()).collect();
        resources::list(&self.domain).ok()?.alive_pids(&name).into_iter().find(|pid| !ours.contains(pid))
    }

    /// Process `i` died while a swapped-in instance of its role (pid `pid`) runs: that one goes on, no
    /// restart (a restart would be refused: two would answer every step).
    fn leave_to_swapped_in(&mut self, i: usize, pid: u32) -> Result<(), CliError> {
        let (role, exit, old) = (self.procs[i].role, self.procs[i].describe_exit(), self.procs[i].child.id());
        protocol::log_line!(
            "warning: the {role} process (pid {old}) stopped unexpectedly ({exit}) during a swap; the swapped-in \
             {role} (pid {pid}) goes on, no restart"
        );
        self.write_log(serde_json::json!({
            "event": "left_to_swapped_in", "t_ns": protocol::now_ns(), "role": role.name(), "pid": old,
            "exit": exit, "swapped_in": pid,
        }));
        self.procs[i].replaced = true;
        resources::remove_dead_nodes(&self.domain).map_err(CliError::Failed)?;
        Ok(())
    }

    /// Restarts process `i` (attempt `attempt`): writes the restart to the log, removes the dead node's
    /// iceoryx2 resources, waits [`restart_backoff`]`(attempt)`, starts the same role with the same flags (a
    /// monitor with `--resume`) and waits until it is ready — or until another process needs a restart: a
    /// restarted emitter-sim gets ready only once the whole pipeline is connected, so it would wait in vain
    /// for a process that died with it (two processes killed at once); the new process then gets ready by
    /// itself. If the new process fails to get ready, it is left exited: the next round restarts it again
    /// (and counts the attempt).
    fn restart(&mut self, i: usize, attempt: u32) -> Result<(), CliError> {
        let backoff = restart_backoff(attempt);
        let (role, exit, pid) = (self.procs[i].role, self.procs[i].describe_exit(), self.procs[i].child.id());
        protocol::log_line!(
            "warning: the {role} process (pid {pid}) stopped unexpectedly ({exit}); restarting it in {backoff:?} \
             (attempt {attempt} of {})",
            self.max_restarts
        );
        self.write_log(serde_json::json!({
            "event": "restart", "t_ns": protocol::now_ns(), "role": role.name(), "pid": pid, "exit": exit,
            "attempt": attempt, "backoff_ms": backoff.as_millis() as u64,
        }));
        self.procs[i].replaced = true;
        resources::remove_dead_nodes(&self.domain).map_err(CliError::Failed)?;
        let until = Instant::now() + backoff;
        while Instant::now() < until {
            self.pump()?;
        }
        // A swap was starting its new instance meanwhile (its node did not show yet when the old one died):
        // that one goes on instead.
        if let Some(other) = self.swapped_in(role) {
            protocol::log_line!("warning: not restarting the {role}: the swapped-in {role} (pid {other}) goes on");
            self.write_log(serde_json::json!({
                "event": "left_to_swapped_in", "t_ns": protocol::now_ns(), "role": role.name(), "pid": pid,
                "exit": exit, "swapped_in": other,
            }));
            return Ok(());
        }
        self.restarts += 1;
        let mut flags = self.procs[i].flags.clone();
        if let Some(flag) = role.restart_flag()
            && !flags.iter().any(|f| f == flag)
        {
            flags.push(flag.into());
        }
        self.spawn(role, flags)?;
        // Not ready, but exited, or another process needs a restart: the next round sees to it.
        self.until_ready(self.procs.len() - 1, |sup, p| {
            Ok(p.exit.is_some() || sup.procs.iter().any(|q| q.needs_restart(sup.recovery())))
        })
    }

    /// Appends one event to the monitor's JSON-lines log (one `write`, like the monitor's own lines).
    fn write_log(&self, event: serde_json::Value) {
        use std::io::Write as _;
        if let Some(path) = &self.log
            && let Ok(mut f) = std::fs::OpenOptions::new().create(true).append(true).open(path)
        {
            let _ = f.write_all(format!("{event}\n").as_bytes());
        }
    }

    /// SIGTERM to every running child, then SIGKILL to those still running after [`STOP_GRACE`]; drains
    /// their last lines (summaries).
    pub(super) fn stop_all(&mut self) {
        for p in &self.procs {
            if p.exit.is_none() {
                // SAFETY: kill(2) on a child we spawned and have not reaped (its pid cannot have been reused).
                unsafe { libc::kill(p.child.id() as libc::pid_t, libc::SIGTERM) };
            }
        }
        let deadline = Instant::now() + STOP_GRACE;
        while self.procs.iter().any(|p| p.exit.is_none()) && Instant::now() < deadline {
            let _ = self.pump();
        }
        for p in &mut self.procs {
            if p.exit.is_none() {
                protocol::log_line!("warning: the {} process ignored SIGTERM; killing it", p.role);
                let _ = p.child.kill();
                p.exit = p.child.wait().ok();
            }
        }
        // Every child has exited: its reader thread forwards the last lines (summaries) and the end of
        // its pipe.
        let deadline = Instant::now() + Duration::from_secs(2);
        while self.procs.iter().any(|p| !p.closed) && Instant::now() < deadline {
            match self.rx.recv_timeout(TICK) {
                Ok(event) => self.handle(event),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
        }
    }
}
