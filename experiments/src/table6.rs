//! Table 6 (Figure 11): robustness to a growing planner-side target error (paper Section 5.6). The
//! true emitter is fixed; the planner is told ẑ = z* + s·e0 with covariance s²·σ_t²·I (the scenario's
//! controlled mode), s ∈ {0, 0.25, 0.5, 0.75, 1}. Per method: terminal RMSE and its degradation relative
//! to s = 0, the time-averaged RMSE degradation, and the paired difference analytical − single.

use model::Scenario;
use model::scenario::TargetMode;
use planning::{ObjectiveKind, SolverKind};
use serde_json::{Value, json};

use crate::batch::{Engine, Metric};
use crate::figures::{Figure, summary_group};
use crate::grid::{Grid, cell};
use crate::stats::{Summary, paired, rel_pct, summarize};
use crate::table2::verdict;
use crate::{ExperimentError, ExperimentReport, paper, settings_json};

/// The planner-side error scales of Table 6.
pub const SCALES: [f64; 5] = [0.0, 0.25, 0.5, 0.75, 1.0];
/// The methods compared.
pub const METHODS: [ObjectiveKind; 3] = [ObjectiveKind::Single, ObjectiveKind::Mc, ObjectiveKind::Analytical];

/// The nominal scenario in controlled mode at scale `s`.
pub fn controlled(s: f64) -> Scenario {
    Scenario { target: TargetMode::Controlled, scale: s, ..Scenario::paper() }
}

/// Runs Table 6.
pub fn run(engine: &Engine) -> Result<ExperimentReport, ExperimentError> {
    // terminal[scale][method], time-averaged[scale][method] (per-run values).
    let mut terminal = Vec::new();
    let mut averaged = Vec::new();
    for s in SCALES {
        let sc = controlled(s);
        let mut t = Vec::new();
        let mut a = Vec::new();
        for m in METHODS {
            let b = engine.batch(&format!("table6 s={s:.2}"), &sc, m, SolverKind::Pso)?;
            t.push(b.terminal(Metric::Rmse));
            a.push(b.time_average(Metric::Rmse));
        }
        terminal.push(t);
        averaged.push(a);
    }
    let mean = |v: &[f64]| summarize(v).mean;
    let base: Vec<f64> = (0..METHODS.len()).map(|j| mean(&terminal[0][j])).collect();
    let base_avg: Vec<f64> = (0..METHODS.len()).map(|j| mean(&averaged[0][j])).collect();

    let mut grid = Grid::new(
        "table6",
        "Table 6 — terminal RMSE (m) / degradation vs s = 0 (%); gain = single − analytical degradation (pp); Δ = ours − paper",
        &[
            "Scale s",
            "source",
            "single RMSE",
            "single deg",
            "MC RMSE",
            "MC deg",
            "analytical RMSE",
            "analytical deg",
            "gain (pp)",
        ],
    );
    let mut rows = Vec::new();
    let mut groups = Vec::new();
    let mut conclusions = Vec::new();
    for (i, s) in SCALES.iter().enumerate() {
        let sums: Vec<Summary> = terminal[i].iter().map(|v| summarize(v)).collect();
        let deg: Vec<f64> = sums.iter().zip(&base).map(|(x, b)| rel_pct(x.mean, *b)).collect();
        let deg_avg: Vec<f64> = (0..METHODS.len()).map(|j| rel_pct(mean(&averaged[i][j]), base_avg[j])).collect();
        let gain = deg[0] - deg[2];
        let ours = [sums[0].mean, deg[0], sums[1].mean, deg[1], sums[2].mean, deg[2], gain];
        let p = paper::TABLE6.iter().find(|(ps, _)| (ps - s).abs() < 1e-12).map(|(_, v)| *v);
        grid.compare(&format!("{s:.2}"), &ours, p.as_ref().map(|r| &r[..]), 2);
        let d_an = paired(&terminal[i][2], &terminal[i][0]);
        let d_mc = paired(&terminal[i][1], &terminal[i][0]);
        if *s > 0.0 {
            conclusions.push(format!("s = {s:.2}: {}", verdict("analytical terminal RMSE", &d_an)));
        }
        groups.push(summary_group(&format!("s = {s:.2}"), &sums));
        let method_json = |j: usize| json!({"terminal_rmse_m": sums[j].mean, "ci95_rmse_m": sums[j].ci95, "degradation_pct": deg[j], "time_averaged_rmse_m": mean(&averaged[i][j]), "time_averaged_degradation_pct": deg_avg[j]});
        rows.push(json!({
            "scale": s,
            "single": method_json(0),
            "mc": method_json(1),
            "analytical": method_json(2),
            "robustness_gain_pp": gain,
            "diff_vs_single": {"analytical_final_rmse_m": d_an.interval(), "mc_final_rmse_m": d_mc.interval()},
            "paper": p.map_or(Value::Null, |p| json!({
                "single_rmse_m": p[0], "single_degradation_pct": p[1], "mc_rmse_m": p[2], "mc_degradation_pct": p[3],
                "analytical_rmse_m": p[4], "analytical_degradation_pct": p[5], "robustness_gain_pp": p[6]
            })),
        }));
    }
    let last = rows.last().cloned().unwrap_or(Value::Null);
    let g = last["robustness_gain_pp"].as_f64().unwrap_or(f64::NAN);
    conclusions.push(format!(
        "At s = 1 the terminal RMSE degrades by {} % (single), {} % (MC) and {} % (analytical): a robustness gain of {} pp for analytical planning (paper: 61.36, 47.80, 40.83 %, gain 20.53 pp). Time-averaged degradation: single {} %, analytical {} % (paper: 19.53, 13.31 %).",
        cell(last["single"]["degradation_pct"].as_f64(), 2),
        cell(last["mc"]["degradation_pct"].as_f64(), 2),
        cell(last["analytical"]["degradation_pct"].as_f64(), 2),
        cell(Some(g), 2),
        cell(last["single"]["time_averaged_degradation_pct"].as_f64(), 2),
        cell(last["analytical"]["time_averaged_degradation_pct"].as_f64(), 2),
    ));
    let sc = controlled(1.0);
    let figures = vec![Figure::Bars {
        name: "terminal-rmse".into(),
        title: "Terminal RMSE vs planner-side error scale, mean and CI95 (Figure 11)".into(),
        y_label: "terminal RMSE (m)".into(),
        series: METHODS.iter().map(|m| m.name().to_string()).collect(),
        groups,
        log_y: false,
    }];
    Ok(ExperimentReport {
        experiment: "table6".into(),
        title: "robustness to planner-side target error (paper Table 6, Figure 11)".into(),
        settings: settings_json(
            engine,
            &sc,
            &[
                ("scales", json!(SCALES)),
                ("target", json!("controlled: ẑ = z* + s·e0, M = s²·σ_t²·I")),
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
