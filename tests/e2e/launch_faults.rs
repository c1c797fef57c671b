//! The faults an adversarial user found in `uavloc launch`, each reproduced here first: two
//! launches into one domain at the same instant; state directories left by a SIGKILLed launcher.

use crate::common;

use std::process::{Command, Stdio};

use common::{UAVLOC, assert_nothing_left, assert_same_run, domain, json_of};
use serde_json::Value;

/// Two launches into one domain started at the same instant: exactly one is refused (exit 2, one line
/// naming the domain), the other completes with exactly its own seed's result (before, in 4 of 5 tries
/// one launch exited 0 with a trajectory that was neither seed's).
#[test]
fn two_launches_into_one_domain_at_once_refuse_one_and_keep_the_other_exact() {
    let _scenario = common::scenario(module_path!());
    for attempt in 0..3 {
        let d = domain("race", &attempt.to_string());
        let start = |seed: &str| {
            Command::new(UAVLOC)
                .args(["launch", "--headless", "--json", "--steps", "20", "--seed", seed, "--domain", &d])
                .stdout(Stdio::piped())
                .stderr(Stdio::piped())
                .spawn()
                .expect("start uavloc launch")
        };
        let (a, b) = (start("7"), start("8"));
        let (a, b) = (a.wait_with_output().unwrap(), b.wait_with_output().unwrap());
        let codes = (a.status.code(), b.status.code());
        assert!(
            codes == (Some(0), Some(2)) || codes == (Some(2), Some(0)),
            "attempt {attempt}: exit codes {codes:?}\nA: {}\nB: {}",
            String::from_utf8_lossy(&a.stderr),
            String::from_utf8_lossy(&b.stderr)
        );
        let (won, lost, seed) = if codes.0 == Some(0) { (&a, &b, "7") } else { (&b, &a, "8") };
        let err = String::from_utf8_lossy(&lost.stderr);
        assert!(err.contains("in use") && err.contains(&d) && err.lines().count() == 1, "{err}");
        assert!(lost.stdout.is_empty());
        let run: Value = serde_json::from_slice(&won.stdout).expect("the winner's JSON");
        let sim = json_of(&["simulate", "--json", "--steps", "20", "--seed", seed]);
        assert_same_run(&sim, &run, &format!("attempt {attempt}, seed {seed}"));
        assert_eq!(run["rejected"].as_u64(), Some(0), "no foreign message was seen");
        assert_nothing_left(&d);
    }
}

/// A state directory whose launcher died (SIGKILL) is removed by the next launch (before, it stayed
/// forever, with the monitor's log in it).
#[test]
fn a_dead_launchers_state_directory_is_removed_by_the_next_launch() {
    let _scenario = common::scenario(module_path!());
    // SAFETY: getuid has no preconditions.
    let uid = unsafe { libc::getuid() };
    let root = std::env::temp_dir().join(format!("uavloc-{uid}"));
    std::fs::create_dir_all(&root).unwrap();
    // A pid that no longer exists: a child that has exited and been reaped.
    let mut gone = Command::new("true").spawn().unwrap();
    let dead_pid = gone.id();
    gone.wait().unwrap();
    let stale = root.join(format!("launch-{dead_pid}-stale-{}", std::process::id()));
    std::fs::create_dir_all(&stale).unwrap();
    std::fs::write(stale.join("monitor.jsonl"), "{}\n").unwrap();
    // A directory of a live process stays.
    let live = root.join(format!("launch-{}-live", std::process::id()));
    std::fs::create_dir_all(&live).unwrap();
    let d = domain("stale", "dirs");
    let out =
        Command::new(UAVLOC).args(["launch", "--headless", "--json", "--steps", "2", "--domain", &d]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(!stale.exists(), "the dead launcher's directory is still there");
    assert!(live.exists(), "a live process's directory was removed");
    std::fs::remove_dir_all(&live).unwrap();
}

/// A scenario whose start cannot be localised (three collinear UAVs; a σ so large no fix means anything)
/// is refused up front by `simulate` and `launch`: exit 2, one line naming the key (before, `launch`
/// ground for a minute through five emitter-sim restarts and ended with a misleading "no command").
#[test]
fn a_start_that_cannot_be_localised_is_refused_up_front() {
    let _scenario = common::scenario(module_path!());
    let dir = common::scratch("unlocalisable");
    for (name, text, key) in [
        ("collinear", "uavs = [[0.0, 0.0], [5000.0, 0.0], [10000.0, 0.0]]\n", "uavs"),
        ("noisy", "sigma = 1e6\n", "sigma"),
    ] {
        let path = dir.join(format!("{name}.toml"));
        std::fs::write(&path, text).unwrap();
        let path = path.to_str().unwrap();
        let d = domain("unloc", name);
        for args in [
            vec!["simulate", "--scenario", path],
            vec!["launch", "--headless", "--json", "--steps", "50", "--scenario", path, "--domain", &d],
        ] {
            // A temporary directory of its own: a launch that got as far as its domain lock or its state
            // directory (before any child starts) leaves `uavloc-<uid>` there.
            let tmp = dir.join(format!("tmp-{name}-{}", args[0]));
            std::fs::create_dir_all(&tmp).unwrap();
            let out = Command::new(UAVLOC).args(&args).env("TMPDIR", &tmp).output().unwrap();
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
            assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
            assert!(err.contains(&format!("key `{key}`")) && err.contains("cannot be localised"), "{err}");
            assert!(out.stdout.is_empty());
            // Refused before anything starts: no lock taken, no state directory, no child.
            let left: Vec<_> = std::fs::read_dir(&tmp).unwrap().flatten().map(|e| e.file_name()).collect();
            assert!(left.is_empty(), "{args:?} got as far as {left:?}");
        }
        assert_nothing_left(&d);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A run whose first steps give no fix: the swarm holds (loiters) and tries the next burst. With
/// σ = 20 km (seed 10) every burst is heard by all three UAVs and none gives a physical solution, so at
/// step `planning::FIRST_FIX_STEPS − 1` `simulate` ends with the reason, and so does `launch` — the
/// planner says the run cannot go on (exit code 3, no restart), at the same step. An emitter silent at
/// 99.99 % of the steps never ends a run (silence is the receiver's, not the geometry's): both hold to
/// the end alike. With σ = 500 m step 0 has no fix but a later one has: both hold, then run alike.
#[test]
fn a_run_without_a_first_fix_holds_then_ends_launch_as_it_ends_simulate() {
    let _scenario = common::scenario(module_path!());
    let dir = common::scratch("no-fix");
    let nominal =
        std::fs::read_to_string(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/nominal.toml"))
            .unwrap();
    let with_sigma = |sigma: &str| -> String {
        nominal
            .lines()
            .map(|l| if l.starts_with("sigma =") { format!("sigma = {sigma}") } else { l.to_string() })
            .collect::<Vec<_>>()
            .join("\n")
    };
    let noisy = with_sigma("20000.0");
    let path = dir.join("noisy.toml");
    std::fs::write(&path, noisy).unwrap();
    let path = path.to_str().unwrap();
    let sim = Command::new(UAVLOC).args(["simulate", "--scenario", path, "--seed", "10"]).output().unwrap();
    assert_eq!(sim.status.code(), Some(1));
    let sim_err = String::from_utf8_lossy(&sim.stderr);
    assert!(sim_err.contains("step 19: estimate") && sim_err.contains("no physical solution"), "{sim_err}");
    let d = domain("nofix", "launch");
    let out = Command::new(UAVLOC)
        .args(["launch", "--headless", "--json", "--scenario", path, "--seed", "10", "--domain", &d])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("step 19: the estimator found no fix in the first 20 steps"), "{err}");
    assert!(err.contains("the run cannot go on"), "{err}");
    // Ended by the planner's verdict, not by a timeout after restarts.
    assert!(!err.contains("restarting") && !err.contains("no command within"), "{err}");
    assert_nothing_left(&d);
    // The same 6-step run of the scenario `text` by simulate and by launch (seed 10), nothing left after.
    let both = |name: &str, text: String| -> (Value, Value) {
        let path = dir.join(format!("{name}.toml"));
        std::fs::write(&path, text).unwrap();
        let path = path.to_str().unwrap();
        let common = ["--json", "--scenario", path, "--seed", "10", "--steps", "6"];
        let sim = json_of(&[&["simulate"][..], &common].concat());
        let d = domain("nofix", name);
        let run = json_of(&[&["launch", "--headless", "--domain", d.as_str()][..], &common].concat());
        assert_nothing_left(&d);
        (sim, run)
    };
    // Silent at 99.99 % of the steps: every step holds, none ends the run.
    let (sim, run) = both("silent", format!("{nominal}\n[receiver]\nsilence = 0.9999\n"));
    let steps = sim["steps"].as_array().unwrap();
    assert_eq!(steps.len(), 7, "every step of the silent run is there");
    for (k, s) in steps.iter().enumerate() {
        assert!(s["estimate"][0].is_null(), "a silent step gave an estimate: {s}");
        // The last step flies nothing more: only the steps before it plan.
        if k + 1 == steps.len() {
            continue;
        }
        assert_eq!(s["active_constraints"], serde_json::json!(["estimate_stale"]), "step {} held", s["step"]);
    }
    assert_same_run(&sim, &run, "a silent run");
    // Every hold of it was for want of a first fix, none for a late estimate (no deadline here).
    assert_eq!((run["stale_steps"].as_u64(), run["held_before_first_fix"].as_u64()), (Some(6), Some(6)), "{run}");
    // σ = 500 m: step 0 has no fix, a later step has; both hold until then and agree.
    let (sim, run) = both("hold", with_sigma("500.0"));
    assert_eq!(sim["steps"][0]["active_constraints"], serde_json::json!(["estimate_stale"]), "step 0 held");
    assert!(sim["steps"][0]["estimate"][0].is_null(), "no estimate at step 0");
    assert_same_run(&sim, &run, "a held step 0");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--out` is checked before the run (before, a 2 000-step launch was computed, then the monitor failed
/// on the path, was restarted five times and the run's JSON was lost), and a failure to write the files
/// at the end no longer loses the run: the JSON is printed, the exit code is 1, the error names the path.
#[test]
fn out_is_checked_before_the_run_and_a_late_failure_keeps_the_json() {
    let _scenario = common::scenario(module_path!());
    let dir = common::scratch("out-checks");
    let file = dir.join("f");
    std::fs::write(&file, "not a directory").unwrap();
    let f = file.to_str().unwrap();
    for args in [
        vec!["launch", "--headless", "--json", "--steps", "2000", "--out", f],
        vec!["simulate", "--json", "--steps", "2000", "--out", f],
    ] {
        let started = std::time::Instant::now();
        let out = Command::new(UAVLOC).args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("--out") && err.contains("not a directory") && err.lines().count() == 1, "{err}");
        assert!(started.elapsed() < std::time::Duration::from_secs(5), "{args:?}: the run was computed first");
    }
    // The directory is fine at the start and replaced by a file during the run.
    let late = dir.join("late");
    let d = domain("out", "late");
    let mut launch =
        common::Launch::start(&d, &dir, &["--steps", "40", "--step-delay-ms", "20", "--out", late.to_str().unwrap()]);
    launch.wait_for_step(3, std::time::Duration::from_secs(30));
    std::fs::remove_dir_all(&late).unwrap();
    std::fs::write(&late, "in the way").unwrap();
    let (status, stdout, stderr) = launch.finish();
    assert_eq!(status.code(), Some(1), "{stderr}");
    let run: Value = serde_json::from_str(&stdout).expect("the run's JSON is printed");
    assert_eq!(run["steps"].as_array().unwrap().len(), 41);
    assert_eq!(run["restarts"].as_u64(), Some(0), "the monitor is not restarted for it");
    assert!(stderr.contains("the run completed, but") && stderr.contains(late.to_str().unwrap()), "{stderr}");
    assert_nothing_left(&d);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A disk that fills under `--log` or `--stamps` (here `/dev/full`, whose writes fail with ENOSPC) ends
/// the run when it happens, naming the file, without restarting the monitor (before: silence, then a
/// misleading "the log has 10 of 201 steps" after five restarts; for the stamps, exit 0 with a short file).
#[test]
fn a_full_disk_under_the_log_or_the_stamps_is_reported_naming_the_file() {
    let _scenario = common::scenario(module_path!());
    for (flag, needle) in
        [("--log", "--log /dev/full"), ("--stamps", "--stamps /dev/full"), ("--record", "--mcap /dev/full")]
    {
        let d = domain("full", &flag[2..]);
        let out = Command::new(UAVLOC)
            .args(["launch", "--headless", "--json", "--steps", "200", "--domain", &d, flag, "/dev/full"])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{flag}: {err}");
        assert!(err.contains(needle) && err.contains("No space left on device"), "{flag}: {err}");
        assert!(!err.contains("restarting"), "{flag}: a full disk is not worth a restart: {err}");
        assert_nothing_left(&d);
    }
}

/// Stamps written before a monitor restart are kept (before, the restarted monitor truncated the file:
/// a SIGKILL at 0.6 s left steps 90–200 only, and the run exited 0): one row per step, in order.
#[test]
fn a_monitor_restart_keeps_the_stamps_written_before_it() {
    let _scenario = common::scenario(module_path!());
    let dir = common::scratch("stamps-restart");
    let d = domain("stamps", "restart");
    let stamps = dir.join("s.csv");
    let mut launch = common::Launch::start(
        &d,
        &dir,
        &["--steps", "120", "--step-delay-ms", "5", "--stamps", stamps.to_str().unwrap()],
    );
    launch.wait_for_step(40, std::time::Duration::from_secs(30));
    let monitor = common::pid_of(&d, "monitor").expect("a monitor");
    common::kill(monitor, libc::SIGKILL);
    let run = launch.finish_json();
    assert_eq!(run["restarts"].as_u64(), Some(1));
    let text = std::fs::read_to_string(&stamps).unwrap();
    let steps: Vec<u64> = text.lines().skip(1).map(|l| l.split(',').next().unwrap().parse().unwrap()).collect();
    assert_eq!(steps, (0..=120).collect::<Vec<u64>>(), "one row per step, in order");
    assert_nothing_left(&d);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The pipeline's record equals `simulate`'s, constraint labels included (before, in 36 of 200 steps of
/// seed 7 the launch labelled `approach(UAV i)` "violated" where `simulate` said "binding": the command's
/// mask had one violation flag per kind).
#[test]
fn constraint_labels_of_launch_and_simulate_agree() {
    let _scenario = common::scenario(module_path!());
    let d = domain("labels", "seed7");
    let run = json_of(&["launch", "--headless", "--json", "--steps", "200", "--seed", "7", "--domain", &d]);
    let sim = json_of(&["simulate", "--json", "--steps", "200", "--seed", "7"]);
    let violated = |v: &Value| {
        v["steps"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|s| s["active_constraints"].to_string().contains("violated"))
            .count()
    };
    assert!(violated(&sim) > 0, "the run reaches the L_min ring, where constraints are violated");
    for (s, l) in sim["steps"].as_array().unwrap().iter().zip(run["steps"].as_array().unwrap()) {
        assert_eq!(s["active_constraints"], l["active_constraints"], "step {}", s["step"]);
    }
    assert_same_run(&sim, &run, "seed 7, 200 steps");
    assert_nothing_left(&d);
}

/// `launch --json` stopped by SIGINT — or SIGHUP, the hang-up of the ssh session it was started from —
/// prints the partial record — the steps done, `"interrupted": true` — instead of nothing, and exits 1.
/// (Before, SIGHUP killed the launcher at once: exit 129, nothing on stdout.)
#[test]
fn an_interrupted_launch_prints_the_steps_done() {
    interrupted_by(libc::SIGINT, "SIGINT");
    interrupted_by(libc::SIGHUP, "SIGHUP");
}

fn interrupted_by(signal: i32, name: &str) {
    let _scenario = common::scenario(module_path!());
    let dir = common::scratch("sigint");
    let d = domain("sigint", name);
    let mut launch = common::Launch::start(&d, &dir, &["--steps", "400", "--step-delay-ms", "10"]);
    launch.wait_for_step(20, std::time::Duration::from_secs(30));
    common::kill(launch.child.id(), signal);
    let (status, stdout, stderr) = launch.finish();
    assert_eq!(status.code(), Some(1), "{stderr}");
    let run: Value = serde_json::from_str(&stdout).unwrap_or_else(|e| panic!("no JSON ({e}): {stdout:?}\n{stderr}"));
    assert_eq!(run["interrupted"], Value::Bool(true));
    let steps = run["steps"].as_array().unwrap();
    assert!(steps.len() >= 20 && steps.len() < 401, "{} steps", steps.len());
    // The steps done are the simulation's first steps, exactly.
    let sim = json_of(&["simulate", "--json", "--steps", "400"]);
    let first: Vec<Value> = sim["steps"].as_array().unwrap()[..steps.len()].to_vec();
    let partial = serde_json::json!({"steps": first});
    common::assert_same_steps(&partial, &serde_json::json!({"steps": steps}), "interrupted");
    assert!(stderr.contains(&format!("interrupted by {name}")), "{stderr}");
    assert_nothing_left(&d);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Kill -9 of a launch and its children can leave a service of the domain half-created: its
/// static config file exists but still has the permissions of a file being written (here: made as such
/// a kill leaves it, empty and owner-read-write). Before, every later launch in the domain failed within
/// ≈ 10 ms with `HangsInCreation`, and `process resources --remove-dead` could not remove it. Now the
/// next launch — holding the domain's lock, with no live node in the domain — removes it and runs.
#[test]
fn a_service_left_half_created_by_kill_9_is_removed_by_the_next_launch() {
    let _scenario = common::scenario(module_path!());
    use std::os::unix::fs::PermissionsExt;
    let d = domain("half", "created");
    let [pubsub, event] = protocol::resources::static_config_files(&format!("{d}/measurement")).unwrap();
    std::fs::create_dir_all(pubsub.parent().unwrap()).unwrap();
    for f in [&pubsub, &event] {
        std::fs::write(f, b"").unwrap();
        std::fs::set_permissions(f, std::fs::Permissions::from_mode(0o600)).unwrap();
    }
    // The next launch comes a moment later (a service younger than a second may still be in creation).
    std::thread::sleep(std::time::Duration::from_millis(1100));
    let out = Command::new(UAVLOC)
        .args(["launch", "--headless", "--json", "--steps", "4", "--domain", &d])
        .stdin(Stdio::null())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "the next launch failed: {stderr}");
    assert!(stderr.contains("half-created"), "the clean-up is reported: {stderr}");
    let run: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_same_run(&json_of(&["simulate", "--json", "--steps", "4"]), &run, "after the clean-up");
    assert_nothing_left(&d);
}

/// A monitor resumed (`--resume`) from the log of another run is refused before it starts (exit 2, naming
/// the log and what differs); before, it took the other run's steps as its first ones and recorded one
/// run made of two. The same run's log is taken.
#[test]
fn a_monitor_resumed_from_another_runs_log_is_refused() {
    let _scenario = common::scenario(module_path!());
    let dir = common::scratch("resume-other-log");
    let log = dir.join("run.jsonl");
    let log = log.to_str().unwrap();
    let out = Command::new(UAVLOC).args(["launch", "--headless", "--steps", "3", "--log", log]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let d = domain("resume", "other");
    let monitor = |extra: &[&str]| {
        let mut args = vec!["process", "monitor", "--domain", &d, "--quiet", "--resume", "--log", log];
        args.extend_from_slice(extra);
        Command::new(UAVLOC).args(&args).output().unwrap()
    };
    let scenario = dir.join("moved.toml");
    std::fs::write(&scenario, "emitter = [25000.0, 15001.0]\n").unwrap();
    for (extra, what) in [
        (vec!["--steps", "3", "--seed", "2"], "seed 2, not 1"),
        (vec!["--steps", "5"], "5 steps, not 3"),
        (vec!["--steps", "3", "--scenario", scenario.to_str().unwrap()], "another scenario"),
    ] {
        let out = monitor(&extra);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{extra:?}: {err}");
        assert!(err.contains("the log of another run") && err.contains(what) && err.contains(log), "{err}");
    }
    // Its own run's log: every step is in it, so the monitor has the whole record at once.
    let out = monitor(&["--steps", "3", "--print-record"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let record: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(record["steps"].as_array().map(Vec::len), Some(4));
    assert_nothing_left(&d);
    let _ = std::fs::remove_dir_all(&dir);
}

/// An emitter-sim given the `--checkpoint` of another run (another seed here) is refused before it starts
/// (exit 2, naming the file); before, it flew this run on from that run's world snapshot. Its own run's
/// checkpoint is taken (it then waits for a pipeline that is not there: exit 1 after the connect timeout).
#[test]
fn an_emitter_sim_checkpoint_of_another_run_is_refused() {
    let _scenario = common::scenario(module_path!());
    let dir = common::scratch("checkpoint-other-run");
    let d = domain("ckpt", "other");
    let file = dir.join("emitter-sim.ckpt");
    let checkpoint = |seed: u64| {
        let sc = model::scenario::load_scenario(None, Some(600), Some(seed)).unwrap();
        let snapshot =
            |step: u64| serde_json::json!([{"step": step, "positions": sc.uavs, "headings": [0.1, 0.2, 0.3]}, false]);
        let text = serde_json::json!({
            "role": "emitter-sim", "domain": d,
            "state": {"scenario": sc.fingerprint(), "snapshots": [snapshot(0), snapshot(512)]},
        });
        std::fs::write(&file, text.to_string()).unwrap();
    };
    let emitter = || {
        let f = file.to_str().unwrap();
        let args = [
            "process",
            "emitter-sim",
            "--domain",
            &d,
            "--steps",
            "600",
            "--checkpoint",
            f,
            "--connect-timeout-s",
            "0.3",
        ];
        Command::new(UAVLOC).args(args).output().unwrap()
    };
    checkpoint(2);
    let out = emitter();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("another run") && err.contains("emitter-sim.ckpt"), "{err}");
    checkpoint(1);
    let out = emitter();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("did not connect"), "{err}");
    assert_nothing_left(&d);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Two outputs of one run on one file — `--log` and `--stamps`, `--log` and `--record`, a file the `--out`
/// directory will hold, by another name of the same path — are refused before the run (exit 2, one line
/// naming both flags), and the file is left as it was. Before, `--log` and `--stamps` on one file ended
/// with exit 0 and a CSV where the log had been; `--log` and `--record` failed the monitor 5 times.
#[test]
fn two_outputs_on_one_file_are_refused_before_the_run() {
    let _scenario = common::scenario(module_path!());
    let dir = common::scratch("same-file");
    let kept = dir.join("kept.txt");
    std::fs::write(&kept, "keep me").unwrap();
    let k = kept.to_str().unwrap();
    let other_name = dir.join("sub/../kept.txt");
    std::fs::create_dir_all(dir.join("sub")).unwrap();
    let o = other_name.to_str().unwrap();
    let d = domain("same", "file");
    let out_dir = dir.to_str().unwrap();
    let run_json = dir.join("run.json");
    let cases: [(&[&str], &str); 5] = [
        (&["launch", "--headless", "--steps", "3", "--domain", &d, "--log", k, "--stamps", o], "--log and --stamps"),
        (&["launch", "--headless", "--steps", "3", "--domain", &d, "--log", k, "--record", k], "--record and --log"),
        (
            &[
                "launch",
                "--headless",
                "--steps",
                "3",
                "--domain",
                &d,
                "--log",
                run_json.to_str().unwrap(),
                "--out",
                out_dir,
            ],
            "(its run.json)",
        ),
        (&["process", "monitor", "--domain", &d, "--log", k, "--mcap", o], "--log and --mcap"),
        (&["simulate", "--steps", "3", "--record", run_json.to_str().unwrap(), "--out", out_dir], "(its run.json)"),
    ];
    for (args, needle) in cases {
        let out = common::uavloc(args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{args:?}: {err}");
        assert!(err.contains(needle) && err.contains("are one file"), "{args:?}: {err}");
        assert_eq!(std::fs::read_to_string(&kept).unwrap(), "keep me", "{args:?} touched the file");
        assert!(!run_json.exists(), "{args:?} wrote run.json");
    }
    assert_nothing_left(&d);
    let _ = std::fs::remove_dir_all(&dir);
}

/// An unusable `$TMPDIR` (the launch's state directory cannot be made there) is bad input: exit 2,
/// naming it (it used to be exit 1).
#[test]
fn an_unusable_tmpdir_is_refused_naming_it() {
    let _scenario = common::scenario(module_path!());
    let out = Command::new(UAVLOC)
        .args(["launch", "--headless", "--steps", "2"])
        .env("TMPDIR", "/nonexistent/uavloc-tmp")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("/nonexistent/uavloc-tmp ($TMPDIR) is not usable"), "{err}");
}
