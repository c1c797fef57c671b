//! `uavloc bench latency|compare` and the socket transport: the real process set over both transports
//! and every wait mode. No timing is asserted (speed is what the benchmark reports, not what a test
//! checks); what is asserted is that the measurement is complete and coherent, and that the transport and
//! wait mode change nothing but the timing.

use crate::common;

use common::{assert_nothing_left, assert_same_run, json_of, scratch, uavloc};
use serde_json::Value;

fn domain(tag: &str) -> String {
    common::domain("bench-test", tag)
}

const SERIES_HOPS: [&str; 6] = [
    "emitter→estimator",
    "estimator→planner",
    "planner→emitter",
    "emitter→monitor",
    "estimator→monitor",
    "planner→monitor",
];
const STAGES: [&str; 3] = ["emitter-sim", "estimator", "planner"];

/// Percentiles present, ordered and with the expected sample count.
fn check_percentiles(p: &Value, n: u64, what: &str) {
    let get = |k: &str| p[k].as_f64().unwrap_or_else(|| panic!("{what}: {k} in {p}"));
    let (p50, p90, p99, p999, max) = (get("p50_us"), get("p90_us"), get("p99_us"), get("p999_us"), get("max_us"));
    assert!(0.0 < p50 && p50 <= p90 && p90 <= p99 && p99 <= p999 && p999 <= max, "{what}: {p}");
    assert_eq!(p["n"].as_u64(), Some(n), "{what}: samples");
}

fn check_run(run: &Value, steps: u64) {
    let label = format!("{} {}", run["transport"], run["wait"]);
    assert_eq!(run["lost"].as_u64(), Some(0), "{label}: lost");
    assert_eq!(run["steps"].as_u64(), Some(steps), "{label}");
    // Every planned step's command came back: one end-to-end sample per step.
    check_percentiles(&run["end_to_end"], steps, &format!("{label} end to end"));
    for h in SERIES_HOPS {
        // The last step is measured and estimated but not planned: no command, and its estimate's receipt
        // by the planner is stamped in no message.
        let n = if h.starts_with("planner") || h == "estimator→planner" { steps } else { steps + 1 };
        check_percentiles(&run["hops"][h], n, &format!("{label} hop {h}"));
    }
    for s in STAGES {
        // emitter-sim computes from a command (none before step 0), the planner not on the last step.
        let n = if s == "estimator" { steps + 1 } else { steps };
        check_percentiles(&run["compute"][s], n, &format!("{label} compute {s}"));
    }
    // End to end covers the planner's compute and both of its hops: its median cannot be below theirs.
    let e2e = run["end_to_end"]["p50_us"].as_f64().unwrap();
    assert!(e2e >= run["compute"]["planner"]["p50_us"].as_f64().unwrap(), "{label}");
    assert!(e2e >= run["hops"]["planner→emitter"]["p50_us"].as_f64().unwrap(), "{label}");
    for role in ["monitor", "planner", "estimator", "emitter-sim"] {
        assert!(run["cpu_s"][role].as_f64().unwrap() > 0.0, "{label}: cpu of {role}");
    }
    for role in ["monitor", "planner", "estimator"] {
        let idle = run["idle_cpu_pct"][role].as_f64().unwrap_or_else(|| panic!("{label}: idle cpu of {role}"));
        assert!((0.0..=200.0).contains(&idle), "{label}: idle cpu of {role} {idle}");
    }
}

#[test]
fn compare_measures_every_transport_and_wait_mode() {
    // Alone, not beside this module's other launches: six measured runs pinned to the same two cores
    // as two other pipelines starved the monitor (a flaky sample count).
    let _scenario = common::scenario(concat!(module_path!(), "::compare"));
    let dir = scratch("bench-compare");
    let steps = 150u64;
    let out = uavloc(&[
        "bench",
        "compare",
        "--steps",
        &steps.to_string(),
        "--rounds",
        "1",
        "--idle-ms",
        "50",
        "--json",
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report: Value = serde_json::from_slice(&out.stdout).unwrap();
    let runs = report["runs"].as_array().unwrap();
    let mut seen: Vec<(String, String)> =
        runs.iter().map(|r| (r["transport"].as_str().unwrap().into(), r["wait"].as_str().unwrap().into())).collect();
    seen.sort();
    let mut expected = Vec::new();
    for t in ["iceoryx2", "uds"] {
        for w in ["block", "spin", "spin-then-block"] {
            expected.push((t.to_string(), w.to_string()));
        }
    }
    assert_eq!(seen, expected);
    for r in runs {
        check_run(r, steps);
    }
    // The ratios are the ratios of the reported percentiles.
    let ratios = report["ratios"].as_array().unwrap();
    assert_eq!(ratios.len(), 3);
    for r in ratios {
        let w = r["wait"].as_str().unwrap();
        let find = |t: &str| runs.iter().find(|x| x["transport"] == t && x["wait"] == w).unwrap();
        for (k, key) in [("p50", "p50_us"), ("p99", "p99_us"), ("max", "max_us")] {
            let expect = find("iceoryx2")["end_to_end"][key].as_f64().unwrap()
                / find("uds")["end_to_end"][key].as_f64().unwrap();
            assert!((r[k].as_f64().unwrap() - expect).abs() < 1e-9 * expect.abs().max(1.0), "{w} {k}");
        }
    }
    let goals = report["goals"].as_array().unwrap();
    assert!(goals.iter().any(|g| g["goal"].as_str().unwrap().contains("iceoryx2 ahead of uds")));
    assert!(goals.iter().all(|g| g["met"].is_boolean() && g["detail"].is_string()));
    // The files: one CSV per run and series, the plots and the summary.
    for t in ["iceoryx2", "uds"] {
        for w in ["block", "spin", "spin-then-block"] {
            let csv = std::fs::read_to_string(dir.join(format!("{t}-{w}-end_to_end.csv"))).unwrap();
            let mut lines = csv.lines();
            assert_eq!(lines.next(), Some("value_us,count,cumulative_count,percentile"));
            let counts: u64 = lines.map(|l| l.split(',').nth(1).unwrap().parse::<u64>().unwrap()).sum();
            assert_eq!(counts, steps, "{t} {w}: histogram CSV holds every sample");
            let stamps = std::fs::read_to_string(dir.join(format!("{t}-{w}-stamps.csv"))).unwrap();
            assert_eq!(stamps.lines().count() as u64, steps + 2, "{t} {w}: the header and a row per step");
        }
    }
    assert!(std::fs::read_to_string(dir.join("end_to_end.svg")).unwrap().contains("uds spin"));
    let png = record::png::read(&dir.join("end_to_end.png")).unwrap();
    assert!(png.width > 100 && png.height > 100);
    let summary: Value = serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["runs"].as_array().unwrap().len(), 6);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn latency_over_sockets_with_a_text_report() {
    let _scenario = common::scenario(module_path!());
    let out = uavloc(&["bench", "latency", "--transport", "uds", "--wait", "spin-then-block", "--steps", "100"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8_lossy(&out.stdout);
    for needle in [
        "online CPU(s)",
        "uds spin-then-block",
        "end to end",
        "hop planner→emitter",
        "compute planner",
        "CPU:",
        "goals",
    ] {
        assert!(text.contains(needle), "{needle} missing in:\n{text}");
    }
    let json = json_of(&["bench", "latency", "--transport", "uds", "--steps", "60", "--idle-ms", "20", "--json"]);
    assert_eq!(json["runs"].as_array().unwrap().len(), 1);
    common::assert_names_the_machine(&json);
    check_run(&json["runs"][0], 60);
}

#[test]
fn the_transport_and_wait_mode_change_nothing_but_timing() {
    let _scenario = common::scenario(module_path!());
    let sim = json_of(&["simulate", "--json", "--steps", "8"]);
    for (transport, wait) in [("uds", "block"), ("uds", "spin"), ("iceoryx2", "spin-then-block")] {
        let d = domain(&format!("{transport}-{wait}"));
        let run = json_of(&[
            "launch",
            "--headless",
            "--json",
            "--steps",
            "8",
            "--domain",
            &d,
            "--transport",
            transport,
            "--wait",
            wait,
        ]);
        assert_same_run(&sim, &run, &format!("{transport} {wait}"));
        assert_eq!(run["rejected"].as_u64(), Some(0));
        assert_nothing_left(&d);
    }
}

#[test]
fn bad_bench_flags_exit_2_with_one_line() {
    let _scenario = common::scenario(module_path!());
    for args in [
        vec!["bench", "latency", "--cores", "99999"],
        vec!["bench", "latency", "--cores", "1-0"],
        vec!["bench", "latency", "--cores", ""],
        vec!["bench", "latency", "--steps", "0"],
        vec!["bench", "latency", "--transport", "tcp"],
        vec!["bench", "latency", "--wait", "busy"],
        vec!["bench", "latency", "--objective", "fastest"],
        vec!["bench", "latency", "--scenario", "/nonexistent/scenario.toml"],
        vec!["bench", "compare", "--rounds", "0"],
        vec!["bench", "compare", "--steps", "3", "--rounds", "4"],
        vec!["launch", "--transport", "pigeon"],
    ] {
        let out = uavloc(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
        let err = String::from_utf8_lossy(&out.stderr);
        let errors: Vec<&str> = err.lines().filter(|l| l.starts_with("error:")).collect();
        assert_eq!(errors.len(), 1, "{args:?}: {err}");
        // The line names the flag at fault: the last one given (`--rounds` for steps fewer than rounds).
        let flag = args.iter().rev().find(|a| a.starts_with("--")).unwrap();
        assert!(errors[0].contains(flag), "{args:?}: {} does not name {flag}", errors[0]);
        assert!(out.stdout.is_empty(), "{args:?}");
    }
}

#[test]
fn bench_help_answers_what_is_measured() {
    let _scenario = common::scenario(module_path!());
    let out = uavloc(&["bench", "latency", "--help"]);
    let text = String::from_utf8_lossy(&out.stdout);
    for needle in ["--cores", "--transport", "--wait", "--steps", "--out", "p99.9", "end to end", "CPU", "lost"] {
        assert!(text.contains(needle), "{needle} missing in bench latency --help");
    }
    let out = uavloc(&["bench", "--help"]);
    let text = String::from_utf8_lossy(&out.stdout);
    for needle in ["latency", "compare", "planner", "BENCHMARKS.md"] {
        assert!(text.contains(needle), "{needle} missing in bench --help");
    }
}
