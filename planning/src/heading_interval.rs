//! The headings one UAV may fly this step, on its own: the gradient planner's search box
//! ([`crate::step`], `--solver gradient`).
//!
//! Three of the four constraints (Section 3.5) concern one UAV each and one heading `φ` each: the turn
//! radius (a box: `|φ − ψ| ≤ θ_max`, eq. 55), the heading cone (a box: `|wrap(φ − α)| ≤ Δα`, eqs. 58–59)
//! and the approach distance (eq. 57, with the standoff chance constraint of [`crate::constraints`]: a
//! smooth function of `φ` through the arc kinematics). Only the spacing (eq. 56) and the criterion couple
//! the UAVs. So the lexicographic order of the planner's standoff tiers (turn radius and spacing, then
//! approach, then cone, then the criterion) can be settled per UAV before any search:
//!
//! 1. the *reachable* headings `[ψ − θ_max, ψ + θ_max]` (unwrapped around the current heading ψ);
//! 2. in them, the headings that keep the approach distance: the approach violation is sampled at
//!    [`SAMPLES`] + 1 evenly spaced headings and every change between allowed and not is bisected to
//!    [`BISECTIONS`] halvings (the allowed side kept), so each end is exact to ≈ 1e-12 rad (the
//!    certificate's own part, costlier to evaluate, at [`CERTIFIED_RESOLUTION`]: ≤ 3e-9 rad);
//! 3. the allowed headings in the cone (the cone taken modulo 2π): when there are some, that interval
//!    — the one holding the current heading moved into the cone, else the widest — is the UAV's box;
//! 4. else the UAV is *pinned* to the allowed heading nearest the cone (the least cone violation that
//!    keeps the approach distance);
//! 5. else (no reachable heading keeps the approach distance) to the reachable heading of least
//!    approach violation (the best sample refined by golden-section search).
//!
//! Every heading of the box so built meets the per-UAV constraints as well as any reachable heading can,
//! so the search over the product of the boxes only weighs the criterion (and the spacing, the one
//! coupling constraint, which the planner checks after it). Units: radians, metres.

use std::f64::consts::{PI, TAU};

use nalgebra::Vector2;

use crate::constraints::Constraints;
use model::kinematics::{bearing, next_position, turn_angle};

/// Intervals the reachable headings are sampled in (the approach constraint's allowed set is found
/// from the sign changes between the samples).
pub const SAMPLES: usize = 32;
/// Halvings of each bracket of a change between allowed and not (2θ_max/32/2⁴⁰ ≈ 1e-14 rad).
pub const BISECTIONS: usize = 40;
/// How finely a box's ends are found: the intervals the reachable headings are sampled in, and the
/// halvings of each bracket of a change between allowed and not.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Resolution {
    /// Intervals the reachable headings are sampled in (`intervals + 1` evaluations).
    pub intervals: usize,
    /// Halvings of each bracket.
    pub bisections: usize,
}

/// The approach distance's boxes: [`SAMPLES`] intervals, [`BISECTIONS`] halvings (≈ 1e-14 rad).
pub const EXACT_RESOLUTION: Resolution = Resolution { intervals: SAMPLES, bisections: BISECTIONS };

/// A box whose violation is costly to evaluate (the safety certificate's own part,
/// [`crate::shield::Shield::own_deficit`]): 16 intervals and 27 halvings, 2θ_max/16/2²⁷ ≤ 3e-9 rad at
/// the ends — a few micrometres of a step's arc, far below what the criterion or the certificate's own
/// brackets resolve — with 16 fewer samples than [`EXACT_RESOLUTION`] and 13 fewer halvings per end. A run
/// of allowed or refused headings narrower than 2θ_max/16 between two samples can be missed; the box only
/// steers the search, every plan is certified whole (`crate::shield`).
pub const CERTIFIED_RESOLUTION: Resolution = Resolution { intervals: 16, bisections: 27 };
/// Golden-section iterations of the least approach violation when no heading keeps it.
pub const GOLDEN_STEPS: usize = 40;

/// One UAV's heading box: `lo ≤ φ ≤ hi` (unwrapped around its current heading), `lo == hi` when pinned.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadingInterval {
    /// Lowest heading, radians.
    pub lo: f64,
    /// Highest heading, radians.
    pub hi: f64,
    /// Whether the cone can be kept (step 3 of the module docs).
    pub in_cone: bool,
}

/// What the interval of one UAV depends on.
#[derive(Debug, Clone, Copy)]
pub struct Uav {
    /// Current position, metres.
    pub position: Vector2<f64>,
    /// Current heading ψ, radians.
    pub heading: f64,
    /// Speed, m/s.
    pub speed: f64,
    /// Step duration, s.
    pub dt: f64,
}

impl Uav {
    fn violation(&self, c: &Constraints, estimate: Vector2<f64>, phi: f64) -> f64 {
        let next = next_position(self.position, self.heading, phi, self.speed, self.dt);
        c.approach_violation(next, phi, estimate)
    }
}

/// The interval of allowed headings (`v(φ) = 0`) around one of the samples: the sample run `[a, b]` of
/// allowed samples, each end moved out by bisection towards its disallowed neighbour.
fn refine(v: &dyn Fn(f64) -> f64, mut inside: f64, mut outside: f64, bisections: usize) -> f64 {
    for _ in 0..bisections {
        let mid = 0.5 * (inside + outside);
        if mid == inside || mid == outside {
            break;
        }
        if v(mid) == 0.0 {
            inside = mid;
        } else {
            outside = mid;
        }
    }
    inside
}

/// The distance of `phi` to the cone `α ± Δα` (radians, 0 inside), taken modulo 2π.
fn cone_distance(phi: f64, alpha: f64, delta_alpha: f64) -> f64 {
    (turn_angle(alpha, phi).abs() - delta_alpha).max(0.0)
}

/// The heading box of one UAV (see the module docs).
pub fn heading_interval(c: &Constraints, uav: &Uav, estimate: Vector2<f64>) -> HeadingInterval {
    heading_interval_of(c, uav, estimate, &|phi| uav.violation(c, estimate, phi), EXACT_RESOLUTION)
}

/// The heading box of one UAV for any per-UAV violation `v(φ)` (0 where the UAV's own limits hold):
/// the approach distance ([`heading_interval`]) or the UAV's own part of the safety certificate
/// ([`crate::shield`]), at the `resolution` given ([`EXACT_RESOLUTION`], [`CERTIFIED_RESOLUTION`]).
pub fn heading_interval_of(
    c: &Constraints,
    uav: &Uav,
    estimate: Vector2<f64>,
    v: &dyn Fn(f64) -> f64,
    resolution: Resolution,
) -> HeadingInterval {
    let Resolution { intervals, bisections } = resolution;
    let psi = uav.heading;
    let theta = c.max_turn();
    let (lo, hi) = (psi - theta, psi + theta);
    let alpha = bearing(uav.position, estimate);

    // The allowed runs of the samples, their ends refined.
    let step = (hi - lo) / intervals as f64;
    let at = |k: usize| if k == intervals { hi } else { lo + k as f64 * step };
    let samples: Vec<(f64, f64)> = (0..=intervals).map(|k| (at(k), v(at(k)))).collect();
    let mut allowed: Vec<(f64, f64)> = Vec::new();
    let mut k = 0;
    while k <= intervals {
        if samples[k].1 != 0.0 {
            k += 1;
            continue;
        }
        let start = k;
        while k < intervals && samples[k + 1].1 == 0.0 {
            k += 1;
        }
        let a = if start == 0 { lo } else { refine(v, samples[start].0, samples[start - 1].0, bisections) };
        let b = if k == intervals { hi } else { refine(v, samples[k].0, samples[k + 1].0, bisections) };
        allowed.push((a, b));
        k += 1;
    }

    // The allowed headings in the cone (the cone modulo 2π, unwrapped around ψ).
    // α itself when ψ is within π of it (the very bounds `α ± Δα` of the cone search, bit for bit),
    // else shifted by whole turns towards ψ.
    let centre = alpha + TAU * ((psi - alpha) / TAU).round();
    let mut in_cone: Vec<(f64, f64)> = Vec::new();
    for (a, b) in &allowed {
        for shift in [-TAU, 0.0, TAU] {
            let (cl, ch) = (centre - c.delta_alpha + shift, centre + c.delta_alpha + shift);
            let (l, h) = (a.max(cl), b.min(ch));
            if l <= h {
                in_cone.push((l, h));
            }
        }
    }
    if !in_cone.is_empty() {
        let moved = psi.clamp(centre - c.delta_alpha.min(PI), centre + c.delta_alpha.min(PI));
        let (l, h) = in_cone.iter().copied().find(|(l, h)| *l <= moved && moved <= *h).unwrap_or_else(|| {
            in_cone.iter().copied().fold((0.0, -1.0), |w, x| if x.1 - x.0 > w.1 - w.0 { x } else { w })
        });
        return HeadingInterval { lo: l, hi: h, in_cone: true };
    }
    if !allowed.is_empty() {
        // The cone cannot hold: the allowed heading nearest it (an end of an allowed run).
        let best = allowed
            .iter()
            .flat_map(|(a, b)| [*a, *b])
            .min_by(|x, y| cone_distance(*x, alpha, c.delta_alpha).total_cmp(&cone_distance(*y, alpha, c.delta_alpha)))
            .expect("not empty");
        return HeadingInterval { lo: best, hi: best, in_cone: false };
    }
    // No reachable heading keeps the approach distance: the least violation.
    let kbest = (0..=intervals).min_by(|x, y| samples[*x].1.total_cmp(&samples[*y].1)).expect("samples");
    let (mut a, mut b) = (at(kbest.saturating_sub(1)), at((kbest + 1).min(intervals)));
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut x1, mut x2) = (b - g * (b - a), a + g * (b - a));
    let (mut f1, mut f2) = (v(x1), v(x2));
    for _ in 0..GOLDEN_STEPS {
        if f1 <= f2 {
            b = x2;
            (x2, f2) = (x1, f1);
            x1 = b - g * (b - a);
            f1 = v(x1);
        } else {
            a = x1;
            (x1, f1) = (x2, f2);
            x2 = a + g * (b - a);
            f2 = v(x2);
        }
    }
    let best = [(samples[kbest].0, samples[kbest].1), (x1, f1), (x2, f2)]
        .into_iter()
        .min_by(|p, q| p.1.total_cmp(&q.1))
        .expect("three")
        .0;
    HeadingInterval { lo: best, hi: best, in_cone: false }
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::scenario::Scenario;
    use nalgebra::Matrix2;

    fn setup(distance: f64, heading_off: f64) -> (Constraints, Uav, Vector2<f64>) {
        let sc = Scenario::default();
        let z = Vector2::new(25_000.0, 15_000.0);
        let c = Constraints::from_scenario(&sc).with_covariance(Matrix2::identity() * 2500.0);
        // The UAV `distance` from ẑ, due west of it, heading `heading_off` away from the bearing to ẑ.
        let uav = Uav { position: z - Vector2::new(distance, 0.0), heading: heading_off, speed: sc.speed, dt: sc.dt };
        (c, uav, z)
    }

    /// The brute-force answer: the lexicographic best (approach violation, cone distance) over a fine
    /// grid of the reachable headings.
    fn brute(c: &Constraints, uav: &Uav, z: Vector2<f64>) -> (f64, f64) {
        let theta = c.max_turn();
        let alpha = bearing(uav.position, z);
        (0..=200_000)
            .map(|k| uav.heading - theta + 2.0 * theta * k as f64 / 200_000.0)
            .map(|phi| (uav.violation(c, z, phi), cone_distance(phi, alpha, c.delta_alpha)))
            .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)))
            .unwrap()
    }

    #[test]
    fn far_from_the_emitter_the_box_is_the_cone_within_reach() {
        let (c, uav, z) = setup(20_000.0, 0.3);
        let got = heading_interval(&c, &uav, z);
        assert!(got.in_cone);
        let theta = c.max_turn();
        assert!((got.lo - (0.0 - c.delta_alpha).max(0.3 - theta)).abs() < 1e-12, "{got:?}");
        assert!((got.hi - (0.0 + c.delta_alpha).min(0.3 + theta)).abs() < 1e-12, "{got:?}");
    }

    #[test]
    fn on_the_ring_the_uav_is_pinned_to_the_best_allowed_heading() {
        // Just outside L_min, heading at ẑ: every cone heading closes in; the best keeps the approach
        // distance with the least cone violation, as a fine grid finds.
        for (distance, off) in [(3600.0, 0.0), (3900.0, 0.4), (3300.0, -0.2), (2500.0, 0.0)] {
            let (c, uav, z) = setup(distance, off);
            let got = heading_interval(&c, &uav, z);
            let alpha = bearing(uav.position, z);
            let (v, d) = (uav.violation(&c, z, got.lo), cone_distance(got.lo, alpha, c.delta_alpha));
            let (bv, bd) = brute(&c, &uav, z);
            assert!(v <= bv + 1e-9, "{distance} {off}: violation {v} vs grid {bv}");
            if bv == 0.0 {
                assert_eq!(v, 0.0);
                assert!(d <= bd + 1e-9, "{distance} {off}: cone distance {d} vs grid {bd}");
                if got.in_cone {
                    assert!(got.lo <= got.hi && d == 0.0);
                } else {
                    assert_eq!(got.lo, got.hi);
                }
            }
            // Every heading of the box keeps what the box promises.
            for k in 0..=50 {
                let phi = got.lo + (got.hi - got.lo) * k as f64 / 50.0;
                assert!(uav.violation(&c, z, phi) <= v + 1e-12, "{distance} {off}: {phi}");
            }
        }
    }

    #[test]
    fn the_cone_is_taken_modulo_two_pi() {
        // Heading almost due east while ẑ lies due west: the cone is around π, reached past ±π.
        let sc = Scenario { r_min: 0.0, ..Scenario::default() };
        let c = Constraints::from_scenario(&sc);
        let z = Vector2::new(0.0, 0.0);
        let uav = Uav { position: Vector2::new(20_000.0, 100.0), heading: 3.0, speed: sc.speed, dt: sc.dt };
        let got = heading_interval(&c, &uav, z);
        assert!(got.in_cone, "{got:?}");
        let alpha = bearing(uav.position, z);
        assert!(
            cone_distance(got.lo, alpha, c.delta_alpha) < 1e-12 && cone_distance(got.hi, alpha, c.delta_alpha) < 1e-12
        );
        assert!((got.hi - got.lo - 2.0 * c.delta_alpha).abs() < 1e-9, "{got:?}");
    }
}
