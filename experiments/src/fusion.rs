//! `uavloc paper fusion` (beyond the paper): what sequential fusion and the standoff chance constraint
//! change. Paired runs (same seeds, hence the same step-0 noise) of the default scenario flown by the
//! waypoint planner (`safety = "waypoints"`, whose chance constraint is compared at c = 0.99 and 0; the
//! certified planner is measured by `uavloc paper safety`), 24 and 60
//! steps, for the paper's method (per-step Chan + analytical criterion) and the fused estimator with the
//! `single`, `analytical`, `posterior` and `posterior-cubature` criteria, each with
//! `standoff_confidence` 0.99 and 0 (the paper's constraint at ẑ).
//!
//! Per row: terminal RMSE of ẑ (`sqrt(mean |ẑ − z|²)` over runs), the PCRLB there
//! (`sqrt(mean tr J⁻¹)`), the time-average of the RMSE curve, the first step from which the RMSE curve
//! stays below 100 m, the closest any UAV came to the TRUE emitter (median over runs of each run's
//! minimum), the runs with at least one (UAV, step) pair inside `L_min` of the truth and the fraction of
//! such pairs; paired differences of the per-run terminal error with CI95 against the paper's method and
//! against fused + single. [`consistency`] is the check of the fused estimator: RMSE / PCRLB and the
//! mean NEES per step against its two-sided 95 % χ² band.

use model::Scenario;
use planning::{ObjectiveKind, SolverKind};
use record::RunRecord;
use serde_json::{Value, json};
use tdoa::dist::mean_chi2_band;
use tdoa::fusion::EstimatorKind;

use crate::batch::{Batch, Engine};
use crate::figures::{Figure, line_series};
use crate::grid::{Grid, cell};
use crate::stats::{median, paired};
use crate::{ExperimentError, ExperimentReport, settings_json};

/// The horizons of the study.
pub const HORIZONS: [usize; 2] = [24, 60];
/// The error level of the "steps until below" column, metres.
pub const BELOW_M: f64 = 100.0;

/// One row of the study: estimator × objective × standoff confidence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Config {
    /// The estimator.
    pub estimator: EstimatorKind,
    /// The planning objective.
    pub objective: ObjectiveKind,
    /// `standoff_confidence`.
    pub confidence: f64,
}

impl Config {
    /// `snapshot + analytical, c = 0.99`-style label.
    pub fn label(&self) -> String {
        let what = if self.estimator == EstimatorKind::Snapshot { "paper: snapshot" } else { "fused" };
        format!("{what} + {}, c = {}", self.objective, self.confidence)
    }

    /// A short legend label: `paper c=0`, `fused analytical c=.99`.
    pub fn short(&self) -> String {
        let c = if self.confidence > 0.0 { "c=.99" } else { "c=0" };
        match self.estimator {
            EstimatorKind::Snapshot => format!("paper {c}"),
            EstimatorKind::Fused => format!("{} {c}", self.objective),
        }
    }

    /// The scenario of this row on `base`.
    pub fn scenario(&self, base: &Scenario, steps: usize) -> Scenario {
        Scenario { estimator: self.estimator, standoff_confidence: self.confidence, steps, ..base.clone() }
    }
}

/// The rows, in order: the paper's method, then fused with each objective; each at c = 0.99 and 0.
pub fn configs() -> Vec<Config> {
    let mut out = Vec::new();
    let rows = [
        (EstimatorKind::Snapshot, ObjectiveKind::Analytical),
        (EstimatorKind::Fused, ObjectiveKind::Single),
        (EstimatorKind::Fused, ObjectiveKind::Analytical),
        (EstimatorKind::Fused, ObjectiveKind::Posterior),
        (EstimatorKind::Fused, ObjectiveKind::PosteriorCubature),
    ];
    for (estimator, objective) in rows {
        for confidence in [0.99, 0.0] {
            out.push(Config { estimator, objective, confidence });
        }
    }
    out
}

/// Per-step consistency of a batch: RMSE of ẑ, PCRLB, mean NEES and its band.
#[derive(Debug, Clone, PartialEq)]
pub struct Consistency {
    /// `sqrt(mean over runs |ẑ_k − z_k|²)`, m.
    pub rmse: Vec<f64>,
    /// `sqrt(mean over runs tr J_k⁻¹)`, m.
    pub pcrlb: Vec<f64>,
    /// Mean NEES over runs.
    pub mean_nees: Vec<f64>,
    /// The two-sided 95 % band of the mean of M χ²₂ variables.
    pub band: (f64, f64),
}

impl Consistency {
    /// RMSE / PCRLB per step.
    pub fn ratio(&self) -> Vec<f64> {
        self.rmse.iter().zip(&self.pcrlb).map(|(r, p)| r / p).collect()
    }

    /// The fraction of steps from `from` on whose mean NEES is inside the band.
    pub fn nees_inside(&self, from: usize) -> f64 {
        let tail = &self.mean_nees[from.min(self.mean_nees.len())..];
        tail.iter().filter(|v| (self.band.0..=self.band.1).contains(*v)).count() as f64 / tail.len().max(1) as f64
    }
}

fn per_step(runs: &[RunRecord], f: impl Fn(&record::StepRecord) -> Option<f64>) -> Vec<f64> {
    let steps = runs.iter().map(|r| r.steps.len()).min().unwrap_or(0);
    (0..steps)
        .map(|k| {
            let v: Vec<f64> = runs.iter().filter_map(|r| f(&r.steps[k])).collect();
            if v.is_empty() { f64::NAN } else { v.iter().sum::<f64>() / v.len() as f64 }
        })
        .collect()
}

/// The consistency of `runs` (records with a truth).
pub fn consistency(runs: &[RunRecord]) -> Consistency {
    let rmse = per_step(runs, |s| s.estimate_error_m.map(|e| e * e)).into_iter().map(f64::sqrt).collect();
    let pcrlb =
        per_step(runs, |s| Some(s.pcrlb_m.map_or(f64::INFINITY, |p| p * p))).into_iter().map(f64::sqrt).collect();
    let mean_nees = per_step(runs, |s| s.nees);
    Consistency { rmse, pcrlb, mean_nees, band: mean_chi2_band(2.0, runs.len(), 0.95) }
}

/// The first step from which `curve` stays below `level` (`None` if it never does).
pub fn settles_below(curve: &[f64], level: f64) -> Option<usize> {
    let last_above = curve.iter().rposition(|v| v.is_nan() || *v >= level);
    match last_above {
        None => Some(0),
        Some(k) if k + 1 < curve.len() => Some(k + 1),
        Some(_) => None,
    }
}

fn terminal_errors(batch: &Batch) -> Vec<f64> {
    batch.runs.iter().map(|r| r.steps.last().and_then(|s| s.estimate_error_m).unwrap_or(f64::NAN)).collect()
}

/// Runs the study.
pub fn run(engine: &Engine) -> Result<ExperimentReport, ExperimentError> {
    // The waypoint planner, whose standoff chance constraint (c = 0.99 vs 0) this study measures; the
    // certified planner is `uavloc paper safety`'s.
    let base = Scenario { safety: model::safety::SafetyMode::Waypoints, ..Scenario::default() };
    let configs = configs();
    let mut rows = Vec::new();
    let mut tables = Vec::new();
    let mut figures = Vec::new();
    let mut conclusions = Vec::new();
    for steps in HORIZONS {
        let mut grid = Grid::new(
            &format!("fusion-{steps}"),
            &format!(
                "{steps} steps: terminal RMSE of ẑ and the PCRLB, mean RMSE over steps, first step the RMSE stays < {BELOW_M} m, \
                 closest approach to the true emitter, runs with a true standoff violation, fraction of (UAV, step) pairs inside L_min"
            ),
            &[
                "row",
                "terminal RMSE (m)",
                "PCRLB (m)",
                "mean RMSE (m)",
                "< 100 m from step",
                "min true distance (m, median)",
                "runs violated",
                "pairs inside (%)",
                "Δ terminal vs paper (m, CI95)",
                "Δ terminal vs fused+single (m, CI95)",
            ],
        );
        let batches: Vec<_> = configs
            .iter()
            .map(|c| engine.batch(&format!("fusion {steps}"), &c.scenario(&base, steps), c.objective, SolverKind::Pso))
            .collect::<Result<_, _>>()?;
        // The paper's method: snapshot + analytical with the constraint at ẑ (row 1).
        let paper_terminal = terminal_errors(&batches[1]);
        let single_terminal = terminal_errors(&batches[2]);
        let mut rmse_series = Vec::new();
        for (c, b) in configs.iter().zip(&batches) {
            let cons = consistency(&b.runs);
            let terminal = terminal_errors(b);
            let terminal_rmse = *cons.rmse.last().unwrap_or(&f64::NAN);
            let terminal_pcrlb = *cons.pcrlb.last().unwrap_or(&f64::NAN);
            let mean_rmse = cons.rmse.iter().sum::<f64>() / cons.rmse.len().max(1) as f64;
            let settle = settles_below(&cons.rmse, BELOW_M);
            let min_dist: Vec<f64> = b
                .runs
                .iter()
                .map(|r| r.steps.iter().filter_map(|s| s.min_true_distance_m).fold(f64::INFINITY, f64::min))
                .collect();
            let violated = b.runs.iter().filter(|r| r.true_standoff_violations.unwrap_or(0) > 0).count();
            let pairs: u64 = b.runs.iter().map(|r| r.true_standoff_violations.unwrap_or(0)).sum();
            let total_pairs: usize = b.runs.iter().map(|r| r.steps.len() * r.scenario.uav_count()).sum();
            let inside_pct = 100.0 * pairs as f64 / total_pairs.max(1) as f64;
            let d_paper = paired(&terminal, &paper_terminal);
            let d_single = paired(&terminal, &single_terminal);
            let ci = |s: &crate::stats::Summary| {
                let [lo, mid, hi] = s.interval();
                format!("{mid:+.1} [{lo:+.1}, {hi:+.1}]")
            };
            grid.push(vec![
                c.label(),
                cell(Some(terminal_rmse), 1),
                cell(Some(terminal_pcrlb), 1),
                cell(Some(mean_rmse), 1),
                settle.map_or("never".into(), |k| k.to_string()),
                cell(Some(median(&min_dist)), 0),
                format!("{violated}/{}", b.runs.len()),
                cell(Some(inside_pct), 3),
                ci(&d_paper),
                ci(&d_single),
            ]);
            rows.push(json!({
                "steps": steps,
                "row": c.label(),
                "estimator": c.estimator.name(),
                "objective": c.objective.name(),
                "standoff_confidence": c.confidence,
                "terminal_rmse_m": terminal_rmse,
                "terminal_pcrlb_m": terminal_pcrlb,
                "mean_rmse_m": mean_rmse,
                "steps_until_below_100m": settle,
                "min_true_distance_m_median": median(&min_dist),
                "min_true_distance_m_min": min_dist.iter().copied().fold(f64::INFINITY, f64::min),
                "runs_with_true_violation": violated,
                "pairs_inside_l_min_fraction": inside_pct / 100.0,
                "rejected_snapshots": b.runs.iter().map(|r| r.rejected_snapshots).sum::<u64>(),
                "diff_terminal_vs_paper_m": d_paper.interval(),
                "diff_terminal_vs_fused_single_m": d_single.interval(),
                "rmse_per_step_m": cons.rmse,
                "pcrlb_per_step_m": cons.pcrlb,
                "mean_nees_per_step": cons.mean_nees,
            }));
            // The paper's method as published (c = 0) and the fused rows at c = 0.99.
            if (c.estimator == EstimatorKind::Snapshot) != (c.confidence > 0.0) {
                let x: Vec<f64> = (0..cons.rmse.len()).map(|k| k as f64).collect();
                rmse_series.push(line_series(&c.short(), x.clone(), cons.rmse.clone()));
                if c.estimator == EstimatorKind::Fused && c.objective == ObjectiveKind::Analytical {
                    rmse_series.push(line_series("PCRLB", x, cons.pcrlb.clone()));
                }
            }
            if steps == HORIZONS[0]
                && c.estimator == EstimatorKind::Fused
                && c.objective == ObjectiveKind::Analytical
                && c.confidence > 0.0
            {
                let cons_note = format!(
                    "Fused + analytical, {steps} steps: RMSE/PCRLB from step 5 in [{:.3}, {:.3}]; mean NEES inside the 95 % band [{:.2}, {:.2}] at {:.0} % of the steps from step 5.",
                    cons.ratio()[5..].iter().copied().fold(f64::INFINITY, f64::min),
                    cons.ratio()[5..].iter().copied().fold(f64::NEG_INFINITY, f64::max),
                    cons.band.0,
                    cons.band.1,
                    100.0 * cons.nees_inside(5)
                );
                conclusions.push(cons_note);
            }
            if c.estimator == EstimatorKind::Fused
                && c.objective == ObjectiveKind::Analytical
                && c.confidence > 0.0
                && let Some(run) = b.runs.first()
            {
                // The UAV paths with the fused estimate's track and 95 % ellipses (first run).
                figures.push(Figure::Trajectories {
                    name: format!("trajectory-fused-{steps}"),
                    run: Box::new(run.clone()),
                });
            }
        }
        let p = &rows[rows.len() - configs.len() + 1];
        let f = &rows[rows.len() - configs.len() + 4];
        conclusions.push(format!(
            "{steps} steps: terminal RMSE {} m with the paper's method, {} m fused + analytical (c = 0.99); PCRLB {} m.",
            cell(p["terminal_rmse_m"].as_f64(), 1),
            cell(f["terminal_rmse_m"].as_f64(), 1),
            cell(f["terminal_pcrlb_m"].as_f64(), 1)
        ));
        figures.push(Figure::Curves {
            name: format!("rmse-{steps}"),
            title: format!("RMSE of ẑ (200 runs) and the PCRLB, {steps} steps"),
            x_label: "step".into(),
            y_label: "m".into(),
            series: rmse_series,
            log_y: true,
        });
        tables.push(grid);
    }
    Ok(ExperimentReport {
        experiment: "fusion".into(),
        title: "sequential fusion, the standoff chance constraint and posterior planning (beyond the paper)".into(),
        settings: settings_json(
            engine,
            &base,
            &[
                ("horizons", json!(HORIZONS)),
                ("rows", Value::Array(configs.iter().map(|c| json!(c.label())).collect())),
            ],
        ),
        rows,
        conclusions,
        tables,
        figures,
        files: Vec::new(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settling_step() {
        assert_eq!(settles_below(&[500.0, 120.0, 90.0, 80.0], 100.0), Some(2));
        assert_eq!(settles_below(&[500.0, 90.0, 120.0, 80.0], 100.0), Some(3));
        assert_eq!(settles_below(&[50.0, 40.0], 100.0), Some(0));
        assert_eq!(settles_below(&[50.0, 400.0], 100.0), None);
    }
}
