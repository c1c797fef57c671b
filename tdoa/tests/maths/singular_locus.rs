//! The singular locus of the FIM and how the global CRLB reports it.

use crate::common;

use common::{config, scene_with};
use nalgebra::{Matrix2, Vector2};
use proptest::prelude::*;
use tdoa::singular::{SingularPiece, singular_set};
use tdoa::{Method, NoiseModel, Sensors, TdoaError, Uncertainty, crlb, fim, global_crlb, trace_crlb};

fn triangle() -> Sensors {
    Sensors::new(&[[0.0, 0.0], [1000.0, 0.0], [0.0, 1000.0]], NoiseModel::uniform(3, 10.0).unwrap()).unwrap()
}

#[test]
fn crlb_on_a_baseline_extension_is_an_error_and_trace_is_infinite() {
    let s = triangle();
    let z = Vector2::new(5000.0, 0.0);
    assert!(matches!(crlb(&s, &z), Err(TdoaError::Degenerate(_))));
    assert!(trace_crlb(&s, &z).is_infinite());
    // On the segment between the two UAVs it is regular.
    assert!(crlb(&s, &Vector2::new(500.0, 0.0)).is_ok());
    // On top of a UAV: error too.
    assert!(crlb(&s, &Vector2::new(1000.0, 0.0)).is_err());
}

#[test]
fn trace_grows_like_inverse_square_distance_near_the_extension() {
    let s = triangle();
    let h = |d: f64| trace_crlb(&s, &Vector2::new(5000.0, d));
    for d in [10.0, 1.0, 0.1] {
        let ratio = h(d / 2.0) * (d / 2.0).powi(2) / (h(d) * d * d);
        assert!((ratio - 1.0).abs() < 0.05, "h·d² not constant: ratio {ratio} at d = {d}");
    }
}

#[test]
fn global_crlb_flags_a_support_that_reaches_the_extension() {
    let s = triangle();
    let u = Uncertainty::new(Vector2::new(3000.0, 10.0), Matrix2::new(1e4, 0.0, 0.0, 1e4), 600.0).unwrap();
    for m in Method::ALL {
        let r = global_crlb(m.build(200, 1).unwrap().as_ref(), &s, &u);
        assert!(r.singular.intersects_support, "{m}");
        assert!((r.singular.distance_m - 10.0).abs() < 1e-9, "{m}: distance {}", r.singular.distance_m);
        match m {
            Method::Mc | Method::Quadrature | Method::Cubature => {
                assert!(r.value.trace_m2.is_infinite(), "{m} returned {}", r.value.trace_m2)
            }
            Method::Single | Method::Analytical => assert!(r.value.trace_m2.is_finite(), "{m}"),
        }
    }
    // Moved away so that the square no longer reaches the line: finite, not flagged.
    let far = Uncertainty::new(Vector2::new(3000.0, 2000.0), Matrix2::new(1e4, 0.0, 0.0, 1e4), 600.0).unwrap();
    let r = global_crlb(Method::Quadrature.build(200, 1).unwrap().as_ref(), &s, &far);
    assert!(!r.singular.intersects_support && r.value.trace_m2.is_finite());
}

fn rcond(s: &Sensors, p: &Vector2<f64>) -> f64 {
    let f = fim(s, p).unwrap();
    let (lo, hi) = tdoa::fim::sym_eigenvalues(&f);
    lo / hi
}

fn sample_points(piece: &SingularPiece) -> Vec<Vector2<f64>> {
    match *piece {
        SingularPiece::Point(p) => vec![p],
        SingularPiece::Ray { origin, dir } => [50.0, 700.0, 9000.0].iter().map(|t| origin + dir * *t).collect(),
        SingularPiece::Segment { a, b } => [0.3, 0.7].iter().map(|t| a + (b - a) * *t).collect(),
    }
}

proptest! {
    #![proptest_config(config(64))]

    #[test]
    fn every_reported_piece_is_singular(sc in scene_with(3..=6)) {
        let set = singular_set(&sc.sensors);
        if sc.sensors.len() == 3 {
            // Three baseline pairs, two outward rays each.
            prop_assert_eq!(set.iter().filter(|p| matches!(p, SingularPiece::Ray { .. })).count(), 6);
        }
        for piece in &set {
            for p in sample_points(piece) {
                if sc.sensors.positions().iter().all(|w| (w - p).norm() > 1.0) {
                    prop_assert!(rcond(&sc.sensors, &p) < 1e-9, "{piece:?} at {p}: rcond {}", rcond(&sc.sensors, &p));
                }
            }
        }
    }

    /// The reported set is complete: every point where the FIM is singular lies on a reported piece. A line
    /// through the UAVs' centroid is scanned for the zeros of λmin/λmax (each local minimum refined by
    /// golden-section search); every zero found must be on a piece. With 3 UAVs such a line meets the
    /// lines of the three baselines; drawn through a point beyond a baseline's ends, it must find a zero there.
    #[test]
    fn every_singular_point_on_a_line_is_reported(sc in scene_with(3..=6), angle in 0.0..std::f64::consts::PI, k in 0usize..3, beyond in 0.2..2.0f64) {
        let set = singular_set(&sc.sensors);
        let pos = sc.sensors.positions();
        let c = pos.iter().fold(Vector2::zeros(), |a, w| a + w) / pos.len() as f64;
        let extent = pos.iter().map(|w| (w - c).norm()).fold(0.0, f64::max);
        // With 3 UAVs: the line through the centroid and a point beyond the ends of baseline k, where the
        // FIM is singular; with more, a line at a random angle.
        let [i, j] = [[0, 1], [1, 2], [2, 0]][k];
        let dir = if pos.len() == 3 {
            (pos[j] + (pos[j] - pos[i]) * beyond - c).normalize()
        } else {
            Vector2::new(angle.cos(), angle.sin())
        };
        let at = |t: f64| c + dir * t;
        let f = |t: f64| {
            let p = at(t);
            if pos.iter().any(|w| (w - p).norm() < 1e-6 * extent) { 1.0 } else { rcond(&sc.sensors, &p) }
        };
        let n = 20_000;
        let ts: Vec<f64> = (0..=n).map(|i| -20.0 * extent + 40.0 * extent * i as f64 / n as f64).collect();
        let rc: Vec<f64> = ts.iter().map(|t| f(*t)).collect();
        let mut zeros = 0;
        for i in 1..n {
            if !(rc[i] <= rc[i - 1] && rc[i] <= rc[i + 1] && rc[i] < 1e-3) {
                continue;
            }
            // Golden-section search for the minimum on [t_{i-1}, t_{i+1}].
            let (mut a, mut b) = (ts[i - 1], ts[i + 1]);
            let g = (5f64.sqrt() - 1.0) / 2.0;
            for _ in 0..80 {
                let (x1, x2) = (b - g * (b - a), a + g * (b - a));
                if f(x1) < f(x2) { b = x2 } else { a = x1 }
            }
            let t = 0.5 * (a + b);
            if f(t) < 1e-9 {
                zeros += 1;
                let d = set.iter().map(|piece| piece.distance(&at(t))).fold(f64::INFINITY, f64::min);
                prop_assert!(d < 1e-4 * extent, "singular at {} (rcond {}), {d} m from every reported piece", at(t), f(t));
            }
        }
        if pos.len() == 3 {
            prop_assert!(zeros >= 1, "no singular point found on the line at {angle} rad");
        }
    }
}

#[test]
fn four_uavs_in_general_position_are_singular_only_at_isolated_points() {
    let s = Sensors::new(
        &[[0.0, 0.0], [1000.0, 0.0], [0.0, 1000.0], [3000.0, 2000.0]],
        NoiseModel::uniform(4, 10.0).unwrap(),
    )
    .unwrap();
    let set = singular_set(&s);
    assert!(!set.is_empty());
    assert!(set.iter().all(|p| matches!(p, SingularPiece::Point(_))), "{set:?}");
    // The extension of one baseline is regular away from those points (unlike the 3-UAV case).
    assert!(crlb(&s, &Vector2::new(-5000.0, 0.0)).is_ok());
}
