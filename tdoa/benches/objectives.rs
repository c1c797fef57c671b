//! One evaluation of each global-CRLB objective (prepared once, as the planner does per step) with 3, 4
//! and 5 UAVs at the paper's nominal geometry, plus one Chan solve.
//! Run: `cargo bench -p uavloc-tdoa --features criterion --bench objectives`.

use std::time::Duration;

use criterion::{BenchmarkId, Criterion, black_box, criterion_group, criterion_main};
use nalgebra::Vector2;
use tdoa::{DEFAULT_KAPPA, Method, NoiseModel, Sensors, Uncertainty, chan, crlb};

const UAVS: [[f64; 2]; 5] = [[1500.0, 500.0], [10000.0, 1500.0], [5000.0, 8500.0], [0.0, 9000.0], [12000.0, 7000.0]];

fn scene(n: usize) -> (Sensors, Uncertainty) {
    let s = Sensors::new(&UAVS[..n], NoiseModel::uniform(n, 28.7712).unwrap()).unwrap();
    let z = Vector2::new(25000.0, 15000.0);
    let m = crlb(&s, &z).unwrap().bound;
    let u = Uncertainty::with_eq36_side(z, m, s.mean_range(&z), DEFAULT_KAPPA).unwrap();
    (s, u)
}

fn objectives(c: &mut Criterion) {
    let mut group = c.benchmark_group("objective");
    group.measurement_time(Duration::from_secs(2)).warm_up_time(Duration::from_millis(500)).sample_size(30);
    for n in 3..=5 {
        let (s, u) = scene(n);
        for method in Method::ALL {
            let prepared = method.build(200, 1).unwrap().prepare(&u);
            group.bench_with_input(BenchmarkId::new(method.name(), n), &s, |b, s| {
                b.iter(|| black_box(prepared.evaluate(black_box(s))))
            });
        }
        let d = s.range_differences(&u.estimate());
        group.bench_with_input(BenchmarkId::new("chan", n), &s, |b, s| {
            b.iter(|| black_box(chan(black_box(s), &d, None)))
        });
    }
    group.finish();
}

criterion_group!(benches, objectives);
criterion_main!(benches);
