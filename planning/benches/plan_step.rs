//! One planning step (PSO 40 particles × 15 iterations, early stop as configured) with each objective,
//! 3 UAVs, at the paper's nominal start with ẑ = truth and M = F⁻¹(truth).
//! Run: `cargo bench -p uavloc-planning --features criterion --bench plan_step`.

use std::time::Duration;

use criterion::{BenchmarkId, Criterion, black_box, criterion_group, criterion_main};
use model::Scenario;
use planning::{ObjectiveKind, PlanRequest, SolverKind, plan_step};
use tdoa::{Sensors, crlb};

fn steps(c: &mut Criterion) {
    let sc = Scenario::default();
    let sensors = Sensors::new(&sc.uavs, sc.noise_model().unwrap()).unwrap();
    let z = sc.emitter_position();
    let m = crlb(&sensors, &z).unwrap().bound;
    let pos = sc.uav_positions();
    let psi = sc.initial_headings();
    let mut group = c.benchmark_group("plan_step");
    group.measurement_time(Duration::from_secs(3)).warm_up_time(Duration::from_millis(500)).sample_size(20);
    for solver in [SolverKind::Pso, SolverKind::Ga, SolverKind::Aco] {
        for objective in [
            ObjectiveKind::Single,
            ObjectiveKind::Analytical,
            ObjectiveKind::Cubature,
            ObjectiveKind::Mc,
            ObjectiveKind::Formation,
        ] {
            if solver != SolverKind::Pso && objective == ObjectiveKind::Formation {
                continue;
            }
            let req = PlanRequest {
                positions: &pos,
                headings: &psi,
                estimate: z,
                covariance: m,
                scenario: &sc,
                objective,
                solver,
                run_seed: 1,
                step: 0,
                motion: None,
            };
            group.bench_function(BenchmarkId::new(format!("{solver:?}").to_lowercase(), objective.name()), |b| {
                b.iter(|| black_box(plan_step(black_box(&req)).unwrap()))
            });
        }
    }
    group.finish();
}

criterion_group!(benches, steps);
criterion_main!(benches);
