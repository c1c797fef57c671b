//! Each solver's plans against PSO's on the same inputs: how many rank at least as well, and the worst
//! cases.

use planning::SolverKind;
use serde::Serialize;

use super::{Combo, PlanInput};

/// One solver's plans against PSO's, paired by input, for one objective (fitness: constraint violation
/// first, then the criterion).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Quality {
    pub objective: String,
    pub solver: String,
    /// `certified` or `waypoints` (both plans).
    pub safety: String,
    /// Planning problems compared.
    pub problems: usize,
    /// Of them, in the standoff regime (PSO's plan gives up a constraint: the L_min ring).
    pub standoff_problems: usize,
    /// Problems where this solver's fitness is ≤ PSO's.
    pub at_most_pso: usize,
    /// `at_most_pso / problems`.
    pub fraction_at_most_pso: f64,
    /// Problems where it is strictly better.
    pub better: usize,
    /// The worst cases (largest excess over PSO), at most five.
    pub worst: Vec<WorstCase>,
}

/// A problem where a solver's plan is worse than PSO's.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WorstCase {
    /// Input index (0-based) and its closed-loop step.
    pub input: usize,
    pub step: u64,
    /// `approach` or `standoff`.
    pub regime: &'static str,
    /// The fitness of each plan.
    pub violation: f64,
    pub pso_violation: f64,
    /// The violations by priority tier of each plan (certified: collision, the step's own limits, the
    /// certificate, the deficits summed, the reserve, the heading cone).
    pub violation_tiers: [f64; planning::TIERS],
    pub pso_violation_tiers: [f64; planning::TIERS],
    pub objective_m2: f64,
    pub pso_objective_m2: f64,
    /// Relative excess: of the violation when either plan violates a constraint, else of the criterion.
    pub excess: f64,
}

/// Every solver's plans against PSO's for the same objective and inputs (see [`Quality`]).
pub fn quality(combos: &[Combo], fitness: &[Vec<planning::Fitness>], inputs: &[PlanInput]) -> Vec<Quality> {
    let mut out = Vec::new();
    for (j, &(o, s, m)) in combos.iter().enumerate() {
        let Some(r) = combos.iter().position(|&c| c == (o, SolverKind::Pso, m)) else { continue };
        if s == SolverKind::Pso || !o.is_optimised() {
            continue;
        }
        let (mine, pso) = (&fitness[j], &fitness[r]);
        let mut worst: Vec<WorstCase> = Vec::new();
        let mut q = Quality {
            objective: o.name().into(),
            solver: s.name().into(),
            safety: m.name().into(),
            problems: mine.len(),
            standoff_problems: pso.iter().filter(|f| !f.is_feasible()).count(),
            at_most_pso: 0,
            fraction_at_most_pso: 0.0,
            better: 0,
            worst: Vec::new(),
        };
        for (i, (a, b)) in mine.iter().zip(pso).enumerate() {
            if a.at_most_within(b, planning::TIE_TOLERANCE) {
                q.at_most_pso += 1;
                q.better += usize::from(!b.at_most_within(a, planning::TIE_TOLERANCE));
                continue;
            }
            let rel = |x: f64, y: f64| if y > 0.0 { (x - y) / y } else { f64::INFINITY };
            let excess = if a.is_feasible() && b.is_feasible() {
                rel(a.objective(), b.objective())
            } else {
                rel(a.violation(), b.violation())
            };
            worst.push(WorstCase {
                input: i,
                step: inputs[i].step,
                regime: if b.is_feasible() { "approach" } else { "standoff" },
                violation: a.violation(),
                pso_violation: b.violation(),
                violation_tiers: a.tiers(),
                pso_violation_tiers: b.tiers(),
                objective_m2: a.objective(),
                pso_objective_m2: b.objective(),
                excess,
            });
        }
        worst.sort_by(|x, y| y.excess.total_cmp(&x.excess));
        worst.truncate(5);
        q.worst = worst;
        q.fraction_at_most_pso = q.at_most_pso as f64 / q.problems.max(1) as f64;
        out.push(q);
    }
    out
}
