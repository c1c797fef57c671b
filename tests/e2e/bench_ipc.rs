//! End-to-end test of `uavloc bench ipc`: the real binary spawns its real echo process and times real
//! iceoryx2 and Unix-socket transfers; checked are the JSON (a row per transport × size, consistent order
//! statistics, CPU per message, the ratios), the files of `--out`, that nothing of the sweep is left, and
//! the exit code on bad input. No assertion is made on how fast anything is.

use crate::common;

use std::process::Command;

use common::UAVLOC;
use serde_json::Value;

/// Runs `uavloc <args>` to its end; its output and the prefix of its sweep's names (`uavloc-ipc-<pid>-`:
/// what must be gone afterwards — a prefix of this sweep alone, as the tests run side by side).
fn sweep(args: &[&str]) -> (std::process::Output, String) {
    let child = Command::new(UAVLOC)
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let prefix = format!("uavloc-ipc-{}-", child.id());
    (child.wait_with_output().unwrap(), prefix)
}

fn num(v: &Value, key: &str) -> f64 {
    v[key].as_f64().unwrap_or_else(|| panic!("{key} is not a number in {v}"))
}

#[test]
fn a_small_sweep_reports_every_transport_and_size() {
    let _scenario = common::scenario(module_path!());
    let dir = common::scratch("bench-ipc");
    let (out, prefix) =
        sweep(&["bench", "ipc", "--messages", "60", "--sizes", "256,65536", "--json", "--out", dir.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report: Value = serde_json::from_slice(&out.stdout).unwrap();
    common::assert_names_the_machine(&report);
    let rows = report["rows"].as_array().unwrap();
    let got: Vec<(&str, u64)> =
        rows.iter().map(|r| (r["transport"].as_str().unwrap(), r["size_bytes"].as_u64().unwrap())).collect();
    assert_eq!(got, vec![("iceoryx2", 256), ("iceoryx2", 65536), ("uds", 256), ("uds", 65536)]);
    for r in rows {
        assert_eq!(r["n"].as_u64(), Some(60), "{r}");
        let (p50, p99, max) = (num(r, "p50_us"), num(r, "p99_us"), num(r, "max_us"));
        assert!(p50 > 0.0 && p50 <= p99 * 1.001 && p99 <= max * 1.001, "{r}");
        assert!(num(r, "cpu_us_per_message") > 0.0, "{r}");
    }
    let ratios = report["ratios"].as_array().unwrap();
    assert_eq!(ratios.len(), 2);
    let (i, u) = (&rows[0], &rows[2]);
    assert!((num(&ratios[0], "p50") - num(u, "p50_us") / num(i, "p50_us")).abs() < 1e-9, "{}", ratios[0]);
    for f in ["ipc.svg", "ipc.png", "ipc.json"] {
        assert!(std::fs::metadata(dir.join(f)).is_ok_and(|m| m.len() > 0), "{f} missing");
    }
    assert_eq!(report["wait"], "block");
    // The echo processes and their services are gone (the sweep's names start with `uavloc-ipc-<pid>-`).
    common::assert_nothing_left(&prefix);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_busy_polling_sweep_times_every_transport_and_size_too() {
    // --wait spin: both ends poll (the socket non-blocking); a payload larger than a socket's buffer is
    // written and read in parts.
    let _scenario = common::scenario(module_path!());
    let (out, prefix) =
        sweep(&["bench", "ipc", "--wait", "spin", "--messages", "40", "--sizes", "256,1048576", "--json"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["wait"], "spin");
    let rows = report["rows"].as_array().unwrap();
    let got: Vec<(&str, u64, u64)> = rows
        .iter()
        .map(|r| (r["transport"].as_str().unwrap(), r["size_bytes"].as_u64().unwrap(), r["n"].as_u64().unwrap()))
        .collect();
    assert_eq!(got, vec![("iceoryx2", 256, 40), ("iceoryx2", 1048576, 40), ("uds", 256, 40), ("uds", 1048576, 40)]);
    for r in rows {
        let (p50, p99, max) = (num(r, "p50_us"), num(r, "p99_us"), num(r, "max_us"));
        assert!(p50 > 0.0 && p50 <= p99 * 1.001 && p99 <= max * 1.001, "{r}");
    }
    common::assert_nothing_left(&prefix);
}

#[test]
fn bad_sweeps_are_one_line_errors_with_exit_2() {
    let _scenario = common::scenario(module_path!());
    for args in [
        &["bench", "ipc", "--sizes", "8"][..],
        &["bench", "ipc", "--sizes", "256,999999999999"],
        &["bench", "ipc", "--messages", "0"],
        &["bench", "ipc", "--cores", "0"],
        &["bench", "ipc", "--sizes", "lots"],
        &["bench", "ipc", "--wait", "spin-then-block"],
    ] {
        let out = Command::new(UAVLOC).args(args).output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert_eq!(stderr.trim().lines().count(), 1, "{args:?}: {stderr}");
    }
}
