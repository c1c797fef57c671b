//! End-to-end test of `uavloc bench planner`: the real binary, its JSON (one entry per objective × solver,
//! consistent order statistics, the reference ratio, the paper's Table 7 numbers beside the PSO rows) and
//! its exit code on bad input. No assertion is made on how fast anything is.

use std::process::Command;

use serde_json::Value;

struct Output {
    code: i32,
    stdout: String,
    stderr: String,
}

fn uavloc(args: &[&str]) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_uavloc")).args(args).output().expect("run the uavloc binary");
    Output {
        code: out.status.code().expect("exit code (not killed by a signal)"),
        stdout: String::from_utf8(out.stdout).expect("UTF-8 stdout"),
        stderr: String::from_utf8(out.stderr).expect("UTF-8 stderr"),
    }
}

fn num(v: &Value, key: &str) -> f64 {
    v[key].as_f64().unwrap_or_else(|| panic!("{key} is not a number in {v}"))
}

#[test]
fn bench_planner_json_has_every_combination() {
    let _scenario = crate::common::scenario(module_path!());
    let out = uavloc(&[
        "bench",
        "planner",
        "--steps",
        "5",
        "--objective",
        "analytical,single",
        "--solver",
        "pso,ga",
        "--json",
    ]);
    assert_eq!(out.code, 0, "stderr: {}", out.stderr);
    let v: Value =
        serde_json::from_str(&out.stdout).unwrap_or_else(|e| panic!("stdout is not JSON only ({e}): {}", out.stdout));
    assert_eq!(v["steps"], 5);
    let repeats = v["repeats"].as_u64().expect("repeats");
    assert_eq!(repeats, 1);
    assert_eq!(v["reference"], "analytical/pso");
    crate::common::assert_names_the_machine(&v);

    let combos = v["combinations"].as_array().expect("combinations");
    assert_eq!(combos.len(), 4, "{combos:?}");
    let mut names: Vec<String> = combos
        .iter()
        .map(|c| format!("{}/{}", c["objective"].as_str().unwrap(), c["solver"].as_str().unwrap()))
        .collect();
    names.sort();
    assert_eq!(names, ["analytical/ga", "analytical/pso", "single/ga", "single/pso"]);

    for c in combos {
        let label = format!("{}/{}", c["objective"], c["solver"]);
        assert_eq!(c["n"].as_u64(), Some(5 * repeats), "{label}");
        let (median, p90, p99, max, mean) =
            (num(c, "median_ms"), num(c, "p90_ms"), num(c, "p99_ms"), num(c, "max_ms"), num(c, "mean_ms"));
        assert!(median > 0.0 && median <= p90 && p90 <= p99 && p99 <= max, "{label}: {c}");
        assert!(mean > 0.0 && mean <= max, "{label}: {c}");
        assert!(num(c, "ratio_to_reference") > 0.0, "{label}");
        let pso = c["solver"] == "pso";
        for key in ["paper_total_mean_ms", "paper_opt_ms"] {
            assert!(c.get(key).is_some(), "{label}: no {key}");
            if pso {
                assert!(num(c, key) > 0.0, "{label}: {key}");
            } else {
                assert!(c[key].is_null(), "{label}: {key} should be null");
            }
        }
    }
    let find = |o: &str, s: &str| combos.iter().find(|c| c["objective"] == o && c["solver"] == s).unwrap();
    let reference = find("analytical", "pso");
    assert_eq!(num(reference, "ratio_to_reference"), 1.0);
    // Paper Table 7, total mean per step: analytical 0.15202 s, single 0.03131 s.
    assert!((num(reference, "paper_total_mean_ms") - 152.02).abs() < 1e-6);
    assert!((num(find("single", "pso"), "paper_total_mean_ms") - 31.31).abs() < 1e-6);
}

#[test]
fn bench_planner_bad_flag_exits_2_with_one_error_line() {
    let _scenario = crate::common::scenario(module_path!());
    for (args, flag) in [
        (&["bench", "planner", "--steps", "0"][..], "--steps"),
        (&["bench", "planner", "--steps", "2", "--objective", "fastest"][..], "--objective"),
    ] {
        let out = uavloc(args);
        assert_eq!(out.code, 2, "{args:?}: stdout {} stderr {}", out.stdout, out.stderr);
        let lines: Vec<&str> = out.stderr.lines().filter(|l| !l.trim().is_empty()).collect();
        assert_eq!(lines.len(), 1, "{args:?}: {}", out.stderr);
        assert!(lines[0].starts_with("error:") && lines[0].contains(flag), "{args:?}: {}", lines[0]);
        assert!(out.stdout.is_empty(), "{args:?}: {}", out.stdout);
    }
}
