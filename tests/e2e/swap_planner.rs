//! `uavloc swap` during a slow `uavloc launch`: a new planner (ga instead of pso) takes over at the next
//! step, the old one plans the steps before and exits, no step is missed or planned twice, the monitor
//! shows and records which planner produced each step, and the swapped-in process stops with the launch.
//! Swapping the estimator hands its state over exactly: the run still equals `simulate`.

use crate::common;

use std::process::{Command, Stdio};
use std::time::Duration;

use common::{Launch, UAVLOC, assert_nothing_left, assert_same_run, domain, is_zombie, json_of, pid_of, scratch};
use serde_json::Value;

const STEPS: u64 = 30;

/// Runs `uavloc swap <args> --json` (stderr to a file: the detached new process keeps writing there).
fn swap(dir: &std::path::Path, args: &[&str]) -> Value {
    let err = dir.join("swap.stderr");
    let out = Command::new(UAVLOC)
        .arg("swap")
        .args(args)
        .arg("--json")
        .stdin(Stdio::null())
        .stderr(std::fs::File::create(&err).unwrap())
        .output()
        .expect("run uavloc swap");
    let stderr = std::fs::read_to_string(&err).unwrap_or_default();
    assert!(out.status.success(), "uavloc swap {args:?} failed ({}): {stderr}", out.status);
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| panic!("not JSON ({e}): {stderr}"))
}

fn gone(pid: u32) -> bool {
    !std::path::Path::new(&format!("/proc/{pid}")).exists() || is_zombie(pid)
}

#[test]
fn the_planner_is_swapped_from_pso_to_ga_mid_run() {
    let _scenario = common::scenario(module_path!());
    let d = domain("swap", "planner");
    let dir = scratch("swap-planner");
    let steps = STEPS.to_string();
    let mut launch = Launch::start(&d, &dir, &["--steps", &steps, "--step-delay-ms", "40", "--solver", "pso"]);
    launch.wait_for_step(5, Duration::from_secs(30));
    let old = pid_of(&d, "planner").expect("the launch's planner");

    let report = swap(&dir, &["planner", "--domain", &d, "--steps", &steps, "--solver", "ga"]);
    let from = report["from_step"].as_u64().unwrap();
    let new = report["pid"].as_u64().unwrap() as u32;
    assert!((6..STEPS).contains(&from), "{report}");
    assert_eq!(report["planner"], "ga/analytical");
    // When the swap returns, the old planner is gone and the new one is the planner of the domain.
    assert!(gone(old), "the old planner {old} still runs");
    assert_eq!(pid_of(&d, "planner"), Some(new));

    let run = launch.finish_json();
    assert_eq!(run["restarts"].as_u64(), Some(0), "a swap is no restart");
    assert_eq!(run["rejected"].as_u64(), Some(0));
    let records = run["steps"].as_array().unwrap();
    assert_eq!(records.len() as u64, STEPS + 1);
    // Every planned step has exactly one command: pso's before the swap, ga's from it on.
    for s in &records[..STEPS as usize] {
        let k = s["step"].as_u64().unwrap();
        let solver = s["planner"]["solver"].as_str().unwrap_or_else(|| panic!("step {k} has no planner: {s}"));
        assert_eq!(solver, if k < from { "pso" } else { "ga" }, "step {k}");
        let pid = s["planner"]["instance"].as_u64().unwrap() >> 32;
        assert_eq!(pid, u64::from(if k < from { old } else { new }), "step {k}");
    }
    assert!(records[STEPS as usize]["planner"].is_null(), "the last step is not planned");
    // Both planners fly under the same certificate: every step certified, nothing broken along the arcs.
    for s in &records[..STEPS as usize] {
        assert_eq!(s["safety"]["certified"], true, "step {}: {}", s["step"], s["safety"]);
    }
    assert_eq!(run["true_spacing_violations"].as_u64(), Some(0), "{}", run["min_pair_m"]);
    assert_eq!(run["true_standoff_violations"].as_u64(), Some(0), "{}", run["min_true_distance_m"]);
    assert_eq!(run["uncertified_steps"].as_u64(), Some(0));
    // No step was missed: emitter-sim never had to ask again, and flew one command per step.
    let processes = run["processes"].as_array().unwrap();
    let emitter = processes.iter().find(|p| p["role"] == "emitter-sim").unwrap();
    assert_eq!(emitter["summary"]["steps"].as_u64(), Some(STEPS), "{emitter}");
    assert_eq!(emitter["summary"]["retries"].as_u64(), Some(0), "{emitter}");
    // The old planner exited cleanly, handing over at the swap step.
    let planner = processes.iter().find(|p| p["role"] == "planner").unwrap();
    assert_eq!(
        (planner["exit"].as_str(), planner["summary"]["handed_over_at"].as_u64()),
        (Some("exit code 0"), Some(from))
    );

    // Up to the swap the run is pso's, i.e. simulate's; from there on the ga planner flew it.
    let sim = json_of(&["simulate", "--json", "--steps", &steps, "--solver", "pso"]);
    let prefix = |v: &Value, n: u64| {
        let mut v = v.clone();
        v["steps"] = Value::Array(v["steps"].as_array().unwrap()[..n as usize].to_vec());
        v
    };
    assert_same_run(&prefix(&sim, from), &prefix(&run, from), "before the swap");
    assert_eq!(sim["steps"][from as usize]["uavs"], run["steps"][from as usize]["uavs"], "pso's last command flown");
    assert_ne!(sim["steps"][STEPS as usize]["uavs"], run["steps"][STEPS as usize]["uavs"], "ga flew the rest");

    // The monitor showed the switch: a take-over event and two planner instances.
    let events = launch_events(&dir);
    let takeover: Vec<&Value> = events.iter().filter(|e| e["event"] == "take_over").collect();
    assert_eq!(takeover.len(), 1, "{takeover:?}");
    assert_eq!((takeover[0]["role"].as_str(), takeover[0]["step"].as_u64()), (Some("planner"), Some(from)));
    assert_eq!(takeover[0]["detail"], "ga/analytical");
    let planners: Vec<&Value> = events.iter().filter(|e| e["event"] == "planner").collect();
    assert_eq!(planners.iter().map(|e| e["solver"].as_str().unwrap()).collect::<Vec<_>>(), ["pso", "ga"]);
    assert_eq!(planners[1]["step"].as_u64(), Some(from));

    // The launch stopped the swapped-in planner too.
    assert_nothing_left(&d);
    assert!(gone(new));
    std::fs::remove_dir_all(&dir).ok();
}

/// A swap without flags restarts the planner as the launch runs it: the launch's solver and transport,
/// not the process's defaults (before: a gradient planner on iceoryx2, which could not even reach this
/// launch's sockets).
#[test]
fn a_swap_without_flags_keeps_the_launchs_solver_and_transport() {
    let _scenario = common::scenario(module_path!());
    let d = domain("swap", "same");
    let dir = scratch("swap-same");
    let steps = STEPS.to_string();
    let mut launch =
        Launch::start(&d, &dir, &["--steps", &steps, "--step-delay-ms", "40", "--solver", "pso", "--transport", "uds"]);
    launch.wait_for_step(5, Duration::from_secs(30));
    let report = swap(&dir, &["planner", "--domain", &d]);
    assert_eq!(report["planner"], "pso/analytical", "{report}");
    let from = report["from_step"].as_u64().unwrap();
    let run = launch.finish_json();
    for s in &run["steps"].as_array().unwrap()[..STEPS as usize] {
        assert_eq!(s["planner"]["solver"], "pso", "step {}", s["step"]);
    }
    // The same planner after the swap as before it: the run is simulate's, bit for bit.
    let sim = json_of(&["simulate", "--json", "--steps", &steps, "--solver", "pso"]);
    assert_same_run(&sim, &run, &format!("a planner swapped at step {from} with no flags"));
    assert_nothing_left(&d);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_estimator_is_swapped_and_the_run_is_unchanged() {
    let _scenario = common::scenario(module_path!());
    let d = domain("swap", "estimator");
    let dir = scratch("swap-estimator");
    let steps = STEPS.to_string();
    let mut launch = Launch::start(&d, &dir, &["--steps", &steps, "--step-delay-ms", "40"]);
    launch.wait_for_step(5, Duration::from_secs(30));
    let old = pid_of(&d, "estimator").expect("the launch's estimator");
    let report = swap(&dir, &["estimator", "--domain", &d]);
    let from = report["from_step"].as_u64().unwrap();
    assert!((6..STEPS).contains(&from), "{report}");
    assert!(gone(old));
    assert_eq!(pid_of(&d, "estimator"), Some(report["pid"].as_u64().unwrap() as u32));
    let run = launch.finish_json();
    // The new estimator continued from exactly the old one's state: the run is simulate's, bit for bit.
    let sim = json_of(&["simulate", "--json", "--steps", &steps]);
    assert_same_run(&sim, &run, "estimator swap");
    assert_eq!((run["restarts"].as_u64(), run["rejected"].as_u64()), (Some(0), Some(0)));
    let processes = run["processes"].as_array().unwrap();
    let estimator = processes.iter().find(|p| p["role"] == "estimator").unwrap();
    assert_eq!(estimator["summary"]["handed_over_at"].as_u64(), Some(from), "{estimator}");
    let emitter = processes.iter().find(|p| p["role"] == "emitter-sim").unwrap();
    assert_eq!(emitter["summary"]["retries"].as_u64(), Some(0), "{emitter}");
    assert_nothing_left(&d);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_swap_without_a_pipeline_is_refused() {
    let _scenario = common::scenario(module_path!());
    let d = domain("swap", "nothing");
    let out = common::uavloc(&["swap", "planner", "--domain", &d]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no planner is running") && err.contains(&d), "{err}");
    assert_nothing_left(&d);
}

fn launch_events(dir: &std::path::Path) -> Vec<Value> {
    common::read_events(&dir.join("run.jsonl"))
}

/// A swapped-in planner is not the launcher's child: killed, it is not restarted, but the launch now
/// fails at once saying so (before, it stalled and failed after 41 s with "no command").
#[test]
fn a_killed_swapped_in_planner_fails_the_run_at_once_with_a_clear_message() {
    let _scenario = common::scenario(module_path!());
    let d = domain("swap", "killed");
    let dir = scratch("swap-killed");
    let mut launch = Launch::start(&d, &dir, &["--steps", "100", "--step-delay-ms", "30"]);
    launch.wait_for_step(5, Duration::from_secs(30));
    let report = swap(&dir, &["planner", "--domain", &d, "--solver", "ga"]);
    let new = report["pid"].as_u64().unwrap() as u32;
    let killed = std::time::Instant::now();
    common::kill(new, libc::SIGKILL);
    let (status, _, stderr) = launch.finish();
    assert!(!status.success(), "{stderr}");
    assert!(stderr.contains("swapped in by `uavloc swap` is gone"), "{stderr}");
    assert!(killed.elapsed() < Duration::from_secs(10), "took {:?} to notice", killed.elapsed());
    common::assert_nothing_left(&d);
}

/// `swap` takes the run's settings from the running launch: a planner given another `--steps` is refused
/// (exit 2) and the run goes on unharmed (before, the swap succeeded and the run stalled at step 24);
/// without `--steps` it takes the run's.
#[test]
fn a_swap_with_other_run_settings_is_refused_and_the_run_goes_on() {
    let _scenario = common::scenario(module_path!());
    let d = domain("swap", "mismatch");
    let dir = scratch("swap-mismatch");
    let mut launch = Launch::start(&d, &dir, &["--steps", "60", "--step-delay-ms", "20"]);
    launch.wait_for_step(3, Duration::from_secs(30));
    let out = Command::new(UAVLOC).args(["swap", "planner", "--domain", &d, "--steps", "24"]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("--steps 24 does not match") && err.contains("60"), "{err}");
    // Without --steps: the run's 60.
    let report = swap(&dir, &["planner", "--domain", &d, "--solver", "aco"]);
    assert!(report["from_step"].as_u64().unwrap() < 60);
    let run = launch.finish_json();
    assert_eq!(run["steps"].as_array().unwrap().len(), 61);
    assert_eq!(run["restarts"].as_u64(), Some(0));
    common::assert_nothing_left(&d);
}

/// A second instance of a role started into a running pipeline without `--takeover` (by hand, not by
/// `uavloc swap`) is refused at once (exit 2, naming the running one and `uavloc swap`), and the run goes
/// on unharmed. Before, a second planner took over silently: its sequence numbers were the higher, so the
/// world flew its plans (another solver) and rejected the launch's planner's commands as stale.
#[test]
fn a_second_instance_of_a_role_without_takeover_is_refused_and_the_run_goes_on() {
    let _scenario = common::scenario(module_path!());
    let d = domain("swap", "second");
    let dir = scratch("swap-second");
    let steps = "40";
    let mut launch = Launch::start(&d, &dir, &["--steps", steps, "--step-delay-ms", "20"]);
    launch.wait_for_step(3, Duration::from_secs(30));
    for role in ["planner", "estimator", "monitor", "emitter-sim"] {
        let mut args = vec!["process", role, "--domain", &d];
        match role {
            "planner" => args.extend(["--steps", steps, "--solver", "pso"]),
            "estimator" => {}
            _ => args.extend(["--steps", steps]),
        }
        let out = Command::new(UAVLOC).args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{role}: {err}");
        assert!(
            err.contains(&format!("a {role} is already running in domain {d}")) && err.contains("uavloc swap"),
            "{err}"
        );
    }
    let run = launch.finish_json();
    assert_same_run(&json_of(&["simulate", "--json", "--steps", steps]), &run, "a second instance refused");
    assert_eq!((run["restarts"].as_u64(), run["rejected"].as_u64()), (Some(0), Some(0)), "{run}");
    common::assert_nothing_left(&d);
}

/// Two `uavloc swap planner` started at the same instant: one swaps (the run's planner from then on is
/// its solver alone), the other is refused at once (exit 2, "in progress"). Before, both reported a swap
/// from the same step, but the first new planner handed over to the second at once and planned nothing.
#[test]
fn of_two_swaps_at_once_one_swaps_and_the_other_is_refused() {
    let _scenario = common::scenario(module_path!());
    let d = domain("swap", "twice");
    let dir = scratch("swap-twice");
    // Steps of 150 ms: a swap takes at least one step, so the second swap starts while the first holds the
    // lock even on a loaded machine.
    let mut launch = Launch::start(&d, &dir, &["--steps", "30", "--step-delay-ms", "150"]);
    launch.wait_for_step(3, Duration::from_secs(30));
    let start = |solver: &str, n: usize| {
        Command::new(UAVLOC)
            .args(["swap", "planner", "--domain", &d, "--solver", solver, "--json"])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(std::fs::File::create(dir.join(format!("swap-{n}.stderr"))).unwrap())
            .spawn()
            .unwrap()
    };
    let swaps = [start("pso", 1), start("ga", 2)];
    let outcomes: Vec<(Option<i32>, String, String)> = swaps
        .into_iter()
        .enumerate()
        .map(|(i, c)| {
            let out = c.wait_with_output().unwrap();
            (
                out.status.code(),
                String::from_utf8_lossy(&out.stdout).into_owned(),
                std::fs::read_to_string(dir.join(format!("swap-{}.stderr", i + 1))).unwrap(),
            )
        })
        .collect();
    let codes: Vec<Option<i32>> = outcomes.iter().map(|o| o.0).collect();
    let mut sorted = codes.clone();
    sorted.sort();
    assert_eq!(sorted, [Some(0), Some(2)], "{outcomes:?}");
    let (_, stdout, _) = outcomes.iter().find(|o| o.0 == Some(0)).unwrap();
    let (_, _, refused) = outcomes.iter().find(|o| o.0 == Some(2)).unwrap();
    assert!(refused.contains("a swap of the planner") && refused.contains("in progress"), "{refused}");
    let report: Value = serde_json::from_str(stdout).unwrap();
    let (from, solver) = (report["from_step"].as_u64().unwrap(), report["planner"].as_str().unwrap().to_string());
    let run = launch.finish_json();
    assert_eq!(run["restarts"].as_u64(), Some(0));
    // Every step from the swap on was planned by the swap that succeeded, with the solver it reported.
    for s in &run["steps"].as_array().unwrap()[from as usize..30] {
        let planner =
            format!("{}/{}", s["planner"]["solver"].as_str().unwrap(), s["planner"]["objective"].as_str().unwrap());
        assert_eq!(planner, solver, "step {}", s["step"]);
    }
    common::assert_nothing_left(&d);
}

/// kill -9 of the launcher after a swap: the swapped-in planner is not the launch's child, so the
/// launch's end did not stop it — it ran on for ever, and every later launch into the domain was refused.
/// It watches the launch (`--watch-pid`, a pidfd) and stops within a second or two; the domain is free
/// for the next launch.
#[test]
fn a_swapped_in_planner_stops_when_its_launcher_is_killed() {
    let _scenario = common::scenario(module_path!());
    let d = domain("swap", "orphan");
    let dir = scratch("swap-orphan");
    let mut launch = Launch::start(&d, &dir, &["--steps", "2000", "--step-delay-ms", "40"]);
    launch.wait_for_step(3, Duration::from_secs(30));
    let report = swap(&dir, &["planner", "--domain", &d, "--solver", "ga"]);
    let new = report["pid"].as_u64().unwrap() as u32;
    common::kill(launch.child.id(), libc::SIGKILL);
    let _ = launch.child.wait();
    let killed = std::time::Instant::now();
    while !gone(new) {
        assert!(killed.elapsed() < Duration::from_secs(10), "the swapped-in planner {new} outlived its launcher");
        std::thread::sleep(Duration::from_millis(20));
    }
    // Every process of the domain is gone (the launch's children by their parent-death signal).
    while !common::processes_mentioning(&d).is_empty() {
        assert!(killed.elapsed() < Duration::from_secs(10), "{:?}", common::processes_mentioning(&d));
        std::thread::sleep(Duration::from_millis(20));
    }
    // The domain is free: a new launch runs in it.
    let next = common::json_of(&["launch", "--headless", "--json", "--steps", "3", "--domain", &d]);
    assert_eq!(next["steps"].as_array().unwrap().len(), 4);
    assert_nothing_left(&d);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The old planner or estimator killed in the first moments of `uavloc swap` (before the new one has
/// taken over): the run used to be lost (the launcher restarted the old role, which was refused — one was
/// already running —, exit 1; the swap said the new one stopped before taking over). The swap completes,
/// the run goes on; with the estimator, the run is still the one `simulate` gives.
fn kill_the_old_one_during_a_swap(role: &str, flags: &[&str], solver_after: Option<&str>) -> Value {
    let _scenario = common::scenario(module_path!());
    let d = domain("swap", &format!("kill{role}"));
    let dir = scratch(&format!("swap-kill-{role}"));
    let steps = STEPS.to_string();
    let mut launch = Launch::start(&d, &dir, &["--steps", &steps, "--step-delay-ms", "40"]);
    launch.wait_for_step(3, Duration::from_secs(30));
    let old = pid_of(&d, role).expect("the launch's process");
    let swap = Command::new(UAVLOC)
        .args(["swap", role, "--domain", &d, "--json"])
        .args(flags)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(dir.join("swap.stderr")).unwrap())
        .spawn()
        .unwrap();
    // As soon as the new process is there (it starts, then takes over at the next step).
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    while common::processes_mentioning(&d).iter().all(|(_, c)| !c.contains("--takeover")) {
        assert!(std::time::Instant::now() < deadline, "no new {role}");
        std::thread::yield_now();
    }
    common::kill(old, libc::SIGKILL);
    let swapped = swap.wait_with_output().unwrap();
    let swap_err = std::fs::read_to_string(dir.join("swap.stderr")).unwrap_or_default();
    let (status, stdout, stderr) = launch.finish();
    assert!(status.success(), "the run was lost: {stderr}\nswap ({}): {swap_err}", swapped.status);
    let run: Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(run["steps"].as_array().unwrap().len() as u64, STEPS + 1);
    // The swap completed: the new process took over and did the rest; the launcher said why it did not
    // restart the old one.
    assert!(swapped.status.success(), "{swap_err}");
    assert!(stderr.contains(&format!("the swapped-in {role}")), "{stderr}");
    let last = &run["steps"].as_array().unwrap()[STEPS as usize - 1];
    let first = &run["steps"].as_array().unwrap()[0];
    assert_eq!(
        last["planner"]["solver"],
        solver_after.map_or(first["planner"]["solver"].clone(), Value::from),
        "{last}"
    );
    assert_nothing_left(&d);
    let _ = std::fs::remove_dir_all(&dir);
    run
}

#[test]
fn the_old_planner_killed_during_a_swap_leaves_the_run_going() {
    kill_the_old_one_during_a_swap("planner", &["--solver", "ga"], Some("ga"));
}

#[test]
fn the_old_estimator_killed_during_a_swap_leaves_the_run_going_and_unchanged() {
    let run = kill_the_old_one_during_a_swap("estimator", &[], None);
    let steps = STEPS.to_string();
    let reference = json_of(&["simulate", "--json", "--steps", &steps]);
    assert_same_run(&reference, &run, "an estimator swap whose old estimator was killed");
}
