//! How far the two cheap surrogates of the global CRLB — the paper's Taylor `analytical` (eq. 74) and our
//! 25-point `cubature` — are from the converged `quadrature`, at target-uncertainty scales 0.25–1.0
//! (cf. the paper's Table 5). Geometries: the paper's nominal 3-UAV start and the 24 geometries of the
//! UAVs flying straight at the emitter, 500 m per step. M at scale 1 is the CRLB matrix F⁻¹(z) at each
//! geometry (what Chan reports as its covariance); the support side follows eq. 36.
//!
//! Run: `cargo run --release -p uavloc-tdoa --example surrogate_error`

use std::time::Instant;

use nalgebra::Vector2;
use tdoa::{DEFAULT_KAPPA, GlobalCrlb, Method, NoiseModel, Sensors, Uncertainty, crlb, global_crlb};

fn main() {
    let start = [[1500.0, 500.0], [10000.0, 1500.0], [5000.0, 8500.0]];
    let z = Vector2::new(25000.0, 15000.0);
    let noise = NoiseModel::uniform(3, 28.7712).unwrap();
    let geometries: Vec<Sensors> = (0..25)
        .map(|k| {
            let w: Vec<[f64; 2]> = start
                .iter()
                .map(|p| {
                    let p = Vector2::new(p[0], p[1]);
                    let q = p + (z - p).normalize() * 500.0 * k as f64;
                    [q.x, q.y]
                })
                .collect();
            Sensors::new(&w, noise.clone()).unwrap()
        })
        .collect();
    let quad = Method::Quadrature.build(0, 0).unwrap();
    let methods: Vec<Box<dyn GlobalCrlb>> =
        [Method::Analytical, Method::Cubature, Method::Mc].iter().map(|m| m.build(200, 1).unwrap()).collect();
    println!(
        "| scale | method | mean abs rel. error vs quadrature (%) | max (%) | median time per evaluation (µs) | geometries skipped (support reaches the singular locus) |"
    );
    println!("|---|---|---|---|---|---|");
    for scale in [0.25, 0.5, 0.75, 1.0] {
        let uncs: Vec<Uncertainty> = geometries
            .iter()
            .map(|s| {
                let m = crlb(s, &z).unwrap().bound * (scale * scale);
                Uncertainty::with_eq36_side(z, m, s.mean_range(&z), DEFAULT_KAPPA).unwrap()
            })
            .collect();
        // Where the support reaches the singular locus the exact value is +∞: count those, compare the rest.
        let exact: Vec<f64> =
            geometries.iter().zip(&uncs).map(|(s, u)| global_crlb(quad.as_ref(), s, u).value.trace_m2).collect();
        let singular = exact.iter().filter(|e| !e.is_finite()).count();
        for method in &methods {
            let mut errs = Vec::new();
            let mut times = Vec::new();
            for ((s, u), e) in geometries.iter().zip(&uncs).zip(&exact).filter(|(_, e)| e.is_finite()) {
                let prepared = method.prepare(u);
                let t0 = Instant::now();
                let reps = 200;
                let mut v = 0.0;
                for _ in 0..reps {
                    v = std::hint::black_box(prepared.evaluate(std::hint::black_box(s))).trace_m2;
                }
                times.push(t0.elapsed().as_secs_f64() * 1e6 / reps as f64);
                errs.push(100.0 * (v - e).abs() / e);
            }
            times.sort_by(f64::total_cmp);
            let mean = errs.iter().sum::<f64>() / errs.len() as f64;
            let max = errs.iter().cloned().fold(0.0, f64::max);
            println!(
                "| {scale:.2} | {} | {mean:.4} | {max:.4} | {:.2} | {singular} |",
                method.method(),
                times[times.len() / 2]
            );
        }
    }
}
