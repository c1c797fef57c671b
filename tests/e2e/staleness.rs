//! Staleness: in a real-time run with a planner deadline (`--estimate-deadline-ms`), the estimator is
//! frozen (SIGSTOP) for several steps. No fresh estimate reaches the planner, so it holds: the UAVs
//! loiter on their backup circles (`planning::hold`: a right turn of θ_b per step, certified for the
//! spacing), which the world flies in time — no step is missed — and the monitor records those steps
//! as `estimate_stale`, logs them and counts them. When the estimator
//! thaws (SIGCONT) it works off its backlog; the late estimates are answered with the holds, and planning
//! goes on from the fresh ones.

use crate::common;

use std::time::Duration;

use common::{Launch, assert_nothing_left, domain, kill, pid_of, read_events, scratch};
use serde_json::Value;

const STEPS: u64 = 40;

fn headings(step: &Value) -> Vec<f64> {
    step["headings_rad"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect()
}

fn uavs(step: &Value) -> Vec<[f64; 2]> {
    serde_json::from_value(step["uavs"].clone()).unwrap()
}

#[test]
fn a_frozen_estimator_makes_the_planner_hold_on_the_backup_circles_and_the_monitor_show_it() {
    let _scenario = common::scenario(module_path!());
    let d = domain("stale", "freeze");
    let dir = scratch("stale-freeze");
    let steps = STEPS.to_string();
    // 0.1 s per step; a step's estimate normally reaches the planner within a millisecond or two.
    let mut launch = Launch::start(
        &d,
        &dir,
        &["--steps", &steps, "--mode", "realtime", "--time-scale", "100", "--estimate-deadline-ms", "30"],
    );
    launch.wait_for_step(8, Duration::from_secs(30));
    let estimator = pid_of(&d, "estimator").expect("the estimator runs");
    kill(estimator, libc::SIGSTOP);
    // Frozen until the planner has held for 4 steps (4 commands more than at the freeze: no
    // estimate can reach it meanwhile), then thawed — whatever the machine's load.
    let commands = |l: &Launch| -> usize {
        l.events().iter().filter(|e| e["event"] == "message" && e["kind"] == "command").count()
    };
    let at_freeze = commands(&launch);
    let deadline = std::time::Instant::now() + Duration::from_secs(30);
    while commands(&launch) < at_freeze + 4 {
        assert!(std::time::Instant::now() < deadline, "the planner did not hold while the estimator was frozen");
        std::thread::sleep(Duration::from_millis(10));
    }
    kill(estimator, libc::SIGCONT);
    let stderr_path = launch.stderr.clone();
    let run = launch.finish_json();
    let stderr = std::fs::read_to_string(stderr_path).unwrap_or_default();

    let records = run["steps"].as_array().unwrap();
    assert_eq!(records.len() as u64, STEPS + 1, "{stderr}");
    let held: Vec<u64> = records
        .iter()
        .filter(|s| s["active_constraints"].as_array().unwrap().iter().any(|a| a == "estimate_stale"))
        .map(|s| s["step"].as_u64().unwrap())
        .collect();
    // Frozen for at least 4 commands: at least 3 held (the first may have been planned from an estimate
    // the estimator published just before it stopped).
    assert!(held.len() >= 3, "held steps {held:?}\n{stderr}");
    assert_eq!(run["stale_steps"].as_u64(), Some(held.len() as u64));

    let sc = model::Scenario::default();
    let turn = planning::shield::safety_limits(&sc).backup_turn();
    for &k in &held {
        let (prev, this, next) = (&records[k as usize - 1], &records[k as usize], &records[k as usize + 1]);
        // A hold turns every UAV right by θ_b from the heading it has (the command flown before's) ...
        for (phi, psi) in headings(this).into_iter().zip(headings(prev)) {
            assert!((phi - (psi - turn)).abs() < 1e-12, "step {k}: {phi} after {psi}");
        }
        assert!(this["objective_value"].is_null() && this["plan_ms"].is_null(), "step {k}: {this}");
        assert_eq!(this["safety"]["certified"].as_bool(), Some(true), "step {k}: {this}");
        // ... and the world flew that arc, one interval at the UAV speed.
        for ((p, q), (psi, phi)) in
            uavs(this).iter().zip(uavs(next)).zip(headings(prev).into_iter().zip(headings(this)))
        {
            let w = model::kinematics::next_position(nalgebra::Vector2::from(*p), psi, phi, sc.speed, sc.dt);
            assert!((q[0] - w.x).hypot(q[1] - w.y) < 1e-6, "step {k}: {q:?} vs {w:?}");
        }
    }
    // Planning went on after the thaw: the last steps have plans again.
    let last_planned = &records[STEPS as usize - 1];
    assert!(last_planned["objective_value"].is_number(), "{last_planned}");

    // The planner counted what it held and the late estimates it answered with the holds.
    let planner = run["processes"].as_array().unwrap().iter().find(|p| p["role"] == "planner").unwrap();
    assert_eq!(planner["summary"]["held"].as_u64(), Some(held.len() as u64), "{planner}");
    assert!(planner["summary"]["late_estimates"].as_u64().unwrap() >= 1, "{planner}");
    let monitor = run["processes"].as_array().unwrap().iter().find(|p| p["role"] == "monitor").unwrap();
    assert_eq!(monitor["summary"]["stale_steps"].as_u64(), Some(held.len() as u64), "{monitor}");
    assert!(stderr.contains("holding (on the backup circles)"), "{stderr}");

    // The monitor's log has an event per held step, and the step events say so.
    let events = read_events(&dir.join("run.jsonl"));
    let logged: Vec<u64> =
        events.iter().filter(|e| e["event"] == "estimate_stale").map(|e| e["step"].as_u64().unwrap()).collect();
    assert_eq!(logged, held);
    for e in events.iter().filter(|e| e["event"] == "step") {
        let k = e["step"].as_u64().unwrap();
        assert_eq!(e["estimate_stale"].as_bool(), Some(held.contains(&k)), "step {k}");
    }
    assert_nothing_left(&d);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_deadline_flag_that_is_not_a_number_is_a_clear_error() {
    let _scenario = common::scenario(module_path!());
    let out = common::uavloc(&["launch", "--estimate-deadline-ms", "soon"]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("--estimate-deadline-ms"), "{stderr}");
}
