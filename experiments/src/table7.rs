//! Table 7 (Figure 12): the cost of each objective inside the planner. A serial timing pass (no other
//! run in parallel, so the figures are not inflated by the outer-run parallelism) of the first
//! [`TIMING_RUNS`] runs of Table 2's seeds per method: per planning step, the time of the displayed
//! CRLB (`tr F⁻¹` at the truth), the PSO optimisation (the whole `plan_step`), and their total (mean and
//! max over steps), in seconds.

use model::Scenario;
use planning::{ObjectiveKind, SolverKind};
use serde_json::{Value, json};
use tdoa::rng::{Purpose, derive_seed};
use tdoa::{Sensors, crlb};

use crate::batch::Engine;
use crate::figures::{Figure, value_group};
use crate::grid::{Grid, cell};
use crate::stats::{median, median_seconds_per_call};
use crate::{ExperimentError, ExperimentReport, paper, settings_json};
use closed_loop::run_closed_loop;

/// Runs timed per method.
pub const TIMING_RUNS: usize = 5;
/// The methods timed.
pub const METHODS: [ObjectiveKind; 3] = [ObjectiveKind::Single, ObjectiveKind::Mc, ObjectiveKind::Analytical];

/// Per-step timings of one method: (CRLB s, optimisation s) per planned step.
fn timings(engine: &Engine, sc: &Scenario, method: ObjectiveKind) -> Result<Vec<(f64, f64)>, ExperimentError> {
    let base = engine.configure(sc);
    let truth = base.emitter_position();
    let noise = base.noise_model().map_err(|e| ExperimentError::Input(e.to_string()))?;
    let mut out = Vec::new();
    for m in 0..TIMING_RUNS.min(engine.settings().runs) {
        let mut run_sc = base.clone();
        run_sc.seed = derive_seed(engine.settings().seed, m as u64, Purpose::OuterRun);
        let run = run_closed_loop(&run_sc, method, SolverKind::Pso, |_, _| {}).map_err(|e| ExperimentError::Run {
            config: format!("table7 {}", method.name()),
            run: m,
            source: e,
        })?;
        for s in run.steps.iter().filter(|s| s.plan_ms.is_some()) {
            let Ok(sensors) = Sensors::new(&s.uavs, noise.clone()) else { continue };
            let crlb_s = median_seconds_per_call(100, || {
                std::hint::black_box(crlb(std::hint::black_box(&sensors), &truth).ok());
            });
            out.push((crlb_s, s.plan_ms.unwrap_or(f64::NAN) / 1e3));
        }
    }
    Ok(out)
}

/// Runs Table 7.
pub fn run(engine: &Engine) -> Result<ExperimentReport, ExperimentError> {
    let sc = Scenario::paper();
    let bar = engine.bar(METHODS.len() as u64, "table7 serial timing");
    let mut grid = Grid::new(
        "table7",
        "Table 7 — time per planning step (s): displayed CRLB, PSO optimisation, total mean and max; Δ = ours / paper (×)",
        &["Method", "source", "CRLB time", "Opt. time", "Total mean", "Total max", "median total"],
    );
    let mut rows = Vec::new();
    let mut totals = Vec::new();
    for m in METHODS {
        let t = timings(engine, &sc, m)?;
        bar.inc(1);
        let n = t.len().max(1) as f64;
        let crlb_mean = t.iter().map(|x| x.0).sum::<f64>() / n;
        let opt_mean = t.iter().map(|x| x.1).sum::<f64>() / n;
        let total: Vec<f64> = t.iter().map(|x| x.0 + x.1).collect();
        let total_mean = total.iter().sum::<f64>() / n;
        let total_max = total.iter().fold(0.0f64, |a, b| a.max(*b));
        let total_median = median(&total);
        let p = paper::row(&paper::TABLE7, m.name());
        let ours = [crlb_mean, opt_mean, total_mean, total_max];
        grid.compare_sig(m.name(), &ours, p.as_ref().map(|r| &r[..]));
        if let Some(last) = grid.rows.iter_mut().rev().find(|r| r[1] == "ours") {
            last[6] = crate::grid::sig(total_median);
        }
        totals.push((m, total_mean, total_median));
        rows.push(json!({
            "method": m.name(),
            "crlb_time_s": crlb_mean,
            "opt_time_s": opt_mean,
            "total_mean_s": total_mean,
            "total_max_s": total_max,
            "total_median_s": total_median,
            "steps_timed": t.len(),
            "paper": p.map_or(Value::Null, |p| json!({"crlb_time_s": p[0], "opt_time_s": p[1], "total_mean_s": p[2], "total_max_s": p[3]})),
        }));
    }
    bar.finish_and_clear();
    let (mc, an) = (totals[1].1, totals[2].1);
    let conclusions = vec![
        format!(
            "Analytical planning takes {} % less time per step than MC planning ({}× faster; paper: 87.14 %, 7.78×); single-point is the fastest ({} s per step).",
            cell(Some((mc - an) / mc * 100.0), 2),
            cell(Some(mc / an), 2),
            cell(Some(totals[0].1), 6)
        ),
        "Times are wall-clock on this machine (Rust, release build, one thread); the paper's are MATLAB R2024a, so only the ratios compare.".to_string(),
    ];
    let figures = vec![Figure::Bars {
        name: "timing".into(),
        title: "Time per planning step, mean (Figure 12, log scale)".into(),
        y_label: "seconds per step".into(),
        series: vec!["ours".into(), "paper".into()],
        groups: totals
            .iter()
            .map(|(m, mean, _)| {
                value_group(m.name(), &[*mean, paper::row(&paper::TABLE7, m.name()).map_or(f64::NAN, |p| p[2])])
            })
            .collect(),
        log_y: true,
    }];
    Ok(ExperimentReport {
        experiment: "table7".into(),
        title: "timing of the objectives inside the PSO planner (paper Table 7, Figure 12)".into(),
        settings: settings_json(
            engine,
            &sc,
            &[
                ("timing_runs", json!(TIMING_RUNS.min(engine.settings().runs))),
                ("solver", json!("pso")),
                ("threads_while_timing", json!(1)),
            ],
        ),
        rows,
        conclusions,
        tables: vec![grid],
        figures,
        files: Vec::new(),
    })
}
