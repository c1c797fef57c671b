//! `uavloc launch --mode realtime --time-scale X`: emitter-sim flies at a rate (step k published at
//! t0 + k·dt/X). With every command in time the run equals `uavloc simulate` and honours the schedule; a
//! command that comes after the next step is due is missed — the UAVs fly the hold of a step without a
//! plan (one step of their backup circles, certified for the spacing), the monitor records the step as
//! `command_missed` with what was flown, a late command is ignored — and the run completes;
//! bad time scales are refused with exit code 2.
//!
//! Every launch runs in its own domain, so the tests run in parallel with each other and with the other
//! pipeline tests. Timing margins are wide (≥ 100 ms where the outcome depends on them): these are not
//! timing benchmarks.

use crate::common;

use std::time::{Duration, Instant};

use common::{assert_nothing_left, assert_same_run, json_of, read_events, scratch, uavloc};
use serde_json::Value;

fn domain(tag: &str) -> String {
    common::domain("realtime-test", tag)
}

/// Runs `uavloc launch --headless --json --domain D --log DIR/run.jsonl <extra>`; the run, its log and the
/// wall time.
fn launch(tag: &str, extra: &[&str]) -> (Value, Vec<Value>, Duration) {
    let d = domain(tag);
    let dir = scratch(&format!("realtime-{tag}"));
    let log = dir.join("run.jsonl");
    let mut args = vec!["launch", "--headless", "--json", "--domain", &d, "--log", log.to_str().unwrap()];
    args.extend_from_slice(extra);
    let start = Instant::now();
    let run = json_of(&args);
    let took = start.elapsed();
    let events = read_events(&log);
    assert_nothing_left(&d);
    std::fs::remove_dir_all(&dir).ok();
    (run, events, took)
}

/// The summary of the (only) emitter-sim of a launch.
fn emitter(run: &Value) -> &Value {
    let processes = run["processes"].as_array().unwrap();
    let all: Vec<&Value> = processes.iter().filter(|p| p["role"] == "emitter-sim").collect();
    assert_eq!(all.len(), 1, "{processes:?}");
    &all[0]["summary"]
}

fn is_missed(step: &Value) -> bool {
    step["active_constraints"].as_array().unwrap().iter().any(|c| c == "command_missed")
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect()
}

/// Checks every step recorded as missed: no plan, no planner, the headings of the hold of a step without
/// a plan (`planning::hold::without_plan` of the step's positions and current headings: one step of the
/// backup circles with the certified planner) with its certificate, and the next positions one arc of
/// `speed · dt` to those headings. Returns the missed steps; their number must be emitter-sim's
/// `missed_commands`.
fn check_missed_steps(run: &Value) -> Vec<u64> {
    let steps = run["steps"].as_array().unwrap();
    let sc: model::Scenario = serde_json::from_value(run["scenario"].clone()).unwrap();
    let (speed, dt) = (sc.speed, sc.dt);
    let same_angle =
        |a: f64, b: f64| (a - b + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
    let mut missed = Vec::new();
    for (k, s) in steps.iter().enumerate() {
        if !is_missed(s) {
            assert!(s["planner"].is_object() || k + 1 == steps.len(), "step {k} has no planner: {s}");
            continue;
        }
        missed.push(k as u64);
        assert_eq!(s["active_constraints"], serde_json::json!(["command_missed"]), "step {k}");
        assert!(s["objective_value"].is_null() && s["plan_ms"].is_null(), "step {k}: {s}");
        assert!(s["planner"].is_null(), "step {k}: {s}");
        assert!(k + 1 < steps.len(), "the last step is never planned, so never missed");
        let current = if k > 0 { floats(&steps[k - 1]["headings_rad"]) } else { sc.initial_headings() };
        let at = |step: &Value, i: usize| {
            let p = floats(&step["uavs"][i]);
            nalgebra::Vector2::new(p[0], p[1])
        };
        let positions: Vec<_> = (0..current.len()).map(|i| at(s, i)).collect();
        let hold = planning::hold::without_plan(&positions, &current, &sc);
        let headings = floats(&s["headings_rad"]);
        for (i, h) in headings.iter().enumerate() {
            assert!(same_angle(*h, hold.headings[i]).abs() < 1e-9, "step {k} UAV {i}: {h} vs the hold's {hold:?}");
            let expected = model::kinematics::next_position(positions[i], current[i], *h, speed, dt);
            assert!((at(&steps[k + 1], i) - expected).norm() < 1e-6, "step {k} UAV {i}: vs {expected:?}");
        }
        let certified = hold.safety.map(|r| r.certified);
        assert_eq!(s["safety"]["certified"].as_bool(), certified, "step {k}: {}", s["safety"]);
    }
    assert_eq!(emitter(run)["missed_commands"].as_u64(), Some(missed.len() as u64), "{}", emitter(run));
    assert_eq!(run["missed_commands"].as_u64(), Some(missed.len() as u64));
    missed
}

#[test]
fn with_every_command_in_time_the_run_equals_simulate_and_keeps_the_schedule() {
    let _scenario = common::scenario(module_path!());
    // 6 steps of 10 s at ×50: 0.2 s per step, 1.2 s in all; a command takes well under 10 ms.
    let (steps, scale) = (6u64, 50.0);
    let interval = Duration::from_secs_f64(10.0 / scale);
    let (run, events, took) =
        launch("in-time", &["--steps", "6", "--mode", "realtime", "--time-scale", "50", "--objective", "analytical"]);
    let sim = json_of(&["simulate", "--json", "--steps", "6", "--objective", "analytical"]);
    assert_same_run(&sim, &run, "realtime ×50");
    assert!(check_missed_steps(&run).is_empty());
    let e = emitter(&run);
    assert_eq!(e["mode"], "realtime");
    assert_eq!((e["steps"].as_u64(), e["late_commands"].as_u64()), (Some(steps), Some(0)), "{e}");
    assert_eq!((run["rejected"].as_u64(), run["restarts"].as_u64()), (Some(0), Some(0)));
    assert!(!events.iter().any(|e| e["event"] == "command_missed"));

    // The schedule is honoured: step k's measurement published (per its stamp, on the monotonic clock of
    // every process) at least k intervals after step 0's.
    eprintln!("a realtime run of {steps} steps at ×{scale} took {took:?}");
    let mut published = vec![None; steps as usize + 1];
    for m in events.iter().filter(|e| e["event"] == "message" && e["kind"] == "measurement") {
        let k = m["step"].as_u64().unwrap() as usize;
        let t = m["t_ns"].as_u64().unwrap() as f64 - m["age_us"].as_f64().unwrap() * 1e3;
        published[k].get_or_insert(t);
    }
    let published: Vec<f64> = published.into_iter().map(|t| t.expect("every measurement logged")).collect();
    for (k, t) in published.iter().enumerate() {
        let since = (t - published[0]) / 1e9;
        // Step 0 is stamped a few µs after t0; allow 1 ms for that.
        assert!(since >= (interval * k as u32).as_secs_f64() - 1e-3, "step {k} published {since} s after step 0");
    }
}

#[test]
fn a_slow_planner_misses_a_step_and_the_uavs_loiter_for_it() {
    let _scenario = common::scenario(module_path!());
    // ×50: 0.2 s per step. The planner sleeps 300 ms before planning step 2, so its command comes after step
    // 3 is due: step 2 is missed, the command is late (ignored), the other steps are flown as planned.
    let (run, events, _) = launch(
        "slow-planner",
        &[
            "--steps",
            "6",
            "--mode",
            "realtime",
            "--time-scale",
            "50",
            "--plan-delay-ms",
            "300",
            "--plan-delay-steps",
            "2",
        ],
    );
    let missed = check_missed_steps(&run);
    // 300 ms for a step of 200 ms: missed whatever the load (the other steps' cycles of about a
    // millisecond are in time on a machine that is not starved; `check_missed_steps` checks any that is not).
    assert!(missed.contains(&2), "step 2 must be missed: {missed:?}");
    // Certified, the hold loiters: every UAV turns onto its backup circle, certified for the spacing.
    let (h1, h2) = (floats(&run["steps"][1]["headings_rad"]), floats(&run["steps"][2]["headings_rad"]));
    assert!(h1.iter().zip(&h2).all(|(a, b)| (a - b).abs() > 1e-3), "step 2 flew straight on: {h1:?} → {h2:?}");
    assert_eq!(run["steps"][2]["safety"]["certified"], true, "{}", run["steps"][2]);
    let e = emitter(&run);
    assert!(e["late_commands"].as_u64().unwrap() >= 1, "step 2's command came late: {e}");
    assert_eq!(e["steps"].as_u64(), Some(6), "every interval flown: {e}");
    // The log names the missed step.
    let logged: Vec<u64> =
        events.iter().filter(|e| e["event"] == "command_missed").map(|e| e["step"].as_u64().unwrap()).collect();
    assert_eq!(logged, missed);
    let step2 = events.iter().find(|e| e["event"] == "step" && e["step"] == 2).unwrap();
    assert_eq!(step2["command_missed"], true);
    // Up to the first miss the run is simulate's; from there the world flew on without that step's plan.
    let sim = json_of(&["simulate", "--json", "--steps", "6"]);
    let first = missed[0] as usize;
    for k in 0..=first {
        assert_eq!(sim["steps"][k]["uavs"], run["steps"][k]["uavs"], "step {k}");
    }
    for k in 0..first {
        assert_eq!(sim["steps"][k]["headings_rad"], run["steps"][k]["headings_rad"], "step {k}");
    }
    assert_ne!(sim["steps"][3]["uavs"], run["steps"][3]["uavs"], "step 2's plan was not flown");
    // The run is complete and clean.
    assert_eq!(run["steps"].as_array().unwrap().len(), 7);
    assert_eq!((run["rejected"].as_u64(), run["restarts"].as_u64()), (Some(0), Some(0)));
}

#[test]
fn an_extreme_time_scale_misses_commands_and_completes() {
    let _scenario = common::scenario(module_path!());
    // ×1e6: 10 µs per step, far less than any cycle (the mc objective plans for milliseconds).
    let (run, _, _) =
        launch("extreme", &["--steps", "6", "--mode", "realtime", "--time-scale", "1e6", "--objective", "mc"]);
    let missed = check_missed_steps(&run);
    assert!(!missed.is_empty(), "{run}");
    assert_eq!(run["steps"].as_array().unwrap().len(), 7);
    assert_eq!(
        (run["objective"].as_str(), run["solver"].as_str()),
        (Some("mc"), Some("gradient")),
        "the default solver"
    );
    assert_eq!(run["restarts"].as_u64(), Some(0));
}

#[test]
fn a_crashed_estimator_is_restarted_and_replayed_to_between_the_steps() {
    let _scenario = common::scenario(module_path!());
    // ×10: 1 s per step. The estimator is killed mid-run; the launcher restarts it (≈ 0.1 s, a tenth of
    // the interval), it says hello and emitter-sim replays the run to it between two scheduled steps:
    // nothing is missed and the run is still simulate's.
    let d = domain("crash");
    let dir = scratch("realtime-crash");
    let mut launch = common::Launch::start(&d, &dir, &["--steps", "8", "--mode", "realtime", "--time-scale", "10"]);
    launch.wait_for_step(2, Duration::from_secs(30));
    let pid = common::pid_of(&d, "estimator").expect("the launch's estimator");
    common::kill(pid, libc::SIGKILL);
    let run = launch.finish_json();
    assert_eq!(run["restarts"].as_u64(), Some(1));
    assert!(check_missed_steps(&run).is_empty(), "{run}");
    assert!(emitter(&run)["replays"].as_u64().unwrap() >= 1, "{}", emitter(&run));
    let sim = json_of(&["simulate", "--json", "--steps", "8"]);
    assert_same_run(&sim, &run, "realtime estimator restart");
    assert_nothing_left(&d);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_time_scales_and_modes_are_refused() {
    let _scenario = common::scenario(module_path!());
    let d = domain("bad");
    for value in ["0", "-1", "-0.5", "nan", "inf", "-inf", "1e-320"] {
        for mode in ["realtime", "lockstep"] {
            if value == "1e-320" && mode == "lockstep" {
                continue; // tiny but valid: only a real-time schedule cannot represent it
            }
            let flag = format!("--time-scale={value}");
            let out = uavloc(&["launch", "--headless", "--steps", "2", "--mode", mode, &flag, "--domain", &d]);
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "{mode} {value}: {err}");
            assert!(err.contains("--time-scale") && err.starts_with("error:"), "{mode} {value}: {err}");
            // The process itself checks too.
            let out = uavloc(&["process", "emitter-sim", "--mode", mode, &flag, "--domain", &d]);
            assert_eq!(out.status.code(), Some(2), "emitter-sim {mode} {value}");
            assert!(String::from_utf8_lossy(&out.stderr).contains("--time-scale"));
        }
    }
    // A negative number after a space is a value too (and refused for what it is).
    let out = uavloc(&["launch", "--mode", "realtime", "--time-scale", "-2", "--domain", &d]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("finite number > 0"));
    // A valid time scale without --mode realtime (it would be silently ignored) is refused too, by the
    // launcher and by the process.
    for args in [
        &["launch", "--headless", "--steps", "2", "--time-scale", "100", "--domain", &d][..],
        &["launch", "--headless", "--steps", "2", "--mode", "lockstep", "--time-scale", "1", "--domain", &d],
        &["process", "emitter-sim", "--time-scale", "100", "--domain", &d],
    ] {
        let out = uavloc(args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("--time-scale applies to --mode realtime only"), "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{args:?}: {err}");
    }
    for args in [
        &["launch", "--mode", "fast", "--domain", &d][..],
        &["launch", "--mode", "realtime", "--time-scale", "x", "--domain", &d],
        &["launch", "--mode", "realtime", "--step-delay-ms", "5", "--domain", &d],
    ] {
        let out = uavloc(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
    }
    assert_nothing_left(&d);

    // --help explains both modes.
    let help = String::from_utf8_lossy(&uavloc(&["launch", "--help"]).stdout).to_string();
    for needle in ["--mode", "lockstep", "realtime", "--time-scale", "simulate", "command_missed"] {
        assert!(help.contains(needle), "launch --help lacks {needle:?}:\n{help}");
    }
}
