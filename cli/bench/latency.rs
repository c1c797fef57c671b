//! `uavloc bench latency` and `uavloc bench compare`: the real process set (the same children as
//! `uavloc launch`), pinned to the given cores, runs N lock-step steps; the latencies come from the
//! `CLOCK_MONOTONIC` stamps carried in the messages (written per step by the monitor, `--stamps`), the CPU
//! time from each process's own `getrusage`, the idle CPU from `/proc/<pid>/stat` while the monitor,
//! planner and estimator wait for a run that has not started yet.
//!
//! Series (all in µs, hdrhistogram, 3 significant figures):
//! - hops: `emitter→estimator` (measurement published → received by the estimator), `estimator→planner`,
//!   `planner→emitter` (command published → received by emitter-sim), and the monitor's
//!   `emitter→monitor`, `estimator→monitor`, `planner→monitor`;
//! - compute: `emitter-sim` (command received → next measurement published: fly, measure, publish the
//!   truth first), `estimator` (measurement received → estimate published), `planner` (estimate received
//!   → command published);
//! - end to end: measurement published → its command received by emitter-sim (both hops of the pipeline,
//!   estimator and planner, and the command's way back).
//!
//! `lost` counts steps missing from the record, messages of recorded steps the monitor never got (a
//! replayed copy carries no publish stamp, so a message the monitor lost and asked to be replayed counts as
//! lost) and emitter-sim's replays for late commands: every one is a message that did not arrive the first
//! time.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use clap::Args;
use planning::ObjectiveKind;
use protocol::{TransportKind, WaitMode};
use runtime::LinkArgs;
use serde::Serialize;

use super::histogram::{LatencyHistogram, Percentiles};
use super::plot::plot_latency_distributions;
use super::sys;
use crate::error::CliError;
use crate::launch::{self, LaunchArgs, LaunchReport};
use crate::output::{Report, Table};

pub const LONG_ABOUT: &str = "\
Measure the latency of the process pipeline: monitor, planner, estimator and emitter-sim (the same
children as `uavloc launch`) pinned to --cores run --steps lock-step steps over --transport, waiting
with --wait. Every latency comes from the CLOCK_MONOTONIC stamps carried in the messages:

  hops      emitter→estimator, estimator→planner, planner→emitter (the command back to the world),
            emitter→monitor, estimator→monitor, planner→monitor
  compute   emitter-sim (command received → next measurement out), estimator (Chan), planner
  end to end  measurement published → its command received by emitter-sim

each as p50/p90/p99/p99.9/max in µs (hdrhistogram), plus the CPU time of every process (and its share of
the run's wall time), the idle CPU of the monitor, planner and estimator while they wait for a run that
has not started (--idle-ms), and lost messages (must be 0).

Transports: iceoryx2 (zero-copy shared memory, an event service for wake-ups) or uds (Unix-domain
datagram sockets carrying the same #[repr(C)] bytes: the baseline a user would otherwise write). Wait
modes: block (sleep in the kernel until a message comes), spin (busy-poll, yielding the CPU; never
sleeps), spin-then-block (busy-poll --spin-us, then block). Nothing else differs between runs.

Bench numbers depend on the machine: on a 2-vCPU VM a blocking cross-core wake-up costs ~40 µs.
Exit codes: 0 success, 1 a run failed, 2 bad input.";

pub const AFTER_HELP: &str = "\
Examples:
  uavloc bench latency
  uavloc bench latency --transport uds --wait spin-then-block --spin-us 200 --steps 20000 --json
  uavloc bench latency --cores 0 --objective mc --out bench/mc
  uavloc bench compare --out bench/compare        (all transports × wait modes, with ratios)";

/// Flags shared by `latency` and `compare`.
#[derive(Args, Debug, Clone, PartialEq)]
pub struct RunFlags {
    /// CPU cores the processes may run on (e.g. 0,1 or 0-3); all four share them.
    #[arg(long, value_name = "LIST", default_value = "0,1")]
    pub cores: String,
    /// Lock-step steps per run.
    #[arg(long, value_name = "N", default_value_t = 10_000)]
    pub steps: usize,
    /// Planning objective: single | mc | analytical | cubature | formation.
    #[arg(long, default_value = "analytical")]
    pub objective: ObjectiveKind,
    /// Solver: gradient (the default of `launch`) | pso | ga | aco.
    #[arg(long, default_value = "gradient")]
    pub solver: planning::SolverKind,
    /// Scenario TOML file (default: the paper's nominal case).
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<PathBuf>,
    /// Busy-poll budget of --wait spin-then-block, µs.
    #[arg(long, value_name = "US", default_value_t = runtime::DEFAULT_SPIN_US)]
    pub spin_us: u64,
    /// Measure the idle CPU of the waiting monitor, planner and estimator over this many ms before each
    /// run (0: skip).
    #[arg(long, value_name = "MS", default_value_t = 500)]
    pub idle_ms: u64,
    /// Write the raw histograms (CSV), the monitor's stamps of each run (`<transport>-<wait>-stamps.csv`,
    /// the last round's), latency-distribution plots (SVG and PNG, log scale) and a JSON summary into DIR
    /// (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

/// Flags of `uavloc bench latency`.
#[derive(Args, Debug, Clone, PartialEq)]
pub struct LatencyArgs {
    #[command(flatten)]
    pub run: RunFlags,
    /// Transport: iceoryx2 | uds.
    #[arg(long, value_name = "KIND", default_value = "iceoryx2")]
    pub transport: TransportKind,
    /// Wait mode of every process: block | spin | spin-then-block.
    #[arg(long, value_name = "MODE", default_value = "block")]
    pub wait: WaitMode,
}

/// Flags of `uavloc bench compare`.
#[derive(Args, Debug, Clone, PartialEq)]
pub struct CompareArgs {
    #[command(flatten)]
    pub run: RunFlags,
    /// Rounds: each round runs every transport × wait mode once with steps/rounds steps, in alternating
    /// order; the histograms of the rounds are merged (slow drifts of the machine hit all configurations).
    #[arg(long, value_name = "R", default_value_t = 2)]
    pub rounds: usize,
}

/// One transport × wait mode, measured.
#[derive(Debug, Clone, Serialize)]
pub struct RunResult {
    pub transport: String,
    pub wait: String,
    /// Steps measured (lock-step; step 0 has no emitter compute).
    pub steps: usize,
    /// Messages that did not arrive the first time (see the module docs); 0 expected.
    pub lost: u64,
    pub end_to_end: Option<Percentiles>,
    pub hops: BTreeMap<String, Option<Percentiles>>,
    pub compute: BTreeMap<String, Option<Percentiles>>,
    /// CPU time per process, seconds.
    pub cpu_s: BTreeMap<String, f64>,
    /// CPU time per process as % of one core over the run's wall time.
    pub cpu_pct: BTreeMap<String, f64>,
    /// CPU use while idle (waiting before the run), % of one core.
    pub idle_cpu_pct: BTreeMap<String, f64>,
    /// Wall time of the run (start of the processes to their end), seconds.
    pub wall_s: f64,
    #[serde(skip)]
    histograms: Vec<(String, LatencyHistogram)>,
    /// Runs merged into this one (`compare --rounds`).
    #[serde(skip)]
    rounds: usize,
}

impl RunResult {
    /// Derives the percentiles of every series from the histograms, and the CPU shares from the CPU
    /// times and the wall time.
    fn summarize(&mut self) {
        self.end_to_end = self.histogram("end_to_end").and_then(LatencyHistogram::percentiles);
        for (kind, name) in SERIES.iter().skip(1) {
            let p = self.histogram(&format!("{kind}/{name}")).and_then(LatencyHistogram::percentiles);
            let map = if *kind == "hop" { &mut self.hops } else { &mut self.compute };
            map.insert(name.to_string(), p);
        }
        let wall = self.wall_s.max(1e-9);
        self.cpu_pct = self.cpu_s.iter().map(|(k, v)| (k.clone(), 100.0 * v / wall)).collect();
    }

    /// The histogram of a series (`end_to_end`, `hop/<name>`, `compute/<name>`).
    pub fn histogram(&self, series: &str) -> Option<&LatencyHistogram> {
        self.histograms.iter().find(|(n, _)| n == series).map(|(_, h)| h)
    }

    fn label(&self) -> String {
        format!("{} {}", self.transport, self.wait)
    }
}

/// The hops and compute stages, in report order: (kind, name).
pub const SERIES: [(&str, &str); 10] = [
    ("end_to_end", "end_to_end"),
    ("hop", "emitter→estimator"),
    ("hop", "estimator→planner"),
    ("hop", "planner→emitter"),
    ("hop", "emitter→monitor"),
    ("hop", "estimator→monitor"),
    ("hop", "planner→monitor"),
    ("compute", "emitter-sim"),
    ("compute", "estimator"),
    ("compute", "planner"),
];

/// One row of the monitor's `--stamps` CSV.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StepStamps {
    pub step: u64,
    pub trigger_command_received: u64,
    pub measurement_published: u64,
    pub measurement_received: u64,
    pub estimate_published: u64,
    pub estimate_received: u64,
    pub command_published: u64,
    pub command_received: u64,
    pub monitor_measurement: u64,
    pub monitor_estimate: u64,
    pub monitor_command: u64,
}

/// Parses the monitor's `--stamps` CSV (header checked against [`monitor::stamps::STAMPS_HEADER`]).
pub fn parse_stamps(text: &str) -> Result<Vec<StepStamps>, String> {
    let mut lines = text.lines();
    match lines.next() {
        Some(h) if h == monitor::stamps::STAMPS_HEADER => {}
        other => return Err(format!("unexpected stamps header {other:?}")),
    }
    lines
        .enumerate()
        .map(|(i, line)| {
            let v: Vec<u64> = line
                .split(',')
                .map(|f| f.parse::<u64>().map_err(|e| format!("stamps line {}: {f:?}: {e}", i + 2)))
                .collect::<Result<_, _>>()?;
            if v.len() != 13 {
                return Err(format!("stamps line {}: {} fields, expected 13", i + 2, v.len()));
            }
            Ok(StepStamps {
                step: v[0],
                trigger_command_received: v[2],
                measurement_published: v[3],
                measurement_received: v[4],
                estimate_published: v[5],
                estimate_received: v[6],
                command_published: v[7],
                command_received: v[8],
                monitor_measurement: v[9],
                monitor_estimate: v[10],
                monitor_command: v[11],
            })
        })
        .collect()
}

/// `end − start` when both are stamped and in order.
fn span(start: u64, end: u64) -> Option<u64> {
    protocol::messages::span_ns(start, end)
}

/// The histograms of every series over `rows` (in [`SERIES`] order, named `end_to_end`, `hop/<name>`,
/// `compute/<name>`). The emitter-sim compute of step k is from the command of step k − 1 (the previous
/// row's `command_received`) to this step's measurement.
pub fn histograms(rows: &[StepStamps]) -> Vec<(String, LatencyHistogram)> {
    let mut out: Vec<(String, LatencyHistogram)> = SERIES
        .iter()
        .map(|(kind, name)| {
            (if *kind == "end_to_end" { kind.to_string() } else { format!("{kind}/{name}") }, LatencyHistogram::new())
        })
        .collect();
    let mut previous: Option<&StepStamps> = None;
    for r in rows {
        let emitter = previous
            .filter(|p| p.step + 1 == r.step)
            .and_then(|_| span(r.trigger_command_received, r.measurement_published));
        let values = [
            span(r.measurement_published, r.command_received),
            span(r.measurement_published, r.measurement_received),
            span(r.estimate_published, r.estimate_received),
            span(r.command_published, r.command_received),
            span(r.measurement_published, r.monitor_measurement),
            span(r.estimate_published, r.monitor_estimate),
            span(r.command_published, r.monitor_command),
            emitter,
            span(r.measurement_received, r.estimate_published),
            span(r.estimate_received, r.command_published),
        ];
        for ((_, h), v) in out.iter_mut().zip(values) {
            if let Some(v) = v {
                h.record(v);
            }
        }
        previous = Some(r);
    }
    out
}

/// The configuration of one measured run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunConfig {
    pub transport: TransportKind,
    pub wait: WaitMode,
    pub steps: usize,
}

fn unique_domain() -> String {
    static NEXT: AtomicU64 = AtomicU64::new(0);
    format!("bench-{}-{}", std::process::id(), NEXT.fetch_add(1, Ordering::Relaxed))
}

/// Checks the shared flags and pins this thread (and so the children it spawns) to the cores.
fn prepare(flags: &RunFlags) -> Result<Vec<usize>, CliError> {
    crate::args::require_count("--steps", flags.steps, 1, model::scenario::MAX_STEPS)?;
    let cores = sys::parse_cores(&flags.cores).map_err(|e| CliError::input_because("--cores", e))?;
    if let Some(s) = &flags.scenario
        && !s.is_file()
    {
        return Err(CliError::Input(format!("--scenario: {} is not a readable file", s.display())));
    }
    if let Some(dir) = &flags.out {
        runtime::output::check_out_dir("--out", dir).map_err(CliError::Input)?;
    }
    sys::pin_current_process(&cores).map_err(|e| CliError::failed_because("--cores", e))?;
    Ok(cores)
}

/// Runs the process set once and measures it.
pub fn measure(flags: &RunFlags, config: &RunConfig) -> Result<RunResult, CliError> {
    let domain = unique_domain();
    let stamps_file = std::env::temp_dir().join(format!("uavloc-{domain}.stamps.csv"));
    let args = LaunchArgs {
        run: crate::args::RunChoice {
            scenario: flags.scenario.clone(),
            objective: flags.objective,
            solver: flags.solver,
            steps: Some(config.steps),
            seed: None,
            estimator: None,
        },
        domain: Some(domain),
        source: runtime::Source::Simulator,
        record: None,
        headless: true,
        out: None,
        log: None,
        command_timeout_s: 10.0,
        link: LinkArgs { transport: config.transport, wait: Some(config.wait), spin_us: Some(flags.spin_us) },
        stamps: Some(stamps_file.clone()),
        idle_probe_ms: flags.idle_ms,
        live: false,
        mode: emitter_sim::args::Mode::Lockstep,
        time_scale: None,
        estimate_deadline_ms: 0,
        step_delay_ms: 0,
        plan_delay_ms: 0,
        plan_delay_steps: Vec::new(),
        retry_interval_ms: 1000,
        max_restarts: 0,
        autopilots: Vec::new(),
    };
    let report = launch::run(&args);
    let text = std::fs::read_to_string(&stamps_file);
    let _ = std::fs::remove_file(&stamps_file);
    let report = report?;
    let text = text.map_err(|e| CliError::failed_because("the monitor's stamps file", e))?;
    if let Some(dir) = &flags.out {
        // The raw stamps of the run (of its last round), beside the histograms made from them.
        let file = dir.join(format!("{}-{}-stamps.csv", config.transport.name(), config.wait.name()));
        std::fs::write(&file, &text).map_err(|e| CliError::failed_because(format!("--out {}", file.display()), e))?;
    }
    let rows = parse_stamps(&text).map_err(CliError::Failed)?;
    Ok(result(config, &report, &rows))
}

fn summary_u64(report: &LaunchReport, role: &str, key: &str) -> u64 {
    report
        .children
        .iter()
        .filter(|c| c.role == role)
        .filter_map(|c| c.summary.as_ref().and_then(|s| s[key].as_u64()))
        .sum()
}

fn result(config: &RunConfig, report: &LaunchReport, rows: &[StepStamps]) -> RunResult {
    let expected_rows = config.steps as u64 + 1;
    let lost = expected_rows.saturating_sub(rows.len() as u64)
        + summary_u64(report, "monitor", "missing_messages")
        + summary_u64(report, "emitter-sim", "retries");
    let mut cpu_s = BTreeMap::new();
    for c in &report.children {
        if let Some(t) = c.summary.as_ref().and_then(|s| s["cpu_s"].as_f64()) {
            *cpu_s.entry(c.role.clone()).or_insert(0.0) += t;
        }
    }
    let mut r = RunResult {
        transport: config.transport.name().into(),
        wait: config.wait.name().into(),
        steps: config.steps,
        lost,
        end_to_end: None,
        hops: BTreeMap::new(),
        compute: BTreeMap::new(),
        cpu_s,
        cpu_pct: BTreeMap::new(),
        idle_cpu_pct: report.idle_cpu.clone(),
        wall_s: report.wall_s,
        histograms: histograms(rows),
        rounds: 1,
    };
    r.summarize();
    r
}

/// Writes the histograms of `runs` as CSV, the end-to-end (and, for one run, every series') distribution
/// plots and `summary.json` into `dir`.
fn write_out(dir: &Path, runs: &[RunResult], summary: &impl Serialize) -> Result<Vec<PathBuf>, CliError> {
    let fail = |p: &Path, e: String| CliError::failed_because(format!("--out {}", p.display()), e);
    let mut written = Vec::new();
    for r in runs {
        for (name, h) in &r.histograms {
            let file = dir.join(format!("{}-{}-{}.csv", r.transport, r.wait, name.replace(['/', '→'], "_")));
            std::fs::write(&file, h.csv()).map_err(|e| fail(&file, e.to_string()))?;
            written.push(file);
        }
    }
    let e2e: Vec<(String, &LatencyHistogram)> =
        runs.iter().filter_map(|r| r.histogram("end_to_end").map(|h| (r.label(), h))).collect();
    for ext in ["svg", "png"] {
        let file = dir.join(format!("end_to_end.{ext}"));
        plot_latency_distributions(&file, "End-to-end latency by percentile (measurement → command received)", &e2e)
            .map_err(|e| fail(&file, e))?;
        written.push(file);
        if let [r] = runs {
            for (group, title) in [("hop", "hops (and end to end)"), ("compute", "compute stages")] {
                let some: Vec<(String, &LatencyHistogram)> = r
                    .histograms
                    .iter()
                    .filter(|(n, _)| n.starts_with(group) || (group == "hop" && n == "end_to_end"))
                    .map(|(n, h)| (n.clone(), h))
                    .collect();
                let file = dir.join(format!("{group}.{ext}"));
                plot_latency_distributions(&file, &format!("Latency by percentile, {title}, {}", r.label()), &some)
                    .map_err(|e| fail(&file, e))?;
                written.push(file);
            }
        }
    }
    let file = dir.join("summary.json");
    let text = serde_json::to_string_pretty(summary).map_err(|e| fail(&file, e.to_string()))?;
    std::fs::write(&file, text + "\n").map_err(|e| fail(&file, e.to_string()))?;
    written.push(file);
    Ok(written)
}

/// What `uavloc bench latency` and `uavloc bench compare` print.
#[derive(Debug, Clone, Serialize)]
pub struct LatencyReport {
    pub runs: Vec<RunResult>,
    /// `compare`: iceoryx2 / uds per wait mode and percentile (end to end).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub ratios: Vec<Ratio>,
    /// The goals of the benchmark, each with its verdict.
    pub goals: Vec<Goal>,
    pub cores: Vec<usize>,
    /// The machine (`cpus`, `cpu_model`).
    #[serde(flatten)]
    pub machine: sys::Machine,
    pub objective: String,
    /// Files written with --out.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub files: Vec<PathBuf>,
}

/// iceoryx2 / uds of one wait mode, end to end.
#[derive(Debug, Clone, Serialize)]
pub struct Ratio {
    pub wait: String,
    pub p50: f64,
    pub p90: f64,
    pub p99: f64,
    pub p999: f64,
    pub max: f64,
}

/// A goal and how the run measured up.
#[derive(Debug, Clone, Serialize)]
pub struct Goal {
    pub goal: String,
    pub met: bool,
    pub detail: String,
}

/// The end-to-end percentiles of the iceoryx2 and the uds run of wait mode `w`, when both were measured.
fn pair(runs: &[RunResult], w: WaitMode) -> Option<(Percentiles, Percentiles)> {
    let (i, u) = pair_runs(runs, w)?;
    Some((i.end_to_end?, u.end_to_end?))
}

/// The iceoryx2 and the uds run of wait mode `w`, when both were measured.
fn pair_runs(runs: &[RunResult], w: WaitMode) -> Option<(&RunResult, &RunResult)> {
    let find = |t: TransportKind| runs.iter().find(|r| r.transport == t.name() && r.wait == w.name());
    Some((find(TransportKind::Iceoryx2)?, find(TransportKind::Uds)?))
}

/// The hops of the control loop (measurement → estimate → command → world).
const LOOP_HOPS: [&str; 3] = ["emitter→estimator", "estimator→planner", "planner→emitter"];

/// The mean p50 of the control loop's hops (µs), when all were measured.
fn loop_hop_p50(r: &RunResult) -> Option<f64> {
    let p: Option<Vec<f64>> = LOOP_HOPS.iter().map(|h| r.hops.get(*h).copied().flatten().map(|p| p.p50_us)).collect();
    p.map(|p| p.iter().sum::<f64>() / p.len() as f64)
}

/// The latency goals (ARCHITECTURE.md, "Budgets") for the runs measured.
fn goals(runs: &[RunResult], objective: ObjectiveKind) -> Vec<Goal> {
    let mut out = Vec::new();
    let note = if objective == ObjectiveKind::Analytical { "" } else { " (goal stated for the analytical objective)" };
    for r in runs {
        if let Some(e) = &r.end_to_end {
            let block = r.wait == "block";
            let p50_goal = if block { 200.0 } else { f64::INFINITY };
            out.push(Goal {
                goal: if block {
                    format!("end-to-end p50 ≤ 200 µs and p99 ≤ 500 µs ({})", r.label())
                } else {
                    format!("end-to-end p99 ≤ 500 µs ({})", r.label())
                },
                met: e.p50_us <= p50_goal && e.p99_us <= 500.0,
                detail: format!("p50 {:.0} µs, p99 {:.0} µs{note}", e.p50_us, e.p99_us),
            });
        }
        if r.wait == "block" && !r.idle_cpu_pct.is_empty() {
            let worst =
                r.idle_cpu_pct.iter().max_by(|a, b| a.1.total_cmp(b.1)).map_or(("-", 0.0), |(k, v)| (k.as_str(), *v));
            out.push(Goal {
                goal: format!("idle CPU < 1 % per process ({})", r.label()),
                met: worst.1 < 1.0,
                detail: format!("highest {:.2} % ({})", worst.1, worst.0),
            });
        }
        out.push(Goal {
            goal: format!("no lost messages ({})", r.label()),
            met: r.lost == 0,
            detail: format!("{} lost", r.lost),
        });
    }
    for w in WaitMode::ALL {
        let Some((i, u)) = pair_runs(runs, w) else { continue };
        let hops = loop_hop_p50(i).zip(loop_hop_p50(u));
        let detail = |(hi, hu): (f64, f64)| {
            format!("control-loop hops, mean p50: iceoryx2 {hi:.1} µs, uds {hu:.1} µs ({:.2}×)", hi / hu)
        };
        match (w, hops) {
            (WaitMode::SpinThenBlock, Some((hi, hu))) => out.push(Goal {
                goal: format!("iceoryx2 hops ≤ 5 µs p50 and ≤ ½ of uds ({w})"),
                met: hi <= 5.0 && hi <= 0.5 * hu,
                detail: detail((hi, hu)),
            }),
            (WaitMode::Block, Some((hi, hu))) => out.push(Goal {
                goal: format!("iceoryx2 hops within 10 % of uds at p50 ({w})"),
                met: hi <= 1.1 * hu,
                detail: detail((hi, hu)),
            }),
            _ => {}
        }
        if let Some((a, b)) = pair(runs, w) {
            out.push(Goal {
                goal: format!("iceoryx2 ahead of uds end to end at p50 and p99 ({w})"),
                met: a.p50_us < b.p50_us && a.p99_us < b.p99_us,
                detail: format!("p50 {:.1} vs {:.1} µs, p99 {:.1} vs {:.1} µs", a.p50_us, b.p50_us, a.p99_us, b.p99_us),
            });
        }
    }
    out
}

fn ratios(runs: &[RunResult]) -> Vec<Ratio> {
    WaitMode::ALL
        .iter()
        .filter_map(|w| {
            let (a, b) = pair(runs, *w)?;
            Some(Ratio {
                wait: w.name().into(),
                p50: a.p50_us / b.p50_us,
                p90: a.p90_us / b.p90_us,
                p99: a.p99_us / b.p99_us,
                p999: a.p999_us / b.p999_us,
                max: a.max_us / b.max_us,
            })
        })
        .collect()
}

fn progress(line: &str) {
    protocol::log_line!("bench: {line}");
}

/// Runs `uavloc bench latency`.
pub fn run_latency(args: &LatencyArgs) -> Result<LatencyReport, CliError> {
    let cores = prepare(&args.run)?;
    let config = RunConfig { transport: args.transport, wait: args.wait, steps: args.run.steps };
    progress(&format!("{} × {} steps, {} on cores {:?} …", config.transport, config.steps, config.wait, cores));
    let start = Instant::now();
    let r = measure(&args.run, &config)?;
    progress(&format!("done in {:.1} s", start.elapsed().as_secs_f64()));
    finish(&args.run, cores, vec![r], Vec::new())
}

/// Runs `uavloc bench compare`.
pub fn run_compare(args: &CompareArgs) -> Result<LatencyReport, CliError> {
    if args.rounds == 0 {
        return Err(CliError::Input("--rounds must be ≥ 1".into()));
    }
    if args.run.steps < args.rounds {
        return Err(CliError::Input(format!("--steps ({}) must be ≥ --rounds ({})", args.run.steps, args.rounds)));
    }
    let cores = prepare(&args.run)?;
    let configs: Vec<(TransportKind, WaitMode)> =
        WaitMode::ALL.iter().flat_map(|w| TransportKind::ALL.iter().map(move |t| (*t, *w))).collect();
    let per_round = args.run.steps / args.rounds;
    let mut merged: Vec<Option<RunResult>> = vec![None; configs.len()];
    let total = configs.len() * args.rounds;
    let start = Instant::now();
    for round in 0..args.rounds {
        // Alternate the order each round (forwards, backwards) so no configuration always runs first.
        let order: Vec<usize> =
            if round % 2 == 0 { (0..configs.len()).collect() } else { (0..configs.len()).rev().collect() };
        for (j, &i) in order.iter().enumerate() {
            let (transport, wait) = configs[i];
            let steps = if round + 1 == args.rounds { args.run.steps - per_round * round } else { per_round };
            progress(&format!(
                "[{}/{total}] {transport} {wait}, {steps} steps (elapsed {:.0} s)",
                round * configs.len() + j + 1,
                start.elapsed().as_secs_f64()
            ));
            let r = measure(&args.run, &RunConfig { transport, wait, steps })?;
            merged[i] = Some(match merged[i].take() {
                None => r,
                Some(m) => merge(m, r),
            });
        }
    }
    let runs: Vec<RunResult> = merged.into_iter().flatten().collect();
    let ratios = ratios(&runs);
    finish(&args.run, cores, runs, ratios)
}

/// Adds run `b` (same configuration) to `a`: histograms merged, counts and times summed, idle CPU the mean
/// over the merged runs.
fn merge(mut a: RunResult, b: RunResult) -> RunResult {
    for ((_, ha), (_, hb)) in a.histograms.iter_mut().zip(&b.histograms) {
        ha.merge(hb);
    }
    a.steps += b.steps;
    a.lost += b.lost;
    a.wall_s += b.wall_s;
    for (k, v) in b.cpu_s {
        *a.cpu_s.entry(k).or_insert(0.0) += v;
    }
    let n = a.rounds as f64;
    for (k, v) in b.idle_cpu_pct {
        a.idle_cpu_pct.entry(k).and_modify(|x| *x = (*x * n + v) / (n + 1.0)).or_insert(v);
    }
    a.rounds += b.rounds;
    a.summarize();
    a
}

fn finish(
    flags: &RunFlags,
    cores: Vec<usize>,
    runs: Vec<RunResult>,
    ratios: Vec<Ratio>,
) -> Result<LatencyReport, CliError> {
    let mut report = LatencyReport {
        goals: goals(&runs, flags.objective),
        runs,
        ratios,
        cores,
        machine: sys::Machine::this(),
        objective: flags.objective.name().into(),
        files: Vec::new(),
    };
    if let Some(dir) = &flags.out {
        let files = write_out(dir, &report.runs, &report)?;
        report.files = files;
    }
    Ok(report)
}

fn fmt_p(p: &Option<Percentiles>) -> String {
    match p {
        Some(p) => {
            format!("{:>8.1} {:>8.1} {:>8.1} {:>8.1} {:>9.1}", p.p50_us, p.p90_us, p.p99_us, p.p999_us, p.max_us)
        }
        None => format!("{:>8} {:>8} {:>8} {:>8} {:>9}", "-", "-", "-", "-", "-"),
    }
}

impl Report for LatencyReport {
    fn table(&self) -> Table {
        let mut t = Table::new()
            .row("machine", self.machine.describe())
            .row("cores", format!("{:?}", self.cores))
            .row("objective", &self.objective);
        for r in &self.runs {
            t = t.row(
                format!("{} end to end p50/p99", r.label()),
                match &r.end_to_end {
                    Some(p) => format!("{:.1} / {:.1} µs", p.p50_us, p.p99_us),
                    None => "-".into(),
                },
            );
        }
        t
    }

    fn text(&self) -> String {
        use std::fmt::Write as _;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "{}; cores {:?}, objective {}; latencies in µs",
            self.machine.describe(),
            self.cores,
            self.objective
        );
        for r in &self.runs {
            let _ = writeln!(s, "\n{} — {} steps in {:.2} s, lost {}", r.label(), r.steps, r.wall_s, r.lost);
            let _ =
                writeln!(s, "  {:<26} {:>8} {:>8} {:>8} {:>8} {:>9}", "series", "p50", "p90", "p99", "p99.9", "max");
            let _ = writeln!(s, "  {:<26} {}", "end to end", fmt_p(&r.end_to_end));
            for (k, v) in &r.hops {
                let _ = writeln!(s, "  {:<26} {}", format!("hop {k}"), fmt_p(v));
            }
            for (k, v) in &r.compute {
                let _ = writeln!(s, "  {:<26} {}", format!("compute {k}"), fmt_p(v));
            }
            let cpu: Vec<String> = r
                .cpu_s
                .iter()
                .map(|(k, v)| {
                    let idle = r.idle_cpu_pct.get(k).map_or(String::new(), |i| format!(", idle {i:.1} %"));
                    format!("{k} {v:.2} s ({:.0} %{idle})", r.cpu_pct.get(k).copied().unwrap_or(0.0))
                })
                .collect();
            let _ = writeln!(s, "  CPU: {}", cpu.join("; "));
        }
        if !self.ratios.is_empty() {
            let _ = writeln!(s, "\niceoryx2 / uds, end to end (< 1: iceoryx2 faster)");
            let _ = writeln!(s, "  {:<16} {:>6} {:>6} {:>6} {:>6} {:>6}", "wait", "p50", "p90", "p99", "p99.9", "max");
            for r in &self.ratios {
                let _ = writeln!(
                    s,
                    "  {:<16} {:>6.2} {:>6.2} {:>6.2} {:>6.2} {:>6.2}",
                    r.wait, r.p50, r.p90, r.p99, r.p999, r.max
                );
            }
        }
        let _ = writeln!(s, "\ngoals");
        for g in &self.goals {
            let _ = writeln!(s, "  [{}] {} — {}", if g.met { "met" } else { "MISSED" }, g.goal, g.detail);
        }
        let csv = self.files.iter().filter(|f| f.extension().is_some_and(|e| e == "csv")).count();
        if let Some(dir) = self.files.first().and_then(|f| f.parent()) {
            let others: Vec<String> = self
                .files
                .iter()
                .filter(|f| f.extension().is_none_or(|e| e != "csv"))
                .filter_map(|f| f.file_name().map(|n| n.to_string_lossy().into_owned()))
                .collect();
            let _ = writeln!(s, "\nwrote {csv} histogram CSVs and {} into {}", others.join(", "), dir.display());
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(step: u64, base: u64) -> StepStamps {
        StepStamps {
            step,
            trigger_command_received: base,
            measurement_published: base + 10,
            measurement_received: base + 30,
            estimate_published: base + 35,
            estimate_received: base + 75,
            command_published: base + 275,
            command_received: base + 315,
            monitor_measurement: base + 50,
            monitor_estimate: base + 95,
            monitor_command: base + 300,
        }
    }

    #[test]
    fn series_are_the_right_differences() {
        let mut rows = vec![row(0, 1000), row(1, 2000)];
        rows[0].trigger_command_received = 0; // step 0 has no trigger
        let h = histograms(&rows);
        let get = |n: &str| h.iter().find(|(k, _)| k == n).unwrap().1.percentiles().unwrap();
        assert_eq!(get("end_to_end").n, 2);
        assert!((get("end_to_end").max_us - 0.305).abs() < 1e-3);
        assert!((get("hop/emitter→estimator").max_us - 0.020).abs() < 1e-4);
        assert!((get("hop/estimator→planner").max_us - 0.040).abs() < 1e-4);
        assert!((get("hop/planner→emitter").max_us - 0.040).abs() < 1e-4);
        assert!((get("hop/emitter→monitor").max_us - 0.040).abs() < 1e-4);
        assert!((get("hop/estimator→monitor").max_us - 0.060).abs() < 1e-4);
        assert!((get("hop/planner→monitor").max_us - 0.025).abs() < 1e-4);
        assert!((get("compute/estimator").max_us - 0.005).abs() < 1e-4);
        assert!((get("compute/planner").max_us - 0.200).abs() < 1e-3);
        // Emitter compute only from step 1 on (trigger of step 1 → its measurement).
        assert_eq!(get("compute/emitter-sim").n, 1);
        assert!((get("compute/emitter-sim").max_us - 0.010).abs() < 1e-4);
    }

    #[test]
    fn missing_stamps_are_skipped_not_zero() {
        let mut r = row(3, 5000);
        r.command_received = 0;
        r.monitor_command = 0;
        let h = histograms(&[r]);
        let get = |n: &str| h.iter().find(|(k, _)| k == n).unwrap().1.len();
        assert_eq!(get("end_to_end"), 0);
        assert_eq!(get("hop/planner→emitter"), 0);
        assert_eq!(get("hop/planner→monitor"), 0);
        assert_eq!(get("hop/emitter→estimator"), 1);
    }

    #[test]
    fn parses_the_monitor_csv() {
        let text = format!("{}\n0,0,0,10,30,35,75,275,315,50,95,300,20\n", monitor::stamps::STAMPS_HEADER);
        let rows = parse_stamps(&text).unwrap();
        assert_eq!(rows.len(), 1);
        assert_eq!(rows[0].command_received, 315);
        assert_eq!(rows[0].monitor_command, 300);
        assert!(parse_stamps("step\n").unwrap_err().contains("header"));
        let bad = format!("{}\n1,2,3\n", monitor::stamps::STAMPS_HEADER);
        assert!(parse_stamps(&bad).unwrap_err().contains("13"));
        let bad = format!("{}\n1,2,3,4,5,6,7,8,9,10,11,12,x\n", monitor::stamps::STAMPS_HEADER);
        assert!(parse_stamps(&bad).unwrap_err().contains("line 2"));
    }

    #[test]
    fn ratios_and_goals() {
        let mk = |t: &str, w: &str, p50: f64, p99: f64, lost: u64| RunResult {
            transport: t.into(),
            wait: w.into(),
            steps: 10,
            lost,
            end_to_end: Some(Percentiles { p50_us: p50, p90_us: p50, p99_us: p99, p999_us: p99, max_us: p99, n: 10 }),
            hops: BTreeMap::new(),
            compute: BTreeMap::new(),
            cpu_s: BTreeMap::new(),
            cpu_pct: BTreeMap::new(),
            idle_cpu_pct: [("planner".to_string(), 0.5), ("monitor".to_string(), 12.0)].into(),
            wall_s: 1.0,
            histograms: Vec::new(),
            rounds: 1,
        };
        let hops = |p50s: [f64; 3]| -> BTreeMap<String, Option<Percentiles>> {
            LOOP_HOPS
                .iter()
                .zip(p50s)
                .map(|(h, p)| {
                    let q = Percentiles { p50_us: p, p90_us: p, p99_us: p, p999_us: p, max_us: p, n: 10 };
                    (h.to_string(), Some(q))
                })
                .collect()
        };
        let runs = [mk("iceoryx2", "block", 100.0, 400.0, 0), mk("uds", "block", 200.0, 300.0, 1)];
        let r = ratios(&runs);
        assert_eq!(r.len(), 1);
        assert!((r[0].p50 - 0.5).abs() < 1e-12 && (r[0].p99 - 400.0 / 300.0).abs() < 1e-12);
        let g = goals(&runs, ObjectiveKind::Analytical);
        let find = |g: &[Goal], s: &str| g.iter().find(|x| x.goal.contains(s)).unwrap_or_else(|| panic!("{s}")).clone();
        assert!(find(&g, "p50 ≤ 200 µs and p99 ≤ 500 µs (iceoryx2 block)").met);
        assert!(find(&g, "p50 ≤ 200 µs and p99 ≤ 500 µs (uds block)").met, "the bounds are inclusive");
        assert!(!find(&g, "idle CPU < 1 % per process (uds block)").met);
        assert!(find(&g, "idle CPU < 1 % per process (uds block)").detail.contains("monitor"));
        assert!(!find(&g, "no lost messages (uds block)").met);
        assert!(!find(&g, "iceoryx2 ahead of uds").met, "p99 is behind");
        // The hop goals of 17.4: spin-then-block ≤ 5 µs and ≤ ½ of uds; block within 10 %.
        let mut runs = vec![
            mk("iceoryx2", "spin-then-block", 50.0, 100.0, 0),
            mk("uds", "spin-then-block", 60.0, 100.0, 0),
            mk("iceoryx2", "block", 150.0, 300.0, 0),
            mk("uds", "block", 150.0, 300.0, 0),
        ];
        for (r, p) in runs.iter_mut().zip([[4.0, 5.0, 6.0], [12.0, 10.0, 8.0], [45.0, 46.0, 47.0], [40.0, 40.0, 40.0]])
        {
            r.hops = hops(p);
        }
        let g = goals(&runs, ObjectiveKind::Analytical);
        assert!(find(&g, "≤ 5 µs p50 and ≤ ½ of uds (spin-then-block)").met, "5.0 ≤ 5 and 5 ≤ 5");
        assert!(!find(&g, "within 10 % of uds at p50 (block)").met, "46 > 1.1 × 40");
        runs[2].hops = hops([43.0, 44.0, 44.0]);
        let g = goals(&runs, ObjectiveKind::Analytical);
        assert!(find(&g, "within 10 % of uds at p50 (block)").met, "43.67 ≤ 44");
    }
}
