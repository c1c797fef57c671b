//! Two UAVs flown into each other: the world cannot measure a geometry with two UAVs on one point, so the
//! run cannot go on. emitter-sim exits with code 3 (unrecoverable) and `uavloc launch` fails at once with
//! its error — no restart (a restarted emitter-sim would fly into the same collision), nothing left.
//!
//! The collision is forced with the real processes: two UAVs 1000 m apart head at each other at 50 m/s
//! for 10 s steps, and the planner is slowed down (`--plan-delay-ms`) in a real-time run, so its first
//! command misses its step. With the paper's waypoint planner (`safety = "waypoints"`) a step without a
//! plan holds course, so the UAVs fly straight on — into the same point. (The certified planner's hold
//! would loiter them on their backup circles: `realtime.rs`.)

use crate::common;

use common::{assert_nothing_left, domain, read_events, scratch, uavloc};

#[test]
fn uavs_flown_into_each_other_end_the_launch_at_once_with_a_clear_error() {
    let _scenario = common::scenario(module_path!());
    let d = domain("collision", "head-on");
    let dir = scratch("collision-head-on");
    let scenario = dir.join("head_on.toml");
    std::fs::write(
        &scenario,
        "uavs = [[0.0, 0.0], [1000.0, 0.0], [0.0, 6000.0]]\n\
         headings_deg = [0.0, 180.0, 0.0]\n\
         emitter = [20000.0, 15000.0]\n\
         steps = 6\n\
         safety = \"waypoints\"\n",
    )
    .unwrap();
    let log = dir.join("run.jsonl");
    let out = uavloc(&[
        "launch",
        "--headless",
        "--json",
        "--domain",
        &d,
        "--log",
        log.to_str().unwrap(),
        "--scenario",
        scenario.to_str().unwrap(),
        "--mode",
        "realtime",
        "--time-scale",
        "100",
        "--plan-delay-ms",
        "400",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("step 1: measurement: cannot measure: UAV 0 and UAV 1 coincide"), "{stderr}");
    assert!(stderr.contains("the run cannot go on"), "{stderr}");
    assert!(stderr.contains("the emitter-sim process stopped unexpectedly (exit code 3)"), "{stderr}");
    // Not restarted: no restart warning and no restart event in the log.
    assert!(!stderr.contains("restarting it"), "{stderr}");
    assert!(!read_events(&log).iter().any(|e| e["event"] == "restart"), "a restart was logged");
    assert_nothing_left(&d);
    std::fs::remove_dir_all(&dir).ok();
}
