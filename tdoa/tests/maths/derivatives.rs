//! The closed-form derivatives of F and of h = tr F⁻¹ (eqs. 67–73) against central finite differences.

use crate::common;

use common::scene;
use nalgebra::{Matrix2, Vector2};
use proptest::prelude::*;
use tdoa::{fim, fim_derivatives, trace_crlb, trace_derivatives};

fn unit(p: usize) -> Vector2<f64> {
    if p == 0 { Vector2::x() } else { Vector2::y() }
}

/// The length over which F varies: the nearest UAV range, shrunk where F is ill-conditioned
/// (there h changes over r/sqrt(cond)).
fn min_range(s: &tdoa::Sensors, z: &Vector2<f64>) -> f64 {
    let r = s.positions().iter().map(|w| (w - z).norm()).fold(f64::INFINITY, f64::min);
    r / tdoa::crlb(s, z).unwrap().cond.sqrt()
}

proptest! {
    #![proptest_config(common::config(96))]

    #[test]
    fn fim_first_and_second_derivatives_match_finite_differences(sc in scene()) {
        let z = sc.target;
        let delta = 1e-4 * min_range(&sc.sensors, &z);
        let d = fim_derivatives(&sc.sensors, &z).unwrap();
        let f = |p: Vector2<f64>| fim(&sc.sensors, &p).unwrap();
        let fd_d = |q: usize, at: Vector2<f64>| (f(at + unit(q) * delta) - f(at - unit(q) * delta)) / (2.0 * delta);
        for p in 0..2 {
            let fd = fd_d(p, z);
            prop_assert!((d.d[p] - fd).norm() <= 1e-6 * d.d[p].norm().max(1e-300) + 1e-9 * d.f.norm() / min_range(&sc.sensors, &z),
                "dF/d{p}: exact {} fd {}", d.d[p], fd);
            for q in 0..2 {
                // Differentiate the exact first derivative, which is itself checked above.
                let fdd: Matrix2<f64> = (fim_derivatives(&sc.sensors, &(z + unit(q) * delta)).unwrap().d[p]
                    - fim_derivatives(&sc.sensors, &(z - unit(q) * delta)).unwrap().d[p]) / (2.0 * delta);
                let scale = d.dd[p][q].norm() + d.d[p].norm() / min_range(&sc.sensors, &z);
                prop_assert!((d.dd[p][q] - fdd).norm() <= 1e-6 * scale, "d2F/d{p}d{q}: exact {} fd {}", d.dd[p][q], fdd);
            }
        }
        // Mixed second derivative is symmetric.
        prop_assert!((d.dd[0][1] - d.dd[1][0]).norm() <= 1e-12 * d.dd[0][1].norm().max(1e-300));
    }

    #[test]
    fn gradient_and_hessian_of_trace_match_finite_differences(sc in scene()) {
        let z = sc.target;
        let r = min_range(&sc.sensors, &z);
        let delta = 1e-4 * r;
        let t = trace_derivatives(&sc.sensors, &z).unwrap();
        prop_assert!((t.value - trace_crlb(&sc.sensors, &z)).abs() <= 1e-12 * t.value);
        let h = |p: Vector2<f64>| trace_crlb(&sc.sensors, &p);
        for p in 0..2 {
            let fd = (h(z + unit(p) * delta) - h(z - unit(p) * delta)) / (2.0 * delta);
            prop_assert!((t.gradient[p] - fd).abs() <= 2e-5 * (t.gradient[p].abs() + t.value / r),
                "dh/d{p}: exact {} fd {}", t.gradient[p], fd);
            for q in 0..2 {
                // Hessian against the central difference of the exact gradient …
                let g = |at: Vector2<f64>| trace_derivatives(&sc.sensors, &at).unwrap().gradient[p];
                let fdd = (g(z + unit(q) * delta) - g(z - unit(q) * delta)) / (2.0 * delta);
                let scale = t.hessian.norm() + t.value / (r * r);
                prop_assert!((t.hessian[(p, q)] - fdd).abs() <= 2e-5 * scale,
                    "d2h/d{p}d{q}: exact {} fd {}", t.hessian[(p, q)], fdd);
            }
        }
        // … and against the plain second difference of h itself (independent of the gradient code).
        let big = 1e-3 * r;
        let hxx = (h(z + unit(0) * big) - 2.0 * t.value + h(z - unit(0) * big)) / (big * big);
        let hxy = (h(z + (unit(0) + unit(1)) * big) - h(z + (unit(0) - unit(1)) * big)
            - h(z + (unit(1) - unit(0)) * big) + h(z - (unit(0) + unit(1)) * big)) / (4.0 * big * big);
        let scale = t.hessian.norm() + t.value / (r * r);
        prop_assert!((t.hessian[(0, 0)] - hxx).abs() <= 1e-3 * scale, "hxx exact {} fd {}", t.hessian[(0, 0)], hxx);
        prop_assert!((t.hessian[(0, 1)] - hxy).abs() <= 1e-3 * scale, "hxy exact {} fd {}", t.hessian[(0, 1)], hxy);
    }
}
