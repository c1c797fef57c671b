//! `uavloc simulate`: the pipeline's closed loop in one process — emitter → estimator → planner → move —
//! step by step ([`closed_loop::run_closed_loop`]: the same library calls the processes make — the
//! world's `World`, the estimator's `Estimator`, the planner's `plan_step`, the record's
//! `step_metrics`), so a run through the processes reproduces it.

use std::path::PathBuf;

use clap::Args;
use model::Scenario;
use record::RunRecord;

use crate::error::CliError;
use crate::output::{Diagnostic, Report, Table};

pub const LONG_ABOUT: &str = "\
Run the closed loop of the paper in one process: at every step the world (emitter-sim) measures the
range differences with noise, Chan's estimator fixes the emitter (with the previous estimate as prior),
the planner picks one heading per UAV for the next interval (PSO/GA/ACO over the heading cones, under
the turn-radius, spacing and approach constraints), and the UAVs fly a circular arc of length v·Δt.

Per step it reports the UAV positions, the estimate, the CRLB at the TRUE emitter for that geometry,
the RMSE of Chan over R noise resamples (paper Section 5.3), the objective value and the planning time.
Step 0 is the initial geometry; the last step is measured but not planned. On a terminal a progress
bar shows the steps done, the rate and the time left.

Without --scenario the paper's nominal case (Table 1) is used: 3 UAVs at [1500,500], [10000,1500],
[5000,8500] m, emitter at [25000,15000] m, 50 m/s, 10 s, σ = 28.7712 m, 24 steps (see
scenarios/nominal.toml for every value and which ones are our choice). Units: metres, radians, ms.";

pub const AFTER_HELP: &str = "\
Examples:
  uavloc simulate
  uavloc simulate --objective single --solver ga --seed 7 --json
  uavloc simulate --scenario scenarios/nominal.toml --objective formation --out runs/formation

--record FILE.mcap writes the messages the pipeline would carry (measurement, estimate, command, truth
of every step) to an MCAP recording, like `uavloc launch --record`; `uavloc replay FILE` runs on it.

--out DIR writes trajectory.csv, steps.csv, run.json and plots (trajectories.svg/.png like the paper's
Figure 4, metrics.svg/.png with CRLB and RMSE per step).";

/// Flags of `uavloc simulate`.
#[derive(Args, Debug, Clone, PartialEq)]
pub struct SimulateArgs {
    /// Scenario, objective, solver, steps, seed, estimator.
    #[command(flatten)]
    pub run: crate::args::RunChoice,
    /// Directory to write CSVs, run.json and plots into (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Show the run on the live view (map, errors) as it goes, a step every 100 ms; `q` skips to the end,
    /// where the view waits for `q`. Needs a terminal (otherwise the table is printed as without it).
    #[arg(long)]
    pub live: bool,
    /// Write the messages of every step (measurement, estimate, command, truth — as the pipeline would
    /// carry them) to FILE as MCAP (see `uavloc launch --record`).
    #[arg(long, value_name = "FILE.mcap")]
    pub record: Option<PathBuf>,
}

/// Loads the scenario of the flags (file or default) with `--steps`/`--seed` applied, validated.
pub fn scenario_from(path: Option<&PathBuf>, steps: Option<usize>, seed: Option<u64>) -> Result<Scenario, CliError> {
    // The same rule every process applies (model::load_scenario), so a run agrees on it.
    model::load_scenario(path.map(PathBuf::as_path), steps, seed).map_err(|e| match path {
        Some(p) => CliError::input_because(format!("--scenario {}", p.display()), e),
        None => CliError::input_because("scenario", e),
    })
}

/// What `uavloc simulate` prints.
#[derive(Debug, Clone, serde::Serialize)]
#[serde(transparent)]
pub struct SimulateReport {
    pub run: RunRecord,
    #[serde(skip)]
    pub written: Vec<PathBuf>,
}

/// Runs `uavloc simulate`.
pub fn run(args: &SimulateArgs) -> Result<SimulateReport, CliError> {
    let sc = args.run.scenario()?;
    let record = [("--record", args.record.as_deref())];
    runtime::output::check_outputs(&record, ("--out", args.out.as_deref(), &record::export::RUN_FILES))
        .map_err(CliError::Input)?;
    let mut recorder = match &args.record {
        Some(file) => {
            let metadata = record::recording::run_metadata(&sc, "simulate", "simulator");
            Some(record::recording::Recorder::create(file, metadata, false).map_err(CliError::Failed)?)
        }
        None => None,
    };
    let (objective, solver) = (args.run.objective, args.run.solver);
    let mut live = match args.live && crate::live::LiveTerminal::available() {
        true => Some((
            crate::live::LiveTerminal::start().map_err(|e| CliError::failed_because("--live", e))?,
            {
                let mut view = crate::live::LiveState::new("simulate", sc.steps as u64, sc.l_min).with_bound(&sc);
                view.planner = Some(format!("{}/{} (in this process)", solver.name(), objective.name()));
                view
            },
            false,
        )),
        false => None,
    };
    // A long run shows its progress on a terminal (steps done, rate, ETA); nothing elsewhere.
    let bar = indicatif::ProgressBar::with_draw_target(
        Some(sc.steps as u64 + 1),
        if live.is_some() { indicatif::ProgressDrawTarget::hidden() } else { indicatif::ProgressDrawTarget::stderr() },
    );
    bar.set_style(
        indicatif::ProgressStyle::with_template("simulate [{bar:30}] step {pos}/{len}, elapsed {elapsed}, ETA {eta}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    let run = closed_loop::run_closed_loop(&sc, objective, solver, |record, trace| {
        bar.inc(1);
        if let Some(r) = &mut recorder {
            record_step(r, record, trace, (objective, solver), &sc);
        }
        if let Some((terminal, view, skip)) = &mut live {
            view.apply_step(record);
            if !*skip {
                let _ = terminal.draw(view);
                *skip = terminal.quit_pressed(std::time::Duration::from_millis(100));
            }
        }
    })
    .map_err(|e| CliError::failed_because("the closed loop", e))?;
    bar.finish_and_clear();
    if let Some((mut terminal, mut view, _)) = live {
        view.note = "the run is over: q closes the view".into();
        let _ = terminal.draw(&view);
        while !terminal.quit_pressed(std::time::Duration::from_millis(200)) {}
    }
    if let Some(r) = recorder {
        r.finish().map_err(CliError::Failed)?;
    }
    let written = match &args.out {
        Some(dir) => record::export::write_run(&run, dir)
            .map_err(|e| CliError::failed_because(format!("--out {}", dir.display()), e))?,
        None => Vec::new(),
    };
    Ok(SimulateReport { run, written })
}

/// Records the messages of one step of the closed loop, as the pipeline's processes would publish them
/// (sequence numbers = the step; no latency stamps: nothing travelled).
fn record_step(
    r: &mut record::recording::Recorder,
    record: &record::StepRecord,
    trace: &closed_loop::StepTrace<'_>,
    (objective, solver): (planning::ObjectiveKind, planning::SolverKind),
    sc: &model::Scenario,
) {
    use protocol::{Command, CommandOutcome, Truth};
    let k = record.step;
    let now = protocol::now_ns();
    let previous = if k == 0 { CommandOutcome::None } else { CommandOutcome::Flown };
    r.record(&Truth::new(k, k, trace.truth).with_previous_command(previous), now);
    let wire = emitter_sim::process::wire_measurement(
        k,
        trace.measurement,
        &sc.range_sigmas(),
        trace.measured_headings,
        &sc.receiver,
    );
    let Ok(mut m) = wire else { return };
    m.header.seq = k;
    r.record(&m, now);
    let reply = estimator::chain::reply_of(trace.estimate);
    let estimate = reply.to_estimate(&m, now, k, 0).ok();
    if let Some(e) = &estimate {
        r.record(e, now);
    }
    if let Some(plan) = trace.plan {
        let waypoints = planner::wire::waypoints(plan);
        let info = planner::wire::plan_info(plan, &waypoints, (solver, objective));
        if let Ok(c) = Command::new(k, k, 0, &info) {
            // The planner echoes the estimator's state in every command planned from an estimate.
            r.record(&estimate.map_or(c, |e| c.with_state_of(&e)), now);
        }
    }
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or("-".to_string(), |x| format!("{x:.digits$}"))
}

impl Report for SimulateReport {
    fn table(&self) -> Table {
        let r = &self.run;
        let mut t = Table::new()
            .row("objective / solver", format!("{} / {}", r.objective, r.solver))
            .row("seed", r.seed.to_string())
            .row("emitter (truth, step 0)", r.emitter.map_or("-".into(), |e| format!("({:.1}, {:.1}) m", e[0], e[1])))
            .row("estimator", format!("{} ({})", r.estimator, r.scenario.emitter_model))
            .row("rejected snapshots", r.rejected_snapshots.to_string())
            .row(
                "safety",
                format!(
                    "{} ({} step(s) without a certified plan)",
                    r.scenario.safety.name(),
                    r.uncertified_steps
                ),
            )
            .row(
                "along the arcs flown",
                format!(
                    "closest pair {} m ({} pair-interval(s) below d_min); closest to the true emitter {} m ({} \
                     UAV-interval(s) inside l_min)",
                    r.min_pair_m.map_or("-".into(), |m| format!("{m:.1}")),
                    r.true_spacing_violations,
                    r.min_true_distance_m.map_or("-".into(), |m| format!("{m:.1}")),
                    r.true_standoff_violations.map_or("-".into(), |v| v.to_string())
                ),
            )
            .row(
                "columns",
                "CRLB at truth (m) | PCRLB (m) | |ẑ − z| (m) | NEES | closest UAV (m) | objective sqrt (m) | plan (ms) | \
                 active constraints",
            );
        for s in &r.steps {
            let active =
                if s.active_constraints.is_empty() { "-".to_string() } else { s.active_constraints.join(", ") };
            t = t.row(
                format!("step {:>3}", s.step),
                format!(
                    "{:>9} | {:>9} | {:>9} | {:>6} | {:>8} | {:>9} | {:>6} | {active}",
                    opt(s.crlb_true_m, 2),
                    opt(s.pcrlb_m, 2),
                    opt(s.estimate_error_m, 1),
                    opt(s.nees, 2),
                    opt(s.min_true_distance_m, 0),
                    opt(s.objective_value, 2),
                    opt(s.plan_ms, 3)
                ),
            );
        }
        for p in &self.written {
            t = t.row("wrote", p.display().to_string());
        }
        t
    }

    fn diagnostics(&self) -> Vec<Diagnostic> {
        let n = self.run.steps.iter().filter(|s| matches!(s.estimate_status.as_str(), "ambiguous" | "failed")).count();
        let mut out = Vec::new();
        if n > 0 {
            out.push(Diagnostic::Warning(format!(
                "{n} step(s) had an ambiguous or failed estimate (see estimate_status)"
            )));
        }
        if self.run.rejected_snapshots > 0 {
            out.push(Diagnostic::Warning(format!(
                "{} snapshot(s) failed the fused estimator's χ² gate and were not fused (estimate_status \"rejected\")",
                self.run.rejected_snapshots
            )));
        }
        out.extend(record::safety_warnings(&self.run).into_iter().map(Diagnostic::Warning));
        out
    }
}
