//! A kill storm: during one slow `uavloc launch`, SIGKILL each of the four processes several times at
//! random steps, and two different processes at once a few times, while the launcher restarts them.
//! Checked at the end: the launch succeeds; `restarts` is the number of kills, and the JSON-lines log has a
//! `restart` event for every kill (role, the killed pid, attempts 1, 2, … with the capped backoff
//! min(50 ms · 2^(attempt − 1), 1.6 s)); the launcher's stderr names every kill and has no stale-resource
//! error ("already exists", "incompatible") and no `error:`; every step is logged exactly once; the
//! emitter-sim that finished flew exactly one command per step; the run equals `uavloc simulate`
//! (trajectory and estimates bit for bit; active constraints as the command's bit mask carries them);
//! nothing is rejected; no process and no iceoryx2 resource of the domain is left.
//!
//! The schedule is drawn from a seeded generator: the seed is printed on stderr (shown when a test fails)
//! and `UAVLOC_KILL_SEED=<seed>` draws the same schedule again (the timing of a run is not reproducible).
//! Each event waits until emitter-sim has published its step (as the monitor received it); the steps are
//! drawn in the first 90% of the run (a kill comes later when the restarts before it took long). The first
//! pair is emitter-sim and another process, killed in that order. A process is killed only once it is
//! ready (see `wait_ready`), never while iceoryx2 creates its node (see the limits in `cli/launch/mod.rs`).
//! The monitor is killed at any step too: emitter-sim runs at most 48 steps ahead of it (its
//! `--monitor-window`) and lingers after the last step, so a monitor restarted late still gets the run.
//!
//! `cargo test` runs the quick storm (2 kills per process and 1 pair over 300 steps at 10 ms per step),
//! the storm with a receiver's every impairment, two deterministic cases the storms found, the storm with
//! aircraft (simulated MAVLink autopilots; the bridge killed three times), and then, alone, the long storm (10 kills per process and 3
//! pairs over 1500 steps at 5 ms, 46 kills; about 85 s on 2 cores). One of them:
//!
//! ```text
//! cargo test --release --test kill_storm ten_kills
//! ```

use crate::common;

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use common::{
    Launch, LineTail, assert_nothing_left, assert_same_run, domain, is_alive, json_of, kill, pid_of, scratch,
};
use runtime::recovery::snapshot_step_at_or_below;
use serde_json::Value;
use tdoa::rng::SplitMix64;

const ROLES: [&str; 4] = ["emitter-sim", "estimator", "planner", "monitor"];

/// How long one step may take to come (a restarted emitter-sim flies the whole run again first).
const STEP_TIMEOUT: Duration = Duration::from_secs(180);
/// How long a killed process may take to be back (restart backoff up to 1.6 s, plus its start).
const READY_TIMEOUT: Duration = Duration::from_secs(60);

/// The kill schedule's generator (SplitMix64: the same schedule for a seed as before it moved to `tdoa`).
struct SplitMix(SplitMix64);

impl SplitMix {
    /// Uniform in `0..n` (n > 0; the modulo bias is irrelevant here).
    fn below(&mut self, n: u64) -> u64 {
        self.0.next_u64() % n
    }
}

/// `$UAVLOC_KILL_SEED`, else the clock.
fn kill_seed() -> u64 {
    match std::env::var("UAVLOC_KILL_SEED") {
        Ok(s) => s.trim().parse().unwrap_or_else(|e| panic!("UAVLOC_KILL_SEED={s:?}: {e}")),
        Err(_) => SystemTime::now().duration_since(UNIX_EPOCH).unwrap().as_nanos() as u64,
    }
}

/// One kill event: the roles killed at once (one or two) once emitter-sim has published `step`.
#[derive(Debug)]
struct Event {
    step: u64,
    roles: Vec<&'static str>,
}

/// Every role `kills_per_role` times alone, plus `pairs` events killing two different roles at once (the
/// first pair: emitter-sim and another one), at distinct random steps in `2..=0.9·steps`, in step order.
fn schedule(rng: &mut SplitMix, kills_per_role: usize, pairs: usize, steps: u64) -> Vec<Event> {
    let mut groups: Vec<Vec<&'static str>> =
        ROLES.iter().flat_map(|&r| std::iter::repeat_n(vec![r], kills_per_role)).collect();
    for i in 0..pairs {
        // The first pair has emitter-sim, killed first: restarted first, it cannot get ready before the
        // other one is back (it waits for the whole pipeline).
        let a = if i == 0 { 0 } else { rng.below(4) as usize };
        let b = (a + 1 + rng.below(3) as usize) % 4;
        groups.push(vec![ROLES[a], ROLES[b]]);
    }
    let (first, last) = (2, steps * 9 / 10);
    assert!(last >= first + groups.len() as u64, "{steps} steps are too few for {} kill events", groups.len());
    let mut taken = BTreeSet::new();
    let mut events: Vec<Event> = groups
        .into_iter()
        .map(|roles| {
            let step = loop {
                let k = first + rng.below(last - first + 1);
                if taken.insert(k) {
                    break k;
                }
            };
            Event { step, roles }
        })
        .collect();
    events.sort_by_key(|e| e.step);
    events
}

/// Follows the launch's JSON-lines log from where it last stopped reading (a long run's log is large:
/// re-reading it all at every poll would cost more than the run).
struct LogTail {
    lines: LineTail,
    /// The newest step the monitor logged.
    newest_step: Option<u64>,
    /// The newest step of a measurement the monitor received: how far emitter-sim is (the monitor logs
    /// steps only in order, and after a restart it is behind until the replay caught up).
    head: Option<u64>,
    /// (role, pid) of every `hello` (a process announced itself; the instance id carries its pid).
    hellos: BTreeSet<(String, u32)>,
    /// `resume` events (a restarted monitor rebuilt its state from the log and is ready).
    resumes: usize,
    /// The time (`t_ns`, the monotonic clock of every process) of the launcher's `restart` event of each
    /// killed pid: it had reaped the process then.
    restarted_at: BTreeMap<u32, u64>,
    /// The highest sequence number of each message kind received by the monitor. A process numbers its
    /// messages from the monotonic clock at the time it is ready, so one numbered above a `restarted_at`
    /// comes from a process that was ready after that restart.
    newest_seq: BTreeMap<String, u64>,
    /// The monitor logged the end of the run.
    ended: bool,
}

impl LogTail {
    fn new(path: &Path) -> Self {
        Self {
            lines: LineTail::new(path),
            newest_step: None,
            head: None,
            hellos: BTreeSet::new(),
            resumes: 0,
            restarted_at: BTreeMap::new(),
            newest_seq: BTreeMap::new(),
            ended: false,
        }
    }

    /// Reads what was appended since the last call.
    fn poll(&mut self) {
        for line in self.lines.poll() {
            let Ok(e) = serde_json::from_str::<Value>(&line) else { continue };
            match e["event"].as_str() {
                Some("step") => {
                    let k = e["step"].as_u64().unwrap();
                    self.newest_step = Some(self.newest_step.map_or(k, |n| n.max(k)));
                }
                Some("hello") => {
                    if let (Some(role), Some(instance)) = (e["role"].as_str(), e["instance"].as_u64()) {
                        self.hellos.insert((role.to_string(), (instance >> 32) as u32));
                    }
                }
                Some("message") => {
                    let (kind, seq) = (e["kind"].as_str().unwrap().to_string(), e["seq"].as_u64().unwrap());
                    if kind == "measurement" {
                        let k = e["step"].as_u64().unwrap();
                        self.head = Some(self.head.map_or(k, |n| n.max(k)));
                    }
                    let newest = self.newest_seq.entry(kind).or_default();
                    *newest = (*newest).max(seq);
                }
                Some("restart") => {
                    self.restarted_at.insert(e["pid"].as_u64().unwrap() as u32, e["t_ns"].as_u64().unwrap());
                }
                Some("resume") => self.resumes += 1,
                Some("end") => self.ended = true,
                _ => {}
            }
        }
    }
}

/// Sends SIGTERM to the launcher if the test panics before the launch ended (it then stops its children
/// and removes their resources).
struct StopOnPanic(Option<u32>);

impl Drop for StopOnPanic {
    fn drop(&mut self) {
        if let Some(pid) = self.0
            && std::thread::panicking()
        {
            // SAFETY: kill(2) on our own unreaped child.
            unsafe { libc::kill(pid as libc::pid_t, libc::SIGTERM) };
        }
    }
}

/// The launch fails the test if it ended early (or the run did: the launcher then waits until its report
/// is read).
fn check_running(launch: &mut Launch, tail: &LogTail, what: &str) {
    if let Ok(Some(status)) = launch.child.try_wait() {
        panic!("the launch ended ({status}) while {what}:\n{}", launch.stderr_text());
    }
    if tail.ended {
        // The launcher ends once its report is read: read it, wait for the end (bounded) and show why the
        // run ended — the launcher says so only after the monitor has logged the end.
        if let Some(mut out) = launch.child.stdout.take() {
            std::thread::spawn(move || std::io::copy(&mut out, &mut std::io::sink()));
        }
        let status = common::exit_within(&mut launch.child, Duration::from_secs(60));
        panic!(
            "the run ended (launch: {status:?}) while {what}; the log showed hellos {:?}, restarts {:?}, newest \
             sequence numbers {:?}, {} monitor resumes:\n{}",
            tail.hellos,
            tail.restarted_at,
            tail.newest_seq,
            tail.resumes,
            launch.stderr_text()
        );
    }
}

/// Waits until the monitor has logged step `step`.
fn wait_for_step(launch: &mut Launch, tail: &mut LogTail, step: u64) {
    wait_until(launch, tail, &format!("step {step} logged"), |t| t.newest_step.is_some_and(|n| n >= step));
}

/// Waits until emitter-sim has published step `step` (as far as the monitor received).
fn wait_for_head(launch: &mut Launch, tail: &mut LogTail, step: u64) {
    wait_until(launch, tail, &format!("step {step} published"), |t| t.head.is_some_and(|n| n >= step));
}

fn wait_until(launch: &mut Launch, tail: &mut LogTail, what: &str, done: impl Fn(&LogTail) -> bool) {
    let deadline = Instant::now() + STEP_TIMEOUT;
    loop {
        tail.poll();
        if done(tail) {
            return;
        }
        check_running(launch, tail, &format!("waiting for {what}"));
        assert!(Instant::now() < deadline, "no {what} within {STEP_TIMEOUT:?}:\n{}", launch.stderr_text());
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Waits until `role` runs as a process none of `killed` and is ready; returns its pid. Ready: the monitor
/// logged its announcement (a `hello` with its pid); for the monitor, the `monitor_kills`-th restarted
/// monitor resumed from the log. A process that announced itself while the monitor was down (killed with
/// it, or being restarted) is ready once the monitor received a message of its kind numbered after the
/// restart of `predecessor`, the last `role` killed (see [`LogTail::newest_seq`]).
fn wait_ready(
    launch: &mut Launch,
    tail: &mut LogTail,
    role: &str,
    killed: &BTreeSet<u32>,
    monitor_kills: usize,
    predecessor: Option<u32>,
) -> u32 {
    let kind = match role {
        "emitter-sim" => "measurement",
        "estimator" => "estimate",
        "planner" => "command",
        _ => "",
    };
    let deadline = Instant::now() + READY_TIMEOUT;
    loop {
        tail.poll();
        if let Some(pid) = pid_of(&launch.domain, role).filter(|p| !killed.contains(p)) {
            let ready = if role == "monitor" {
                tail.resumes >= monitor_kills
            } else {
                tail.hellos.contains(&(role.to_string(), pid))
                    || predecessor
                        .and_then(|q| tail.restarted_at.get(&q))
                        .is_some_and(|&restarted| tail.newest_seq.get(kind).is_some_and(|&seq| seq > restarted))
            };
            if ready && is_alive(pid) {
                return pid;
            }
        }
        check_running(launch, tail, &format!("waiting for a ready {role}"));
        assert!(
            Instant::now() < deadline,
            "no ready {role} (other than the killed {killed:?}) within {READY_TIMEOUT:?}:\n{}",
            launch.stderr_text()
        );
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// What was killed: (role, pid, the newest step published then).
type Kill = (&'static str, u32, u64);

/// The launcher's wait before restart number `attempt` of a role, ms.
fn backoff_ms(attempt: usize) -> u64 {
    (50u64 << (attempt - 1).min(10)).min(1600)
}

/// One storm: a launch of `steps` steps at `step_delay_ms`, every role killed `kills_per_role` times
/// alone plus `pairs` double kills, then every check of the module doc.
/// A storm of `kills_per_role` SIGKILLs per process and `pairs` pairs killed together over a launch of
/// `steps` steps (`scenario`: a scenario file, or the default one), checked against `simulate`.
fn storm(tag: &str, kills_per_role: usize, pairs: usize, steps: u64, step_delay_ms: u64, scenario: Option<&str>) {
    let started = Instant::now();
    let seed = kill_seed();
    eprintln!("kill storm {tag}: UAVLOC_KILL_SEED={seed}");
    let mut rng = SplitMix(SplitMix64::new(seed));
    let events = schedule(&mut rng, kills_per_role, pairs, steps);
    eprintln!("kill storm {tag}: schedule {events:?}");

    let d = domain("storm", tag);
    let dir = scratch(&format!("storm-{tag}"));
    let (n, delay, max_restarts) =
        (steps.to_string(), step_delay_ms.to_string(), (kills_per_role + pairs + 2).to_string());
    // emitter-sim gives up on a step whose command has not come after --command-timeout-s (10 s by default):
    // the launcher restarts one process at a time, up to 1.6 s each, so a burst of kills (events that fell
    // due together while the monitor was restarting) can hold a step longer than that.
    let mut flags =
        vec!["--steps", &n, "--step-delay-ms", &delay, "--max-restarts", &max_restarts, "--command-timeout-s", "60"];
    let mut sim_args = vec!["simulate", "--json", "--steps", &n];
    if let Some(path) = scenario {
        flags.extend(["--scenario", path]);
        sim_args.extend(["--scenario", path]);
    }
    let mut launch = Launch::start(&d, &dir, &flags);
    let mut guard = StopOnPanic(Some(launch.child.id()));
    let mut tail = LogTail::new(&launch.log);

    let mut kills: Vec<Kill> = Vec::new();
    let mut killed: BTreeSet<u32> = BTreeSet::new();
    for event in &events {
        wait_for_head(&mut launch, &mut tail, event.step);
        let mut pids = Vec::new();
        let monitor_kills = kills.iter().filter(|k| k.0 == "monitor").count();
        let ready = |launch: &mut Launch, tail: &mut LogTail, role: &str| {
            let predecessor = kills.iter().rev().find(|k| k.0 == role).map(|k| k.1);
            wait_ready(launch, tail, role, &killed, monitor_kills, predecessor)
        };
        for role in &event.roles {
            pids.push(ready(&mut launch, &mut tail, role));
        }
        check_running(&mut launch, &tail, &format!("about to kill {:?}", event.roles));
        // Back to back: the processes of a pair die together.
        for &pid in &pids {
            kill(pid, libc::SIGKILL);
        }
        let at = tail.head.unwrap_or(0);
        for (&role, &pid) in event.roles.iter().zip(&pids) {
            killed.insert(pid);
            kills.push((role, pid, at));
        }
    }
    eprintln!("kill storm {tag}: {} kills done after {:.1} s: {kills:?}", kills.len(), started.elapsed().as_secs_f64());

    guard.0 = None;
    let stderr_path = launch.stderr.clone();
    let run = launch.finish_json();
    let stderr = std::fs::read_to_string(stderr_path).unwrap_or_default();
    // Kept with the log when the test fails.
    std::fs::write(dir.join("launch.json"), run.to_string()).unwrap();
    eprintln!("kill storm {tag}: the launch ended after {:.1} s", started.elapsed().as_secs_f64());

    // Every kill happened during the run and was restarted.
    assert!(kills.iter().all(|k| k.2 < steps), "{kills:?}");
    assert_eq!(run["restarts"].as_u64(), Some(kills.len() as u64), "{stderr}");
    for (role, pid, _) in &kills {
        assert!(
            stderr.contains(&format!("the {role} process (pid {pid}) stopped unexpectedly (signal 9)")),
            "{role} {pid}:\n{stderr}"
        );
    }
    for bad in ["AlreadyExists", "already exists", "Incompatible", "incompatible", "error:"] {
        assert!(!stderr.contains(bad), "{bad:?} in:\n{stderr}");
    }

    // The log has every restart: per role, the killed pids in order, attempts 1, 2, … with the capped
    // backoff.
    let log = common::read_events(&dir.join("run.jsonl"));
    let processes = run["processes"].as_array().unwrap();
    for role in ROLES {
        let pids: Vec<u64> = kills.iter().filter(|k| k.0 == role).map(|k| u64::from(k.1)).collect();
        let restarts: Vec<&Value> = log.iter().filter(|e| e["event"] == "restart" && e["role"] == role).collect();
        assert_eq!(restarts.iter().map(|e| e["pid"].as_u64().unwrap()).collect::<Vec<_>>(), pids, "{role}");
        for (i, e) in restarts.iter().enumerate() {
            let attempt = i + 1;
            assert_eq!(e["attempt"].as_u64(), Some(attempt as u64), "{role}: {e}");
            assert_eq!(e["backoff_ms"].as_u64(), Some(backoff_ms(attempt)), "{role}: {e}");
            assert!(e["exit"].as_str().unwrap().contains("signal 9"), "{role}: {e}");
        }
        // Every instance is in the report: the killed ones (in order) marked restarted, then the one that
        // ran to the end.
        let instances: Vec<&Value> = processes.iter().filter(|p| p["role"] == role).collect();
        assert_eq!(instances.len(), pids.len() + 1, "{role}: {processes:?}");
        for (p, pid) in instances.iter().zip(&pids) {
            assert_eq!((p["pid"].as_u64(), p["restarted"].as_bool()), (Some(*pid), Some(true)), "{role}: {p}");
            assert!(p["exit"].as_str().unwrap().contains("signal 9"), "{role}: {p}");
        }
        assert_eq!(instances.last().unwrap()["restarted"].as_bool(), Some(false), "{role}");
    }

    // Every step exactly once in the log.
    common::assert_each_step_logged_once(&log, steps, tag);

    // One command applied per step by the emitter-sim that finished the run, from the step it started at
    // (0, or its checkpoint's older snapshot after a restart).
    let emitter = processes.iter().rev().find(|p| p["role"] == "emitter-sim").unwrap();
    let started_at = emitter["summary"]["started_at"].as_u64().unwrap();
    assert!(started_at < steps && snapshot_step_at_or_below(started_at) == started_at, "{emitter}");
    assert_eq!(emitter["summary"]["steps"].as_u64(), Some(steps - started_at), "{emitter}");

    // The run is exactly simulate's (its active constraints as the command's bit mask carries them).
    let sim = json_of(&sim_args);
    assert_same_run(&sim, &run, tag);
    assert_eq!(run["rejected"].as_u64(), Some(0), "{}", run["rejected_by"]);
    // Kills and restarts leave the flight safe: nothing broken along the arcs.
    assert_eq!(run["true_spacing_violations"].as_u64(), Some(0), "{tag}: {}", run["min_pair_m"]);
    assert_eq!(run["true_standoff_violations"].as_u64(), Some(0), "{tag}: {}", run["min_true_distance_m"]);
    assert_nothing_left(&d);
    std::fs::remove_dir_all(&dir).ok();
    eprintln!("kill storm {tag}: passed in {:.1} s", started.elapsed().as_secs_f64());
}

#[test]
fn quick_storm_two_kills_per_process_and_one_pair() {
    let _scenario = common::scenario(module_path!());
    storm("quick", 2, 1, 300, 10, None);
}

/// The long storm: alone (a scenario of its own), so that no other test takes the 2 cores from it.
#[test]
fn ten_kills_per_process_and_pairs() {
    let _scenario = common::scenario(concat!(module_path!(), "::long"));
    storm("long", 10, 3, 1500, 5, None);
}

/// The quick storm in a world with every receiver impairment on (`scenarios/receiver.toml`: lost
/// arrivals, silent steps, multipath, GNSS and clock errors per step and for the flight): a restarted
/// estimator takes the whole state from the messages — the fused posterior, the track's confirmation and
/// the bias sensitivity — and the run is still `simulate`'s, bit for bit.
#[test]
fn quick_storm_with_every_receiver_impairment() {
    let _scenario = common::scenario(module_path!());
    storm("receiver", 2, 1, 300, 10, Some(concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/receiver.toml")));
}

/// A restarted monitor asks emitter-sim to replay the run from its first missing step. When that step's
/// estimate failed (no position on the wire), the planner must answer the replay from the estimate of the
/// step before it — not from the newest one it received, since the pipeline went on while the monitor was
/// down — or the monitor records another command for that step than the one flown. The monitor is stopped
/// (SIGSTOP) right after it logged the step before the first failed estimate (the planner is slowed on that
/// step, so the monitor cannot log it yet), left behind for a while, then killed.
#[test]
fn a_monitor_restarted_at_a_failed_estimate_records_the_command_flown() {
    let _scenario = common::scenario(module_path!());
    let steps = "300";
    let d = domain("storm", "failed");
    let dir = scratch("storm-failed");
    // The nominal scenario with σ = 500 m and the per-step Chan estimator: Chan fails now and then. (The
    // fused estimator does not fail there: after its start it needs no Chan solve.)
    let scenario = dir.join("noisy.toml");
    std::fs::write(&scenario, "sigma = 500.0\nestimator = \"snapshot\"\n").unwrap();
    let scenario = scenario.to_str().unwrap();
    let sim = json_of(&["simulate", "--json", "--scenario", scenario, "--steps", steps]);
    let failed = sim["steps"].as_array().unwrap().iter().find(|s| s["estimate_status"] == "failed");
    let failed = failed.expect("the scenario has a failed estimate in 300 steps")["step"].as_u64().unwrap();
    let at = failed.to_string();
    let mut launch = Launch::start(
        &d,
        &dir,
        &[
            "--scenario",
            scenario,
            "--steps",
            steps,
            "--step-delay-ms",
            "10",
            "--plan-delay-ms",
            "300",
            "--plan-delay-steps",
            &at,
        ],
    );
    let mut guard = StopOnPanic(Some(launch.child.id()));
    let mut tail = LogTail::new(&launch.log);
    wait_for_step(&mut launch, &mut tail, 1);
    let monitor = pid_of(&d, "monitor").expect("a monitor");
    wait_for_step(&mut launch, &mut tail, failed - 1);
    kill(monitor, libc::SIGSTOP);
    tail.poll();
    assert_eq!(tail.newest_step, Some(failed - 1), "the monitor was stopped too late");
    // The planner's delay, then about 30 steps without the monitor.
    std::thread::sleep(Duration::from_millis(600));
    kill(monitor, libc::SIGKILL);
    guard.0 = None;
    let run = launch.finish_json();

    let log = common::read_events(&dir.join("run.jsonl"));
    let resumed: Vec<&Value> = log.iter().filter(|e| e["event"] == "resume").collect();
    assert_eq!(resumed.len(), 1, "{resumed:?}");
    assert_eq!(resumed[0]["steps_in_log"].as_u64(), Some(failed), "{resumed:?}");
    assert_eq!(run["restarts"].as_u64(), Some(1));
    assert_same_run(&sim, &run, "monitor restarted at a failed estimate");
    assert_eq!(run["rejected"].as_u64(), Some(0), "{}", run["rejected_by"]);
    assert_nothing_left(&d);
    std::fs::remove_dir_all(&dir).ok();
}

/// emitter-sim killed while the launcher restarts another process (here the planner, during its restart
/// backoff) is restarted too, and its crash is not taken for the end of the run: the launcher once kept
/// that moment as emitter-sim's end, and at the real end gave the monitor no grace ("the monitor did not
/// record the last step within …").
#[test]
fn emitter_sim_killed_while_the_planner_restarts_is_not_the_end_of_the_run() {
    let _scenario = common::scenario(module_path!());
    let steps = "600";
    let d = domain("storm", "during");
    let dir = scratch("storm-during");
    let mut launch = Launch::start(&d, &dir, &["--steps", steps, "--step-delay-ms", "10", "--command-timeout-s", "3"]);
    let mut guard = StopOnPanic(Some(launch.child.id()));
    let mut tail = LogTail::new(&launch.log);
    // The first planner restart puts the planner after emitter-sim in the launcher's list, so a restart of
    // the second one is under way when the launcher reaps emitter-sim.
    wait_for_step(&mut launch, &mut tail, 5);
    let planner = pid_of(&d, "planner").expect("a planner");
    kill(planner, libc::SIGKILL);
    let killed = BTreeSet::from([planner]);
    let planner = wait_ready(&mut launch, &mut tail, "planner", &killed, 0, Some(planner));
    wait_for_step(&mut launch, &mut tail, 20);
    let emitter = pid_of(&d, "emitter-sim").expect("an emitter-sim");
    kill(planner, libc::SIGKILL);
    // As soon as the launcher has begun the planner's restart (its `restart` event, written before the
    // backoff), within that backoff: checked against the event's own time and backoff, so that a starved
    // run fails here instead of passing while testing something else.
    let deadline = Instant::now() + READY_TIMEOUT;
    let restart = loop {
        let found = launch.events().into_iter().find(|e| e["event"] == "restart" && e["pid"] == planner);
        if let Some(e) = found {
            break e;
        }
        assert!(Instant::now() < deadline, "no restart of the planner {planner} logged");
        std::thread::yield_now();
    };
    kill(emitter, libc::SIGKILL);
    let killed_at = protocol::now_ns();
    let backoff_ends = restart["t_ns"].as_u64().unwrap() + restart["backoff_ms"].as_u64().unwrap() * 1_000_000;
    assert!(killed_at < backoff_ends, "emitter-sim was killed after the planner's backoff: {restart}");
    guard.0 = None;
    let run = launch.finish_json();

    assert_eq!(run["restarts"].as_u64(), Some(3));
    let sim = json_of(&["simulate", "--json", "--steps", steps]);
    assert_same_run(&sim, &run, "emitter-sim killed while the planner restarts");
    assert_nothing_left(&d);
    std::fs::remove_dir_all(&dir).ok();
}

/// The storm with aircraft: simulated autopilots fly a real-time launch (`--autopilot`) while the bridge
/// is killed three times and the planner, the estimator and the monitor once each; the launcher restarts
/// them and the run localises as `simulate` does. A killed emitter-sim is not restarted with aircraft
/// (the steps flown cannot be measured again): the launch fails at once, saying so.
#[test]
fn aircraft_storm_kills_the_bridge_three_times_and_every_restartable_process() {
    use common::autopilots::{Autopilots, GEO, TIME_SCALE, endpoints, ports};
    let _scenario = common::scenario(module_path!());
    let dir = scratch("storm-aircraft");
    let aircraft = Autopilots::start(ports(5), [&[], &[], &[]], &dir);
    let d = domain("storm", "aircraft");
    let steps = "40";
    let mut flags = vec!["--scenario", GEO, "--steps", steps, "--mode", "realtime", "--time-scale", TIME_SCALE];
    let eps = endpoints(ports(5));
    let mut first = flags.clone();
    first.extend(eps.iter().map(String::as_str));
    let mut launch = Launch::start(&d, &dir, &first);
    let kills = [(4, "bridge"), (8, "planner"), (12, "bridge"), (16, "estimator"), (20, "monitor"), (26, "bridge")];
    for (step, role) in kills {
        launch.wait_for_step(step, STEP_TIMEOUT);
        // The previous kill's successor must be up before the next kill of its role.
        let deadline = Instant::now() + READY_TIMEOUT;
        let pid = loop {
            if let Some(pid) = pid_of(&d, role) {
                break pid;
            }
            assert!(Instant::now() < deadline, "no {role} to kill at step {step}:\n{}", launch.stderr_text());
            std::thread::sleep(Duration::from_millis(20));
        };
        kill(pid, libc::SIGKILL);
        eprintln!("aircraft storm: killed the {role} (pid {pid}) at step {step}");
    }
    let run = launch.finish_json();
    // Kept beside the log when an assertion fails (the directory is removed at the end otherwise).
    std::fs::write(dir.join("run.json"), run.to_string()).unwrap();
    assert_eq!(run["steps"].as_array().unwrap().len(), 41, "every step");
    assert_eq!(run["restarts"], kills.len(), "each kill restarted once: {}", run["processes"]);
    let bridges = run["processes"].as_array().unwrap().iter().filter(|p| p["role"] == "bridge").count();
    assert_eq!(bridges, 4, "three killed, the fourth ran to the end");
    let flown = run["steps"][40]["estimate_error_m"].as_f64().unwrap();
    let simulated =
        json_of(&["simulate", "--json", "--scenario", GEO, "--steps", steps])["steps"][40]["estimate_error_m"]
            .as_f64()
            .unwrap();
    eprintln!("aircraft storm: terminal error {flown:.1} m, simulate {simulated:.1} m");
    assert!(flown < 2.0 * simulated + 20.0, "flown {flown:.1} m vs simulated {simulated:.1} m");
    assert_nothing_left(&d);

    drop(aircraft);

    // emitter-sim killed with aircraft: the launch fails at once, naming why (fresh aircraft at their starts).
    let second = dir.join("world");
    std::fs::create_dir_all(&second).unwrap();
    let _aircraft = Autopilots::start(ports(6), [&[], &[], &[]], &second);
    let d = domain("storm", "aircraft-world");
    let eps = endpoints(ports(6));
    flags.extend(eps.iter().map(String::as_str));
    let mut launch = Launch::start(&d, &second, &flags);
    launch.wait_for_step(4, STEP_TIMEOUT);
    kill(pid_of(&d, "emitter-sim").expect("emitter-sim runs"), libc::SIGKILL);
    let (status, _, stderr) = launch.finish();
    assert!(!status.success(), "{stderr}");
    assert!(stderr.contains("with aircraft (--autopilot) it is not restarted"), "{stderr}");
    assert_nothing_left(&d);
    std::fs::remove_dir_all(&dir).ok();
}
