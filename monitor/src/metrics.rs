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

/// Single-point CRLB `sqrt(tr F⁻¹(p))` of `sensors` at the point `p` (e.g. the estimate), metres;
/// `None` where F is singular or `p` is not finite.
pub fn crlb_at(sensors: &Sensors, p: &Vector2<f64>) -> Option<f64> {
    if !p.iter().all(|v| v.is_finite()) {
        return None;
    }
    crlb(sensors, p).ok().map(|c| c.crlb_m).filter(|c| c.is_finite())
}

/// Fills in what needs the whole run and the truth: per step `estimate_error_m`, `nees`, `pcrlb_m`
/// (the posterior CRLB from every snapshot so far, under the scenario's emitter model) and
/// `min_true_distance_m`; for the run `rejected_snapshots` and `true_standoff_violations` (UAV, step
/// pairs closer than `L_min` to the true emitter). Steps without a `truth` get `None`. The same pure
/// function for `simulate` and the pipeline's monitor, so their records agree.
pub fn annotate(run: &mut crate::RunRecord) {
    let sc = &run.scenario;
    let dynamics = sc.dynamics().unwrap_or_else(|_| tdoa::Dynamics::fixed());
    let noise = tdoa::NoiseModel::from_range_sigmas(&sc.range_sigmas()).ok();
    let mut bound = tdoa::InformationBound::new(dynamics);
    let mut last_step: Option<u64> = None;
    let mut violations = 0u64;
    let mut any_truth = false;
    run.rejected_snapshots = run.steps.iter().filter(|s| s.estimate_status == "rejected").count() as u64;
    for s in &mut run.steps {
        let Some(truth) = s.truth else {
            s.estimate_error_m = None;
            s.nees = None;
            s.pcrlb_m = None;
            s.min_true_distance_m = None;
            continue;
        };
        any_truth = true;
        let z = Vector2::new(truth[0], truth[1]);
        let est = Vector2::new(s.estimate[0], s.estimate[1]);
        let cov = nalgebra::Matrix2::new(
            s.estimate_cov[0][0],
            s.estimate_cov[0][1],
            s.estimate_cov[1][0],
            s.estimate_cov[1][1],
        );
        s.estimate_error_m = est.iter().all(|v| v.is_finite()).then(|| (est - z).norm());
        s.nees = tdoa::nees(&est, &cov, &z);
        let fim = noise
            .as_ref()
            .and_then(|noise| Sensors::new(&s.uavs, noise.clone()).ok())
            .and_then(|sensors| tdoa::fim(&sensors, &z));
        let elapsed = last_step.map_or(1, |l| s.step.saturating_sub(l).max(1));
        last_step = Some(s.step);
        let b = bound.add(fim, elapsed);
        s.pcrlb_m = b.is_finite().then_some(b);
        let min = s.uavs.iter().map(|w| (w[0] - z.x).hypot(w[1] - z.y)).fold(f64::INFINITY, f64::min);
        s.min_true_distance_m = min.is_finite().then_some(min);
        if sc.l_min > 0.0 {
            violations += s.uavs.iter().filter(|w| (w[0] - z.x).hypot(w[1] - z.y) < sc.l_min).count() as u64;
        }
    }
    run.true_standoff_violations = any_truth.then_some(violations);
}
