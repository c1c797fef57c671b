//! `uavloc paper`: the paper's experiments through the documented CLI with the `--quick` preset
//! (M = 20). One `all --quick --json` run is checked against robust expectations:
//! every planned objective beats the fixed formation at the terminal step (every solver), the
//! fixed-geometry RMSE/CRLB ratio stays within 0.9–1.15 with the CRLB exactly linear in the noise scale,
//! the criteria are compared against the deterministic quadrature, the paired differences are coherent
//! intervals, the paper's numbers are carried beside ours, and every setting is stated. Also: results
//! do not depend on the thread count, `--out` writes readable files, bad input exits 2.

use crate::common;

use std::sync::OnceLock;

use common::{UAVLOC, json_of, scratch, uavloc};
use serde_json::Value;

/// `uavloc paper all --quick --json`, run once for the whole test binary.
fn all_quick() -> &'static Value {
    static ALL: OnceLock<Value> = OnceLock::new();
    ALL.get_or_init(|| json_of(&["paper", "all", "--quick", "--json"]))
}

fn experiment(name: &str) -> &'static Value {
    let all = all_quick();
    assert_eq!(all["experiment"], "all");
    all["experiments"]
        .as_array()
        .expect("experiments")
        .iter()
        .find(|e| e["experiment"] == name)
        .unwrap_or_else(|| panic!("no experiment {name}"))
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

fn interval(v: &Value) -> [f64; 3] {
    let a = v.as_array().unwrap_or_else(|| panic!("not an interval: {v}"));
    assert_eq!(a.len(), 3, "{v}");
    [f(&a[0]), f(&a[1]), f(&a[2])]
}

#[test]
fn all_experiments_run_in_order_with_their_settings() {
    let _scenario = common::scenario(module_path!());
    let names: Vec<&str> =
        all_quick()["experiments"].as_array().unwrap().iter().map(|e| e["experiment"].as_str().unwrap()).collect();
    assert_eq!(
        names,
        ["table2", "table4", "table5", "table6", "table7", "table8", "table9", "table10", "optimizers", "sensitivity"]
    );
    for name in names {
        let e = experiment(name);
        let s = &e["settings"];
        assert_eq!(s["runs_m"], 20, "{name}: --quick is M = 20");
        assert_eq!(s["resamples_r"], 30, "{name}");
        assert_eq!(s["mc_samples_k"], 200, "{name}");
        assert_eq!(s["scenario"]["pso"]["particles"], 40, "{name}");
        assert_eq!(s["scenario"]["pso"]["iterations"], 15, "{name}");
        assert!(s["chosen_not_stated_by_paper"].as_array().is_some_and(|a| a.len() >= 5), "{name}");
        assert!(!e["rows"].as_array().unwrap().is_empty(), "{name}: rows");
        assert!(!e["conclusions"].as_array().unwrap().is_empty(), "{name}: conclusions");
    }
}

#[test]
fn table2_rows_have_the_papers_columns_and_paired_differences() {
    let _scenario = common::scenario(module_path!());
    let t = experiment("table2");
    let rows = t["rows"].as_array().unwrap();
    let methods: Vec<&str> = rows.iter().map(|r| r["method"].as_str().unwrap()).collect();
    assert_eq!(methods, ["formation", "single", "mc", "analytical"]);
    let formation_final = f(&rows[0]["final_crlb_m"]);
    for r in rows {
        for key in ["mean_crlb_m", "final_crlb_m", "ci95_crlb_m", "mean_rmse_m", "final_rmse_m", "ci95_rmse_m"] {
            assert!(f(&r[key]).is_finite() && f(&r[key]) >= 0.0, "{}: {key}", r["method"]);
        }
        // The mean over a run that starts at the initial CRLB (1655.58 m) lies above the terminal value.
        assert!(f(&r["mean_crlb_m"]) > f(&r["final_crlb_m"]));
        let d = &r["diff_vs_single"];
        for key in ["final_crlb_m", "final_rmse_m", "mean_crlb_m", "mean_rmse_m"] {
            let [lo, mid, hi] = interval(&d[key]);
            assert!(lo <= mid && mid <= hi, "{}: {key} {lo} {mid} {hi}", r["method"]);
        }
        if r["method"] == "single" {
            // Paired with itself: exactly zero.
            assert_eq!(interval(&d["final_crlb_m"]), [0.0, 0.0, 0.0]);
        } else {
            // diff = method − single, on the same seeds.
            let mid = interval(&d["final_crlb_m"])[1];
            assert!((mid - (f(&r["final_crlb_m"]) - f(&rows[1]["final_crlb_m"]))).abs() < 1e-9);
        }
        if r["method"] != "formation" {
            assert!(f(&r["final_crlb_m"]) < formation_final, "{} must beat the formation", r["method"]);
        }
    }
    // The output states whether the paper's ordering holds, one way or the other.
    let c: Vec<&str> = t["conclusions"].as_array().unwrap().iter().map(|c| c.as_str().unwrap()).collect();
    assert!(c.iter().any(|s| s.contains("The paper's ordering")), "{c:?}");
    // The MC criterion's effective sample size is reported.
    assert!(f(&rows[2]["criterion_ess_median"]) >= 1.0);
    assert!(rows[3]["criterion_ess_median"].is_null());
}

#[test]
fn every_solver_beats_the_formation() {
    let _scenario = common::scenario(module_path!());
    let rows = experiment("optimizers")["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 12, "3 solvers × 4 methods");
    for solver in ["pso", "ga", "aco"] {
        let of = |m: &str| f(&rows.iter().find(|r| r["solver"] == solver && r["method"] == m).unwrap()["final_crlb_m"]);
        for m in ["single", "mc", "analytical"] {
            assert!(of(m) < of("formation"), "{solver}/{m}");
        }
    }
}

#[test]
fn table9_rmse_tracks_the_crlb_which_is_linear_in_the_noise() {
    let _scenario = common::scenario(module_path!());
    let t = experiment("table9");
    let rows = t["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 4);
    let unit = rows.iter().find(|r| r["noise_scale"] == 1.0).unwrap();
    assert!((f(&unit["crlb_3_node_m"]) - 1655.58).abs() < 0.01, "the paper's initial CRLB");
    for r in rows {
        let s = f(&r["noise_scale"]);
        for n in ["3", "4", "5"] {
            let ratio = f(&r["rmse_crlb_ratio"][n]);
            assert!((0.9..=1.15).contains(&ratio), "scale {s}, {n} nodes: RMSE/CRLB {ratio}");
            let key = format!("crlb_{n}_node_m");
            let linear = f(&r[&key]) / (s * f(&unit[&key]));
            assert!((linear - 1.0).abs() < 1e-12, "scale {s}, {n} nodes: CRLB not linear ({linear})");
        }
    }
    assert_eq!(t["settings"]["fixed_geometry_runs_m"], 200, "--quick keeps M = 200 for the fixed geometries");
}

#[test]
fn criteria_are_checked_against_the_quadrature() {
    let _scenario = common::scenario(module_path!());
    let t4 = experiment("table4");
    let rows = t4["rows"].as_array().unwrap();
    let get = |m: &str| rows.iter().find(|r| r["metric"] == m).unwrap_or_else(|| panic!("no {m}"));
    for m in ["crlb", "global_crlb_objective", "rmse", "analytical_vs_quadrature", "mc_vs_quadrature"] {
        assert!(f(&get(m)["max_abs_diff_pct"]) >= f(&get(m)["mean_abs_diff_pct"]), "{m}");
    }
    // Analytical planning follows MC planning (the paper: 1.62 % mean, 3.43 % at most, in the CRLB).
    for m in ["crlb", "rmse"] {
        assert!(f(&get(m)["mean_abs_diff_pct"]) < 5.0 && f(&get(m)["max_abs_diff_pct"]) < 10.0, "{m}: {}", get(m));
    }
    // The second-order surrogate is within 1 % of the exact global CRLB on every planned step; 200 MC
    // points scatter around it (not zero: they are a sample), by a few per cent.
    assert!(f(&get("analytical_vs_quadrature")["max_abs_diff_pct"]) < 1.0, "{}", get("analytical_vs_quadrature"));
    let mc = f(&get("mc_vs_quadrature")["mean_abs_diff_pct"]);
    assert!((0.1..15.0).contains(&mc), "MC against the quadrature: {mc} %");
    // The Taylor surrogate is far closer to the exact value than 200 weighted MC points are.
    assert!(
        f(&get("analytical_vs_quadrature")["mean_abs_diff_pct"]) < f(&get("mc_vs_quadrature")["mean_abs_diff_pct"])
    );
    let t5 = experiment("table5");
    let rows = t5["rows"].as_array().unwrap();
    assert_eq!(rows.iter().map(|r| f(&r["uncertainty_scale"])).collect::<Vec<_>>(), [0.25, 0.5, 0.75, 1.0]);
    let aq: Vec<f64> = rows.iter().map(|r| f(&r["analytical_vs_quadrature"]["mean_abs_diff_pct"])).collect();
    // A second-order approximation: its error grows with the uncertainty scale.
    assert!(aq[0] <= aq[3], "{aq:?}");
}

#[test]
fn table6_table10_and_sensitivity_report_their_cases() {
    let _scenario = common::scenario(module_path!());
    let t6 = experiment("table6")["rows"].as_array().unwrap().clone();
    assert_eq!(t6.len(), 5);
    assert_eq!(f(&t6[0]["single"]["degradation_pct"]), 0.0, "s = 0 is the reference");
    let t10 = experiment("table10")["rows"].as_array().unwrap().clone();
    assert_eq!(t10.len(), 3);
    assert!((f(&t10[0]["initial_crlb_m"]) - 1655.58).abs() < 0.01);
    for r in &t10 {
        assert!(f(&r["analytical_final_crlb_m"]) < f(&r["initial_crlb_m"]), "planning improves {}", r["geometry"]);
    }
    let sens = experiment("sensitivity")["rows"].as_array().unwrap().clone();
    let settings: Vec<&str> = sens.iter().map(|r| r["setting"].as_str().unwrap()).collect();
    for s in ["default", "delta_alpha_deg", "controlled_scale", "controlled_sigma_t_m", "mc_scheme"] {
        assert!(settings.contains(&s), "sensitivity lacks {s}: {settings:?}");
    }
    for r in &sens {
        let mc = r["methods"].as_array().unwrap().iter().find(|m| m["method"] == "mc").unwrap();
        assert!(f(&mc["criterion_ess_median"]) >= 1.0, "{}", r["setting"]);
    }
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    let _scenario = common::scenario(module_path!());
    let run = |threads: &str| {
        let out = std::process::Command::new(UAVLOC)
            .args(["paper", "table2", "--runs", "4", "--json"])
            .env("RAYON_NUM_THREADS", threads)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let v: Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(v["settings"]["threads"].as_u64(), Some(threads.parse().unwrap()));
        v["rows"].clone()
    };
    assert_eq!(run("1"), run("2"));
    // And another seed gives other numbers.
    let other = json_of(&["paper", "table2", "--runs", "4", "--seed", "9", "--json"]);
    assert_ne!(other["rows"], run("1"));
}

#[test]
fn out_writes_tables_and_figures() {
    let _scenario = common::scenario(module_path!());
    let dir = scratch("paper-out");
    let out = uavloc(&["paper", "table9", "--runs", "3", "--out", dir.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8_lossy(&out.stdout);
    // The table in the paper's layout: ours, the paper's numbers, the difference.
    for needle in ["Table 9", "ours", "paper", "Δ", "1655.58", "wrote"] {
        assert!(text.contains(needle), "missing {needle:?} in:\n{text}");
    }
    let md = std::fs::read_to_string(dir.join("table9.md")).unwrap();
    assert!(md.contains("| Noise scale | source |") && md.contains("---:|"), "{md}");
    let csv = std::fs::read_to_string(dir.join("table9.csv")).unwrap();
    assert_eq!(csv.lines().next().unwrap().split(',').count(), 8, "{csv}");
    assert_eq!(csv.lines().count(), 1 + 4 * 3, "header + ours, paper, Δ per noise scale");
    for (fig, label) in [("table9-crlb-rmse", "3-node CRLB"), ("table9-ratio", "3 nodes")] {
        let svg = std::fs::read_to_string(dir.join(format!("{fig}.svg"))).unwrap();
        assert!(svg.contains("<svg") && svg.contains(label), "{fig}");
        let png = record::png::read(&dir.join(format!("{fig}.png"))).unwrap();
        assert!(png.width > 100 && png.height > 100);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_input_is_one_line_and_exit_2() {
    let _scenario = common::scenario(module_path!());
    for args in [
        vec!["paper", "table3"],
        vec!["paper"],
        vec!["paper", "table2", "--runs", "1"],
        vec!["paper", "table2", "--runs", "-5"],
        vec!["paper", "table2", "--samples", "1"],
        vec!["paper", "table2", "--resamples", "0"],
        vec!["paper", "table2", "--seed", "x"],
        vec!["paper", "table2", "--bogus"],
    ] {
        let out = uavloc(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{args:?}: {err}");
        assert!(err.starts_with("error:"), "{args:?}: {err}");
    }
    // An --out that cannot be a directory is bad input (exit 2) that names the path, refused before the
    // experiments run.
    let dir = scratch("paper-bad-out");
    let file = dir.join("a-file");
    std::fs::write(&file, "x").unwrap();
    let out = uavloc(&["paper", "table8", "--runs", "2", "--out", file.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("a-file"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn help_answers_the_questions() {
    let _scenario = common::scenario(module_path!());
    let out = uavloc(&["paper", "--help"]);
    let text = String::from_utf8_lossy(&out.stdout);
    for needle in [
        "table2",
        "sensitivity",
        "--quick",
        "--runs",
        "--out",
        "M = 200",
        "chosen_not_stated_by_paper",
        "RAYON_NUM_THREADS",
    ] {
        assert!(text.contains(needle), "missing {needle:?}");
    }
}
