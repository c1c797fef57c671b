//! The arc of eq. 54 against a fine numerical integration of the motion it stands for: constant speed
//! `v`, heading turning at the constant rate `θ/Δt` from `ψ` to `ψ + θ` (θ the wrapped turn to `φ`).
//! Integrated with the midpoint rule in 20 000 steps (error ≈ L·(θ/20 000)² / 24: below a micrometre).

use model::arc::Arc;
use model::kinematics::{next_position, turn_angle, wrap_angle};
use nalgebra::Vector2;
use proptest::prelude::*;

const STEPS: usize = 20_000;

/// The position after the fraction `s` of the interval, by integrating the velocity.
fn integrate(p: Vector2<f64>, psi: f64, theta: f64, length: f64, s: f64) -> Vector2<f64> {
    let n = ((STEPS as f64 * s).ceil() as usize).max(1);
    let h = s / n as f64;
    let mut q = p;
    for k in 0..n {
        let heading = psi + theta * (k as f64 + 0.5) * h;
        q += Vector2::new(heading.cos(), heading.sin()) * (length * h);
    }
    q
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 256,
        rng_seed: proptest::test_runner::RngSeed::Fixed(0x0A2C_5EED),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn the_arc_is_the_integrated_path(
        x in -5e4..5e4f64, y in -5e4..5e4f64,
        psi in -10.0..10.0f64, phi in -10.0..10.0f64,
        v in 1.0..120.0f64, dt in 0.5..20.0f64, s in 0.0..=1.0f64,
    ) {
        let p = Vector2::new(x, y);
        let length = v * dt;
        let theta = turn_angle(psi, phi);
        prop_assert!(theta.abs() <= std::f64::consts::PI + 1e-12);
        let arc = Arc::new(p, psi, phi, length);
        let tol = 1e-6 * length.max(1.0);
        // Anywhere along it, and at its end (the waypoint of eq. 54, also `next_position`).
        let reference = integrate(p, psi, theta, length, s);
        prop_assert!((arc.at(s) - reference).norm() <= tol, "s = {s}: {} vs {reference}", arc.at(s));
        let end = integrate(p, psi, theta, length, 1.0);
        prop_assert!((arc.end() - end).norm() <= tol);
        prop_assert!((next_position(p, psi, phi, v, dt) - end).norm() <= tol);
        // It ends on the commanded heading, and its length is v·Δt (the integrated path's by construction).
        prop_assert!(wrap_angle(arc.heading_at(1.0) - phi).abs() <= 1e-9);
        // The chord never exceeds the arc.
        prop_assert!((arc.end() - p).norm() <= length * (1.0 + 1e-12));
    }
}
