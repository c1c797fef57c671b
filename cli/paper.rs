//! `uavloc paper <experiment>`: the paper's Section 5 experiments (Tables 2–10, Figures 4–17) with our
//! numbers beside the paper's; see the `experiments` crate.

use std::path::PathBuf;

use clap::Args;
use experiments::{ExperimentKind, ExperimentReport, QUICK_RUNS, Settings};
use serde::ser::{Serialize, SerializeMap, Serializer};

use crate::error::CliError;
use crate::output::{Report, Table};

pub const LONG_ABOUT: &str = "\
Reproduce the numerical experiments of the paper (Sensors 2026, 26, 5393, Section 5): every table in
the paper's layout with our numbers, the paper's own numbers and the difference (ours − paper), the
conclusions they support — including whether the paper's central claim (uncertainty-aware planning
beats single-point planning by about 7 %) holds — and, with --out, Markdown/CSV tables and SVG/PNG
figures.

Experiments:
  table2       single-point vs MC vs analytical planning (and the fixed formation): mean and terminal
               CRLB at the truth and RMSE with CI95, paired differences to single-point (Figures 4–6)
  table4       analytical vs MC planning, relative differences; both criteria vs the exact quadrature
  table5       uncertainty-scale sweep 0.25–1.0: accuracy and MC/analytical time ratio (Figure 10)
  table6       robustness to planner-side target error, scales 0–1.0 (Figure 11)
  table7       time of the objectives inside the planner (Figure 12)
  table8       3-, 4-, 5-node fixed geometries: evaluation cost, FIM condition, RMSE (Figure 13)
  table9       3-, 4-, 5-node fixed geometries, noise scales 0.5–2.0: CRLB, RMSE, RMSE/CRLB (Figs 14–16)
  table10      initial-geometry sensitivity (Figure 17)
  optimizers   PSO / GA / ACO × formation / single / MC / analytical (Figures 7–8)
  sensitivity  the table2 comparison over the settings the paper does not state (heading cone Δα,
               planner-side error, σ_t, MC sampling scheme), with the MC criterion's effective sample size
  fusion       beyond the paper: sequential fusion vs the paper's per-step Chan, the standoff chance
               constraint (standoff_confidence 0.99 vs 0) and the posterior criteria, 24 and 60 steps:
               terminal RMSE vs PCRLB, steps until < 100 m, closest approach to the TRUE emitter, true
               L_min violations, paired differences (not part of `all`)
  safety       beyond the paper: the certified planner (safety = \"certified\") against the waypoint
               planner on M random scenarios (3–8 UAVs, L_min 1–8 km, D_min 200–1000 m, R_min
               500–2000 m, 30–80 m/s, every other emitter moving), 120 steps each: pair approaches
               below D_min and UAV-steps inside L_min of the TRUE emitter along the arcs flown, steps
               without a certified plan (listed), terminal error and error/PCRLB (not part of `all`)
  receiver     beyond the paper: the estimator on bursts as a real receiver gives them — arrivals lost
               (0.1, 0.3), a silent emitter (0.3), multipath outliers (0.05, 0.15 per arrival, 200–1000 m
               late), GNSS (5, 20 m) and clock (10, 30 ns) errors, per step and per flight — for 3 and 5
               UAVs, beside a receiver-blind estimator on the same runs: RMSE / PCRLB of the arrivals
               received, NEES (and of the same paths flown open loop), outliers identified, steps
               commanded (not part of `all`)
  all          everything above but fusion, safety and receiver, sharing runs

Defaults are the paper's: M = 200 outer runs, R = 30 inner TDOA-noise resamples per RMSE point, K = 200
MC target samples, PSO 40 × 15, the nominal scenario of Table 1 (scenarios/nominal.toml). Settings the
paper does not state (horizon 24 steps, Δα = 25°, L_min, D_min, R_min, σ_t, e0, the 4-/5-node and the
alternative 3-UAV geometries) are the scenario's documented choices; every report lists them under
settings.chosen_not_stated_by_paper.

Outer runs run in parallel on all cores and are reproducible for a --seed regardless of the thread
count (RAYON_NUM_THREADS limits the threads). A progress bar with an ETA is shown on a terminal.
Units: metres, seconds, percent.";

pub const AFTER_HELP: &str = "\
Examples:
  uavloc paper table2
  uavloc paper all --quick
  uavloc paper table6 --runs 50 --json
  uavloc paper safety --runs 200 --out results/safety/
  uavloc paper receiver --quick --out results/receiver/
  uavloc paper all --out results/      # Markdown + CSV per table, SVG + PNG per figure

JSON (--json): {\"experiment\", \"title\", \"settings\", \"rows\", \"conclusions\"}; for `all`,
{\"experiment\": \"all\", \"settings\", \"experiments\": [..one such object per experiment..]}.
table2 rows: {\"method\", \"mean_crlb_m\", \"final_crlb_m\", \"ci95_crlb_m\", \"mean_rmse_m\", \"final_rmse_m\",
\"ci95_rmse_m\", \"diff_vs_single\": {\"final_crlb_m\": [lo, mid, hi], ..}, \"paper\": {..}}.
Timing: `all` with the defaults takes a few minutes on 2 cores; --quick (M = 20) well under one.";

/// Flags of `uavloc paper`.
#[derive(Args, Debug, Clone, PartialEq)]
pub struct PaperArgs {
    /// Which experiment: table2 | table4 | table5 | table6 | table7 | table8 | table9 | table10 |
    /// optimizers | sensitivity | fusion | safety | receiver | all.
    pub experiment: ExperimentKind,
    /// Outer Monte Carlo runs M (default 200, the paper's; 20 with --quick).
    #[arg(long, value_name = "M")]
    pub runs: Option<usize>,
    /// Inner TDOA-noise resamples R per RMSE point.
    #[arg(long, value_name = "R", default_value_t = 30)]
    pub resamples: usize,
    /// Target-position samples K of the MC global CRLB.
    #[arg(long, value_name = "K", default_value_t = 200)]
    pub samples: usize,
    /// Experiment seed (outer run m uses a stream derived from it and m).
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub seed: u64,
    /// The quick preset: M = 20 outer runs of the closed-loop experiments (unless --runs is given); the
    /// fixed-geometry tables 8 and 9 (milliseconds per run) keep M = 200.
    #[arg(long)]
    pub quick: bool,
    /// Directory for `<experiment>.md`, one CSV per table and every figure as SVG and PNG (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

/// What `uavloc paper` prints: one experiment, or all of them.
#[derive(Debug, Clone)]
pub struct PaperReport {
    /// `all` or the single experiment's name.
    pub experiment: ExperimentKind,
    /// The settings.
    pub settings: Settings,
    /// The reports, in run order.
    pub reports: Vec<ExperimentReport>,
}

impl Serialize for PaperReport {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match (self.experiment, self.reports.as_slice()) {
            (ExperimentKind::All, _) | (_, []) | (_, [_, _, ..]) => {
                let mut m = s.serialize_map(Some(3))?;
                m.serialize_entry("experiment", self.experiment.name())?;
                m.serialize_entry("settings", &self.settings)?;
                m.serialize_entry("experiments", &self.reports)?;
                m.end()
            }
            (_, [one]) => one.serialize(s),
        }
    }
}

/// Runs `uavloc paper`.
pub fn run(args: &PaperArgs) -> Result<PaperReport, CliError> {
    // Checked first: `paper all` runs for a long time, and its tables are written only at the end.
    if let Some(dir) = &args.out {
        runtime::output::check_out_dir("--out", dir).map_err(CliError::Input)?;
    }
    use model::scenario::MAX_COUNT;
    if let Some(runs) = args.runs {
        crate::args::require_count("--runs", runs, 1, MAX_COUNT)?;
    }
    crate::args::require_count("--resamples", args.resamples, 1, MAX_COUNT)?;
    crate::args::require_count("--samples", args.samples, 2, MAX_COUNT)?;
    let settings = Settings {
        runs: args.runs.unwrap_or(if args.quick { QUICK_RUNS } else { experiments::PAPER_RUNS }),
        fixed_runs: args.runs.unwrap_or(experiments::PAPER_RUNS),
        resamples: args.resamples,
        samples: args.samples,
        seed: args.seed,
        quick: args.quick,
        progress: true,
    };
    let mut reports = args.experiment.run(&settings).map_err(|e| match e {
        experiments::ExperimentError::Input(m) => CliError::Input(m),
        other => CliError::failed_because("uavloc paper", other),
    })?;
    if let Some(dir) = &args.out {
        for r in &mut reports {
            r.write(dir).map_err(|e| CliError::failed_because("--out", e))?;
        }
    }
    Ok(PaperReport { experiment: args.experiment, settings, reports })
}

impl Report for PaperReport {
    fn table(&self) -> Table {
        Table::new()
    }

    fn text(&self) -> String {
        let mut out = format!(
            "uavloc paper {} — M = {} outer runs, R = {} resamples, K = {} MC samples, seed {}{}\n\n",
            self.experiment,
            self.settings.runs,
            self.settings.resamples,
            self.settings.samples,
            self.settings.seed,
            if self.settings.quick { " (--quick)" } else { "" }
        );
        for r in &self.reports {
            out.push_str(&r.text());
            for f in &r.files {
                out.push_str(&format!("wrote {}\n", f.display()));
            }
            out.push('\n');
        }
        out
    }
}
