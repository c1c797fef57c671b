//! `uavloc launch`: the four real processes over real iceoryx2, in lock-step, reproduce `uavloc simulate`
//! exactly, count no rejected message, and leave no process and no iceoryx2 resource behind.
//!
//! Every launch runs in its own domain (`--domain launch-test-<pid>-<tag>`), so the tests run in parallel
//! with each other and with anything else on the machine.

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use serde_json::Value;

fn uavloc(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_uavloc")).args(args).output().expect("run uavloc")
}

fn json_of(args: &[&str]) -> Value {
    let out = uavloc(args);
    assert!(out.status.success(), "uavloc {args:?} failed ({}): {}", out.status, String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!("uavloc {args:?}: stdout is not JSON ({e}): {}", String::from_utf8_lossy(&out.stdout))
    })
}

fn domain(tag: &str) -> String {
    format!("launch-test-{}-{tag}", std::process::id())
}

/// Every step field of `simulate` must be equal in the launch — compared as parsed f64 with `==` (the
/// workspace's serde_json parses floats exactly) — except the wall-clock planning time.
fn assert_same_run(sim: &Value, launch: &Value, label: &str) {
    for key in ["objective", "solver", "seed", "emitter", "scenario"] {
        assert_eq!(sim[key], launch[key], "{label}: {key}");
    }
    let (a, b) = (sim["steps"].as_array().unwrap(), launch["steps"].as_array().unwrap());
    assert_eq!(a.len(), b.len(), "{label}: number of steps");
    for (s, l) in a.iter().zip(b) {
        let k = &s["step"];
        assert_eq!(k, &l["step"], "{label}");
        for key in ["uavs", "headings_rad", "estimate"] {
            assert_eq!(s[key], l[key], "{label}: step {k} {key}");
            // Bit for bit, not only as JSON text.
            let bits = |v: &Value| -> Vec<u64> {
                let mut out = Vec::new();
                let mut stack = vec![v.clone()];
                while let Some(x) = stack.pop() {
                    match x {
                        Value::Array(items) => stack.extend(items),
                        Value::Number(n) => out.push(n.as_f64().unwrap().to_bits()),
                        other => panic!("{label}: step {k} {key}: unexpected {other}"),
                    }
                }
                out
            };
            assert_eq!(bits(&s[key]), bits(&l[key]), "{label}: step {k} {key} bits");
        }
        for key in ["estimate_cov", "estimate_status", "crlb_true_m", "rmse_m", "objective_value", "active_constraints"]
        {
            assert_eq!(s[key], l[key], "{label}: step {k} {key}");
        }
        assert_eq!(s["plan_ms"].is_null(), l["plan_ms"].is_null(), "{label}: step {k} plan_ms presence");
    }
}

/// Processes whose command line mentions `needle` (children are started with `--domain <needle>`).
fn processes_mentioning(needle: &str) -> Vec<String> {
    let me = std::process::id().to_string();
    let mut found = Vec::new();
    for entry in std::fs::read_dir("/proc").expect("/proc") {
        let Ok(entry) = entry else { continue };
        let name = entry.file_name().to_string_lossy().to_string();
        if !name.bytes().all(|b| b.is_ascii_digit()) || name == me {
            continue;
        }
        let Ok(cmdline) = std::fs::read(entry.path().join("cmdline")) else { continue };
        let cmdline = String::from_utf8_lossy(&cmdline).replace('\0', " ");
        if cmdline.contains(needle) {
            found.push(format!("{name}: {cmdline}"));
        }
    }
    found
}

/// Files under `dir` (recursively) whose name or content mentions `needle`.
fn files_mentioning(dir: &Path, needle: &str, out: &mut Vec<String>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for entry in entries.flatten() {
        let path = entry.path();
        let Ok(meta) = entry.metadata() else { continue };
        if meta.is_dir() {
            files_mentioning(&path, needle, out);
        } else if path.to_string_lossy().contains(needle) {
            out.push(path.display().to_string());
        } else if meta.len() < 1 << 20
            && let Ok(bytes) = std::fs::read(&path)
            && bytes.windows(needle.len()).any(|w| w == needle.as_bytes())
        {
            out.push(path.display().to_string());
        }
    }
}

/// No process and no iceoryx2 resource of `domain` is left.
///
/// iceoryx2 0.10 keeps its state in the shared-memory filesystem (`/dev/shm/iox2_*`: service dynamic
/// configs, data segments, event and connection files) and in `<temp>/iceoryx2/` (`services/*.service`,
/// the static configs, which contain the service names; `nodes/<id>/`, whose `iox2_node.details` contains
/// the node name). The files are named after hashes, so the domain is searched in names *and* contents;
/// iceoryx2's own node and service lists are checked too (`uavloc process resources`).
fn assert_nothing_left(domain: &str) {
    // The launcher has reaped its children before exiting; allow the kernel a moment to drop them.
    let deadline = Instant::now() + Duration::from_secs(2);
    let mut procs = processes_mentioning(domain);
    while !procs.is_empty() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(20));
        procs = processes_mentioning(domain);
    }
    assert!(procs.is_empty(), "processes of {domain} are still running: {procs:#?}");

    let mut files = Vec::new();
    files_mentioning(&std::env::temp_dir().join("iceoryx2"), domain, &mut files);
    files_mentioning(Path::new("/dev/shm"), domain, &mut files);
    assert!(files.is_empty(), "iceoryx2 files of {domain} are left: {files:#?}");

    let listed = json_of(&["process", "resources", "--domain", domain]);
    assert_eq!(listed["nodes"], Value::Array(vec![]), "nodes of {domain}: {listed}");
    assert_eq!(listed["services"], Value::Array(vec![]), "services of {domain}: {listed}");
}

fn launch(domain: &str, extra: &[&str]) -> (Value, Duration) {
    let mut args = vec!["launch", "--headless", "--json", "--domain", domain];
    args.extend_from_slice(extra);
    let start = Instant::now();
    let run = json_of(&args);
    (run, start.elapsed())
}

#[test]
fn six_steps_equal_simulate_for_analytical_and_mc() {
    for objective in ["analytical", "mc"] {
        let d = domain(&format!("six-{objective}"));
        let (run, _) = launch(&d, &["--steps", "6", "--objective", objective]);
        let sim = json_of(&["simulate", "--json", "--steps", "6", "--objective", objective]);
        assert_eq!(run["steps"].as_array().unwrap().len(), 7, "steps 0..=6");
        assert_same_run(&sim, &run, objective);
        assert_eq!(run["rejected"].as_u64(), Some(0), "{objective}: rejected");
        assert_eq!(run["restarts"].as_u64(), Some(0), "{objective}: restarts");
        assert_nothing_left(&d);
    }
}

#[test]
fn the_default_24_step_run_equals_simulate() {
    let d = domain("default");
    let (run, took) = launch(&d, &[]);
    let sim = json_of(&["simulate", "--json"]);
    assert_eq!(run["steps"].as_array().unwrap().len(), 25, "the paper's 24 steps plus step 0");
    assert_same_run(&sim, &run, "default");
    assert_eq!(run["rejected"].as_u64(), Some(0));
    assert_eq!(run["restarts"].as_u64(), Some(0));
    assert!(took < Duration::from_secs(20), "a 24-step launch took {took:?}");
    assert_nothing_left(&d);
}

#[test]
fn the_table_and_a_second_seed() {
    // Another seed and solver through the table output: it runs and reports the run.
    let d = domain("table");
    let out = uavloc(&["launch", "--headless", "--steps", "2", "--seed", "7", "--solver", "ga", "--domain", &d]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for expected in [d.as_str(), "analytical / ga", "final CRLB at truth", "rejected messages", "restarts"] {
        assert!(text.contains(expected), "missing {expected:?} in:\n{text}");
    }
    assert_nothing_left(&d);
}

#[test]
fn controlled_scenarios_and_bad_domains_are_refused() {
    let dir = std::env::temp_dir().join(format!("uavloc-launch-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("controlled.toml");
    std::fs::write(&file, "target = \"controlled\"\n").unwrap();
    let out = uavloc(&["launch", "--headless", "--scenario", file.to_str().unwrap(), "--domain", &domain("ctl")]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("controlled") && err.contains("simulate"), "{err}");
    let out = uavloc(&["launch", "--domain", "no/slash"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("invalid domain"));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_domain_in_use_is_refused() {
    use std::io::{BufRead, BufReader};
    use std::process::Stdio;

    let d = domain("busy");
    // A stand-alone estimator of the domain, started by hand.
    let mut estimator = Command::new(env!("CARGO_BIN_EXE_uavloc"))
        .args(["process", "estimator", "--domain", &d, "--quiet", "--supervised"])
        .stdout(Stdio::piped())
        .spawn()
        .expect("start an estimator");
    let mut ready = String::new();
    BufReader::new(estimator.stdout.take().unwrap()).read_line(&mut ready).unwrap();
    assert_eq!(ready.trim(), "ready");
    // While it runs, its resources are visible the way `assert_nothing_left` looks for them.
    let mut files = Vec::new();
    files_mentioning(&std::env::temp_dir().join("iceoryx2"), &d, &mut files);
    assert!(!files.is_empty(), "the leftover check would not see a live node of {d}");
    let listed = json_of(&["process", "resources", "--domain", &d]);
    assert_eq!(listed["nodes"][0]["name"].as_str(), Some(format!("{d}/estimator").as_str()), "{listed}");
    let out = uavloc(&["launch", "--headless", "--steps", "1", "--domain", &d]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("in use") && err.contains(&format!("{d}/estimator")), "{err}");
    // SIGTERM: the estimator exits cleanly and takes its iceoryx2 resources with it.
    // SAFETY: kill(2) on our own child, not yet reaped.
    unsafe { libc::kill(estimator.id() as libc::pid_t, libc::SIGTERM) };
    assert!(estimator.wait().unwrap().success());
    assert_nothing_left(&d);
}
