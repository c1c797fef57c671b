//! Fisher information of the range differences, the CRLB, and exact first and second derivatives of
//! the FIM and of `h(z) = tr F⁻¹(z)` with respect to the emitter position (paper eqs. 45–50, 67–73).
//!
//! Units: positions in metres, `F` in 1/m², `tr F⁻¹` in m², derivatives per metre.
//!
//! With `u_i = (z − w_i)/r_i` the unit vector from UAV i to the emitter, the Jacobian row of
//! `d_i = r_i − r_0` is `g_i = u_i − u_0`, and `F = Σ_ij (Q⁻¹)_ij g_i g_jᵀ = Jᵀ Q⁻¹ J` (eq. 48).
//! The derivatives of `g_i` follow from those of `r = |z − w|`:
//! `∂²r/∂z_a∂z_b = (δ_ab − u_a u_b)/r` and
//! `∂³r/∂z_a∂z_b∂z_c = (3 u_a u_b u_c − δ_ab u_c − δ_ac u_b − δ_bc u_a)/r²`.

use nalgebra::{Matrix2, Vector2};

use crate::{MAX_UAVS, Sensors, TdoaError};

/// A range below this (metres) means the emitter sits on a UAV: the FIM is undefined there.
const MIN_RANGE_M: f64 = 1e-6;

/// `F` whose reciprocal condition number is below this is treated as singular.
const SINGULAR_RCOND: f64 = 1e-13;

/// Unit vectors and ranges of one emitter position; `None` if the emitter is on a UAV.
pub(crate) struct Rays {
    pub(crate) u: [Vector2<f64>; MAX_UAVS],
    pub(crate) r: [f64; MAX_UAVS],
    pub(crate) n: usize,
}

impl Rays {
    pub(crate) fn new(sensors: &Sensors, z: &Vector2<f64>) -> Option<Self> {
        let n = sensors.len();
        let mut u = [Vector2::zeros(); MAX_UAVS];
        let mut r = [0.0; MAX_UAVS];
        for (i, w) in sensors.positions().iter().enumerate() {
            let d = z - w;
            let ri = d.norm();
            if ri.is_nan() || ri < MIN_RANGE_M {
                return None;
            }
            u[i] = d / ri;
            r[i] = ri;
        }
        Some(Self { u, r, n })
    }

    /// The Hessian of UAV k's range `r_k = |z − w_k|` with respect to the emitter position,
    /// `(I − u_k u_kᵀ)/r_k` (1/m): the derivative of its unit vector.
    pub(crate) fn range_hessian(&self, k: usize) -> Matrix2<f64> {
        let u = self.u[k];
        (Matrix2::identity() - u * u.transpose()) / self.r[k]
    }

    /// Jacobian rows `g_i = u_i − u_0`, i = 1..N−1 (stored at index i−1).
    fn jacobian(&self) -> [Vector2<f64>; MAX_UAVS] {
        let mut g = [Vector2::zeros(); MAX_UAVS];
        for i in 1..self.n {
            g[i - 1] = self.u[i] - self.u[0];
        }
        g
    }
}

/// Σ_ij (Q⁻¹)_ij a_i b_jᵀ over the N−1 range differences.
#[inline]
fn weighted_outer(sensors: &Sensors, a: &[Vector2<f64>], b: &[Vector2<f64>]) -> Matrix2<f64> {
    let m = sensors.len() - 1;
    let noise = sensors.noise();
    let mut out = Matrix2::zeros();
    for (i, ai) in a.iter().enumerate().take(m) {
        // c = Σ_j Qinv_ij b_j
        let mut c = Vector2::zeros();
        for (j, bj) in b.iter().enumerate().take(m) {
            c += noise.q_inv(i, j) * bj;
        }
        out += ai * c.transpose();
    }
    out
}

/// The FIM `F(z) = Jᵀ Q⁻¹ J` (eq. 48/50), 1/m². `None` if the emitter coincides with a UAV.
pub fn fim(sensors: &Sensors, z: &Vector2<f64>) -> Option<Matrix2<f64>> {
    let rays = Rays::new(sensors, z)?;
    let g = rays.jacobian();
    let f = weighted_outer(sensors, &g, &g);
    // Symmetric in exact arithmetic; make it so in floating point too.
    Some(0.5 * (f + f.transpose()))
}

/// Inverse of a symmetric 2×2 matrix if it is numerically non-singular and positive definite.
#[inline]
pub(crate) fn inverse_spd(f: &Matrix2<f64>) -> Option<Matrix2<f64>> {
    let det = f[(0, 0)] * f[(1, 1)] - f[(0, 1)] * f[(1, 0)];
    let tr = f[(0, 0)] + f[(1, 1)];
    if !(det.is_finite() && tr > 0.0) || det <= SINGULAR_RCOND * tr * tr {
        return None;
    }
    Some(Matrix2::new(f[(1, 1)], -f[(0, 1)], -f[(1, 0)], f[(0, 0)]) / det)
}

/// Eigenvalues (ascending) of a symmetric 2×2 matrix.
pub fn sym_eigenvalues(a: &Matrix2<f64>) -> (f64, f64) {
    let mean = 0.5 * (a[(0, 0)] + a[(1, 1)]);
    let half_diff = 0.5 * (a[(0, 0)] - a[(1, 1)]);
    let off = 0.5 * (a[(0, 1)] + a[(1, 0)]);
    let rad = half_diff.hypot(off);
    (mean - rad, mean + rad)
}

/// `h(z) = tr F⁻¹(z)`, m² — the squared single-point CRLB. `+∞` where `F` is singular
/// (baseline extensions for 3 UAVs, the emitter on a UAV).
#[inline]
pub fn trace_crlb(sensors: &Sensors, z: &Vector2<f64>) -> f64 {
    fim(sensors, z).and_then(|f| inverse_spd(&f)).map_or(f64::INFINITY, |c| c.trace())
}

/// The single-point CRLB at one emitter position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crlb {
    /// `F`, 1/m².
    pub fim: Matrix2<f64>,
    /// `F⁻¹` (the CRLB matrix, eq. 49), m².
    pub bound: Matrix2<f64>,
    /// `tr F⁻¹`, m².
    pub trace_m2: f64,
    /// `sqrt(tr F⁻¹)`, metres.
    pub crlb_m: f64,
    /// 2-norm condition number of `F`.
    pub cond: f64,
}

/// The single-point CRLB of the emitter at `z` (eq. 49); an error where `F` is singular.
pub fn crlb(sensors: &Sensors, z: &Vector2<f64>) -> Result<Crlb, TdoaError> {
    let f = fim(sensors, z)
        .ok_or_else(|| TdoaError::Degenerate("the emitter coincides with a UAV; the FIM is undefined".into()))?;
    let bound = inverse_spd(&f).ok_or_else(|| {
        TdoaError::Degenerate(
            "the FIM is singular here (emitter on the extension of a baseline, or all UAVs on one line through it)"
                .into(),
        )
    })?;
    let (lo, hi) = sym_eigenvalues(&f);
    let trace_m2 = bound.trace();
    Ok(Crlb { fim: f, bound, trace_m2, crlb_m: trace_m2.sqrt(), cond: hi / lo })
}

/// `F` and its exact first and second partial derivatives with respect to the emitter position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FimDerivatives {
    /// `F`, 1/m².
    pub f: Matrix2<f64>,
    /// `∂F/∂x`, `∂F/∂y`, 1/m³.
    pub d: [Matrix2<f64>; 2],
    /// `∂²F/∂z_p∂z_q` indexed `[p][q]`, 1/m⁴.
    pub dd: [[Matrix2<f64>; 2]; 2],
}

/// `F`, `F_,p` and `F_,pq` at `z`; `None` if the emitter coincides with a UAV.
pub fn fim_derivatives(sensors: &Sensors, z: &Vector2<f64>) -> Option<FimDerivatives> {
    let rays = Rays::new(sensors, z)?;
    let n = rays.n;
    let g = rays.jacobian();
    // Per UAV k: K_k = (I − u uᵀ)/r (∂u/∂z) and the third-derivative tensor of r_k.
    let mut gp = [[Vector2::zeros(); MAX_UAVS]; 2];
    let mut gpq = [[[Vector2::zeros(); MAX_UAVS]; 2]; 2];
    let hess_r = |k: usize, p: usize| -> Vector2<f64> {
        let u = rays.u[k];
        let mut e = Vector2::zeros();
        e[p] = 1.0;
        (e - u * u[p]) / rays.r[k]
    };
    let third_r = |k: usize, p: usize, q: usize| -> Vector2<f64> {
        let u = rays.u[k];
        let r2 = rays.r[k] * rays.r[k];
        let mut out = Vector2::zeros();
        for a in 0..2 {
            let dab = f64::from(u8::from(a == p));
            let dac = f64::from(u8::from(a == q));
            let dbc = f64::from(u8::from(p == q));
            out[a] = (3.0 * u[a] * u[p] * u[q] - dab * u[q] - dac * u[p] - dbc * u[a]) / r2;
        }
        out
    };
    #[allow(clippy::needless_range_loop)]
    for p in 0..2 {
        let h0 = hess_r(0, p);
        for i in 1..n {
            gp[p][i - 1] = hess_r(i, p) - h0;
        }
        for q in 0..2 {
            let t0 = third_r(0, p, q);
            for i in 1..n {
                gpq[p][q][i - 1] = third_r(i, p, q) - t0;
            }
        }
    }
    let f = weighted_outer(sensors, &g, &g);
    let f = 0.5 * (f + f.transpose());
    let mut d = [Matrix2::zeros(); 2];
    for p in 0..2 {
        let a = weighted_outer(sensors, &gp[p], &g);
        d[p] = a + a.transpose();
    }
    let mut dd = [[Matrix2::zeros(); 2]; 2];
    for p in 0..2 {
        for q in p..2 {
            let a = weighted_outer(sensors, &gpq[p][q], &g);
            let b = weighted_outer(sensors, &gp[p], &gp[q]);
            let m = a + a.transpose() + b + b.transpose();
            dd[p][q] = m;
            dd[q][p] = m;
        }
    }
    Some(FimDerivatives { f, d, dd })
}

/// `h(z) = tr F⁻¹(z)` with its exact gradient (eqs. 68–69) and Hessian (eqs. 67, 70–73).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceDerivatives {
    /// `h`, m².
    pub value: f64,
    /// `∇h`, m.
    pub gradient: Vector2<f64>,
    /// `H = ∇²h`, dimensionless.
    pub hessian: Matrix2<f64>,
}

/// `h`, `∇h`, `∇²h` at `z`; `None` where `F` is singular or undefined.
///
/// `∂h/∂p = −tr(C F_,p C)` and
/// `∂²h/∂p∂q = tr(C F_,q C F_,p C + C F_,p C F_,q C − C F_,pq C)` with `C = F⁻¹` (eq. 67).
pub fn trace_derivatives(sensors: &Sensors, z: &Vector2<f64>) -> Option<TraceDerivatives> {
    let fd = fim_derivatives(sensors, z)?;
    let c = inverse_spd(&fd.f)?;
    let cd = [c * fd.d[0], c * fd.d[1]]; // C F_,p
    let c2 = c * c;
    let gradient = Vector2::new(-(cd[0] * c).trace(), -(cd[1] * c).trace());
    let mut hessian = Matrix2::zeros();
    for p in 0..2 {
        for q in p..2 {
            // tr(C F_q C F_p C) = tr(C² F_q C F_p) etc.; use cyclicity to keep it to 2×2 products.
            let v = (cd[q] * cd[p] * c).trace() + (cd[p] * cd[q] * c).trace() - (c2 * fd.dd[p][q]).trace();
            hessian[(p, q)] = v;
            hessian[(q, p)] = v;
        }
    }
    Some(TraceDerivatives { value: c.trace(), gradient, hessian })
}
