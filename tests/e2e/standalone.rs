//! The four processes started by hand, one after the other in one domain, as on an onboard computer
//! without `uavloc launch` (`uavloc process <role>` is what the standalone binaries run).

use crate::common;

use std::process::{Child, Command, Stdio};
use std::time::Duration;

use common::{UAVLOC, assert_nothing_left, assert_same_steps, domain, json_of};
use serde_json::Value;

fn start(role: &str, d: &str, extra: &[&str]) -> Child {
    Command::new(UAVLOC)
        .args(["process", role, "--domain", d, "--quiet"])
        .args(extra)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// Waits for `child` to exit (at most 30 s, [`common::wait_exit`]); its exit code, stdout and stderr (a
/// few kB: the pipes hold them until then).
fn wait(mut child: Child, what: &str) -> (Option<i32>, String, String) {
    use std::io::Read as _;
    let status = common::wait_exit(&mut child, Duration::from_secs(30), what);
    let (mut out, mut err) = (String::new(), String::new());
    child.stdout.take().unwrap().read_to_string(&mut out).unwrap();
    child.stderr.take().unwrap().read_to_string(&mut err).unwrap();
    (status.code(), out, err)
}

/// A planner given another `--seed` than the monitor already running (so another scenario: another run) is
/// told to leave by it and exits 2 naming the monitor, before it plans anything; the set then started
/// with one seed runs the scenario exactly, as `simulate` does. Before, the planner of the other seed
/// planned the run silently.
#[test]
fn a_process_of_another_scenario_is_told_to_leave_and_the_set_runs_on() {
    let _scenario = common::scenario(module_path!());
    let d = domain("hand", "other-run");
    // Supervised, for its `ready` line: its control subscriber exists before the planner says hello.
    let monitor = common::start_process_keeping_output("monitor", &d, &["--steps", "12"]);
    let (code, _, err) = wait(start("planner", &d, &["--steps", "12", "--seed", "2"]), "the planner of seed 2");
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains(&format!("domain {d} runs another scenario")) && err.contains("the monitor"), "{err}");
    let planner = start("planner", &d, &["--steps", "12"]);
    let estimator = start("estimator", &d, &[]);
    let (code, _, err) = wait(start("emitter-sim", &d, &["--steps", "12", "--min-subscribers", "2"]), "emitter-sim");
    assert_eq!(code, Some(0), "emitter-sim: {err}");
    let (code, out, err) = wait(monitor, "the monitor");
    assert_eq!(code, Some(0), "monitor: {err}");
    let record: Value = out
        .lines()
        .find_map(|l| l.strip_prefix("record "))
        .and_then(|r| serde_json::from_str(r).ok())
        .unwrap_or_else(|| panic!("no record line: {out}"));
    assert_same_steps(&json_of(&["simulate", "--json", "--steps", "12"]), &record, "a set of one scenario");
    for p in [planner, estimator] {
        common::kill(p.id(), libc::SIGTERM);
        let (code, _, err) = wait(p, "a process stopped");
        assert_eq!(code, Some(0), "{err}");
    }
    assert_nothing_left(&d);
}

/// A process started by hand from a terminal that hangs up (an ssh session closed) ends as on SIGTERM:
/// the monitor says its record is partial and exits 130, leaving nothing of the domain behind. Before,
/// SIGHUP killed it on the spot (no exit code, its record lost, its iceoryx2 resources left).
#[test]
fn a_hang_up_ends_a_process_cleanly() {
    let _scenario = common::scenario(module_path!());
    let d = domain("hand", "hangup");
    let monitor = start("monitor", &d, &["--steps", "12"]);
    // Once its node exists (a loaded machine may take long to get there): a hang-up before the process
    // has set up its signals kills it, as for any program.
    let dom = protocol::services::Domain::new(&d).unwrap();
    let node = protocol::services::node_name(&dom, "monitor");
    let deadline = std::time::Instant::now() + Duration::from_secs(30);
    while !protocol::resources::list(&dom).is_ok_and(|r| r.alive_nodes().any(|n| *n == node)) {
        assert!(std::time::Instant::now() < deadline, "the monitor's node did not appear");
        std::thread::sleep(Duration::from_millis(20));
    }
    common::kill(monitor.id(), libc::SIGHUP);
    let (code, _, err) = wait(monitor, "the monitor hung up");
    assert_eq!(code, Some(130), "{err}");
    assert!(err.contains("interrupted before the last step"), "{err}");
    assert_nothing_left(&d);
}
