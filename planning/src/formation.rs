//! The paper's "traditional method" baseline (Section 5.4): the fixed-formation flight group. All UAVs
//! are commanded one common heading — the bearing from the formation's centroid to ẑ — with no
//! optimisation, so the formation keeps its shape while closing in.
//!
//! Each UAV's command is the common heading clamped first into its heading cone `α_i ± Δα` (eq. 58) and
//! then into its turn-rate limit `ψ_i ± L/R_min` (eq. 55). The turn limit is applied last because it is
//! physical: when the two intervals do not overlap the UAV turns as far as it can towards the cone and
//! the plan reports the cone as violated. (Our reading: the paper does not say how the formation
//! handles the limits; with the nominal geometry neither binds for long.)
//!
//! Units: metres, radians.

use nalgebra::Vector2;

use crate::constraints::Constraints;
use model::kinematics::{bearing, turn_angle, wrap_angle};

/// The formation's headings in (−π, π]: the centroid-to-ẑ bearing, clamped per UAV as described above.
/// `positions` and `headings` are the current ones (same length, at least one UAV).
pub fn formation_headings(
    positions: &[Vector2<f64>],
    headings: &[f64],
    estimate: Vector2<f64>,
    constraints: &Constraints,
) -> Vec<f64> {
    let n = positions.len().max(1) as f64;
    let centroid = positions.iter().fold(Vector2::zeros(), |acc, p| acc + p) / n;
    let common = bearing(centroid, estimate);
    let max_turn = constraints.max_turn();
    positions
        .iter()
        .zip(headings)
        .map(|(p, &psi)| {
            let alpha = bearing(*p, estimate);
            let da = constraints.delta_alpha;
            let in_cone = alpha + turn_angle(alpha, common).clamp(-da, da);
            wrap_angle(psi + turn_angle(psi, in_cone).clamp(-max_turn, max_turn))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::constraints::tests::constraints;

    #[test]
    fn common_heading_when_unconstrained() {
        let p = vec![Vector2::new(0.0, 0.0), Vector2::new(0.0, 1000.0), Vector2::new(1000.0, 0.0)];
        let z = Vector2::new(30000.0, 30000.0);
        let h: Vec<f64> = p.iter().map(|q| bearing(*q, z)).collect();
        let out = formation_headings(&p, &h, z, &constraints());
        let c = bearing(Vector2::new(1000.0 / 3.0, 1000.0 / 3.0), z);
        for o in out {
            assert!((o - c).abs() < 1e-12);
        }
    }

    #[test]
    fn clamped_to_turn_limit_and_cone() {
        let c = constraints();
        // UAV 0 currently flies away from ẑ: it turns by the most it can (0.5 rad).
        let p = vec![Vector2::new(0.0, 0.0), Vector2::new(0.0, 1000.0), Vector2::new(1000.0, 0.0)];
        let z = Vector2::new(30000.0, 0.0);
        let mut h: Vec<f64> = p.iter().map(|q| bearing(*q, z)).collect();
        h[0] = 2.0;
        let out = formation_headings(&p, &h, z, &c);
        assert!((turn_angle(h[0], out[0]).abs() - 0.5).abs() < 1e-12);
        // UAV 2 is far off the centroid line: its heading stays inside its cone.
        let p = vec![Vector2::new(0.0, 0.0), Vector2::new(0.0, 1000.0), Vector2::new(25000.0, 20000.0)];
        let h: Vec<f64> = p.iter().map(|q| bearing(*q, z)).collect();
        let out = formation_headings(&p, &h, z, &c);
        let alpha = bearing(p[2], z);
        assert!(turn_angle(alpha, out[2]).abs() <= c.delta_alpha + 1e-12);
    }
}
