//! # uavloc-experiments — the paper's Section 5, reproduced
//!
//! Every table and figure of the paper's numerical results (Sensors 2026, 26, 5393, Tables 2–10,
//! Figures 4–17) as a function of a few [`Settings`] (M outer runs, R inner resamples, K MC samples,
//! the seed), over the same in-process closed loop as `uavloc simulate` (crate `uavloc-closed-loop`). No IPC.
//!
//! Each experiment returns an [`ExperimentReport`]: the settings it used (stated by the paper or our
//! documented choice), one JSON row per method with the paper's columns as snake_case keys with units,
//! the tables in the paper's layout with the paper's own numbers and the difference beside ours, the
//! conclusions measured (whatever they are), and its figures. Nothing here is tuned toward the
//! paper's numbers: a setting the paper does not state keeps the scenario's documented value, and a
//! sweep over those settings is its own experiment ([`sensitivity`]).
//!
//! Outer runs are parallel ([`batch`]) and reproducible for a seed regardless of the thread count.

pub mod batch;
pub mod figures;
pub mod fixed_geometry;
pub mod fusion;
pub mod grid;
pub mod optimizers;
pub mod paper;
pub mod receiver;
pub mod safety;
pub mod sensitivity;
pub mod stats;
pub mod table10;
pub mod table2;
pub mod table4;
pub mod table5;
pub mod table6;
pub mod table7;

use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use model::Scenario;
use serde::Serialize;
use serde_json::{Map, Value, json};
use thiserror::Error;

pub use batch::{Batch, Engine, Metric};
pub use figures::Figure;
pub use grid::Grid;

/// The paper's outer Monte Carlo runs M (Section 5.1).
pub const PAPER_RUNS: usize = 200;
/// The `--quick` preset's M.
pub const QUICK_RUNS: usize = 20;

/// Why an experiment could not finish.
#[derive(Debug, Error)]
pub enum ExperimentError {
    /// A flag or setting is out of range.
    #[error("{0}")]
    Input(String),
    /// One outer run of one configuration failed.
    #[error("{config}, outer run {run}: {source}")]
    Run {
        /// The configuration (experiment, objective, solver).
        config: String,
        /// The outer run.
        run: usize,
        /// Why the closed loop stopped.
        #[source]
        source: closed_loop::LoopError,
    },
    /// A worker thread panicked while holding the batch cache.
    #[error("internal error: the batch cache was poisoned by a panicking worker")]
    Poisoned,
    /// Writing `--out` failed.
    #[error("{}: {source}", path.display())]
    Write {
        /// The file or directory.
        path: PathBuf,
        /// Why it could not be written.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
}

/// The knobs of every experiment.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Settings {
    /// Outer Monte Carlo runs M of the closed-loop experiments (paper: 200).
    pub runs: usize,
    /// Outer runs M of the fixed-geometry tables 8 and 9 (no planning, milliseconds per run): M, except
    /// under `--quick` without `--runs`, where they keep the paper's 200 (their RMSE/CRLB check needs
    /// the M·R = 6000 draws; 600 leave the 3-node heavy tail too noisy).
    pub fixed_runs: usize,
    /// Inner TDOA-noise resamples R per RMSE point (paper: 30).
    pub resamples: usize,
    /// Target-position samples K of the MC global CRLB (paper: 200).
    pub samples: usize,
    /// Experiment seed; run m uses `derive_seed(seed, m, OuterRun)`.
    pub seed: u64,
    /// Whether the `--quick` preset (M = 20) is in use.
    pub quick: bool,
    /// Show progress bars on stderr.
    #[serde(skip)]
    pub progress: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            runs: PAPER_RUNS,
            fixed_runs: PAPER_RUNS,
            resamples: 30,
            samples: 200,
            seed: 1,
            quick: false,
            progress: false,
        }
    }
}

impl Settings {
    /// Checks the ranges: M ≥ 2 (a CI needs two runs), R ≥ 1, K ≥ 2.
    pub fn validate(&self) -> Result<(), ExperimentError> {
        if self.runs < 2 || self.fixed_runs < 2 {
            return Err(ExperimentError::Input(format!(
                "--runs must be at least 2 (a CI95 needs two runs), got {}",
                self.runs.min(self.fixed_runs)
            )));
        }
        if self.resamples < 1 {
            return Err(ExperimentError::Input("--resamples must be at least 1".into()));
        }
        if self.samples < 2 {
            return Err(ExperimentError::Input(format!("--samples must be at least 2, got {}", self.samples)));
        }
        Ok(())
    }
}

/// The experiments of `uavloc paper`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ExperimentKind {
    Table2,
    Table4,
    Table5,
    Table6,
    Table7,
    Table8,
    Table9,
    Table10,
    Optimizers,
    Sensitivity,
    Fusion,
    Safety,
    Receiver,
    All,
}

impl ExperimentKind {
    /// Every single experiment, in the order `all` runs them.
    pub const EACH: [ExperimentKind; 10] = [
        ExperimentKind::Table2,
        ExperimentKind::Table4,
        ExperimentKind::Table5,
        ExperimentKind::Table6,
        ExperimentKind::Table7,
        ExperimentKind::Table8,
        ExperimentKind::Table9,
        ExperimentKind::Table10,
        ExperimentKind::Optimizers,
        ExperimentKind::Sensitivity,
    ];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            ExperimentKind::Table2 => "table2",
            ExperimentKind::Table4 => "table4",
            ExperimentKind::Table5 => "table5",
            ExperimentKind::Table6 => "table6",
            ExperimentKind::Table7 => "table7",
            ExperimentKind::Table8 => "table8",
            ExperimentKind::Table9 => "table9",
            ExperimentKind::Table10 => "table10",
            ExperimentKind::Optimizers => "optimizers",
            ExperimentKind::Sensitivity => "sensitivity",
            ExperimentKind::Fusion => "fusion",
            ExperimentKind::Safety => "safety",
            ExperimentKind::Receiver => "receiver",
            ExperimentKind::All => "all",
        }
    }

    /// Runs this single experiment (not `all`).
    fn run_one(self, engine: &Engine) -> Result<ExperimentReport, ExperimentError> {
        match self {
            ExperimentKind::Table2 => table2::run(engine),
            ExperimentKind::Table4 => table4::run(engine),
            ExperimentKind::Table5 => table5::run(engine),
            ExperimentKind::Table6 => table6::run(engine),
            ExperimentKind::Table7 => table7::run(engine),
            ExperimentKind::Table8 => fixed_geometry::run_table8(engine),
            ExperimentKind::Table9 => fixed_geometry::run_table9(engine),
            ExperimentKind::Table10 => table10::run(engine),
            ExperimentKind::Optimizers => optimizers::run(engine),
            ExperimentKind::Sensitivity => sensitivity::run(engine),
            ExperimentKind::Fusion => fusion::run(engine),
            ExperimentKind::Safety => safety::run(engine),
            ExperimentKind::Receiver => receiver::run(engine),
            ExperimentKind::All => Err(ExperimentError::Input("`all` is not a single experiment".into())),
        }
    }

    /// Runs the experiment(s): one report, or every report for `all` (sharing their runs).
    pub fn run(self, settings: &Settings) -> Result<Vec<ExperimentReport>, ExperimentError> {
        settings.validate()?;
        let engine = Engine::new(settings.clone());
        match self {
            ExperimentKind::All => {
                let overall = engine.bar(Self::EACH.len() as u64, "uavloc paper all");
                let mut reports = Vec::new();
                for kind in Self::EACH {
                    overall.set_message(kind.name());
                    reports.push(kind.run_one(&engine)?);
                    overall.inc(1);
                }
                overall.finish_and_clear();
                Ok(reports)
            }
            kind => Ok(vec![kind.run_one(&engine)?]),
        }
    }
}

impl fmt::Display for ExperimentKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for ExperimentKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::EACH.into_iter().chain([Self::Fusion, Self::Safety, Self::Receiver, Self::All]).find(|k| k.name() == s).ok_or_else(|| {
            format!(
                "unknown experiment '{s}' (expected one of: table2, table4, table5, table6, table7, table8, table9, \
                 table10, optimizers, sensitivity, fusion, safety, receiver, all)"
            )
        })
    }
}

/// What one experiment measured.
#[derive(Debug, Clone, Serialize)]
pub struct ExperimentReport {
    /// The experiment's name (`table2`, …).
    pub experiment: String,
    /// What it reproduces.
    pub title: String,
    /// Every parameter used, stated by the paper or our choice (`chosen_not_stated_by_paper` lists ours).
    pub settings: Map<String, Value>,
    /// One row per method (or per case), the paper's columns as snake_case keys with units, the paper's
    /// own numbers under `paper`.
    pub rows: Vec<Value>,
    /// What the numbers say, in sentences (including whether the paper's claims hold).
    pub conclusions: Vec<String>,
    /// The tables in the paper's layout.
    #[serde(skip)]
    pub tables: Vec<Grid>,
    /// The figures.
    #[serde(skip)]
    pub figures: Vec<Figure>,
    /// Files written by `--out`.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub files: Vec<PathBuf>,
}

impl ExperimentReport {
    /// The report as terminal text: title, tables, conclusions.
    pub fn text(&self) -> String {
        let mut out = format!("== {}: {}\n\n", self.experiment, self.title);
        for t in &self.tables {
            out.push_str(&t.text());
            out.push('\n');
        }
        for c in &self.conclusions {
            out.push_str(&format!("* {c}\n"));
        }
        out
    }

    /// The report as Markdown (for EXPERIMENTS.md and `--out`).
    pub fn markdown(&self) -> String {
        let mut out = format!("## {}: {}\n\n", self.experiment, self.title);
        for t in &self.tables {
            out.push_str(&t.markdown());
            out.push('\n');
        }
        for c in &self.conclusions {
            out.push_str(&format!("- {c}\n"));
        }
        out.push_str(&format!("\nSettings: `{}`\n", serde_json::to_string(&self.settings).unwrap_or_default()));
        out
    }

    /// Writes `<experiment>.md`, one CSV per table (`<table name>.csv`) and every figure as SVG and PNG
    /// into `dir` (created if missing); records the paths in `files`.
    pub fn write(&mut self, dir: &Path) -> Result<(), ExperimentError> {
        fn werr(path: &Path, e: impl Into<Box<dyn std::error::Error + Send + Sync>>) -> ExperimentError {
            ExperimentError::Write { path: path.to_path_buf(), source: e.into() }
        }
        std::fs::create_dir_all(dir).map_err(|e| werr(dir, e))?;
        let mut files = Vec::new();
        let md = dir.join(format!("{}.md", self.experiment));
        std::fs::write(&md, self.markdown()).map_err(|e| werr(&md, e))?;
        files.push(md);
        for t in &self.tables {
            let csv = dir.join(format!("{}.csv", t.name));
            std::fs::write(&csv, t.csv()).map_err(|e| werr(&csv, e))?;
            files.push(csv);
        }
        for f in &self.figures {
            for ext in ["svg", "png"] {
                let path = dir.join(format!("{}-{}.{ext}", self.experiment, f.name()));
                f.draw(&path).map_err(|e| werr(&path, e))?;
                files.push(path);
            }
        }
        self.files = files;
        Ok(())
    }
}

/// The settings block of a report: M, R, K, seed, the scenario as used (angles in degrees), `extra`
/// experiment-specific entries, and which of them the paper does not state.
pub fn settings_json(engine: &Engine, scenario: &Scenario, extra: &[(&str, Value)]) -> Map<String, Value> {
    let s = engine.settings();
    let mut m = Map::new();
    m.insert("runs_m".into(), json!(s.runs));
    m.insert("fixed_geometry_runs_m".into(), json!(s.fixed_runs));
    m.insert("resamples_r".into(), json!(s.resamples));
    m.insert("mc_samples_k".into(), json!(s.samples));
    m.insert("seed".into(), json!(s.seed));
    m.insert("quick".into(), json!(s.quick));
    m.insert("threads".into(), json!(rayon::current_num_threads()));
    m.insert("scenario".into(), serde_json::to_value(engine.configure(scenario)).unwrap_or(Value::Null));
    for (k, v) in extra {
        m.insert((*k).to_string(), v.clone());
    }
    m.insert(
        "chosen_not_stated_by_paper".into(),
        json!([
            "scenario.steps (horizon)",
            "scenario.delta_alpha_deg",
            "scenario.l_min",
            "scenario.d_min",
            "scenario.r_min",
            "scenario.sigma (range noise, reproduces the paper's initial CRLB 1655.58 m)",
            "scenario.sigma_t and scenario.e0 (controlled planner-side error)",
            "scenario.kappa (support side, eq. 36)",
            "initial headings (straight at the emitter)",
            "scenario.early_stop.tolerance",
            "solver details beyond Table 3 (see scenarios/nominal.toml)",
            "4- and 5-node and alternative 3-UAV geometries (table8/9/10)"
        ]),
    );
    m
}
