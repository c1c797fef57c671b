//! The fused estimator: Monte Carlo consistency over closed-loop runs of the default scenario
//! through the same library calls as `uavloc simulate`, and the constant-velocity model against a moving
//! emitter, and the standoff chance constraint against the TRUE emitter. 200 runs of the closed loop
//! take about a second in release; `uavloc paper fusion` is the full study.

use experiments::fusion::consistency;
use experiments::{Engine, Settings};
use model::Scenario;
use planning::{ObjectiveKind, SolverKind};
use tdoa::EmitterModel;
use tdoa::fusion::EstimatorKind;

fn batch(runs: usize, scenario: &Scenario) -> Vec<record::RunRecord> {
    let engine = Engine::new(Settings { runs, resamples: 1, ..Settings::default() });
    engine.batch("fusion test", scenario, ObjectiveKind::Analytical, SolverKind::Pso).unwrap().runs.clone()
}

/// The consistency criteria on `runs` runs: RMSE within `ratio` × PCRLB at every step from step 5, mean NEES
/// in the 95 % band at ≥ `nees_share` of those steps, terminal RMSE ≤ `terminal_max`.
fn assert_consistent(label: &str, runs: &[record::RunRecord], ratio: (f64, f64), nees_share: f64, terminal_max: f64) {
    let c = consistency(runs);
    for (k, r) in c.ratio().iter().enumerate().skip(5) {
        assert!(
            (ratio.0..=ratio.1).contains(r),
            "{label}: step {k}: RMSE {:.1} m vs PCRLB {:.1} m (ratio {r:.3})",
            c.rmse[k],
            c.pcrlb[k]
        );
    }
    let inside = c.nees_inside(5);
    assert!(
        inside >= nees_share,
        "{label}: mean NEES inside {:?} at {:.0} % of steps: {:?}",
        c.band,
        100.0 * inside,
        c.mean_nees
    );
    let terminal = *c.rmse.last().unwrap();
    assert!(terminal <= terminal_max, "{label}: terminal RMSE {terminal:.1} m");
}

#[test]
fn fusion_beats_the_per_step_chan_of_the_paper() {
    let _scenario = crate::common::scenario(module_path!());
    let runs = batch(60, &Scenario::default());
    assert!(runs.iter().all(|r| r.estimator == "fused"));
    // The paper's per-step Chan on the same seeds is far from the bound at the end.
    let snap = batch(60, &Scenario { estimator: EstimatorKind::Snapshot, ..Scenario::default() });
    let (f, s) = (consistency(&runs), consistency(&snap));
    assert!(
        s.rmse.last().unwrap() > &(2.0 * f.rmse.last().unwrap()),
        "snapshot {:?} vs fused {:?}",
        s.rmse.last(),
        f.rmse.last()
    );
}

#[test]
fn fused_default_scenario_is_efficient_and_consistent() {
    let _scenario = crate::common::scenario(module_path!());
    let runs = batch(200, &Scenario::default());
    assert_consistent("fused, 200 runs", &runs, (0.9, 1.2), 0.9, 100.0);
}

#[test]
fn constant_velocity_model_tracks_a_moving_emitter_and_the_static_model_shows_its_lag() {
    let _scenario = crate::common::scenario(module_path!());
    let moving = Scenario { emitter_velocity: [10.0, 0.0], ..Scenario::default() };
    // The model matched to the truth: a 10 m/s emitter flying straight, prior σ_v = 10 m/s per axis and a
    // small process noise. (With the defaults, σ_v = 20 m/s and σ_a = 0.05 m/s², the model is looser than
    // this truth and the filter is conservative: RMSE 0.86–1.06 × PCRLB, mean NEES below the band at some
    // steps — measured, see EXPERIMENTS.md.)
    let cv = batch(
        200,
        &Scenario {
            emitter_model: EmitterModel::ConstantVelocity,
            velocity_prior_sigma: 10.0,
            process_noise_accel: 0.01,
            ..moving.clone()
        },
    );
    assert_consistent("constant velocity, 200 runs", &cv, (0.9, 1.2), 0.9, 200.0);
    // Velocity estimates are reported, and converge to the truth (10, 0) m/s.
    let v: Vec<[f64; 2]> = cv.iter().map(|r| r.steps.last().unwrap().estimate_velocity.unwrap()).collect();
    let mean_vx = v.iter().map(|v| v[0]).sum::<f64>() / v.len() as f64;
    assert!((mean_vx - 10.0).abs() < 2.0, "mean vx {mean_vx}");
    // The static model on the same moving emitter: the mismatch is visible, NEES far above the band.
    let fixed = batch(200, &moving);
    let c = consistency(&fixed);
    let late = c.mean_nees[12..].iter().sum::<f64>() / c.mean_nees[12..].len() as f64;
    assert!(late > 3.0 * c.band.1, "static model on a moving emitter: late mean NEES {late:.2} (band {:?})", c.band);
}

/// Fraction of (UAV, step) pairs inside `L_min` of the TRUE emitter, and the deepest one (m inside).
fn true_violations(runs: &[record::RunRecord]) -> (f64, f64) {
    let pairs: u64 = runs.iter().map(|r| r.true_standoff_violations.unwrap()).sum();
    let total: usize = runs.iter().map(|r| r.steps.len() * r.scenario.uav_count()).sum();
    let l_min = runs[0].scenario.l_min;
    let closest =
        runs.iter().flat_map(|r| r.steps.iter().filter_map(|s| s.min_true_distance_m)).fold(f64::INFINITY, f64::min);
    (pairs as f64 / total as f64, l_min - closest)
}

#[test]
fn the_standoff_chance_constraint_is_calibrated_on_60_step_runs() {
    let _scenario = crate::common::scenario(module_path!());
    // 200 runs of 60 steps: the UAVs reach the L_min ring at about step 38 and orbit it. The waypoint
    // planner keeps the chance constraint at its waypoints: along the arcs it holds at c = 0.99 …
    let long = Scenario { steps: 60, safety: model::safety::SafetyMode::Waypoints, ..Scenario::default() };
    let (inside, depth) = true_violations(&batch(200, &long));
    assert!(inside <= 1.0 - long.standoff_confidence, "c = 0.99: {:.3} % of the pairs inside L_min", 100.0 * inside);
    assert!(depth < 100.0, "c = 0.99: the deepest violation is {depth:.1} m inside L_min");
    // … while the paper's constraint at ẑ (c = 0) lets the UAVs well inside the true standoff.
    let paper = Scenario { standoff_confidence: 0.0, ..long.clone() };
    let (inside0, depth0) = true_violations(&batch(200, &paper));
    assert!(inside0 > 0.05 && depth0 > 300.0, "c = 0: {:.2} % inside, {depth0:.0} m deep", 100.0 * inside0);
    // The certified planner keeps it along the arcs too, with no more UAV-steps inside than the waypoint
    // planner.
    let certified = Scenario { safety: model::safety::SafetyMode::Certified, ..long };
    let (inside_c, depth_c) = true_violations(&batch(200, &certified));
    assert!(inside_c <= inside, "certified: {:.3} % inside against {:.3} %", 100.0 * inside_c, 100.0 * inside);
    assert!(depth_c < 100.0, "certified: the deepest violation is {depth_c:.1} m inside L_min");
}
