//! The waypoint planner's (`safety = "waypoints"`, what `uavloc paper` runs) recorded plans: every change
//! to how candidates are evaluated must give the same plans bit for bit — headings, waypoints, criterion
//! value, iterations and evaluations — for every solver and criterion on 64 planning problems drawn in
//! both regimes (approach from afar, and inside the standoff ring where the standoff search runs).
//!
//! `UAVLOC_WRITE_GOLDEN=1 cargo test --release -p uavloc-planning --test plans golden` records them again
//! (only when a change of the plans is intended).

use crate::problems::{PROBLEMS, plan};
use model::Scenario;
use planning::{ObjectiveKind, SolverKind};

const FILE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/golden_plans.txt");

fn bits_of_all() -> Vec<String> {
    let sc = Scenario { safety: model::safety::SafetyMode::Waypoints, ..Scenario::default() };
    let mut lines = Vec::new();
    for k in 0..PROBLEMS {
        for objective in [ObjectiveKind::Analytical, ObjectiveKind::PosteriorCubature, ObjectiveKind::Single] {
            for solver in SolverKind::PAPER {
                let out = plan(&sc, k, objective, solver);
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
