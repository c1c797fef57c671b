//! Fixed-speed circular-arc motion of one UAV over one planning interval (paper Section 3.5, eq. 54).
//!
//! A UAV at `p` flying with heading `ψ` that is commanded the new heading `φ` flies, at constant speed
//! `v` for `Δt`, an arc of length `L = v·Δt` that starts tangent to `ψ` and ends with heading `φ`:
//!
//! - turn angle (the arc's central angle) `θ = wrap(φ − ψ)` in (−π, π],
//! - turn radius `R = L / |θ|` (∞ for a straight flight, `θ = 0`),
//! - the chord from `p` to the next waypoint has length `2R·sin(|θ|/2)` (eq. 54) and direction `ψ + θ/2`.
//!
//! The turn-radius constraint `R ≥ R_min` is therefore `|θ| ≤ L / R_min` ([`max_turn`]).
//!
//! Units: metres, seconds, radians; headings are measured from the +x axis, counter-clockwise.

use std::f64::consts::{PI, TAU};

use nalgebra::Vector2;

/// Wraps an angle into (−π, π], radians.
#[inline]
pub fn wrap_angle(a: f64) -> f64 {
    // `rem_euclid` is `fmod` then `+ TAU` for a negative remainder; `fmod(a, TAU)` is exactly `a` when
    // |a| < TAU, so that case skips the `fmod` call and gives the same bits.
    let r = if a.abs() < TAU { if a < 0.0 { a + TAU } else { a } } else { a.rem_euclid(TAU) };
    if r > PI { r - TAU } else { r }
}

/// Bearing from `from` to `to`, radians in (−π, π] (the paper's `α_i` of eq. 58 when `to` is ẑ).
#[inline]
pub fn bearing(from: Vector2<f64>, to: Vector2<f64>) -> f64 {
    let d = to - from;
    d.y.atan2(d.x)
}

/// Turn (central) angle `θ = wrap(φ − ψ)` in (−π, π], radians, from heading `psi` to heading `phi`.
#[inline]
pub fn turn_angle(psi: f64, phi: f64) -> f64 {
    wrap_angle(phi - psi)
}

/// Turn radius `R = L / |θ|` (metres) of the arc of length `arc_len` (metres) from heading `psi` to
/// `phi` (radians); `+∞` when the headings are equal.
#[inline]
pub fn turn_radius(psi: f64, phi: f64, arc_len: f64) -> f64 {
    let theta = turn_angle(psi, phi).abs();
    if theta == 0.0 { f64::INFINITY } else { arc_len / theta }
}

/// Largest turn angle (radians, at most π) that keeps the radius of an arc of length `arc_len` at or
/// above `r_min` (both metres): `min(π, L / R_min)`; π (no limit) for `r_min = 0`.
#[inline]
pub fn max_turn(arc_len: f64, r_min: f64) -> f64 {
    if r_min <= 0.0 { PI } else { (arc_len / r_min).min(PI) }
}

/// Length of the chord of an arc of length `arc_len` (metres) turning by `theta` (radians):
/// `2R·sin(|θ|/2) = L·sin(θ/2)/(θ/2)` (eq. 54), equal to `L` for `θ = 0`.
#[inline]
pub fn chord_length(arc_len: f64, theta: f64) -> f64 {
    let h = 0.5 * theta;
    if h == 0.0 { arc_len } else { arc_len * h.sin() / h }
}

/// Position (metres) after flying for `dt` seconds at `v` m/s from `p` with heading `psi`, turning
/// along a circular arc to end with heading `phi` (radians).
#[inline]
pub fn next_position(p: Vector2<f64>, psi: f64, phi: f64, v: f64, dt: f64) -> Vector2<f64> {
    let theta = turn_angle(psi, phi);
    let chord = chord_length(v * dt, theta);
    let dir = psi + 0.5 * theta;
    p + Vector2::new(dir.cos(), dir.sin()) * chord
}

#[cfg(test)]
mod tests {
    use super::*;

    const EPS: f64 = 1e-9;

    #[test]
    fn wrap_skips_fmod_only_where_it_gives_the_same_bits() {
        let reference = |a: f64| {
            let r = a.rem_euclid(TAU);
            if r > PI { r - TAU } else { r }
        };
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        let mut values = vec![0.0, -0.0, PI, -PI, TAU, -TAU, f64::MIN_POSITIVE, -f64::MIN_POSITIVE, 1e300, -1e300];
        values.extend([TAU - 1e-15, -TAU + 1e-15, TAU.next_down(), (-TAU).next_up(), PI.next_up(), (-PI).next_down()]);
        for _ in 0..200_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            values.push((x as f64 / u64::MAX as f64 - 0.5) * 4.0 * TAU);
        }
        for a in values {
            assert_eq!(wrap_angle(a).to_bits(), reference(a).to_bits(), "{a:e}");
        }
        assert!(wrap_angle(f64::NAN).is_nan() && wrap_angle(f64::INFINITY).is_nan());
    }

    #[test]
    fn wrap_stays_in_half_open_interval() {
        assert_eq!(wrap_angle(PI), PI);
        assert_eq!(wrap_angle(-PI), PI);
        assert!((wrap_angle(3.0 * PI) - PI).abs() < EPS);
        assert!((wrap_angle(-0.5 * PI) + 0.5 * PI).abs() < EPS);
        assert!((wrap_angle(TAU + 0.25) - 0.25).abs() < EPS);
        for k in -20..=20 {
            let a = wrap_angle(0.37 * k as f64);
            assert!(a > -PI && a <= PI, "{a}");
        }
    }

    #[test]
    fn bearing_matches_axes() {
        let o = Vector2::new(1.0, 1.0);
        assert!((bearing(o, Vector2::new(2.0, 1.0))).abs() < EPS);
        assert!((bearing(o, Vector2::new(1.0, 5.0)) - 0.5 * PI).abs() < EPS);
        assert!((bearing(o, Vector2::new(-3.0, 1.0)) - PI).abs() < EPS);
    }

    #[test]
    fn straight_flight_moves_exactly_l() {
        let p = Vector2::new(100.0, -50.0);
        let psi = 0.7;
        let q = next_position(p, psi, psi, 50.0, 10.0);
        assert!(((q - p).norm() - 500.0).abs() < EPS);
        assert!((bearing(p, q) - psi).abs() < EPS);
        assert_eq!(turn_radius(psi, psi, 500.0), f64::INFINITY);
    }

    #[test]
    fn chord_equals_two_r_sin_half_theta() {
        let p = Vector2::new(0.0, 0.0);
        for &(psi, phi) in &[(0.0, 0.3), (1.0, 0.2), (-2.0, -2.9), (0.0, PI), (3.0, -3.0)] {
            let q = next_position(p, psi, phi, 50.0, 10.0);
            let theta = turn_angle(psi, phi);
            let r = turn_radius(psi, phi, 500.0);
            let expected = 2.0 * r * (0.5 * theta.abs()).sin();
            assert!(((q - p).norm() - expected).abs() < 1e-7, "psi {psi} phi {phi}");
            // The chord bisects the turn.
            assert!((wrap_angle(bearing(p, q) - (psi + 0.5 * theta))).abs() < 1e-9);
        }
    }

    #[test]
    fn arc_geometry_matches_circle() {
        // Left turn by θ around the centre p + R·n (n the left normal of ψ).
        let (psi, phi, l) = (0.4, 1.1, 500.0);
        let theta = turn_angle(psi, phi);
        let r = l / theta;
        let p = Vector2::new(10.0, 20.0);
        let centre = p + Vector2::new(-psi.sin(), psi.cos()) * r;
        let q = next_position(p, psi, phi, 50.0, 10.0);
        assert!(((q - centre).norm() - r).abs() < 1e-7);
        // Tangent at q is φ: centre-to-q direction is φ − π/2.
        assert!(wrap_angle(bearing(centre, q) - (phi - 0.5 * PI)).abs() < 1e-9);
    }

    #[test]
    fn turn_wraps_across_pi() {
        let psi = 179f64.to_radians();
        let phi = (-179f64).to_radians();
        let theta = turn_angle(psi, phi);
        assert!((theta - 2f64.to_radians()).abs() < 1e-12, "{theta}");
        assert!((turn_radius(psi, phi, 500.0) - 500.0 / 2f64.to_radians()).abs() < 1e-6);
        let q = next_position(Vector2::zeros(), psi, phi, 50.0, 10.0);
        // Nearly straight towards −x.
        assert!(q.x < -499.0 && q.y.abs() < 10.0, "{q}");
    }

    #[test]
    fn max_turn_is_arc_over_radius() {
        assert!((max_turn(500.0, 1000.0) - 0.5).abs() < EPS);
        assert_eq!(max_turn(500.0, 0.0), PI);
        assert_eq!(max_turn(5000.0, 1.0), PI);
        // |θ| = L/R_min gives exactly R_min.
        assert!((turn_radius(0.0, 0.5, 500.0) - 1000.0).abs() < 1e-9);
    }
}
