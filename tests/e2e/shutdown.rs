//! SIGTERM stops a pipeline cleanly: sent to `uavloc launch` mid-run, the launcher stops its four
//! children and exits 1, leaving no process and no iceoryx2 resource of the domain; sent to processes
//! started by hand, each exits on its own (estimator and planner 0, emitter-sim and monitor 130: the run
//! was cut short) and takes its iceoryx2 resources with it.

use crate::common;

use std::time::{Duration, Instant};

use common::{
    Launch, assert_nothing_left, domain, kill, pid_of, read_events, scratch, start_process as start, wait_exit,
};

#[test]
fn sigterm_to_the_launcher_mid_run_stops_everything() {
    let _scenario = common::scenario(module_path!());
    let d = domain("shutdown", "launch");
    let dir = scratch("shutdown-launch");
    let mut launch = Launch::start(&d, &dir, &["--steps", "500", "--step-delay-ms", "20"]);
    launch.wait_for_step(3, Duration::from_secs(30));
    for role in ["monitor", "planner", "estimator", "emitter-sim"] {
        assert!(pid_of(&d, role).is_some(), "the {role} of {d} runs");
    }
    kill(launch.child.id(), libc::SIGTERM);
    let status = wait_exit(&mut launch.child, Duration::from_secs(10), "the launcher");
    assert_eq!(status.code(), Some(1), "{}", launch.stderr_text());
    let stderr = launch.stderr_text();
    assert!(stderr.contains("interrupted by SIGTERM"), "{stderr}");
    // The monitor wrote its partial run and said it ended early.
    let events = launch.events();
    let end = events.iter().find(|e| e["event"] == "end").expect("an end event");
    assert_eq!(end["complete"], false, "{end}");
    assert!(end["steps"].as_u64().unwrap() < 500);
    assert_nothing_left(&d);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn sigterm_to_processes_started_by_hand() {
    let _scenario = common::scenario(module_path!());
    let d = domain("shutdown", "hand");
    let dir = scratch("shutdown-hand");
    let log = dir.join("run.jsonl");
    let run = ["--steps", "500"];
    let mut monitor = start("monitor", &d, &[&run[..], &["--log", log.to_str().unwrap()]].concat());
    let mut planner = start("planner", &d, &run);
    let mut estimator = start("estimator", &d, &[]);
    let mut emitter =
        start("emitter-sim", &d, &[&run[..], &["--min-subscribers", "2", "--step-delay-ms", "20"]].concat());
    let deadline = Instant::now() + Duration::from_secs(30);
    while !read_events(&log).iter().any(|e| e["event"] == "step" && e["step"].as_u64() >= Some(2)) {
        assert!(Instant::now() < deadline, "the hand-started pipeline does not run");
        std::thread::sleep(Duration::from_millis(10));
    }
    // One at a time, mid-run: each exits by itself, with its own exit code.
    for (child, role, code) in [
        (&mut estimator, "estimator", 0),
        (&mut planner, "planner", 0),
        (&mut emitter, "emitter-sim", 130),
        (&mut monitor, "monitor", 130),
    ] {
        kill(child.id(), libc::SIGTERM);
        let status = wait_exit(child, Duration::from_secs(5), role);
        assert_eq!(status.code(), Some(code), "{role}");
        assert!(pid_of(&d, role).is_none(), "{role} is gone");
    }
    assert_nothing_left(&d);
    std::fs::remove_dir_all(&dir).ok();
}

/// SIGKILL to the launcher (no handler runs): its children get SIGTERM from the kernel
/// (PR_SET_PDEATHSIG), stop cleanly and leave no process and no iceoryx2 resource behind.
#[test]
fn sigkill_to_the_launcher_leaves_no_child_behind() {
    let _scenario = common::scenario(module_path!());
    let d = domain("shutdown", "launcher-killed");
    let dir = scratch("shutdown-launcher-killed");
    let mut launch = Launch::start(&d, &dir, &["--steps", "500", "--step-delay-ms", "20"]);
    launch.wait_for_step(3, Duration::from_secs(30));
    let children: Vec<u32> =
        ["monitor", "planner", "estimator", "emitter-sim"].iter().filter_map(|r| pid_of(&d, r)).collect();
    assert_eq!(children.len(), 4, "the four children of {d} run");
    kill(launch.child.id(), libc::SIGKILL);
    let status = wait_exit(&mut launch.child, Duration::from_secs(10), "the launcher");
    assert_eq!(status.code(), None, "killed by a signal");
    let deadline = Instant::now() + Duration::from_secs(10);
    while children.iter().any(|&pid| common::is_alive(pid)) {
        assert!(Instant::now() < deadline, "children of a killed launcher still run: {children:?}");
        std::thread::sleep(Duration::from_millis(20));
    }
    assert_nothing_left(&d);
    std::fs::remove_dir_all(&dir).ok();
}
