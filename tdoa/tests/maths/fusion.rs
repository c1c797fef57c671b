//! Sequential fusion (`tdoa::fusion`) against independent references, over random snapshot sequences:
//! - static emitter: the posterior after a batch of snapshots, fused one by one, is the batch
//!   maximum a posteriori estimate (one Gauss–Newton over the prior and every snapshot at once, written
//!   here from the measurement model alone) and its covariance the inverse of the batch information;
//! - constant velocity: the covariance stays symmetric positive definite through every prediction and
//!   update, and an update's covariance is the information form `(P̄⁻¹ + Hᵀ Q⁻¹ H)⁻¹` at the posterior
//!   mean (what the Joseph form computes, by another formula).

use crate::common::config;

use nalgebra::{DMatrix, DVector, Matrix2, Matrix4, Vector2, Vector4};
use proptest::prelude::*;
use tdoa::rng::{Purpose, stream};
use tdoa::{Dynamics, EmitterModel, NoiseModel, Posterior, Sensors, fuse, montecarlo::noisy_range_diffs};

/// A sequence of snapshots of one emitter: per snapshot 3–5 UAVs 8–30 km from it, σ 10–50 m each.
#[derive(Debug, Clone)]
struct Sequence {
    emitter: Vector2<f64>,
    snapshots: Vec<Sensors>,
    /// Offset of the prior mean from the truth (m) and the prior's standard deviations (m) and correlation.
    prior_offset: Vector2<f64>,
    prior_sigma: (f64, f64, f64),
    seed: u64,
}

fn sequence() -> impl Strategy<Value = Sequence> {
    let uav = (8_000.0..30_000.0f64, 0.0..std::f64::consts::TAU, 10.0..50.0f64);
    let snapshot = prop::collection::vec(uav, 3..=5);
    (
        prop::collection::vec(snapshot, 2..=8),
        (-300.0..300.0f64, -300.0..300.0f64),
        (300.0..1500.0f64, 300.0..1500.0f64, -0.5..0.5f64),
        0u64..1_000_000,
    )
        .prop_filter_map("a well-spread snapshot", |(snaps, off, prior_sigma, seed)| {
            let emitter = Vector2::new(25_000.0, 15_000.0);
            let mut snapshots = Vec::new();
            for uavs in snaps {
                // Bearings at least 20° apart: a spread geometry (no UAVs nearly in line with the emitter).
                let mut angles: Vec<f64> = uavs.iter().map(|u| u.1).collect();
                angles.sort_by(f64::total_cmp);
                let gaps = angles
                    .windows(2)
                    .map(|w| w[1] - w[0])
                    .chain([angles[0] + std::f64::consts::TAU - angles[angles.len() - 1]]);
                if gaps.fold(f64::INFINITY, f64::min) < 20f64.to_radians() {
                    return None;
                }
                let pts: Vec<[f64; 2]> =
                    uavs.iter().map(|(r, a, _)| [emitter.x + r * a.cos(), emitter.y + r * a.sin()]).collect();
                let sigmas: Vec<f64> = uavs.iter().map(|u| u.2).collect();
                snapshots.push(Sensors::new(&pts, NoiseModel::from_range_sigmas(&sigmas).ok()?).ok()?);
            }
            Some(Sequence { emitter, snapshots, prior_offset: Vector2::new(off.0, off.1), prior_sigma, seed })
        })
}

fn prior_cov(s: &Sequence) -> Matrix2<f64> {
    let (a, b, rho) = s.prior_sigma;
    Matrix2::new(a * a, rho * a * b, rho * a * b, b * b)
}

/// `h(z)` (range differences to UAV 0) and its Jacobian, from the geometry alone.
fn model(sensors: &Sensors, z: &Vector2<f64>) -> (DVector<f64>, DMatrix<f64>) {
    let w = sensors.positions();
    let r = |i: usize| (z - w[i]).norm();
    let u = |i: usize| (z - w[i]) / r(i);
    let m = w.len() - 1;
    let h = DVector::from_fn(m, |i, _| r(i + 1) - r(0));
    let jac = DMatrix::from_fn(m, 2, |i, c| u(i + 1)[c] - u(0)[c]);
    (h, jac)
}

/// The batch MAP estimate and its covariance: Gauss–Newton on
/// `(x − x₀)ᵀ P₀⁻¹ (x − x₀) + Σ_k (d_k − h_k(x))ᵀ Q_k⁻¹ (d_k − h_k(x))`.
fn batch(x0: Vector2<f64>, p0: Matrix2<f64>, snaps: &[(Sensors, DVector<f64>)]) -> (Vector2<f64>, Matrix2<f64>) {
    let p0_inv = p0.try_inverse().unwrap();
    let mut x = x0;
    let mut info = p0_inv;
    for _ in 0..50 {
        info = p0_inv;
        let mut grad = p0_inv * (x - x0);
        for (s, d) in snaps {
            let (h, jac) = model(s, &x);
            let q_inv = s.noise().q().try_inverse().unwrap();
            let jt_qi = jac.transpose() * &q_inv;
            let a = &jt_qi * &jac;
            let g = &jt_qi * (d - &h);
            info += Matrix2::new(a[(0, 0)], a[(0, 1)], a[(1, 0)], a[(1, 1)]);
            grad -= Vector2::new(g[0], g[1]);
        }
        let step = info.try_inverse().unwrap() * grad;
        x -= step;
        if step.norm() < 1e-9 {
            break;
        }
    }
    (x, info.try_inverse().unwrap())
}

fn is_spd(p: &Matrix4<f64>, n: usize) -> bool {
    let sub = p.view((0, 0), (n, n)).into_owned();
    let sym = (&sub - sub.transpose()).norm() <= 1e-9 * sub.norm();
    sym && sub.cholesky().is_some()
}

proptest! {
    #![proptest_config(config(96))]

    #[test]
    fn static_fusion_one_by_one_is_the_batch_estimate(seq in sequence()) {
        let x0 = seq.emitter + seq.prior_offset;
        let p0 = prior_cov(&seq);
        let mut mean = Vector4::zeros();
        mean[0] = x0.x;
        mean[1] = x0.y;
        let mut cov = Matrix4::zeros();
        cov.fixed_view_mut::<2, 2>(0, 0).copy_from(&p0);
        let mut post = Posterior::new(EmitterModel::Static, mean, cov).unwrap();
        let mut snaps = Vec::new();
        for (k, s) in seq.snapshots.iter().enumerate() {
            let d = noisy_range_diffs(s, &seq.emitter, &mut stream(seq.seed, k as u64, Purpose::MeasurementNoise));
            post = fuse(&post, s, &d, f64::INFINITY).unwrap().posterior;
            snaps.push((s.clone(), DVector::from_column_slice(d.as_slice())));
        }
        let (x, p) = batch(x0, p0, &snaps);
        let scale = p.symmetric_eigenvalues().max().sqrt();
        let gap = (post.position() - x).norm();
        // The snapshots' linearisation points differ from the batch's by the estimation error (tens of
        // metres at 8–30 km): a small fraction of the posterior's standard deviation (at most 0.017 σ and
        // 0.7 % of the covariance over these cases).
        prop_assert!(gap <= 0.05 * scale, "sequential {} vs batch {x}: {gap} m, σ {scale} m", post.position());
        let rel = (post.position_cov() - p).norm() / p.norm();
        prop_assert!(rel <= 0.03, "covariance {} vs batch {p}: {rel}", post.position_cov());
    }

    #[test]
    fn constant_velocity_covariance_stays_spd_and_each_update_is_the_information_form(seq in sequence(), accel in 0.01..2.0f64) {
        let dynamics = Dynamics::new(EmitterModel::ConstantVelocity, 10.0, accel, 10.0).unwrap();
        let x0 = seq.emitter + seq.prior_offset;
        let mean = Vector4::new(x0.x, x0.y, 0.0, 0.0);
        let mut cov = Matrix4::from_diagonal(&Vector4::new(0.0, 0.0, 100.0, 100.0));
        cov.fixed_view_mut::<2, 2>(0, 0).copy_from(&prior_cov(&seq));
        let mut post = Posterior::new(EmitterModel::ConstantVelocity, mean, cov).unwrap();
        for (k, s) in seq.snapshots.iter().enumerate() {
            let predicted = post.predict(&dynamics, 1);
            prop_assert!(is_spd(&predicted.cov(), 4), "prediction {k}: {}", predicted.cov());
            let d = noisy_range_diffs(s, &seq.emitter, &mut stream(seq.seed, k as u64, Purpose::MeasurementNoise));
            post = fuse(&predicted, s, &d, f64::INFINITY).unwrap().posterior;
            prop_assert!(is_spd(&post.cov(), 4), "update {k}: {}", post.cov());
            // (P̄⁻¹ + Hᵀ Q⁻¹ H)⁻¹ with H = [G 0] at the posterior mean.
            let (_, g) = model(s, &post.position());
            let q_inv = s.noise().q().try_inverse().unwrap();
            let a = g.transpose() * q_inv * &g;
            let mut info = predicted.cov().try_inverse().unwrap();
            for (i, j) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                info[(i, j)] += a[(i, j)];
            }
            let expected = info.try_inverse().unwrap();
            let rel = (post.cov() - expected).norm() / expected.norm();
            prop_assert!(rel <= 1e-6, "update {k}: Joseph {} vs information form {expected}: {rel}", post.cov());
        }
    }
}
