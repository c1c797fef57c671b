//! The report of `uavloc bench planner` as a table and as text.

use crate::output::{Report, Table};

use super::PlannerBenchReport;

/// A time in ms with about four significant digits.
fn ms(v: f64) -> String {
    if !v.is_finite() {
        "-".into()
    } else if v >= 100.0 {
        format!("{v:.1}")
    } else if v >= 1.0 {
        format!("{v:.3}")
    } else {
        format!("{v:.4}")
    }
}

fn opt_ms(v: Option<f64>) -> String {
    v.map_or("-".into(), ms)
}

fn ratio(v: Option<f64>) -> String {
    v.map_or("-".into(), |r| match r {
        r if r >= 10.0 => format!("{r:.1}×"),
        r if r >= 0.1 => format!("{r:.2}×"),
        r => format!("{r:.4}×"),
    })
}

impl PlannerBenchReport {
    fn context(&self) -> Vec<(&'static str, String)> {
        let s = &self.settings;
        vec![
            ("scenario", format!("{} (seed {})", self.scenario, self.seed)),
            (
                "inputs",
                format!(
                    "{} planned steps from {} analytical/pso closed-loop run(s) of {} steps; {} repeat(s) each",
                    self.steps, self.input_runs, self.steps_per_run, self.repeats
                ),
            ),
            (
                "solvers",
                format!(
                    "PSO {}×{}, GA {}×{}, ACO {}×{} (early stop after {}); mc K = {}",
                    s.pso[0], s.pso[1], s.ga[0], s.ga[1], s.aco[0], s.aco[1], s.early_stop_window, s.mc_samples
                ),
            ),
            ("machine", format!("{}; timed on one thread", self.machine.describe())),
        ]
    }
}

impl Report for PlannerBenchReport {
    fn table(&self) -> Table {
        let mut t = Table::new();
        for (k, v) in self.context() {
            t = t.row(k, v);
        }
        for c in &self.combinations {
            let mode = if c.safety == "waypoints" { "/waypoints" } else { "" };
            t = t.row(
                format!("{}/{}{mode}", c.objective, c.solver),
                format!(
                    "median {} ms, p90 {}, p99 {}, max {}, mean {} (n = {}); {} evals/plan; {} of {}{}",
                    ms(c.median_ms),
                    ms(c.p90_ms),
                    ms(c.p99_ms),
                    ms(c.max_ms),
                    ms(c.mean_ms),
                    c.n,
                    c.evaluations_per_plan.round(),
                    ratio(c.ratio_to_reference),
                    self.reference,
                    c.paper_total_mean_ms.map_or(String::new(), |p| format!("; paper total mean {} ms", ms(p)))
                ),
            );
        }
        t
    }

    fn text(&self) -> String {
        let mut out = String::new();
        let width = self.context().iter().map(|(k, _)| k.len()).max().unwrap_or(0) + 2;
        for (k, v) in self.context() {
            out += &format!("{k:<width$}{v}\n");
        }
        out += "\n";
        let header = [
            "objective",
            "solver",
            "safety",
            "n",
            "median ms",
            "p90 ms",
            "p99 ms",
            "max ms",
            "mean ms",
            "evals/plan",
            "× ref",
            "paper opt ms",
            "paper total ms",
            "paper × ref",
        ];
        let mut rows: Vec<Vec<String>> = vec![header.iter().map(|h| h.to_string()).collect()];
        for c in &self.combinations {
            rows.push(vec![
                c.objective.clone(),
                c.solver.clone(),
                c.safety.clone(),
                c.n.to_string(),
                ms(c.median_ms),
                ms(c.p90_ms),
                ms(c.p99_ms),
                ms(c.max_ms),
                ms(c.mean_ms),
                format!("{:.0}", c.evaluations_per_plan),
                ratio(c.ratio_to_reference),
                opt_ms(c.paper_opt_ms),
                opt_ms(c.paper_total_mean_ms),
                ratio(c.paper_ratio_to_reference),
            ]);
        }
        let widths: Vec<usize> =
            (0..header.len()).map(|i| rows.iter().map(|r| r[i].chars().count()).max().unwrap_or(0)).collect();
        for r in &rows {
            let mut line = String::new();
            for (i, cell) in r.iter().enumerate() {
                let pad = widths[i] - cell.chars().count();
                if i < 3 {
                    line += &format!("{cell}{:pad$}  ", "");
                } else {
                    line += &format!("{:pad$}{cell}  ", "");
                }
            }
            out += line.trim_end();
            out += "\n";
        }
        for q in &self.quality {
            out += &format!(
                "\n{}/{} vs {}/pso ({}): fitness <= PSO's on {} of {} problems ({:.2} %; {} standoff), better on {}",
                q.objective,
                q.solver,
                q.objective,
                q.safety,
                q.at_most_pso,
                q.problems,
                100.0 * q.fraction_at_most_pso,
                q.standoff_problems,
                q.better
            );
            for w in &q.worst {
                out += &format!(
                    "\n  worse: input {} (step {}, {}): violation {:.3e} vs {:.3e}, criterion {:.6e} vs {:.6e} m² (+{:.2e})",
                    w.input,
                    w.step,
                    w.regime,
                    w.violation,
                    w.pso_violation,
                    w.objective_m2,
                    w.pso_objective_m2,
                    w.excess
                );
            }
            out += "\n";
        }
        out += &format!(
            "\nEach sample is one plan_step call (criterion preparation + solver + constraint check), wall clock,\n\
             one thread, release build; '× ref' = median / the median of {}. Paper Table 7 (PSO rows;\n\
             MATLAB R2024a on another machine): 'paper opt' is its optimisation time, the comparable number;\n\
             'paper total' adds its CRLB display. Only the ratios compare ('paper × ref': its total mean / its\n\
             analytical total mean).\n",
            self.reference
        );
        out
    }
}
