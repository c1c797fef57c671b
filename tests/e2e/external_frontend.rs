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
    run_with(domain, tag, &[], extra)
}

/// [`run`] with `launch_extra` flags for the launch.
fn run_with(domain: &str, tag: &str, launch_extra: &[&str], extra: &[&str]) -> (Value, Value) {
    let dir = scratch(tag);
    let steps = STEPS.to_string();
    let mut launch =
        Launch::start(domain, &dir, &[&["--source", "external", "--steps", &steps][..], launch_extra].concat());
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

/// A front end whose receivers lose arrivals, hear a silent emitter and time reflections: every step is
/// answered with a command (a hold until the first fix), the monitor records who was heard and counts
/// what was lost as the front end says, and the emitter is still localised.
#[test]
fn partial_and_silent_steps_from_the_python_front_end_are_fused_and_commanded() {
    let _scenario = common::scenario(module_path!());
    let d = domain("ext", "rx");
    let kept = scratch("ext-rx-recording");
    let recording = kept.join("run.mcap");
    let (report, fe) = run_with(
        &d,
        "ext-rx",
        &["--record", recording.to_str().unwrap()],
        &["--loss", "0.2", "--silence", "0.2", "--multipath", "0.05", "--seed", "3"],
    );
    assert_eq!(fe["commands_flown"], STEPS, "every step but the last answered with a command");
    assert_eq!(report["rejected"], 0, "{}", report["rejected_by"]);
    let rx = &report["receiver"];
    assert_eq!(rx["silent_steps"], fe["silent_steps"], "{rx}");
    assert_eq!(rx["arrivals_lost"], fe["arrivals_lost"], "{rx}");
    assert!(fe["silent_steps"].as_u64().unwrap() + fe["partial_steps"].as_u64().unwrap() > 0, "{fe}");
    let steps = report["steps"].as_array().unwrap();
    let silent = steps.iter().filter(|s| s["receiver"]["silent"] == true).count() as u64;
    assert_eq!(silent, fe["silent_steps"].as_u64().unwrap());
    for s in steps.iter().filter(|s| s["receiver"]["silent"] == true) {
        assert!(matches!(s["estimate_status"].as_str(), Some("predicted" | "failed")), "{s}");
    }
    // Step 0 has no fix here; the run and that step are still the fused estimator's (a fused estimator
    // sends no posterior before its first fix: the record named it "snapshot", unlike `simulate`).
    assert_eq!(steps[0]["estimate_status"], "failed", "this seed's first step has no fix");
    assert_eq!(report["estimator"], "fused");
    assert!(steps.iter().all(|s| s["estimator"] == "fused"), "every step the fused estimator's");
    // The recording replays to the same estimates and plans: the replay, too, takes the estimator from
    // a step with a fix (from step 0's "snapshot" it replayed 3 of 16 estimates alike).
    let replay = common::json_of(&["replay", recording.to_str().unwrap(), "--json"]);
    assert_eq!(replay["estimator"], "fused", "{replay}");
    assert_eq!(replay["estimates_equal"], replay["estimates_compared"], "{replay}");
    assert_eq!(replay["estimates_compared"], STEPS + 1, "{replay}");
    assert_eq!(replay["plans_equal"], replay["plans_compared"], "{replay}");
    // The recording names no estimator for step 0 (no posterior yet), the fused one from the first fix.
    let recorded = record::recording::read_recording(&recording).unwrap();
    let estimators: Vec<(u64, &Value)> = recorded
        .messages
        .iter()
        .filter(|m| m.topic == "/estimate")
        .map(|m| (m.json["step"].as_u64().unwrap(), &m.json["estimator"]))
        .collect();
    assert!(estimators.iter().any(|(k, e)| *k == 0 && e.is_null()), "{estimators:?}");
    assert!(estimators.iter().all(|(_, e)| e.is_null() || *e == "fused"), "{estimators:?}");
    let _ = std::fs::remove_dir_all(&kept);
    let last = steps.last().unwrap();
    let truth = [fe["truth"][0].as_f64().unwrap(), fe["truth"][1].as_f64().unwrap()];
    let e = (last["estimate"][0].as_f64().unwrap() - truth[0]).hypot(last["estimate"][1].as_f64().unwrap() - truth[1]);
    assert!(e < 1655.58, "final error {e} m");
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
    let (status, stdout, stderr) = launch.finish();
    assert_eq!(status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("the front end left the measurement topic"), "{stderr}");
    assert!(stderr.contains("the monitor process stopped unexpectedly (exit code 3)"), "{stderr}");
    // The steps recorded are printed as the run's record, with why it failed in the monitor's words.
    let run: serde_json::Value = serde_json::from_str(&stdout).expect("the record on stdout");
    assert_eq!(run["steps"].as_array().map(Vec::len), Some(7), "steps 0..=6 in the record");
    let failed = run["failed"].as_str().expect("\"failed\"");
    assert!(failed.contains("(exit code 3): the front end left the measurement topic"), "{failed}");
    // Ended after the monitor's grace, not at the test's bound.
    assert!(left.elapsed() < common::FINISH_TIMEOUT / 4, "took {:?}", left.elapsed());
    let events = common::read_events(&log);
    let steps = events.iter().filter(|e| e["event"] == "step").count();
    assert_eq!(steps, 7, "steps 0..=6 recorded");
    assert_eq!(events.iter().filter(|e| e["event"] == "front_end_left").count(), 1);
    assert_nothing_left(&d);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A front end that skips a step (its measurement lost on its way) gets no command for the next one: the
/// monitor says, within seconds, which step the run waits for and why, and when the front end gives up
/// and leaves, the launch ends naming that step.
#[test]
fn a_skipped_step_is_named_while_the_run_waits_for_it() {
    let _scenario = common::scenario(module_path!());
    let d = domain("ext", "skip");
    let dir = scratch("ext-skip");
    let launch = Launch::start(&d, &dir, &["--source", "external", "--steps", &STEPS.to_string()]);
    let out = front_end(&d, &STEPS.to_string(), &["--skip", "3", "--timeout-s", "3", "--linger-s", "0"])
        .expect("run the front end");
    let front_end_err = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(1), "{front_end_err}");
    assert!(front_end_err.contains("no command for step 4"), "{front_end_err}");
    let log = launch.log.clone();
    let (status, _stdout, stderr) = launch.finish();
    assert_eq!(status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("step 4's measurement is in but step 3's has not come"), "{stderr}");
    assert!(stderr.contains("with step 3 of 0..=12 not recorded"), "{stderr}");
    let events = common::read_events(&log);
    let gaps: Vec<_> = events.iter().filter(|e| e["event"] == "measurement_gap").collect();
    assert_eq!(gaps.len(), 1, "said once: {gaps:?}");
    assert_eq!((gaps[0]["missing"].as_u64(), gaps[0]["later"].as_u64()), (Some(3), Some(4)));
    assert_eq!(events.iter().filter(|e| e["event"] == "step").count(), 3, "steps 0..=2 recorded");
    assert_nothing_left(&d);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A front end flying another formation than the launch's scenario (4 UAVs against 3): the planner rejects
/// its first estimate naming both counts (before: "positions: expected 3 values, got 4", as if the planner
/// had erred), counts it, and ends the run at once (exit code 3, not restarted) — it used to stall until
/// the front end gave up, then exit 1 with no JSON. The launch prints the record it has.
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
    let started = std::time::Instant::now();
    let fe = spawn_front_end(&d, "6", &["--scenario", world.to_str().unwrap(), "--timeout-s", "3", "--linger-s", "0"]);
    let (status, stdout, stderr) = launch.finish();
    // At once, not when the front end gives up waiting for a command (it used to).
    assert!(started.elapsed() < std::time::Duration::from_secs(3), "took {:?}: {stderr}", started.elapsed());
    let out = fe.wait_with_output().expect("the front end");
    assert!(!out.status.success(), "the front end got a command for another formation");
    assert_eq!(status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("rejected the estimate of step 0: 4 UAVs, this run's scenario has 3"), "{stderr}");
    assert!(stderr.contains("the run cannot go on"), "{stderr}");
    assert!(!stderr.contains("expected 3 values") && !stderr.contains("restarting"), "{stderr}");
    let record: Value = serde_json::from_str(&stdout).unwrap_or_else(|e| panic!("the record ({e}): {stdout}"));
    assert!(record["steps"].is_array(), "{record}");
    assert_nothing_left(&d);
    std::fs::remove_dir_all(&dir).ok();
}

/// Starts `examples/python/frontend.py` in the background (stdout piped: its JSON summary).
fn spawn_front_end(domain: &str, steps: &str, extra: &[&str]) -> std::process::Child {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/python/frontend.py");
    Command::new(python())
        .arg(script)
        .args(["--domain", domain, "--steps", steps])
        .args(extra)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("start the front end")
}

/// The rejections of `reason` the monitor logged (one line per refused publisher for a second source).
fn logged_rejections(events: &[Value], reason: &str) -> usize {
    events.iter().filter(|e| e["event"] == "rejected" && e["reason"] == reason).count()
}

/// Two front ends on one domain: A (emitter at 25 000, 15 000) runs; B (emitter at 20 000, 24 000) joins
/// once A's step 2 is recorded. One measurement source per run: B's measurements are refused
/// (`second_source`, logged once, counted each) while A is there, and the run is A's alone — its estimate
/// is A's emitter, every recorded measurement A's. (It used to be mixed: A's measurements, B's emitter.)
#[test]
fn a_second_front_end_is_refused_and_the_run_stays_the_first_ones() {
    let _scenario = common::scenario(module_path!());
    let d = domain("ext", "two");
    let dir = scratch("ext-two");
    let steps = STEPS.to_string();
    let mut launch = Launch::start(&d, &dir, &["--source", "external", "--steps", &steps]);
    let a = spawn_front_end(&d, &steps, &["--step-delay-s", "0.1", "--timeout-s", "60"]);
    launch.wait_for_step(2, common::FINISH_TIMEOUT / 4);
    let b = front_end(&d, &steps, &["--emitter", "20000,24000", "--seed", "8", "--timeout-s", "2", "--linger-s", "0"])
        .expect("run the second front end");
    // B never gets a command for its steps: the run's commands answer A's (B's step 0 was long answered).
    assert!(!b.status.success(), "the second front end was answered");
    let a = a.wait_with_output().expect("the first front end");
    assert!(a.status.success(), "the first front end failed: {}", String::from_utf8_lossy(&a.stderr));
    let fe: Value = serde_json::from_slice(&a.stdout).expect("the first front end's summary");
    let log = launch.log.clone();
    let report = launch.finish_json();
    let events = common::read_events(&log);
    // Logged once per receiver (the monitor's log holds its own); counted for each message.
    assert_eq!(logged_rejections(&events, "second_source"), 1, "{}", report["rejected_by"]);
    assert!(report["rejected_by"]["estimator"].as_u64().unwrap() >= 1, "{}", report["rejected_by"]);
    assert_eq!(logged_rejections(&events, "stale"), 0);
    let steps = report["steps"].as_array().unwrap();
    assert_eq!(steps.len() as u64, STEPS + 1);
    let last = &steps[STEPS as usize];
    assert_eq!(last["uavs"], fe["uavs"], "the record's geometry is A's");
    let (x, y) = (last["estimate"][0].as_f64().unwrap(), last["estimate"][1].as_f64().unwrap());
    let a_err = (x - 25000.0).hypot(y - 15000.0);
    assert!(a_err < 1655.58, "the final estimate ({x}, {y}) is not A's emitter ({a_err} m off)");
    assert_nothing_left(&d);
    let _ = std::fs::remove_dir_all(&dir);
}

/// One valid measurement numbered `u64::MAX` from another client (here: a second front end that publishes
/// one step and leaves) used to make every later measurement of the real front end stale — the run
/// stalled. The sequence numbers are a stream per source, and the other client is refused as a second
/// source: nothing stale, every step recorded.
#[test]
fn a_foreign_measurement_numbered_u64_max_cannot_stall_the_run() {
    let _scenario = common::scenario(module_path!());
    let d = domain("ext", "max");
    let dir = scratch("ext-max");
    let steps = STEPS.to_string();
    let mut launch = Launch::start(&d, &dir, &["--source", "external", "--steps", &steps]);
    let a = spawn_front_end(&d, &steps, &["--step-delay-s", "0.1", "--timeout-s", "20"]);
    launch.wait_for_step(2, common::FINISH_TIMEOUT / 4);
    let max = u64::MAX.to_string();
    // It stays a second after publishing: a sample no subscriber has read yet goes with its publisher, and
    // both receivers must have seen it (leaving at once, it was sometimes gone before the monitor read it).
    let b = front_end(&d, "0", &["--seq-start", &max, "--linger-s", "1"]).expect("run the intruder");
    assert!(b.status.success(), "{}", String::from_utf8_lossy(&b.stderr));
    let a = a.wait_with_output().expect("the front end");
    assert!(a.status.success(), "the front end stalled: {}", String::from_utf8_lossy(&a.stderr));
    let log = launch.log.clone();
    let report = launch.finish_json();
    let events = common::read_events(&log);
    assert_eq!(logged_rejections(&events, "stale"), 0);
    assert_eq!(logged_rejections(&events, "second_source"), 1);
    assert_eq!(report["rejected_by"]["estimator"], 1, "{}", report["rejected_by"]);
    assert_eq!(report["steps"].as_array().unwrap().len() as u64, STEPS + 1);
    assert_nothing_left(&d);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A front end that publishes step 5 twice with different data: the second copy is refused
/// (`conflict`) by the estimator and the monitor alike, so what is recorded is what was estimated —
/// `uavloc replay` of the recording reproduces every estimate. (The estimator used to continue from the
/// second copy while the monitor recorded the first: 6 of 21 estimates reproduced.)
#[test]
fn a_different_copy_of_a_step_is_refused_and_the_recording_replays_every_estimate() {
    let _scenario = common::scenario(module_path!());
    let d = domain("ext", "twice");
    let dir = scratch("ext-twice");
    let steps = STEPS.to_string();
    let mcap = dir.join("run.mcap");
    let launch =
        Launch::start(&d, &dir, &["--source", "external", "--steps", &steps, "--record", mcap.to_str().unwrap()]);
    let out = front_end(&d, &steps, &["--remeasure", "5"]).expect("run the front end");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let log = launch.log.clone();
    let report = launch.finish_json();
    assert_eq!(report["rejected_by"]["estimator"], 1, "{}", report["rejected_by"]);
    assert_eq!(report["rejected_by"]["monitor"], 1, "{}", report["rejected_by"]);
    assert_eq!(logged_rejections(&common::read_events(&log), "conflict"), 1);
    let replay = common::json_of(&["--json", "replay", mcap.to_str().unwrap()]);
    assert_eq!(replay["estimates_equal"], STEPS + 1, "{replay}");
    assert_nothing_left(&d);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The estimates of a run, bit for bit (as JSON text).
fn estimates(report: &Value) -> Vec<String> {
    report["steps"].as_array().unwrap().iter().map(|s| format!("{} {}", s["estimate"], s["estimate_cov"])).collect()
}

/// SIGKILL of the estimator or the planner with an external front end, a step in flight: the process is
/// stopped (SIGSTOP) until the step's measurement (estimator) or estimate (planner) is in its buffer, then
/// killed — that message is lost with it, and the front end measures each step once. It used to hang:
/// the restarted process waited for ever for a replay nobody served. The monitor, which recorded the
/// step's measurement, now gives it again: the run completes, equal estimate for estimate to one that
/// was not interrupted.
#[test]
fn a_process_killed_with_a_step_in_flight_is_recovered_with_an_external_front_end() {
    let _scenario = common::scenario(module_path!());
    let (reference, _) = run(&domain("ext", "ref"), "ext-ref", &[]);
    for (role, lost) in [("estimator", "measurement"), ("planner", "estimate")] {
        let d = domain("ext", &format!("flight-{role}"));
        let dir = scratch(&format!("ext-flight-{role}"));
        let steps = STEPS.to_string();
        let mut launch = Launch::start(&d, &dir, &["--source", "external", "--steps", &steps]);
        let fe = spawn_front_end(&d, &steps, &["--step-delay-s", "0.2", "--timeout-s", "30"]);
        launch.wait_for_step(3, common::FINISH_TIMEOUT / 4);
        let pid = common::pid_of(&d, role).expect("the role's process");
        common::kill(pid, libc::SIGSTOP);
        // The monitor logs each message it takes: once it has the lost kind of a step not recorded yet,
        // the stopped process has it in its buffer too.
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(20);
        loop {
            let events = launch.events();
            let recorded = events.iter().filter(|e| e["event"] == "step").filter_map(|e| e["step"].as_u64()).max();
            if events.iter().any(|e| e["event"] == "message" && e["kind"] == lost && e["step"].as_u64() > recorded) {
                break;
            }
            assert!(std::time::Instant::now() < deadline, "{role}: no {lost} in flight");
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        common::kill(pid, libc::SIGKILL);
        let fe = fe.wait_with_output().expect("the front end");
        assert!(fe.status.success(), "{role}: {}", String::from_utf8_lossy(&fe.stderr));
        let log = launch.log.clone();
        let report = launch.finish_json();
        assert_eq!(report["restarts"], 1, "{role}");
        assert_eq!(estimates(&report), estimates(&reference), "{role}: the run differs from the uninterrupted one");
        let events = common::read_events(&log);
        assert!(events.iter().any(|e| e["event"] == "replay_request" && e["measurement"] == "given again"), "{role}");
        assert_nothing_left(&d);
        let _ = std::fs::remove_dir_all(&dir);
    }
}

/// SIGKILL of the monitor with an external front end: the steps the front end publishes while it is down
/// cannot be replayed to a restarted monitor (it used to end with "step 11 never recorded" after the
/// front end had flown every command). The launch fails at once, saying that a crashed monitor is not
/// restarted with an external source, and leaves nothing behind.
#[test]
fn a_monitor_crash_with_an_external_front_end_fails_the_launch_at_once_saying_why() {
    let _scenario = common::scenario(module_path!());
    let d = domain("ext", "kill-monitor");
    let dir = scratch("ext-kill-monitor");
    let steps = STEPS.to_string();
    let mut launch = Launch::start(&d, &dir, &["--source", "external", "--steps", &steps]);
    let fe = spawn_front_end(&d, &steps, &["--step-delay-s", "0.1", "--timeout-s", "3", "--linger-s", "0"]);
    launch.wait_for_step(2, common::FINISH_TIMEOUT / 4);
    common::kill(common::pid_of(&d, "monitor").expect("the monitor"), libc::SIGKILL);
    let killed = std::time::Instant::now();
    let (status, _stdout, stderr) = launch.finish();
    assert_eq!(status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("the monitor process stopped unexpectedly (signal 9)"), "{stderr}");
    assert!(stderr.contains("not restarted"), "{stderr}");
    assert!(killed.elapsed() < std::time::Duration::from_secs(15), "took {:?}", killed.elapsed());
    // The front end gets no more commands and gives up after its own timeout.
    let _ = fe.wait_with_output().expect("the front end");
    assert_nothing_left(&d);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A front end whose range noise is not the launch scenario's (σ 20/35/50 m against 28.77 m): the noise
/// it states in its measurements is the noise every stage uses — the estimator's estimate carries it
/// (the Estimate carries it), the planner plans with it, the monitor's bounds use it. The run equals one whose
/// `--scenario` states the same σ, plan for plan; the record says which σ each step had. (The planner and
/// the monitor used to take the scenario's σ: the plans silently changed from step 2.)
#[test]
fn the_noise_a_front_end_states_is_the_noise_the_run_plans_for() {
    let _scenario = common::scenario(module_path!());
    let dir = scratch("ext-sigma");
    let nominal =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/nominal.toml")).unwrap();
    let noisy: String = nominal
        .lines()
        .map(|l| if l.starts_with("sigma =") { "sigma = [20.0, 35.0, 50.0]" } else { l })
        .collect::<Vec<_>>()
        .join("\n");
    assert_ne!(noisy, nominal);
    let world = dir.join("noisy.toml");
    std::fs::write(&world, noisy).unwrap();
    let world = world.to_str().unwrap();
    let steps = STEPS.to_string();
    let run_with = |tag: &str, launch_scenario: &[&str]| -> Value {
        let d = domain("ext", tag);
        let mut args = vec!["--source", "external", "--steps", &steps];
        args.extend_from_slice(launch_scenario);
        let launch = Launch::start(&d, &dir.join(tag), &args);
        let out = front_end(&d, &steps, &["--scenario", world]).expect("run the front end");
        assert!(out.status.success(), "{tag}: {}", String::from_utf8_lossy(&out.stderr));
        let report = launch.finish_json();
        assert_nothing_left(&d);
        report
    };
    std::fs::create_dir_all(dir.join("default")).unwrap();
    std::fs::create_dir_all(dir.join("stated")).unwrap();
    let default = run_with("default", &[]);
    let stated = run_with("stated", &["--scenario", world]);
    let (a, b) = (default["steps"].as_array().unwrap(), stated["steps"].as_array().unwrap());
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(b) {
        let k = &x["step"];
        for key in ["headings_rad", "estimate", "objective_value", "pcrlb_at_estimate_m"] {
            assert_eq!(x[key], y[key], "step {k}: {key}");
        }
        assert_eq!(x["range_sigmas_m"], serde_json::json!([20.0, 35.0, 50.0]), "step {k}");
        assert!(y.get("range_sigmas_m").is_none(), "the scenario's own σ is not repeated: {y}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
