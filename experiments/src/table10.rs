//! Table 10 (Figure 17): sensitivity to the initial three-UAV geometry. Per geometry: the initial FIM
//! condition number and CRLB at the truth, the analytical planner's terminal CRLB and RMSE, its terminal
//! CRLB relative to MC planning's, and its speed-up over MC (median planning time per step). The
//! paper's alternative geometries are not given: ours are a wide-baseline triangle that surrounds more
//! of the emitter's bearings, and a moderate asymmetric perturbation of the nominal one.

use model::Scenario;
use planning::{ObjectiveKind, SolverKind};
use serde_json::{Value, json};
use tdoa::{Sensors, crlb};

use crate::batch::{Engine, Metric};
use crate::figures::{Figure, value_group};
use crate::grid::{Grid, cell};
use crate::stats::{median, rel_pct, summarize};
use crate::{ExperimentError, ExperimentReport, paper, settings_json};

/// (name, UAV positions in metres) of the three initial geometries.
pub fn geometries() -> [(&'static str, Vec<[f64; 2]>); 3] {
    [
        ("nominal", vec![[1500.0, 500.0], [10000.0, 1500.0], [5000.0, 8500.0]]),
        ("favorable_wide_baseline", vec![[1500.0, 500.0], [24000.0, 1000.0], [6000.0, 22000.0]]),
        ("moderately_asymmetric", vec![[1500.0, 500.0], [12000.0, 2500.0], [4000.0, 10000.0]]),
    ]
}

/// Runs Table 10.
pub fn run(engine: &Engine) -> Result<ExperimentReport, ExperimentError> {
    let mut grid = Grid::new(
        "table10",
        "Table 10 — initial geometry: FIM cond., initial CRLB, analytical final CRLB/RMSE (m), analytical vs MC final CRLB (%), speed-up; Δ = ours − paper",
        &[
            "Geometry",
            "source",
            "Initial FIM cond.",
            "Initial CRLB",
            "Final CRLB",
            "Final RMSE",
            "vs MC (%)",
            "Speed-up",
        ],
    );
    let mut rows = Vec::new();
    let mut groups = Vec::new();
    for (name, uavs) in geometries() {
        let sc = Scenario { uavs: uavs.clone(), ..Scenario::paper() };
        sc.validate().map_err(|e| ExperimentError::Input(format!("table10 geometry {name}: {e}")))?;
        let noise = sc.noise_model().map_err(|e| ExperimentError::Input(e.to_string()))?;
        let sensors = Sensors::new(&uavs, noise).map_err(|e| ExperimentError::Input(e.to_string()))?;
        let c0 = crlb(&sensors, &sc.emitter_position()).map_err(|e| ExperimentError::Input(e.to_string()))?;
        let an = engine.batch(&format!("table10 {name}"), &sc, ObjectiveKind::Analytical, SolverKind::Pso)?;
        let mc = engine.batch(&format!("table10 {name}"), &sc, ObjectiveKind::Mc, SolverKind::Pso)?;
        let fc = summarize(&an.terminal(Metric::Crlb));
        let fr = summarize(&an.terminal(Metric::Rmse));
        let mc_fc = summarize(&mc.terminal(Metric::Crlb));
        let diff = rel_pct(fc.mean, mc_fc.mean);
        let speedup = median(&mc.plan_ms()) / median(&an.plan_ms());
        let ours = [c0.cond, c0.crlb_m, fc.mean, fr.mean, diff, speedup];
        let p = paper::row(&paper::TABLE10, name);
        grid.compare(name, &ours, p.as_ref().map(|r| &r[..]), 2);
        groups.push(value_group(name, &[c0.crlb_m, fc.mean, fr.mean]));
        rows.push(json!({
            "geometry": name,
            "uavs_m": uavs,
            "initial_fim_cond": c0.cond,
            "initial_crlb_m": c0.crlb_m,
            "analytical_final_crlb_m": fc.mean,
            "analytical_final_crlb_ci95_m": fc.ci95,
            "analytical_final_rmse_m": fr.mean,
            "analytical_final_rmse_ci95_m": fr.ci95,
            "mc_final_crlb_m": mc_fc.mean,
            "analytical_vs_mc_diff_pct": diff,
            "analytical_speedup_vs_mc": speedup,
            "paper": p.map_or(Value::Null, |p| json!({
                "initial_fim_cond": p[0], "initial_crlb_m": p[1], "analytical_final_crlb_m": p[2],
                "analytical_final_rmse_m": p[3], "analytical_vs_mc_diff_pct": p[4], "analytical_speedup_vs_mc": p[5]
            })),
        }));
    }
    let conclusions = vec![
        format!(
            "The nominal geometry's initial CRLB reproduces the paper's ({1} m vs 1655.58 m), its condition number does not ({0} vs 345.83, see table8); the other two geometries are our choice, so only their trend compares: the wide baseline starts far better conditioned ({2}) and ends lower.",
            cell(rows[0]["initial_fim_cond"].as_f64(), 2),
            cell(rows[0]["initial_crlb_m"].as_f64(), 2),
            cell(rows[1]["initial_fim_cond"].as_f64(), 2)
        ),
        format!(
            "Analytical planning ends within {} % of MC planning's terminal CRLB in every geometry, {}–{}× faster per planning step.",
            cell(rows.iter().filter_map(|r| r["analytical_vs_mc_diff_pct"].as_f64()).map(f64::abs).reduce(f64::max), 2),
            cell(rows.iter().filter_map(|r| r["analytical_speedup_vs_mc"].as_f64()).reduce(f64::min), 1),
            cell(rows.iter().filter_map(|r| r["analytical_speedup_vs_mc"].as_f64()).reduce(f64::max), 1)
        ),
    ];
    let figures = vec![Figure::Bars {
        name: "geometries".into(),
        title: "Initial CRLB and analytical terminal CRLB/RMSE per initial geometry (Figure 17, log scale)".into(),
        y_label: "metres".into(),
        series: vec!["initial CRLB".into(), "final CRLB".into(), "final RMSE".into()],
        groups,
        log_y: true,
    }];
    let sc = Scenario::paper();
    Ok(ExperimentReport {
        experiment: "table10".into(),
        title: "initial-geometry sensitivity, analytical vs MC planning (paper Table 10, Figure 17)".into(),
        settings: settings_json(
            engine,
            &sc,
            &[
                (
                    "geometries_m",
                    json!(geometries().iter().map(|(n, g)| json!({"name": n, "uavs": g})).collect::<Vec<_>>()),
                ),
                ("solver", json!("pso")),
            ],
        ),
        rows,
        conclusions,
        tables: vec![grid],
        figures,
        files: Vec::new(),
    })
}
