//! Monte Carlo helpers: noisy range-difference draws with covariance `Q` and the RMSE of Chan's
//! estimator over R draws (paper Section 5.3, eq. 79).

use nalgebra::Vector2;
use rand::Rng;
use rand_distr::{Distribution, Normal};

use crate::chan::chan;
use crate::fim::crlb;
use crate::geometry::MAX_DIFFS;
use crate::rng::{Purpose, stream};
use crate::{MAX_UAVS, RangeDiffs, Sensors, TdoaError};

/// One noisy measurement of the range differences of an emitter at `z`.
///
/// Each UAV's range gets independent noise `e_i ~ N(0, s_i²)` and `d̂_i = (r_i + e_i) − (r_0 + e_0)`,
/// whose covariance is exactly `Q` of eq. 19 (`Q_ii = s_i² + s_0²`, `Q_ij = s_0²`).
pub fn noisy_range_diffs<R: Rng + ?Sized>(sensors: &Sensors, z: &Vector2<f64>, rng: &mut R) -> RangeDiffs {
    let ranges = sensors.ranges(z);
    let mut noisy = [0.0; MAX_UAVS];
    for (i, s) in sensors.noise().sigmas().iter().enumerate() {
        // σ > 0 and finite is guaranteed by NoiseModel.
        let e = Normal::new(0.0, *s).map_or(0.0, |n| n.sample(rng));
        noisy[i] = ranges[i] + e;
    }
    let n = sensors.len();
    let mut d = [0.0; MAX_DIFFS];
    for i in 1..n {
        d[i - 1] = noisy[i] - noisy[0];
    }
    RangeDiffs::from_slice(&d[..n - 1]).expect("finite range differences of a validated geometry")
}

/// RMSE of Chan's estimator against the CRLB at one geometry.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct RmseReport {
    /// `sqrt(mean |ẑ − z|²)` over the successful draws, metres.
    pub rmse_m: f64,
    /// `sqrt(tr F⁻¹(z))`, metres.
    pub crlb_m: f64,
    /// `rmse_m / crlb_m`.
    pub ratio: f64,
    /// Draws attempted.
    pub draws: usize,
    /// Draws where Chan returned an error or, with no prior, an unresolved ambiguity.
    pub failures: usize,
}

/// The most samples or draws a Monte Carlo computation takes (the global CRLB's samples are held in
/// memory, 24 bytes each; the RMSE's draws are one Chan solve each): beyond it the run takes hours or the
/// allocation fails — 10¹¹ aborted `uavloc global`, `usize::MAX` panicked it.
pub const MAX_SAMPLES: usize = 10_000_000;

/// RMSE of Chan over `draws` noisy measurements of the emitter at `z`, seeded. `prior` resolves the
/// 3-UAV ambiguity (without one, ambiguous draws count as failures and are left out of the RMSE).
pub fn rmse(
    sensors: &Sensors,
    z: &Vector2<f64>,
    draws: usize,
    seed: u64,
    prior: Option<Vector2<f64>>,
) -> Result<RmseReport, TdoaError> {
    if draws == 0 {
        return Err(TdoaError::NonPositive { what: "draws".into(), value: 0.0 });
    }
    if draws > MAX_SAMPLES {
        return Err(TdoaError::OutOfRange {
            what: "draws".into(),
            value: draws as f64,
            min: 1.0,
            max: MAX_SAMPLES as f64,
        });
    }
    let bound = crlb(sensors, z)?;
    let mut rng = stream(seed, 0, Purpose::RmseResamples);
    let mut sum_sq = 0.0;
    let mut ok = 0usize;
    for _ in 0..draws {
        let d = noisy_range_diffs(sensors, z, &mut rng);
        match chan(sensors, &d, prior) {
            Ok(sol) if !sol.ambiguous => {
                sum_sq += (sol.position - z).norm_squared();
                ok += 1;
            }
            _ => {}
        }
    }
    let rmse_m = if ok > 0 { (sum_sq / ok as f64).sqrt() } else { f64::NAN };
    Ok(RmseReport { rmse_m, crlb_m: bound.crlb_m, ratio: rmse_m / bound.crlb_m, draws, failures: draws - ok })
}
