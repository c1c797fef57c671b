//! The 64 planning problems of the planner's regression tests (drawn once, fixed by their seeds): three
//! UAVs around the emitter's estimate, far from it (approach) or within 1.5 L_min (standoff).

use model::Scenario;
use nalgebra::{Matrix2, Vector2};
use planning::{ObjectiveKind, PlanOutput, PlanRequest, SolverKind, plan_step};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Number of problems.
pub const PROBLEMS: usize = 64;

/// Problem `k`: three UAVs around the emitter's estimate, far (approach) or within 1.5 L_min (standoff).
pub fn problem(k: usize) -> (Vec<Vector2<f64>>, Vec<f64>, Vector2<f64>, Matrix2<f64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(1000 + k as u64);
    let z = Vector2::new(25000.0 + rng.random_range(-500.0..500.0), 15000.0 + rng.random_range(-500.0..500.0));
    let near = k % 2 == 1;
    let pos: Vec<Vector2<f64>> = (0..3)
        .map(|i| {
            let bearing = std::f64::consts::TAU * (i as f64 / 3.0) + rng.random_range(-0.4..0.4);
            let r = if near { rng.random_range(2000.0..4500.0) } else { rng.random_range(8000.0..25000.0) };
            z + r * Vector2::new(bearing.cos(), bearing.sin())
        })
        .collect();
    let psi: Vec<f64> = pos.iter().map(|p| (z.y - p.y).atan2(z.x - p.x) + rng.random_range(-0.6..0.6)).collect();
    let (a, b, c): (f64, f64, f64) =
        (rng.random_range(1.0e3..4.0e5), rng.random_range(-0.8..0.8), rng.random_range(1.0e3..4.0e5));
    let m = Matrix2::new(a, b * (a * c).sqrt(), b * (a * c).sqrt(), c);
    (pos, psi, z, m)
}

/// The plan of problem `k` with `objective` and `solver` in scenario `sc` (run seed 7, step `k`).
pub fn plan(sc: &Scenario, k: usize, objective: ObjectiveKind, solver: SolverKind) -> PlanOutput {
    let (pos, psi, z, m) = problem(k);
    plan_step(&PlanRequest {
        positions: &pos,
        headings: &psi,
        estimate: z,
        covariance: m,
        scenario: sc,
        objective,
        solver,
        run_seed: 7,
        step: k as u64,
        motion: None,
    })
    .unwrap()
}
