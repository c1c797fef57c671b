//! The optimizer comparison (Section 5.4, Figures 7–8): PSO, GA and ACO × the fixed formation and the
//! single-point, MC and analytical objectives — terminal CRLB and RMSE with CI95, and per solver the
//! paired difference of each objective to single-point.

use model::Scenario;
use planning::SolverKind;
use serde_json::json;

use crate::batch::Engine;
use crate::figures::{Figure, summary_group};
use crate::grid::Grid;
use crate::table2::{METHODS, MethodStats, batches, verdict};
use crate::{ExperimentError, ExperimentReport, paper, settings_json};

/// Runs the optimizer comparison.
pub fn run(engine: &Engine) -> Result<ExperimentReport, ExperimentError> {
    let sc = Scenario::paper();
    let mut grid = Grid::new(
        "optimizers",
        "Optimizer comparison — terminal CRLB and RMSE (m) per solver and objective; Δ = ours − paper",
        &["Solver / objective", "source", "Final CRLB", "CI95", "Final RMSE", "CI95"],
    );
    let mut rows = Vec::new();
    let mut conclusions = Vec::new();
    let mut crlb_groups = Vec::new();
    let mut rmse_groups = Vec::new();
    let mut all_beat_formation = true;
    for solver in SolverKind::PAPER {
        let b = batches(engine, "optimizers", &sc, solver, &METHODS)?;
        let stats: Vec<MethodStats> = b.iter().map(|x| MethodStats::of(x, Some(&b[1]))).collect();
        let p = paper::OPTIMIZERS.iter().find(|(s, _, _)| *s == solver.name());
        for (j, (kind, st)) in METHODS.iter().zip(&stats).enumerate() {
            let ours = [st.final_crlb.mean, st.final_crlb.ci95, st.final_rmse.mean, st.final_rmse.ci95];
            let paper_row = p.map(|(_, c, r)| [c[j], f64::NAN, r[j], f64::NAN]);
            grid.compare(&format!("{} / {}", solver.name(), kind.name()), &ours, paper_row.as_ref().map(|r| &r[..]), 2);
            rows.push(json!({
                "solver": solver.name(),
                "method": kind.name(),
                "final_crlb_m": ours[0],
                "ci95_crlb_m": ours[1],
                "final_rmse_m": ours[2],
                "ci95_rmse_m": ours[3],
                "diff_vs_single": st.diff_json(),
                "paper": p.map(|(_, c, r)| json!({"final_crlb_m": c[j], "final_rmse_m": r[j]})),
            }));
            if j > 0 {
                all_beat_formation &= st.final_crlb.mean < stats[0].final_crlb.mean;
            }
            if j >= 2
                && let Some(d) = &st.diff
            {
                conclusions.push(format!(
                    "{}: {}",
                    solver.name(),
                    verdict(&format!("{} terminal CRLB", kind.name()), &d[1])
                ));
            }
        }
        let red = (stats[0].final_crlb.mean - stats[1].final_crlb.mean) / stats[0].final_crlb.mean * 100.0;
        conclusions.push(format!(
            "{}: single-point planning ends {red:.2} % below the fixed formation in terminal CRLB (paper, PSO: 25.87 %).",
            solver.name()
        ));
        crlb_groups.push(summary_group(solver.name(), &stats.iter().map(|s| s.final_crlb).collect::<Vec<_>>()));
        rmse_groups.push(summary_group(solver.name(), &stats.iter().map(|s| s.final_rmse).collect::<Vec<_>>()));
    }
    conclusions.insert(
        0,
        format!(
            "Every planned objective beats the fixed formation at the terminal step with every solver: {}.",
            if all_beat_formation { "HOLDS" } else { "does NOT hold" }
        ),
    );
    let series: Vec<String> = METHODS.iter().map(|m| m.name().to_string()).collect();
    let figures = vec![
        Figure::Bars {
            name: "crlb".into(),
            title: "Terminal CRLB per solver and objective, mean and CI95 (Figure 7)".into(),
            y_label: "terminal CRLB (m)".into(),
            series: series.clone(),
            groups: crlb_groups,
            log_y: false,
        },
        Figure::Bars {
            name: "rmse".into(),
            title: "Terminal RMSE per solver and objective, mean and CI95 (Figure 8)".into(),
            y_label: "terminal RMSE (m)".into(),
            series,
            groups: rmse_groups,
            log_y: false,
        },
    ];
    Ok(ExperimentReport {
        experiment: "optimizers".into(),
        title: "PSO / GA / ACO × formation / single / MC / analytical (paper Section 5.4, Figures 7–8)".into(),
        settings: settings_json(engine, &sc, &[("solvers", json!(["pso", "ga", "aco"]))]),
        rows,
        conclusions,
        tables: vec![grid],
        figures,
        files: Vec::new(),
    })
}
