//! The constraints of eqs. 55–58 against their definitions, over random plans:
//! - the heading cone wraps at every bearing α, not only at ±π: a heading `α + δ + 2πk` is `|δ|` off
//!   the bearing (δ wrapped), whatever k;
//! - a plan's total violation is zero exactly when every constraint holds, each checked here from its
//!   definition (turn ≤ L/R_min, every pair of waypoints ≥ D_min apart, every waypoint ≥ L_min from ẑ,
//!   every heading within Δα of its bearing); plans within 10⁻⁶ of a bound are left out (the binding
//!   tolerance decides those).

use model::kinematics::{bearing, next_position, turn_angle, wrap_angle};
use nalgebra::Vector2;
use planning::Constraints;
use proptest::prelude::*;

fn constraints(speed: f64, dt: f64, r_min: f64, d_min: f64, l_min: f64, delta_alpha: f64) -> Constraints {
    // The paper's constraints (no chance bound, no turn-aware standoff).
    let sc = model::Scenario {
        speed,
        dt,
        r_min,
        d_min,
        l_min,
        delta_alpha,
        standoff_confidence: 0.0,
        ..model::Scenario::default()
    };
    Constraints::from_scenario(&sc)
}

fn config() -> ProptestConfig {
    ProptestConfig {
        cases: 512,
        rng_seed: proptest::test_runner::RngSeed::Fixed(0xC00E_5EED),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn the_cone_wraps_at_every_bearing(
        ex in -3e4..3e4f64, ey in -3e4..3e4f64, delta in -3.1..3.1f64, k in -3i32..=3,
        delta_alpha in 0.05..1.5f64,
    ) {
        let c = constraints(50.0, 10.0, 0.0, 0.0, 0.0, delta_alpha);
        let p = Vector2::zeros();
        let e = Vector2::new(ex, ey);
        prop_assume!(e.norm() > 1.0);
        let alpha = bearing(p, e);
        let heading = alpha + delta + std::f64::consts::TAU * f64::from(k);
        let next = next_position(p, heading, heading, 50.0, 10.0);
        let report = c.check(&[p], &[heading], e, &[heading], &[next]);
        let cone = report.active.iter().find(|a| a.kind == planning::ConstraintKind::HeadingCone);
        let off = wrap_angle(delta).abs();
        prop_assume!((off - delta_alpha).abs() > 1e-6);
        if off > delta_alpha {
            let a = cone.expect("the cone is violated");
            prop_assert!((a.value - off).abs() < 1e-9, "{} vs {off}", a.value);
            prop_assert!(!report.is_feasible());
        } else {
            prop_assert!(report.is_feasible(), "{report:?}");
        }
        // The cone the planner searches contains the heading exactly when it is feasible.
        let (lo, hi) = c.cone(p, e);
        let unwrapped = lo + (heading - lo).rem_euclid(std::f64::consts::TAU);
        prop_assert_eq!(unwrapped <= hi, off <= delta_alpha);
    }

    #[test]
    fn the_violation_is_zero_exactly_when_every_constraint_holds(
        n in 2usize..6,
        seed in prop::collection::vec((-4e3..4e3f64, -4e3..4e3f64, -3.2..3.2f64, -1.2..1.2f64), 6),
        ex in -6e3..6e3f64, ey in -6e3..6e3f64,
        r_min in 0.0..2000.0f64, d_min in 0.0..1500.0f64, l_min in 0.0..3000.0f64, delta_alpha in 0.1..1.6f64,
    ) {
        let (speed, dt) = (50.0, 10.0);
        let c = constraints(speed, dt, r_min, d_min, l_min, delta_alpha);
        let e = Vector2::new(ex, ey);
        let positions: Vec<Vector2<f64>> = seed[..n].iter().map(|s| Vector2::new(s.0, s.1)).collect();
        let headings: Vec<f64> = seed[..n].iter().map(|s| s.2).collect();
        // New headings near the bearing to ẑ, so that every outcome occurs.
        let new: Vec<f64> = positions.iter().zip(&seed).map(|(p, s)| bearing(*p, e) + s.3).collect();
        let next: Vec<Vector2<f64>> =
            positions.iter().zip(&headings).zip(&new).map(|((p, psi), phi)| next_position(*p, *psi, *phi, speed, dt)).collect();
        // Each constraint from its definition, as a signed relative margin (≥ 0: holds).
        let mut margins = Vec::new();
        let theta_max = (speed * dt / r_min).min(std::f64::consts::PI);
        for i in 0..n {
            if r_min > 0.0 {
                margins.push((theta_max - turn_angle(headings[i], new[i]).abs()) / theta_max);
            }
            margins.push((delta_alpha - wrap_angle(new[i] - bearing(positions[i], e)).abs()) / delta_alpha);
            if l_min > 0.0 {
                margins.push(((next[i] - e).norm() - l_min) / l_min);
            }
            for j in i + 1..n {
                if d_min > 0.0 {
                    margins.push(((next[i] - next[j]).norm() - d_min) / d_min);
                }
            }
        }
        prop_assume!(margins.iter().all(|m| m.abs() > 1e-6));
        let holds = margins.iter().all(|m| *m > 0.0);
        let report = c.check(&positions, &headings, e, &new, &next);
        prop_assert_eq!(report.is_feasible(), holds, "{:?} / {:?}", margins, report);
        prop_assert_eq!(c.violation(&positions, &headings, e, &new, &next), report.violation);
        let by_kind: f64 = c.violations_by_kind(&positions, &headings, e, &new, &next).iter().sum();
        prop_assert!((by_kind - report.violation).abs() <= 1e-12 * report.violation.max(1.0));
    }
}
