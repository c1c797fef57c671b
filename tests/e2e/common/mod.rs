//! Helpers shared by the process-pipeline tests (`launch_default`, `bad_messages`, `shutdown`,
//! `crash_restart`, `swap_planner`): run `uavloc`, start a launch in the background, follow its JSONL log,
//! compare a run with `uavloc simulate`, find the processes of a domain, check that nothing is left.
//!
//! Every test runs its pipelines in its own domain (`<prefix>-<test pid>-<tag>`), so the tests run in
//! parallel with each other and with anything else on the machine.

#![allow(dead_code)]

pub mod autopilots;

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

pub const UAVLOC: &str = env!("CARGO_BIN_EXE_uavloc");

pub fn uavloc(args: &[&str]) -> std::process::Output {
    Command::new(UAVLOC).args(args).output().expect("run uavloc")
}

pub fn json_of(args: &[&str]) -> Value {
    let out = uavloc(args);
    assert!(out.status.success(), "uavloc {args:?} failed ({}): {}", out.status, String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!("uavloc {args:?}: stdout is not JSON ({e}): {}", String::from_utf8_lossy(&out.stdout))
    })
}

/// A domain unique to this test process and `tag`.
pub fn domain(prefix: &str, tag: &str) -> String {
    format!("{prefix}-{}-{tag}", std::process::id())
}

/// A fresh scratch directory for one test.
pub fn scratch(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("uavloc-test-{}-{tag}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The f64 bits of every number in a JSON value (arrays flattened; a null — no estimate yet — as NaN's).
fn bits(v: &Value, label: &str) -> Vec<u64> {
    let mut out = Vec::new();
    let mut stack = vec![v.clone()];
    while let Some(x) = stack.pop() {
        match x {
            Value::Array(items) => stack.extend(items),
            Value::Number(n) => out.push(n.as_f64().unwrap().to_bits()),
            Value::Null => out.push(f64::NAN.to_bits()),
            other => panic!("{label}: unexpected {other}"),
        }
    }
    out
}

/// Every step field of `simulate` must be equal in the launch — compared as parsed f64 with `==` (the
/// workspace's serde_json parses floats exactly), trajectory and estimates bit for bit — except the
/// wall-clock planning time.
pub fn assert_same_run(sim: &Value, launch: &Value, label: &str) {
    for key in ["objective", "solver", "seed", "emitter", "scenario"] {
        assert_eq!(sim[key], launch[key], "{label}: {key}");
    }
    // The safety along the arcs, run totals included (the certificate's word crossed the wire).
    for key in ["true_spacing_violations", "true_standoff_violations", "uncertified_steps", "min_pair_m"] {
        assert_eq!(sim[key], launch[key], "{label}: {key}");
    }
    assert_same_steps(sim, launch, label);
}

/// [`assert_same_run`] for the steps only (a run whose planner was swapped has another solver name).
pub fn assert_same_steps(sim: &Value, launch: &Value, label: &str) {
    let (a, b) = (sim["steps"].as_array().unwrap(), launch["steps"].as_array().unwrap());
    assert_eq!(a.len(), b.len(), "{label}: number of steps");
    for (i, (s, l)) in a.iter().zip(b).enumerate() {
        let k = &s["step"];
        assert_eq!(k, &l["step"], "{label}");
        for key in ["uavs", "headings_rad", "estimate"] {
            assert_eq!(s[key], l[key], "{label}: step {k} {key}");
            assert_eq!(bits(&s[key], label), bits(&l[key], label), "{label}: step {k} {key} bits");
        }
        for key in ["estimate_cov", "estimate_status", "crlb_true_m", "rmse_m", "objective_value"] {
            assert_eq!(s[key], l[key], "{label}: step {k} {key}");
        }
        // The labels are equal, `violated` / `binding` included (both runs record the wire form).
        assert_eq!(s["active_constraints"], l["active_constraints"], "{label}: step {k} active_constraints");
        // What the receivers delivered: heard, outliers, silent, and the world's reflections (the truth
        // carries them to the monitor).
        for key in ["pcrlb_m", "estimate_error_m", "nees", "min_true_distance_m", "truth", "receiver"] {
            assert_eq!(s[key], l[key], "{label}: step {k} {key}");
        }
        // The safety of the interval to the next step (none after a record's last step: a partial run's
        // last step has no next one in its record, though the longer run's has).
        if i + 1 < b.len() {
            assert_eq!(s["safety"], l["safety"], "{label}: step {k} safety");
        }
        assert_eq!(s["plan_ms"].is_null(), l["plan_ms"].is_null(), "{label}: step {k} plan_ms presence");
    }
}

/// Processes (pid, command line) whose command line mentions `needle` (children are started with
/// `--domain <needle>`), other than this test process.
pub fn processes_mentioning(needle: &str) -> Vec<(u32, String)> {
    let me = std::process::id();
    let mut found = Vec::new();
    for entry in std::fs::read_dir("/proc").expect("/proc") {
        let Ok(entry) = entry else { continue };
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else { continue };
        if pid == me {
            continue;
        }
        let Ok(cmdline) = std::fs::read(entry.path().join("cmdline")) else { continue };
        let cmdline = String::from_utf8_lossy(&cmdline).replace('\0', " ");
        if cmdline.contains(needle) {
            found.push((pid, cmdline));
        }
    }
    found
}

/// Whether the command line `c` runs on `domain` as a whole argument: `crash-1-estimator` is not
/// `crash-1-estimator-planner` (two crash tests run at once).
fn of_domain(c: &str, domain: &str) -> bool {
    let args: Vec<&str> = c.split(' ').collect();
    args.iter().any(|a| *a == format!("--domain={domain}")) || args.windows(2).any(|w| w == ["--domain", domain])
}

/// The pid of the running `uavloc process <role>` of `domain` (exactly one expected).
pub fn pid_of(domain: &str, role: &str) -> Option<u32> {
    let needle = format!("process {role} ");
    // The domain as a whole argument: `crash-1-estimator` is not `crash-1-estimator-planner`.
    let procs: Vec<_> = processes_mentioning(domain)
        .into_iter()
        .filter(|(pid, c)| c.contains(&needle) && of_domain(c, domain) && !is_zombie(*pid))
        .collect();
    assert!(procs.len() <= 1, "more than one {role} of {domain}: {procs:?}");
    procs.first().map(|(pid, _)| *pid)
}

/// Whether the process has exited but is not reaped yet.
pub fn is_zombie(pid: u32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .ok()
        .and_then(|s| s.rsplit_once(") ").map(|(_, rest)| rest.starts_with('Z')))
        .unwrap_or(false)
}

/// Whether `pid` runs (exists and is not a zombie waiting to be reaped).
pub fn is_alive(pid: u32) -> bool {
    std::path::Path::new(&format!("/proc/{pid}")).exists() && !is_zombie(pid)
}

/// Sends `signal` to `pid`.
pub fn kill(pid: u32, signal: i32) {
    // SAFETY: kill(2) with a pid read from /proc or of our own child; a stale pid at worst gets ESRCH.
    let rc = unsafe { libc::kill(pid as libc::pid_t, signal) };
    assert_eq!(rc, 0, "kill({pid}, {signal}) failed");
}

/// Files under `dir` (recursively) whose name or content mentions `needle`.
pub fn files_mentioning(dir: &Path, needle: &str, out: &mut Vec<String>) {
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

/// No process and no iceoryx2 resource of `domain` is left: no command line mentions it, no file of
/// iceoryx2 (`/dev/shm`, `<temp>/iceoryx2/`, searched by name and content since iceoryx2 names its files
/// after hashes) mentions it, and iceoryx2's own node and service lists (`uavloc process resources`) have
/// nothing of it.
pub fn assert_nothing_left(domain: &str) {
    let deadline = Instant::now() + Duration::from_secs(3);
    let of_it = || -> Vec<(u32, String)> {
        processes_mentioning(domain).into_iter().filter(|(_, c)| of_domain(c, domain)).collect()
    };
    let mut procs = of_it();
    while !procs.is_empty() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(20));
        procs = of_it();
    }
    assert!(procs.is_empty(), "processes of {domain} are still running: {procs:#?}");

    // The domain's service names start `<domain>/` (not another domain that begins with this one).
    let needle = format!("{domain}/");
    let mut files = Vec::new();
    files_mentioning(&std::env::temp_dir().join("iceoryx2"), &needle, &mut files);
    files_mentioning(Path::new("/dev/shm"), &needle, &mut files);
    assert!(files.is_empty(), "iceoryx2 files of {domain} are left: {files:#?}");

    let listed = json_of(&["process", "resources", "--domain", domain]);
    assert_eq!(listed["nodes"], Value::Array(vec![]), "nodes of {domain}: {listed}");
    assert_eq!(listed["services"], Value::Array(vec![]), "services of {domain}: {listed}");
}

/// The longest a test waits for a launch to end ([`Launch::finish`]); the longest launch of the suite
/// (the long kill storm) takes ≈ 90 s.
pub const FINISH_TIMEOUT: Duration = Duration::from_secs(240);

/// A `uavloc launch --headless --json` running in the background, its stderr going to a file.
pub struct Launch {
    pub child: Child,
    pub domain: String,
    pub log: PathBuf,
    pub stderr: PathBuf,
}

impl Launch {
    /// Starts `uavloc launch --headless --json --domain D --log DIR/run.jsonl <extra>`.
    pub fn start(domain: &str, dir: &Path, extra: &[&str]) -> Launch {
        let log = dir.join("run.jsonl");
        let stderr = dir.join("launch.stderr");
        let mut args = vec!["launch", "--headless", "--json", "--domain", domain, "--log", log.to_str().unwrap()];
        args.extend_from_slice(extra);
        let child = Command::new(UAVLOC)
            .args(&args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(std::fs::File::create(&stderr).unwrap())
            .spawn()
            .expect("start uavloc launch");
        Launch { child, domain: domain.to_string(), log, stderr }
    }

    /// The events of the JSONL log so far.
    pub fn events(&self) -> Vec<Value> {
        read_events(&self.log)
    }

    /// Waits until the monitor has logged step `step` (panics after `timeout` or if the launch exits).
    pub fn wait_for_step(&mut self, step: u64, timeout: Duration) {
        let deadline = Instant::now() + timeout;
        loop {
            if self.events().iter().any(|e| e["event"] == "step" && e["step"].as_u64().is_some_and(|s| s >= step)) {
                return;
            }
            if let Ok(Some(status)) = self.child.try_wait() {
                panic!("the launch ended ({status}) before step {step}:\n{}", self.stderr_text());
            }
            assert!(Instant::now() < deadline, "step {step} not logged within {timeout:?}:\n{}", self.stderr_text());
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    pub fn stderr_text(&self) -> String {
        std::fs::read_to_string(&self.stderr).unwrap_or_default()
    }

    /// Waits for the launch to end; its exit status and stdout. A launch still running after
    /// [`FINISH_TIMEOUT`] is stopped (SIGTERM, then SIGKILL) and the test fails with its stderr and the end
    /// of its log: a hang is a failure with a diagnosis, never a CI run that sits out its time limit.
    pub fn finish(mut self) -> (std::process::ExitStatus, String, String) {
        use std::io::Read as _;
        let mut stdout = self.child.stdout.take().expect("piped stdout");
        let reader = std::thread::spawn(move || {
            let mut out = Vec::new();
            let _ = stdout.read_to_end(&mut out);
            out
        });
        let status = match exit_within(&mut self.child, FINISH_TIMEOUT) {
            Some(status) => status,
            None => {
                kill(self.child.id(), libc::SIGTERM);
                let _ = exit_within(&mut self.child, Duration::from_secs(10));
                let _ = self.child.kill();
                let _ = self.child.wait();
                let log = std::fs::read_to_string(&self.log).unwrap_or_default();
                let lines: Vec<&str> = log.lines().collect();
                panic!(
                    "the launch did not end within {FINISH_TIMEOUT:?}; stopped it.\nstderr:\n{}\nlog (last 40 lines):\n{}",
                    self.stderr_text(),
                    lines[lines.len().saturating_sub(40)..].join("\n")
                );
            }
        };
        let out = reader.join().unwrap_or_default();
        (status, String::from_utf8_lossy(&out).to_string(), self.stderr_text())
    }

    /// Waits for a successful end and returns its JSON.
    pub fn finish_json(self) -> Value {
        let (status, stdout, stderr) = self.finish();
        assert!(status.success(), "the launch failed ({status}):\n{stderr}");
        serde_json::from_str(&stdout).unwrap_or_else(|e| panic!("not JSON ({e}): {stdout}\n{stderr}"))
    }
}

/// `uavloc process <role> --domain D --supervised --quiet <extra>`, after it printed `ready`.
pub fn start_process(role: &str, d: &str, extra: &[&str]) -> Child {
    start_supervised(role, d, extra, Stdio::null())
}

/// As [`start_process`], its stderr piped too (for what it says at its end).
pub fn start_process_keeping_output(role: &str, d: &str, extra: &[&str]) -> Child {
    start_supervised(role, d, extra, Stdio::piped())
}

fn start_supervised(role: &str, d: &str, extra: &[&str], stderr: Stdio) -> Child {
    use std::io::Read as _;
    let mut child = Command::new(UAVLOC)
        .args(["process", role, "--domain", d, "--supervised", "--quiet"])
        .args(extra)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(stderr)
        .spawn()
        .expect("start a process");
    // Byte by byte up to the first newline: nothing after it is taken from the pipe.
    let (mut line, mut byte) = (Vec::new(), [0u8]);
    let out = child.stdout.as_mut().unwrap();
    while out.read(&mut byte).unwrap() == 1 && byte[0] != b'\n' {
        line.push(byte[0]);
    }
    assert_eq!(String::from_utf8_lossy(&line).trim(), "ready", "{role}");
    child
}

/// Waits at most `timeout` for `child` to exit.
pub fn wait_exit(child: &mut Child, timeout: Duration, what: &str) -> std::process::ExitStatus {
    exit_within(child, timeout).unwrap_or_else(|| panic!("{what} did not exit within {timeout:?}"))
}

/// The exit status of `child` if it exits within `timeout`; `None` if it is still running then.
pub fn exit_within(child: &mut Child, timeout: Duration) -> Option<std::process::ExitStatus> {
    let deadline = Instant::now() + timeout;
    loop {
        if let Some(status) = child.try_wait().expect("wait for a child") {
            return Some(status);
        }
        if Instant::now() >= deadline {
            return None;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// The events of a JSONL log (incomplete last lines skipped).
pub fn read_events(path: &Path) -> Vec<Value> {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .collect()
}

/// Follows a growing file of lines (a launch's JSON-lines log): the live view's own reader.
#[allow(unused_imports)]
pub use uavloc::live::LogTail as LineTail;

/// Asserts that the `step` events of a launch's log name every step `0..=steps` exactly once (the
/// wrong ones, with how often they were logged, in the message).
pub fn assert_each_step_logged_once(events: &[Value], steps: u64, label: &str) {
    let mut logged: std::collections::BTreeMap<u64, usize> = std::collections::BTreeMap::new();
    for e in events.iter().filter(|e| e["event"] == "step") {
        *logged.entry(e["step"].as_u64().expect("a step event without a step")).or_default() += 1;
    }
    let wrong: Vec<(u64, usize)> = (0..=steps)
        .map(|k| (k, logged.get(&k).copied().unwrap_or(0)))
        .filter(|&(_, n)| n != 1)
        .chain(logged.range(steps + 1..).map(|(&k, &n)| (k, n)))
        .collect();
    assert!(wrong.is_empty(), "{label}: steps not logged exactly once (step, times): {wrong:?}");
}

/// The end of a launch that must have gone right: every step logged once in `DIR/run.jsonl`, the run
/// equal to `uavloc simulate --steps <steps>` bit for bit, nothing rejected, nothing of the domain left.
pub fn assert_complete_run_equals_simulate(run: &Value, dir: &Path, domain: &str, steps: u64, label: &str) {
    let events = read_events(&dir.join("run.jsonl"));
    assert_each_step_logged_once(&events, steps, label);
    let sim = json_of(&["simulate", "--json", "--steps", &steps.to_string()]);
    assert_same_run(&sim, run, label);
    assert_eq!(run["rejected"].as_u64(), Some(0), "{label}: {}", run["rejected_by"]);
    assert_nothing_left(domain);
}

/// The Python interpreter of the tests that drive uavloc from Python through the official iceoryx2
/// bindings (`examples/python/requirements.txt`): `$UAVLOC_PYTHON`, else the virtual environment
/// `target/pyenv`, made on first use (`python3 -m venv`, then `pip install -r` the requirements; `.ci/run`
/// makes it before the tests). Made in a private directory and renamed into place, so that test binaries
/// running at once do not trip over each other.
pub fn python() -> PathBuf {
    if let Some(p) = std::env::var_os("UAVLOC_PYTHON").filter(|p| !p.is_empty()) {
        return PathBuf::from(p);
    }
    // One test of this binary makes it; the others wait for it.
    static MAKING: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _one = MAKING.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let venv = root.join("target").join("pyenv");
    let py = venv.join("bin").join("python");
    let usable = |py: &Path| {
        Command::new(py)
            .args(["-c", "import iceoryx2, mcap, jsonschema, pymavlink, pymap3d"])
            .output()
            .is_ok_and(|o| o.status.success())
    };
    if usable(&py) {
        return py;
    }
    let tmp = root.join("target").join(format!("pyenv.{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    let run = |cmd: &mut Command, what: &str| {
        let out = cmd.output().unwrap_or_else(|e| panic!("{what}: {e}"));
        assert!(out.status.success(), "{what} failed: {}", String::from_utf8_lossy(&out.stderr));
    };
    run(Command::new("python3").args(["-m", "venv"]).arg(&tmp), "python3 -m venv (Python 3.11 or newer is needed)");
    run(
        Command::new(tmp.join("bin").join("pip"))
            .args(["install", "-q", "-r"])
            .arg(root.join("examples").join("python").join("requirements.txt")),
        "pip install -r examples/python/requirements.txt",
    );
    if std::fs::rename(&tmp, &venv).is_err() {
        let _ = std::fs::remove_dir_all(&tmp); // another test binary was first
    }
    assert!(usable(&py), "{} cannot import iceoryx2, mcap and jsonschema", py.display());
    py
}

/// Foxglove's published JSON schemas (`@foxglove/schemas` from the npm registry), one file per schema in
/// `target/foxglove-schemas`, fetched on first use by `examples/python/fetch_foxglove_schemas.sh`
/// (`.ci/run` fetches them before the tests).
pub fn foxglove_schemas() -> PathBuf {
    static FETCHING: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _one = FETCHING.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = root.join("target").join("foxglove-schemas");
    if dir.join("LocationFix.json").exists() {
        return dir;
    }
    let out = Command::new(root.join("examples/python/fetch_foxglove_schemas.sh"))
        .arg(&dir)
        .output()
        .expect("run examples/python/fetch_foxglove_schemas.sh");
    assert!(out.status.success(), "fetching @foxglove/schemas failed: {}", String::from_utf8_lossy(&out.stderr));
    dir
}

/// The scenario running now and how many of its tests are running.
static RUNNING: std::sync::Mutex<(Option<&'static str>, usize)> = std::sync::Mutex::new((None, 0));
static CHANGED: std::sync::Condvar = std::sync::Condvar::new();

/// Held while a test of `scenario` (its module path) runs: tests of one scenario run in parallel, tests
/// of different scenarios one after the other (see the crate docs).
#[must_use]
pub struct ScenarioGuard;

/// Waits until no test of another scenario runs, then counts this one in until the guard drops.
pub fn scenario(scenario: &'static str) -> ScenarioGuard {
    let mut running = RUNNING.lock().unwrap_or_else(|e| e.into_inner());
    while running.0.is_some_and(|s| s != scenario) {
        running = CHANGED.wait(running).unwrap_or_else(|e| e.into_inner());
    }
    *running = (Some(scenario), running.1 + 1);
    ScenarioGuard
}

impl Drop for ScenarioGuard {
    fn drop(&mut self) {
        let mut running = RUNNING.lock().unwrap_or_else(|e| e.into_inner());
        running.1 -= 1;
        if running.1 == 0 {
            running.0 = None;
            CHANGED.notify_all();
        }
    }
}

/// Asserts that a `uavloc bench` report names the machine it ran on: `cpus` (the online CPUs, not the
/// cores the benchmark is pinned to) and
/// `cpu_model` (`/proc/cpuinfo`'s model name, `null` where there is none).
pub fn assert_names_the_machine(report: &Value) {
    let cpus = unsafe { libc::sysconf(libc::_SC_NPROCESSORS_ONLN) } as u64;
    assert_eq!(report["cpus"].as_u64(), Some(cpus), "cpus in {report}");
    let model = std::fs::read_to_string("/proc/cpuinfo").ok().and_then(|info| {
        info.lines()
            .find(|l| l.starts_with("model name"))
            .and_then(|l| l.split_once(':'))
            .map(|(_, v)| v.trim().to_string())
    });
    match model.filter(|m| !m.is_empty()) {
        Some(m) => assert_eq!(report["cpu_model"].as_str(), Some(m.as_str()), "cpu_model in {report}"),
        None => assert!(report["cpu_model"].is_null(), "cpu_model in {report}"),
    }
}
