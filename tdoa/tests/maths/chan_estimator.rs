//! Chan's estimator: exactness on noise-free input, equivariance, degenerate geometry, and Monte Carlo
//! RMSE against the CRLB.

use crate::common;

use common::{NOMINAL_SIGMA, config, nominal, scene};
use nalgebra::{Rotation2, Vector2};
use proptest::prelude::*;
use tdoa::montecarlo::{noisy_range_diffs, rmse};
use tdoa::rng::{Purpose, stream};
use tdoa::{NoiseModel, RangeDiffs, Sensors, TdoaError, chan, crlb, maximum_likelihood};

fn transformed(s: &Sensors, rot: &Rotation2<f64>, shift: Vector2<f64>) -> Sensors {
    let w: Vec<[f64; 2]> = s.positions().iter().map(|p| rot * p + shift).map(|p| [p.x, p.y]).collect();
    s.with_positions(&w).unwrap()
}

proptest! {
    #![proptest_config(config(128))]

    #[test]
    fn noise_free_input_returns_the_truth(sc in scene()) {
        let d = sc.sensors.range_differences(&sc.target);
        let sol = chan(&sc.sensors, &d, None).unwrap();
        if sol.ambiguous {
            // Two exact solutions: the truth is one of them, and a nearby prior picks it.
            prop_assert!(sol.candidates.iter().any(|c| (c - sc.target).norm() < 1e-6));
            let resolved = chan(&sc.sensors, &d, Some(sc.target + Vector2::new(100.0, -100.0))).unwrap();
            prop_assert!(!resolved.ambiguous);
            prop_assert!((resolved.position - sc.target).norm() < 1e-6, "{:?}", resolved.position);
        } else {
            prop_assert!((sol.position - sc.target).norm() < 1e-6, "error {} m", (sol.position - sc.target).norm());
        }
        // The reported covariance is the CRLB at the estimate (exact at zero noise).
        let bound = crlb(&sc.sensors, &sc.target).unwrap().bound;
        let pos = if sol.ambiguous { sc.target } else { sol.position };
        let sol2 = chan(&sc.sensors, &d, Some(pos)).unwrap();
        prop_assert!((sol2.covariance - bound).norm() <= 1e-6 * bound.norm(), "cov {} vs crlb {}", sol2.covariance, bound);
    }

    #[test]
    fn translation_and_rotation_equivariance(sc in scene(), angle in -std::f64::consts::PI..std::f64::consts::PI, tx in -1e5..1e5f64, ty in -1e5..1e5f64, seed in 0u64..1000) {
        let mut rng = stream(seed, 0, Purpose::MeasurementNoise);
        let d = noisy_range_diffs(&sc.sensors, &sc.target, &mut rng);
        let prior = sc.target + Vector2::new(50.0, 50.0);
        let rot = Rotation2::new(angle);
        let shift = Vector2::new(tx, ty);
        let moved = transformed(&sc.sensors, &rot, shift);
        // A failure is equivariant too: the moved scene fails exactly when the original does.
        let (a, b) = match (chan(&sc.sensors, &d, Some(prior)), chan(&moved, &d, Some(rot * prior + shift))) {
            (Ok(a), Ok(b)) => (a, b),
            (Err(_), Err(_)) => return Ok(()),
            (a, b) => return Err(TestCaseError::fail(format!("one scene failed: {:?} vs {:?}", a.err(), b.err()))),
        };
        let scale = sc.sensors.positions().iter().map(|w| (w - sc.target).norm()).fold(0.0, f64::max);
        prop_assert!((b.position - (rot * a.position + shift)).norm() <= 1e-7 * scale,
            "{} vs {}", b.position, rot * a.position + shift);
        let rc = rot.matrix() * a.covariance * rot.matrix().transpose();
        prop_assert!((b.covariance - rc).norm() <= 1e-6 * rc.norm());
    }
}

#[test]
fn nominal_geometry_gives_the_papers_crlb() {
    // 57.543·σ at the paper's nominal geometry; 1655.58 m with σ = 28.7712 m (paper Table 9).
    let (s1, z) = nominal(1.0);
    assert!((crlb(&s1, &z).unwrap().crlb_m - 57.543).abs() < 5e-4);
    let (s, z) = nominal(NOMINAL_SIGMA);
    assert!((crlb(&s, &z).unwrap().crlb_m - 1655.58).abs() < 0.005);
    // Linear in σ.
    let (s2, _) = nominal(2.0 * NOMINAL_SIGMA);
    assert!((crlb(&s2, &z).unwrap().crlb_m - 2.0 * 1655.5822).abs() < 0.01);
}

#[test]
fn monte_carlo_rmse_matches_the_crlb_for_3_4_and_5_uavs() {
    let (s, z) = nominal(NOMINAL_SIGMA);
    let extra = [[0.0, 9000.0], [12000.0, 7000.0]];
    for n in 3..=5 {
        let mut w: Vec<[f64; 2]> = s.positions().iter().map(|p| [p.x, p.y]).collect();
        w.extend_from_slice(&extra[..n - 3]);
        let sn = Sensors::new(&w, NoiseModel::uniform(n, NOMINAL_SIGMA).unwrap()).unwrap();
        let r = rmse(&sn, &z, 4000, 11, None).unwrap();
        assert_eq!(r.failures, 0, "{n} UAVs");
        assert!((r.ratio - 1.0).abs() < 0.05, "{n} UAVs: RMSE/CRLB = {}", r.ratio);
    }
}

/// Four UAVs on a square (10 km side) with the emitter at its centre — where a swarm that surrounds the
/// emitter ends — inside it, or on an axis of symmetry far out: Chan's two-step WLS loses the emitter
/// there (RMSE tens to hundreds of times the CRLB over 4000 draws); the maximum likelihood started from
/// it is within 10 % of the CRLB at every one, and so is it away from the square's axes.
#[test]
fn the_maximum_likelihood_keeps_the_crlb_inside_and_on_the_axes_of_a_square() {
    let w = [[-5000.0, 20000.0], [5000.0, 20000.0], [-5000.0, 30000.0], [5000.0, 30000.0]];
    let s = Sensors::new(&w, NoiseModel::uniform(4, NOMINAL_SIGMA).unwrap()).unwrap();
    let mut rng = stream(11, 0, Purpose::MeasurementNoise);
    for z in [
        Vector2::new(0.0, 25000.0),
        Vector2::new(1500.0, 24000.0),
        Vector2::new(0.0, 0.0),
        Vector2::new(12000.0, -7000.0),
    ] {
        let (mut plain, mut ml, draws) = (0.0, 0.0, 4000);
        for _ in 0..draws {
            let d = noisy_range_diffs(&s, &z, &mut rng);
            plain += (chan(&s, &d, None).unwrap().position - z).norm_squared();
            ml += (maximum_likelihood(&s, &d, None).unwrap().position - z).norm_squared();
        }
        let bound = crlb(&s, &z).unwrap().crlb_m;
        let (plain, ml) = ((plain / draws as f64).sqrt() / bound, (ml / draws as f64).sqrt() / bound);
        eprintln!("emitter at {z:?}: RMSE/CRLB {ml:.3} (Chan alone {plain:.3})");
        assert!((0.9..1.1).contains(&ml), "emitter at {z:?}: RMSE/CRLB {ml} (Chan alone {plain})");
        if z == Vector2::new(0.0, 25000.0) {
            assert!(plain > 10.0, "Chan alone at the centre: {plain}");
        }
    }
}

#[test]
fn empirical_covariance_of_noise_draws_is_q() {
    let s = Sensors::new(
        &[[0.0, 0.0], [1000.0, 0.0], [0.0, 1000.0], [900.0, 900.0]],
        NoiseModel::from_range_sigmas(&[3.0, 5.0, 7.0, 11.0]).unwrap(),
    )
    .unwrap();
    let z = Vector2::new(4000.0, 2500.0);
    let truth = s.range_differences(&z);
    let q = s.noise().q();
    let mut rng = stream(5, 0, Purpose::MeasurementNoise);
    let n = 40_000;
    let mut acc = nalgebra::DMatrix::<f64>::zeros(3, 3);
    for _ in 0..n {
        let d = noisy_range_diffs(&s, &z, &mut rng);
        let e = nalgebra::DVector::from_iterator(3, d.as_slice().iter().zip(truth.as_slice()).map(|(a, b)| a - b));
        acc += &e * e.transpose();
    }
    acc /= n as f64;
    for i in 0..3 {
        for j in 0..3 {
            assert!(
                (acc[(i, j)] - q[(i, j)]).abs() < 0.04 * q[(i, i)].max(q[(j, j)]),
                "Q[{i},{j}] {} vs {}",
                acc[(i, j)],
                q[(i, j)]
            );
        }
    }
    // Q_ii = s_i² + s_0², Q_ij = s_0².
    assert_eq!(q[(0, 0)], 25.0 + 9.0);
    assert_eq!(q[(1, 2)], 9.0);
}

#[test]
fn time_sigma_in_ns_converts_with_the_speed_of_light() {
    let m = NoiseModel::from_time_sigmas_ns(&[10.0, 10.0, 10.0]).unwrap();
    assert!((m.sigmas()[0] - 2.99792458).abs() < 1e-12);
}

#[test]
fn degenerate_input_is_an_error_not_a_number() {
    let noise3 = NoiseModel::uniform(3, 10.0).unwrap();
    let collinear = Sensors::new(&[[0.0, 0.0], [1000.0, 0.0], [2500.0, 0.0]], noise3.clone()).unwrap();
    let d = RangeDiffs::from_slice(&[100.0, 200.0]).unwrap();
    assert!(matches!(chan(&collinear, &d, None), Err(TdoaError::Degenerate(_))));
    let collinear4 =
        Sensors::new(&[[0.0, 0.0], [1000.0, 0.0], [2500.0, 0.0], [4000.0, 0.0]], NoiseModel::uniform(4, 10.0).unwrap())
            .unwrap();
    let d4 = RangeDiffs::from_slice(&[100.0, 200.0, 300.0]).unwrap();
    assert!(matches!(chan(&collinear4, &d4, None), Err(TdoaError::Degenerate(_))));
    // Wrong number of range differences.
    let tri = Sensors::new(&[[0.0, 0.0], [1000.0, 0.0], [0.0, 1000.0]], noise3.clone()).unwrap();
    assert!(matches!(chan(&tri, &d4, None), Err(TdoaError::LengthMismatch { .. })));
    // Impossible range differences (larger than the baselines): no physical root.
    let bad = RangeDiffs::from_slice(&[5000.0, -5000.0]).unwrap();
    assert!(chan(&tri, &bad, None).is_err());
    // Constructors reject coincident UAVs, too few/many, and bad σ.
    assert!(matches!(
        Sensors::new(&[[0.0, 0.0], [0.0, 0.0], [0.0, 1000.0]], noise3.clone()),
        Err(TdoaError::CoincidentUavs { .. })
    ));
    assert!(matches!(Sensors::new(&[[0.0, 0.0], [1.0, 0.0]], noise3.clone()), Err(TdoaError::UavCount { .. })));
    // A UAV beyond the plane model's extent (a world flown out of it) is out of range, a NaN not finite;
    // the extent itself is taken.
    let m = tdoa::MAX_EXTENT_M;
    assert!(matches!(
        Sensors::new(&[[0.0, 0.0], [1000.0, 0.0], [0.0, -1.5 * m]], noise3.clone()),
        Err(TdoaError::OutOfRange { .. })
    ));
    assert!(matches!(
        Sensors::new(&[[0.0, 0.0], [1000.0, f64::NAN], [0.0, 1000.0]], noise3.clone()),
        Err(TdoaError::NotFinite { .. })
    ));
    assert!(Sensors::new(&[[-m, 0.0], [m, 0.0], [0.0, m]], noise3).is_ok());
    assert!(matches!(NoiseModel::uniform(9, 1.0), Err(TdoaError::UavCount { .. })));
    assert!(matches!(NoiseModel::uniform(3, 0.0), Err(TdoaError::NonPositive { .. })));
    assert!(matches!(NoiseModel::uniform(3, f64::NAN), Err(TdoaError::NotFinite { .. })));
    // A σ whose square or inverse leaves the finite numbers (a CRLB of 0 or ∞ that would read as a
    // singular geometry) is refused as out of range; the extremes themselves are taken.
    for sigma in [1e300, 1e-300, 2.0 * tdoa::MAX_EXTENT_M, 0.5 * tdoa::MIN_SIGMA_M] {
        assert!(matches!(NoiseModel::uniform(3, sigma), Err(TdoaError::OutOfRange { .. })), "{sigma}");
    }
    assert!(NoiseModel::uniform(3, tdoa::MAX_EXTENT_M).is_ok() && NoiseModel::uniform(3, tdoa::MIN_SIGMA_M).is_ok());
    assert!(RangeDiffs::from_slice(&[1.0, f64::INFINITY]).is_err());
}

/// Four UAVs on a rectangle with the emitter on one of its axes of symmetry: `r₀ + r₃ = r₁ + r₂`, so the
/// first step's range column is a combination of the baselines' and the linear system cannot tell r₀
/// from the position — yet the emitter is fixed. Noise-free range differences give the truth, on both
/// axes, near the rectangle and far from it, for rectangles turned and moved anywhere; off the axes
/// the two-step WLS is unchanged.
#[test]
fn a_rectangle_with_the_emitter_on_its_axis_is_solved_exactly() {
    let (half_w, half_h) = (5000.0, 3000.0);
    let corners = [[-half_w, -half_h], [half_w, -half_h], [-half_w, half_h], [half_w, half_h]];
    let noise = NoiseModel::uniform(4, NOMINAL_SIGMA).unwrap();
    for (angle, shift) in
        [(0.0, Vector2::zeros()), (0.7, Vector2::new(12_000.0, -40_000.0)), (-2.1, Vector2::new(-3e5, 2e5))]
    {
        let rot = Rotation2::new(angle);
        let w: Vec<[f64; 2]> =
            corners.iter().map(|c| rot * Vector2::new(c[0], c[1]) + shift).map(|p| [p.x, p.y]).collect();
        let sensors = Sensors::new(&w, noise.clone()).unwrap();
        let along = [-80_000.0, -20_000.0, -2_500.0, 0.0, 700.0, 9_000.0, 60_000.0];
        let on_axes = along.iter().flat_map(|&t| [Vector2::new(t, 0.0), Vector2::new(0.0, t)]);
        for local in on_axes.chain([Vector2::new(700.0, 1_300.0), Vector2::new(-20_000.0, 45_000.0)]) {
            let target = rot * local + shift;
            let d = sensors.range_differences(&target);
            let sol = chan(&sensors, &d, None).unwrap_or_else(|e| panic!("angle {angle}, local {local:?}: {e}"));
            assert!(!sol.ambiguous);
            let error = (sol.position - target).norm();
            assert!(error < 1e-6, "angle {angle}, local {local:?}: {error} m");
            let bound = crlb(&sensors, &target).unwrap().bound;
            assert!((sol.covariance - bound).norm() <= 1e-6 * bound.norm() + 1e-9, "covariance at {local:?}");
        }
    }
}
