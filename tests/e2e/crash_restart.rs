//! SIGKILL each of the four processes once in the middle of a slow launch: the launcher restarts it
//! (written to the log, counted in `restarts`), the stale iceoryx2 resources of the dead node are removed
//! (no "already exists" or "incompatible" error), emitter-sim replays the run to the new instance (see
//! `emitter_sim::process`), and the run completes all its steps with exactly `simulate`'s trajectory,
//! estimates and metrics — each step recorded once, one command applied per step.

use crate::common;

use std::time::Duration;

use common::{
    Launch, assert_nothing_left, assert_same_run, domain, json_of, kill, pid_of, scratch, start_process, wait_exit,
};
use serde_json::Value;

const STEPS: u64 = 30;

fn kill_once(role: &str) {
    kill_together(&[role], STEPS, 5, 30);
}

/// What a run with kills ended with: the step the finishing emitter-sim started from, the estimator's
/// state requests.
struct Outcome {
    started_at: u64,
    state_requests: Vec<u64>,
}

/// SIGKILLs the processes of `roles` at once (each restarted once) once the monitor has logged step
/// `kill_at` of a run of `total` steps paced at `delay_ms` per step, and checks the run.
fn kill_together(roles: &[&str], total: u64, kill_at: u64, delay_ms: u64) -> Outcome {
    let tag = roles.join("-");
    let d = domain("crash", &tag);
    let dir = scratch(&format!("crash-{tag}"));
    let steps = total.to_string();
    let mut launch = Launch::start(&d, &dir, &["--steps", &steps, "--step-delay-ms", &delay_ms.to_string()]);
    launch.wait_for_step(kill_at, Duration::from_secs(60));
    let pids: Vec<u32> =
        roles.iter().map(|role| pid_of(&d, role).unwrap_or_else(|| panic!("no {role} of {d} found"))).collect();
    for &pid in &pids {
        kill(pid, libc::SIGKILL);
    }
    let events_at_kill = launch.events();
    let stderr_path = launch.stderr.clone();
    let run = launch.finish_json();
    let stderr = std::fs::read_to_string(stderr_path).unwrap_or_default();

    // The kill happened mid-run.
    let logged_at_kill = events_at_kill.iter().filter(|e| e["event"] == "step").count() as u64;
    assert!(logged_at_kill < total, "{tag}: the run was over before the kill");

    // Each restarted once, and said so.
    assert_eq!(run["restarts"].as_u64(), Some(roles.len() as u64), "{tag}: {stderr}");
    for bad in ["AlreadyExists", "already exists", "Incompatible", "incompatible", "error:"] {
        assert!(!stderr.contains(bad), "{tag}: {bad:?} in:\n{stderr}");
    }
    let processes = run["processes"].as_array().unwrap();
    let events = common::read_events(&dir.join("run.jsonl"));
    for (&role, &pid) in roles.iter().zip(&pids) {
        assert!(
            stderr.contains(&format!("the {role} process (pid {pid}) stopped unexpectedly (signal 9)")),
            "{stderr}"
        );
        let instances: Vec<&Value> = processes.iter().filter(|p| p["role"] == role).collect();
        assert_eq!(instances.len(), 2, "{role}: {processes:?}");
        assert_eq!((instances[0]["restarted"].as_bool(), instances[0]["pid"].as_u64()), (Some(true), Some(pid as u64)));
        assert!(instances[0]["exit"].as_str().unwrap().contains("signal 9"));
        // The log has the restart.
        let restarts: Vec<&Value> = events.iter().filter(|e| e["event"] == "restart" && e["role"] == role).collect();
        assert_eq!(restarts.len(), 1, "{role}: {restarts:?}");
        assert_eq!(restarts[0]["attempt"].as_u64(), Some(1), "{role}");
        // The restarted process joined, and (but for emitter-sim itself) the run was replayed to it.
        assert!(
            events.iter().any(|e| e["event"] == "hello" && e["role"] == role)
                || role == "monitor" && events.iter().any(|e| e["event"] == "resume"),
            "{role}: no hello"
        );
    }
    // Every step exactly once.
    common::assert_each_step_logged_once(&events, total, &tag);

    // One command applied per step: the emitter-sim that finished the run flew exactly the steps from
    // where it started (a restarted emitter-sim flies the run again from its older world snapshot, from
    // step 0 in a run this short, and the estimator and the planner answer every step again from what
    // the messages carry).
    let emitter = processes.iter().rev().find(|p| p["role"] == "emitter-sim").unwrap();
    let started_at = emitter["summary"]["started_at"].as_u64().unwrap();
    assert_eq!(emitter["summary"]["steps"].as_u64(), Some(total - started_at), "{tag}: {emitter}");
    let asked: Vec<u64> = events
        .iter()
        .filter(|e| e["event"] == "state_request" && e["role"] == "estimator")
        .filter_map(|e| e["step"].as_u64())
        .collect();
    // A restarted estimator keeps no file: it asked the monitor for the state after the step before the
    // first one it was given — the one in flight, or the snapshot step a restarted emitter-sim flew on
    // from — which the monitor had from that step's estimate and command. (None when the world starts
    // again from step 0: a fresh run needs no state.)
    if roles.contains(&"estimator") {
        let first = if roles.contains(&"emitter-sim") { started_at } else { logged_at_kill };
        assert!(asked.iter().all(|&k| k + 1 >= first), "{tag}: {asked:?}");
        assert!(first == 0 || asked.contains(&(first - 1)) || !roles.contains(&"emitter-sim"), "{tag}: {asked:?}");
        assert!(first == 0 || !asked.is_empty(), "{tag}: {asked:?}");
    }
    if !roles.contains(&"emitter-sim") {
        assert!(emitter["summary"]["replays"].as_u64().unwrap() >= 1, "{tag}: {emitter}");
    }
    // The restarted monitor recorded the steps it lacked from replayed copies, which carry no publish
    // stamp: it counts their messages as missing (copies stamped at every send
    // would make the count 0).
    if roles.contains(&"monitor") {
        let monitor = processes.iter().rev().find(|p| p["role"] == "monitor").unwrap();
        assert!(monitor["summary"]["missing_messages"].as_u64().unwrap() >= 1, "{tag}: {monitor}");
    }

    // The run is exactly simulate's: no restart changes the result (their inputs are the same).
    let sim = json_of(&["simulate", "--json", "--steps", &steps]);
    assert_same_run(&sim, &run, &tag);
    assert_eq!(run["rejected"].as_u64(), Some(0), "{tag}");
    assert_nothing_left(&d);
    std::fs::remove_dir_all(&dir).ok();
    Outcome { started_at, state_requests: asked }
}

#[test]
fn the_estimator_is_restarted() {
    let _scenario = common::scenario(module_path!());
    kill_once("estimator");
}

#[test]
fn the_estimator_and_the_planner_killed_together_go_on_from_the_monitors_states() {
    // Both holders of the newest estimator state in the messages (the estimator, the planner's commands)
    // are gone at once: the monitor answers.
    let _scenario = common::scenario(module_path!());
    let outcome = kill_together(&["estimator", "planner"], STEPS, 5, 30);
    assert!(!outcome.state_requests.is_empty());
}

#[test]
fn the_estimator_and_emitter_sim_killed_together_go_on_from_a_snapshot_with_the_monitors_state() {
    // A restarted emitter-sim flies on from its older world snapshot (step 256 here); the restarted
    // estimator has seen no step before it and asks the monitor for the state after step 255.
    let _scenario = common::scenario(module_path!());
    let outcome = kill_together(&["estimator", "emitter-sim"], 700, 620, 1);
    assert_eq!(outcome.started_at, 256);
    assert!(outcome.state_requests.contains(&255), "{:?}", outcome.state_requests);
}

#[test]
fn the_planner_is_restarted() {
    let _scenario = common::scenario(module_path!());
    kill_once("planner");
}

#[test]
fn the_monitor_is_restarted_and_rebuilds_from_its_log() {
    let _scenario = common::scenario(module_path!());
    kill_once("monitor");
}

#[test]
fn emitter_sim_is_restarted_and_fast_forwards() {
    let _scenario = common::scenario(module_path!());
    kill_once("emitter-sim");
}

#[test]
fn a_process_that_keeps_crashing_fails_the_launch_after_the_bounded_restarts() {
    let _scenario = common::scenario(module_path!());
    let d = domain("crash", "always");
    let dir = scratch("crash-always");
    let mut launch = Launch::start(&d, &dir, &["--steps", "400", "--step-delay-ms", "20", "--max-restarts", "2"]);
    launch.wait_for_step(2, Duration::from_secs(30));
    // Kill every planner instance once it runs (it announced itself: its hello is in the log, the instance
    // id carries its pid): the third kill exceeds --max-restarts 2. (A process killed while iceoryx2
    // creates its node — a window of microseconds between the node's details file and its monitoring
    // token — leaves a node directory that iceoryx2 cannot list or clean; the test does not aim there.)
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    let mut kills = 0;
    while launch.child.try_wait().unwrap().is_none() {
        assert!(std::time::Instant::now() < deadline, "the launch did not give up");
        if let Some(pid) = pid_of(&d, "planner") {
            let joined = launch.events().iter().any(|e| {
                e["event"] == "hello"
                    && e["role"] == "planner"
                    && e["instance"].as_u64().map(|i| i >> 32) == Some(pid.into())
            });
            if joined {
                kill(pid, libc::SIGKILL);
                kills += 1;
                while pid_of(&d, "planner") == Some(pid) {
                    std::thread::sleep(Duration::from_millis(1));
                }
            }
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    let (status, _, stderr) = launch.finish();
    assert_eq!(status.code(), Some(1), "{stderr}");
    assert!(kills >= 3, "{kills} kills");
    assert!(stderr.contains("the planner process stopped unexpectedly (signal 9) after 2 restart(s)"), "{stderr}");
    let restarts: Vec<Value> =
        common::read_events(&dir.join("run.jsonl")).into_iter().filter(|e| e["event"] == "restart").collect();
    assert_eq!(restarts.iter().map(|e| e["backoff_ms"].as_u64().unwrap()).collect::<Vec<_>>(), vec![50, 100]);
    assert_nothing_left(&d);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn an_estimator_restarted_in_a_pipeline_without_a_monitor_has_the_run_replayed_from_step_0() {
    // Started by hand, without a monitor (no holder of old states): the restarted estimator, holding the
    // step in flight, finds no one to ask for the state before it and asks for a replay from step 0,
    // which brings every state again. Before it did, the run stalled into emitter-sim's command timeout.
    let _scenario = common::scenario(module_path!());
    let d = domain("crash", "no-monitor");
    let run = ["--steps", "60"];
    let mut planner = start_process("planner", &d, &run);
    let mut estimator = start_process("estimator", &d, &[]);
    let mut emitter = start_process(
        "emitter-sim",
        &d,
        &[&run[..], &["--min-subscribers", "1", "--step-delay-ms", "20", "--retry-interval-ms", "200"]].concat(),
    );
    // Mid-run: once the estimator has answered step 5 (an observer of the estimate topic sees it), well
    // before the last step (60, at ≥ 20 ms a step).
    let link = protocol::Link::open(protocol::TransportKind::Iceoryx2, &format!("{d}-observer")).unwrap();
    let dom = protocol::services::Domain::new(&d).unwrap();
    let estimates =
        protocol::Topic::<protocol::Estimate>::subscriber(&link, &protocol::services::estimate(&dom)).unwrap();
    let deadline = std::time::Instant::now() + Duration::from_secs(30);
    let mut newest = 0;
    while newest < 5 {
        newest = estimates.receive_all().unwrap().iter().map(|e| e.header.step).fold(newest, u64::max);
        assert!(std::time::Instant::now() < deadline, "no estimate of step 5 within 30 s");
        std::thread::sleep(Duration::from_millis(2));
    }
    assert!(newest < 50, "the run was nearly over (step {newest}) when the estimator was to be killed");
    drop(estimates);
    drop(link);
    kill(estimator.id(), libc::SIGKILL);
    let _ = estimator.wait();
    let mut estimator = start_process("estimator", &d, &[]);
    let status = wait_exit(&mut emitter, Duration::from_secs(60), "emitter-sim");
    assert!(status.success(), "emitter-sim: {status:?}");
    let summary = summary_of(&mut emitter);
    assert_eq!(summary["steps"].as_u64(), Some(60), "{summary}");
    assert!(summary["replays"].as_u64().unwrap() >= 1, "{summary}");
    for (child, role) in [(&mut estimator, "estimator"), (&mut planner, "planner")] {
        kill(child.id(), libc::SIGTERM);
        assert!(wait_exit(child, Duration::from_secs(5), role).success(), "{role}");
    }
    // The restarted estimator held the step in flight until the replay brought the states.
    let summary = summary_of(&mut estimator);
    assert!(summary["out_of_chain"].as_u64().unwrap() >= 1, "{summary}");
    assert_nothing_left(&d);
}

/// The `summary` line a supervised process printed on stdout before it exited.
fn summary_of(child: &mut std::process::Child) -> Value {
    let mut out = String::new();
    std::io::Read::read_to_string(child.stdout.as_mut().unwrap(), &mut out).unwrap();
    out.lines()
        .find_map(|l| match runtime::SupervisorLine::parse(l) {
            Some(runtime::SupervisorLine::Summary(v)) => Some(v),
            _ => None,
        })
        .unwrap_or_else(|| panic!("no summary line in:\n{out}"))
}

/// The scenario file edited during a run (the user preparing the next experiment) changes no restart: the
/// processes read the launch's own copy, so the planner restarted after the edit plans the scenario the
/// launch started with and the run equals `simulate` of the original file. Before, the restarted planner
/// read the edited file, was of another run, was told to leave (exit 2) and the launch failed.
#[test]
fn a_scenario_file_edited_during_the_run_changes_no_restart() {
    let _scenario = common::scenario(module_path!());
    let dir = scratch("edited-scenario");
    let (file, original) = (dir.join("edited.toml"), dir.join("original.toml"));
    for f in [&file, &original] {
        std::fs::write(f, "speed = 45.0\n").unwrap();
    }
    let d = domain("edit", "scenario");
    let mut launch =
        Launch::start(&d, &dir, &["--steps", "40", "--step-delay-ms", "20", "--scenario", file.to_str().unwrap()]);
    launch.wait_for_step(5, Duration::from_secs(30));
    std::fs::write(&file, "speed = 60.0\n").unwrap();
    kill(pid_of(&d, "planner").expect("the planner"), libc::SIGKILL);
    let run = launch.finish_json();
    assert_eq!(run["restarts"].as_u64(), Some(1), "{}", run["processes"]);
    let sim = json_of(&["simulate", "--json", "--steps", "40", "--scenario", original.to_str().unwrap()]);
    assert_same_run(&sim, &run, "the original scenario");
    assert_nothing_left(&d);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A restarted process killed again during its start-up (its node being created, its resources in the
/// making), three times in a row, for the estimator and for the monitor: each kill is one more restart.
/// It used to abort the launch now and then ("removing a dead node's resources: InternalError", exit 1;
/// estimator 3 of 8, monitor 2 of 5): a node killed mid-creation leaves files iceoryx2's clean-up stops
/// at. Its directory is removed instead, and the run completes equal to `simulate`.
#[test]
fn a_restarted_process_killed_during_its_start_up_is_one_more_restart() {
    let _scenario = common::scenario(module_path!());
    for role in ["estimator", "monitor"] {
        let d = domain("startup", role);
        let dir = scratch(&format!("startup-{role}"));
        let total = 60u64;
        let steps = total.to_string();
        let mut launch = Launch::start(&d, &dir, &["--steps", &steps, "--step-delay-ms", "30"]);
        launch.wait_for_step(3, Duration::from_secs(60));
        let mut pid = pid_of(&d, role).expect("the role's process");
        for _ in 0..3 {
            kill(pid, libc::SIGKILL);
            // The next instance, killed as soon as it is seen (while it starts up).
            let deadline = std::time::Instant::now() + Duration::from_secs(20);
            pid = loop {
                if let Some(next) = pid_of(&d, role).filter(|p| *p != pid) {
                    break next;
                }
                assert!(std::time::Instant::now() < deadline, "{role}: no restarted instance");
                std::thread::yield_now();
            };
        }
        let run = launch.finish_json();
        assert_eq!(run["restarts"].as_u64(), Some(3), "{role}");
        common::assert_complete_run_equals_simulate(&run, &dir, &d, total, role);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
