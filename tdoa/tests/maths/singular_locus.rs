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
        // A point well away from every piece is regular.
        let d = set.iter().map(|p| p.distance(&sc.target)).fold(f64::INFINITY, f64::min);
        prop_assert!(d >= 1000.0);
        prop_assert!(rcond(&sc.sensors, &sc.target) > 1e-12);
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
