//! The safety certificate of one planning step: spacing and standoff along the flown arcs, and a
//! backup manoeuvre from where the step ends that keeps both for ever.
//!
//! A plan (one commanded heading per UAV) is **certified** when, with `L_min`, `D_min`, `R_min` of the
//! scenario (eqs. 55–57, kept here in continuous time instead of at the waypoints):
//!
//! 1. **Turn radius**: every arc turns by at most `θ_max = L/R_min` (eq. 55).
//! 2. **Spacing along the arcs**: every pair of UAVs, flying their arcs at the same time, stays at least
//!    `D_min` apart over the whole interval ([`crate::arc::pair_min_distance`], a certified bound).
//! 3. **Standoff along the arcs**: every UAV stays at least `B(Δt) = L_min + k·σ̄(Δt)` from the emitter
//!    as predicted over the interval ([`EmitterPrediction`]: ẑ moving at the estimated velocity; for a
//!    static model ẑ), with `k = Φ⁻¹(c)` of `standoff_confidence` and `σ̄(τ)` a bound on the standard
//!    deviation of the predicted position along every direction. For every instant and every direction
//!    `u`, `|w − z| ≥ uᵀ(w − z)` (Cauchy–Schwarz) gives `P(|w − z| < L_min) ≤ Φ((L_min − |w − ẑ|)/σ_u)`
//!    — the chance bound of `standoff_confidence`, now along the path.
//! 4. **A safe continuation for ever** (recursive feasibility): the *backup* from the step's end is for
//!    every UAV to turn right at the backup rate `θ_b = min(L/R_min, 0.9π)` per step, i.e. to circle
//!    clockwise on the circle of radius `R_b = L/θ_b ≥ R_min` tangent to its end heading (centre
//!    `c_i = w_i + R_b·(sin φ_i, −cos φ_i)`). All UAVs circle at the same angular rate `v/R_b`, so the
//!    difference of two positions is `c_i − c_j` plus a vector of constant length
//!    `b_ij = 2R_b·|sin((φ_i − φ_j)/2)|` turning once per period: the pair's distance for all future time
//!    has the closed-form minimum `| |c_i − c_j| − b_ij |`, required `≥ D_min + δ`. The standoff on the
//!    circle is `| |ẑ(τ) − c_i| − R_b |`, required `≥ B(τ) + k·σ_p + δ`: for a static emitter for all
//!    τ (a constant); for a moving one over the horizon `τ ∈ [Δt, Δt + H]` (`safety_horizon_s`), with
//!    the bound `σ̄(Δt + H)`. The extra `k·σ_p` is room for the next estimate: an update moves ẑ by at
//!    most `k·σ_p` along any direction with probability `c` (its covariance `M_k − M_{k+1}` is below
//!    `M_k`), so the backup still holds from where the next step's estimate puts the emitter — for a moving emitter whose velocity is uncertain no orbit is safe for ever, so
//!    the certificate there is for the horizon `H`, renewed every step. Where a moving emitter comes
//!    at a UAV's circle, that UAV's backup may **fly away** instead ([`crate::backup`]: turn either way
//!    to the heading that opens the distance in the emitter's frame, then straight), its standoff
//!    bracketed along the whole path over the horizon and every pair's spacing bounded for all future
//!    time. A plan certified only with a fly-away ranks below every plan the circles certify
//!    (`reserve_deficit > 1`), and the circles' spacing stays the collision tier.
//!
//! **Why the certificate carries over (static emitter).** If step t's plan is certified, the step
//! after it has at least one certified plan: the backup's first step itself (every UAV turns right by
//! `θ_b`). Its arcs lie on the backup circles, flown in step, so the pair distances along them are at
//! least the backup's minimum `D_min + δ`, and the distances to ẑ at least `B + δ`; its turn is
//! `θ_b ≤ θ_max`; and its own backup is the same circles. The margin `δ = MIN_TOLERANCE_M` is what the
//! certified bound along the arcs may fall short of the true minimum, so the check of that step passes.
//! The planner always evaluates this candidate, so a certified plan exists at every step after a
//! certified one — as long as the estimate ẑ and its covariance do not move so much that the standing
//! backup loses its margin (then the step says so, and the UAVs fly the plan with the largest minimum
//! margin), and for a moving emitter within the horizon.
//!
//! Units: metres, seconds, radians.

mod certifier;
mod limits;
mod prediction;
mod report;

pub use certifier::{Certifier, certify};
pub use limits::{
    BACKUP_MAX_TURN, SPACING_POSITION_SIGMAS, SafetyLimits, SafetyMode, TURN_ROUNDING, backup_turn,
    position_sigma_of_reach,
};
pub use prediction::{EmitterPrediction, sqrt_lambda_max};
pub use report::{SafetyLimit, SafetyReport, Tightest};
