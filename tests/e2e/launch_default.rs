//! `uavloc launch`: the four real processes over real iceoryx2, in lock-step, reproduce `uavloc simulate`
//! exactly, count no rejected message, and leave no process and no iceoryx2 resource behind.
//!
//! Every launch runs in its own domain (`--domain launch-test-<pid>-<tag>`), so the tests run in parallel
//! with each other and with anything else on the machine.

use crate::common;

use std::process::Command;
use std::time::{Duration, Instant};

use common::{assert_nothing_left, assert_same_run, files_mentioning, json_of, uavloc};
use serde_json::Value;

fn domain(tag: &str) -> String {
    common::domain("launch-test", tag)
}

fn launch(domain: &str, extra: &[&str]) -> (Value, Duration) {
    let mut args = vec!["launch", "--headless", "--json", "--domain", domain];
    args.extend_from_slice(extra);
    let start = Instant::now();
    let run = json_of(&args);
    (run, start.elapsed())
}

#[test]
fn six_steps_equal_simulate_for_analytical_and_mc() {
    let _scenario = common::scenario(module_path!());
    for objective in ["analytical", "mc"] {
        let d = domain(&format!("six-{objective}"));
        let (run, _) = launch(&d, &["--steps", "6", "--objective", objective]);
        let sim = json_of(&["simulate", "--json", "--steps", "6", "--objective", objective]);
        assert_eq!(run["steps"].as_array().unwrap().len(), 7, "steps 0..=6");
        assert_same_run(&sim, &run, objective);
        assert_eq!(run["rejected"].as_u64(), Some(0), "{objective}: rejected");
        assert_eq!(run["restarts"].as_u64(), Some(0), "{objective}: restarts");
        assert_nothing_left(&d);
    }
}

#[test]
fn the_default_24_step_run_equals_simulate() {
    let _scenario = common::scenario(module_path!());
    let d = domain("default");
    let (run, took) = launch(&d, &[]);
    let sim = json_of(&["simulate", "--json"]);
    assert_eq!(run["steps"].as_array().unwrap().len(), 25, "the paper's 24 steps plus step 0");
    assert_same_run(&sim, &run, "default");
    assert_eq!(run["rejected"].as_u64(), Some(0));
    assert_eq!(run["restarts"].as_u64(), Some(0));
    // Lock-step from start to end: nothing was waited for until a retry interval or replayed.
    let emitter = run["processes"].as_array().unwrap().iter().find(|p| p["role"] == "emitter-sim").unwrap();
    assert_eq!(emitter["summary"]["retries"].as_u64(), Some(0), "{emitter}");
    assert_eq!(emitter["summary"]["replays"].as_u64(), Some(0), "{emitter}");
    eprintln!("a 24-step launch took {took:?}");
    assert_nothing_left(&d);
}

/// Every receiver impairment on (`scenarios/receiver.toml`: lost arrivals, a silent emitter, multipath,
/// GNSS and clock errors per step and per flight): the processes reproduce `simulate` bit for bit — who
/// was heard, the arrivals dropped, the holds and predictions included — and every step is commanded.
#[test]
fn every_receiver_impairment_on_launch_equals_simulate() {
    let _scenario = common::scenario(module_path!());
    let scenario = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/receiver.toml");
    let d = domain("receiver");
    let (run, _) = launch(&d, &["--scenario", scenario, "--steps", "20"]);
    let sim = json_of(&["simulate", "--json", "--scenario", scenario, "--steps", "20"]);
    assert_same_run(&sim, &run, "receiver");
    let (a, b) = (sim["steps"].as_array().unwrap(), run["steps"].as_array().unwrap());
    let mut impaired = 0;
    for (s, l) in a.iter().zip(b) {
        // `simulate` also records the steps whose only impairment is a reflection (known from the truth
        // alone); the receiver's own view of such a step is a complete one, as `launch` records it.
        assert_eq!(receiver_view(s), receiver_view(l), "step {}: the receiver's view", s["step"]);
        impaired += usize::from(!l["receiver"].is_null());
        assert_eq!(s["range_sigmas_m"], l["range_sigmas_m"], "step {}", s["step"]);
    }
    assert!(impaired >= 3, "the scenario impaired {impaired} steps only");
    for key in ["arrivals_lost", "silent_steps", "steps_without_fix", "outliers_by_uav"] {
        assert_eq!(sim["receiver"][key], run["receiver"][key], "receiver.{key}");
    }
    assert!(
        sim["receiver"]["silent_steps"].as_u64().unwrap() > 0 && sim["receiver"]["arrivals_lost"].as_u64().unwrap() > 0
    );
    assert_eq!(run["rejected"].as_u64(), Some(0));
    assert_nothing_left(&d);
}

/// A step's receiver as the estimator saw it: (UAVs heard, arrivals dropped, silent); a step recorded
/// without a `receiver` was complete.
fn receiver_view(step: &Value) -> (Value, Value, bool) {
    let r = &step["receiver"];
    let n = step["uavs"].as_array().map_or(0, Vec::len);
    let all = Value::from((0..n as u64).collect::<Vec<_>>());
    if r.is_null() {
        return (all, serde_json::json!([]), false);
    }
    (r["heard"].clone(), r["outliers"].clone(), r["silent"].as_bool().unwrap_or(false))
}

#[test]
fn the_table_and_a_second_seed() {
    let _scenario = common::scenario(module_path!());
    // Another seed and solver through the table output: it runs and reports the run.
    let d = domain("table");
    let out = uavloc(&["launch", "--headless", "--steps", "2", "--seed", "7", "--solver", "ga", "--domain", &d]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for expected in [d.as_str(), "analytical / ga", "final CRLB at truth", "rejected messages", "restarts"] {
        assert!(text.contains(expected), "missing {expected:?} in:\n{text}");
    }
    assert_nothing_left(&d);
}

#[test]
fn controlled_scenarios_and_bad_domains_are_refused() {
    let _scenario = common::scenario(module_path!());
    let dir = std::env::temp_dir().join(format!("uavloc-launch-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("controlled.toml");
    std::fs::write(&file, "target = \"controlled\"\n").unwrap();
    let out = uavloc(&["launch", "--headless", "--scenario", file.to_str().unwrap(), "--domain", &domain("ctl")]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("controlled") && err.contains("simulate"), "{err}");
    let out = uavloc(&["launch", "--domain", "no/slash"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("invalid domain"));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_domain_in_use_is_refused() {
    let _scenario = common::scenario(module_path!());
    use std::io::{BufRead, BufReader};
    use std::process::Stdio;

    let d = domain("busy");
    // A stand-alone estimator of the domain, started by hand.
    let mut estimator = Command::new(env!("CARGO_BIN_EXE_uavloc"))
        .args(["process", "estimator", "--domain", &d, "--quiet", "--supervised"])
        .stdout(Stdio::piped())
        .spawn()
        .expect("start an estimator");
    let mut ready = String::new();
    BufReader::new(estimator.stdout.take().unwrap()).read_line(&mut ready).unwrap();
    assert_eq!(ready.trim(), "ready");
    // While it runs, its resources are visible the way `assert_nothing_left` looks for them.
    let mut files = Vec::new();
    files_mentioning(&std::env::temp_dir().join("iceoryx2"), &d, &mut files);
    assert!(!files.is_empty(), "the leftover check would not see a live node of {d}");
    let listed = json_of(&["process", "resources", "--domain", &d]);
    assert_eq!(listed["nodes"][0]["name"].as_str(), Some(format!("{d}/estimator").as_str()), "{listed}");
    let out = uavloc(&["launch", "--headless", "--steps", "1", "--domain", &d]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("in use") && err.contains(&format!("{d}/estimator")), "{err}");
    // SIGTERM: the estimator exits cleanly and takes its iceoryx2 resources with it.
    // SAFETY: kill(2) on our own child, not yet reaped.
    unsafe { libc::kill(estimator.id() as libc::pid_t, libc::SIGTERM) };
    assert!(estimator.wait().unwrap().success());
    assert_nothing_left(&d);
}
