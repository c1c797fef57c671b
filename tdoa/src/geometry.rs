//! UAV geometry and the noise model of the range differences (paper Section 2, eqs. 1–3, 19).
//!
//! Units: metres. `uavs[0]` is the reference UAV (UAV0 of the paper).

use nalgebra::{SMatrix, Vector2};

use crate::{MAX_UAVS, TdoaError};

/// Speed of light in vacuum, m/s (used to turn a TDOA time σ into a range σ).
pub const SPEED_OF_LIGHT: f64 = 299_792_458.0;

/// Two UAVs closer than this (metres) are treated as coincident.
pub const COINCIDENCE_TOLERANCE_M: f64 = 1e-3;

/// The largest length the model takes, metres (10 000 km): a coordinate, a range σ, a distance flown
/// per step. The method is two-dimensional on a flat plane, which stops describing the world long before
/// this; the bound keeps every square, product and inverse the maths forms a finite number.
pub const MAX_EXTENT_M: f64 = 1.0e7;

/// The smallest range σ the noise model takes, metres (1 µm, about 3 fs of timing): below it `Q⁻¹`
/// stops being a finite number long before any receiver could time that well.
pub const MIN_SIGMA_M: f64 = 1.0e-6;

/// Maximum number of range differences (`MAX_UAVS − 1`).
pub const MAX_DIFFS: usize = MAX_UAVS - 1;

/// A fixed-capacity list of range differences `d_i = r_i − r_0`, i = 1..N−1, metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangeDiffs {
    values: [f64; MAX_DIFFS],
    len: usize,
}

impl RangeDiffs {
    /// Builds from a slice of N−1 values; errors if longer than the capacity or not finite.
    pub fn from_slice(values: &[f64]) -> Result<Self, TdoaError> {
        Self::with_min(values, 2)
    }

    /// [`from_slice`](Self::from_slice) for a burst heard by as few as two UAVs: one value or more.
    pub fn heard(values: &[f64]) -> Result<Self, TdoaError> {
        Self::with_min(values, 1)
    }

    fn with_min(values: &[f64], min: usize) -> Result<Self, TdoaError> {
        if values.len() > MAX_DIFFS || values.len() < min {
            return Err(TdoaError::LengthMismatch {
                what: "range differences".into(),
                expected: values.len().clamp(min, MAX_DIFFS),
                got: values.len(),
            });
        }
        let mut out = [0.0; MAX_DIFFS];
        for (i, &v) in values.iter().enumerate() {
            check_finite(format_args!("range difference d{}", i + 1), v)?;
            out[i] = v;
        }
        Ok(Self { values: out, len: values.len() })
    }

    /// The values, `d_1 .. d_{N−1}`.
    pub fn as_slice(&self) -> &[f64] {
        &self.values[..self.len]
    }
}

/// `value` if finite, else [`TdoaError::NotFinite`] naming it `what` — written only then: the
/// constructors below run for every candidate geometry of a planning step and every Monte Carlo draw, so
/// their callers pass `format_args!`, not a `String` built each time.
pub(crate) fn check_finite(what: impl std::fmt::Display, value: f64) -> Result<(), TdoaError> {
    if value.is_finite() { Ok(()) } else { Err(TdoaError::NotFinite { what: what.to_string(), value }) }
}

/// Per-UAV range noise and the covariance `Q` of the range differences (eq. 19):
/// `Q_ii = s_i² + s_0²`, `Q_ij = s_0²` (i ≠ j), with `s_i` the range standard deviation of UAV i in metres.
///
/// `Q` and `Q⁻¹` are shared between clones (a planner builds a [`Sensors`] with the step's noise model for
/// every candidate geometry: a clone is a reference count, not 800 bytes).
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseModel {
    sigmas: [f64; MAX_UAVS],
    n: usize,
    mats: std::sync::Arc<QMatrices>,
}

/// `Q` and `Q⁻¹` of a [`NoiseModel`].
#[derive(Debug, PartialEq)]
struct QMatrices {
    q: SMatrix<f64, MAX_DIFFS, MAX_DIFFS>,
    q_inv: SMatrix<f64, MAX_DIFFS, MAX_DIFFS>,
}

impl NoiseModel {
    /// From per-UAV range standard deviations in metres (`sigmas[0]` is the reference UAV).
    pub fn from_range_sigmas(sigmas: &[f64]) -> Result<Self, TdoaError> {
        Self::with_min(sigmas, 3)
    }

    /// [`from_range_sigmas`](Self::from_range_sigmas) for the arrivals of one burst heard by as few as
    /// two UAVs (one range difference: information on one direction only, for a fused posterior).
    pub fn heard(sigmas: &[f64]) -> Result<Self, TdoaError> {
        Self::with_min(sigmas, 2)
    }

    fn with_min(sigmas: &[f64], min: usize) -> Result<Self, TdoaError> {
        let n = sigmas.len();
        if !(min..=MAX_UAVS).contains(&n) {
            return Err(TdoaError::UavCount { got: n, min, max: MAX_UAVS });
        }
        let mut s = [0.0; MAX_UAVS];
        for (i, &v) in sigmas.iter().enumerate() {
            check_finite(format_args!("sigma of UAV {i}"), v)?;
            if v <= 0.0 {
                return Err(TdoaError::NonPositive { what: format!("sigma of UAV {i}"), value: v });
            }
            if !(MIN_SIGMA_M..=MAX_EXTENT_M).contains(&v) {
                return Err(TdoaError::OutOfRange {
                    what: format!("the range sigma of UAV {i} (m)"),
                    value: v,
                    min: MIN_SIGMA_M,
                    max: MAX_EXTENT_M,
                });
            }
            s[i] = v;
        }
        let m = n - 1;
        let mut q = SMatrix::<f64, MAX_DIFFS, MAX_DIFFS>::zeros();
        for i in 0..m {
            for j in 0..m {
                q[(i, j)] = s[0] * s[0] + if i == j { s[i + 1] * s[i + 1] } else { 0.0 };
            }
        }
        // Q = D + s0² 1 1ᵀ with D = diag(s_i²): Sherman–Morrison gives the inverse exactly.
        let s0sq = s[0] * s[0];
        let sum_inv: f64 = (1..n).map(|i| 1.0 / (s[i] * s[i])).sum();
        let denom = 1.0 + s0sq * sum_inv;
        let mut q_inv = SMatrix::<f64, MAX_DIFFS, MAX_DIFFS>::zeros();
        for i in 0..m {
            for j in 0..m {
                let di = 1.0 / (s[i + 1] * s[i + 1]);
                let dj = 1.0 / (s[j + 1] * s[j + 1]);
                q_inv[(i, j)] = if i == j { di } else { 0.0 } - s0sq * di * dj / denom;
            }
        }
        Ok(Self { sigmas: s, n, mats: std::sync::Arc::new(QMatrices { q, q_inv }) })
    }

    /// Equal range σ (metres) for all `n` UAVs.
    pub fn uniform(n: usize, sigma_m: f64) -> Result<Self, TdoaError> {
        Self::from_range_sigmas(&vec![sigma_m; n])
    }

    /// From per-UAV time-of-arrival standard deviations in nanoseconds, converted with c.
    pub fn from_time_sigmas_ns(sigmas_ns: &[f64]) -> Result<Self, TdoaError> {
        let m: Vec<f64> = sigmas_ns.iter().map(|s| s * 1e-9 * SPEED_OF_LIGHT).collect();
        Self::from_range_sigmas(&m)
    }

    /// Number of UAVs this model describes.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Always false: a model has at least 3 UAVs.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Per-UAV range σ, metres.
    pub fn sigmas(&self) -> &[f64] {
        &self.sigmas[..self.n]
    }

    /// `Q` (eq. 19), m², as a dynamic matrix of size (N−1)×(N−1).
    pub fn q(&self) -> nalgebra::DMatrix<f64> {
        let m = self.n - 1;
        nalgebra::DMatrix::from_fn(m, m, |i, j| self.mats.q[(i, j)])
    }

    /// Entry (i, j) of `Q⁻¹`, 1/m²; i, j index range differences (0 ↔ d_1).
    #[inline]
    pub fn q_inv(&self, i: usize, j: usize) -> f64 {
        self.mats.q_inv[(i, j)]
    }

    /// `rᵀ Q⁻¹ r` of range-difference residuals `r` (metres; as many as the model has differences),
    /// dimensionless.
    pub fn quadratic_form(&self, r: &[f64]) -> f64 {
        let mut s = 0.0;
        for i in 0..r.len() {
            for j in 0..r.len() {
                s += r[i] * self.q_inv(i, j) * r[j];
            }
        }
        s
    }

    /// Same model with every σ multiplied by `factor` (> 0).
    pub fn scaled(&self, factor: f64) -> Result<Self, TdoaError> {
        let s: Vec<f64> = self.sigmas().iter().map(|s| s * factor).collect();
        Self::from_range_sigmas(&s)
    }
}

/// The sensing system: validated UAV positions (metres) and their noise model.
#[derive(Debug, Clone, PartialEq)]
pub struct Sensors {
    pos: [Vector2<f64>; MAX_UAVS],
    n: usize,
    noise: NoiseModel,
}

impl Sensors {
    /// Validates 3..=8 pairwise distinct UAV positions within ±[`MAX_EXTENT_M`] (finite) and a noise model of
    /// the same size. (A world whose UAVs flew out of the extent fails here, at its next measurement.)
    pub fn new(uavs: &[[f64; 2]], noise: NoiseModel) -> Result<Self, TdoaError> {
        Self::with_min(uavs, noise, 3)
    }

    /// [`new`](Self::new) for the UAVs that heard one burst: as few as two (see [`NoiseModel::heard`]).
    /// Chan's fix needs three; a fused posterior takes one range difference.
    pub fn heard(uavs: &[[f64; 2]], noise: NoiseModel) -> Result<Self, TdoaError> {
        Self::with_min(uavs, noise, 2)
    }

    fn with_min(uavs: &[[f64; 2]], noise: NoiseModel, min: usize) -> Result<Self, TdoaError> {
        let n = uavs.len();
        if !(min..=MAX_UAVS).contains(&n) {
            return Err(TdoaError::UavCount { got: n, min, max: MAX_UAVS });
        }
        if noise.len() != n {
            return Err(TdoaError::LengthMismatch { what: "sigma per UAV".into(), expected: n, got: noise.len() });
        }
        let mut pos = [Vector2::zeros(); MAX_UAVS];
        for (i, p) in uavs.iter().enumerate() {
            // Format the message only on failure: this runs for every planner candidate.
            if !(p[0].abs() <= MAX_EXTENT_M && p[1].abs() <= MAX_EXTENT_M) {
                check_finite(format_args!("x of UAV {i}"), p[0])?;
                check_finite(format_args!("y of UAV {i}"), p[1])?;
                return Err(TdoaError::OutOfRange {
                    what: format!("a coordinate of UAV {i}"),
                    value: p[0].abs().max(p[1].abs()),
                    min: -MAX_EXTENT_M,
                    max: MAX_EXTENT_M,
                });
            }
            pos[i] = Vector2::new(p[0], p[1]);
        }
        for a in 0..n {
            for b in a + 1..n {
                let d = (pos[a] - pos[b]).norm();
                if d < COINCIDENCE_TOLERANCE_M {
                    return Err(TdoaError::CoincidentUavs { a, b, distance: d });
                }
            }
        }
        Ok(Self { pos, n, noise })
    }

    /// Same noise, UAVs moved to `uavs` (same count), validated.
    pub fn with_positions(&self, uavs: &[[f64; 2]]) -> Result<Self, TdoaError> {
        Self::new(uavs, self.noise.clone())
    }

    /// Number of UAVs N.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Always false: there are at least 2 UAVs.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// UAV positions, metres; index 0 is the reference.
    pub fn positions(&self) -> &[Vector2<f64>] {
        &self.pos[..self.n]
    }

    /// The noise model.
    pub fn noise(&self) -> &NoiseModel {
        &self.noise
    }

    /// Ranges `r_i = |z − w_i|` (eq. 1), metres.
    pub fn ranges(&self, z: &Vector2<f64>) -> [f64; MAX_UAVS] {
        let mut r = [0.0; MAX_UAVS];
        for (ri, w) in r.iter_mut().zip(self.positions()) {
            *ri = (z - w).norm();
        }
        r
    }

    /// Noise-free range differences `d_i = r_i − r_0`, i = 1..N−1 (eq. 3), metres.
    pub fn range_differences(&self, z: &Vector2<f64>) -> RangeDiffs {
        let r = self.ranges(z);
        let mut values = [0.0; MAX_DIFFS];
        for i in 1..self.n {
            values[i - 1] = r[i] - r[0];
        }
        RangeDiffs { values, len: self.n - 1 }
    }

    /// Mean distance from the UAVs to `z` (`r_avg` of eq. 35), metres.
    pub fn mean_range(&self, z: &Vector2<f64>) -> f64 {
        self.ranges(z)[..self.n].iter().sum::<f64>() / self.n as f64
    }
}
