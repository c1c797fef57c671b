//! Aircraft over MAVLink: `uavloc launch --autopilot …` with simulated fixed-wing autopilots that speak
//! real MAVLink 2 (`examples/python/sim_autopilot.py`, pymavlink; one process per UAV, time-scaled), the
//! MAVLink bridge between them and the pipeline. The run localises the emitter within the error of
//! `simulate` on the same scenario, with the bridge killed once mid-run and one UAV's link dropped for
//! a few seconds; and the bridge's bad inputs — an endpoint it cannot open, an autopilot that never arms,
//! one that reports another system id or a position 100 km off — end in a clear error, never a command
//! sent from a bad state.

use crate::common;

use std::time::Duration;

use common::autopilots::{Autopilots, GEO, TIME_SCALE, endpoints, ports};
use std::path::Path;
use std::process::Command;

use common::{Launch, domain, json_of, kill, pid_of, scratch, uavloc};
use serde_json::Value;

fn summary_of<'a>(run: &'a Value, role: &str) -> Vec<&'a Value> {
    run["processes"].as_array().unwrap().iter().filter(|p| p["role"] == role).map(|p| &p["summary"]).collect()
}

#[test]
fn simulated_autopilots_fly_the_plan_to_a_fix_through_a_bridge_killed_once_and_a_dropped_link() {
    let _scenario = common::scenario(module_path!());
    let dir = scratch("flying");
    let ports = ports(0);
    // UAV 1's link drops 7 s (wall) after its first target for 3 s: both ways, while it flies on. UAV 2
    // sends a NaN yaw in every ATTITUDE (refused and counted; its heading comes from its fixes).
    let _aircraft = Autopilots::start(ports, [&[], &["--drop-at", "7", "--drop-for", "3"], &["--nan-yaw"]], &dir);
    let d = domain("fly", "e2e");
    let file = dir.join("run.mcap");
    let mut flags =
        vec!["--scenario", GEO, "--mode", "realtime", "--time-scale", TIME_SCALE, "--record", file.to_str().unwrap()];
    let eps = endpoints(ports);
    flags.extend(eps.iter().map(String::as_str));
    let mut launch = Launch::start(&d, &dir, &flags);
    launch.wait_for_step(2, Duration::from_secs(60));
    // A foreign client reads the swarm state as a receiver front end on aircraft would: iceoryx2's
    // official Python bindings, the ctypes layout of examples/python/uavloc_messages.py.
    let reader = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/python/read_swarm.py");
    let out = Command::new(common::python()).arg(reader).args(["--domain", &d, "--seconds", "1"]).output().unwrap();
    let swarm: Value = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("not JSON ({e}): {}", String::from_utf8_lossy(&out.stderr)));
    assert!(swarm["states"].as_u64().unwrap() >= 5, "about 10 a second: {swarm}");
    for (i, u) in swarm["uavs"].as_array().unwrap().iter().enumerate() {
        assert_eq!(u["link"], "flying", "UAV {i}: {swarm}");
        assert!(u["fix_age_s"].as_f64().unwrap() < 0.5, "UAV {i}: a fresh fix: {swarm}");
        let lat = u["lat_lon_deg"][0].as_f64().unwrap();
        assert!((47.39..47.6).contains(&lat), "UAV {i} over the scenario's area: {swarm}");
    }
    launch.wait_for_step(5, Duration::from_secs(60));
    let bridge = pid_of(&d, "bridge").expect("the bridge runs");
    kill(bridge, libc::SIGKILL);
    let log = launch.log.clone();
    let run = launch.finish_json();
    // The monitor logged the links as the bridge reported them (what the live view shows): UAV 1 quiet
    // during its drop, and flying again after it.
    let links: Vec<(u64, String)> = common::read_events(&log)
        .iter()
        .filter(|e| e["event"] == "link" && e["uav"] == 1)
        .map(|e| (e["step"].as_u64().unwrap(), e["state"].as_str().unwrap().to_string()))
        .collect();
    let quiet = links.iter().position(|(_, s)| s == "quiet").unwrap_or_else(|| panic!("no quiet link: {links:?}"));
    assert!(links[quiet + 1..].iter().any(|(_, s)| s == "flying"), "back after the drop: {links:?}");

    let steps = run["steps"].as_array().unwrap();
    assert_eq!(steps.len(), 25, "every step of the scenario");
    let flown = steps.last().unwrap()["estimate_error_m"].as_f64().unwrap();
    let simulated =
        json_of(&["simulate", "--json", "--scenario", GEO])["steps"][24]["estimate_error_m"].as_f64().unwrap();
    // Not bit-equal (real time, the autopilots' own turns), but the same localisation: the initial error
    // is ≈ 820 m, simulate ends at ≈ 131 m.
    eprintln!("flying: terminal error flown {flown:.1} m, simulated {simulated:.1} m");
    assert!(flown < 2.0 * simulated + 20.0, "flown {flown:.1} m vs simulated {simulated:.1} m");
    // The bridge was restarted once (the killed one left no summary); the restarted one flew targets.
    let bridges = summary_of(&run, "bridge");
    assert_eq!(bridges.len(), 2, "killed once, restarted once: {}", run["processes"]);
    assert!(bridges[0].is_null(), "SIGKILL: no summary");
    let bridges = &bridges[1..];
    assert!(bridges[0]["links"][0]["targets_sent"].as_u64().unwrap() > 0, "{bridges:?}");
    // The dropped link: the bridge saw it go quiet, emitter-sim did not hear that UAV for some steps.
    let quiet: u64 = bridges.iter().map(|b| b["links"][1]["quiet_periods"].as_u64().unwrap()).sum();
    assert!(quiet >= 1, "UAV 1's link went quiet: {bridges:?}");
    let unheard = summary_of(&run, "emitter-sim")[0]["unheard_uav_steps"].as_u64().unwrap();
    assert!(unheard >= 1, "steps without UAV 1's arrival");
    let missing: Vec<u64> = steps
        .iter()
        .filter(|s| s["receiver"]["heard"].as_array().is_some_and(|h| !h.iter().any(|u| u == 1)))
        .map(|s| s["step"].as_u64().unwrap())
        .collect();
    assert!(!missing.is_empty(), "the record shows the steps UAV 1 was not heard");
    eprintln!("flying: UAV 1 not heard at steps {missing:?}");
    // Those steps state UAV 1's position with the σ of how far it may have flown since its last fix
    // (≥ 1.5 s · 20 · 50 m/s = 1.5 km of reach, σ = reach / (5 √2)), which the planner's margins take.
    let recording = record::recording::read_recording(&file).unwrap();
    for m in recording.messages.iter().filter(|m| m.topic == "/measurement") {
        let step = m.json["step"].as_u64().unwrap();
        let sigma = m.json["position_sigmas"][1].as_f64().unwrap();
        if missing.contains(&step) {
            assert!(sigma >= 1_500.0 / (5.0 * 2f64.sqrt()) - 1.0, "step {step}: UAV 1 stated σ {sigma}");
        } else {
            assert_eq!(sigma, 0.0, "step {step}: a fresh fix is exact");
        }
    }
    let nan_yaws: u64 = bridges.iter().map(|b| b["links"][2]["rejected"].as_u64().unwrap()).sum();
    assert!(nan_yaws > 10, "UAV 2's NaN yaws refused and counted: {bridges:?}");
    // The UAVs flew: step 24's positions are kilometres from the starts, as the plan takes them.
    let moved =
        (steps[24]["uavs"][0][0].as_f64().unwrap() - 1500.0).hypot(steps[24]["uavs"][0][1].as_f64().unwrap() - 500.0);
    assert!(moved > 5_000.0, "UAV 0 flew {moved:.0} m");
    std::fs::remove_dir_all(&dir).ok();
}

/// The bridge alone against bad peers: each a clear error (exit code, the UAV and why) within its ready
/// timeout, and no target ever sent to the bad autopilot (it counts the targets it gets).
#[test]
fn the_bridge_refuses_bad_autopilots_with_a_clear_error() {
    let _scenario = common::scenario(module_path!());
    let dir = scratch("flying-bad");
    let d = domain("fly", "bad");
    // An endpoint it cannot open: a TCP peer that refuses.
    let out = uavloc(&[
        "process",
        "bridge",
        "--domain",
        &d,
        "--scenario",
        GEO,
        "--autopilot",
        "tcpout:127.0.0.1:1",
        "--autopilot",
        "udpin:127.0.0.1:0",
        "--autopilot",
        "udpin:127.0.0.1:0",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("tcpout:127.0.0.1:1") && err.contains("UAV 0"), "{err}");
    // No origin: the bridge cannot place a target.
    let out = uavloc(&[
        "process",
        "bridge",
        "--domain",
        &d,
        "--autopilot",
        "udpin:127.0.0.1:0",
        "--autopilot",
        "udpin:127.0.0.1:0",
        "--autopilot",
        "udpin:127.0.0.1:0",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("[origin]"));

    // The launch checks its aircraft flags before anything starts.
    for (flags, says) in [
        (vec!["--mode", "realtime"], "[origin]"),
        (
            vec!["--scenario", GEO, "--autopilot", "udpin:127.0.0.1:1", "--autopilot", "udpin:127.0.0.1:2"],
            "--mode realtime",
        ),
        (vec!["--scenario", GEO, "--mode", "realtime", "--autopilot", "udpin:127.0.0.1:1"], "given 2 time(s)"),
    ] {
        let mut args = vec!["launch", "--headless", "--autopilot", "udpin:127.0.0.1:0"];
        args.extend(flags);
        let out = uavloc(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
    }
    for (case, (bad, says)) in [
        (&["--never-arm"][..], "never armed"),
        (&["--system-id-sent", "7"][..], "system 7"),
        (&["--offset-m", "100000"][..], "m from the scenario's start"),
    ]
    .into_iter()
    .enumerate()
    {
        let ports = ports(1 + case as u16);
        let aircraft = Autopilots::start(ports, [&[], bad, &[]], &dir);
        let mut args = vec![
            "process",
            "bridge",
            "--domain",
            &d,
            "--scenario",
            GEO,
            "--ready-timeout-ms",
            "3000",
            "--time-scale",
            TIME_SCALE,
        ];
        let eps = endpoints(ports);
        args.extend(eps.iter().map(String::as_str));
        let started = std::time::Instant::now();
        let out = uavloc(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{bad:?}: {err}");
        assert!(err.contains("UAV 1") && err.contains(says), "{bad:?}: {err}");
        assert!(started.elapsed() < Duration::from_secs(15), "no hang");
        drop(aircraft);
        // The bad autopilot got no target (and none came before any command: there was none).
        let report: Value =
            serde_json::from_str(std::fs::read_to_string(dir.join("autopilot1.out")).unwrap().trim()).unwrap();
        assert_eq!(report["targets"], 0, "{bad:?}: {report}");
    }
    std::fs::remove_dir_all(&dir).ok();
}
