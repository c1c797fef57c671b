//! Sequential fusion of TDOA snapshots: the Gaussian posterior of the emitter's state given every
//! snapshot so far, updated on the raw range differences with their covariance `Q` (eq. 19).
//!
//! The update is an iterated EKF, i.e. Gauss–Newton on the MAP cost of one step
//! `J(x) = (x − x̄)ᵀ P̄⁻¹ (x − x̄) + (d − h(x))ᵀ Q⁻¹ (d − h(x))`, with a halving line search on `J` so
//! that a large prior never makes it diverge (Bell & Cathey 1993):
//!
//! ```text
//! x_{i+1} = x̄ + K_i (d − h(x_i) − H_i (x̄ − x_i)),   K_i = P̄ H_iᵀ (H_i P̄ H_iᵀ + Q)⁻¹
//! P = (I − K H) P̄ (I − K H)ᵀ + K Q Kᵀ                  (Joseph form, at the last iterate)
//! ```
//!
//! with `h_i(x) = |z − w_i| − |z − w_0|` and `H_i = [(u_i − u_0)ᵀ, 0]` (eq. 45, `u_i` the unit vector
//! from UAV i to the emitter). The cost per snapshot is constant (a few (N−1)-square solves), whatever
//! the run's length.
//!
//! **Gate.** Before fusing, the innovation `ν = d − h(x̄)` is tested against its predicted covariance
//! `S = H P̄ Hᵀ + Q`: a snapshot with `νᵀ S⁻¹ ν > χ²_{N−1}(p_gate)` is not fused (the posterior stays the
//! prediction) and is reported as [`Outcome::Rejected`] — never silently used. Where the prediction is
//! wide beside its range the linearised `S` misses the hyperbolas' curvature over it: a snapshot that
//! fails the first-order test is tested again against `S` plus the second-order term below (the
//! innovation covariance of a second-order filter; its mean shift `½ tr(∇²h P̄)` is left out), and fused
//! when that passes.
//!
//! **One range difference.** A burst heard by two UAVs gives one hyperbola. Where the burst has two or
//! more differences the iterated update re-linearises at their intersection and its spread is the
//! burst's own; with one, the point on the hyperbola is set by the prior, and the hyperbola's curvature
//! over the prior's extent is an error the linearised update does not see (a 7 km-wide prior and a
//! hyperbola 20 km away: a posterior 14 km off with a 300 m σ). That error is counted as noise — the
//! second-order term of the expansion of `h` about the prediction, for `δ ~ N(0, P̄)`:
//!
//! ```text
//! h(x̄ + δ) ≈ h(x̄) + H δ + ½ δᵀ ∇²h δ,   Var(½ δᵀ ∇²h δ) = ½ tr(∇²h P̄ ∇²h P̄)
//! ∇²h = (I − e₁e₁ᵀ)/r₁ − (I − e₀e₀ᵀ)/r₀      (e_i the unit vector from UAV i, r_i its range)
//! ```
//!
//! so a single difference is fused with `Q + ½ tr(∇²h P̄ ∇²h P̄)` ([`linearisation_noise`],
//! [`crate::linearisation`]): negligible once the prior is small beside the range (300 m at 15 km: 2 % of
//! Q), dominant while it is not.
//!
//! **Start.** The first posterior is Chan's fix, with the velocity of the constant-velocity model at
//! 0 ± `velocity_prior_sigma`; the fused estimator gives a fix of three arrivals the sigma-point
//! covariance of the fix ([`crate::sigma_points`]) rather than the CRLB at the fix, which a poor geometry
//! makes overconfident.
//!
//! Units: metres, m/s, m², s.

use nalgebra::{DMatrix, DVector, Matrix2, Matrix4, Vector2, Vector4};

use crate::dist::chi2_quantile;
pub use crate::linearisation::linearisation_noise;
use crate::motion::{Dynamics, EmitterModel};
use crate::{ChanSolution, RangeDiffs, Sensors, TdoaError};

/// Which estimator a run uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EstimatorKind {
    /// The posterior of every snapshot so far (this module).
    #[default]
    Fused,
    /// The paper's per-step Chan fix (the previous fix only resolves the 3-UAV ambiguity).
    Snapshot,
}

impl EstimatorKind {
    /// Both kinds.
    pub const ALL: [EstimatorKind; 2] = [EstimatorKind::Fused, EstimatorKind::Snapshot];

    /// `fused` or `snapshot`.
    pub fn name(self) -> &'static str {
        match self {
            EstimatorKind::Fused => "fused",
            EstimatorKind::Snapshot => "snapshot",
        }
    }
}

impl std::fmt::Display for EstimatorKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for EstimatorKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        EstimatorKind::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| format!("unknown estimator '{s}' (expected fused or snapshot)"))
    }
}

/// The default gate probability: a consistent snapshot is refused once in 10 000.
pub const DEFAULT_GATE_PROBABILITY: f64 = 0.9999;

/// Gauss–Newton iterations of one update at most.
const MAX_ITERATIONS: usize = 25;

/// The iteration stops when the position moves less than this, metres.
const STEP_TOLERANCE_M: f64 = 1e-7;

/// A range below this (metres) puts the emitter on a UAV: no Jacobian there.
const MIN_RANGE_M: f64 = 1e-6;

/// The Gaussian posterior of the emitter's state.
///
/// `mean` and `cov` are 4-dimensional whatever the model; for `static` only the position block is
/// used and the velocity entries are 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Posterior {
    model: EmitterModel,
    mean: Vector4<f64>,
    cov: Matrix4<f64>,
}

impl Posterior {
    /// A posterior of `model` with `mean` (m, m/s) and covariance `cov` (row-major, m², m²/s, m²/s²);
    /// refuses non-finite numbers and a covariance (of the model's dimension) that is not symmetric
    /// positive definite.
    pub fn new(model: EmitterModel, mean: Vector4<f64>, cov: Matrix4<f64>) -> Result<Self, TdoaError> {
        let n = model.dim();
        for (i, v) in mean.iter().take(n).enumerate() {
            crate::geometry::check_finite(if i < 2 { "posterior position" } else { "posterior velocity" }, *v)?;
        }
        for v in cov.fixed_view::<4, 4>(0, 0).iter() {
            if !v.is_finite() {
                return Err(TdoaError::NotFinite { what: "posterior covariance".into(), value: *v });
            }
        }
        let mut m = Vector4::zeros();
        let mut p = Matrix4::zeros();
        for i in 0..n {
            m[i] = mean[i];
            for j in 0..n {
                p[(i, j)] = 0.5 * (cov[(i, j)] + cov[(j, i)]);
            }
        }
        let block = DMatrix::from_fn(n, n, |i, j| p[(i, j)]);
        if block.cholesky().is_none() {
            return Err(TdoaError::CovarianceNotPositiveDefinite { xx: p[(0, 0)], xy: p[(0, 1)], yy: p[(1, 1)] });
        }
        Ok(Self { model, mean: m, cov: p })
    }

    /// The first posterior: Chan's fix `solution` (position and covariance), with the velocity of the
    /// constant-velocity model at 0 ± `dynamics.velocity_prior_sigma()`.
    pub fn from_chan(solution: &ChanSolution, dynamics: &Dynamics) -> Result<Self, TdoaError> {
        let mut mean = Vector4::zeros();
        mean[0] = solution.position.x;
        mean[1] = solution.position.y;
        let mut cov = Matrix4::zeros();
        cov.fixed_view_mut::<2, 2>(0, 0).copy_from(&solution.covariance);
        let s2 = dynamics.velocity_prior_sigma().powi(2);
        cov[(2, 2)] = s2;
        cov[(3, 3)] = s2;
        Self::new(dynamics.model(), mean, cov)
    }

    /// The model.
    pub fn model(&self) -> EmitterModel {
        self.model
    }

    /// The full mean (velocity 0 for `static`).
    pub fn mean(&self) -> Vector4<f64> {
        self.mean
    }

    /// The full covariance (velocity blocks 0 for `static`).
    pub fn cov(&self) -> Matrix4<f64> {
        self.cov
    }

    /// ẑ, metres.
    pub fn position(&self) -> Vector2<f64> {
        Vector2::new(self.mean[0], self.mean[1])
    }

    /// The position's covariance, m².
    pub fn position_cov(&self) -> Matrix2<f64> {
        self.cov.fixed_view::<2, 2>(0, 0).into_owned()
    }

    /// The velocity estimate (m/s) and its covariance (m²/s²); `None` for `static`.
    pub fn velocity(&self) -> Option<(Vector2<f64>, Matrix2<f64>)> {
        (self.model == EmitterModel::ConstantVelocity)
            .then(|| (Vector2::new(self.mean[2], self.mean[3]), self.cov.fixed_view::<2, 2>(2, 2).into_owned()))
    }

    /// The prediction `steps` intervals ahead: `Φ x`, `Φ P Φᵀ + Q_p` (unchanged for `static`).
    pub fn predict(&self, dynamics: &Dynamics, steps: u64) -> Self {
        if self.model == EmitterModel::Static || steps == 0 {
            return *self;
        }
        self.propagated(&dynamics.transition(steps), Some(dynamics.process_noise(steps)))
    }

    /// The posterior of the state `Φ x` without process noise: `Φ x`, `Φ P Φᵀ` (`Φ` a transition or
    /// its inverse; the static model is left as it is). With [`Dynamics::transition`]'s inverse it
    /// carries a posterior back to an earlier step, where a burst heard then can be fused, and with the
    /// transition forward again.
    pub fn transformed(&self, phi: &Matrix4<f64>) -> Self {
        if self.model == EmitterModel::Static {
            return *self;
        }
        self.propagated(phi, None)
    }

    /// `Φ x`, `Φ P Φᵀ` plus the process noise `noise` when there is one (symmetrised).
    fn propagated(&self, phi: &Matrix4<f64>, noise: Option<Matrix4<f64>>) -> Self {
        let mut cov = phi * self.cov * phi.transpose();
        if let Some(q) = noise {
            cov += q;
        }
        Self { model: self.model, mean: phi * self.mean, cov: 0.5 * (cov + cov.transpose()) }
    }

    fn state(&self) -> DVector<f64> {
        DVector::from_fn(self.model.dim(), |i, _| self.mean[i])
    }

    fn covariance(&self) -> DMatrix<f64> {
        let n = self.model.dim();
        DMatrix::from_fn(n, n, |i, j| self.cov[(i, j)])
    }

    fn with(&self, x: &DVector<f64>, p: &DMatrix<f64>) -> Self {
        let n = self.model.dim();
        let mut mean = Vector4::zeros();
        let mut cov = Matrix4::zeros();
        for i in 0..n {
            mean[i] = x[i];
            for j in 0..n {
                cov[(i, j)] = 0.5 * (p[(i, j)] + p[(j, i)]);
            }
        }
        Self { model: self.model, mean, cov }
    }
}

/// What an update did with a snapshot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Outcome {
    /// Fused. `nis` is the normalised innovation squared at the prediction.
    Fused {
        /// `νᵀ S⁻¹ ν`.
        nis: f64,
        /// Gauss–Newton iterations taken.
        iterations: usize,
    },
    /// Not fused: the innovation failed the χ² gate; the posterior is the prediction.
    Rejected {
        /// `νᵀ S⁻¹ ν`.
        nis: f64,
        /// The gate `χ²_{N−1}(p_gate)` it exceeded.
        threshold: f64,
    },
}

/// The result of [`fuse`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Update {
    /// The posterior after the snapshot (the prediction when it was rejected).
    pub posterior: Posterior,
    /// Fused or rejected, with the innovation statistic.
    pub outcome: Outcome,
}

/// The gate `χ²_{m}(p)` for `m` range differences at gate probability `p` in (0, 1].
pub fn gate_threshold(m: usize, p: f64) -> f64 {
    chi2_quantile(m as f64, p)
}

/// The point `at(α)` of the largest step length α of 1, ½, ¼, … (30 halvings) whose cost is at most
/// `current`, with that cost; `None` when none is. The line search of a Gauss–Newton step.
pub(crate) fn halving_step<T>(current: f64, at: impl Fn(f64) -> T, cost: impl Fn(&T) -> f64) -> Option<(T, f64)> {
    let mut alpha = 1.0;
    for _ in 0..30 {
        let candidate = at(alpha);
        let c = cost(&candidate);
        if c <= current {
            return Some((candidate, c));
        }
        alpha *= 0.5;
    }
    None
}

/// `h(z)` and its Jacobian rows `(u_i − u_0)ᵀ` (m×2), or `None` when the emitter is on a UAV.
pub(crate) fn measure(sensors: &Sensors, z: &Vector2<f64>) -> Option<(DVector<f64>, DMatrix<f64>)> {
    let w = sensors.positions();
    let m = w.len() - 1;
    let unit = |p: &Vector2<f64>| {
        let d = z - p;
        let r = d.norm();
        (r.is_finite() && r >= MIN_RANGE_M).then(|| (r, d / r))
    };
    let (r0, u0) = unit(&w[0])?;
    let mut h = DVector::zeros(m);
    let mut jac = DMatrix::zeros(m, 2);
    for i in 1..=m {
        let (ri, ui) = unit(&w[i])?;
        h[i - 1] = ri - r0;
        jac[(i - 1, 0)] = ui.x - u0.x;
        jac[(i - 1, 1)] = ui.y - u0.y;
    }
    Some((h, jac))
}

/// The noise a burst of `sensors` is fused with into the prediction `prior`: `Q`, and for a single range
/// difference `Q` plus its [`linearisation_noise`] over the prediction (module docs). `None` when the
/// prediction is on a UAV.
pub fn update_noise(prior: &Posterior, sensors: &Sensors) -> Option<DMatrix<f64>> {
    let q = sensors.noise().q();
    if sensors.len() != 2 {
        return Some(q);
    }
    linearisation_noise(sensors, &prior.position(), &prior.position_cov()).map(|r| q + r)
}

/// Fuses the snapshot `d` (range differences, m) taken by `sensors` into the **predicted** posterior
/// `prior` (see [`Posterior::predict`]), gating at `gate` (a χ² threshold, e.g. [`gate_threshold`];
/// `+∞` fuses everything), with the noise of [`update_noise`]. Errors on a wrong count or an emitter
/// estimate on a UAV.
pub fn fuse(prior: &Posterior, sensors: &Sensors, d: &RangeDiffs, gate: f64) -> Result<Update, TdoaError> {
    let q =
        update_noise(prior, sensors).ok_or_else(|| TdoaError::Degenerate("the emitter estimate is on a UAV".into()))?;
    fuse_with(prior, sensors, d, gate, q)
}

/// [`fuse`] with the noise `q` (m², (N−1)-square) instead of [`update_noise`]'s.
pub fn fuse_with(
    prior: &Posterior,
    sensors: &Sensors,
    d: &RangeDiffs,
    gate: f64,
    q: DMatrix<f64>,
) -> Result<Update, TdoaError> {
    let m = sensors.len() - 1;
    if d.as_slice().len() != m {
        return Err(TdoaError::LengthMismatch {
            what: "range differences".into(),
            expected: m,
            got: d.as_slice().len(),
        });
    }
    let n = prior.model.dim();
    if q.nrows() != m || q.ncols() != m {
        return Err(TdoaError::LengthMismatch { what: "noise covariance rows".into(), expected: m, got: q.nrows() });
    }
    let d = DVector::from_column_slice(d.as_slice());
    let x_bar = prior.state();
    let p_bar = prior.covariance();
    let jacobian = |x: &DVector<f64>| -> Result<(DVector<f64>, DMatrix<f64>), TdoaError> {
        let (h, g) = measure(sensors, &Vector2::new(x[0], x[1]))
            .ok_or_else(|| TdoaError::Degenerate("the emitter estimate is on a UAV".into()))?;
        let mut big = DMatrix::zeros(m, n);
        big.view_mut((0, 0), (m, 2)).copy_from(&g);
        Ok((h, big))
    };
    let singular = || TdoaError::Degenerate("the innovation covariance is singular".into());

    // The gate, at the prediction.
    let (h0, j0) = jacobian(&x_bar)?;
    let nu = &d - &h0;
    let s = &j0 * &p_bar * j0.transpose() + &q;
    let s_chol = s.clone().cholesky().ok_or_else(singular)?;
    let nis = nu.dot(&s_chol.solve(&nu));
    if !nis.is_finite() {
        return Err(TdoaError::Degenerate("the innovation is not finite".into()));
    }
    // Failing the first-order test, the second-order one (module docs); rejected, the first-order NIS.
    let nis = if nis <= gate {
        nis
    } else {
        match second_order_nis(prior, sensors, &nu, &s) {
            Some(widened) if widened <= gate => widened,
            _ => return Ok(Update { posterior: *prior, outcome: Outcome::Rejected { nis, threshold: gate } }),
        }
    };

    // Gauss–Newton on J(x), with a halving line search.
    let p_chol = p_bar.clone().cholesky().ok_or_else(singular)?;
    let q_chol = q.clone().cholesky().ok_or_else(singular)?;
    let cost = |x: &DVector<f64>| -> f64 {
        let Some((h, _)) = measure(sensors, &Vector2::new(x[0], x[1])) else { return f64::INFINITY };
        let dx = x - &x_bar;
        let r = &d - h;
        dx.dot(&p_chol.solve(&dx)) + r.dot(&q_chol.solve(&r))
    };
    let mut x = x_bar.clone();
    let mut j_x = cost(&x);
    let mut iterations = 0;
    for _ in 0..MAX_ITERATIONS {
        iterations += 1;
        let (h, jac) = jacobian(&x)?;
        let s = &jac * &p_bar * jac.transpose() + &q;
        let s_chol = s.cholesky().ok_or_else(singular)?;
        let innovation = &d - &h - &jac * (&x_bar - &x);
        let full = &x_bar + &p_bar * jac.transpose() * s_chol.solve(&innovation);
        let step = &full - &x;
        let Some((next, c)) = halving_step(j_x, |alpha| &x + &step * alpha, cost) else { break };
        let moved = (next[0] - x[0]).hypot(next[1] - x[1]);
        x = next;
        j_x = c;
        if moved < STEP_TOLERANCE_M {
            break;
        }
    }
    // The covariance at the final iterate (Joseph form).
    let (_, jac) = jacobian(&x)?;
    let s = &jac * &p_bar * jac.transpose() + &q;
    let s_chol = s.cholesky().ok_or_else(singular)?;
    let k = (s_chol.solve(&(&jac * &p_bar))).transpose();
    let i_kh = DMatrix::identity(n, n) - &k * &jac;
    let p = &i_kh * &p_bar * i_kh.transpose() + &k * &q * k.transpose();
    let posterior = prior.with(&x, &p);
    if posterior.mean.iter().chain(posterior.cov.iter()).any(|v| !v.is_finite()) {
        return Err(TdoaError::Degenerate("the fused posterior is not finite".into()));
    }
    Ok(Update { posterior, outcome: Outcome::Fused { nis, iterations } })
}

/// The innovation `nu` of a burst of three or more arrivals tested against `S` plus the second-order
/// term of the expansion of `h` over the prediction, `S + ½ tr(∇²h_i P̄ ∇²h_j P̄)` ([`linearisation_noise`]):
/// what a gate at a wide prediction takes for disagreement is then the curvature of the hyperbolas over
/// the prior's extent (a first fix of three arrivals kilometres across rejected the clean bursts that
/// came after it). Never larger than `νᵀ S⁻¹ ν`, and the same where the prior is small beside the range.
/// `None` for a single difference (its noise holds the term already: [`update_noise`]) or where the
/// term cannot be formed.
fn second_order_nis(prior: &Posterior, sensors: &Sensors, nu: &DVector<f64>, s: &DMatrix<f64>) -> Option<f64> {
    if sensors.len() < 3 {
        return None;
    }
    let r = linearisation_noise(sensors, &prior.position(), &prior.position_cov())?;
    let widened = (s + r).cholesky()?;
    let nis = nu.dot(&widened.solve(nu));
    nis.is_finite().then_some(nis)
}

/// The normalised estimation error squared `eᵀ M⁻¹ e` of the position estimate `estimate` with
/// covariance `cov` against the truth; `None` if `cov` is not positive definite.
pub fn nees(estimate: &Vector2<f64>, cov: &Matrix2<f64>, truth: &Vector2<f64>) -> Option<f64> {
    let e = estimate - truth;
    let inv = crate::fim::inverse_spd(cov)?;
    Some(e.dot(&(inv * e)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{Purpose, stream};
    use crate::{NoiseModel, chan, fim, montecarlo::noisy_range_diffs};

    fn sensors(pts: &[[f64; 2]]) -> Sensors {
        Sensors::new(pts, NoiseModel::uniform(pts.len(), 28.7712).unwrap()).unwrap()
    }

    fn geometry(k: usize) -> Sensors {
        let t = k as f64 * 500.0;
        sensors(&[[1500.0 + t, 500.0], [10_000.0 + 0.7 * t, 1500.0 + 0.7 * t], [5000.0, 8500.0 + t]])
    }

    #[test]
    fn noise_free_snapshots_leave_the_truth_in_place() {
        let z = Vector2::new(25_000.0, 15_000.0);
        let s0 = geometry(0);
        let sol = chan(&s0, &s0.range_differences(&z), None).unwrap();
        let mut post = Posterior::from_chan(&sol, &Dynamics::fixed()).unwrap();
        assert!((post.position() - z).norm() < 1e-6);
        let mut trace = post.position_cov().trace();
        for k in 1..10 {
            let s = geometry(k);
            let up = fuse(&post, &s, &s.range_differences(&z), f64::INFINITY).unwrap();
            assert!(matches!(up.outcome, Outcome::Fused { nis, .. } if nis < 1e-12));
            post = up.posterior;
            assert!((post.position() - z).norm() < 1e-6, "step {k}");
            // Information only accumulates.
            assert!(post.position_cov().trace() < trace);
            trace = post.position_cov().trace();
        }
    }

    #[test]
    fn with_a_small_prior_the_covariance_is_the_accumulated_information() {
        // Noise-free and started at the truth, the linearisation point never moves: P⁻¹ = P₀⁻¹ + Σ F_k.
        let z = Vector2::new(25_000.0, 15_000.0);
        let p0 = Matrix2::new(4.0e4, 1.0e3, 1.0e3, 9.0e4);
        let mut mean = Vector4::zeros();
        mean[0] = z.x;
        mean[1] = z.y;
        let mut cov = Matrix4::zeros();
        cov.fixed_view_mut::<2, 2>(0, 0).copy_from(&p0);
        let mut post = Posterior::new(EmitterModel::Static, mean, cov).unwrap();
        let mut info = p0.try_inverse().unwrap();
        for k in 0..8 {
            let s = geometry(k);
            post = fuse(&post, &s, &s.range_differences(&z), f64::INFINITY).unwrap().posterior;
            info += fim(&s, &z).unwrap();
            let expected = info.try_inverse().unwrap();
            let rel = (post.position_cov() - expected).norm() / expected.norm();
            assert!(rel < 1e-9, "step {k}: {rel}");
        }
    }

    /// One range difference fused into a wide prior (σ 3–6 km, an early track): with the hyperbola's
    /// curvature over the prior counted as noise the posterior is never overconfident (Monte Carlo NEES:
    /// no tail above χ²₂(0.999) = 13.8); the same update with `Q` alone has eight times the tail of a
    /// consistent filter. A prior already small beside the range adds next to nothing (< 3 % of `Q`).
    #[test]
    fn one_difference_into_a_wide_prior_stays_consistent() {
        let z = Vector2::new(25_000.0, 15_000.0);
        let pair =
            Sensors::heard(&[[1500.0, 500.0], [8000.0, -4000.0]], NoiseModel::heard(&[28.7712; 2]).unwrap()).unwrap();
        let p_bar = Matrix2::new(3.0e7, 1.2e7, 1.2e7, 1.0e7);
        let l = p_bar.cholesky().unwrap().l();
        let mut rng = stream(9, 0, Purpose::MeasurementNoise);
        let normal = rand_distr::StandardNormal;
        let mut sample = || rand_distr::Distribution::<f64>::sample(&normal, &mut rng);
        let (mut n, mut sum_with, mut sum_without, mut tail_with, mut tail_without) = (0, 0.0, 0.0, 0, 0);
        for _ in 0..3000 {
            // The prior's mean is the truth moved by its own covariance; the difference has its noise.
            let mean = z + l * Vector2::new(sample(), sample());
            let prior = Posterior::new(
                EmitterModel::Static,
                Vector4::new(mean.x, mean.y, 0.0, 0.0),
                Matrix4::from_fn(|i, j| if i < 2 && j < 2 { p_bar[(i, j)] } else { 0.0 }),
            )
            .unwrap();
            let d0 = pair.range_differences(&z).as_slice()[0] + 28.7712 * 2f64.sqrt() * sample();
            let d = RangeDiffs::heard(&[d0]).unwrap();
            let Ok(with) = fuse(&prior, &pair, &d, f64::INFINITY) else { continue };
            let Ok(without) = fuse_with(&prior, &pair, &d, f64::INFINITY, pair.noise().q()) else { continue };
            let a = nees(&with.posterior.position(), &with.posterior.position_cov(), &z).unwrap();
            let b = nees(&without.posterior.position(), &without.posterior.position_cov(), &z).unwrap();
            n += 1;
            sum_with += a.min(1e3);
            sum_without += b.min(1e3);
            tail_with += usize::from(a > 13.8);
            tail_without += usize::from(b > 13.8);
        }
        let (mean_with, mean_without) = (sum_with / n as f64, sum_without / n as f64);
        let (tail_with, tail_without) = (tail_with as f64 / n as f64, tail_without as f64 / n as f64);
        assert!(n > 2900);
        // Consistent: mean 2 and 0.1 % above 13.8. With the term the tail is gone and the mean is
        // conservative (1.2 here: the term is taken over the prior, wider than the posterior); with `Q`
        // alone the tail is 0.8 %, eight times a consistent filter's.
        assert!(mean_with < 2.2 && tail_with < 0.002, "with: mean {mean_with}, tail {tail_with}");
        assert!(
            tail_without > 0.004 && tail_without > 3.0 * tail_with,
            "without: mean {mean_without}, tail {tail_without}"
        );
        let small = linearisation_noise(&pair, &z, &Matrix2::new(9e4, 0.0, 0.0, 9e4)).unwrap();
        assert!(small[(0, 0)] < 0.03 * pair.noise().q()[(0, 0)], "{small}");
    }

    #[test]
    fn a_wild_snapshot_is_gated_not_fused() {
        let z = Vector2::new(25_000.0, 15_000.0);
        let s0 = geometry(0);
        let sol = chan(&s0, &s0.range_differences(&z), None).unwrap();
        let post = Posterior::from_chan(&sol, &Dynamics::fixed()).unwrap();
        let s = geometry(1);
        let mut d = s.range_differences(&z).as_slice().to_vec();
        d[0] += 2000.0; // a multipath-like outlier, far beyond σ√2 ≈ 40 m
        let gate = gate_threshold(2, DEFAULT_GATE_PROBABILITY);
        let up = fuse(&post, &s, &RangeDiffs::from_slice(&d).unwrap(), gate).unwrap();
        assert!(matches!(up.outcome, Outcome::Rejected { nis, threshold } if nis > threshold));
        assert_eq!(up.posterior, post);
        // With no gate it would have been fused, and moved the estimate far.
        let forced = fuse(&post, &s, &RangeDiffs::from_slice(&d).unwrap(), f64::INFINITY).unwrap();
        assert!((forced.posterior.position() - z).norm() > 100.0);
    }

    #[test]
    fn a_clean_burst_into_a_wide_prior_passes_the_second_order_gate() {
        // Five UAVs, a noise-free burst, a prior 7 km wide whose mean is 1.5 σ off the truth (a draw a
        // consistent prior gives): the innovation at the prediction is far outside the first-order gate
        // (the hyperbolas bend over the prior's extent), the second-order test passes it, and the
        // update lands near the truth. Gated on the first order alone, the clean burst was rejected.
        let pts = [[1500.0, 500.0], [10_000.0, 1500.0], [5000.0, 8500.0], [-2000.0, 6000.0], [8000.0, -4000.0]];
        let s = sensors(&pts);
        let z = Vector2::new(25_000.0, 15_000.0);
        let d = s.range_differences(&z);
        let sd = 7000.0;
        let off = Vector2::new(-1.0, 1.0).normalize() * 1.5 * sd;
        let cov = Matrix4::from_diagonal(&Vector4::new(sd * sd, sd * sd, 1.0, 1.0));
        let prior =
            Posterior::new(EmitterModel::Static, Vector4::new(z.x + off.x, z.y + off.y, 0.0, 0.0), cov).unwrap();
        let gate = gate_threshold(4, DEFAULT_GATE_PROBABILITY);
        let first_order = fuse(&prior, &s, &d, f64::INFINITY).unwrap();
        assert!(matches!(first_order.outcome, Outcome::Fused { nis, .. } if nis > 10.0 * gate), "{first_order:?}");
        let gated = fuse(&prior, &s, &d, gate).unwrap();
        assert!(matches!(gated.outcome, Outcome::Fused { nis, .. } if nis <= gate), "{gated:?}");
        assert!((gated.posterior.position() - z).norm() < 100.0, "{:?}", gated.posterior.position());
        // The same burst with one arrival 2 km late, into a prior 300 m wide at the truth: both tests fail.
        let tight = Posterior::new(
            EmitterModel::Static,
            Vector4::new(z.x, z.y, 0.0, 0.0),
            Matrix4::from_diagonal(&Vector4::new(9e4, 9e4, 1.0, 1.0)),
        )
        .unwrap();
        let mut late = d.as_slice().to_vec();
        late[1] += 2000.0;
        let up = fuse(&tight, &s, &RangeDiffs::from_slice(&late).unwrap(), gate).unwrap();
        assert!(matches!(up.outcome, Outcome::Rejected { nis, threshold } if nis > threshold), "{up:?}");
    }

    #[test]
    fn monte_carlo_error_matches_the_accumulated_bound_and_nees_is_consistent() {
        // 400 runs over a fixed (open-loop) trajectory of 12 snapshots: from snapshot 4 the RMSE is within
        // 0.85–1.2 × sqrt(tr (Σ F_k(z))⁻¹) and the mean NEES inside the 99 % band.
        let z = Vector2::new(25_000.0, 15_000.0);
        let runs = 400;
        let steps = 12;
        let mut sq = vec![0.0; steps];
        let mut nees_sum = vec![0.0; steps];
        for run in 0..runs {
            let mut post: Option<Posterior> = None;
            for (k, (sq_k, nees_k)) in sq.iter_mut().zip(nees_sum.iter_mut()).enumerate() {
                let s = geometry(k);
                let mut rng = stream(run as u64 + 11, k as u64, Purpose::MeasurementNoise);
                let d = noisy_range_diffs(&s, &z, &mut rng);
                post = Some(match post {
                    None => Posterior::from_chan(&chan(&s, &d, Some(z)).unwrap(), &Dynamics::fixed()).unwrap(),
                    Some(p) => fuse(&p, &s, &d, f64::INFINITY).unwrap().posterior,
                });
                let p = post.unwrap();
                *sq_k += (p.position() - z).norm_squared();
                *nees_k += nees(&p.position(), &p.position_cov(), &z).unwrap();
            }
        }
        let mut info = Matrix2::zeros();
        let (lo, hi) = crate::dist::mean_chi2_band(2.0, runs, 0.99);
        for k in 0..steps {
            info += fim(&geometry(k), &z).unwrap();
            let bound = info.try_inverse().unwrap().trace().sqrt();
            let rmse = (sq[k] / runs as f64).sqrt();
            let ratio = rmse / bound;
            let mean_nees = nees_sum[k] / runs as f64;
            if k >= 4 {
                assert!((0.85..=1.2).contains(&ratio), "step {k}: RMSE {rmse:.1} vs bound {bound:.1}");
                assert!((lo..=hi).contains(&mean_nees), "step {k}: mean NEES {mean_nees:.3} not in [{lo:.3}, {hi:.3}]");
            }
        }
    }
}
