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
//!
//! The violation can also be split into [`TIERS`] priority tiers ([`Fitness::tiered`]), compared one
//! after the other: the planner's standoff search (see [`crate::step`]) ranks collision avoidance above
//! the approach distance above the heading cone. [`Fitness::new`] puts the whole violation in the first
//! tier, which is exactly the single-violation order above.

use std::cmp::Ordering;

/// Number of violation tiers.
pub const TIERS: usize = 6;

/// The relative difference below which two solvers' fitness values tie ([`Fitness::at_most_within`]):
/// far below anything a plan can change, far above the rounding of a sum of a few dozen terms.
pub const TIE_TOLERANCE: f64 = 1e-12;

/// Violation (normalised, ≥ 0, 0 when feasible; by priority tier) and objective (m²) of one candidate;
/// smaller is better.
#[derive(Debug, Clone, Copy)]
pub struct Fitness {
    tiers: [f64; TIERS],
    objective: f64,
}

impl serde::Serialize for Fitness {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct as _;
        let mut st = s.serialize_struct("Fitness", 3)?;
        st.serialize_field("violation", &self.violation())?;
        st.serialize_field("violation_tiers", &self.tiers)?;
        st.serialize_field("objective", &self.objective)?;
        st.end()
    }
}

fn sanitize(x: f64) -> f64 {
    // `+ 0.0` turns −0.0 into +0.0 so that the total order does not separate them.
    if x.is_nan() { f64::INFINITY } else { x + 0.0 }
}

impl Fitness {
    /// From a constraint violation (negative values count as 0) and an objective value, m².
    pub fn new(violation: f64, objective: f64) -> Self {
        Self::tiered([violation, 0.0, 0.0, 0.0, 0.0, 0.0], objective)
    }

    /// From violations by priority tier (first tier first; negative values count as 0) and an objective
    /// value, m².
    pub fn tiered(tiers: [f64; TIERS], objective: f64) -> Self {
        Self { tiers: tiers.map(|v| sanitize(v).max(0.0)), objective: sanitize(objective) }
    }

    /// A feasible candidate with this objective, m².
    pub fn feasible(objective: f64) -> Self {
        Self::new(0.0, objective)
    }

    /// The worst possible fitness (infinite violation and objective).
    pub fn worst() -> Self {
        Self { tiers: [f64::INFINITY; TIERS], objective: f64::INFINITY }
    }

    /// Sum of the normalised constraint violations (0 when feasible).
    pub fn violation(&self) -> f64 {
        self.tiers.iter().sum()
    }

    /// The violations by priority tier.
    pub fn tiers(&self) -> [f64; TIERS] {
        self.tiers
    }

    /// The objective, m² (may be `+∞`, never NaN).
    pub fn objective(&self) -> f64 {
        self.objective
    }

    /// Whether this fitness is at most `other`'s when values within `rel` of each other (relative) count
    /// as equal: tier by tier, then the objective. Two solvers that reach the same plan can differ in
    /// the last bits of what they sum; comparing solvers, [`TIE_TOLERANCE`] says they tie.
    pub fn at_most_within(&self, other: &Self, rel: f64) -> bool {
        let close = |a: f64, b: f64| a == b || (a - b).abs() <= rel * a.abs().max(b.abs());
        for (a, b) in self.tiers.iter().zip(&other.tiers) {
            if !close(*a, *b) {
                return a < b;
            }
        }
        close(self.objective, other.objective) || self.objective < other.objective
    }

    /// Whether every constraint holds.
    pub fn is_feasible(&self) -> bool {
        self.tiers.iter().all(|v| *v == 0.0)
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
        self.tiers
            .iter()
            .zip(&other.tiers)
            .map(|(a, b)| a.total_cmp(b))
            .find(|o| o.is_ne())
            .unwrap_or(Ordering::Equal)
            .then_with(|| self.objective.total_cmp(&other.objective))
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
    fn values_within_the_tolerance_tie_tier_by_tier() {
        let a = Fitness::tiered([0.0, 0.0, 0.0, 9.98, 0.0, 0.0], 5.0);
        let b = Fitness::tiered([0.0, 0.0, 0.0, 9.98 + 4e-15, 0.0, 0.0], 7.0);
        // Exactly, b ranks below a on the cone tier; within the tolerance the tier ties and b's larger
        // objective decides.
        assert!(a < b);
        assert!(a.at_most_within(&b, TIE_TOLERANCE) && !b.at_most_within(&a, TIE_TOLERANCE));
        let c = Fitness::tiered([0.0, 0.0, 0.0, 9.98 + 4e-15, 0.0, 0.0], 5.0 * (1.0 + 1e-13));
        assert!(a.at_most_within(&c, TIE_TOLERANCE) && c.at_most_within(&a, TIE_TOLERANCE));
        // Beyond the tolerance the exact order stands; a feasible tier never ties with a violated one.
        let d = Fitness::tiered([0.0, 0.0, 0.0, 9.99, 0.0, 0.0], 1.0);
        assert!(!d.at_most_within(&a, TIE_TOLERANCE) && a.at_most_within(&d, TIE_TOLERANCE));
        assert!(!Fitness::new(1e-300, 1.0).at_most_within(&Fitness::feasible(2.0), TIE_TOLERANCE));
        assert!(Fitness::worst().at_most_within(&Fitness::worst(), TIE_TOLERANCE));
    }

    #[test]
    fn ordering_is_lexicographic() {
        assert!(Fitness::feasible(1.0) < Fitness::feasible(2.0));
        assert!(Fitness::new(0.1, 100.0) < Fitness::new(0.2, 1.0));
        assert!(Fitness::new(0.1, 1.0) < Fitness::new(0.1, 2.0));
        assert!(Fitness::new(0.1, 1.0) < Fitness::worst());
    }

    #[test]
    fn tiers_are_compared_in_priority_order() {
        // A smaller first tier wins whatever the later tiers and the objective.
        assert!(
            Fitness::tiered([0.1, 5.0, 5.0, 0.0, 0.0, 0.0], 1e9) < Fitness::tiered([0.2, 0.0, 0.0, 0.0, 0.0, 0.0], 1.0)
        );
        assert!(
            Fitness::tiered([0.0, 0.1, 9.0, 0.0, 0.0, 0.0], 1e9) < Fitness::tiered([0.0, 0.2, 0.0, 0.0, 0.0, 0.0], 1.0)
        );
        assert!(
            Fitness::tiered([0.0, 0.0, 0.1, 0.0, 0.0, 0.0], 1e9) < Fitness::tiered([0.0, 0.0, 0.2, 0.0, 0.0, 0.0], 1.0)
        );
        assert!(Fitness::tiered([0.0; TIERS], 1e9) < Fitness::tiered([0.0, 0.0, 1e-12, 0.0, 0.0, 0.0], 1.0));
        assert_eq!(Fitness::tiered([0.3, 0.0, 0.0, 0.0, 0.0, 0.0], 2.0), Fitness::new(0.3, 2.0));
        let f = Fitness::tiered([0.5, 0.25, f64::NAN, 0.0, 0.0, 0.0], 1.0);
        assert_eq!((f.violation(), f.tiers()), (f64::INFINITY, [0.5, 0.25, f64::INFINITY, 0.0, 0.0, 0.0]));
        assert!(!f.is_feasible() && Fitness::tiered([0.0, -1.0, 0.0, 0.0, 0.0, 0.0], 1.0).is_feasible());
    }

    #[test]
    fn nan_is_mapped_to_infinity() {
        let f = Fitness::new(f64::NAN, f64::NAN);
        assert_eq!(f.violation(), f64::INFINITY);
        assert_eq!(f.objective(), f64::INFINITY);
        assert!(f < Fitness::worst() && f == Fitness::new(f64::INFINITY, f64::INFINITY));
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
