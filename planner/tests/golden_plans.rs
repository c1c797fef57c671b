//! Plans recorded before the planner's candidate evaluation was made faster (issue 17.2): every change
//! to how candidates are evaluated must give the same plans bit for bit — headings, waypoints, criterion
//! value, iterations and evaluations — for every solver and criterion on 64 planning problems drawn in
//! both regimes (approach from afar, and inside the standoff ring where the standoff search runs).
//!
//! `UAVLOC_WRITE_GOLDEN=1 cargo test --release -p uavloc-planner --test golden_plans` records them again
//! (only when a change of the plans is intended).

use nalgebra::{Matrix2, Vector2};
use planner::{ObjectiveKind, PlanRequest, Scenario, SolverKind, plan_step};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const PROBLEMS: usize = 64;
const FILE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/golden_plans.txt");

/// Problem `k`: three UAVs around the emitter's estimate, far (approach) or within 1.5 L_min (standoff).
fn problem(k: usize) -> (Vec<Vector2<f64>>, Vec<f64>, Vector2<f64>, Matrix2<f64>) {
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

fn bits_of_all() -> Vec<String> {
    let sc = Scenario::default();
    let mut lines = Vec::new();
    for k in 0..PROBLEMS {
        let (pos, psi, z, m) = problem(k);
        for objective in [ObjectiveKind::Analytical, ObjectiveKind::PosteriorCubature, ObjectiveKind::Single] {
            for solver in SolverKind::PAPER {
                let out = plan_step(&PlanRequest {
                    positions: &pos,
                    headings: &psi,
                    estimate: z,
                    covariance: m,
                    scenario: &sc,
                    objective,
                    solver,
                    run_seed: 7,
                    step: k as u64,
                })
                .unwrap();
                let mut v: Vec<String> = out.headings.iter().map(|h| format!("{:016x}", h.to_bits())).collect();
                v.extend(out.waypoints.iter().flat_map(|w| [w.x, w.y]).map(|x| format!("{:016x}", x.to_bits())));
                v.push(format!("{:016x}", out.objective_value.to_bits()));
                v.push(format!("{} {}", out.iterations, out.evaluations));
                lines.push(format!("{k} {objective} {solver} {}", v.join(" ")));
            }
        }
    }
    lines
}

#[test]
fn plans_are_those_recorded_bit_for_bit() {
    let lines = bits_of_all();
    if std::env::var_os("UAVLOC_WRITE_GOLDEN").is_some() {
        std::fs::write(FILE, lines.join("\n") + "\n").unwrap();
        return;
    }
    let recorded = std::fs::read_to_string(FILE).expect("the recorded plans");
    let recorded: Vec<&str> = recorded.lines().collect();
    assert_eq!(recorded.len(), lines.len());
    let differ: Vec<String> =
        lines.iter().zip(&recorded).filter(|(a, b)| a.as_str() != **b).map(|(a, _)| a.clone()).collect();
    assert!(
        differ.is_empty(),
        "{} of {} plans differ, e.g.\n{}",
        differ.len(),
        lines.len(),
        differ[..differ.len().min(3)].join("\n")
    );
    // Both regimes are covered: some plans ran the standoff search (more evaluations than one search).
    let evals: Vec<usize> = lines.iter().map(|l| l.split(' ').next_back().unwrap().parse().unwrap()).collect();
    assert!(evals.iter().any(|&e| e > 40 * 16), "no plan ran the standoff search");
}
