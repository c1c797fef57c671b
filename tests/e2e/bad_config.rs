//! Malformed scenarios and command-line flags, through every entry point a user types (`simulate`,
//! `launch`, the process binaries via `uavloc process <role>`, `bench`, the calculator): each is refused
//! with exactly one `error:` line on stderr that names the problem (the key or the flag), exit code 2,
//! nothing on stdout, and no process started.

use crate::common;

use common::{scratch, uavloc};
use std::process::Command;

/// Runs `args` and checks the refusal; `needle` must appear in the error line.
fn refused(args: &[&str], needle: &str) {
    let out = uavloc(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{args:?} should exit 2; stderr: {err}");
    let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "{args:?}: one line expected, got: {err}");
    assert!(lines[0].starts_with("error:"), "{args:?}: {err}");
    assert!(lines[0].contains(needle), "{args:?}: {needle:?} not named in: {}", lines[0]);
    assert!(out.stdout.is_empty(), "{args:?}: stdout {}", String::from_utf8_lossy(&out.stdout));
}

/// (scenario file content, what the error must name).
const BAD_SCENARIOS: [(&str, &str); 45] = [
    ("speeed = 10.0", "speeed"),                                                // unknown key
    ("[pso]\nparticle = 40", "particle"),                                       // unknown key in a table
    ("speed = \"fast\"", "speed"),                                              // wrong type
    ("steps = 2.5", "steps"),                                                   // wrong type
    ("steps = -1", "steps"),                                                    // negative count
    ("speed = -5.0", "speed"),                                                  // negative speed
    ("speed = 0.0", "speed"),                                                   // zero speed
    ("speed = nan", "speed"),                                                   // NaN in a file
    ("emitter = [nan, 0.0]", "emitter"),                                        // NaN in a file
    ("sigma = nan", "sigma"),                                                   // NaN in a file
    ("uavs = [[0.0, 0.0], [1000.0, 0.0], [0.0, inf]]", "uavs"),                 // infinity
    ("delta_alpha_deg = 0", "delta_alpha_deg"),                                 // Δα outside (0, π]
    ("delta_alpha_deg = 181", "delta_alpha_deg"),                               // Δα outside (0, π]
    ("delta_alpha_deg = -30", "delta_alpha_deg"),                               // Δα outside (0, π]
    ("uavs = [[0.0, 0.0], [1000.0, 0.0]]", "uavs"),                             // fewer than 3 UAVs
    ("uavs = [[0,0],[1,0],[2,0],[3,0],[4,0],[5,0],[6,0],[7,0],[8,0]]", "uavs"), // more than 8
    ("uavs = [[0.0, 0.0], [1000.0, 0.0], [0.0, 0.0]]", "uavs"),                 // coincident UAVs
    ("sigma = [1.0, -1.0, 1.0]", "sigma"),                                      // negative σ
    ("sigma = [1.0, 1.0]", "sigma"),                                            // σ list of the wrong length
    ("dt = 0", "dt"),
    ("steps = 0", "steps"),
    ("headings_deg = [0.0, 1.0]", "headings_deg"), // wrong length
    ("target = \"oracle\"", "target"),
    ("mc_scheme = \"bogus\"", "mc_scheme"),
    ("[pso]\nparticles = 0", "pso.particles"),
    ("[ga]\nmutation_rate = 2.0", "ga.mutation_rate"),
    ("l_min = -1", "l_min"),
    ("standoff_confidence = 1.0", "standoff_confidence"),
    ("standoff_confidence = -0.1", "standoff_confidence"),
    ("process_noise_accel = -0.5", "process_noise_accel"),
    ("velocity_prior_sigma = 0", "velocity_prior_sigma"),
    ("emitter_velocity = [1.0, nan]", "emitter_velocity"),
    ("estimator = \"kalman\"", "estimator"),
    ("emitter_model = \"zigzag\"", "emitter_model"),
    ("speed = ", "speed"), // syntax error
    // Finite but beyond the plane model's lengths: each made simulate or emitter-sim panic (NaN ranges
    // from coordinates that overflowed, a heading tolerance above the polish step).
    ("speed = 1e300", "speed"),
    ("dt = 1e300", "speed × dt"),
    ("emitter_velocity = [1e300, 0.0]", "emitter_velocity"),
    // Within the per-step bound but out of the extent at step 1: the run left the model's extent silently.
    ("emitter_velocity = [999000.0, 0.0]", "emitter_velocity"),
    ("[gradient]\ntolerance = 1e300", "gradient.tolerance"),
    ("sigma = 1e-300", "sigma"),
    // Counts beyond what can be held or computed: each aborted the run on a failed allocation.
    ("[pso]\nparticles = 100000000000", "pso.particles"),
    ("mc_samples = 100000000000", "mc_samples"),
    ("[ga]\npopulation = 100000000000", "ga.population"),
    ("rmse_resamples = 100000000000", "rmse_resamples"),
];

#[test]
fn malformed_scenarios_are_refused_by_every_entry_point() {
    let _scenario = common::scenario(module_path!());
    let dir = scratch("bad-config");
    // Each file through one entry point, rotating, so every entry point sees several kinds of error.
    let entry_points: [&[&str]; 5] = [
        &["simulate", "--steps", "1"],
        &["launch", "--headless", "--steps", "1"],
        &["process", "planner"],
        &["process", "emitter-sim"],
        &["process", "monitor"],
    ];
    for (i, (text, needle)) in BAD_SCENARIOS.iter().enumerate() {
        let file = dir.join(format!("bad-{i}.toml"));
        std::fs::write(&file, text).unwrap();
        let mut args: Vec<&str> = entry_points[i % entry_points.len()].to_vec();
        let path = file.to_str().unwrap().to_string();
        args.extend(["--scenario", &path]);
        refused(&args, needle);
    }
    // Not a scenario at all: a missing file, a directory, bytes that are not UTF-8.
    refused(&["simulate", "--scenario", "/nonexistent/uavloc.toml"], "/nonexistent/uavloc.toml");
    let binary = dir.join("binary.toml");
    std::fs::write(&binary, [0xff, 0xfe, 0x00, 0x9c]).unwrap();
    refused(&["launch", "--headless", "--scenario", binary.to_str().unwrap()], "binary.toml");
    refused(&["simulate", "--scenario", dir.to_str().unwrap()], "scenario");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn malformed_flags_are_refused() {
    let _scenario = common::scenario(module_path!());
    let cases: &[(&[&str], &str)] = &[
        (&["launch", "--steps", "-3"], "-3"),
        (&["launch", "--steps=-3"], "--steps"),
        (&["launch", "--steps", "many"], "--steps"),
        (&["launch", "--seed", "abc"], "--seed"),
        (&["launch", "--objective", "nonsense"], "--objective"),
        (&["launch", "--estimator", "kalman"], "--estimator"),
        (&["simulate", "--estimator", "kalman"], "--estimator"),
        (&["process", "estimator", "--process-noise-accel=-1"], "--process-noise-accel"),
        (&["process", "estimator", "--velocity-prior-sigma", "0"], "--velocity-prior-sigma"),
        (&["process", "estimator", "--interval-s", "1e300"], "--interval-s"),
        (&["launch", "--solver", "simplex"], "--solver"),
        (&["launch", "--transport", "pigeon"], "--transport"),
        (&["launch", "--wait", "sometimes"], "--wait"),
        (&["launch", "--domain", "a/b"], "domain"),
        (&["launch", "--mode", "fast"], "--mode"),
        (&["launch", "--mode", "realtime", "--time-scale", "0"], "time-scale"),
        (&["launch", "--mode", "realtime", "--time-scale", "nan"], "time-scale"),
        (&["launch", "--mode", "realtime", "--time-scale", "-2"], "time-scale"),
        (&["launch", "--mode", "realtime", "--step-delay-ms", "5"], "step-delay-ms"),
        (&["launch", "--command-timeout-s=-1"], "command-timeout-s"),
        (&["launch", "--no-such-flag"], "--no-such-flag"),
        (&["simulate", "--steps", "0"], "steps"),
        (&["process", "planner", "--objective", "x"], "--objective"),
        (&["process", "estimator", "--transport", "tcp"], "--transport"),
        (&["process", "emitter-sim", "--retry-interval-ms", "0"], "retry-interval-ms"),
        (&["process", "emitter-sim", "--monitor-window", "256"], "monitor-window"),
        // Hours per step (it would run as asked). The process first: without the check it
        // fails at once (nothing to connect to within 0 s), where the launch would run for hours.
        (&["process", "emitter-sim", "--step-delay-ms", "60001", "--connect-timeout-s", "0"], "step-delay-ms"),
        (&["launch", "--step-delay-ms", "36000000"], "step-delay-ms"),
        // The monitor's outputs are checked before it waits for a run (it used to learn at the end).
        (&["process", "monitor", "--domain", "bad-config-out", "--out", "/proc/version"], "--out"),
        (&["process", "monitor", "--domain", "bad-config-out", "--record", "/proc/none/run.json"], "--record"),
        (&["bench", "latency", "--cores", "5000"], "--cores"),
        // Before the experiments run (`paper all` takes long; its tables are written at the end).
        (&["paper", "all", "--out", "/proc/version"], "--out"),
        // The launch's own checks, before any child starts (before: the monitor's exit 2, then the launch's
        // "stopped unexpectedly", exit 1).
        (&["launch", "--headless", "--steps", "2", "--log", "/proc/none/run.jsonl"], "--log"),
        (&["launch", "--headless", "--steps", "2", "--stamps", "/tmp"], "--stamps"),
        (&["bench", "latency", "--steps", "10", "--out", "/proc/version"], "--out"),
        (&["bench", "planner", "--steps", "0"], "--steps"),
        (&["crlb", "--uav", "0,0", "--uav", "1000,0", "--uav", "0,1000", "--target", "5,5", "--sigma", "-1"], "sigma"),
        (&["crlb", "--uav", "0,0", "--uav", "1000,0", "--target", "5,5", "--sigma", "1"], "3"),
        (&["crlb", "--uav", "0,0", "--uav", "0,0", "--uav", "0,1000", "--target", "5,5", "--sigma", "1"], "coincide"),
        (&["crlb", "--uav", "0,nan", "--uav", "1000,0", "--uav", "0,1000", "--target", "5,5", "--sigma", "1"], "--uav"),
        // Beyond the plane model (before: reported as three collinear UAVs or a singular FIM).
        (
            &["crlb", "--uav", "1e300,0", "--uav", "1000,0", "--uav", "0,1000", "--target", "5,5", "--sigma", "1"],
            "extent",
        ),
        (
            &["crlb", "--uav", "0,0", "--uav", "1000,0", "--uav", "0,1000", "--target", "5,5", "--sigma", "1e300"],
            "sigma",
        ),
        // Counts beyond what can be held or computed (`simulate --steps 10¹¹` would build a
        // record of that many steps; the calculators' below).
        (&["simulate", "--steps", "100000000000"], "steps"),
    ];
    for (args, needle) in cases {
        refused(args, needle);
    }
    // usize::MAX Monte Carlo samples panicked `global` ("capacity overflow"), 10¹¹ aborted it.
    let triangle = ["--uav", "0,0", "--uav", "1000,0", "--uav", "0,1000"];
    let global = ["--estimate", "3000,3000", "--cov", "100,0,100", "--sigma", "10", "--method", "mc"];
    refused(&[&["global"][..], &triangle, &global, &["--samples", "18446744073709551615"]].concat(), "--samples");
    refused(
        &[&["rmse"][..], &triangle, &["--target", "5,5", "--sigma", "1", "--draws", "100000000000"]].concat(),
        "--draws",
    );
}

/// A bad `UAVLOC_DOMAIN` is named as such, not as a `--domain` the user never gave.
#[test]
fn a_bad_domain_from_the_environment_is_named_as_such() {
    let _scenario = common::scenario(module_path!());
    for args in [&["launch", "--headless", "--steps", "1"][..], &["process", "planner"], &["swap", "planner"]] {
        let out = Command::new(common::UAVLOC).args(args).env("UAVLOC_DOMAIN", "bad/domain").output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("UAVLOC_DOMAIN") && !err.contains("--domain:"), "{args:?}: {err}");
    }
}

/// A `UAVLOC_UDS_DIR` the socket transport cannot use — a directory that cannot be created, or one so long
/// that a socket path under it would not fit a Unix socket address — is refused up front as bad input
/// (exit 2, one line naming `UAVLOC_UDS_DIR`), by `launch` before any child starts and by a process on its
/// own. Before, the first process to open a topic failed (exit 1) naming only the topic and the system's
/// error ("creating the socket directory on \"d/control\" failed: No such file or directory").
#[test]
fn an_unusable_socket_directory_is_named_as_such() {
    let _scenario = common::scenario(module_path!());
    let long = std::env::temp_dir().join("u".repeat(90));
    for dir in [std::path::PathBuf::from("/proc/uavloc-no-such-dir"), long] {
        for args in [
            &["launch", "--headless", "--steps", "1", "--transport", "uds"][..],
            &["process", "planner", "--transport", "uds"],
        ] {
            let out = Command::new(common::UAVLOC).args(args).env("UAVLOC_UDS_DIR", &dir).output().unwrap();
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "{args:?} {}: {err}", dir.display());
            assert_eq!(err.trim().lines().count(), 1, "{args:?}: {err}");
            assert!(err.contains(&format!("UAVLOC_UDS_DIR={}", dir.display())), "{args:?}: {err}");
        }
        assert!(!dir.exists() || dir.starts_with("/proc"), "{} was created", dir.display());
    }
}
