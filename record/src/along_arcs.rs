//! A run's safety along the arcs the UAVs flew: per interval the smallest pair distance, the smallest
//! standoff margin to the estimate (with the chance bound) and the smallest distance to the true
//! emitter; per run the violations of `D_min` and `L_min` counted along the arcs, not at the waypoints.
//!
//! The arc of UAV i from step k to k + 1 starts at its recorded position with the heading it flew into
//! step k (step k − 1's commanded heading; at step 0 the scenario's initial heading) and turns to step
//! k's commanded heading, `v·Δt` long ([`model::arc::Arc`]). Where that arc does not end at the next
//! recorded position (an external front end that flew otherwise), the straight segment between the two
//! recorded positions is taken instead. The true emitter moves in a straight line between its recorded
//! positions (a constant-velocity truth). Minima are certified lower bounds within 1 mm of the
//! true minimum (a pair's within 10⁻⁴ of its distance where that cannot reach `D_min`).
//!
//! Units: metres, seconds, radians.

use model::arc::{Arc, moving_point_min_distance_within, pair_min_distance_within};
use model::safety::EmitterPrediction;
use nalgebra::Vector2;

use crate::record::RunRecord;

/// How far (m) an arc's end may be from the next recorded position and still be the path flown.
const ARC_MATCH_M: f64 = 1.0;

/// The bracket of every reported minimum, metres: fine enough to tell a pair the planner certified on
/// its bound (the planner brackets to `model::arc::MIN_TOLERANCE_M`) from one below it.
const REPORT_TOLERANCE_M: f64 = 1e-3;

/// The relative bracket of a pair minimum well above `D_min`: 10⁻⁴ of the distance (0.7 m at 7 km).
const REPORT_RELATIVE: f64 = 1e-4;

/// A pair's minimum distance along its arcs (the certified lower bound), bracketed to 10⁻⁴ of the
/// distance — or to [`REPORT_TOLERANCE_M`] when that bracket reaches `D_min`, so that a pair on its
/// bound is told from one below it. (The fine bracket of a pair kilometres apart costs hundreds of
/// evaluations for digits nobody reads.)
fn report_pair_min(a: &Arc, b: &Arc, d_min: f64) -> f64 {
    let ends = (a.start - b.start).norm().min((a.end() - b.end()).norm());
    let coarse = (REPORT_RELATIVE * ends).max(REPORT_TOLERANCE_M);
    let m = pair_min_distance_within(a, b, coarse).lower;
    if coarse > REPORT_TOLERANCE_M && m < d_min + 2.0 * coarse {
        pair_min_distance_within(a, b, REPORT_TOLERANCE_M).lower
    } else {
        m
    }
}

fn v2(p: [f64; 2]) -> Vector2<f64> {
    Vector2::new(p[0], p[1])
}

/// Fills every interval's [`StepSafety`](crate::StepSafety) margins and the run's totals (see the module docs).
pub fn annotate_along_arcs(run: &mut RunRecord) {
    let sc = run.scenario.clone();
    let length = sc.speed * sc.dt;
    let k = if sc.standoff_confidence > 0.0 { tdoa::dist::normal_quantile(sc.standoff_confidence) } else { 0.0 };
    let initial = sc.initial_headings();
    let (mut spacing, mut standoff, mut uncertified) = (0u64, 0u64, 0u64);
    let (mut min_pair, mut min_true) = (None::<f64>, None::<f64>);
    let mut any_truth = false;
    let last = run.steps.len().saturating_sub(1);
    for idx in 0..run.steps.len() {
        if idx == last {
            run.steps[idx].safety = None;
            continue;
        }
        let (here, next) = (&run.steps[idx], &run.steps[idx + 1]);
        let n = here.uavs.len().min(next.uavs.len()).min(here.headings_rad.len());
        let start_heading =
            |i: usize| if idx == 0 { initial.get(i).copied() } else { run.steps[idx - 1].headings_rad.get(i).copied() };
        let arcs: Vec<Arc> = (0..n)
            .map(|i| {
                let (p, q) = (v2(here.uavs[i]), v2(next.uavs[i]));
                let flown = start_heading(i).map(|psi| Arc::new(p, psi, here.headings_rad[i], length));
                match flown {
                    Some(arc) if (arc.end() - q).norm() <= ARC_MATCH_M => arc,
                    _ => {
                        let d = q - p;
                        Arc { start: p, heading: d.y.atan2(d.x), turn: 0.0, length: d.norm() }
                    }
                }
            })
            .collect();
        let mut safety = here.safety.unwrap_or_default();
        if safety.certified == Some(false) {
            uncertified += 1;
        }
        // Pairs.
        let mut pair = None::<f64>;
        for i in 0..n {
            for j in i + 1..n {
                let m = report_pair_min(&arcs[i], &arcs[j], sc.d_min);
                pair = Some(pair.map_or(m, |p: f64| p.min(m)));
                if sc.d_min > 0.0 && m < sc.d_min {
                    spacing += 1;
                }
            }
        }
        safety.min_pair_m = pair;
        if let Some(p) = pair {
            min_pair = Some(min_pair.map_or(p, |q: f64| q.min(p)));
        }
        // The standoff margin to the estimate, as the planner's certificate predicts it.
        let est = v2(here.estimate);
        safety.standoff_margin_m = (sc.l_min > 0.0 && est.iter().all(|v| v.is_finite())).then(|| {
            let cov = tdoa::matrix_from_rows(&here.estimate_cov);
            let e = match (here.estimate_velocity, here.estimate_velocity_cov) {
                (Some(v), Some(vc)) => {
                    EmitterPrediction::moving(est, &cov, v2(v), &tdoa::matrix_from_rows(&vc), sc.process_noise_accel)
                }
                _ => EmitterPrediction::fixed(est, &cov),
            };
            let bound = sc.l_min + k * e.sigma_bound(sc.dt);
            arcs.iter()
                .map(|a| {
                    let m = moving_point_min_distance_within(
                        a,
                        e.position,
                        e.velocity,
                        sc.dt,
                        f64::INFINITY,
                        REPORT_TOLERANCE_M,
                    );
                    m.lower - bound
                })
                .fold(f64::INFINITY, f64::min)
        });
        // The true emitter.
        safety.min_true_distance_m = match (here.truth, next.truth) {
            (Some(z0), Some(z1)) => {
                any_truth = true;
                let velocity = (v2(z1) - v2(z0)) / sc.dt;
                let mut closest = f64::INFINITY;
                for a in &arcs {
                    let m =
                        moving_point_min_distance_within(a, v2(z0), velocity, sc.dt, f64::INFINITY, REPORT_TOLERANCE_M)
                            .lower;
                    closest = closest.min(m);
                    if sc.l_min > 0.0 && m < sc.l_min {
                        standoff += 1;
                    }
                }
                min_true = Some(min_true.map_or(closest, |q: f64| q.min(closest)));
                Some(closest)
            }
            _ => None,
        };
        run.steps[idx].safety = Some(safety);
    }
    run.true_spacing_violations = spacing;
    run.true_standoff_violations = any_truth.then_some(standoff);
    run.uncertified_steps = uncertified;
    run.min_pair_m = min_pair;
    run.min_true_distance_m = min_true;
}

/// The warnings a run's safety calls for (`simulate` and `launch` print them): steps without a
/// certified plan, and every limit broken along the arcs flown.
pub fn safety_warnings(run: &RunRecord) -> Vec<String> {
    let sc = &run.scenario;
    let mut out = Vec::new();
    if run.uncertified_steps > 0 {
        out.push(format!(
            "{} step(s) had no certified plan (the UAVs flew the plan with the largest minimum margin): see \
             safety.certified",
            run.uncertified_steps
        ));
    }
    if run.true_spacing_violations > 0 {
        out.push(format!(
            "{} time(s) two UAVs came closer than d_min = {} m along the arcs flown (closest {:.1} m): see \
             safety.min_pair_m",
            run.true_spacing_violations,
            sc.d_min,
            run.min_pair_m.unwrap_or(f64::NAN)
        ));
    }
    if let Some(n) = run.true_standoff_violations.filter(|n| *n > 0) {
        out.push(format!(
            "{n} time(s) a UAV came inside l_min = {} m of the true emitter along the arcs flown (closest {:.1} \
             m): see safety.min_true_distance_m",
            sc.l_min,
            run.min_true_distance_m.unwrap_or(f64::NAN)
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::tests::record;

    /// The coarse bracket of a far pair is within 10⁻⁴ of the end points' distance below the fine one and
    /// never above the true minimum; near D_min the
    /// fine one is taken, exactly.
    #[test]
    fn a_far_pair_is_bracketed_relatively_and_a_near_one_finely() {
        let mut rng = tdoa::rng::SplitMix64::new(5);
        let mut u = || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        for _ in 0..200 {
            let length = 100.0 + 900.0 * u();
            let a = Arc::new(Vector2::zeros(), 6.3 * u(), 6.3 * u(), length);
            let gap = 300.0 + 8000.0 * u();
            let b =
                Arc::new(Vector2::new(gap * (6.3 * u()).cos(), gap * (6.3 * u()).sin()), 6.3 * u(), 6.3 * u(), length);
            let fine = pair_min_distance_within(&a, &b, REPORT_TOLERANCE_M);
            let d_min = 500.0;
            let m = report_pair_min(&a, &b, d_min);
            let ends = (a.start - b.start).norm().min((a.end() - b.end()).norm());
            assert!(m <= fine.upper + 1e-9 && m >= fine.lower - REPORT_RELATIVE * ends - 1e-9, "{m} vs {fine:?}");
            // A violation of D_min is counted exactly as with the fine bracket.
            assert_eq!(m < d_min, fine.lower < d_min, "{m} vs {fine:?}");
            if m < d_min + 2.0 * (REPORT_RELATIVE * ends).max(REPORT_TOLERANCE_M) {
                assert_eq!(m, fine.lower, "near D_min the fine bracket");
            }
        }
    }

    /// Two UAVs whose paths cross mid-interval: 354 m apart at both waypoints (above D_min = 300 m), on
    /// top of each other halfway.
    #[test]
    fn spacing_is_counted_between_the_waypoints() {
        let half_pi = std::f64::consts::FRAC_PI_2;
        let sc = model::Scenario {
            uavs: vec![[0.0, 0.0], [250.0, -250.0], [0.0, 50_000.0]],
            headings: Some(vec![0.0, half_pi, 0.0]),
            emitter: [500.0, 40_000.0],
            d_min: 300.0,
            l_min: 0.0,
            safety: model::safety::SafetyMode::Waypoints,
            ..model::Scenario::default()
        };
        let steps = [[[0.0, 0.0], [250.0, -250.0], [0.0, 50_000.0]], [[500.0, 0.0], [250.0, 250.0], [500.0, 50_000.0]]]
            .iter()
            .enumerate()
            .map(|(k, uavs)| crate::StepRecord {
                uavs: uavs.to_vec(),
                headings_rad: vec![0.0, half_pi, 0.0],
                truth: Some([500.0, 40_000.0]),
                ..record(k as u64, 1.0)
            })
            .collect();
        let mut run = crate::RunRecord::new(sc, ("analytical", "pso"), 1, None, "fused", steps);
        annotate_along_arcs(&mut run);
        let s0 = run.steps[0].safety.unwrap();
        assert!(s0.min_pair_m.unwrap() < 0.25, "{s0:?}");
        assert_eq!(run.true_spacing_violations, 1);
        assert!(run.steps[1].safety.is_none());
        // The truth is static 40 km away: the closest approach is UAV 2's, 10 km at the end of its arc.
        assert!((run.min_true_distance_m.unwrap() - (500f64.hypot(10_000.0) - 500.0 * 0.0)).abs() < 600.0);
        assert_eq!(run.true_standoff_violations, Some(0));
        let warnings = safety_warnings(&run);
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(warnings[0].starts_with("1 time(s) two UAVs came closer than d_min = 300 m"), "{warnings:?}");
        run.uncertified_steps = 2;
        assert!(safety_warnings(&run)[0].starts_with("2 step(s) had no certified plan"));
    }
}
