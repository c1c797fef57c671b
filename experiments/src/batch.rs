//! Outer Monte Carlo runs (the paper's M = 200): the closed loop run M times for one configuration,
//! in parallel (rayon), each run `m` seeded with `derive_seed(seed, m, OuterRun)`.
//!
//! Reproducibility: a run is a pure function of its scenario and seed, and the runs are collected in
//! run order, so a batch is bit-identical for any thread count. Configurations that share a seed share
//! their runs' seeds, so their differences are **paired** (same measurement noise at step 0, same RMSE
//! resample streams): `stats::paired` on per-run values compares methods run for run.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use model::Scenario;
use planning::{ObjectiveKind, SolverKind};
use rayon::prelude::*;
use record::RunRecord;
use tdoa::rng::{Purpose, derive_seed};

use crate::stats::{Summary, summarize};
use crate::{ExperimentError, Settings};
use closed_loop::run_closed_loop;

/// The per-step metric of a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Metric {
    /// Single-point CRLB `sqrt(tr F⁻¹)` at the TRUE emitter (the paper's displayed CRLB), metres.
    Crlb,
    /// Run-level RMSE of Chan over R noise resamples (paper Section 5.3), metres.
    Rmse,
}

impl Metric {
    /// The value of `step` of a run (NaN when not available).
    fn of(self, s: &record::StepRecord) -> f64 {
        match self {
            Metric::Crlb => s.crlb_true_m.unwrap_or(f64::NAN),
            Metric::Rmse => s.rmse_m.unwrap_or(f64::NAN),
        }
    }
}

/// The M runs of one configuration.
#[derive(Debug, Clone)]
pub struct Batch {
    /// The planning objective.
    pub objective: ObjectiveKind,
    /// The solver.
    pub solver: SolverKind,
    /// The configuration's scenario (its `seed` is the experiment seed, not a run's).
    pub scenario: Scenario,
    /// Run `m` of the batch, `m = 0..M`.
    pub runs: Vec<RunRecord>,
}

impl Batch {
    /// `metric` per run and step: `[run][step]`.
    pub fn matrix(&self, metric: Metric) -> Vec<Vec<f64>> {
        self.runs.iter().map(|r| r.steps.iter().map(|s| metric.of(s)).collect()).collect()
    }

    /// Number of recorded steps per run (planning steps + 1).
    pub fn steps(&self) -> usize {
        self.runs.first().map_or(0, |r| r.steps.len())
    }

    /// The mean curve over runs with its CI95, one summary per step.
    pub fn curve(&self, metric: Metric) -> Vec<Summary> {
        let m = self.matrix(metric);
        (0..self.steps()).map(|k| summarize(&m.iter().map(|r| r[k]).collect::<Vec<_>>())).collect()
    }

    /// The terminal value of `metric`, per run.
    pub fn terminal(&self, metric: Metric) -> Vec<f64> {
        self.matrix(metric).iter().map(|r| r.last().copied().unwrap_or(f64::NAN)).collect()
    }

    /// The time average of `metric` over all recorded steps (0..=T), per run — the paper's "mean" column
    /// (the average of the mean curve over time, when no value is missing).
    pub fn time_average(&self, metric: Metric) -> Vec<f64> {
        self.matrix(metric).iter().map(|r| r.iter().sum::<f64>() / r.len() as f64).collect()
    }

    /// Planning time of every planned step of every run, milliseconds.
    pub fn plan_ms(&self) -> Vec<f64> {
        self.runs.iter().flat_map(|r| r.steps.iter().filter_map(|s| s.plan_ms)).collect()
    }

    /// The `mc` criterion's effective sample size at every planned step of every run (empty otherwise).
    pub fn criterion_ess(&self) -> Vec<f64> {
        self.runs.iter().flat_map(|r| r.steps.iter().filter_map(|s| s.criterion_ess)).collect()
    }

    /// Steps (over all runs) whose estimate was ambiguous or failed.
    pub fn bad_estimates(&self) -> usize {
        self.runs.iter().map(|r| r.steps.iter().filter(|s| s.estimate_status != "ok").count()).sum()
    }

    /// Steps (over all runs) without an RMSE value (every resample failed).
    pub fn missing_rmse(&self) -> usize {
        self.runs.iter().map(|r| r.steps.iter().filter(|s| s.rmse_m.is_none()).count()).sum()
    }
}

/// Runs batches and keeps them, so experiments that share a configuration (Table 2, Table 4, Table 7
/// and the optimizer comparison share the nominal PSO runs) compute it once per invocation.
pub struct Engine {
    settings: Settings,
    cache: Mutex<HashMap<String, Arc<Batch>>>,
    progress: MultiProgress,
}

impl Engine {
    /// An engine for `settings`; progress bars go to stderr when `settings.progress` and stderr is a
    /// terminal.
    pub fn new(settings: Settings) -> Self {
        let target = if settings.progress { ProgressDrawTarget::stderr() } else { ProgressDrawTarget::hidden() };
        Self { settings, cache: Mutex::new(HashMap::new()), progress: MultiProgress::with_draw_target(target) }
    }

    /// The settings.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// `scenario` with the experiment's K and R applied (the seed is set per run).
    pub fn configure(&self, scenario: &Scenario) -> Scenario {
        let mut sc = scenario.clone();
        sc.mc_samples = self.settings.samples;
        sc.rmse_resamples = self.settings.resamples;
        sc.seed = self.settings.seed;
        sc
    }

    /// A progress bar of `len` units labelled `label` (hidden when progress is off).
    pub fn bar(&self, len: u64, label: &str) -> ProgressBar {
        let bar = self.progress.add(ProgressBar::new(len));
        let style =
            ProgressStyle::with_template("{prefix:>34} [{bar:30}] {pos:>4}/{len} {msg} elapsed {elapsed}, ETA {eta}")
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> ");
        bar.set_style(style);
        bar.set_prefix(label.to_string());
        bar.enable_steady_tick(Duration::from_millis(250));
        bar
    }

    /// The M runs of (`scenario` with K and R applied, `objective`, `solver`), computed once.
    pub fn batch(
        &self,
        label: &str,
        scenario: &Scenario,
        objective: ObjectiveKind,
        solver: SolverKind,
    ) -> Result<Arc<Batch>, ExperimentError> {
        let sc = self.configure(scenario);
        // Formation ignores the solver: one batch serves every solver.
        let solver = if objective.is_optimised() { solver } else { SolverKind::Pso };
        let key = format!("{}|{}|{}", serde_json::to_string(&sc).unwrap_or_default(), objective.name(), solver.name());
        if let Some(b) = self.cache.lock().map_err(|_| ExperimentError::Poisoned)?.get(&key) {
            return Ok(Arc::clone(b));
        }
        let bar = self.bar(self.settings.runs as u64, &format!("{label} {}/{}", objective.name(), solver.name()));
        bar.set_message("runs");
        let runs: Result<Vec<RunRecord>, ExperimentError> = (0..self.settings.runs)
            .into_par_iter()
            .map(|m| {
                let mut run_sc = sc.clone();
                run_sc.seed = derive_seed(self.settings.seed, m as u64, Purpose::OuterRun);
                let run = run_closed_loop(&run_sc, objective, solver, |_, _| {}).map_err(|e| ExperimentError::Run {
                    config: format!("{label} {}/{}", objective.name(), solver.name()),
                    run: m,
                    source: e,
                });
                bar.inc(1);
                run
            })
            .collect();
        bar.finish_and_clear();
        self.progress.remove(&bar);
        let batch = Arc::new(Batch { objective, solver, scenario: sc, runs: runs? });
        self.cache.lock().map_err(|_| ExperimentError::Poisoned)?.insert(key, Arc::clone(&batch));
        Ok(batch)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn engine(runs: usize) -> Engine {
        Engine::new(Settings { runs, fixed_runs: runs, ..Settings::default() })
    }

    fn short() -> Scenario {
        Scenario { steps: 3, ..Scenario::default() }
    }

    #[test]
    fn a_batch_does_not_depend_on_the_thread_count() {
        let in_pool = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mut runs = pool
                .install(|| engine(5).batch("t", &short(), ObjectiveKind::Mc, SolverKind::Pso).unwrap().runs.clone());
            // Everything but the wall-clock planning time.
            runs.iter_mut().flat_map(|r| r.steps.iter_mut()).for_each(|s| s.plan_ms = s.plan_ms.map(|_| 0.0));
            runs
        };
        let one = in_pool(1);
        assert_eq!(one.len(), 5);
        assert_eq!(one, in_pool(2));
        assert_eq!(one, in_pool(3));
        // Runs differ from each other (their seeds do).
        assert_ne!(one[0].steps[0].estimate, one[1].steps[0].estimate);
    }

    #[test]
    fn configurations_share_run_seeds_so_differences_are_paired() {
        let e = engine(3);
        let a = e.batch("t", &short(), ObjectiveKind::Single, SolverKind::Pso).unwrap();
        let b = e.batch("t", &short(), ObjectiveKind::Analytical, SolverKind::Ga).unwrap();
        for (x, y) in a.runs.iter().zip(&b.runs) {
            assert_eq!(x.seed, y.seed);
            // Same measurement noise at step 0, before any plan differs.
            assert_eq!(x.steps[0].estimate, y.steps[0].estimate);
            assert_eq!(x.steps[0].rmse_m, y.steps[0].rmse_m);
        }
        // The experiment's K and R are applied.
        assert_eq!(a.scenario.mc_samples, 200);
        assert_eq!(a.runs[0].scenario.rmse_resamples, 30);
    }

    #[test]
    fn batches_are_computed_once_and_formation_ignores_the_solver() {
        let e = engine(2);
        let a = e.batch("t", &short(), ObjectiveKind::Formation, SolverKind::Pso).unwrap();
        let b = e.batch("other label", &short(), ObjectiveKind::Formation, SolverKind::Aco).unwrap();
        assert!(Arc::ptr_eq(&a, &b));
        let c = e.batch("t", &Scenario { steps: 2, ..Scenario::default() }, ObjectiveKind::Formation, SolverKind::Pso);
        assert!(!Arc::ptr_eq(&a, &c.unwrap()));
    }

    #[test]
    fn curves_and_per_run_values() {
        let b = engine(4).batch("t", &short(), ObjectiveKind::Analytical, SolverKind::Pso).unwrap();
        assert_eq!(b.steps(), 4);
        let m = b.matrix(Metric::Crlb);
        let curve = b.curve(Metric::Crlb);
        for k in 0..4 {
            let mean = m.iter().map(|r| r[k]).sum::<f64>() / 4.0;
            assert!((curve[k].mean - mean).abs() < 1e-9 * mean);
        }
        // Step 0 is the same initial geometry in every run: the CRLB at the truth is 1655.58 m, CI 0.
        assert!((curve[0].mean - 1655.58).abs() < 0.01 && curve[0].ci95.abs() < 1e-9);
        let terminal = b.terminal(Metric::Crlb);
        assert_eq!(terminal, m.iter().map(|r| r[3]).collect::<Vec<_>>());
        let avg = b.time_average(Metric::Rmse);
        assert!(avg.iter().all(|v| v.is_finite() && *v > 0.0));
        assert_eq!(b.plan_ms().len(), 4 * 3, "3 planned steps per run");
        assert!(b.criterion_ess().is_empty(), "ESS only for mc");
    }
}
