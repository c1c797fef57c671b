//! Lock-step backpressure: a lock-step emitter-sim runs at most `--monitor-window` (48) steps ahead of the
//! monitor's progress (the monitor reports the first step it lacks on the control topic every 16 recorded
//! steps). The monitor of a launch is frozen (SIGSTOP) for 3 s: emitter-sim — watched by a subscriber of
//! the measurement topic of this test — publishes no step beyond 48 after the monitor's newest logged
//! one, and no new step at all in the last seconds of the freeze, although the whole run would take a
//! fraction of that. Thawed, the monitor catches up and the run ends complete and equal to
//! `uavloc simulate`, every step logged once, with nothing restarted.

use crate::common;

use std::time::{Duration, Instant};

use common::{Launch, domain, kill, pid_of, scratch};
use protocol::services::{self, Domain};
use protocol::{Measurement, Topic, TopicSubscriber};

const STEPS: u64 = 600;
const WINDOW: u64 = runtime::recovery::MONITOR_WINDOW;

/// The newest step `sub` receives in the next `how_long`, the newest it had received `quiet` before the
/// end, and how many measurements it received.
fn newest_step(sub: &TopicSubscriber<Measurement>, how_long: Duration, quiet: Duration) -> (u64, u64, usize) {
    let start = Instant::now();
    let (mut newest, mut early, mut received) = (0, 0, 0);
    while start.elapsed() < how_long {
        for m in sub.receive_all().expect("receive") {
            newest = newest.max(m.header.step);
            received += 1;
        }
        if start.elapsed() + quiet < how_long {
            early = newest;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    (newest, early, received)
}

#[test]
fn a_frozen_monitor_holds_emitter_sim_within_the_window() {
    let _scenario = common::scenario(module_path!());
    let d = domain("backpressure", "frozen");
    let dir = scratch("backpressure-frozen");
    let steps = STEPS.to_string();
    let mut launch = Launch::start(&d, &dir, &["--steps", &steps, "--command-timeout-s", "20"]);
    launch.wait_for_step(20, Duration::from_secs(60));
    let node = protocol::Link::open(protocol::TransportKind::Iceoryx2, &format!("{d}-observer")).unwrap();
    let sub = Topic::<Measurement>::subscriber(&node, &services::measurement(&Domain::new(&d).unwrap())).unwrap();

    let monitor = pid_of(&d, "monitor").expect("a monitor");
    kill(monitor, libc::SIGSTOP);
    std::thread::sleep(Duration::from_millis(100));
    let logged = launch
        .events()
        .iter()
        .filter(|e| e["event"] == "step")
        .filter_map(|e| e["step"].as_u64())
        .max()
        .expect("steps logged");
    // Held for 3 s; no new step in the last 1.5 s (replays to the frozen monitor re-publish older ones).
    let (newest, early, received) = newest_step(&sub, Duration::from_secs(3), Duration::from_millis(1500));
    kill(monitor, libc::SIGCONT);
    eprintln!("backpressure: the monitor had logged step {logged}; emitter-sim published up to step {newest}");
    assert!(logged + WINDOW < STEPS, "the monitor was stopped too late (step {logged})");
    // The observer heard emitter-sim during the freeze (its replays to the frozen monitor), so the window
    // checks below are about what it published, not about an observer that heard nothing.
    assert!(received >= 1 && newest + WINDOW >= logged, "the observer received {received}, newest step {newest}");
    assert!(newest <= logged + WINDOW, "emitter-sim published step {newest}, the monitor had logged {logged}");
    assert_eq!(newest, early, "emitter-sim went on late in the freeze");
    drop(sub);
    drop(node);

    let stderr_path = launch.stderr.clone();
    let run = launch.finish_json();
    let stderr = std::fs::read_to_string(stderr_path).unwrap_or_default();
    assert_eq!(run["restarts"].as_u64(), Some(0), "{stderr}");
    assert!(!stderr.contains("error:"), "{stderr}");
    let emitter = run["processes"].as_array().unwrap().iter().find(|p| p["role"] == "emitter-sim").unwrap();
    // It replayed to the frozen monitor (no progress for the retry interval).
    assert!(emitter["summary"]["retries"].as_u64().unwrap() >= 1, "{emitter}");
    common::assert_complete_run_equals_simulate(&run, &dir, &d, STEPS, "backpressure");
    std::fs::remove_dir_all(&dir).ok();
}
