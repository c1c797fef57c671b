//! Runs recorded as MCAP (`uavloc launch --record FILE.mcap`) and replayed (`uavloc replay FILE`): the file
//! is read back by the Python `mcap` package alone (channels, counts, values against the run's JSON), the
//! replay with the recorded settings reproduces every recorded estimate bit for bit, another estimator
//! gives other estimates, a monitor killed mid-run still leaves a whole recording, and a cut or corrupt
//! file is refused naming the byte offset (exit 2).

use crate::common;

use std::path::Path;
use std::process::Command;
use std::time::Duration;

use common::{Launch, domain, json_of, kill, pid_of, python, scratch, uavloc};
use serde_json::Value;

const STEPS: u64 = 8;

fn replay(file: &Path, extra: &[&str]) -> Value {
    json_of(&[&["--json", "replay", file.to_str().unwrap()][..], extra].concat())
}

#[test]
fn a_recorded_run_reads_back_in_python_and_replays_to_the_same_estimates() {
    let _scenario = common::scenario(module_path!());
    let dir = scratch("record");
    let file = dir.join("run.mcap");
    let d = domain("rec", "py");
    let steps = STEPS.to_string();
    let run = Launch::start(&d, &dir, &["--steps", &steps, "--record", file.to_str().unwrap()]).finish_json();

    // The Python `mcap` package reads it without uavloc.
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/python/read_recording.py");
    let out = Command::new(python()).arg(script).arg(&file).output().expect("run the Python reader");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let read: Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let channels = &read["channels"];
    for (topic, count) in
        [("/measurement", STEPS + 1), ("/estimate", STEPS + 1), ("/truth", STEPS + 1), ("/command", STEPS)]
    {
        // A step published again (emitter-sim's retry when a loaded machine is slow to answer) is recorded
        // again: each step once at least.
        assert_eq!(channels[topic]["steps"], count, "{topic}: {channels}");
        assert!(channels[topic]["count"].as_u64().unwrap() >= count, "{topic}: {channels}");
        assert_eq!(channels[topic]["message_encoding"], "json");
        assert_eq!(channels[topic]["schema_encoding"], "jsonschema");
    }
    assert_eq!(channels["/estimate"]["schema"], "uavloc::Estimate/v10");
    assert!(channels["/control"]["count"].as_u64().unwrap() >= 4, "every process said hello: {channels}");
    assert_eq!(read["metadata"]["uavloc"]["steps"], steps);
    for (k, s) in run["steps"].as_array().unwrap().iter().enumerate() {
        let recorded = &read["estimates"][k.to_string()];
        assert_eq!(recorded["position"], s["estimate"], "step {k}: the recorded estimate is the run's");
        assert_eq!(recorded["status"], s["estimate_status"]);
    }

    // Replayed with the recorded settings: every estimate and every plan as recorded.
    let same = replay(&file, &[]);
    assert_eq!(same["steps"], STEPS + 1);
    assert_eq!(same["estimates_compared"], STEPS + 1);
    assert_eq!(same["estimates_equal"], STEPS + 1, "{same}");
    assert_eq!(same["max_estimate_delta_m"], 0.0);
    assert_eq!((same["plans_compared"].clone(), same["plans_equal"].clone()), (STEPS.into(), STEPS.into()));
    // Another estimator on the same flight: other estimates (the first snapshot is Chan's in both).
    let other = replay(&file, &["--estimator", "snapshot"]);
    assert_eq!(other["estimator"], "snapshot");
    assert!(other["estimates_equal"].as_u64().unwrap() < STEPS + 1, "{other}");
    assert!(other["max_estimate_delta_m"].as_f64().unwrap() > 1.0, "{other}");

    // `simulate --record` writes the messages the pipeline carried: the same measurements and estimates.
    let sim_file = dir.join("sim.mcap");
    let out = uavloc(&["simulate", "--steps", &steps, "--record", sim_file.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let fields = |file: &Path, topic: &str, keys: &[&str]| -> Vec<Value> {
        let r = record::recording::read_recording(file).unwrap();
        let mut seen = std::collections::BTreeMap::new();
        for m in r.messages.iter().filter(|m| m.topic == topic) {
            let picked: Vec<Value> = keys.iter().map(|k| m.json[*k].clone()).collect();
            seen.entry(m.json["step"].as_u64().unwrap()).or_insert(Value::Array(picked));
        }
        seen.into_values().collect()
    };
    let m_keys = ["uavs", "heard", "arrivals", "sigmas", "headings"];
    assert_eq!(fields(&sim_file, "/measurement", &m_keys), fields(&file, "/measurement", &m_keys));
    let e_keys = ["status", "position", "covariance", "velocity"];
    assert_eq!(fields(&sim_file, "/estimate", &e_keys), fields(&file, "/estimate", &e_keys));
    let c_keys = ["headings", "waypoints", "active_constraints"];
    assert_eq!(fields(&sim_file, "/command", &c_keys), fields(&file, "/command", &c_keys));
    assert_eq!(replay(&sim_file, &[])["estimates_equal"], STEPS + 1);

    // Cut short, or not MCAP at all: exit 2, naming the offset.
    let bytes = std::fs::read(&file).unwrap();
    let cut = dir.join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).unwrap();
    let out = uavloc(&["replay", cut.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("cut short") && err.contains("at byte offset"), "{err}");
    let junk = dir.join("junk.mcap");
    std::fs::write(&junk, b"{\"not\": \"mcap\"}").unwrap();
    let out = uavloc(&["replay", junk.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("not an MCAP file"), "{out:?}");
    // One digit of a recorded arrival changed: still valid JSON, a different report — refused by the data
    // section's CRC (it used to be replayed, exit 0).
    let at = bytes.windows(12).position(|w| w == b"\"arrivals\":[").expect("a recorded measurement") + 13;
    let digit = at + bytes[at..].iter().position(u8::is_ascii_digit).unwrap();
    let mut changed = bytes.clone();
    changed[digit] = if changed[digit] == b'7' { b'8' } else { b'7' };
    let fuzzed = dir.join("fuzzed.mcap");
    std::fs::write(&fuzzed, &changed).unwrap();
    let out = uavloc(&["replay", fuzzed.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("CRC does not match") && err.contains("at byte offset"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_monitor_killed_mid_run_still_leaves_a_whole_recording() {
    let _scenario = common::scenario(module_path!());
    let dir = scratch("record-kill");
    let file = dir.join("run.mcap");
    let d = domain("rec", "kill");
    let steps = 30u64;
    let mut launch =
        Launch::start(&d, &dir, &["--steps", "30", "--step-delay-ms", "20", "--record", file.to_str().unwrap()]);
    launch.wait_for_step(8, Duration::from_secs(30));
    kill(pid_of(&d, "monitor").expect("the monitor"), libc::SIGKILL);
    let run = launch.finish_json();
    assert_eq!(run["restarts"], 1);
    let recording = record::recording::read_recording(&file).expect("a whole recording");
    for topic in ["/measurement", "/estimate", "/truth"] {
        let mut seen: Vec<u64> =
            recording.messages.iter().filter(|m| m.topic == topic).map(|m| m.json["step"].as_u64().unwrap()).collect();
        seen.sort_unstable();
        seen.dedup();
        assert_eq!(seen, (0..=steps).collect::<Vec<_>>(), "{topic}");
    }
    let same = replay(&file, &[]);
    assert_eq!(same["estimates_equal"], steps + 1, "{same}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A run whose planner was swapped (pso, then ga) replays, without flags, with each planner on its own
/// steps: every plan as recorded. Before, the first recorded planner replayed every step, and the steps of
/// the second read as different plans (24 of 40 equal in the probe).
#[test]
fn a_recording_of_a_swapped_planner_replays_each_step_with_its_own_planner() {
    let _scenario = common::scenario(module_path!());
    let dir = scratch("record-swap");
    let file = dir.join("run.mcap");
    let d = domain("rec", "swap");
    let mut launch = Launch::start(
        &d,
        &dir,
        &["--steps", "24", "--step-delay-ms", "80", "--solver", "pso", "--record", file.to_str().unwrap()],
    );
    launch.wait_for_step(3, Duration::from_secs(30));
    // stderr to a file: the detached new planner keeps writing there until the launch ends.
    let swapped = Command::new(common::UAVLOC)
        .args(["swap", "planner", "--domain", &d, "--solver", "ga", "--json"])
        .stderr(std::fs::File::create(dir.join("swap.stderr")).unwrap())
        .output()
        .unwrap();
    assert!(swapped.status.success(), "{}", std::fs::read_to_string(dir.join("swap.stderr")).unwrap_or_default());
    let from = serde_json::from_slice::<Value>(&swapped.stdout).unwrap()["from_step"].as_u64().unwrap();
    launch.finish_json();
    let r = replay(&file, &[]);
    assert_eq!((r["solver"].as_str(), r["objective"].as_str()), (Some("pso → ga"), Some("analytical")), "{r}");
    assert_eq!(r["plans_compared"], 24, "{r}");
    assert_eq!(r["plans_equal"], 24, "{r}");
    for s in r["per_step"].as_array().unwrap().iter().take(24) {
        let k = s["step"].as_u64().unwrap();
        assert_eq!(s["planner"], if k < from { "pso/analytical" } else { "ga/analytical" }, "step {k}");
    }
    // A flag still replays every step with one planner.
    let one = replay(&file, &["--solver", "gradient"]);
    assert_eq!(one["solver"], "gradient", "{one}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `uavloc swap estimator --estimator snapshot` mid-run: each step of the record says which estimator
/// made its estimate, and `uavloc replay` replays each step with it, the snapshot estimator resumed from
/// the fused one's last estimate — every estimate reproduced. (The record said `fused` throughout, and
/// the replay redid every step as fused: 36 of 101 equal.)
#[test]
fn a_recording_of_a_swapped_estimator_replays_each_step_with_its_own_estimator() {
    let _scenario = common::scenario(module_path!());
    let dir = scratch("record-swap-est");
    let file = dir.join("run.mcap");
    let d = domain("rec", "swap-est");
    let mut launch =
        Launch::start(&d, &dir, &["--steps", "24", "--step-delay-ms", "80", "--record", file.to_str().unwrap()]);
    launch.wait_for_step(3, Duration::from_secs(30));
    let swapped = Command::new(common::UAVLOC)
        .args(["swap", "estimator", "--domain", &d, "--estimator", "snapshot", "--json"])
        .stderr(std::fs::File::create(dir.join("swap.stderr")).unwrap())
        .output()
        .unwrap();
    assert!(swapped.status.success(), "{}", std::fs::read_to_string(dir.join("swap.stderr")).unwrap_or_default());
    let from = serde_json::from_slice::<Value>(&swapped.stdout).unwrap()["from_step"].as_u64().unwrap();
    let run = launch.finish_json();
    for s in run["steps"].as_array().unwrap() {
        let k = s["step"].as_u64().unwrap();
        assert_eq!(s["estimator"], if k < from { "fused" } else { "snapshot" }, "step {k}");
    }
    let r = replay(&file, &[]);
    assert_eq!(r["estimator"], "fused → snapshot", "{r}");
    assert_eq!(r["estimates_equal"], 25, "{r}");
    // A flag still replays every step with one estimator.
    assert_eq!(replay(&file, &["--estimator", "fused"])["estimator"], "fused");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_recording_with_a_step_missing_or_without_its_scenario_is_refused() {
    let _scenario = common::scenario(module_path!());
    use record::recording::{Recorder, run_metadata};
    let dir = scratch("record-gaps");
    let uavs = [[1500.0, 500.0], [10000.0, 1500.0], [5000.0, 8500.0]];
    let m =
        |k: u64| protocol::Measurement::new(k, k + 1, &uavs, &[-2012.3, -4010.9], &[28.7712; 3], &[0.1; 3]).unwrap();
    let write = |name: &str, metadata, steps: &[u64]| {
        let path = dir.join(name);
        let mut r = Recorder::create(&path, metadata, false).unwrap();
        for &k in steps {
            r.record(&m(k), k);
        }
        r.finish().unwrap();
        path
    };
    let gap = write("gap.mcap", run_metadata(&model::Scenario::default(), "d", "simulator"), &[0, 1, 2, 4]);
    let out = uavloc(&["replay", gap.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("step 3 is missing"), "{out:?}");
    let bare = write("bare.mcap", Default::default(), &[0, 1]);
    let out = uavloc(&["replay", bare.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("not a uavloc recording"), "{out:?}");
    // Whole and with its scenario: replayed (no estimate was recorded, so none is compared).
    let whole = write("whole.mcap", run_metadata(&model::Scenario::default(), "d", "simulator"), &[0, 1, 2]);
    let r = replay(&whole, &[]);
    assert_eq!((r["steps"].clone(), r["estimates_compared"].clone()), (3.into(), 0.into()));
    let _ = std::fs::remove_dir_all(&dir);
}
