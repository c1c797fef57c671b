//! The five global-CRLB methods against each other and against the deterministic quadrature.

use crate::common;

use common::{config, nominal, scene};
use nalgebra::{Matrix2, Vector2};
use proptest::prelude::*;
use tdoa::global::{Analytical, Cubature, McScheme, MonteCarlo, Quadrature, SinglePoint};
use tdoa::singular::singular_report;
use tdoa::{DEFAULT_KAPPA, GlobalCrlb, Method, Sensors, Uncertainty, crlb, global_crlb, trace_crlb};

/// An uncertainty whose largest standard deviation is `eps` times the length over which h varies
/// (nearest range / sqrt(cond)), shaped like the CRLB at the target.
fn uncertainty(sensors: &Sensors, z: Vector2<f64>, eps: f64) -> Uncertainty {
    let c = crlb(sensors, &z).unwrap();
    let r = sensors.positions().iter().map(|w| (w - z).norm()).fold(f64::INFINITY, f64::min);
    let ell = r / c.cond.sqrt();
    let lmax = tdoa::fim::sym_eigenvalues(&c.bound).1;
    let cov = c.bound * (eps * ell).powi(2) / lmax;
    Uncertainty::with_eq36_side(z, cov, sensors.mean_range(&z), DEFAULT_KAPPA).unwrap()
}

fn value(method: &dyn GlobalCrlb, s: &Sensors, u: &Uncertainty) -> f64 {
    global_crlb(method, s, u).value.trace_m2
}

proptest! {
    #![proptest_config(config(48))]

    #[test]
    fn analytical_tends_to_quadrature_as_uncertainty_shrinks(sc in scene()) {
        let q = Quadrature::default();
        let diff = |eps: f64| {
            let u = uncertainty(&sc.sensors, sc.target, eps);
            let exact = value(&q, &sc.sensors, &u);
            (value(&Analytical, &sc.sensors, &u) - exact).abs() / exact
        };
        let (d1, d2) = (diff(0.04), diff(0.02));
        prop_assert!(d2 < 1e-3, "relative difference {d2} at eps 0.02");
        // Second-order surrogate: the gap shrinks at least like eps² (ratio ≈ 1/4).
        prop_assert!(d2 <= 0.4 * d1 + 1e-8, "gap did not shrink: {d1} -> {d2}");
    }

    #[test]
    fn monte_carlo_is_within_four_standard_errors_of_quadrature(sc in scene(), seed in 0u64..1_000_000, eps in 0.05..0.5f64) {
        let u = uncertainty(&sc.sensors, sc.target, eps);
        prop_assume!(singular_report(&sc.sensors, &u).distance_m > u.side());
        let exact = value(&Quadrature::default(), &sc.sensors, &u);
        for scheme in [McScheme::UniformWeighted, McScheme::TruncatedGaussian] {
            let mc = MonteCarlo::new(1000, seed, scheme).unwrap();
            let r = global_crlb(&mc, &sc.sensors, &u).value;
            let se = r.stderr_m2.unwrap();
            prop_assert!(se > 0.0);
            // The delta-method standard error means something only with enough effective samples; eq. 60
            // around a needle-thin Gaussian can have an ESS of 1 (see eq60_effective_sample_size_…).
            if r.effective_samples.unwrap() < 100.0 {
                prop_assert_eq!(scheme, McScheme::UniformWeighted);
                continue;
            }
            prop_assert!((r.trace_m2 - exact).abs() <= 4.0 * se, "{scheme:?}: mc {} ± {se}, quadrature {exact}", r.trace_m2);
        }
    }

    #[test]
    fn cubature_uses_at_most_25_points_and_is_exact_for_small_uncertainty(sc in scene()) {
        let u = uncertainty(&sc.sensors, sc.target, 0.02);
        let r = global_crlb(&Cubature, &sc.sensors, &u).value;
        prop_assert!(r.evaluations <= 25);
        let exact = value(&Quadrature::default(), &sc.sensors, &u);
        prop_assert!((r.trace_m2 - exact).abs() / exact < 1e-3);
    }

    #[test]
    fn single_is_the_trace_at_the_estimate(sc in scene()) {
        let u = uncertainty(&sc.sensors, sc.target, 0.3);
        prop_assert_eq!(value(&SinglePoint, &sc.sensors, &u), trace_crlb(&sc.sensors, &sc.target));
    }
}

#[test]
fn quadrature_converges_and_matches_a_brute_force_midpoint_sum() {
    let (s, z) = nominal(28.7712);
    let c = crlb(&s, &z).unwrap();
    let u = Uncertainty::with_eq36_side(z, c.bound, s.mean_range(&z), DEFAULT_KAPPA).unwrap();
    let q = global_crlb(&Quadrature::default(), &s, &u).value;
    assert!(q.stderr_m2.is_none(), "quadrature did not converge");
    // Independent check: a plain 1200×1200 midpoint rule.
    let n = 1200;
    let (lo, _) = u.bounds();
    let h = u.side() / n as f64;
    let (mut num, mut den) = (0.0, 0.0);
    for i in 0..n {
        for j in 0..n {
            let p = lo + Vector2::new((i as f64 + 0.5) * h, (j as f64 + 0.5) * h);
            let w = u.density(&p);
            num += w * trace_crlb(&s, &p);
            den += w;
        }
    }
    assert!((q.trace_m2 - num / den).abs() / q.trace_m2 < 1e-5, "quadrature {} midpoint {}", q.trace_m2, num / den);
}

#[test]
fn monte_carlo_is_reproducible_per_seed() {
    let (s, z) = nominal(28.7712);
    let u = Uncertainty::with_eq36_side(z, crlb(&s, &z).unwrap().bound, s.mean_range(&z), DEFAULT_KAPPA).unwrap();
    let a = Method::Mc.build(200, 9).unwrap();
    let b = Method::Mc.build(200, 9).unwrap();
    let c = Method::Mc.build(200, 10).unwrap();
    assert_eq!(value(a.as_ref(), &s, &u), value(b.as_ref(), &s, &u));
    assert_ne!(value(a.as_ref(), &s, &u), value(c.as_ref(), &s, &u));
}

#[test]
fn eq60_effective_sample_size_is_small_for_a_wide_square() {
    let (s, z) = nominal(28.7712);
    let u = Uncertainty::new(z, Matrix2::new(1e6, 0.0, 0.0, 1e6), 10_000.0).unwrap();
    let uniform = MonteCarlo::new(200, 1, McScheme::UniformWeighted).unwrap().rule(&u);
    let gauss = MonteCarlo::new(200, 1, McScheme::TruncatedGaussian).unwrap().rule(&u);
    // 4π σ²/A² · K ≈ 25 for A = 10σ; drawing from the Gaussian keeps all 200.
    assert!(uniform.effective_sample_size() < 50.0, "ESS {}", uniform.effective_sample_size());
    assert!((gauss.effective_sample_size() - 200.0).abs() < 1e-9);
    let _ = s;
}
