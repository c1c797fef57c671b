//! The planner allocates per planning step, not per candidate (issue 17.2): the heap allocations of one
//! `plan_step` do not grow with the number of candidates the solver evaluates.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use planner::{ObjectiveKind, PlanRequest, Scenario, SolverKind, plan_step};
use tdoa::{Sensors, crlb};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: the caller's contract is passed on unchanged.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract is passed on unchanged.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn allocations_per_plan_do_not_grow_with_the_candidates() {
    let mut seen = Vec::new();
    for particles in [10, 40, 160] {
        let mut sc = Scenario::default();
        sc.pso.particles = particles;
        sc.early_stop.window = usize::MAX; // every iteration runs: evaluations = particles · 16
        for (objective, (evaluations, allocations)) in ["analytical", "single"].iter().zip(allocations_of(&sc)) {
            assert_eq!(evaluations, particles * 16, "{objective}");
            seen.push((objective, particles, allocations));
        }
    }
    // The same count for 160 or 2 560 evaluations, for each criterion.
    for objective in ["analytical", "single"] {
        let counts: Vec<usize> = seen.iter().filter(|s| *s.0 == objective).map(|s| s.2).collect();
        assert!(counts.windows(2).all(|w| w[0] == w[1]), "{objective}: {seen:?}");
        assert!(counts[0] < 64, "{objective}: {seen:?}");
    }
}

fn allocations_of(sc: &Scenario) -> Vec<(usize, usize)> {
    let sc = sc.clone();
    let mut out = Vec::new();
    let sensors = Sensors::new(&sc.uavs, sc.noise_model().unwrap()).unwrap();
    let z = sc.emitter_position();
    let m = crlb(&sensors, &z).unwrap().bound;
    let (pos, psi) = (sc.uav_positions(), sc.initial_headings());
    for objective in [ObjectiveKind::Analytical, ObjectiveKind::Single] {
        let req = PlanRequest {
            positions: &pos,
            headings: &psi,
            estimate: z,
            covariance: m,
            scenario: &sc,
            objective,
            solver: SolverKind::Pso,
            run_seed: 42,
            step: 3,
            motion: None,
        };
        plan_step(&req).unwrap(); // warm-up (thread-locals, lazy statics)
        let before = ALLOCATIONS.load(Ordering::Relaxed);
        let plan = plan_step(&req).unwrap();
        out.push((plan.evaluations, ALLOCATIONS.load(Ordering::Relaxed) - before));
    }
    out
}
