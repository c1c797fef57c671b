//! Per-step performance metrics computed with knowledge of the truth (only the monitor and the
//! in-process simulation have it): the single-point CRLB at the true emitter and the RMSE of Chan over
//! R TDOA-noise resamples (paper Section 5.3, eq. 79).

use nalgebra::Vector2;
use tdoa::rng::{Purpose, derive_seed};
use tdoa::{Sensors, crlb, montecarlo};

/// CRLB at the truth (m) and RMSE (m, `None` if every resample failed) of one geometry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepMetrics {
    pub crlb_true_m: f64,
    pub rmse_m: Option<f64>,
}

/// Metrics of `sensors` observing the emitter at `truth`. The R resamples are drawn from the stream
/// (`seed`, `step`, RMSE resamples); a 3-UAV ambiguity is resolved with `prior` (the live estimate).
/// The CRLB is +∞ where the truth lies on the singular locus.
pub fn step_metrics(
    sensors: &Sensors,
    truth: &Vector2<f64>,
    resamples: usize,
    seed: u64,
    step: u64,
    prior: Option<Vector2<f64>>,
) -> StepMetrics {
    let crlb_true_m = crlb(sensors, truth).map_or(f64::INFINITY, |c| c.crlb_m);
    let rmse_m = if resamples == 0 {
        None
    } else {
        montecarlo::rmse(sensors, truth, resamples, derive_seed(seed, step, Purpose::RmseResamples), prior)
            .ok()
            .map(|r| r.rmse_m)
            .filter(|r| r.is_finite())
    };
    StepMetrics { crlb_true_m, rmse_m }
}
