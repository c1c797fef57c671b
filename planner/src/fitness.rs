//! The totally ordered fitness of a candidate plan: the paper's penalised fitness (eq. 78) made exact.
//!
//! Eq. 78 adds a penalty to the objective, `F = J_CRLB + J_penalty`. A finite penalty weight can let an
//! infeasible candidate with a small objective beat a feasible one; here the comparison is lexicographic
//! instead — first the constraint violation, then the objective — which is the limit of an infinitely
//! heavy penalty:
//!
//! 1. every feasible candidate (violation 0) ranks above every infeasible one, however large its
//!    objective or however small the infeasible candidate's objective;
//! 2. among feasible candidates the smaller objective wins, and a feasible candidate with an objective
//!    of `+∞` ("feasible but useless", e.g. a singular FIM) ranks below every finite one;
//! 3. among infeasible candidates the smaller violation wins, then the smaller objective.
//!
//! NaN never appears: a NaN violation or objective is stored as `+∞`.

use std::cmp::Ordering;

/// Violation (normalised, ≥ 0, 0 when feasible) and objective (m²) of one candidate; smaller is better.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct Fitness {
    violation: f64,
    objective: f64,
}

fn sanitize(x: f64) -> f64 {
    // `+ 0.0` turns −0.0 into +0.0 so that the total order does not separate them.
    if x.is_nan() { f64::INFINITY } else { x + 0.0 }
}

impl Fitness {
    /// From a constraint violation (negative values count as 0) and an objective value, m².
    pub fn new(violation: f64, objective: f64) -> Self {
        Self { violation: sanitize(violation).max(0.0), objective: sanitize(objective) }
    }

    /// A feasible candidate with this objective, m².
    pub fn feasible(objective: f64) -> Self {
        Self::new(0.0, objective)
    }

    /// The worst possible fitness (infinite violation and objective).
    pub fn worst() -> Self {
        Self { violation: f64::INFINITY, objective: f64::INFINITY }
    }

    /// Sum of the normalised constraint violations (0 when feasible).
    pub fn violation(&self) -> f64 {
        self.violation
    }

    /// The objective, m² (may be `+∞`, never NaN).
    pub fn objective(&self) -> f64 {
        self.objective
    }

    /// Whether every constraint holds.
    pub fn is_feasible(&self) -> bool {
        self.violation == 0.0
    }
}

impl PartialEq for Fitness {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Fitness {}

impl PartialOrd for Fitness {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Fitness {
    fn cmp(&self, other: &Self) -> Ordering {
        self.violation.total_cmp(&other.violation).then_with(|| self.objective.total_cmp(&other.objective))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn feasible_beats_infeasible_whatever_the_objective() {
        let infeasible = Fitness::new(1e-12, 1e-300);
        let feasible = Fitness::feasible(1e300);
        assert!(feasible < infeasible);
        assert!(Fitness::feasible(f64::INFINITY) < infeasible);
        assert!(Fitness::feasible(f64::MAX) < Fitness::feasible(f64::INFINITY));
    }

    #[test]
    fn ordering_is_lexicographic() {
        assert!(Fitness::feasible(1.0) < Fitness::feasible(2.0));
        assert!(Fitness::new(0.1, 100.0) < Fitness::new(0.2, 1.0));
        assert!(Fitness::new(0.1, 1.0) < Fitness::new(0.1, 2.0));
        assert!(Fitness::new(0.1, 1.0) < Fitness::worst());
    }

    #[test]
    fn nan_is_mapped_to_infinity() {
        let f = Fitness::new(f64::NAN, f64::NAN);
        assert_eq!(f.violation(), f64::INFINITY);
        assert_eq!(f.objective(), f64::INFINITY);
        assert_eq!(f, Fitness::worst());
        let g = Fitness::feasible(f64::NAN);
        assert!(g.is_feasible());
        assert!(Fitness::feasible(1.0) < g);
    }

    #[test]
    fn negative_zero_and_negative_violation_are_feasible() {
        assert!(Fitness::new(-0.0, 1.0).is_feasible());
        assert!(Fitness::new(-3.0, 1.0).is_feasible());
        assert_eq!(Fitness::new(-0.0, -0.0), Fitness::feasible(0.0));
    }
}
