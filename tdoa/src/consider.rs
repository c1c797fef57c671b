//! The flight-long range bias of each UAV as a *consider* parameter: what the fused estimate owes to
//! it, carried step to step (a Schmidt consider analysis).
//!
//! UAV i's arrivals carry a range bias `β_i ~ N(0, σ_bi²)` fixed for the flight (its GNSS position
//! bias seen along its line of sight and its clock bias, [`crate::arrivals`]). Every estimate is a
//! linear function of the arrivals to first order, so its error has a part `S β` with the *sensitivity*
//! `S = ∂(x̂ − x)/∂β` (4 × N: position and velocity rows, one column per UAV), and that part's
//! covariance `S Σ_β Sᵀ`, `Σ_β = diag(σ_bi²)`, is what no number of bursts averages out. `S` follows
//! the estimate:
//!
//! ```text
//! Chan's fix           S = [(Gᵀ Q⁻¹ G)⁻¹ Gᵀ Q⁻¹ D ; 0]          (the WLS of the burst, eq. 26/33)
//! a fused burst        S⁺ = (I − K H) S̄ + K D                   (K, H: the update's gain and Jacobian)
//! a prediction         S = Φ S                                   (unchanged for a static emitter)
//! ```
//!
//! with `G` the Jacobian of the burst's range differences at the estimate, `Q` their covariance, and
//! `D` (m × N) the differences' dependence on the biases: `+1` at the UAV of difference k, `−1` at the
//! burst's reference UAV. The estimator's gain is unchanged (its per-step noise keeps the bias variance,
//! so that the gate sees the real spread): this is the covariance of the estimator that runs, not of an
//! optimal one. Treating the GNSS bias's projection as constant is conservative: as a UAV circles, its
//! line of sight turns and that part averages out.
//!
//! Units: metres per metre of bias (position rows), 1/s (velocity rows per metre), m² (covariances).

use nalgebra::{DMatrix, Matrix2, Matrix4, SMatrix, Vector2};

use crate::motion::Dynamics;
use crate::{Heard, MAX_UAVS, TdoaError};

/// `S = ∂(x̂ − x)/∂β` of one estimate (see the module documentation): rows x, y, vx, vy; one column per
/// UAV (always [`MAX_UAVS`] columns, 0 beyond the swarm: every computation has the same shape whatever
/// the swarm, so a state rebuilt from a message continues bit for bit).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BiasSensitivity {
    s: SMatrix<f64, 4, MAX_UAVS>,
}

impl BiasSensitivity {
    /// No dependence on the biases (before any burst).
    pub fn zero() -> Self {
        Self { s: SMatrix::zeros() }
    }

    /// From its rows as a message carries them; refuses a non-finite entry.
    pub fn from_rows(rows: &[[f64; MAX_UAVS]; 4]) -> Result<Self, TdoaError> {
        let mut s = SMatrix::zeros();
        for (r, row) in rows.iter().enumerate() {
            for (c, v) in row.iter().enumerate() {
                crate::geometry::check_finite("a bias sensitivity", *v)?;
                s[(r, c)] = *v;
            }
        }
        Ok(Self { s })
    }

    /// Its rows, as a message carries them (0 beyond the swarm).
    pub fn rows(&self) -> [[f64; MAX_UAVS]; 4] {
        let mut out = [[0.0; MAX_UAVS]; 4];
        for (r, row) in out.iter_mut().enumerate() {
            for (c, v) in row.iter_mut().enumerate() {
                *v = self.s[(r, c)];
            }
        }
        out
    }

    /// `Φ S` over `steps` intervals of `dynamics` (unchanged for a static emitter).
    pub fn predict(&self, dynamics: &Dynamics, steps: u64) -> Self {
        if dynamics.model() == crate::EmitterModel::Static || steps == 0 {
            return *self;
        }
        self.transformed(&dynamics.transition(steps))
    }

    /// The sensitivity of the state `Φ x` (e.g. `Φ` a transition or its inverse): `Φ S`.
    pub fn transformed(&self, phi: &Matrix4<f64>) -> Self {
        Self { s: phi * self.s }
    }

    /// Chan's fix of the burst `heard` at `z`: the weighted least squares' sensitivity (velocity rows 0).
    /// `None` if `z` sits on a UAV or the geometry gives no fix.
    pub fn of_fix(heard: &Heard, z: &Vector2<f64>) -> Option<Self> {
        let (g, d) = jacobians(heard, z)?;
        let q_inv = heard.sensors.noise().q().try_inverse()?;
        let info = g.transpose() * &q_inv * &g;
        let sol = info.try_inverse()? * g.transpose() * q_inv * d;
        let mut s = SMatrix::zeros();
        for c in 0..MAX_UAVS {
            s[(0, c)] = sol[(0, c)];
            s[(1, c)] = sol[(1, c)];
        }
        finite(Self { s })
    }

    /// After a burst `heard` fused into the predicted covariance `p_bar` (the model's `dim` × `dim`
    /// block of a 4 × 4 matrix), the posterior's position `z`: `(I − K H) S̄ + K D`, with the gain at `z`
    /// as the update's final covariance takes it. `self` is the sensitivity of the prediction.
    pub fn after_update(&self, p_bar: &Matrix4<f64>, dim: usize, heard: &Heard, z: &Vector2<f64>) -> Option<Self> {
        self.after_update_with(p_bar, dim, heard, z, &heard.sensors.noise().q())
    }

    /// [`after_update`](Self::after_update) for an update that fused with the noise `q` (m², the
    /// burst's (N−1)-square; [`crate::fusion::update_noise`]) instead of the burst's `Q`.
    pub fn after_update_with(
        &self,
        p_bar: &Matrix4<f64>,
        dim: usize,
        heard: &Heard,
        z: &Vector2<f64>,
        q: &DMatrix<f64>,
    ) -> Option<Self> {
        let (g, d) = jacobians(heard, z)?;
        let m = g.nrows();
        let mut h = DMatrix::zeros(m, dim);
        h.view_mut((0, 0), (m, 2)).copy_from(&g);
        let p = DMatrix::from_fn(dim, dim, |i, j| p_bar[(i, j)]);
        let s_inn = &h * &p * h.transpose() + q;
        let k = (s_inn.cholesky()?.solve(&(&h * &p))).transpose();
        let s_bar = DMatrix::from_fn(dim, MAX_UAVS, |i, j| self.s[(i, j)]);
        let next = (DMatrix::identity(dim, dim) - &k * &h) * s_bar + k * d;
        let mut s = SMatrix::zeros();
        for i in 0..dim {
            for j in 0..MAX_UAVS {
                s[(i, j)] = next[(i, j)];
            }
        }
        finite(Self { s })
    }

    /// The position block of `S Σ_β Sᵀ` for per-UAV bias σ `bias_sigmas` (metres), m².
    pub fn position_covariance(&self, bias_sigmas: &[f64]) -> Matrix2<f64> {
        let mut c = Matrix2::zeros();
        for (j, sigma) in bias_sigmas.iter().enumerate().take(MAX_UAVS) {
            let col = Vector2::new(self.s[(0, j)], self.s[(1, j)]);
            c += sigma * sigma * col * col.transpose();
        }
        c
    }
}

fn finite(s: BiasSensitivity) -> Option<BiasSensitivity> {
    s.s.iter().all(|v| v.is_finite()).then_some(s)
}

/// `G` (m × 2, the range differences' Jacobian at `z`) and `D` (m × [`MAX_UAVS`], their dependence on
/// the biases) of the burst `heard`.
fn jacobians(heard: &Heard, z: &Vector2<f64>) -> Option<(DMatrix<f64>, DMatrix<f64>)> {
    let (_, g) = crate::fusion::measure(&heard.sensors, z)?;
    let mut d = DMatrix::zeros(g.nrows(), MAX_UAVS);
    let reference = *heard.uavs.first()?;
    for k in 1..=g.nrows() {
        let uav = *heard.uavs.get(k)?;
        if uav >= MAX_UAVS || reference >= MAX_UAVS {
            return None;
        }
        d[(k - 1, uav)] = 1.0;
        d[(k - 1, reference)] = -1.0;
    }
    Some((g, d))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fusion::{Posterior, fuse};
    use crate::{Arrivals, EmitterModel, NoiseModel, Sensors, chan};
    use nalgebra::Vector4;

    fn swarm() -> Vec<[f64; 2]> {
        vec![[1500.0, 500.0], [10000.0, 1500.0], [5000.0, 8500.0], [-3000.0, 4000.0]]
    }

    /// Noise-free arrivals at `z` with UAV j's shifted by `beta[j]`, heard by `mask`.
    fn burst(z: &Vector2<f64>, beta: &[f64], mask: u8) -> Arrivals {
        let pts = swarm();
        let arrivals: Vec<f64> = pts.iter().zip(beta).map(|(p, b)| (z - Vector2::new(p[0], p[1])).norm() + b).collect();
        Arrivals::new(&pts, &arrivals, mask, &[20.0, 25.0, 30.0, 35.0], &[3.0; 4]).unwrap()
    }

    /// Chan's fix moves with each UAV's bias as `S` says: finite differences of the noise-free fix, within
    /// 0.2 % of `S`'s norm (Chan's two steps weight by the ranges of its own first step: the WLS to first
    /// order only up to that).
    #[test]
    fn the_fix_sensitivity_is_the_derivative_of_chans_fix() {
        let z = Vector2::new(25000.0, 15000.0);
        for mask in [0b1111u8, 0b1110, 0b1011] {
            let base = burst(&z, &[0.0; 4], mask).heard().unwrap().unwrap();
            let s = BiasSensitivity::of_fix(&base, &z).unwrap();
            let norm = s.s.fixed_view::<2, MAX_UAVS>(0, 0).norm();
            let fix = |beta: &[f64; 4]| {
                let h = burst(&z, beta, mask).heard().unwrap().unwrap();
                chan(&h.sensors, &h.diffs, Some(z)).unwrap().position
            };
            for j in 0..4 {
                // Central differences: the second order cancels.
                let (mut up, mut down) = ([0.0; 4], [0.0; 4]);
                up[j] = 0.05;
                down[j] = -0.05;
                let fd = (fix(&up) - fix(&down)) / 0.1;
                let want = Vector2::new(s.rows()[0][j], s.rows()[1][j]);
                assert!((fd - want).norm() <= 2e-3 * norm, "mask {mask:b} UAV {j}: {fd} vs {want}");
            }
        }
    }

    /// One fused burst: `(I − K H) S̄ + K D` is the derivative of the fused position with respect to the
    /// biases, the prior's own dependence included (finite differences through `fusion::fuse`).
    #[test]
    fn the_update_sensitivity_is_the_derivative_of_the_fused_estimate() {
        let z = Vector2::new(25000.0, 15000.0);
        let p_bar = Matrix4::new(9e4, 2e4, 0.0, 0.0, 2e4, 4e4, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        // A prior whose mean depends on the biases through S̄ (an earlier burst's fix).
        let s_bar = BiasSensitivity::of_fix(&burst(&z, &[0.0; 4], 0b0111).heard().unwrap().unwrap(), &z).unwrap();
        let posterior_at = |beta: &[f64; 4]| -> Vector2<f64> {
            let shift = s_bar.s * nalgebra::SVector::<f64, MAX_UAVS>::from_fn(|i, _| if i < 4 { beta[i] } else { 0.0 });
            let mean = Vector4::new(z.x + shift[0], z.y + shift[1], 0.0, 0.0);
            let prior = Posterior::new(EmitterModel::Static, mean, p_bar).unwrap();
            let h = burst(&z, beta, 0b1111).heard().unwrap().unwrap();
            fuse(&prior, &h.sensors, &h.diffs, f64::INFINITY).unwrap().posterior.position()
        };
        let base = posterior_at(&[0.0; 4]);
        let heard = burst(&z, &[0.0; 4], 0b1111).heard().unwrap().unwrap();
        let s = s_bar.after_update(&p_bar, 2, &heard, &base).unwrap();
        for j in 0..4 {
            let mut beta = [0.0; 4];
            beta[j] = 0.5;
            let fd = (posterior_at(&beta) - base) / 0.5;
            let want = Vector2::new(s.rows()[0][j], s.rows()[1][j]);
            assert!((fd - want).norm() <= 1e-3 * want.norm().max(1.0), "UAV {j}: {fd} vs {want}");
        }
    }

    /// A bias common to every UAV is the burst's unknown epoch: it moves nothing.
    #[test]
    fn a_common_bias_moves_nothing_and_the_covariance_is_s_sigma_s() {
        let z = Vector2::new(25000.0, 15000.0);
        let h = burst(&z, &[0.0; 4], 0b1111).heard().unwrap().unwrap();
        let s = BiasSensitivity::of_fix(&h, &z).unwrap();
        let rows = s.rows();
        for row in &rows[..2] {
            assert!(row[..4].iter().sum::<f64>().abs() <= 1e-9 * row[..4].iter().map(|v| v.abs()).sum::<f64>());
        }
        let sig = [1.0, 2.0, 3.0, 4.0];
        let c = s.position_covariance(&sig);
        let mut want = Matrix2::zeros();
        for (j, sigma) in sig.iter().enumerate() {
            let col = Vector2::new(rows[0][j], rows[1][j]);
            want += sigma * sigma * col * col.transpose();
        }
        assert!((c - want).norm() <= 1e-12 * want.norm());
        // Round trip through the message form; a NaN is refused.
        assert_eq!(BiasSensitivity::from_rows(&s.rows()).unwrap(), s);
        let mut bad = s.rows();
        bad[1][2] = f64::NAN;
        assert!(BiasSensitivity::from_rows(&bad).is_err());
        let _ = Sensors::new(&swarm(), NoiseModel::uniform(4, 10.0).unwrap()).unwrap();
    }
}
