//! `uavloc launch`: the process pipeline — monitor, planner, estimator and emitter-sim as child processes
//! talking over iceoryx2 — run to the end of a scenario, in lock-step or in real time (`--mode`,
//! `--time-scale`, passed to emitter-sim; see `emitter_sim::process`); and the hidden
//! `uavloc process <role>` that makes `uavloc` a multi-call binary (each child is `uavloc` itself, running
//! the same library entry point as the standalone `monitor`, `planner`, `estimator`, `emitter-sim`
//! binaries).
//!
//! # How a launch runs
//!
//! 1. The scenario is loaded as `uavloc simulate` loads it; the domain is `--domain`, else
//!    `$UAVLOC_DOMAIN`, else `uavloc-<pid>` (unique per launch). A domain with live processes is refused;
//!    dead leftovers of an earlier crash in it are cleaned up.
//! 2. The children start in the order monitor → planner → estimator → emitter-sim, each only after the
//!    previous one has printed `ready` on its stdout (its subscriptions exist), so no message is published
//!    before its subscribers are there (the topics keep no history). emitter-sim also checks the topics
//!    itself (≥ 2 measurement subscribers, a planner) before step 0.
//! 3. The run ends when emitter-sim has published the last step (it prints `finished` and, started with
//!    `--linger`, stays to replay the run to a monitor that fell behind or was restarted meanwhile) and the
//!    monitor has recorded it and exited 0; emitter-sim, the estimator and the planner are then stopped
//!    with SIGTERM (SIGKILL after a grace period).
//! 4. A child that exits before that (a crash, a kill, an error) is restarted: the restart is written to
//!    the `--log` (`{"event": "restart", "role", "pid", "exit", "attempt", "backoff_ms"}`) and counted in
//!    `restarts`; the dead node's iceoryx2 resources are removed; after min(50 ms · 2^(attempt − 1), 1.6 s)
//!    the same role starts again with the same flags (a monitor with `--resume`: it takes the steps of its
//!    log). The new process announces itself on the control topic and emitter-sim replays the run to it (see
//!    `emitter_sim::process`), so the run resumes exactly where it was; a restarted emitter-sim starts
//!    from the older world snapshot of its checkpoint (step 0 in a run younger than 512 steps) and
//!    fast-forwards through the answers the estimator and planner kept. In lock-step mode emitter-sim runs
//!    at most 128 steps ahead of the monitor (its `--monitor-window`), so a monitor restarted many times
//!    does not fall behind what can be replayed to it. A child that exits
//!    with code 2 (bad input) or 3 (the run cannot go on: two UAVs collided, so the world cannot measure),
//!    or crashes more than `--max-restarts` times, stops the others and fails the
//!    launch. (`tests/crash_restart.rs`.)
//! 5. At the end (or on an error or a signal), once its children are stopped, the launcher publishes a
//!    shutdown on the domain's control topic if processes of the domain are still alive — processes
//!    swapped in by `uavloc swap` are not its children and stop on it — and waits for them. A planner or estimator that exits because a swapped-in one took over (`handed_over_at` in
//!    its summary) is not restarted.
//! 6. Stale iceoryx2 resources of the domain (a child killed) are removed, and the launcher checks that
//!    none are left.
//!
//! Limits of restarts: in real-time mode emitter-sim does not wait for the monitor (the world keeps its
//! clock), so a monitor down for more than 256 steps while emitter-sim is restarted too may ask for a step
//! no longer kept (the run then stops with an error naming the steps); a process SIGKILLed inside
//! iceoryx2's node creation (a window of microseconds between its details file and its monitoring token)
//! leaves a node directory iceoryx2 cannot list or clean.
//!
//! Every child runs in its own process group (a terminal's Ctrl-C reaches only the launcher, which stops
//! the children in order) with `PR_SET_PDEATHSIG = SIGTERM`, so none outlives a launcher that dies.
//! SIGINT/SIGTERM on the launcher stop all children (exit code 1) and remove the iceoryx2 resources any of
//! them left behind (`tests/shutdown.rs`).
//!
//! The output is the monitor's run record, i.e. the JSON of `uavloc simulate --json` (built only from what
//! the monitor received), plus `restarts`, `rejected` (invalid messages counted by all four processes),
//! `rejected_by` (the same per process role; `tests/bad_messages.rs`) and `processes` (every instance
//! started: role, pid, exit, whether it was restarted, its summary).

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::os::unix::process::CommandExt as _;
use std::path::PathBuf;
use std::process::{Child, ExitCode, Stdio};
use std::sync::atomic::{AtomicI32, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::time::{Duration, Instant};

use clap::{Args, Subcommand};
use emitter_sim::process::Mode;
use estimator::EstimatorKind;
use monitor::RunRecord;
use monitor::resources::{self, DomainResources};
use planner::{ObjectiveKind, Scenario, SolverKind, TargetMode};
use protocol::services::{self, DOMAIN_ENV, Domain};
use serde::Serialize;

use crate::error::CliError;
use crate::output::{Diagnostic, Report, Table};
use crate::simulate::scenario_from;

pub const LONG_ABOUT: &str = "\
Run the closed loop as the four processes of the uavloc pipeline, exchanging zero-copy messages over
iceoryx2: emitter-sim (the world: true emitter, UAV motion, noisy TDOA) → estimator (Chan) → planner
(objective × solver under the motion constraints) → back to emitter-sim, with the monitor listening to
everything. The children are `uavloc` itself (`uavloc process <role>`), so no other binary is needed.

Two modes (--mode):
  lockstep (default)  the world advances as soon as the planner's command for a step arrives. For
                      benchmarks and tests, and the exact reproduction of `uavloc simulate`: for the same
                      scenario, objective, solver, steps and seed the trajectory, the estimates and the
                      metrics equal simulate's (only the planning times differ).
  realtime            the world flies at a rate: step k at t0 + k*dt/X, X = --time-scale (simulated
                      seconds per real second; the paper's 10 s step takes 0.1 s at --time-scale 100).
                      A command that is not there when the next step is due is missed: the UAVs fly
                      straight on at their headings, the step is recorded with objective_value null and
                      active_constraints [\"command_missed\"], and \"missed_commands\" counts it. With
                      every command in time the run still equals simulate.

Staleness (--estimate-deadline-ms D, off by default): when a step's estimate has not reached the planner D
ms after the step's measurement, the planner holds course (commands the current headings; the UAVs fly
straight on); the step is recorded with active_constraints [\"estimate_stale\"] and counted in
\"stale_steps\". Meant for realtime runs; a lock-step run with a deadline depends on timing.

The monitor shows one line per step on stderr (CRLB and RMSE at the truth, estimate error, hop latencies,
active planner, rejected messages) unless --headless. At the end the run is printed as a table, or with
--json as the JSON of `uavloc simulate --json` plus \"restarts\", \"rejected\", \"rejected_by\",
\"missed_commands\" and \"processes\".

A child that crashes is restarted (at most --max-restarts times per process role, after 50 ms, 100 ms, ...,
at most 1.6 s; written to the --log): emitter-sim replays the run to the new process, which picks up
exactly where its predecessor was, so the result does not change. A child whose run cannot go on (exit
code 3: two UAVs collided, so the world cannot measure) is not restarted: the launch fails with its error.

Only target = \"chan\" scenarios run in the pipeline (controlled mode needs the truth in the planner).
Exit codes: 0 success, 1 a process failed or the launch was interrupted, 2 bad input.";

pub const AFTER_HELP: &str = "\
Examples:
  uavloc launch
  uavloc launch --headless --json --steps 6 --objective mc
  uavloc launch --mode realtime --time-scale 100
  uavloc launch --scenario scenarios/nominal.toml --solver ga --domain lab1 --log run.jsonl --out runs/lab1

Each process also runs on its own, e.g. in four terminals (or systemd units) with one --domain:
  monitor --domain lab1 --log run.jsonl;  planner --domain lab1;  estimator --domain lab1
  emitter-sim --domain lab1 --min-subscribers 2";

/// Flags of `uavloc launch`.
#[derive(Args, Debug, Clone, PartialEq)]
pub struct LaunchArgs {
    /// Scenario TOML file (default: the paper's nominal case; see scenarios/nominal.toml).
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<PathBuf>,
    /// Planning objective: single | mc | analytical | cubature | formation.
    #[arg(long, default_value = "analytical")]
    pub objective: ObjectiveKind,
    /// Solver: pso | ga | aco (ignored by formation).
    #[arg(long, default_value = "pso")]
    pub solver: SolverKind,
    /// Number of planning steps (default: the scenario's, 24 for the paper).
    #[arg(long, value_name = "N")]
    pub steps: Option<usize>,
    /// Run seed (default: the scenario's).
    #[arg(long, value_name = "N")]
    pub seed: Option<u64>,
    /// The estimator: fused (the posterior of every measurement so far) or snapshot (the paper's Chan
    /// per step); default: the scenario's `estimator` (fused).
    #[arg(long, value_name = "KIND")]
    pub estimator: Option<EstimatorKind>,
    /// Pipeline domain, the prefix of every iceoryx2 service name (default: $UAVLOC_DOMAIN, else
    /// `uavloc-<pid>`, unique per launch).
    #[arg(long, value_name = "NAME")]
    pub domain: Option<String>,
    /// No live view: the monitor and the other processes print only errors.
    #[arg(long)]
    pub headless: bool,
    /// Directory for the monitor's CSVs, run.json and plots (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// The monitor's JSON-lines event log (default: a file in the launch's private state directory,
    /// removed at the end). The step records are kept there during the run, not in memory.
    #[arg(long, value_name = "FILE")]
    pub log: Option<PathBuf>,
    /// emitter-sim gives up when a step's command has not arrived after this many seconds.
    #[arg(long, value_name = "S", default_value_t = 10.0)]
    pub command_timeout_s: f64,
    /// Transport and waiting of every process.
    #[command(flatten)]
    pub link: protocol::LinkArgs,
    /// Write the raw stamps of every step as CSV (the monitor's --stamps; what `uavloc bench` reads).
    #[arg(long, value_name = "FILE")]
    pub stamps: Option<PathBuf>,
    /// For `uavloc bench`: before starting emitter-sim, measure the CPU use of the waiting monitor,
    /// planner and estimator over this many milliseconds (0: no probe).
    #[arg(skip)]
    pub idle_probe_ms: u64,
    /// Pacing of emitter-sim: lockstep (the next step as soon as the command arrives; for benchmarks and
    /// tests, and the exact reproduction of `uavloc simulate`) or realtime (fly at a rate set by
    /// --time-scale; a command that comes after the next step is due is missed and the UAVs keep their
    /// headings).
    #[arg(long, value_enum, value_name = "MODE", default_value_t = Mode::Lockstep)]
    pub mode: Mode,
    /// Realtime mode: simulated seconds per real second, > 0; a step lasts dt/X real seconds
    /// (--time-scale 100 runs the paper's 10 s step in 0.1 s, 1 is true real time). Ignored in lockstep.
    #[arg(long, value_name = "X", default_value_t = 1.0, allow_negative_numbers = true)]
    pub time_scale: f64,
    /// The planner's staleness deadline: a step whose estimate has not arrived this many milliseconds
    /// after its measurement is held (the current headings commanded, recorded as "estimate_stale").
    /// 0: no deadline.
    #[arg(long, value_name = "MS", default_value_t = 0)]
    pub estimate_deadline_ms: u64,
    /// emitter-sim waits this many milliseconds before each step after step 0 (a slow lock-step run for
    /// a demo, or to swap or kill a process mid-run; the results do not change). 0: full speed. Lockstep
    /// mode only (realtime: --time-scale).
    #[arg(long, value_name = "MS", default_value_t = 0)]
    pub step_delay_ms: u64,
    /// Test / fault-injection aid: the planner sleeps this many milliseconds before planning a step
    /// (those of --plan-delay-steps), like a slow planner; in realtime mode its commands then miss steps.
    #[arg(long, value_name = "MS", default_value_t = 0)]
    pub plan_delay_ms: u64,
    /// Test / fault-injection aid: the steps --plan-delay-ms applies to, comma-separated (default: all).
    #[arg(long, value_name = "K,..", value_delimiter = ',')]
    pub plan_delay_steps: Vec<u64>,
    /// emitter-sim replays the run when a step's command is this many milliseconds late.
    #[arg(long, value_name = "MS", default_value_t = 1000)]
    pub retry_interval_ms: u64,
    /// Restart a crashed process at most this many times (per process role, in total), after 50 ms, 100 ms,
    /// 200 ms, … (doubling, at most 1.6 s).
    #[arg(long, value_name = "N", default_value_t = 5)]
    pub max_restarts: u32,
}

/// `uavloc process <role>`: runs one pipeline process in this binary (what `uavloc launch` spawns).
#[derive(Args, Debug, Clone, PartialEq)]
pub struct ProcessArgs {
    #[command(subcommand)]
    pub role: Role,
}

/// The processes `uavloc` can be.
#[derive(Subcommand, Debug, Clone, PartialEq)]
pub enum Role {
    /// The world: truth and a noisy measurement per step, flies each command (lock-step or real time).
    #[command(after_help = emitter_sim::process::AFTER_HELP)]
    EmitterSim(emitter_sim::process::EmitterSimArgs),
    /// Chan's estimator: an estimate per measurement.
    #[command(after_help = estimator::process::AFTER_HELP)]
    Estimator(estimator::process::EstimatorArgs),
    /// The planner: a command per estimate.
    #[command(after_help = planner::process::AFTER_HELP)]
    Planner(planner::process::PlannerArgs),
    /// The monitor: live view, event log, run record, plots.
    #[command(after_help = monitor::process::AFTER_HELP)]
    Monitor(monitor::process::MonitorArgs),
    /// Lists the iceoryx2 nodes and services of a domain as JSON (optionally removing dead nodes first).
    Resources(ResourcesArgs),
}

/// Flags of `uavloc process resources`.
#[derive(Args, Debug, Clone, PartialEq)]
pub struct ResourcesArgs {
    /// The domain (default: $UAVLOC_DOMAIN, else "uavloc").
    #[arg(long, value_name = "NAME")]
    pub domain: Option<String>,
    /// Remove the stale resources of the domain's dead nodes before listing.
    #[arg(long)]
    pub remove_dead: bool,
}

/// Runs `uavloc process <role>`.
pub fn run_process(args: &ProcessArgs) -> ExitCode {
    match &args.role {
        Role::EmitterSim(a) => emitter_sim::process::main_with(a),
        Role::Estimator(a) => estimator::process::main_with(a),
        Role::Planner(a) => planner::process::main_with(a),
        Role::Monitor(a) => monitor::process::main_with(a),
        Role::Resources(a) => {
            protocol::transport::quiet_logs();
            let listed =
                Domain::resolve(a.domain.as_deref()).map_err(|e| CliError::Input(e.to_string())).and_then(|domain| {
                    if a.remove_dead {
                        resources::remove_dead_nodes(&domain).map_err(CliError::Failed)?;
                    }
                    resources::list(&domain).map_err(CliError::Failed)
                });
            match listed {
                Ok(r) => {
                    println!("{}", serde_json::to_string_pretty(&r).unwrap_or_default());
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("error: {e}");
                    e.exit_code()
                }
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------------------
// Signals
// ---------------------------------------------------------------------------------------------------------

/// The last SIGINT/SIGTERM the launcher received (0: none).
static SIGNAL: AtomicI32 = AtomicI32::new(0);

extern "C" fn on_signal(signal: libc::c_int) {
    SIGNAL.store(signal, Ordering::SeqCst);
}

/// Routes SIGINT and SIGTERM to [`SIGNAL`] (instead of killing the launcher before it stops its children).
fn catch_termination_signals() {
    for signal in [libc::SIGINT, libc::SIGTERM] {
        // SAFETY: `on_signal` only performs an atomic store, which is async-signal-safe; the sigaction struct
        // is fully initialised (zeroed, then handler and an empty mask set) before the call.
        unsafe {
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
            libc::sigemptyset(&mut action.sa_mask);
            libc::sigaction(signal, &action, std::ptr::null_mut());
        }
    }
}

fn signal_name(signal: i32) -> &'static str {
    if signal == libc::SIGINT { "SIGINT" } else { "SIGTERM" }
}

// ---------------------------------------------------------------------------------------------------------
// Children
// ---------------------------------------------------------------------------------------------------------

/// The four processes, in start order.
const START_ORDER: [&str; 4] = ["monitor", "planner", "estimator", "emitter-sim"];

/// How long a child may take to print `ready`.
const READY_TIMEOUT: Duration = Duration::from_secs(30);
/// How long the estimator and planner get to exit after SIGTERM before SIGKILL.
const STOP_GRACE: Duration = Duration::from_secs(5);
/// How often the launcher looks at its children and signals when nothing else happens.
const TICK: Duration = Duration::from_millis(50);
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
    Line(usize, String),
    Closed(usize),
}

struct Proc {
    role: &'static str,
    /// Its flags (a restart uses them again).
    flags: Vec<String>,
    /// It crashed and was restarted (a newer entry of the same role took its place).
    replaced: bool,
    child: Child,
    ready: bool,
    /// Its stdout reached end of file (every line it printed has been handled).
    closed: bool,
    exit: Option<std::process::ExitStatus>,
    summary: Option<serde_json::Value>,
    /// emitter-sim with `--linger`: it published the last step (and stays to serve replays).
    finished: bool,
}

impl Proc {
    /// It exited because a newer instance took over (`uavloc swap`): no restart.
    fn handed_over(&self) -> bool {
        self.exit.is_some_and(|s| s.success()) && self.summary.as_ref().is_some_and(|s| !s["handed_over_at"].is_null())
    }

    /// It exited although it should still run — all but emitter-sim and the monitor after a successful
    /// end, and one that handed over — and has not been restarted yet.
    fn needs_restart(&self) -> bool {
        let Some(status) = self.exit else { return false };
        if status.success() && !self.closed {
            return false; // judged once its last lines (its summary) are in
        }
        !(self.replaced || self.handed_over() || (matches!(self.role, "emitter-sim" | "monitor") && status.success()))
    }

    fn describe_exit(&self) -> String {
        match self.exit {
            Some(s) => match (s.code(), std::os::unix::process::ExitStatusExt::signal(&s)) {
                (Some(c), _) => format!("exit code {c}"),
                (None, Some(sig)) => format!("signal {sig}"),
                _ => "an unknown status".into(),
            },
            None => "still running".into(),
        }
    }
}

/// The running children and the lines they print on stdout.
struct Supervisor {
    procs: Vec<Proc>,
    tx: Sender<Event>,
    rx: Receiver<Event>,
    record: Option<String>,
    domain: Domain,
    /// The monitor's JSON-lines log, where restarts are written too.
    log: Option<PathBuf>,
    max_restarts: u32,
    restarts: u64,
    /// CPU use of the idle children before the run (see [`LaunchArgs::idle_probe_ms`]).
    idle_cpu: BTreeMap<String, f64>,
}

impl Supervisor {
    fn new(domain: Domain, log: Option<PathBuf>, max_restarts: u32) -> Self {
        let (tx, rx) = mpsc::channel();
        Self {
            procs: Vec::new(),
            tx,
            rx,
            record: None,
            domain,
            log,
            max_restarts,
            restarts: 0,
            idle_cpu: BTreeMap::new(),
        }
    }

    /// The current instance of `role`.
    fn index(&self, role: &str) -> usize {
        self.procs.iter().rposition(|p| p.role == role).expect("a started role")
    }

    /// Starts `uavloc process <role> <flags> --supervised` with stdout piped to a reader thread.
    fn spawn(&mut self, role: &'static str, flags: Vec<String>) -> Result<(), CliError> {
        let exe = std::env::current_exe().map_err(|e| CliError::Failed(format!("cannot find this executable: {e}")))?;
        let mut command = std::process::Command::new(exe);
        command
            .arg("process")
            .arg(role)
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
        let mut child = command.spawn().map_err(|e| CliError::Failed(format!("cannot start the {role}: {e}")))?;
        let stdout = child.stdout.take().expect("piped stdout");
        let index = self.procs.len();
        let tx = self.tx.clone();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if tx.send(Event::Line(index, line)).is_err() {
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
        });
        Ok(())
    }

    fn handle(&mut self, event: Event) {
        match event {
            Event::Line(i, line) => {
                let p = &mut self.procs[i];
                if line == "ready" {
                    p.ready = true;
                } else if line == "finished" {
                    p.finished = true;
                } else if let Some(json) = line.strip_prefix("summary ") {
                    p.summary = serde_json::from_str(json).ok();
                } else if let Some(json) = line.strip_prefix("record ") {
                    self.record = Some(json.to_string());
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
        match SIGNAL.load(Ordering::SeqCst) {
            0 => Ok(()),
            s => Err(CliError::Failed(format!("interrupted by {}; stopped every process", signal_name(s)))),
        }
    }

    /// Fails if a child has exited although it should still run (`expected` lists the roles allowed to
    /// have finished, with exit code 0).
    fn check_exits(&self, finished_ok: &[&str]) -> Result<(), CliError> {
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

    fn wait_ready(&mut self, role: &str) -> Result<(), CliError> {
        let i = self.index(role);
        let deadline = Instant::now() + READY_TIMEOUT;
        while !self.procs[i].ready {
            self.pump()?;
            self.check_exits(&[])?;
            if Instant::now() > deadline {
                return Err(CliError::Failed(format!("the {role} process did not get ready within {READY_TIMEOUT:?}")));
            }
        }
        Ok(())
    }

    /// Runs until emitter-sim and the monitor have finished, restarting the processes that crash; the
    /// monitor gets `monitor_grace` after emitter-sim's end (its `finished`, or its exit) to record the
    /// last step. A lingering emitter-sim (`--linger`) replays the run to a monitor that fell behind or was
    /// restarted while the run ended, and is stopped with the others afterwards.
    fn wait_for_the_end(&mut self, monitor_grace: Duration) -> Result<(), CliError> {
        let mut emitter_done_at = None;
        loop {
            self.pump()?;
            self.restart_crashed()?;
            let (emitter, monitor) = (self.index("emitter-sim"), self.index("monitor"));
            // Only a successful exit is the end: one that crashed while another process was being restarted
            // (after `restart_crashed` went past it) is restarted in the next round.
            let ended = |i: usize| self.procs[i].exit.is_some_and(|s| s.success());
            if ended(emitter) || self.procs[emitter].finished {
                let since = *emitter_done_at.get_or_insert_with(Instant::now);
                if ended(monitor) {
                    return Ok(());
                }
                if since.elapsed() > monitor_grace {
                    return Err(CliError::Failed(format!(
                        "the monitor did not record the last step within {monitor_grace:?} of the end of the run"
                    )));
                }
            }
        }
    }

    /// Restarts every current process that exited although it should still run — all but emitter-sim and
    /// the monitor after a successful end. A process that exits with code 2 (bad input) or 3 (the run cannot
    /// go on, e.g. two UAVs collided), or has crashed
    /// `max_restarts` times fails the launch.
    fn restart_crashed(&mut self) -> Result<(), CliError> {
        for i in 0..self.procs.len() {
            let p = &self.procs[i];
            let Some(status) = p.exit.filter(|_| p.needs_restart()) else { continue };
            let role = p.role;
            let attempt = self.procs.iter().filter(|q| q.role == role && q.replaced).count() as u32 + 1;
            // Bad input (2) and a run that cannot go on (3) would fail again: no restart.
            let deterministic =
                matches!(status.code(), Some(c) if c == 2 || c == i32::from(protocol::EXIT_UNRECOVERABLE));
            if deterministic || attempt > self.max_restarts {
                let why = if deterministic { String::new() } else { format!(" after {} restart(s)", attempt - 1) };
                return Err(CliError::Failed(format!(
                    "the {role} process stopped unexpectedly ({}){why}",
                    p.describe_exit()
                )));
            }
            self.restart(i, attempt)?;
        }
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
        eprintln!(
            "warning: the {role} process (pid {pid}) stopped unexpectedly ({exit}); restarting it in {backoff:?} \
             (attempt {attempt} of {})",
            self.max_restarts
        );
        self.write_log(serde_json::json!({
            "event": "restart", "t_ns": protocol::now_ns(), "role": role, "pid": pid, "exit": exit,
            "attempt": attempt, "backoff_ms": backoff.as_millis() as u64,
        }));
        self.procs[i].replaced = true;
        self.restarts += 1;
        resources::remove_dead_nodes(&self.domain).map_err(CliError::Failed)?;
        let until = Instant::now() + backoff;
        while Instant::now() < until {
            self.pump()?;
        }
        let mut flags = self.procs[i].flags.clone();
        if role == "monitor" && !flags.iter().any(|f| f == "--resume") {
            flags.push("--resume".into());
        }
        self.spawn(role, flags)?;
        let new = self.procs.len() - 1;
        let deadline = Instant::now() + READY_TIMEOUT;
        while !self.procs[new].ready && self.procs[new].exit.is_none() {
            self.pump()?;
            if self.procs.iter().any(Proc::needs_restart) {
                break;
            }
            if Instant::now() > deadline {
                return Err(CliError::Failed(format!(
                    "the restarted {role} did not get ready within {READY_TIMEOUT:?}"
                )));
            }
        }
        Ok(())
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
    fn stop_all(&mut self) {
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
                eprintln!("warning: the {} process ignored SIGTERM; killing it", p.role);
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

// ---------------------------------------------------------------------------------------------------------
// The launch
// ---------------------------------------------------------------------------------------------------------

/// One child's outcome (every instance, also the crashed ones).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ChildReport {
    pub role: String,
    pub pid: u32,
    pub exit: String,
    pub rejected: u64,
    /// Whether it crashed and was replaced by a restarted instance.
    pub restarted: bool,
    /// Its `summary` line (none if it was killed).
    pub summary: Option<serde_json::Value>,
}

/// What `uavloc launch` prints: the monitor's run record (the JSON shape of `uavloc simulate --json`)
/// plus `restarts` and `rejected`.
#[derive(Debug, Clone, Serialize)]
pub struct LaunchReport {
    #[serde(flatten)]
    pub run: RunRecord,
    /// Children restarted after a crash.
    pub restarts: u64,
    /// Invalid messages counted and ignored by all four processes.
    pub rejected: u64,
    /// The same count per process role.
    pub rejected_by: BTreeMap<String, u64>,
    /// Realtime mode: steps whose command had not reached emitter-sim when the next step was due (the UAVs
    /// flew straight on); 0 in lock-step mode.
    pub missed_commands: u64,
    /// Steps whose command was the planner's hold (no fresh estimate within --estimate-deadline-ms).
    pub stale_steps: u64,
    /// Every process instance the launch started, in start order.
    #[serde(rename = "processes")]
    pub children: Vec<ChildReport>,
    #[serde(skip)]
    pub domain: String,
    #[serde(skip)]
    pub mode: String,
    #[serde(skip)]
    pub wall_s: f64,
    #[serde(skip)]
    pub latency: Option<serde_json::Value>,
    #[serde(skip)]
    pub leftovers: DomainResources,
    /// CPU use of the waiting monitor, planner and estimator before the run, % of one core (only with
    /// an idle probe, see [`LaunchArgs::idle_probe_ms`]).
    #[serde(skip)]
    pub idle_cpu: BTreeMap<String, f64>,
}

/// CPU use (% of one core) of each running child over `window`, from /proc (the children are idle: they
/// wait for messages that do not come yet).
fn probe_idle_cpu(sup: &Supervisor, window: Duration) -> BTreeMap<String, f64> {
    use crate::bench::sys::process_cpu_seconds;
    let before: Vec<(String, u32, Option<f64>)> =
        sup.procs.iter().map(|p| (p.role.to_string(), p.child.id(), process_cpu_seconds(p.child.id()).ok())).collect();
    let start = Instant::now();
    std::thread::sleep(window);
    let elapsed = start.elapsed().as_secs_f64();
    before
        .into_iter()
        .filter_map(|(role, pid, t0)| Some((role, 100.0 * (process_cpu_seconds(pid).ok()? - t0?) / elapsed)))
        .collect()
}

/// The domain of a launch: the flag, else `$UAVLOC_DOMAIN`, else `uavloc-<pid>`.
fn launch_domain(flag: Option<&str>) -> Result<Domain, CliError> {
    let env = std::env::var(DOMAIN_ENV).ok().filter(|v| !v.is_empty());
    let name = flag.map(str::to_string).or(env).unwrap_or_else(|| format!("uavloc-{}", std::process::id()));
    Domain::new(&name).map_err(|e| CliError::Input(format!("--domain: {e}")))
}

/// Runs `uavloc launch`.
pub fn run(args: &LaunchArgs) -> Result<LaunchReport, CliError> {
    let start = Instant::now();
    let mut sc = scenario_from(args.scenario.as_ref(), args.steps, args.seed)?;
    if let Some(kind) = args.estimator {
        sc.estimator = kind;
    }
    if sc.target == TargetMode::Controlled {
        return Err(CliError::Input(
            "scenario key `target`: \"controlled\" is not supported by the process pipeline (the planner never \
             sees the true emitter); use `uavloc simulate` for controlled runs"
                .into(),
        ));
    }
    if !(args.command_timeout_s > 0.0 && args.command_timeout_s.is_finite()) {
        return Err(CliError::Input(format!("--command-timeout-s must be > 0, got {}", args.command_timeout_s)));
    }
    emitter_sim::process::check_time_scale(args.time_scale).map_err(CliError::Input)?;
    if args.mode == Mode::Realtime {
        if args.step_delay_ms > 0 {
            return Err(CliError::Input(
                "--step-delay-ms applies to lockstep mode only; in realtime mode --time-scale sets the pace".into(),
            ));
        }
        emitter_sim::process::step_interval(sc.dt, args.time_scale, sc.steps).map_err(CliError::Input)?;
    }
    let domain = launch_domain(args.domain.as_deref())?;
    protocol::transport::quiet_logs();
    resources::remove_dead_nodes(&domain).map_err(CliError::Failed)?;
    let existing = resources::list(&domain).map_err(CliError::Failed)?;
    if let Some(node) = existing.alive_nodes().next() {
        return Err(CliError::Input(format!(
            "domain {domain} is in use (process node {node} is running); choose another --domain"
        )));
    }

    catch_termination_signals();
    // Checkpoints (and the monitor's log when --log is not given) live in a private directory of this
    // launch, removed at the end: a restarted child resumes from what its predecessor wrote there.
    let state = StateDir::create(&domain)?;
    let log = args.log.clone().unwrap_or_else(|| state.path("monitor.jsonl"));
    let mut sup = Supervisor::new(domain.clone(), Some(log.clone()), args.max_restarts);
    let result = start_and_run(&mut sup, args, &sc, &domain, &state, &log);
    sup.stop_all();
    // Processes that are not our children (swapped in by `uavloc swap`) stop on the domain's shutdown
    // message.
    if resources::list(&domain).is_ok_and(|r| r.alive_nodes().next().is_some()) {
        match send_shutdown(&domain, args.link.transport) {
            Ok(control) => {
                wait_until_no_process_left(&domain);
                drop(control);
            }
            Err(e) => eprintln!("warning: cannot send the shutdown message to domain {domain}: {e}"),
        }
    }
    // A child that crashed or had to be killed leaves its iceoryx2 node behind: remove it — also when the
    // launch failed or was interrupted — then check.
    let cleaned = resources::remove_dead_nodes(&domain).map_err(CliError::Failed);
    if args.link.transport == protocol::TransportKind::Uds {
        protocol::transport::uds::cleanup_stale();
    }
    result?;
    cleaned?;
    let leftovers = resources::list(&domain).map_err(CliError::Failed)?;

    let record = sup.record.as_deref().ok_or_else(|| CliError::Failed("the monitor sent no run record".into()))?;
    let mut run: RunRecord =
        serde_json::from_str(record).map_err(|e| CliError::Failed(format!("the monitor's run record: {e}")))?;
    // The scenario as loaded here, like `simulate` (the record's copy went through TOML-style degree
    // conversions on the way).
    run.scenario = sc;
    // The monitor names the run after the commands it recorded; if none was flown (every one missed, in
    // realtime mode), the names are the launch's.
    if run.objective == "-" && run.solver == "-" {
        run.objective = args.objective.name().to_string();
        run.solver = args.solver.name().to_string();
    }
    let children: Vec<ChildReport> = sup
        .procs
        .iter()
        .map(|p| ChildReport {
            role: p.role.to_string(),
            pid: p.child.id(),
            exit: p.describe_exit(),
            rejected: p.summary.as_ref().and_then(|s| s["rejected"].as_u64()).unwrap_or(0),
            restarted: p.replaced,
            summary: p.summary.clone(),
        })
        .collect();
    let latency = sup.procs[sup.index("monitor")].summary.as_ref().map(|s| s["latency"].clone());
    let mut rejected_by = BTreeMap::new();
    for c in &children {
        *rejected_by.entry(c.role.clone()).or_insert(0) += c.rejected;
    }
    let missed_commands = children
        .iter()
        .filter(|c| c.role == "emitter-sim")
        .filter_map(|c| c.summary.as_ref().and_then(|s| s["missed_commands"].as_u64()))
        .sum();
    let stale_steps = run
        .steps
        .iter()
        .filter(|s| s.active_constraints.iter().any(|a| a == monitor::assemble::ESTIMATE_STALE))
        .count() as u64;
    Ok(LaunchReport {
        run,
        restarts: sup.restarts,
        rejected: children.iter().map(|c| c.rejected).sum(),
        rejected_by,
        missed_commands,
        stale_steps,
        domain: domain.to_string(),
        mode: match args.mode {
            Mode::Lockstep => "lockstep".to_string(),
            Mode::Realtime => format!("realtime ×{}", args.time_scale),
        },
        wall_s: start.elapsed().as_secs_f64(),
        children,
        latency,
        leftovers,
        idle_cpu: std::mem::take(&mut sup.idle_cpu),
    })
}

/// The launcher's own node on the control topic, kept until the others have stopped.
type ControlNode = (protocol::ControlChannel, protocol::Link);

/// Publishes [`ControlKind::Shutdown`](protocol::ControlKind::Shutdown) on the domain's control topic.
fn send_shutdown(domain: &Domain, kind: protocol::TransportKind) -> Result<ControlNode, String> {
    let node = protocol::Link::open_without_signal_handling(kind, &services::node_name(domain, "launcher"))
        .map_err(|e| e.to_string())?;
    let started_ns = protocol::now_ns();
    let control = protocol::ControlChannel::open(
        &node,
        domain,
        "launcher",
        protocol::control::instance_id_at(started_ns),
        started_ns,
    )
    .map_err(|e| e.to_string())?;
    control.send(protocol::ControlKind::Shutdown, 0, "").map_err(|e| e.to_string())?;
    Ok((control, node))
}

/// Waits (at most [`STOP_GRACE`]) until no process of the domain is alive (swapped-in processes that got
/// the shutdown message).
fn wait_until_no_process_left(domain: &Domain) {
    let deadline = Instant::now() + STOP_GRACE;
    while Instant::now() < deadline {
        match resources::list(domain) {
            Ok(r) if r.alive_nodes().any(|n| !n.ends_with("/launcher")) => std::thread::sleep(TICK / 5),
            _ => return,
        }
    }
    eprintln!("warning: processes of domain {domain} are still running after the shutdown message");
}

/// The private directory of one launch (checkpoints, and the monitor's log when `--log` is not given):
/// `$TMPDIR/uavloc-<uid>/launch-<pid>`, mode 0700 (as its parent), removed when dropped.
struct StateDir(PathBuf);

impl StateDir {
    fn create(domain: &Domain) -> Result<Self, CliError> {
        use std::os::unix::fs::{DirBuilderExt as _, MetadataExt as _};
        // SAFETY: getuid has no preconditions and cannot fail.
        let uid = unsafe { libc::getuid() };
        let parent = std::env::temp_dir().join(format!("uavloc-{uid}"));
        let failed = |what: &PathBuf, e: std::io::Error| {
            CliError::Failed(format!("the launch's state directory {}: {e}", what.display()))
        };
        match std::fs::DirBuilder::new().mode(0o700).create(&parent) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
            Err(e) => return Err(failed(&parent, e)),
        }
        let meta = std::fs::symlink_metadata(&parent).map_err(|e| failed(&parent, e))?;
        if !meta.is_dir() || meta.uid() != uid || meta.mode() & 0o077 != 0 {
            return Err(CliError::Failed(format!(
                "the launch's state directory {} is not a directory of this user with mode 0700; remove it",
                parent.display()
            )));
        }
        let dir = parent.join(format!("launch-{}-{domain}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir); // a leftover of an earlier launch with the same pid
        std::fs::DirBuilder::new().mode(0o700).create(&dir).map_err(|e| failed(&dir, e))?;
        Ok(StateDir(dir))
    }

    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for StateDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Starts the children in order, each after the previous one is ready, and waits for the end of the run.
fn start_and_run(
    sup: &mut Supervisor,
    args: &LaunchArgs,
    sc: &Scenario,
    domain: &Domain,
    state: &StateDir,
    log: &std::path::Path,
) -> Result<(), CliError> {
    let common = ["--domain".to_string(), domain.to_string()];
    let mut run_flags = Vec::new();
    if let Some(p) = &args.scenario {
        run_flags.extend(["--scenario".to_string(), p.display().to_string()]);
    }
    if let Some(n) = args.steps {
        run_flags.extend(["--steps".to_string(), n.to_string()]);
    }
    if let Some(s) = args.seed {
        run_flags.extend(["--seed".to_string(), s.to_string()]);
    }
    let link = args.link.to_flags();
    for role in START_ORDER {
        let mut flags = common.to_vec();
        flags.extend(link.iter().cloned());
        if role != "monitor" {
            flags.extend(["--checkpoint".to_string(), state.path(&format!("{role}.ckpt")).display().to_string()]);
        }
        if role == "emitter-sim" {
            flags.push("--linger".into());
        }
        if role == "emitter-sim" && args.idle_probe_ms > 0 {
            sup.idle_cpu = probe_idle_cpu(sup, Duration::from_millis(args.idle_probe_ms));
        }
        match role {
            "monitor" => {
                flags.extend(run_flags.iter().cloned());
                flags.extend(["--log".to_string(), log.display().to_string()]);
                if let Some(p) = &args.out {
                    flags.extend(["--out".to_string(), p.display().to_string()]);
                }
                if let Some(p) = &args.stamps {
                    flags.extend(["--stamps".to_string(), p.display().to_string()]);
                }
            }
            "planner" => {
                flags.extend(run_flags.iter().cloned());
                flags.extend([
                    "--objective".into(),
                    args.objective.name().into(),
                    "--solver".into(),
                    args.solver.name().into(),
                ]);
                if args.estimate_deadline_ms > 0 {
                    flags.extend(["--estimate-deadline-ms".to_string(), args.estimate_deadline_ms.to_string()]);
                }
                if args.plan_delay_ms > 0 {
                    flags.extend(["--plan-delay-ms".to_string(), args.plan_delay_ms.to_string()]);
                    if !args.plan_delay_steps.is_empty() {
                        let steps: Vec<String> = args.plan_delay_steps.iter().map(u64::to_string).collect();
                        flags.extend(["--plan-delay-steps".to_string(), steps.join(",")]);
                    }
                }
            }
            "estimator" => {
                // `{:?}` keeps every digit (and the value parses back exactly).
                flags.extend([
                    "--estimator".to_string(),
                    sc.estimator.name().to_string(),
                    "--emitter-model".to_string(),
                    sc.emitter_model.name().to_string(),
                    "--process-noise-accel".to_string(),
                    format!("{:?}", sc.process_noise_accel),
                    "--velocity-prior-sigma".to_string(),
                    format!("{:?}", sc.velocity_prior_sigma),
                    "--interval-s".to_string(),
                    format!("{:?}", sc.dt),
                ]);
            }
            _ => {
                flags.extend(run_flags.iter().cloned());
                flags.extend([
                    "--step-delay-ms".to_string(),
                    args.step_delay_ms.to_string(),
                    "--retry-interval-ms".to_string(),
                    args.retry_interval_ms.to_string(),
                    "--command-timeout-s".to_string(),
                    args.command_timeout_s.to_string(),
                    "--mode".to_string(),
                    args.mode.name().to_string(),
                    // `{:?}` keeps every digit (and the value parses back exactly).
                    "--time-scale".to_string(),
                    format!("{:?}", args.time_scale),
                    // The estimator and the monitor.
                    "--min-subscribers".to_string(),
                    "2".to_string(),
                ]);
            }
        }
        if args.headless || role != "monitor" {
            flags.push("--quiet".into());
        }
        sup.spawn(role, flags)?;
        sup.wait_ready(role)?;
    }
    sup.wait_for_the_end(Duration::from_secs_f64(args.command_timeout_s))
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or("-".to_string(), |x| format!("{x:.digits$}"))
}

impl Report for LaunchReport {
    fn table(&self) -> Table {
        let r = &self.run;
        let last = r.steps.last();
        let p50 = |key: &str| {
            self.latency
                .as_ref()
                .and_then(|l| l[key]["p50_us"].as_f64())
                .map_or("-".to_string(), |v| format!("{v:.0} µs"))
        };
        let mut t = Table::new()
            .row("domain", self.domain.clone())
            .row("objective / solver", format!("{} / {}", r.objective, r.solver))
            .row("mode", self.mode.clone())
            .row("seed", r.seed.to_string())
            .row("steps recorded", format!("{} (0..{})", r.steps.len(), r.steps.len().saturating_sub(1)))
            .row("emitter (truth)", format!("({:.1}, {:.1}) m", r.emitter[0], r.emitter[1]))
            .row("final CRLB at truth", format!("{} m", opt(last.map(|s| s.crlb_true_m), 2)))
            .row("final RMSE", format!("{} m", opt(last.and_then(|s| s.rmse_m), 2)))
            .row(
                "final |ẑ − z|",
                format!(
                    "{} m",
                    opt(last.map(|s| (s.estimate[0] - r.emitter[0]).hypot(s.estimate[1] - r.emitter[1])), 1)
                ),
            )
            .row(
                "median hops",
                format!(
                    "command {}, measurement {}, estimate {}",
                    p50("command_hop"),
                    p50("measurement_hop"),
                    p50("estimate_hop")
                ),
            )
            .row("median cycle", p50("cycle"))
            .row("rejected messages", self.rejected.to_string())
            .row("missed commands", self.missed_commands.to_string())
            .row("stale estimates (held course)", self.stale_steps.to_string())
            .row("restarts", self.restarts.to_string())
            .row("wall time", format!("{:.2} s", self.wall_s));
        for c in &self.children {
            let restarted = if c.restarted { " (crashed, restarted)" } else { "" };
            t = t
                .row(format!("  {}", c.role), format!("pid {}, {}, rejected {}{restarted}", c.pid, c.exit, c.rejected));
        }
        t
    }

    fn diagnostics(&self) -> Vec<Diagnostic> {
        let mut out = Vec::new();
        if !self.leftovers.is_empty() {
            out.push(Diagnostic::Warning(format!(
                "iceoryx2 resources of domain {} are left: nodes {:?}, services {:?}",
                self.domain,
                self.leftovers.nodes.iter().map(|n| format!("{} ({})", n.name, n.state)).collect::<Vec<_>>(),
                self.leftovers.services
            )));
        }
        if self.stale_steps > 0 {
            out.push(Diagnostic::Warning(format!(
                "{} step(s) had no fresh estimate within the planner's deadline (it held course): see \
                 active_constraints \"estimate_stale\"",
                self.stale_steps
            )));
        }
        if self.missed_commands > 0 {
            out.push(Diagnostic::Warning(format!(
                "{} step(s) missed their command (it reached emitter-sim after the next step was due; the UAVs \
                 flew straight on): see active_constraints \"command_missed\"",
                self.missed_commands
            )));
        }
        let n = self.run.steps.iter().filter(|s| s.estimate_status != "ok").count();
        if n > 0 {
            out.push(Diagnostic::Warning(format!(
                "{n} step(s) had an ambiguous or failed estimate (see estimate_status)"
            )));
        }
        out
    }
}
