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

/// The posterior CRLB of a run as its snapshots come in (`pcrlb_m` at the truth, `pcrlb_at_estimate_m`
/// along the estimates, the live view's series): each snapshot's information taken at a point `z`, under
/// the scenario's σ and emitter model (Tichavský's recursion, [`tdoa::InformationBound`]).
#[derive(Debug, Clone)]
pub struct RunningBound {
    noise: Option<tdoa::NoiseModel>,
    bound: tdoa::InformationBound,
    last_step: Option<u64>,
}

impl RunningBound {
    /// No snapshot yet, for a run of `scenario`.
    pub fn new(scenario: &model::Scenario) -> Self {
        let dynamics = scenario.dynamics().unwrap_or_else(|_| tdoa::Dynamics::fixed());
        let noise = tdoa::NoiseModel::from_range_sigmas(&scenario.range_sigmas()).ok();
        Self { noise, bound: tdoa::InformationBound::new(dynamics), last_step: None }
    }

    /// The bound (m) after the snapshot of `step` from UAVs at `uavs`, its information taken at `z` under
    /// the scenario's σ or the snapshot's own (`sigmas`: what an external front end stated); `None` while
    /// the information is singular.
    /// With `heard` (the UAVs whose arrival the step held), only their information counts: none when
    /// fewer than two heard the burst.
    pub fn add(
        &mut self,
        step: u64,
        uavs: &[[f64; 2]],
        sigmas: Option<&[f64]>,
        heard: Option<&[usize]>,
        z: &Vector2<f64>,
    ) -> Option<f64> {
        let own = sigmas.and_then(|s| tdoa::NoiseModel::from_range_sigmas(s).ok());
        let noise = own.or_else(|| self.noise.clone());
        let fim = match heard {
            None => noise.and_then(|noise| Sensors::new(uavs, noise).ok()).and_then(|s| tdoa::fim(&s, z)),
            Some(heard) => noise.and_then(|noise| {
                let pts: Vec<[f64; 2]> = heard.iter().filter_map(|&i| uavs.get(i).copied()).collect();
                let sig: Vec<f64> = heard.iter().filter_map(|&i| noise.sigmas().get(i).copied()).collect();
                let sensors = Sensors::heard(&pts, tdoa::NoiseModel::heard(&sig).ok()?).ok()?;
                tdoa::fim(&sensors, z)
            }),
        };
        let elapsed = self.last_step.map_or(1, |l| step.saturating_sub(l).max(1));
        self.last_step = Some(step);
        let b = self.bound.add(fim, elapsed);
        b.is_finite().then_some(b)
    }
}

/// The UAVs a step's information comes from: the arrivals received (`None`: every UAV).
fn heard_of(s: &crate::StepRecord) -> Option<&[usize]> {
    s.receiver.as_ref().map(|r| r.heard.as_slice())
}

/// The run's receiver totals; `None` when every step was complete.
fn receiver_totals(run: &crate::RunRecord) -> Option<crate::ReceiverTotals> {
    if run.steps.iter().all(|s| s.receiver.is_none()) {
        return None;
    }
    let n = run.steps.iter().map(|s| s.uavs.len()).max().unwrap_or(0);
    let truth = run.steps.iter().all(|s| s.truth.is_some());
    let mut t = crate::ReceiverTotals { outliers_by_uav: vec![0; n], ..Default::default() };
    let (mut multipath, mut found, mut good) = (0u64, 0u64, 0u64);
    let (mut minority, mut minority_found) = (0u64, 0u64);
    for s in &run.steps {
        let Some(r) = &s.receiver else { continue };
        if r.silent == Some(true) {
            t.silent_steps += 1;
        } else {
            t.arrivals_lost += s.uavs.len().saturating_sub(r.heard.len()) as u64;
        }
        if r.heard.len() < 2 {
            t.steps_without_fix += 1;
        }
        for &i in &r.outliers {
            if let Some(c) = t.outliers_by_uav.get_mut(i) {
                *c += 1;
            }
        }
        let reflected = r.multipath.as_deref().unwrap_or(&[]);
        multipath += reflected.len() as u64;
        found += r.outliers.iter().filter(|i| reflected.contains(i)).count() as u64;
        good += r.outliers.iter().filter(|i| !reflected.contains(i)).count() as u64;
        if 2 * reflected.len() < r.heard.len() {
            minority += reflected.len() as u64;
            minority_found += r.outliers.iter().filter(|i| reflected.contains(i)).count() as u64;
        }
    }
    if truth {
        t.multipath_arrivals = Some(multipath);
        t.multipath_dropped = Some(found);
        t.good_arrivals_dropped = Some(good);
        t.multipath_minority_arrivals = Some(minority);
        t.multipath_minority_dropped = Some(minority_found);
    }
    Some(t)
}

/// Fills in what needs the whole run: per step `pcrlb_at_estimate_m` (the same recursion as `pcrlb_m`,
/// each snapshot's information at that step's estimate); and what needs the truth: per step
/// `estimate_error_m`, `nees`, `pcrlb_m`
/// (the posterior CRLB from every snapshot so far, under the scenario's emitter model) and
/// `min_true_distance_m`; for the run `rejected_snapshots`; and the safety along the arcs flown
/// ([`crate::along_arcs`]: per interval the margins, for the run `true_spacing_violations`,
/// `true_standoff_violations`, `uncertified_steps`). Steps without a `truth` get `None`. The same pure
/// function for `simulate` and the pipeline's monitor, so their records agree.
pub fn annotate(run: &mut crate::RunRecord) {
    let sc = &run.scenario;
    let mut at_truth = RunningBound::new(sc);
    let mut along_estimates = RunningBound::new(sc);
    run.rejected_snapshots = run.steps.iter().filter(|s| s.estimate_status == "rejected").count() as u64;
    for s in &mut run.steps {
        let est = Vector2::new(s.estimate[0], s.estimate[1]);
        s.pcrlb_at_estimate_m = if est.iter().all(|v| v.is_finite()) {
            along_estimates.add(s.step, &s.uavs, s.range_sigmas_m.as_deref(), heard_of(s), &est)
        } else {
            None
        };
        let Some(truth) = s.truth else {
            s.estimate_error_m = None;
            s.nees = None;
            s.pcrlb_m = None;
            s.min_true_distance_m = None;
            continue;
        };
        let z = Vector2::new(truth[0], truth[1]);
        let cov = nalgebra::Matrix2::new(
            s.estimate_cov[0][0],
            s.estimate_cov[0][1],
            s.estimate_cov[1][0],
            s.estimate_cov[1][1],
        );
        s.estimate_error_m = est.iter().all(|v| v.is_finite()).then(|| (est - z).norm());
        s.nees = tdoa::nees(&est, &cov, &z);
        s.pcrlb_m = at_truth.add(s.step, &s.uavs, s.range_sigmas_m.as_deref(), heard_of(s), &z);
        let min = s.uavs.iter().map(|w| (w[0] - z.x).hypot(w[1] - z.y)).fold(f64::INFINITY, f64::min);
        s.min_true_distance_m = min.is_finite().then_some(min);
    }
    run.receiver = receiver_totals(run);
    // The violations of D_min and L_min, counted along the arcs flown.
    crate::along_arcs::annotate_along_arcs(run);
    crate::geographic::annotate_geographic(run);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::tests::record;

    fn run_of(estimates: &[[f64; 2]], truth: Option<[f64; 2]>) -> crate::RunRecord {
        let steps = estimates
            .iter()
            .enumerate()
            .map(|(k, e)| crate::StepRecord {
                uavs: vec![[1500.0 + 400.0 * k as f64, 500.0], [10000.0, 1500.0 + 300.0 * k as f64], [5000.0, 8500.0]],
                estimate: *e,
                truth,
                estimate_status: "ok".into(),
                ..record(k as u64, 1.0)
            })
            .collect();
        crate::RunRecord::new(model::Scenario::default(), ("analytical", "pso"), 1, truth, "fused", steps)
    }

    #[test]
    fn the_pcrlb_along_the_estimates_is_the_pcrlb_when_they_are_the_truth_and_is_there_without_one() {
        let z = [25000.0, 15000.0];
        let mut exact = run_of(&[z; 5], Some(z));
        annotate(&mut exact);
        for s in &exact.steps {
            assert_eq!(s.pcrlb_at_estimate_m, s.pcrlb_m, "step {}", s.step);
            assert!(s.pcrlb_m.is_some());
        }
        // Without a truth: only the bound along the estimates, shrinking as snapshots add information.
        let moved =
            [[24000.0, 14000.0], [24500.0, 14600.0], [24900.0, 15100.0], [25050.0, 15000.0], [25000.0, 15000.0]];
        let mut blind = run_of(&moved, None);
        annotate(&mut blind);
        let b: Vec<f64> = blind.steps.iter().map(|s| s.pcrlb_at_estimate_m.unwrap()).collect();
        assert!(b.windows(2).all(|w| w[1] < w[0]), "{b:?}");
        assert!(blind.steps.iter().all(|s| s.pcrlb_m.is_none() && s.estimate_error_m.is_none()));
        // A NaN estimate (failed, none standing) adds nothing and has no value.
        let mut gap = run_of(&[z, [f64::NAN, f64::NAN], z], None);
        annotate(&mut gap);
        assert_eq!(gap.steps[1].pcrlb_at_estimate_m, None);
        assert!(gap.steps[2].pcrlb_at_estimate_m.unwrap() < gap.steps[0].pcrlb_at_estimate_m.unwrap());
    }
}
