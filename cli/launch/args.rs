//! The flags of `uavloc launch` and its help text.

use std::path::PathBuf;

use clap::Args;
use emitter_sim::args::Mode;

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
                      the hold of a step without a plan (one step of their backup circles, certified
                      for the spacing; straight on with safety = \"waypoints\"), the step is recorded with objective_value null and
                      active_constraints [\"command_missed\"], and \"missed_commands\" counts it. With
                      every command in time the run still equals simulate.

An external front end (--source external): the launch starts the estimator, the planner and the monitor
only; a front end of your own (C, C++, Python, … through iceoryx2; docs/wire-format.md, and
examples/python/frontend.py) publishes each step's Measurement on <domain>/measurement and reads the
Command on <domain>/command. There is no truth: the record's truth-based fields (truth, crlb_true_m,
rmse_m, estimate_error_m, nees, pcrlb_m) are absent or null, never zero; crlb_at_estimate_m and
pcrlb_at_estimate_m (the CRLB and the posterior CRLB at the estimates) are there.
The run ends when the monitor has the last step (--steps N: steps 0..N), or on Ctrl-C. A front end that
leaves before the last step (it ended, or died) ends the launch 5 s later unless one comes back: exit code
1, the monitor's error names the first step not recorded, the steps recorded are in the log (and, with
--json, printed with \"failed\").

Staleness (--estimate-deadline-ms D, off by default): when a step's estimate has not reached the planner D
ms after the step's measurement, the planner holds: every UAV loiters on its backup circle, a right turn
at the radius the certificate keeps clear (with safety = \"waypoints\" they hold course); the step is recorded with active_constraints [\"estimate_stale\"] and counted in
\"stale_steps\". Meant for realtime runs; a lock-step run with a deadline depends on timing. The planner
holds the same way, with or without a deadline, while there is no estimate to plan from (before a first
fix): those steps are counted in \"stale_steps\" too, and apart in \"held_before_first_fix\".

On a terminal (stdout and stderr) the launch shows a live view: the map with the UAV tracks, the true
emitter (T), the estimate (E) with its 95 % ellipse and the L_min circle; beside it the RMSE and the CRLB
at the truth over the steps, the processes (pid, restarts, rejected messages), the planner in charge and
the last hop latencies; `q` stops the run (as Ctrl-C: the steps done are kept, exit code 1). Not on a
terminal, or with --headless or --json, the monitor shows one line per step on stderr instead (CRLB and
RMSE at the truth, estimate error, hop latencies, active planner, rejected messages), or nothing with
--headless. At the end the run is printed as a table, or with
--json as the JSON of `uavloc simulate --json` plus \"restarts\", \"rejected\", \"rejected_by\",
\"missed_commands\" and \"processes\" — and, for a run that ended early, \"interrupted\": true (Ctrl-C) or
\"failed\": \"<the error>\" (the process that ended the run and why, in its words: a step 0 without a
fix, a front end of another formation, a front end that left for good; exit code 1, the steps done are in
the record).

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
  uavloc launch --source external --domain lab1 --steps 20    (then: python3 examples/python/frontend.py --domain lab1 --steps 20)
  uavloc launch --scenario scenarios/nominal.toml --solver ga --domain lab1 --log run.jsonl --out runs/lab1
  uavloc launch --scenario scenarios/geo.toml --mode realtime --time-scale 20 --autopilot udpin:127.0.0.1:14550 \\
      --autopilot udpin:127.0.0.1:14551 --autopilot udpin:127.0.0.1:14552   (aircraft over MAVLink, docs/flying.md)

Each process also runs on its own, e.g. in four terminals (or systemd units) with one --domain:
  monitor --domain lab1 --log run.jsonl;  planner --domain lab1;  estimator --domain lab1
  emitter-sim --domain lab1 --min-subscribers 2";

/// Flags of `uavloc launch`.
#[derive(Args, Debug, Clone, PartialEq)]
pub struct LaunchArgs {
    /// Scenario, objective, solver, steps, seed, estimator.
    #[command(flatten)]
    pub run: crate::args::RunChoice,
    /// Pipeline domain, the prefix of every iceoryx2 service name (default: $UAVLOC_DOMAIN, else
    /// `uavloc-<pid>`, unique per launch; with --source external `uavloc`, the default of every process
    /// and of examples/python/frontend.py).
    #[arg(long, value_name = "NAME")]
    pub domain: Option<String>,
    /// Where the measurements come from: simulator (emitter-sim, the simulated world) or external (a front
    /// end outside uavloc publishes the measurements and reads the commands, see docs/wire-format.md and
    /// examples/python/; no truth, so the columns that need one are absent).
    #[arg(long, value_name = "SOURCE", default_value = "simulator")]
    pub source: runtime::Source,
    /// No live view and no status lines: the monitor and the other processes print only errors.
    #[arg(long)]
    pub headless: bool,
    /// Directory for the monitor's CSVs, run.json and plots (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Record every message of the run (measurement, estimate, command, truth, control) to FILE as MCAP:
    /// JSON channels with JSON schemas, so Foxglove and the Python `mcap` package open it; `uavloc replay
    /// FILE` runs the estimator and the planner on it again. Kept whole across monitor restarts.
    #[arg(long, value_name = "FILE.mcap")]
    pub record: Option<PathBuf>,
    /// The monitor's JSON-lines event log (default: a file in the launch's private state directory,
    /// removed at the end). The step records are kept there during the run, not in memory.
    #[arg(long, value_name = "FILE")]
    pub log: Option<PathBuf>,
    /// emitter-sim gives up when a step's command has not arrived after this many seconds; the monitor
    /// has as long after the run's end to record the last step.
    #[arg(long, value_name = "S", default_value_t = 10.0)]
    pub command_timeout_s: f64,
    /// Transport and waiting of every process.
    #[command(flatten)]
    pub link: runtime::LinkArgs,
    /// Write the raw stamps of every step as CSV (the monitor's --stamps; what `uavloc bench` reads).
    #[arg(long, value_name = "FILE")]
    pub stamps: Option<PathBuf>,
    /// Show the live view (set by `uavloc launch` on a terminal without --headless or --json).
    #[arg(skip)]
    pub live: bool,
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
    /// (--time-scale 100 runs the paper's 10 s step in 0.1 s; default 1, true real time). Refused
    /// without --mode realtime.
    #[arg(long, value_name = "X", allow_negative_numbers = true)]
    pub time_scale: Option<f64>,
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
    /// Fly real (or simulated) aircraft: one MAVLink endpoint per UAV, UAV0 first (udpin:HOST:PORT,
    /// udpout:HOST:PORT, tcpout:HOST:PORT, serial:DEVICE:BAUD). The launch starts the MAVLink bridge,
    /// which streams each command to the autopilots as guided targets, and emitter-sim measures from
    /// where they report the UAVs (`--uavs autopilots`). Needs --mode realtime and a scenario with an
    /// `[origin]` (docs/flying.md).
    #[arg(long = "autopilot", value_name = "ENDPOINT")]
    pub autopilots: Vec<String>,
}

impl LaunchArgs {
    /// The flags' defaults (for tests: `uavloc launch` with no flag).
    #[cfg(test)]
    pub(crate) fn try_parse_from_defaults() -> Self {
        use clap::FromArgMatches as _;
        let cmd = <Self as Args>::augment_args(clap::Command::new("launch"));
        Self::from_arg_matches(&cmd.get_matches_from(["launch"])).expect("defaults")
    }
}
