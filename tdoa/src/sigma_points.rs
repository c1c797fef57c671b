//! The sigma-point (unscented) covariance of Chan's fix: how far the fix moves when the arrivals it
//! was computed from move by their noise, through Chan's solution itself rather than its linearisation.
//!
//! Chan's covariance is the CRLB at the fix, `M = F⁻¹(ẑ)` (eq. 28): the first-order spread of the map
//! from the arrivals to the position, taken at the fix. Where the map bends within the noise — an
//! emitter far beyond a small or nearly collinear group of UAVs, whose hyperbolas cross at a shallow
//! angle — the fix lands, with noise, where the hyperbolas happen to cross more steeply than at the
//! truth, and `F⁻¹(ẑ)` states a spread many times smaller than the fix really has. With three of the
//! five UAVs of the study's 5-UAV swarm (the reference and the two on its far side) the CRLB at the
//! truth is 46 km while `F⁻¹(ẑ)` states ≈ 2 km: 44 % of those fixes have a NEES above χ²₂(0.999) = 13.8.
//!
//! The unscented transform (Julier & Uhlmann 2004) propagates the arrivals' noise through the solver:
//! with `n` arrivals of range σ `σ_i`, the `2n` sigma points move arrival `i` by `±√n σ_i` (κ = 0, weights
//! `1/2n`), each is solved by Chan with the fix as the prior (so the same root of the 3-UAV case), and
//!
//! ```text
//! P = Σ_i Σ_± (ẑ_i± − ẑ)(ẑ_i± − ẑ)ᵀ / 2n
//! ```
//!
//! about the fix itself (its asymmetry counts). For a map linear in the noise this is `J⁻¹ Q J⁻ᵀ`, the
//! CRLB at the fix, exactly; where it bends it widens. On the geometry above the share of NEES above
//! 13.8 falls from 44 % to 16 %, and on a geometry whose CRLB is 26 km from 13 % to 2.6 %; on a good
//! geometry the two covariances agree (the default three UAVs: within a few per cent).
//!
//! Units: metres, m².

use nalgebra::{Matrix2, Vector2};

use crate::chan::chan;
use crate::{RangeDiffs, Sensors, TdoaError};

/// The sigma-point covariance (m²) of the fix `fix` that Chan gave for the range differences `d`
/// (`d_i = r_i − r_0`, metres) measured by `sensors` (their range σ per UAV; see the module docs).
///
/// Errors when a sigma point has no physical solution (the arrivals, moved by √n σ, no longer fix the
/// emitter anywhere: the fix is not determined within its own noise) or when the result is not finite.
pub fn fix_covariance(sensors: &Sensors, d: &RangeDiffs, fix: &Vector2<f64>) -> Result<Matrix2<f64>, TdoaError> {
    let n = sensors.len();
    let m = d.as_slice().len();
    if m + 1 != n {
        return Err(TdoaError::LengthMismatch { what: "range differences".into(), expected: n - 1, got: m });
    }
    let scale = (n as f64).sqrt();
    let weight = 0.5 / n as f64;
    let sigmas = sensors.noise().sigmas();
    let mut p = Matrix2::zeros();
    let mut moved = d.as_slice().to_vec();
    for (i, sigma) in sigmas.iter().enumerate() {
        for sign in [-1.0, 1.0] {
            moved.copy_from_slice(d.as_slice());
            let delta = sign * scale * sigma;
            // Arrival i later by δ: d_i grows by δ; the reference's arrival later: every d_k shrinks.
            if i == 0 {
                moved.iter_mut().for_each(|x| *x -= delta);
            } else {
                moved[i - 1] += delta;
            }
            let point = chan(sensors, &RangeDiffs::from_slice(&moved)?, Some(*fix)).map_err(|e| {
                TdoaError::NoSolution(format!(
                    "the fix is not determined within its noise (arrival {i} moved by {delta:.1} m): {e}"
                ))
            })?;
            let e = point.position - fix;
            p += weight * e * e.transpose();
        }
    }
    if p.iter().all(|v| v.is_finite()) {
        Ok(0.5 * (p + p.transpose()))
    } else {
        Err(TdoaError::Degenerate("the sigma-point covariance of the fix is not finite".into()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{NoiseModel, crlb, nees};
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    fn sensors(pts: &[[f64; 2]], sigma: f64) -> Sensors {
        Sensors::new(pts, NoiseModel::uniform(pts.len(), sigma).unwrap()).unwrap()
    }

    fn diffs(pts: &[[f64; 2]], z: &Vector2<f64>, noise: &[f64]) -> RangeDiffs {
        let r: Vec<f64> = pts.iter().zip(noise).map(|(p, n)| (z - Vector2::new(p[0], p[1])).norm() + n).collect();
        RangeDiffs::from_slice(&r[1..].iter().map(|x| x - r[0]).collect::<Vec<_>>()).unwrap()
    }

    fn relative(a: &Matrix2<f64>, b: &Matrix2<f64>) -> f64 {
        (a - b).norm() / b.norm()
    }

    /// With a noise small enough for the map to be linear over it, the sigma points give Chan's own
    /// covariance `F⁻¹(ẑ)` (3 and 5 UAVs).
    #[test]
    fn in_the_linear_limit_it_is_the_crlb_at_the_fix() {
        let z = Vector2::new(25_000.0, 15_000.0);
        for pts in [
            vec![[1500.0, 500.0], [10_000.0, 1500.0], [5000.0, 8500.0]],
            vec![[1500.0, 500.0], [10_000.0, 1500.0], [5000.0, 8500.0], [-2000.0, 6000.0], [8000.0, -4000.0]],
        ] {
            let s = sensors(&pts, 1e-3);
            let d = diffs(&pts, &z, &vec![0.0; pts.len()]);
            let fix = chan(&s, &d, None).unwrap();
            let p = fix_covariance(&s, &d, &fix.position).unwrap();
            assert!(relative(&p, &fix.covariance) < 1e-5, "{p} vs {}", fix.covariance);
        }
    }

    /// On a good geometry (the default three UAVs, CRLB 1.66 km at σ = 28.8 m) the sigma points and the
    /// CRLB agree within a few per cent; on a poor one (an emitter far beyond three UAVs on one side,
    /// CRLB 46 km at the truth) the sigma points widen it, and the Monte Carlo NEES of the fixes shows
    /// which one is honest: the share above χ²₂(0.999) = 13.8 is several times smaller.
    #[test]
    fn the_sigma_points_make_a_poor_geometrys_fixes_honest() {
        let z = Vector2::new(25_000.0, 15_000.0);
        let sigma = 28.7712;
        let normal = Normal::new(0.0, sigma).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let good = [[1500.0, 500.0], [10_000.0, 1500.0], [5000.0, 8500.0]];
        let poor = [[1500.0, 500.0], [5000.0, 8500.0], [-2000.0, 6000.0]];
        let mut tails = Vec::new();
        for pts in [good, poor] {
            let s = sensors(&pts, sigma);
            assert!(crlb(&s, &z).is_ok());
            let (mut fixes, mut tail_crlb, mut tail_sigma, mut ratio) = (0usize, 0usize, 0usize, 0.0);
            for _ in 0..4000 {
                let noise: Vec<f64> = (0..3).map(|_| normal.sample(&mut rng)).collect();
                let d = diffs(&pts, &z, &noise);
                let Ok(fix) = chan(&s, &d, None) else { continue };
                if fix.ambiguous {
                    continue;
                }
                let Ok(p) = fix_covariance(&s, &d, &fix.position) else { continue };
                fixes += 1;
                ratio += p.trace() / fix.covariance.trace();
                tail_crlb += usize::from(nees(&fix.position, &fix.covariance, &z).unwrap() > 13.8);
                tail_sigma += usize::from(nees(&fix.position, &p, &z).unwrap() > 13.8);
            }
            assert!(fixes > 1000, "{fixes} unambiguous fixes");
            tails.push((tail_crlb as f64 / fixes as f64, tail_sigma as f64 / fixes as f64, ratio / fixes as f64));
        }
        let (good_crlb, good_sigma, good_ratio) = tails[0];
        assert!((0.95..1.05).contains(&good_ratio), "good geometry: trace ratio {good_ratio}");
        assert!(good_sigma < 0.01 && good_crlb < 0.01, "good geometry tails {good_crlb} {good_sigma}");
        let (poor_crlb, poor_sigma, poor_ratio) = tails[1];
        assert!(poor_ratio > 2.0, "poor geometry: trace ratio {poor_ratio}");
        assert!(poor_crlb > 0.2, "poor geometry: the CRLB at the fix is overconfident ({poor_crlb})");
        assert!(poor_sigma < 0.5 * poor_crlb, "poor geometry: {poor_sigma} vs {poor_crlb}");
    }

    #[test]
    fn a_wrong_count_is_an_error() {
        let pts = [[1500.0, 500.0], [10_000.0, 1500.0], [5000.0, 8500.0]];
        let s = sensors(&pts, 10.0);
        let d = RangeDiffs::heard(&[1.0]).unwrap();
        assert!(matches!(
            fix_covariance(&s, &d, &Vector2::new(0.0, 0.0)),
            Err(TdoaError::LengthMismatch { expected: 2, got: 1, .. })
        ));
    }
}
