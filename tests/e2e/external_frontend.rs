//! An external front end: `uavloc launch --source external` runs the estimator, the planner and the
//! monitor without emitter-sim, and a real foreign client — `examples/python/frontend.py`, on iceoryx2's
//! official Python bindings (PyPI `iceoryx2` 0.10) — plays the default scenario's world: it publishes each
//! step's measurement and flies each command.

use crate::common;

use std::path::Path;
use std::process::Command;

use serde_json::Value;

use common::{Launch, assert_nothing_left, domain, python, scratch};

const STEPS: u64 = 12;

/// Runs `examples/python/frontend.py --domain D --steps N --timeout-s 60 <extra>` to its end.
fn front_end(domain: &str, steps: &str, extra: &[&str]) -> std::io::Result<std::process::Output> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/python/frontend.py");
    Command::new(python())
        .arg(script)
        .args(["--domain", domain, "--steps", steps, "--timeout-s", "60"])
        .args(extra)
        .output()
}

/// Runs the front end against a launch in `domain`; the launch's JSON and the front end's summary.
fn run(domain: &str, tag: &str, extra: &[&str]) -> (Value, Value) {
    let dir = scratch(tag);
    let steps = STEPS.to_string();
    let mut launch = Launch::start(domain, &dir, &["--source", "external", "--steps", &steps]);
    let out = front_end(domain, &steps, extra);
    // A launch with an external source waits for its front end: never leave one behind.
    let out = match out {
        Ok(out) if out.status.success() => out,
        other => {
            let _ = launch.child.kill();
            let _ = launch.child.wait();
            panic!("the front end failed: {other:?}\nlaunch:\n{}", launch.stderr_text());
        }
    };
    let summary: Value = serde_json::from_slice(&out.stdout).expect("the front end's JSON summary");
    let report = launch.finish_json();
    assert_nothing_left(domain);
    let _ = std::fs::remove_dir_all(&dir);
    (report, summary)
}

#[test]
fn a_python_front_end_is_answered_every_step_and_its_emitter_is_localised() {
    let _scenario = common::scenario(module_path!());
    let d = domain("ext", "py");
    let (report, fe) = run(&d, "ext-py", &[]);
    assert_eq!(fe["steps_published"], STEPS + 1);
    assert_eq!(fe["commands_flown"], STEPS, "every step but the last answered with a command");
    assert_eq!(fe["holds"], 0);
    assert_eq!(report["rejected"], 0, "{}", report["rejected_by"]);
    let steps = report["steps"].as_array().unwrap();
    assert_eq!(steps.len() as u64, STEPS + 1, "every step recorded");
    for s in &steps[..STEPS as usize] {
        assert!(s["planner"].is_object() && s["objective_value"].is_f64(), "step planned: {s}");
    }
    // The world flew the commands: where the front end's UAVs ended is the last measurement's geometry.
    let last = &steps[STEPS as usize];
    assert_eq!(last["uavs"], fe["uavs"]);
    assert_ne!(last["uavs"], steps[0]["uavs"]);
    // No truth: the truth-based fields are absent or null, never zero; the CRLB at the estimate is there.
    assert!(report["emitter"].is_null() && report["true_standoff_violations"].is_null(), "{}", report["emitter"]);
    for s in steps {
        assert!(s.get("crlb_true_m").is_none(), "{s}");
        for key in ["truth", "rmse_m", "estimate_error_m", "nees", "pcrlb_m", "min_true_distance_m"] {
            assert!(s[key].is_null(), "{key}: {s}");
        }
        assert!(s["crlb_at_estimate_m"].as_f64().is_some_and(|c| c > 0.0), "{s}");
    }
    // The information gathered, along the estimates: the bound shrinks over the run.
    let bound = |s: &Value| s["pcrlb_at_estimate_m"].as_f64().unwrap();
    assert!(bound(last) < 0.5 * bound(&steps[0]), "{} → {}", bound(&steps[0]), bound(last));
    // The estimate is within its expected error of the truth only the front end knows: the NEES of the
    // reported covariance below the 99.9 % point of χ²(2), and closer than the initial CRLB (1655.58 m).
    let truth = [fe["truth"][0].as_f64().unwrap(), fe["truth"][1].as_f64().unwrap()];
    let e = [last["estimate"][0].as_f64().unwrap() - truth[0], last["estimate"][1].as_f64().unwrap() - truth[1]];
    let c = |i: usize, j: usize| last["estimate_cov"][i][j].as_f64().unwrap();
    let det = c(0, 0) * c(1, 1) - c(0, 1) * c(1, 0);
    let nees = (c(1, 1) * e[0] * e[0] - (c(0, 1) + c(1, 0)) * e[0] * e[1] + c(0, 0) * e[1] * e[1]) / det;
    assert!(nees < 13.82, "NEES {nees} of the final estimate (error {e:?})");
    assert!(e[0].hypot(e[1]) < 1655.58, "final error {e:?}");
    assert!(last["estimate_status"] == "ok", "{last}");
}

#[test]
fn malformed_messages_from_the_python_front_end_are_rejected_and_counted() {
    let _scenario = common::scenario(module_path!());
    let d = domain("ext", "bad");
    let (report, fe) = run(&d, "ext-bad", &["--inject-bad"]);
    assert_eq!(fe["bad_sent"], serde_json::json!(["nan", "count", "stale"]));
    // Each of the three is rejected by each process that reads measurements, and the run goes on.
    assert_eq!(report["rejected_by"]["estimator"], 3, "{}", report["rejected_by"]);
    assert_eq!(report["rejected_by"]["monitor"], 3, "{}", report["rejected_by"]);
    assert_eq!(report["steps"].as_array().unwrap().len() as u64, STEPS + 1);
    assert_eq!(fe["commands_flown"], STEPS);
}

#[test]
fn pacing_flags_of_emitter_sim_are_refused_with_an_external_source() {
    let _scenario = common::scenario(module_path!());
    for flags in [&["--mode", "realtime"][..], &["--step-delay-ms", "5"]] {
        let out = common::uavloc(&[&["launch", "--source", "external", "--headless"][..], flags].concat());
        assert_eq!(out.status.code(), Some(2), "{flags:?}");
        assert!(String::from_utf8_lossy(&out.stderr).contains("--source external"), "{flags:?}");
    }
}

/// A front end that stops publishing before the launch's last step (here: it was told 6 steps, the launch
/// 12) ends the launch with a clear error a few seconds after it left — the launch used to wait for ever.
/// The steps it did publish are recorded in the log.
#[test]
fn a_front_end_that_leaves_before_the_last_step_ends_the_launch_with_a_clear_error() {
    let _scenario = common::scenario(module_path!());
    let d = domain("ext", "left");
    let dir = scratch("ext-left");
    let launch = Launch::start(&d, &dir, &["--source", "external", "--steps", &STEPS.to_string()]);
    let out = front_end(&d, "6", &["--linger-s", "0"]).expect("run the front end");
    assert!(out.status.success(), "the front end failed: {}", String::from_utf8_lossy(&out.stderr));
    let left = std::time::Instant::now();
    let log = launch.log.clone();
    let (status, _stdout, stderr) = launch.finish();
    assert_eq!(status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("the front end left the measurement topic"), "{stderr}");
    assert!(stderr.contains("the monitor process stopped unexpectedly (exit code 3)"), "{stderr}");
    // Ended after the monitor's grace, not at the test's bound.
    assert!(left.elapsed() < common::FINISH_TIMEOUT / 4, "took {:?}", left.elapsed());
    let events = common::read_events(&log);
    let steps = events.iter().filter(|e| e["event"] == "step").count();
    assert_eq!(steps, 7, "steps 0..=6 recorded");
    assert_eq!(events.iter().filter(|e| e["event"] == "front_end_left").count(), 1);
    assert_nothing_left(&d);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A front end flying another formation than the launch's scenario (4 UAVs against 3): the planner rejects
/// its estimates naming both counts (before: "positions: expected 3 values, got 4", as if the planner had
/// erred), plans nothing, and the launch ends once the front end gives up waiting for a command.
#[test]
fn a_front_end_with_another_uav_count_is_rejected_naming_both_counts() {
    let _scenario = common::scenario(module_path!());
    let d = domain("ext", "count");
    let dir = scratch("ext-count");
    let nominal =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/nominal.toml")).unwrap();
    let four: String = nominal
        .lines()
        .map(|l| {
            if l.starts_with("uavs =") {
                "uavs = [[1500.0, 500.0], [10000.0, 1500.0], [5000.0, 8500.0], [7000.0, 3000.0]]"
            } else {
                l
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    assert_ne!(four, nominal);
    let world = dir.join("four.toml");
    std::fs::write(&world, four).unwrap();
    let launch = Launch::start(&d, &dir, &["--source", "external", "--steps", "6"]);
    let out = front_end(&d, "6", &["--scenario", world.to_str().unwrap(), "--timeout-s", "3", "--linger-s", "0"])
        .expect("run the front end");
    assert!(!out.status.success(), "the front end got a command for another formation");
    let (status, _stdout, stderr) = launch.finish();
    assert_eq!(status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("rejected the estimate of step 0: 4 UAVs, this run's scenario has 3"), "{stderr}");
    assert!(!stderr.contains("expected 3 values"), "{stderr}");
    assert_nothing_left(&d);
    std::fs::remove_dir_all(&dir).ok();
}
