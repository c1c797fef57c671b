//! The solver a [`SolverKind`] names, built with a scenario's settings for it: the one place that knows
//! every solver (the trait in [`crate::solver`] knows none of them).

use model::scenario::Scenario;

use crate::aco::Aco;
use crate::ga::Ga;
use crate::gradient::Gradient;
use crate::pso::Pso;
use crate::solver::{Solver, SolverKind};

impl SolverKind {
    /// The solver with the scenario's settings for it.
    pub fn build(self, sc: &Scenario) -> Box<dyn Solver> {
        let stop = sc.early_stop;
        match self {
            SolverKind::Pso => Box::new(Pso { config: sc.pso, stop }),
            SolverKind::Ga => Box::new(Ga { config: sc.ga, stop }),
            SolverKind::Aco => Box::new(Aco { config: sc.aco, stop }),
            SolverKind::Gradient => Box::new(Gradient::new(sc.gradient)),
        }
    }
}
