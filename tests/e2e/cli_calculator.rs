//! End-to-end tests of the calculator subcommands (`crlb`, `global`, `locate`, `rmse`): the real
//! `uavloc` binary, its JSON output, tables, help and exit codes.

use std::collections::BTreeSet;
use std::process::Command;

use serde_json::Value;

const SPEED_OF_LIGHT: f64 = 299_792_458.0;

/// The paper's nominal geometry.
const NOMINAL_UAVS: [[f64; 2]; 3] = [[1500.0, 500.0], [10000.0, 1500.0], [5000.0, 8500.0]];
const NOMINAL_TARGET: [f64; 2] = [25000.0, 15000.0];
const NOMINAL_SIGMA: &str = "28.7712";
const PD_COV: &str = "250000,100000,160000";

struct Output {
    code: i32,
    stdout: String,
    stderr: String,
}

impl Output {
    fn json(&self) -> Value {
        assert_eq!(self.code, 0, "exit code {}; stderr: {}", self.code, self.stderr);
        serde_json::from_str(&self.stdout).unwrap_or_else(|e| panic!("stdout is not JSON ({e}): {}", self.stdout))
    }
}

fn uavloc<S: AsRef<str>>(args: &[S]) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_uavloc"))
        .args(args.iter().map(|s| s.as_ref()))
        .output()
        .expect("run the uavloc binary");
    Output {
        code: out.status.code().expect("exit code (not killed by a signal)"),
        stdout: String::from_utf8(out.stdout).expect("UTF-8 stdout"),
        stderr: String::from_utf8(out.stderr).expect("UTF-8 stderr"),
    }
}

fn pt(p: [f64; 2]) -> String {
    format!("{},{}", p[0], p[1])
}

fn uav_args(uavs: &[[f64; 2]]) -> Vec<String> {
    uavs.iter().flat_map(|u| ["--uav".to_string(), pt(*u)]).collect()
}

fn args(parts: &[&str]) -> Vec<String> {
    parts.iter().map(|s| s.to_string()).collect()
}

fn nominal() -> Vec<String> {
    uav_args(&NOMINAL_UAVS)
}

fn range_diffs(uavs: &[[f64; 2]], target: [f64; 2]) -> String {
    let r: Vec<f64> = uavs.iter().map(|u| (u[0] - target[0]).hypot(u[1] - target[1])).collect();
    r[1..].iter().map(|ri| format!("{:?}", ri - r[0])).collect::<Vec<_>>().join(",")
}

fn keys(v: &Value) -> BTreeSet<String> {
    v.as_object().expect("a JSON object").keys().cloned().collect()
}

fn key_set(names: &[&str]) -> BTreeSet<String> {
    names.iter().map(|s| s.to_string()).collect()
}

fn f(v: &Value, key: &str) -> f64 {
    v[key].as_f64().unwrap_or_else(|| panic!("{key} is not a number in {v}"))
}

// ---------------------------------------------------------------- crlb

fn crlb_json(extra: &[&str]) -> Value {
    let mut a = args(&["crlb", "--json"]);
    a.extend(nominal());
    a.extend(args(&["--target", &pt(NOMINAL_TARGET)]));
    a.extend(args(extra));
    uavloc(&a).json()
}

#[test]
fn crlb_nominal_matches_the_paper() {
    let _scenario = crate::common::scenario(module_path!());
    let v = crlb_json(&["--sigma", NOMINAL_SIGMA]);
    assert_eq!(keys(&v), key_set(&["crlb_m", "trace_m2", "cond", "fim"]));
    assert!((f(&v, "crlb_m") - 1655.58).abs() < 0.01, "{v}");
    assert!((f(&v, "trace_m2") - f(&v, "crlb_m").powi(2)).abs() < 1e-6 * f(&v, "trace_m2"));
    assert!(f(&v, "cond") >= 1.0);
    let fim = &v["fim"];
    assert_eq!(fim.as_array().unwrap().len(), 2);
    let (f01, f10) = (fim[0][1].as_f64().unwrap(), fim[1][0].as_f64().unwrap());
    assert!((f01 - f10).abs() <= 1e-12 * f01.abs(), "FIM must be symmetric: {fim}");
    assert!(fim[0][0].as_f64().unwrap() > 0.0 && fim[1][1].as_f64().unwrap() > 0.0);

    let unit = crlb_json(&["--sigma", "1"]);
    assert!((f(&unit, "crlb_m") - 57.543).abs() < 0.001, "{unit}");
}

#[test]
fn crlb_sigma_ns_equals_metres_and_lists_work() {
    let _scenario = crate::common::scenario(module_path!());
    let metres = 28.7712;
    let ns = metres * 1e9 / SPEED_OF_LIGHT;
    let by_m = crlb_json(&["--sigma", "28.7712"]);
    let by_ns = crlb_json(&["--sigma-ns", &format!("{ns:?}")]);
    assert!((f(&by_m, "crlb_m") - f(&by_ns, "crlb_m")).abs() < 1e-6, "{by_m} vs {by_ns}");
    let by_list = crlb_json(&["--sigma", "28.7712,28.7712,28.7712"]);
    assert_eq!(f(&by_list, "crlb_m"), f(&by_m, "crlb_m"));
    let by_ns_list = crlb_json(&["--sigma-ns", &format!("{ns:?},{ns:?},{ns:?}")]);
    assert!((f(&by_ns_list, "crlb_m") - f(&by_m, "crlb_m")).abs() < 1e-6);
    // A noisier reference UAV makes the bound worse.
    let worse = crlb_json(&["--sigma", "60,28.7712,28.7712"]);
    assert!(f(&worse, "crlb_m") > f(&by_m, "crlb_m") + 1.0);
}

#[test]
fn crlb_table_is_aligned_with_units() {
    let _scenario = crate::common::scenario(module_path!());
    let mut a = args(&["crlb"]);
    a.extend(nominal());
    a.extend(args(&["--target", "25000,15000", "--sigma", NOMINAL_SIGMA]));
    let out = uavloc(&a);
    assert_eq!(out.code, 0, "{}", out.stderr);
    let first = out.stdout.lines().next().unwrap();
    assert!(first.starts_with("CRLB") && first.ends_with("1655.58 m"), "{first}");
    // Labels may contain single spaces; the value starts after the first run of two or more spaces.
    let value_column = |l: &str| {
        let gap = l.find("  ").unwrap_or_else(|| panic!("no label/value gap in {l:?}"));
        l.len() - l[gap..].trim_start().len()
    };
    let columns: BTreeSet<usize> = out.stdout.lines().map(value_column).collect();
    assert_eq!(columns.len(), 1, "values must start in one column:\n{}", out.stdout);
    assert!(out.stdout.contains("m²"));
}

#[test]
fn negative_coordinates_are_accepted_in_every_spelling() {
    let _scenario = crate::common::scenario(module_path!());
    let v = uavloc(&[
        "crlb",
        "--uav",
        "-1500,200",
        "--uav",
        "0,0",
        "--uav=-800,-900",
        "--target",
        "-3000,-4000",
        "--sigma",
        "10",
        "--json",
    ])
    .json();
    assert!(f(&v, "crlb_m").is_finite() && f(&v, "crlb_m") > 0.0);
    // The same scene written with '=' everywhere gives the same answer.
    let w = uavloc(&[
        "crlb",
        "--uav=-1500,200",
        "--uav=0,0",
        "--uav=-800,-900",
        "--target=-3000,-4000",
        "--sigma=10",
        "--json",
    ])
    .json();
    assert_eq!(v, w);
}

// ---------------------------------------------------------------- locate

fn locate(uavs: &[[f64; 2]], target: [f64; 2], extra: &[&str]) -> Value {
    let mut a = args(&["locate", "--json"]);
    a.extend(uav_args(uavs));
    a.push(format!("--range-diff={}", range_diffs(uavs, target)));
    a.extend(args(extra));
    uavloc(&a).json()
}

fn assert_at(v: &Value, target: [f64; 2], tol: f64) {
    assert!((f(v, "x") - target[0]).abs() < tol && (f(v, "y") - target[1]).abs() < tol, "{v} vs {target:?}");
}

#[test]
fn locate_noise_free_returns_the_target() {
    let _scenario = crate::common::scenario(module_path!());
    let v = locate(&NOMINAL_UAVS, NOMINAL_TARGET, &["--sigma", NOMINAL_SIGMA]);
    assert_eq!(keys(&v), key_set(&["x", "y", "cov", "ambiguous", "candidates"]));
    assert_at(&v, NOMINAL_TARGET, 1e-6);
    assert_eq!(v["ambiguous"], Value::Bool(false));
    assert_eq!(v["candidates"].as_array().unwrap().len(), 1);
    let cov = &v["cov"];
    assert!(cov[0][0].as_f64().unwrap() > 0.0 && cov[1][1].as_f64().unwrap() > 0.0);
    let (c01, c10) = (cov[0][1].as_f64().unwrap(), cov[1][0].as_f64().unwrap());
    assert!((c01 - c10).abs() <= 1e-9 * c01.abs(), "cov must be symmetric: {cov}");
}

#[test]
fn locate_translated_to_negative_coordinates() {
    let _scenario = crate::common::scenario(module_path!());
    let shift = |p: [f64; 2]| [p[0] - 30000.0, p[1] - 20000.0];
    let uavs: Vec<[f64; 2]> = NOMINAL_UAVS.iter().map(|&p| shift(p)).collect();
    let target = shift(NOMINAL_TARGET);
    let v = locate(&uavs, target, &["--sigma", NOMINAL_SIGMA]);
    assert_at(&v, target, 1e-6);
    // Four UAVs, all coordinates negative, negative range differences passed with a space.
    let uavs4 = [[-31500.0, -20200.0], [-30000.0, -21000.0], [-29200.0, -19100.0], [-30300.0, -22700.0]];
    let target4 = [-34000.0, -26000.0];
    let mut a = args(&["locate", "--json", "--sigma-ns", "30", "--range-diff", &range_diffs(&uavs4, target4)]);
    a.extend(uav_args(&uavs4));
    let v = uavloc(&a).json();
    assert_at(&v, target4, 1e-6);
}

#[test]
fn locate_ambiguity_is_reported_and_resolved_by_the_prior() {
    let _scenario = crate::common::scenario(module_path!());
    let uavs = [[0.0, 0.0], [1000.0, 0.0], [0.0, 1000.0]];
    let target = [-2000.0, -500.0];
    let mut a = args(&["locate", "--json", "--sigma", "1", "--range-diff", &range_diffs(&uavs, target)]);
    a.extend(uav_args(&uavs));
    let out = uavloc(&a);
    let v = out.json();
    assert_eq!(v["ambiguous"], Value::Bool(true));
    let cands = v["candidates"].as_array().unwrap();
    assert_eq!(cands.len(), 2);
    assert!(cands.iter().any(
        |c| (c[0].as_f64().unwrap() - target[0]).abs() < 1e-6 && (c[1].as_f64().unwrap() - target[1]).abs() < 1e-6
    ));
    assert!(out.stderr.contains("warning") && out.stderr.contains("--prior"), "{}", out.stderr);

    a.extend(args(&["--prior", "-1800,-300"]));
    let out = uavloc(&a);
    let v = out.json();
    assert_eq!(v["ambiguous"], Value::Bool(false));
    assert_at(&v, target, 1e-6);
    assert!(out.stderr.is_empty(), "{}", out.stderr);
}

// ---------------------------------------------------------------- global

fn global(uavs: &[[f64; 2]], estimate: &str, cov: &str, sigma: &str, extra: &[&str]) -> Output {
    let mut a = args(&["global", "--json", "--estimate", estimate, "--cov", cov, "--sigma", sigma]);
    a.extend(uav_args(uavs));
    a.extend(args(extra));
    uavloc(&a)
}

const METHODS: [&str; 5] = ["single", "mc", "analytical", "quadrature", "cubature"];

#[test]
fn global_all_methods_at_the_nominal_geometry() {
    let _scenario = crate::common::scenario(module_path!());
    let mut values = std::collections::BTreeMap::new();
    for m in METHODS {
        let v = global(&NOMINAL_UAVS, "25000,15000", PD_COV, NOMINAL_SIGMA, &["--method", m]).json();
        let mut expected = key_set(&[
            "method",
            "trace_m2",
            "crlb_m",
            "side_m",
            "singular_locus",
            "singular_distance_m",
            "evaluations",
        ]);
        if m == "mc" {
            expected.insert("stderr_trace_m2".into());
            expected.insert("effective_samples".into());
            assert!(f(&v, "stderr_trace_m2") > 0.0);
            assert!(f(&v, "effective_samples") >= 1.0 && f(&v, "effective_samples") <= 200.0);
        }
        assert_eq!(keys(&v), expected, "{m}: {v}");
        assert_eq!(v["method"], Value::String(m.into()));
        let tr = f(&v, "trace_m2");
        assert!(tr.is_finite() && tr > 0.0, "{m}: {v}");
        assert!((f(&v, "crlb_m") - tr.sqrt()).abs() < 1e-9 * tr.sqrt());
        assert_eq!(v["singular_locus"], Value::Bool(false));
        assert!(f(&v, "singular_distance_m") > 0.5 * f(&v, "side_m"));
        assert!(v["evaluations"].as_u64().unwrap() >= 1);
        values.insert(m, tr);
    }
    let quad = values["quadrature"];
    for m in ["analytical", "cubature"] {
        assert!((values[m] - quad).abs() < 0.01 * quad, "{m} {} vs quadrature {quad}", values[m]);
    }
    // single is tr F⁻¹ at the estimate, i.e. the square of the crlb subcommand's answer.
    let single_crlb = crlb_json(&["--sigma", NOMINAL_SIGMA]);
    assert!((values["single"] - f(&single_crlb, "trace_m2")).abs() < 1e-6 * values["single"]);
}

#[test]
fn global_support_side_follows_eq36_unless_given() {
    let _scenario = crate::common::scenario(module_path!());
    let v = global(&NOMINAL_UAVS, "25000,15000", PD_COV, NOMINAL_SIGMA, &["--method", "single"]).json();
    // eq. 36 by hand: σ_t = sqrt(λ_max(M)), r_avg = mean UAV–estimate distance, κ = 0.1.
    let (a, b, c) = (250000.0_f64, 100000.0_f64, 160000.0_f64);
    let lmax = 0.5 * (a + c) + (0.25 * (a - c).powi(2) + b * b).sqrt();
    let st = lmax.sqrt();
    let r_avg = NOMINAL_UAVS.iter().map(|u| (u[0] - 25000.0).hypot(u[1] - 15000.0)).sum::<f64>() / 3.0;
    let side = (10.0 * st).min(6.0 * st + 0.1 * r_avg);
    assert!((f(&v, "side_m") - side).abs() < 1e-6 * side, "{v} vs {side}");

    let v = global(&NOMINAL_UAVS, "25000,15000", PD_COV, NOMINAL_SIGMA, &["--method", "single", "--side", "1234.5"]);
    assert_eq!(f(&v.json(), "side_m"), 1234.5);
    let v = global(&NOMINAL_UAVS, "25000,15000", PD_COV, NOMINAL_SIGMA, &["--method", "single", "--kappa", "0"]);
    assert!((f(&v.json(), "side_m") - 6.0 * st).abs() < 1e-6 * st);
}

#[test]
fn global_mc_is_seeded() {
    let _scenario = crate::common::scenario(module_path!());
    let run = |seed: &str, samples: &str| {
        global(
            &NOMINAL_UAVS,
            "25000,15000",
            PD_COV,
            NOMINAL_SIGMA,
            &["--method", "mc", "--seed", seed, "--samples", samples],
        )
    };
    let a = run("5", "300");
    let b = run("5", "300");
    assert_eq!(a.stdout, b.stdout);
    let c = run("6", "300");
    assert_ne!(f(&a.json(), "trace_m2"), f(&c.json(), "trace_m2"));
    assert_eq!(run("5", "300").json()["evaluations"], Value::from(300));
    // Default samples is 200.
    let d = global(&NOMINAL_UAVS, "25000,15000", PD_COV, NOMINAL_SIGMA, &["--method", "mc"]).json();
    assert_eq!(d["evaluations"], Value::from(200));
}

#[test]
fn global_support_reaching_the_singular_locus_is_infinite() {
    let _scenario = crate::common::scenario(module_path!());
    let uavs = [[0.0, 0.0], [1000.0, 0.0], [0.0, 1000.0]];
    for m in METHODS {
        let out = global(&uavs, "3000,10", "10000,0,10000", "10", &["--method", m]);
        let v = out.json();
        assert_eq!(v["singular_locus"], Value::Bool(true), "{m}: {v}");
        assert!((f(&v, "singular_distance_m") - 10.0).abs() < 1e-6, "{m}: {v}");
        match m {
            "single" | "analytical" => {
                assert!(f(&v, "trace_m2").is_finite(), "{m}: {v}");
                assert!(f(&v, "crlb_m").is_finite());
                assert!(out.stderr.starts_with("warning") && out.stderr.contains("infinite"), "{}", out.stderr);
            }
            _ => {
                assert!(v["trace_m2"].is_null() && v["crlb_m"].is_null(), "{m}: {v}");
                assert!(out.stderr.starts_with("warning") && out.stderr.lines().count() == 1, "{}", out.stderr);
                assert!(out.stderr.contains("singular locus"));
            }
        }
        if m == "mc" {
            assert!(v["stderr_trace_m2"].is_null());
        } else {
            assert!(v.get("stderr_trace_m2").is_none(), "{m}: {v}");
        }
    }
    // The table says so in words.
    let mut a = args(&["global", "--method", "quadrature", "--estimate", "3000,10", "--cov", "10000,0,10000"]);
    a.extend(args(&["--sigma", "10"]));
    a.extend(uav_args(&uavs));
    let out = uavloc(&a);
    assert_eq!(out.code, 0);
    assert!(out.stdout.contains("infinite (support reaches the singular locus at distance 10"), "{}", out.stdout);
}

#[test]
fn global_singular_distance_is_null_without_a_singular_set() {
    let _scenario = crate::common::scenario(module_path!());
    // Four UAVs on a square: opposite sides are parallel and the diagonals cross between the UAVs, so
    // the FIM is regular everywhere off the UAVs.
    let uavs = [[0.0, 0.0], [1000.0, 0.0], [1000.0, 1000.0], [0.0, 1000.0]];
    let v = global(&uavs, "20000,15000", "10000,0,10000", "10", &["--method", "quadrature"]).json();
    assert!(f(&v, "trace_m2").is_finite());
    assert!(v["singular_distance_m"].is_null(), "{v}");
    assert_eq!(v["singular_locus"], Value::Bool(false));
}

// ---------------------------------------------------------------- rmse

fn rmse(seed: &str, extra: &[&str]) -> Output {
    let mut a = args(&["rmse", "--json", "--target", "25000,15000", "--sigma", NOMINAL_SIGMA, "--seed", seed]);
    a.extend(nominal());
    a.extend(args(extra));
    uavloc(&a)
}

#[test]
fn rmse_nominal_is_close_to_the_crlb_and_seeded() {
    let _scenario = crate::common::scenario(module_path!());
    let a = rmse("3", &["--draws", "2000"]);
    let v = a.json();
    assert_eq!(keys(&v), key_set(&["rmse_m", "crlb_m", "ratio", "failures", "draws"]));
    let ratio = f(&v, "ratio");
    assert!((0.95..=1.05).contains(&ratio), "{v}");
    assert_eq!(v["failures"], Value::from(0));
    assert_eq!(v["draws"], Value::from(2000));
    assert!((f(&v, "crlb_m") - 1655.58).abs() < 0.01);
    assert!((f(&v, "rmse_m") / f(&v, "crlb_m") - ratio).abs() < 1e-12);

    let b = rmse("3", &["--draws", "2000"]);
    assert_eq!(a.stdout, b.stdout, "same seed, same output");
    let c = rmse("4", &["--draws", "2000"]);
    assert_ne!(f(&v, "rmse_m"), f(&c.json(), "rmse_m"), "different seed, different RMSE");
}

#[test]
fn rmse_all_draws_failing_exits_1_with_nulls() {
    let _scenario = crate::common::scenario(module_path!());
    // Every noisy measurement of this emitter leaves Chan's 3-UAV ambiguity unresolved.
    let mut a = args(&["rmse", "--json", "--target", "-2000,-500", "--sigma", "0.1", "--draws", "20", "--seed", "1"]);
    a.extend(uav_args(&[[0.0, 0.0], [1000.0, 0.0], [0.0, 1000.0]]));
    let out = uavloc(&a);
    assert_eq!(out.code, 1, "{}", out.stderr);
    assert!(out.stderr.contains("error") && !out.stderr.contains("panicked"));
    let v: Value = serde_json::from_str(&out.stdout).unwrap();
    assert!(v["rmse_m"].is_null() && v["ratio"].is_null());
    assert_eq!(v["failures"], Value::from(20));
    // A prior resolves it.
    a.extend(args(&["--prior", "-1900,-400"]));
    let v = uavloc(&a).json();
    assert_eq!(v["failures"], Value::from(0));
    assert!(f(&v, "ratio") > 0.5 && f(&v, "ratio") < 2.0);
}

// ---------------------------------------------------------------- bad input

fn assert_input_error(a: &[String], what: &str) {
    let out = uavloc(a);
    assert_eq!(out.code, 2, "{what}: exit code {}; stdout: {}; stderr: {}", out.code, out.stdout, out.stderr);
    assert!(out.stderr.starts_with("error:"), "{what}: stderr must start with 'error:': {:?}", out.stderr);
    assert_eq!(out.stderr.trim_end().lines().count(), 1, "{what}: one line expected: {:?}", out.stderr);
    assert!(!out.stderr.contains("panicked"), "{what}: {}", out.stderr);
    assert!(out.stdout.is_empty(), "{what}: nothing on stdout: {}", out.stdout);
}

fn with(cmd: &str, uavs: &[&str], rest: &[&str]) -> Vec<String> {
    let mut a = args(&[cmd]);
    for u in uavs {
        a.push("--uav".into());
        a.push(u.to_string());
    }
    a.extend(args(rest));
    a
}

const N3: [&str; 3] = ["1500,500", "10000,1500", "5000,8500"];
const T: [&str; 2] = ["--target", "25000,15000"];

#[test]
fn bad_input_is_one_error_line_and_exit_2() {
    let _scenario = crate::common::scenario(module_path!());
    let crlb = |uavs: &[&str], rest: &[&str]| with("crlb", uavs, rest);
    let t_s1 = ["--target", "25000,15000", "--sigma", "1"];
    let nine: Vec<String> = (0..9).map(|i| format!("{},{}", i * 100, i * i * 10)).collect();
    let nine: Vec<&str> = nine.iter().map(String::as_str).collect();
    let cases: Vec<(Vec<String>, &str)> = vec![
        (crlb(&N3[..2], &t_s1), "2 UAVs"),
        (crlb(&nine, &t_s1), "9 UAVs"),
        (crlb(&["1,2,3", N3[1], N3[2]], &t_s1), "--uav 1,2,3"),
        (crlb(&["1", N3[1], N3[2]], &t_s1), "--uav 1"),
        (crlb(&["a,b", N3[1], N3[2]], &t_s1), "--uav a,b"),
        (crlb(&["", N3[1], N3[2]], &t_s1), "--uav ''"),
        (crlb(&["nan,0", N3[1], N3[2]], &t_s1), "--uav nan,0"),
        (crlb(&["inf,0", N3[1], N3[2]], &t_s1), "--uav inf,0"),
        (crlb(&N3, &["--target", "25000,15000", "--sigma", "1,2"]), "sigma list too short"),
        (crlb(&N3, &["--target", "25000,15000", "--sigma", "1,2,3,4"]), "sigma list too long"),
        (crlb(&N3, &["--target", "25000,15000", "--sigma", "0"]), "sigma 0"),
        (crlb(&N3, &["--target", "25000,15000", "--sigma", "-1"]), "sigma -1"),
        (crlb(&N3, &["--target", "25000,15000", "--sigma", "1,-1,1"]), "negative sigma in list"),
        (crlb(&N3, &["--target", "25000,15000", "--sigma-ns", "0"]), "sigma-ns 0"),
        (crlb(&N3, &["--target", "25000,15000"]), "no sigma"),
        (crlb(&N3, &["--target", "25000,15000", "--sigma", "1", "--sigma-ns", "1"]), "both sigmas"),
        (crlb(&["0,0", "0,0", "5000,8500"], &t_s1), "coincident UAVs"),
        (crlb(&N3, &["--sigma", "1"]), "missing --target"),
        (crlb(&N3, &["--target", "nan,1", "--sigma", "1"]), "--target nan"),
        (crlb(&N3, &["--target", "1500,500", "--sigma", "1"]), "emitter on a UAV"),
        (crlb(&["0,0", "1000,0", "0,1000"], &["--target", "3000,0", "--sigma", "1"]), "baseline extension"),
        (crlb(&N3, &["--target", "25000,15000", "--sigma", "1", "--frobnicate"]), "unknown flag"),
        (with("locate", &N3, &["--range-diff", "1,2,3", "--sigma", "1"]), "range-diff count"),
        (with("locate", &N3, &["--range-diff", "1", "--sigma", "1"]), "range-diff too short"),
        (with("locate", &N3, &["--range-diff", "1,x", "--sigma", "1"]), "range-diff not a number"),
        (
            with("locate", &["0,0", "1000,0", "2000,0"], &["--range-diff", "100,200", "--sigma", "1"]),
            "collinear UAVs for locate",
        ),
        (
            with("locate", &["0,0", "1000,0", "2000,0", "-500,0"], &["--range-diff", "100,200,50", "--sigma", "1"]),
            "4 collinear UAVs for locate",
        ),
        (with("locate", &N3, &["--range-diff", "50000,2", "--sigma", "1"]), "no physical solution"),
        (
            with("global", &N3, &["--estimate", "0,0", "--cov", "1,2,1", "--sigma", "1", "--method", "single"]),
            "cov not PD",
        ),
        (
            with("global", &N3, &["--estimate", "0,0", "--cov", "1,0", "--sigma", "1", "--method", "single"]),
            "cov 2 values",
        ),
        (
            with("global", &N3, &["--estimate", "0,0", "--cov", "1,0,1", "--sigma", "1", "--method", "foo"]),
            "unknown --method",
        ),
        (with("global", &N3, &["--estimate", "0,0", "--cov", "1,0,1", "--sigma", "1"]), "missing --method"),
        (
            with(
                "global",
                &N3,
                &["--estimate", "0,0", "--cov", "1,0,1", "--sigma", "1", "--method", "mc", "--side", "0"],
            ),
            "side 0",
        ),
        (
            with(
                "global",
                &N3,
                &["--estimate", "0,0", "--cov", "1,0,1", "--sigma", "1", "--method", "mc", "--side", "-3"],
            ),
            "side < 0",
        ),
        (
            with(
                "global",
                &N3,
                &["--estimate", "0,0", "--cov", "1,0,1", "--sigma", "1", "--method", "mc", "--samples", "1"],
            ),
            "samples 1",
        ),
        (
            with(
                "global",
                &N3,
                &["--estimate", "0,0", "--cov", "1,0,1", "--sigma", "1", "--method", "mc", "--samples", "-4"],
            ),
            "samples negative",
        ),
        (with("rmse", &N3, &[T[0], T[1], "--sigma", "1", "--draws", "0"]), "draws 0"),
        (with("rmse", &N3, &[T[0], T[1], "--sigma", "1", "--draws", "-5"]), "draws negative"),
        (with("rmse", &N3, &[T[0], T[1], "--sigma", "1", "--draws", "2.5"]), "draws fractional"),
        (with("rmse", &N3, &["--target", "5000,8500", "--sigma", "1", "--draws", "10"]), "rmse target on a UAV"),
        (args(&["frobnicate"]), "unknown subcommand"),
    ];
    assert!(cases.len() >= 12);
    for (a, what) in &cases {
        assert_input_error(a, what);
    }
}

#[test]
fn error_lines_name_the_flag_and_value() {
    let _scenario = crate::common::scenario(module_path!());
    let cases: Vec<(Vec<String>, &[&str])> = vec![
        (with("crlb", &["1,2,3", N3[1], N3[2]], &[T[0], T[1], "--sigma", "1"]), &["--uav", "1,2,3"]),
        (with("crlb", &["nan,0", N3[1], N3[2]], &[T[0], T[1], "--sigma", "1"]), &["--uav", "nan"]),
        (with("crlb", &N3[..2], &[T[0], T[1], "--sigma", "1"]), &["--uav", "2"]),
        (with("crlb", &N3, &[T[0], T[1], "--sigma", "1,2"]), &["--sigma", "2"]),
        (with("crlb", &N3, &[T[0], T[1], "--sigma", "-1"]), &["--sigma", "-1"]),
        (with("crlb", &N3, &["--sigma", "1"]), &["--target"]),
        (with("locate", &N3, &["--range-diff", "1,2,3", "--sigma", "1"]), &["--range-diff", "3"]),
        (with("global", &N3, &["--estimate", "0,0", "--cov", "1,2,1", "--sigma", "1", "--method", "mc"]), &["--cov"]),
        (
            with("global", &N3, &["--estimate", "0,0", "--cov", "1,0,1", "--sigma", "1", "--method", "x"]),
            &["--method", "'x'"],
        ),
    ];
    for (a, needles) in cases {
        let out = uavloc(&a);
        assert_eq!(out.code, 2);
        for n in needles {
            assert!(out.stderr.contains(n), "{a:?}: {:?} should mention {n}", out.stderr);
        }
    }
}

#[test]
fn a_flag_after_a_negative_value_is_still_a_flag() {
    let _scenario = crate::common::scenario(module_path!());
    let v = uavloc(&[
        "crlb",
        "--uav",
        "-1500,200",
        "--uav",
        "0,0",
        "--uav",
        "-200,-1800",
        "--target",
        "-3,-4000",
        "--sigma",
        "1",
        "--json",
    ])
    .json();
    assert!(f(&v, "crlb_m") > 0.0);
    // `--range-diff -120.5,300` followed by another flag.
    let uavs = [[-1500.0, 200.0], [0.0, 0.0], [800.0, -900.0]];
    let d = range_diffs(&uavs, [3000.0, -4000.0]);
    assert!(d.starts_with('-'), "{d}");
    let mut a = args(&["locate", "--range-diff", &d, "--sigma", "1", "--json"]);
    a.extend(uav_args(&uavs));
    let v = uavloc(&a).json();
    let cands = v["candidates"].as_array().unwrap();
    assert!(
        cands
            .iter()
            .any(|c| (c[0].as_f64().unwrap() - 3000.0).abs() < 1e-6 && (c[1].as_f64().unwrap() + 4000.0).abs() < 1e-6),
        "{v}"
    );
}

// ---------------------------------------------------------------- help

#[test]
fn help_answers_the_usual_questions() {
    let _scenario = crate::common::scenario(module_path!());
    let top = uavloc(&["--help"]);
    assert_eq!(top.code, 0);
    for needle in ["TDOA", "UAV", "crlb", "global", "locate", "rmse", "--json", "metres"] {
        assert!(top.stdout.contains(needle), "top-level help lacks {needle}:\n{}", top.stdout);
    }
    for cmd in ["crlb", "global", "locate", "rmse"] {
        let line = top.stdout.lines().find(|l| l.trim_start().starts_with(cmd)).unwrap();
        assert!(line.split_whitespace().count() > 3, "{cmd} needs a one-line description: {line}");
        let h = uavloc(&[cmd, "--help"]);
        assert_eq!(h.code, 0, "{cmd}");
        for needle in ["metres", "UAV0", "Example", "uavloc ", "--sigma-ns", "ns", "--json"] {
            assert!(h.stdout.contains(needle), "{cmd} --help lacks {needle}:\n{}", h.stdout);
        }
        assert!(uavloc(&[cmd, "-h"]).stdout.contains("Usage"));
    }
    let g = uavloc(&["global", "--help"]).stdout;
    for needle in ["[default: 200]", "[default: 1]", "[default: 0.1]", "quadrature", "cubature", "m²"] {
        assert!(g.contains(needle), "global --help lacks {needle}");
    }
    assert!(uavloc(&["locate", "--help"]).stdout.contains("d_i = r_i − r_0"));
}

/// `locate --fuse FILE`: recorded snapshots of UAVs flying past the nominal emitter, with noise, as CSV
/// and as JSON lines. The fused estimate is far closer to the truth than each line's Chan fix, CSV and
/// JSON agree exactly, and a malformed line is refused naming its number.
#[test]
fn locate_fuses_recorded_snapshots() {
    let _scenario = crate::common::scenario(module_path!());
    let dir = std::env::temp_dir().join(format!("uavloc-fuse-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let z = NOMINAL_TARGET;
    let r = |p: [f64; 2]| (p[0] - z[0]).hypot(p[1] - z[1]);
    // A deterministic "noise" of a few σ per snapshot.
    let e = |k: usize, i: usize| 28.7712 * (((k * 7 + i * 3) % 11) as f64 - 5.0) / 3.0;
    let (mut csv, mut jsonl) = (String::from("x0,y0,x1,y1,x2,y2,d1,d2,sigma_m\n"), String::new());
    let mut chan_errors = Vec::new();
    for k in 0..20 {
        let t = 500.0 * k as f64;
        let uavs = [[1500.0 + t, 500.0], [10_000.0 + t, 1500.0 + 0.5 * t], [5000.0, 8500.0 + t]];
        let d = [r(uavs[1]) - r(uavs[0]) + e(k, 1), r(uavs[2]) - r(uavs[0]) + e(k, 2)];
        csv += &format!(
            "{},{},{},{},{},{},{:?},{:?},28.7712\n",
            uavs[0][0], uavs[0][1], uavs[1][0], uavs[1][1], uavs[2][0], uavs[2][1], d[0], d[1]
        );
        jsonl += &format!("{{\"uavs\": {uavs:?}, \"range_diffs\": [{:?}, {:?}], \"sigma\": 28.7712}}\n", d[0], d[1]);
        let mut args: Vec<String> = vec!["locate".into(), "--json".into(), "--sigma".into(), NOMINAL_SIGMA.into()];
        for u in uavs {
            args.extend(["--uav".into(), format!("{},{}", u[0], u[1])]);
        }
        args.extend(["--range-diff".into(), format!("{:?},{:?}", d[0], d[1]), "--prior".into(), "20000,20000".into()]);
        let fix = uavloc(&args).json();
        chan_errors.push((fix["x"].as_f64().unwrap() - z[0]).hypot(fix["y"].as_f64().unwrap() - z[1]));
    }
    std::fs::write(dir.join("s.csv"), &csv).unwrap();
    std::fs::write(dir.join("s.jsonl"), &jsonl).unwrap();
    let a =
        uavloc(&["locate", "--json", "--prior", "20000,20000", "--fuse", dir.join("s.csv").to_str().unwrap()]).json();
    let b =
        uavloc(&["locate", "--json", "--prior", "20000,20000", "--fuse", dir.join("s.jsonl").to_str().unwrap()]).json();
    for key in ["x", "y", "cov", "fused", "rejected_snapshots"] {
        assert_eq!(a[key], b[key], "CSV and JSON lines give the same fused {key}");
    }
    let est = |v: &Value| v["steps"].as_array().unwrap().iter().map(|s| s["estimate"].clone()).collect::<Vec<_>>();
    assert_eq!(est(&a), est(&b));
    assert_eq!(a["snapshots"].as_u64(), Some(20));
    assert_eq!(a["fused"].as_u64(), Some(20));
    assert_eq!(a["steps"].as_array().unwrap().len(), 20);
    let fused_error = (a["x"].as_f64().unwrap() - z[0]).hypot(a["y"].as_f64().unwrap() - z[1]);
    let mean_chan = chan_errors.iter().sum::<f64>() / chan_errors.len() as f64;
    assert!(fused_error < 0.5 * mean_chan, "fused {fused_error:.1} m vs Chan per line {mean_chan:.1} m on average");
    let sd = a["cov"][0][0].as_f64().unwrap().sqrt();
    assert!(fused_error < 5.0 * sd.max(1.0), "error {fused_error:.1} m vs std {sd:.1} m");
    // A malformed line: exit 2, the line named.
    std::fs::write(dir.join("bad.csv"), csv.replacen("28.7712\n", "28.7712,9\n", 3)).unwrap();
    let bad = uavloc(&["locate", "--fuse", dir.join("bad.csv").to_str().unwrap()]);
    assert_eq!(bad.code, 2, "{}", bad.stderr);
    assert!(bad.stderr.contains("line 2") && bad.stderr.lines().count() == 1, "{}", bad.stderr);
    let _ = std::fs::remove_dir_all(&dir);
}

/// `locate` with the UAVs as latitude/longitude around `--origin` finds the same emitter as with the
/// plane's metres (the positions are nominal to 0.1 mm), and gives it as latitude/longitude with its
/// 95 % ellipse; bad geographic input is a clear error (exit 2).
#[test]
fn locate_takes_and_gives_latitude_longitude_around_an_origin() {
    let d = range_diffs(&NOMINAL_UAVS, NOMINAL_TARGET);
    let geo = uavloc(&args(&[
        "locate",
        "--json",
        "--origin",
        "47.3977,8.5456,488",
        "--uav-lat-lon",
        "47.402195200,8.565470406",
        "--uav-lat-lon",
        "47.411114214,8.678091854",
        "--uav-lat-lon",
        "47.474128061,8.611925036",
        "--range-diff",
        &d,
        "--sigma",
        NOMINAL_SIGMA,
        "--prior",
        "20000,20000",
    ]))
    .json();
    assert!(
        (f(&geo, "x") - NOMINAL_TARGET[0]).abs() < 1e-3 && (f(&geo, "y") - NOMINAL_TARGET[1]).abs() < 1e-3,
        "{geo}"
    );
    // scenarios/geo.toml puts the emitter at 47.532126769, 8.877592429.
    assert!((f(&geo, "lat_deg") - 47.532_126_769).abs() < 1e-8 && (f(&geo, "lon_deg") - 8.877_592_429).abs() < 1e-8);
    assert_eq!(geo["ellipse_95_lat_lon_deg"].as_array().unwrap().len(), 65);
    let plain = uavloc(
        &[
            &["locate", "--json"][..],
            &nominal().iter().map(String::as_str).collect::<Vec<_>>(),
            &["--range-diff", &d, "--sigma", NOMINAL_SIGMA, "--prior", "20000,20000"],
        ]
        .concat(),
    )
    .json();
    assert!(plain.get("lat_deg").is_none(), "no origin, no latitude");
    for (bad, says) in [
        (vec!["--origin", "91,8", "--uav", "0,0", "--uav", "1000,0", "--uav", "0,1000"], "latitude 91"),
        (vec!["--uav-lat-lon", "47.4,8.5", "--uav-lat-lon", "47.5,8.5", "--uav-lat-lon", "47.4,8.6"], "--origin"),
        (
            vec![
                "--origin",
                "47,8",
                "--uav-lat-lon",
                "47.4,8.5",
                "--uav-lat-lon",
                "57.5,8.5",
                "--uav-lat-lon",
                "47.4,8.6",
            ],
            "from the origin",
        ),
        (
            vec!["--origin", "47,8", "--uav-lat-lon", "47.4", "--uav-lat-lon", "47.5,8.5", "--uav-lat-lon", "47.4,8.6"],
            "LAT,LON",
        ),
    ] {
        let out = uavloc(&[&["locate"][..], &bad, &["--range-diff", "1,2", "--sigma", "30"]].concat());
        assert_eq!(out.code, 2, "{bad:?}: {}", out.stderr);
        assert!(out.stderr.contains(says), "{bad:?}: {}", out.stderr);
    }
}
