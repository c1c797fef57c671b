//! The four motion constraints of one planning step (paper Section 3.5, eqs. 54–59).
//!
//! For candidate headings `φ_i` and the resulting next waypoints `w_i^{t+1}`:
//!
//! | name | constraint | paper | normalised violation |
//! |---|---|---|---|
//! | `turn_radius` | `R_i = L/|θ_i| ≥ R_min`, i.e. `|θ_i| ≤ L/R_min` | eqs. 54, 55 | `(|θ_i| − θ_max)/θ_max` |
//! | `spacing` | `|w_i^{t+1} − w_j^{t+1}| ≥ D_min` for every pair | eq. 56 | `(D_min − D_ij)/D_min` |
//! | `approach` | `|w_i^{t+1} − ẑ| ≥ L_min + k·σ_i` | eq. 57 (k = 0) | `(B_i − L_i)/B_i`, `B_i = L_min + k·σ_i` |
//! | `heading_cone` | `|wrap(φ_i − α_i)| ≤ Δα`, `α_i` the bearing from `w_i^t` to ẑ | eqs. 58, 59 | `(|φ_i − α_i| − Δα)/Δα` |
//!
//! The approach and cone constraints use the planner's estimate ẑ: the true emitter is unknown to it.
//!
//! **The standoff under uncertainty.** `L_min` is about the *true* emitter `z ~ N(ẑ, M)`. With
//! `u_i = (w_i − ẑ)/|w_i − ẑ|` the line of sight from ẑ to the waypoint, Cauchy–Schwarz gives
//! `|w_i − z| ≥ u_iᵀ(w_i − z) = |w_i − ẑ| − u_iᵀ(z − ẑ)`, and `u_iᵀ(z − ẑ) ~ N(0, σ_i²)` with
//! `σ_i² = u_iᵀ M u_i`. Hence, exactly (no linearisation) under the Gaussian posterior,
//! `P(|w_i − z| < L_min) ≤ Φ((L_min − |w_i − ẑ|)/σ_i)`, and the chance constraint
//! `P(|w_i − z| < L_min) ≤ 1 − c` holds whenever `|w_i − ẑ| ≥ L_min + k(c)·σ_i` with `k(c) = Φ⁻¹(c)`
//! (c = `standoff_confidence`; 0.99 → k = 2.326). `c = 0` is the paper's constraint at ẑ (k = 0).
//!
//! With `c > 0` the constraint is also *turn-aware*: a one-step planner that only checks the next
//! waypoint lets a UAV fly straight at the ring and then find that its turn radius carries it inside
//! (the 60-step runs went ~540 m inside `L_min`). The constrained distance is therefore the distance of
//! the UAV's escape orbit: its right-hand minimum-radius turning circle at the waypoint (centre
//! `c = w + R_min·(sin φ, −cos φ)`, φ the heading), minus `R_min` —
//! `L_esc = min(|c − ẑ| − R_min, |w − ẑ|)`. If `L_esc ≥ L_min + k·σ`, the UAV can circle on that orbit
//! forever without coming closer than the bound, so every later step has a feasible standoff
//! (viability). Only the right-hand circle counts — a roundabout rule: every UAV breaks away to the
//! right and so circulates counter-clockwise around ẑ. With either circle allowed (the farther one),
//! two UAVs reached the ring circulating in opposite senses, met head-on, and the spacing constraint
//! (ranked first) pushed one of them ~150 m inside: 1.8 % of the (UAV, step) pairs of 60-step runs were
//! inside `L_min` of the true emitter at c = 0.99; with the rule, 0.4 %. Flying tangentially with ẑ on
//! the left `L_esc = |w − ẑ|`; heading straight in `L_esc = sqrt(D² + R²) − R`.
//! The paper writes strict inequalities; the bounds are treated as closed here so that a plan on a
//! bound is feasible. A bound of 0 (for `R_min`, `D_min`, `L_min`) switches that constraint off.
//!
//! Units: metres, radians.

use nalgebra::{Matrix2, Vector2};

use model::kinematics::{bearing, max_turn, turn_angle, turn_radius, wrap_angle};
use model::scenario::Scenario;

/// A constraint within this relative distance of its bound is reported as active (binding) even
/// when it holds — our choice, so that a plan shows which limits shaped it.
pub const BINDING_TOLERANCE: f64 = 1e-3;

/// Relative excesses up to this are rounding, not violation: a heading clamped exactly onto the cone
/// bound `α + Δα` can come back from `wrap(φ − α)` one ulp beyond it.
pub const FEASIBILITY_EPS: f64 = 1e-9;

/// Normalised violation `excess/bound`, with excesses within [`FEASIBILITY_EPS`] counted as 0.
#[inline]
fn normalised(excess: f64, bound: f64) -> f64 {
    let v = excess / bound;
    if v > FEASIBILITY_EPS { v } else { 0.0 }
}

pub use model::constraint::{ActiveConstraint, ConstraintKind};

/// The constraint check of one candidate plan.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ConstraintReport {
    /// Sum of the normalised violation magnitudes; 0 when every constraint holds.
    pub violation: f64,
    /// The violated and the binding constraints.
    pub active: Vec<ActiveConstraint>,
}

impl ConstraintReport {
    /// Whether every constraint holds.
    pub fn is_feasible(&self) -> bool {
        self.violation == 0.0
    }
}

/// The constraint parameters of a scenario (eq. 59).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Constraints {
    /// Arc length flown per step `L = v·Δt`, metres.
    pub arc_len: f64,
    /// Minimum turn radius `R_min`, metres.
    pub r_min: f64,
    /// Minimum spacing between UAVs `D_min`, metres.
    pub d_min: f64,
    /// Minimum distance to the (estimated) emitter `L_min`, metres.
    pub l_min: f64,
    /// Half-width `Δα` of the heading cone around the bearing to ẑ, radians.
    pub delta_alpha: f64,
    /// `k(c) = Φ⁻¹(c)` of the standoff chance constraint (0: the paper's constraint at ẑ).
    pub standoff_k: f64,
    /// The covariance M of ẑ, m² (used by the standoff chance constraint only).
    pub covariance: Matrix2<f64>,
    /// The bearings to ẑ of one planning step's UAVs ([`Constraints::for_step`]).
    bearings: Option<Bearings>,
}

/// The bearings `α_i` from the UAVs' current positions to ẑ, computed once for a planning step: every
/// candidate of the step is checked against the same positions and ẑ, and `atan2` is the costliest part
/// of a check. Used only for exactly those positions and that ẑ (the same bits as computing them again).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Bearings {
    positions: [Vector2<f64>; tdoa::MAX_UAVS],
    n: usize,
    estimate: Vector2<f64>,
    alpha: [f64; tdoa::MAX_UAVS],
}

/// `k(c) = Φ⁻¹(c)` for a standoff confidence `c` in [0, 1); `c = 0` gives 0 (the paper's constraint).
///
/// Φ⁻¹ is an iterative inversion (≈ 2 µs) and every planning step of a run asks for the same `c`: the
/// last answer is kept per thread.
pub fn standoff_k(confidence: f64) -> f64 {
    use std::cell::Cell;
    thread_local! {
        static LAST: Cell<(u64, f64)> = const { Cell::new((0, 0.0)) };
    }
    if confidence.is_nan() || confidence <= 0.0 {
        return 0.0;
    }
    LAST.with(|last| {
        let (bits, k) = last.get();
        if bits == confidence.to_bits() {
            return k;
        }
        let k = tdoa::dist::normal_quantile(confidence);
        last.set((confidence.to_bits(), k));
        k
    })
}

impl Constraints {
    /// The constraints of `scenario`.
    pub fn from_scenario(scenario: &Scenario) -> Self {
        Self {
            arc_len: scenario.speed * scenario.dt,
            r_min: scenario.r_min,
            // Between reported positions, with the margin their GNSS errors need (0 for exact ones).
            d_min: scenario.d_min + crate::shield::PositionMargin::of(scenario).spacing_m,
            l_min: scenario.l_min,
            delta_alpha: scenario.delta_alpha,
            standoff_k: standoff_k(scenario.standoff_confidence),
            covariance: Matrix2::zeros(),
            bearings: None,
        }
    }

    /// These constraints with the bearings of the UAVs at `positions` to `estimate` computed once (a
    /// private `Bearings`); checks of other positions compute theirs as before.
    pub fn for_step(self, positions: &[Vector2<f64>], estimate: Vector2<f64>) -> Self {
        if positions.len() > tdoa::MAX_UAVS {
            return self;
        }
        let mut b = Bearings {
            positions: [Vector2::zeros(); tdoa::MAX_UAVS],
            n: positions.len(),
            estimate,
            alpha: [0.0; tdoa::MAX_UAVS],
        };
        for (i, p) in positions.iter().enumerate() {
            b.positions[i] = *p;
            b.alpha[i] = bearing(*p, estimate);
        }
        Self { bearings: Some(b), ..self }
    }

    /// The kept bearings if they are those of `positions` and `estimate`.
    fn bearings_of(&self, positions: &[Vector2<f64>], estimate: Vector2<f64>) -> Option<&[f64]> {
        let b = self.bearings.as_ref()?;
        (b.n == positions.len() && b.estimate == estimate && b.positions[..b.n] == *positions).then(|| &b.alpha[..b.n])
    }

    /// These constraints for an estimate with covariance `m` (m²): the standoff chance constraint's σ.
    pub fn with_covariance(self, m: Matrix2<f64>) -> Self {
        Self { covariance: m, ..self }
    }

    /// The constrained distance of a UAV at waypoint `next` with heading `heading` to `estimate`:
    /// `|next − ẑ|` for the paper's constraint (k = 0, or no turn limit); with the chance constraint the
    /// escape-orbit distance `min(|c − ẑ| − R_min, |next − ẑ|)` of the right-hand turning circle centred
    /// at `c` (see the module docs), metres.
    pub fn standoff_distance(&self, next: Vector2<f64>, heading: f64, estimate: Vector2<f64>) -> f64 {
        let direct = (next - estimate).norm();
        if self.standoff_k == 0.0 || self.r_min <= 0.0 {
            return direct;
        }
        // The right-hand turning circle (centre to the right of the heading).
        let centre = next + Vector2::new(heading.sin(), -heading.cos()) * self.r_min;
        ((centre - estimate).norm() - self.r_min).min(direct)
    }

    /// The approach bound `L_min + k·sqrt(uᵀ M u)` of a waypoint at `next` (m), `u` the unit line of sight
    /// from `estimate` to it (see the module docs); `L_min` when k = 0 or the bound is off.
    pub fn approach_bound(&self, next: Vector2<f64>, estimate: Vector2<f64>) -> f64 {
        if self.l_min <= 0.0 || self.standoff_k == 0.0 {
            return self.l_min;
        }
        let d = next - estimate;
        let r = d.norm();
        if r.is_nan() || r <= 0.0 {
            // On ẑ: every direction; take the largest spread.
            let (_, hi) = tdoa::fim::sym_eigenvalues(&self.covariance);
            return self.l_min + self.standoff_k * hi.max(0.0).sqrt();
        }
        let u = d / r;
        let var = u.dot(&(self.covariance * u));
        self.l_min + self.standoff_k * var.max(0.0).sqrt()
    }

    /// The normalised approach violation `(B − L)/B` of one UAV at waypoint `next` with heading `heading`
    /// (0 when it holds, within [`FEASIBILITY_EPS`], or when `L_min` is off): `L` its
    /// [`standoff_distance`](Self::standoff_distance), `B` its [`approach_bound`](Self::approach_bound).
    pub fn approach_violation(&self, next: Vector2<f64>, heading: f64, estimate: Vector2<f64>) -> f64 {
        let bound = self.approach_bound(next, estimate);
        if bound.is_nan() || bound <= 0.0 {
            return 0.0;
        }
        normalised(bound - self.standoff_distance(next, heading, estimate), bound)
    }

    /// Largest turn per step that keeps `R ≥ R_min`: `min(π, L/R_min)`, radians.
    pub fn max_turn(&self) -> f64 {
        max_turn(self.arc_len, self.r_min)
    }

    /// The heading cone `[α − Δα, α + Δα]` (radians, unwrapped around `α ∈ (−π, π]`, so `hi` may exceed
    /// π) of a UAV at `position` with the emitter estimated at `estimate` (eq. 58).
    pub fn cone(&self, position: Vector2<f64>, estimate: Vector2<f64>) -> (f64, f64) {
        let alpha = bearing(position, estimate);
        (alpha - self.delta_alpha, alpha + self.delta_alpha)
    }

    /// The full report for a candidate: current `positions` and `headings`, the estimate ẑ, the
    /// candidate headings `new_headings` and the next waypoints `next` they lead to.
    pub fn check(
        &self,
        positions: &[Vector2<f64>],
        headings: &[f64],
        estimate: Vector2<f64>,
        new_headings: &[f64],
        next: &[Vector2<f64>],
    ) -> ConstraintReport {
        let mut active = Vec::new();
        let mut violation = 0.0;
        self.visit(positions, headings, estimate, new_headings, next, |c| {
            violation += c.violation;
            active.push(c);
        });
        ConstraintReport { violation, active }
    }

    /// Only the total normalised violation of [`Constraints::check`] (no allocation).
    pub fn violation(
        &self,
        positions: &[Vector2<f64>],
        headings: &[f64],
        estimate: Vector2<f64>,
        new_headings: &[f64],
        next: &[Vector2<f64>],
    ) -> f64 {
        let mut violation = 0.0;
        self.visit(positions, headings, estimate, new_headings, next, |c| violation += c.violation);
        violation
    }

    /// The normalised violations summed per kind, indexed by [`ConstraintKind::index`] (no allocation).
    pub fn violations_by_kind(
        &self,
        positions: &[Vector2<f64>],
        headings: &[f64],
        estimate: Vector2<f64>,
        new_headings: &[f64],
        next: &[Vector2<f64>],
    ) -> [f64; 4] {
        let mut by_kind = [0.0; 4];
        self.visit(positions, headings, estimate, new_headings, next, |c| by_kind[c.kind.index()] += c.violation);
        by_kind
    }

    /// Calls `sink` for every violated or binding constraint.
    fn visit(
        &self,
        positions: &[Vector2<f64>],
        headings: &[f64],
        estimate: Vector2<f64>,
        new_headings: &[f64],
        next: &[Vector2<f64>],
        mut sink: impl FnMut(ActiveConstraint),
    ) {
        let n = positions.len().min(headings.len()).min(new_headings.len()).min(next.len());
        let theta_max = self.max_turn();
        let kept = self.bearings_of(positions, estimate);
        let lower_bound = |kind, uav, other, value: f64, bound: f64| -> Option<ActiveConstraint> {
            (bound > 0.0 && value <= bound * (1.0 + BINDING_TOLERANCE)).then(|| ActiveConstraint {
                kind,
                uav,
                other,
                value,
                bound,
                violation: normalised(bound - value, bound),
            })
        };
        for i in 0..n {
            // Turn radius, in terms of the turn angle so that the violation grows with the excess turn.
            let theta = turn_angle(headings[i], new_headings[i]).abs();
            if self.r_min > 0.0 && theta >= theta_max * (1.0 - BINDING_TOLERANCE) {
                sink(ActiveConstraint {
                    kind: ConstraintKind::TurnRadius,
                    uav: i,
                    other: None,
                    value: turn_radius(headings[i], new_headings[i], self.arc_len),
                    bound: self.r_min,
                    violation: normalised(theta - theta_max, theta_max),
                });
            }
            // Heading cone around the bearing from the current position to ẑ.
            let alpha = kept.map_or_else(|| bearing(positions[i], estimate), |a| a[i]);
            let off = wrap_angle(new_headings[i] - alpha).abs();
            if off >= self.delta_alpha * (1.0 - BINDING_TOLERANCE) {
                sink(ActiveConstraint {
                    kind: ConstraintKind::HeadingCone,
                    uav: i,
                    other: None,
                    value: off,
                    bound: self.delta_alpha,
                    violation: normalised(off - self.delta_alpha, self.delta_alpha),
                });
            }
            // Approach distance of the next waypoint to ẑ.
            let approach = self.approach_bound(next[i], estimate);
            let distance = self.standoff_distance(next[i], new_headings[i], estimate);
            if let Some(c) = lower_bound(ConstraintKind::Approach, i, None, distance, approach) {
                sink(c);
            }
            // Spacing of the next waypoints.
            for j in i + 1..n {
                if let Some(c) =
                    lower_bound(ConstraintKind::Spacing, i, Some(j), (next[i] - next[j]).norm(), self.d_min)
                {
                    sink(c);
                }
            }
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    fn m_small() -> Matrix2<f64> {
        Matrix2::identity() * 100.0
    }

    #[test]
    fn the_standoff_chance_constraint_is_calibrated() {
        // A waypoint exactly on the bound L_min + k σ_u: the probability that the true emitter
        // z ~ N(ẑ, M) lies within L_min of it is at most 1 − c (Monte Carlo, 200 000 draws), and close
        // to it when L_min ≫ σ (the bound is tight along the line of sight).
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let z_hat = Vector2::new(25_000.0, 15_000.0);
        for (scale, c) in [(1.0, 0.9), (1.0, 0.99), (0.01, 0.9), (0.01, 0.99)] {
            let m = Matrix2::new(250_000.0, 120_000.0, 120_000.0, 90_000.0) * scale;
            let chol = m.cholesky().unwrap().l();
            let cons = Constraints { standoff_k: standoff_k(c), covariance: m, ..constraints() };
            for dir in [0.3_f64, 1.9, 4.0] {
                let u = Vector2::new(dir.cos(), dir.sin());
                let sigma = u.dot(&(m * u)).sqrt();
                let bound = cons.approach_bound(z_hat + u * 4000.0, z_hat);
                assert!((bound - (3000.0 + standoff_k(c) * sigma)).abs() < 1e-9);
                let w = z_hat + u * bound;
                let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
                let draws = 200_000;
                let inside = (0..draws)
                    .filter(|_| {
                        let e = Vector2::new(StandardNormal.sample(&mut rng), StandardNormal.sample(&mut rng));
                        (w - (z_hat + chol * e)).norm() < 3000.0
                    })
                    .count() as f64
                    / draws as f64;
                let eps = 1.0 - c;
                assert!(inside <= eps * 1.05 + 3.0 * (eps / draws as f64).sqrt(), "c {c}, dir {dir}: {inside}");
                // With σ ≪ L_min the lateral spread hardly matters: the bound is tight.
                if scale < 1.0 {
                    assert!(inside >= 0.8 * eps, "c {c}, dir {dir}: {inside} (too conservative)");
                }
            }
        }
        // The escape-orbit distance: the UAV 5 km east of ẑ flying north (ẑ on its left, counter-clockwise)
        // keeps its distance; heading straight at ẑ it is sqrt(D² + R²) − R; flying south (ẑ on its right)
        // its right-hand circle comes R_min closer on each side: D − 2R.
        let aware = Constraints { standoff_k: 2.0, covariance: m_small(), ..constraints() };
        let w = z_hat + Vector2::new(5000.0, 0.0);
        let pi = std::f64::consts::PI;
        assert!((aware.standoff_distance(w, pi / 2.0, z_hat) - 5000.0).abs() < 1e-9);
        let straight = (5000.0f64.hypot(1000.0)) - 1000.0;
        assert!((aware.standoff_distance(w, pi, z_hat) - straight).abs() < 1e-9);
        assert!((aware.standoff_distance(w, -pi / 2.0, z_hat) - 3000.0).abs() < 1e-9);
        // c = 0 (k = 0): the paper's plain distance.
        let plain = Constraints { standoff_k: 0.0, ..aware };
        assert_eq!(plain.standoff_distance(w, pi, z_hat), 5000.0);
        // c = 0: the paper's constraint at ẑ.
        assert_eq!(standoff_k(0.0), 0.0);
        let paper = Constraints { standoff_k: 0.0, covariance: Matrix2::identity() * 1e6, ..constraints() };
        assert_eq!(paper.approach_bound(z_hat + Vector2::new(5000.0, 0.0), z_hat), 3000.0);
    }
    use crate::fitness::Fitness;
    use model::kinematics::next_position;

    /// The nominal constraints (L = 500 m, R_min 1000 m, D_min 500 m, L_min 3000 m, Δα 25°), k = 0.
    pub(crate) fn constraints() -> Constraints {
        Constraints {
            arc_len: 500.0,
            r_min: 1000.0,
            d_min: 500.0,
            l_min: 3000.0,
            delta_alpha: 25f64.to_radians(),
            standoff_k: 0.0,
            covariance: Matrix2::zeros(),
            bearings: None,
        }
    }

    #[test]
    fn kept_bearings_serve_their_step_only_and_change_nothing() {
        let (p, h, z) = situation();
        let c = constraints();
        let kept = c.for_step(&p, z);
        let phi = [0.4, -0.3, 0.1];
        let next: Vec<_> =
            p.iter().zip(&h).zip(&phi).map(|((p, h), f)| next_position(*p, *h, *f, 50.0, 10.0)).collect();
        assert_eq!(kept.check(&p, &h, z, &phi, &next), c.check(&p, &h, z, &phi, &next));
        // Other positions or another estimate: their own bearings, not the kept ones.
        let moved: Vec<_> = p.iter().map(|q| q + Vector2::new(0.0, 3000.0)).collect();
        assert_eq!(kept.check(&moved, &h, z, &phi, &next), c.check(&moved, &h, z, &phi, &next));
        let z2 = z + Vector2::new(0.0, 9000.0);
        assert_eq!(kept.check(&p, &h, z2, &phi, &next), c.check(&p, &h, z2, &phi, &next));
        assert!(kept.bearings_of(&moved, z).is_none() && kept.bearings_of(&p, z).is_some());
    }

    /// Three UAVs far apart, west of ẑ, all heading straight at it.
    fn situation() -> (Vec<Vector2<f64>>, Vec<f64>, Vector2<f64>) {
        let p = vec![Vector2::new(0.0, 0.0), Vector2::new(0.0, 5000.0), Vector2::new(0.0, -5000.0)];
        let z = Vector2::new(20000.0, 0.0);
        let h = p.iter().map(|q| bearing(*q, z)).collect();
        (p, h, z)
    }

    fn report(c: &Constraints, p: &[Vector2<f64>], h: &[f64], z: Vector2<f64>, phi: &[f64]) -> ConstraintReport {
        let next: Vec<_> = (0..p.len()).map(|i| next_position(p[i], h[i], phi[i], 50.0, 10.0)).collect();
        let r = c.check(p, h, z, phi, &next);
        assert_eq!(r.violation, c.violation(p, h, z, phi, &next));
        r
    }

    fn violated(r: &ConstraintReport) -> Vec<(ConstraintKind, usize, Option<usize>)> {
        r.active.iter().filter(|c| c.is_violated()).map(|c| (c.kind, c.uav, c.other)).collect()
    }

    #[test]
    fn straight_at_the_target_is_feasible() {
        let (p, h, z) = situation();
        let r = report(&constraints(), &p, &h, z, &h);
        assert!(r.is_feasible(), "{r:?}");
        assert!(r.active.is_empty());
    }

    #[test]
    fn turn_radius() {
        let c = constraints();
        let (p, h, z) = situation();
        // A 20° turn (< 28.6° = L/R_min) is fine; the cone is 25°.
        let mut phi = h.clone();
        phi[1] = h[1] + 20f64.to_radians();
        assert!(report(&c, &p, &h, z, &phi).is_feasible());
        // Current heading far from the bearing: a 40° turn back into the cone breaks the turn limit only.
        let mut h2 = h.clone();
        h2[1] = h[1] + 60f64.to_radians();
        let phi = h.clone();
        let r = report(&c, &p, &h2, z, &phi);
        assert_eq!(violated(&r), vec![(ConstraintKind::TurnRadius, 1, None)]);
        let excess = (60f64.to_radians() - 0.5) / 0.5;
        assert!((r.violation - excess).abs() < 1e-12);
        assert!((r.active[0].value - 500.0 / 60f64.to_radians()).abs() < 1e-9);
    }

    #[test]
    fn spacing() {
        let c = constraints();
        let p = vec![Vector2::new(0.0, 0.0), Vector2::new(0.0, 600.0), Vector2::new(0.0, -5000.0)];
        let z = Vector2::new(20000.0, 0.0);
        let h: Vec<f64> = p.iter().map(|q| bearing(*q, z)).collect();
        // Flying straight keeps them ≈ 600 m apart: fine.
        assert!(report(&c, &p, &h, z, &h).is_feasible());
        // UAV 0 turns left and UAV 1 right (inside turn and cone limits): they close in below 500 m.
        let mut phi = h.clone();
        phi[0] = h[0] + 24f64.to_radians();
        phi[1] = h[1] - 24f64.to_radians();
        let r = report(&c, &p, &h, z, &phi);
        assert_eq!(violated(&r), vec![(ConstraintKind::Spacing, 0, Some(1))]);
    }

    #[test]
    fn approach() {
        let c = constraints();
        let (mut p, _, z) = situation();
        p[0] = Vector2::new(16800.0, 0.0);
        let h: Vec<f64> = p.iter().map(|q| bearing(*q, z)).collect();
        // Next waypoint 2700 m from ẑ < 3000 m.
        let r = report(&c, &p, &h, z, &h);
        assert_eq!(violated(&r), vec![(ConstraintKind::Approach, 0, None)]);
        assert!((r.violation - 300.0 / 3000.0).abs() < 1e-9);
        p[0] = Vector2::new(16000.0, 0.0);
        assert!(report(&c, &p, &h, z, &h).is_feasible());
    }

    #[test]
    fn heading_cone() {
        let c = constraints();
        let (p, h, z) = situation();
        let mut phi = h.clone();
        phi[2] = h[2] - 27f64.to_radians();
        let r = report(&c, &p, &h, z, &phi);
        assert_eq!(violated(&r), vec![(ConstraintKind::HeadingCone, 2, None)]);
        phi[2] = h[2] - 24f64.to_radians();
        assert!(report(&c, &p, &h, z, &phi).is_feasible());
    }

    #[test]
    fn heading_cone_wraps_across_pi() {
        let c = constraints();
        // ẑ due west: α = π; a heading of −170° is 10° off, inside the cone.
        let p = vec![Vector2::new(0.0, 0.0), Vector2::new(0.0, 5000.0), Vector2::new(0.0, -5000.0)];
        let z = Vector2::new(-20000.0, 0.0);
        let h: Vec<f64> = p.iter().map(|q| bearing(*q, z)).collect();
        let mut phi = h.clone();
        phi[0] = (-170f64).to_radians();
        assert!(report(&c, &p, &h, z, &phi).is_feasible());
        phi[0] = (-150f64).to_radians();
        assert!(!report(&c, &p, &h, z, &phi).is_feasible());
    }

    #[test]
    fn binding_constraints_are_reported_but_feasible() {
        let c = constraints();
        let (p, h, z) = situation();
        let mut phi = h.clone();
        phi[0] = h[0] + c.delta_alpha;
        let r = report(&c, &p, &h, z, &phi);
        assert!(r.is_feasible());
        assert_eq!(r.active.len(), 1);
        assert_eq!(r.active[0].kind, ConstraintKind::HeadingCone);
        assert!(!r.active[0].is_violated());
    }

    #[test]
    fn zero_bounds_switch_constraints_off() {
        let c = Constraints { r_min: 0.0, d_min: 0.0, l_min: 0.0, ..constraints() };
        let p = vec![Vector2::new(0.0, 0.0), Vector2::new(0.0, 10.0), Vector2::new(30.0, 0.0)];
        let z = Vector2::new(100.0, 0.0);
        let h = vec![3.0, 3.0, 3.0];
        let phi: Vec<f64> = p.iter().map(|q| bearing(*q, z)).collect();
        assert!(report(&c, &p, &h, z, &phi).is_feasible());
    }

    #[test]
    fn infeasible_with_tiny_objective_loses_to_feasible_with_huge_objective() {
        let c = constraints();
        let (p, h, z) = situation();
        let mut phi = h.clone();
        phi[2] = h[2] - 26f64.to_radians();
        let next: Vec<_> = (0..3).map(|i| next_position(p[i], h[i], phi[i], 50.0, 10.0)).collect();
        let bad = Fitness::new(c.violation(&p, &h, z, &phi, &next), 1e-9);
        let good = Fitness::feasible(1e30);
        assert!(!bad.is_feasible());
        assert!(good < bad);
    }
}
