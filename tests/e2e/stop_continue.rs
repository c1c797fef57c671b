//! SIGSTOP then SIGCONT (a debugger, `kill -STOP`, a job-control stop, a machine that froze a process):
//! every process of a lock-step launch is frozen for a second, one after the other, and thawed. None may
//! take the thaw for a termination request (a signal interrupting a sleep is not SIGINT/SIGTERM): nothing
//! is restarted, no step is lost or doubled, and the run equals `uavloc simulate` bit for bit.

use crate::common;

use std::time::Duration;

use common::{Launch, domain, kill, pid_of, scratch};

const STEPS: u64 = 300;

#[test]
fn every_process_stopped_and_continued_goes_on_without_a_restart() {
    let _scenario = common::scenario(module_path!());
    let d = domain("stopcont", "all");
    let dir = scratch("stopcont-all");
    let steps = STEPS.to_string();
    // ≈ 5 ms per step (emitter-sim sleeps between steps, where a thaw interrupts its sleep).
    let mut launch = Launch::start(&d, &dir, &["--steps", &steps, "--step-delay-ms", "5"]);
    let mut at = 20;
    for role in ["emitter-sim", "estimator", "planner", "monitor"] {
        launch.wait_for_step(at, Duration::from_secs(60));
        let pid = pid_of(&d, role).unwrap_or_else(|| panic!("no {role} running"));
        kill(pid, libc::SIGSTOP);
        std::thread::sleep(Duration::from_millis(1000));
        kill(pid, libc::SIGCONT);
        assert_eq!(pid_of(&d, role), Some(pid), "{role} was replaced");
        at += 40;
    }
    let stderr_path = launch.stderr.clone();
    let run = launch.finish_json();
    let stderr = std::fs::read_to_string(stderr_path).unwrap_or_default();

    assert_eq!(run["restarts"].as_u64(), Some(0), "{stderr}");
    assert!(!stderr.contains("stopped by a signal") && !stderr.contains("error:"), "{stderr}");
    common::assert_complete_run_equals_simulate(&run, &dir, &d, STEPS, "stop/continue");
    std::fs::remove_dir_all(&dir).ok();
}
