//! Long runs through the four processes: memory stays flat, nothing is lost, and a crash after the replay
//! history has wrapped is recovered from the world's snapshots and the states the messages carry (see
//! `runtime::recovery`).
//!
//! - `soak_flat_memory_and_no_lost_message` (in `cargo test`): 14 000 lock-step steps (≈ 3 s), more than
//!   three times the replay history (4 096 steps), the private resident memory (`RssAnon`) of every
//!   process sampled at step 5 000 (after the history and the estimator's echoed states are full) and
//!   [`END_MARGIN`] steps before the end.
//! - `soak_100k_steps` (in `cargo test` too, alone: `cargo test --release --test e2e soak_100k`): the same
//!   over 100 000 steps (≈ 25 s on 2 cores; the monitor's log grows to ≈ 350 MB on disk, in the test's
//!   scratch directory, removed at the end).
//! - `a_crash_after_the_history_wrapped_resumes_from_the_states_the_messages_carry`: 5 000 steps; the estimator, the
//!   planner, emitter-sim and the monitor are each killed once after step 4 096 — a replay from step 0 is
//!   impossible then — and the run still equals `uavloc simulate`'s, bit for bit.

use crate::common;

use std::collections::BTreeMap;
use std::path::Path;
use std::time::{Duration, Instant};

use common::{Launch, LineTail, assert_nothing_left, assert_same_run, domain, json_of, kill, pid_of, scratch};
use serde_json::Value;

const ROLES: [&str; 4] = ["emitter-sim", "estimator", "planner", "monitor"];

/// The second memory sample is taken this many steps before the end: at the end the monitor reads every
/// step record back from its log to build the run record (megabytes, by design), and a sample taken
/// 100 steps before the end — 17 ms at full speed, less than the log poll's 20 ms — often saw that and
/// failed the test (1 run in 5 on this VM, whatever the commit).
const END_MARGIN: u64 = 2_000;

/// Follows the monitor's log without re-reading it: the newest step logged so far.
struct LogTail {
    lines: LineTail,
    newest: Option<u64>,
}

impl LogTail {
    fn new(path: &Path) -> Self {
        Self { lines: LineTail::new(path), newest: None }
    }

    fn poll(&mut self) -> Option<u64> {
        for line in self.lines.poll() {
            // Only the step events are parsed (the log has a line per message too).
            if line.contains("\"event\":\"step\"")
                && let Ok(e) = serde_json::from_str::<Value>(&line)
                && let Some(k) = e["step"].as_u64()
            {
                self.newest = self.newest.max(Some(k));
            }
        }
        self.newest
    }

    /// Waits until step `step` is logged (panics after `timeout` or when the launch ends first).
    fn wait_for(&mut self, launch: &mut Launch, step: u64, timeout: Duration) {
        let deadline = Instant::now() + timeout;
        while self.poll().is_none_or(|n| n < step) {
            if let Ok(Some(status)) = launch.child.try_wait() {
                panic!("the launch ended ({status}) before step {step}:\n{}", launch.stderr_text());
            }
            assert!(Instant::now() < deadline, "step {step} not logged within {timeout:?}");
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

fn rss_of_all(d: &str) -> BTreeMap<&'static str, (u32, u64)> {
    ROLES
        .iter()
        .map(|r| {
            let pid = pid_of(d, r).unwrap_or_else(|| panic!("no {r} of {d}"));
            // The private memory: a process whose memory grew with the run shows there. (The total RSS also
            // counts the iceoryx2 sample pages a subscriber touched, which grow — up to the segments' fixed
            // size — whenever it falls further behind than before.)
            (*r, (pid, uavloc::bench::sys::anon_rss_bytes(pid).unwrap_or_else(|e| panic!("RSS of {r}: {e}"))))
        })
        .collect()
}

fn summary<'a>(run: &'a Value, role: &str) -> &'a Value {
    &run["processes"].as_array().unwrap().iter().rev().find(|p| p["role"] == role).unwrap()["summary"]
}

fn soak(steps: u64, first_sample: u64) {
    let d = domain("soak", &steps.to_string());
    let dir = scratch(&format!("soak-{steps}"));
    let n = steps.to_string();
    let mut launch = Launch::start(&d, &dir, &["--steps", &n]);
    let mut tail = LogTail::new(&launch.log);
    let timeout = Duration::from_secs(60 + steps / 200);
    tail.wait_for(&mut launch, first_sample, timeout);
    let start = rss_of_all(&d);
    tail.wait_for(&mut launch, steps - END_MARGIN, timeout);
    let end = rss_of_all(&d);
    let run = launch.finish_json();

    let mut table = String::new();
    for r in ROLES {
        let ((p0, a), (p1, b)) = (start[r], end[r]);
        assert_eq!(p0, p1, "{r} was restarted");
        table += &format!(
            "{r:>12}: private RSS {:.1} MiB at step {first_sample}, {:.1} MiB at step {}, {:+.2} %\n",
            a as f64 / 1048576.0,
            b as f64 / 1048576.0,
            steps - END_MARGIN,
            100.0 * (b as f64 / a as f64 - 1.0)
        );
    }
    eprintln!("{table}");
    // At most 5 %, or 2 MiB: the allocator's high-water mark still rises when a loaded machine lets the
    // monitor lag (up to its 48-step window of pending steps), a bounded amount that cannot flake this
    // check; a leak of 300 bytes per step exceeds it over the 14 000-step run, one of 23 bytes over the
    // 100 000-step run.
    for r in ROLES {
        let (a, b) = (start[r].1, end[r].1);
        let allowed = (a as f64 * 0.05).max(2.0 * 1024.0 * 1024.0);
        assert!(b as f64 <= a as f64 + allowed, "{r}: private RSS grew by more than 5 % and 2 MiB:\n{table}");
    }

    // Every step recorded, nothing lost, nothing replayed or rejected.
    assert_eq!(run["steps"].as_array().unwrap().len() as u64, steps + 1);
    assert_eq!((run["restarts"].as_u64(), run["rejected"].as_u64()), (Some(0), Some(0)));
    let monitor = summary(&run, "monitor");
    assert_eq!(monitor["complete"], true, "{monitor}");
    assert_eq!(monitor["missing_messages"].as_u64(), Some(0), "{monitor}");
    // (A monitor starved of CPU may ask for a replay when it falls 3 steps behind; that loses nothing.)
    // Every planned step timed end to end (measurement published → command published) and at each hop
    // (the stamps ride the command: the last step has none), from its first copy (a replay's copies carry
    // no publish stamp). The end-to-end span contains the hops, so its median is at least theirs.
    let lat = &monitor["latency"];
    let stat = |h: &str, k: &str| lat[h][k].as_f64().unwrap_or_else(|| panic!("{h}.{k}: {lat}"));
    for timed in ["end_to_end", "measurement_hop", "estimate_hop"] {
        assert_eq!(lat[timed]["n"].as_u64(), Some(steps), "{timed}: {lat}");
    }
    for hop in ["measurement_hop", "estimate_hop"] {
        assert!(stat(hop, "p50_us") > 0.0 && stat(hop, "p50_us") <= stat("end_to_end", "p50_us"), "{hop}: {lat}");
    }
    let emitter = summary(&run, "emitter-sim");
    assert_eq!(emitter["steps"].as_u64(), Some(steps), "{emitter}");
    let estimator = summary(&run, "estimator");
    let fresh = |s: &Value| s["published"].as_u64().unwrap() - s["resent"].as_u64().unwrap();
    assert_eq!(fresh(estimator), steps + 1, "{estimator}");
    assert_eq!(estimator["out_of_chain"].as_u64(), Some(0), "{estimator}");
    let planner = summary(&run, "planner");
    assert_eq!(fresh(planner), steps, "{planner}");
    assert_nothing_left(&d);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn soak_flat_memory_and_no_lost_message() {
    let _scenario = common::scenario(module_path!());
    soak(14_000, 5_000);
}

/// 100 000 steps (about 25 s), alone (a scenario of its own).
#[test]
fn soak_100k_steps() {
    let _scenario = common::scenario(concat!(module_path!(), "::long"));
    soak(100_000, 5_000);
}

#[test]
fn a_crash_after_the_history_wrapped_resumes_from_the_states_the_messages_carry() {
    let _scenario = common::scenario(module_path!());
    const STEPS: u64 = 5_000;
    let d = domain("soak", "wrapped");
    let dir = scratch("soak-wrapped");
    let n = STEPS.to_string();
    // Slow enough to kill at chosen steps (≈ 2 ms per step).
    let mut launch = Launch::start(&d, &dir, &["--steps", &n, "--step-delay-ms", "1"]);
    let mut tail = LogTail::new(&launch.log);
    let mut killed = BTreeMap::new();
    for (role, at) in [("monitor", 4_200), ("estimator", 4_350), ("planner", 4_500), ("emitter-sim", 4_650)] {
        tail.wait_for(&mut launch, at, Duration::from_secs(120));
        // The previous victim's successor must be up before the next kill.
        let deadline = Instant::now() + Duration::from_secs(20);
        let pid = loop {
            if let Some(pid) = pid_of(&d, role) {
                break pid;
            }
            assert!(Instant::now() < deadline, "no {role} running");
            std::thread::sleep(Duration::from_millis(20));
        };
        kill(pid, libc::SIGKILL);
        killed.insert(role, (pid, at));
    }
    let stderr_path = launch.stderr.clone();
    let run = launch.finish_json();
    let stderr = std::fs::read_to_string(stderr_path).unwrap_or_default();
    assert_eq!(run["restarts"].as_u64(), Some(4), "{stderr}");
    for bad in ["AlreadyExists", "already exists", "Incompatible", "incompatible", "error:", "are kept"] {
        assert!(!stderr.contains(bad), "{bad:?} in:\n{stderr}");
    }
    // The restarted estimator and planner, which keep no state, asked for a replay (a `replay` event) of the
    // step in flight only; the estimator asked the monitor for the state after the step before it (a
    // `state_request` event), not for a replay from step 0 (which emitter-sim no longer has); and the
    // restarted emitter-sim flew on from a snapshot.
    let events = common::read_events(&dir.join("run.jsonl"));
    let asked = |event: &str, role: &str| -> Vec<u64> {
        events.iter().filter(|e| e["event"] == event && e["role"] == role).filter_map(|e| e["step"].as_u64()).collect()
    };
    let hellos = |role: &str| asked("replay", role);
    let at = killed["estimator"].1;
    let estimator = hellos("estimator");
    assert!(!estimator.is_empty() && estimator.iter().all(|&s| s == protocol::ControlKind::IN_FLIGHT), "{estimator:?}");
    let states = asked("state_request", "estimator");
    assert!(states.iter().any(|&s| s + 2 >= at && s <= at + 256), "estimator: state requests {states:?}");
    let planner = hellos("planner");
    assert!(planner.len() >= 2 && planner.iter().all(|&s| s == protocol::ControlKind::IN_FLIGHT), "{planner:?}");
    let emitter = summary(&run, "emitter-sim");
    let started = emitter["started_at"].as_u64().unwrap();
    assert!(started > 0 && started < killed["emitter-sim"].1, "{emitter}");
    assert_eq!(emitter["steps"].as_u64(), Some(STEPS - started), "{emitter}");

    // And the run is exactly simulate's.
    let sim = json_of(&["simulate", "--json", "--steps", &n]);
    assert_same_run(&sim, &run, "wrapped");
    assert_eq!(run["rejected"].as_u64(), Some(0));
    assert_nothing_left(&d);
    std::fs::remove_dir_all(&dir).ok();
}
