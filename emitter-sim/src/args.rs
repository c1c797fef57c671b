//! emitter-sim's flags (`emitter-sim [FLAGS]`, `uavloc process emitter-sim [FLAGS]`), their checks and the
//! pacing they give ([`crate::schedule::Pacing`]).

use std::path::PathBuf;
use std::time::{Duration, Instant};

use clap::{Args, ValueEnum};
use runtime::recovery;

use crate::schedule::Pacing;

/// What `emitter-sim --help` shows after the flags.
pub const AFTER_HELP: &str = "\
emitter-sim publishes <domain>/truth and <domain>/measurement and subscribes to <domain>/command. Start
estimator, planner (and monitor) first, with the same --domain, --scenario, --steps and --seed;
emitter-sim waits until they are connected, runs steps 0..N (the last one is measured, not planned) and
exits 0.

Modes:
  --mode lockstep   the next step as soon as the command for the current one arrives (default): for
                    benchmarks and tests, and the exact reproduction of `uavloc simulate`.
  --mode realtime   step k is published at t0 + k*dt/X with X = --time-scale (dt = the scenario's
                    interval, 10 s in the paper; --time-scale 100 runs it in 0.1 s). A command that has
                    not arrived when the next step is due is missed: the UAVs fly the hold of a
                    step without a plan (one step of their backup circles; straight on with
                    safety = \"waypoints\"), the step is counted in missed_commands and logged, a
                    later command for it is ignored (late_commands). With every command in time the run equals lock-step.

Examples:
  emitter-sim --domain lab1
  emitter-sim --domain lab1 --scenario scenarios/nominal.toml --steps 6 --seed 3 --min-subscribers 2
  emitter-sim --domain lab1 --mode realtime --time-scale 100";

/// How emitter-sim paces the run (`--mode`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, ValueEnum)]
pub enum Mode {
    /// The next step as soon as the command for the current one arrives (benchmarks, tests, exact
    /// reproduction of `uavloc simulate`).
    #[default]
    Lockstep,
    /// Step k at t0 + k·dt/X (X = --time-scale); a command that is not there when the next step is due is
    /// missed (the UAVs keep their headings).
    Realtime,
}

impl Mode {
    /// `"lockstep"` or `"realtime"`.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Lockstep => "lockstep",
            Mode::Realtime => "realtime",
        }
    }
}

impl std::fmt::Display for Mode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Where the UAVs are (`--uavs`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, ValueEnum)]
pub enum UavSource {
    /// emitter-sim flies them along the planner's arcs (the model of `uavloc simulate`).
    #[default]
    World,
    /// Real (or simulated) aircraft fly the commands through the MAVLink bridge: each step measures
    /// from the positions its swarm state reports (`<domain>/swarm`). Needs --mode realtime.
    Autopilots,
}

impl std::fmt::Display for UavSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            UavSource::World => "world",
            UavSource::Autopilots => "autopilots",
        })
    }
}

/// Checks `--time-scale` against `--mode`: given only with `realtime`, and then a valid scale.
/// The longest `--step-delay-ms`: a minute per step (a typo of hours per step would otherwise run as asked).
pub const MAX_STEP_DELAY_MS: u64 = 60_000;

fn check_time_scale_flag(mode: Mode, time_scale: Option<f64>) -> Result<(), String> {
    match (mode, time_scale) {
        (Mode::Lockstep, Some(_)) => {
            Err("--time-scale applies to --mode realtime only; a lock-step run goes as fast as \
                                          the commands come (--step-delay-ms slows it down)"
                .into())
        }
        (_, Some(x)) => check_time_scale(x),
        (_, None) => Ok(()),
    }
}

/// Checks a `--time-scale` value: finite and > 0.
fn check_time_scale(x: f64) -> Result<(), String> {
    if x.is_finite() && x > 0.0 {
        Ok(())
    } else {
        Err(format!("--time-scale must be a finite number > 0 (simulated seconds per real second, e.g. 100), got {x}"))
    }
}

/// The real time between two steps in real-time mode, `dt / time_scale`; an error (for `--time-scale`)
/// if that, or the whole run of `steps` steps, is not a valid duration (a time scale so small that the run
/// would last for ages).
fn step_interval(dt: f64, time_scale: f64, steps: usize) -> Result<Duration, String> {
    let seconds = dt / time_scale;
    Duration::try_from_secs_f64(seconds * steps as f64)
        .ok()
        .filter(|total| Instant::now().checked_add(*total).is_some())
        .and_then(|_| Duration::try_from_secs_f64(seconds).ok())
        .ok_or_else(|| {
            format!(
                "--time-scale {time_scale:e}: a step of {dt} s would last {seconds:e} s in real time; choose a larger \
                 time scale"
            )
        })
}

/// Flags of the emitter-sim process (`emitter-sim [FLAGS]` or `uavloc process emitter-sim [FLAGS]`).
/// Also `Serialize`: [`runtime::flags::to_flags`] writes the command line of these flags.
#[derive(Args, serde::Serialize, Debug, Clone, PartialEq)]
pub struct EmitterSimArgs {
    /// The node (domain, link, quiet, supervised) and the run (scenario, steps, seed).
    #[command(flatten)]
    #[serde(flatten)]
    pub process: runtime::ProcessArgs,
    /// Give up (exit 1) when the command for a step has not arrived after this many seconds.
    #[arg(long, value_name = "S", default_value_t = 10.0)]
    #[serde(serialize_with = "runtime::flags::finite")]
    pub command_timeout_s: f64,
    /// Publish the step in flight again when its command has not arrived this many milliseconds after
    /// it was published (a process died or lost it).
    #[arg(long, value_name = "MS", default_value_t = 1000)]
    pub retry_interval_ms: u64,
    /// Give up (exit 1) when the pipeline is not connected after this many seconds.
    #[arg(long, value_name = "S", default_value_t = 60.0)]
    #[serde(serialize_with = "runtime::flags::finite")]
    pub connect_timeout_s: f64,
    /// Subscribers the measurement topic needs before step 0 (estimator, plus 1 for a monitor; with 2 or
    /// more a monitor is taken to be in the pipeline, see --monitor-window).
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub min_subscribers: usize,
    /// Wait this many milliseconds before each step after step 0 (slows a lock-step run down for a demo or
    /// a test; the results do not change). 0: lock-step at full speed. At most 60000 (a minute per step).
    /// Lock-step mode only.
    #[arg(long, value_name = "MS", default_value_t = 0)]
    pub step_delay_ms: u64,
    /// Pacing: lockstep (the next step as soon as the command arrives; benchmarks, tests, exact
    /// reproduction of `uavloc simulate`) or realtime (step k at t0 + k·dt/X; a late command is missed and
    /// the UAVs keep their headings).
    #[arg(long, value_enum, value_name = "MODE", default_value_t = Mode::Lockstep)]
    #[serde(serialize_with = "runtime::flags::display")]
    pub mode: Mode,
    /// Real-time mode: simulated seconds per real second, > 0. A step lasts dt/X real seconds (the paper's
    /// 10 s interval takes 0.1 s at --time-scale 100; default 1). Refused in lock-step mode.
    #[arg(long, value_name = "X", allow_negative_numbers = true)]
    #[serde(serialize_with = "runtime::flags::finite_opt")]
    pub time_scale: Option<f64>,
    /// Checkpoint file: a world snapshot is written there every 256 steps, and a start that finds it (a
    /// restart in the same run) flies on from the oldest snapshot kept instead of from step 0. Remove it
    /// before a new run. (`uavloc launch` gives each process one in a fresh directory per launch.)
    #[arg(long, value_name = "FILE")]
    pub checkpoint: Option<PathBuf>,
    /// After the last step, stay: replay the run to a process that asks (a monitor that fell behind or
    /// was restarted while the run ended) until SIGINT/SIGTERM or a shutdown on the control topic, which
    /// end it normally (exit code 0). `uavloc launch` passes it and stops emitter-sim once the monitor has
    /// the whole run.
    #[arg(long)]
    pub linger: bool,
    /// Lock-step mode: do not publish step k while the monitor lacks step k − N or an older one (its
    /// progress comes on the control topic); when it makes no progress for --retry-interval-ms, replay to
    /// it from the first step it lacks; give up (exit 1) after
    /// --command-timeout-s without progress. A monitor then never loses a message from its full subscriber
    /// buffers (64 per topic), and one restarted again and again stays within reach of a restarted
    /// emitter-sim's replays. At most 64. 0: never wait for the monitor. Before the monitor's first
    /// progress report it is taken to lack the first step when --min-subscribers is 2 or more (a monitor
    /// is in the pipeline), else it has no effect until a monitor reports. No effect in real-time mode.
    #[arg(long, value_name = "N", default_value_t = recovery::MONITOR_WINDOW)]
    pub monitor_window: u64,
    /// Where the UAVs are: world (emitter-sim flies the commanded arcs) or autopilots (the MAVLink
    /// bridge's swarm state: each step is measured from where the autopilots report the UAVs; needs
    /// --mode realtime).
    #[arg(long, value_enum, value_name = "SOURCE", default_value_t = UavSource::World)]
    #[serde(serialize_with = "runtime::flags::display")]
    pub uavs: UavSource,
    /// With --uavs autopilots: a UAV whose last fix is older than this at a step (a quiet link) is not
    /// heard in that step's burst, ms.
    #[arg(long, value_name = "MS", default_value_t = 1500)]
    pub fix_timeout_ms: u64,
}

impl EmitterSimArgs {
    /// Checks the flags that need no scenario — also what `uavloc launch` checks of the flags it passes on;
    /// an error names the flag.
    pub fn check(&self) -> Result<(), String> {
        check_time_scale_flag(self.mode, self.time_scale)?;
        if self.step_delay_ms > MAX_STEP_DELAY_MS {
            return Err(format!(
                "--step-delay-ms must be at most {MAX_STEP_DELAY_MS} (a minute per step), got {}; for a run in the \
                 scenario's own time use --mode realtime",
                self.step_delay_ms
            ));
        }
        if self.mode == Mode::Realtime && self.step_delay_ms > 0 {
            return Err(
                "--step-delay-ms applies to lock-step mode only; in realtime mode --time-scale sets the pace".into()
            );
        }
        if !(self.command_timeout_s > 0.0 && self.command_timeout_s.is_finite()) {
            return Err(format!("--command-timeout-s must be > 0, got {}", self.command_timeout_s));
        }
        if !(self.connect_timeout_s >= 0.0 && self.connect_timeout_s.is_finite()) {
            return Err(format!("--connect-timeout-s must be ≥ 0, got {}", self.connect_timeout_s));
        }
        // The bound of both: a monitor further behind would lose messages from its full buffers, and a
        // restarted emitter-sim could not replay to it from its older snapshot.
        let most = (protocol::transport::SUBSCRIBER_BUFFER as u64).min(recovery::SNAPSHOT_EVERY - 1);
        if self.monitor_window > most {
            return Err(format!(
                "--monitor-window must be at most {most} (the monitor's subscriber buffer: a monitor further \
                 behind loses messages; 0 turns it off), got {}",
                self.monitor_window
            ));
        }
        if self.retry_interval_ms == 0 {
            return Err("--retry-interval-ms must be > 0".into());
        }
        if self.uavs == UavSource::Autopilots && self.mode != Mode::Realtime {
            return Err("--uavs autopilots needs --mode realtime: aircraft fly in real time (with --time-scale for \
                        simulated ones)"
                .into());
        }
        if self.fix_timeout_ms == 0 {
            return Err("--fix-timeout-ms must be > 0".into());
        }
        Ok(())
    }

    /// The pacing of these flags for a scenario of `steps` steps `dt` seconds apart (real time: an error
    /// for a `--time-scale` that makes a step or the run too long to be a duration).
    pub fn pacing(&self, dt: f64, steps: usize) -> Result<Pacing, String> {
        Ok(match self.mode {
            Mode::Lockstep => {
                Pacing::Lockstep {
                    step_delay: Duration::from_millis(self.step_delay_ms),
                    window: self.monitor_window,
                    // Two measurement subscribers: the estimator and a monitor (see --min-subscribers).
                    monitor_expected: self.min_subscribers >= 2,
                }
            }
            Mode::Realtime => Pacing::Realtime { interval: step_interval(dt, self.time_scale.unwrap_or(1.0), steps)? },
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_flags_round_trip() {
        let link = runtime::LinkArgs {
            transport: protocol::TransportKind::Uds,
            wait: Some(protocol::WaitMode::Spin),
            spin_us: None,
        };
        let e = EmitterSimArgs {
            process: runtime::ProcessArgs {
                node: runtime::NodeArgs {
                    domain: Some("d".into()),
                    link,
                    quiet: true,
                    supervised: false,
                    watch_pid: None,
                },
                run: runtime::RunArgs { scenario: Some("x.toml".into()), steps: Some(2), seed: Some(1) },
            },
            command_timeout_s: 0.1 + 0.2,
            retry_interval_ms: 77,
            connect_timeout_s: 3.5,
            min_subscribers: 2,
            step_delay_ms: 4,
            mode: Mode::Realtime,
            time_scale: Some(1.0 / 3.0),
            checkpoint: None,
            linger: true,
            monitor_window: 17,
            uavs: UavSource::Autopilots,
            fix_timeout_ms: 900,
        };
        assert_eq!(runtime::flags::round_trip(&e).unwrap(), e);
        // A value that is not a finite number is an error, not a flag left out (the child's default).
        let nan = EmitterSimArgs { time_scale: Some(f64::NAN), ..e.clone() };
        assert!(runtime::flags::to_flags(&nan).unwrap_err().contains("finite"));
        let inf = EmitterSimArgs { command_timeout_s: f64::INFINITY, ..e };
        assert!(runtime::flags::to_flags(&inf).is_err());
    }
}
