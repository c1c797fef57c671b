//! The monitor's JSON-lines run log (`--log`): writing it (one `write` per event line, appended) and
//! reading a run back from it (a restarted monitor's steps, the record at the end).
//!
//! One object per line with `t_ns` (monotonic clock, the stamps' clock) and `event`:
//! - `start` (domain, steps, seed, source, scenario: its [`model::Scenario::fingerprint`]) or `resume`
//!   (domain, steps recorded in the log; a log whose `start` names another run is refused, exit 2);
//!   `message` (kind, step, seq, age_us: publish → received here);
//! - `rejected` (kind, reason, detail); `planner` (a new planner instance: instance, solver, objective, step);
//! - `hello` / `take_over` (a process joined or took over: role, instance, detail, step);
//! - `step` (the step's record, its truth, its latencies in µs and planner; `command_missed: true` when
//!   the step's command did not reach emitter-sim in time — real-time mode — and the UAVs kept their
//!   headings: the record then has `active_constraints: ["command_missed"]`, `objective_value` null);
//!   `command_missed` (step) for such a step; `estimate_stale: true` when the step's command was the
//!   planner's hold (no fresh estimate within its `--estimate-deadline-ms`; the record then has
//!   `active_constraints: ["estimate_stale"]`), and an `estimate_stale` (step) event; `uncertified`
//!   (step) when the step's command said that no certified plan existed (`safety.certified` false);
//!   `end` (complete, steps, rejected, ignored, missed_commands, stale_steps, uncertified_steps);
//! - `front_end_left` (step: the first step not recorded) with `--source external`, when the front end
//!   left the measurement topic before the last step; `measurement_gap` (missing, later) once per
//!   missing step, when the next step's measurement has not come for a second while a later one is in
//!   (a front end that skipped a step: the run waits for it); `beyond_last_step` (kind, step, last) for
//!   a measurement of a step after the run's last (ignored; floods summarised as `rejected_unlogged`).
//!
//! `uavloc launch` appends `restart` events (role, attempt, exit, backoff_ms) to the same file: every line
//! is written with one `write` on a file opened for appending.

use std::fs::File;
use std::path::Path;

use crate::lines::LineFile;

use protocol::messages::AnyBitPattern as _;
use protocol::{StateEcho, now_ns};
use serde_json::json;

use crate::assemble::Assembler;
use model::Scenario;
use record::record::StepRecord;
use runtime::ProcessError;
use runtime::recovery::StateStore;

/// The JSON-lines run log (a no-op without `--log`), opened for appending: whole lines, one `write` per
/// wake-up ([`LineFile`]), so lines of other writers (the launcher's `restart` events) never land inside
/// one.
pub(crate) struct EventLog {
    file: Option<LineFile>,
}

impl EventLog {
    /// Opens `path` for appending; truncates it first unless `append`.
    pub(crate) fn open(path: Option<&Path>, append: bool) -> Result<Self, ProcessError> {
        let Some(p) = path else { return Ok(EventLog { file: None }) };
        // Cannot be opened: a bad flag (exit 2), not worth a restart.
        let failed = |e: std::io::Error| ProcessError::input_because(format!("--log {}", p.display()), e);
        if !append {
            File::create(p).map_err(failed)?;
        }
        let file = std::fs::OpenOptions::new().create(true).append(true).open(p).map_err(failed)?;
        let consequence = " (the step records live in the log: the run cannot be recorded)";
        Ok(EventLog { file: Some(LineFile::new(file, p, "--log", consequence)) })
    }

    /// Adds an event line (written at the next [`flush`](Self::flush)).
    pub(crate) fn write(&mut self, event: &str, fields: impl serde::Serialize) {
        if let Some(file) = &mut self.file {
            file.push(&event_line(event, now_ns(), &fields));
        }
    }

    /// Writes the lines added since the last flush.
    pub(crate) fn flush(&mut self) {
        if let Some(file) = &mut self.file {
            file.flush();
        }
    }

    /// The first write error, as the unrecoverable end of the run (a restart would hit it again).
    pub(crate) fn check(&self) -> Result<(), ProcessError> {
        self.file.as_ref().map_or(Ok(()), LineFile::check)
    }
}

/// Where a monitor starts: a new record; or, with `--resume` and a `log`, the steps its predecessor
/// logged there and the estimator states they echoed (a log of another run is refused, exit 2). With a
/// log the step records live there, not in memory (read back at the end). Also the steps resumed.
pub(crate) fn resume(
    log: Option<&Path>,
    resume: bool,
    scenario: &Scenario,
    source: runtime::Source,
) -> Result<(Assembler, StateStore, Option<u64>), ProcessError> {
    let mut states = StateStore::new();
    let (assembler, resumed) = match (log, resume) {
        (Some(path), true) => {
            let LoggedRun { count, last, truth, names, states: logged, start, .. } = read_log(path, false);
            // Resuming another run's log would make one record of two runs.
            let differences = start
                .map(|s| s.differences(scenario.steps as u64, scenario.seed, source.name(), &scenario.fingerprint()));
            if let Some(d) = differences.filter(|d| !d.is_empty()) {
                return Err(ProcessError::Input(format!(
                    "--log {}: the log of another run; this run has {}. Resuming would make one record of two \
                     runs: give this run's log, or start without --resume",
                    path.display(),
                    d.join(", ")
                )));
            }
            for echo in logged {
                states.keep(echo);
            }
            match Assembler::resume_forgetting(scenario.clone(), count, last.as_ref(), truth, names) {
                Some(a) => (a, Some(count)),
                None => (Assembler::new(scenario.clone()).forgetting(), Some(0)),
            }
        }
        (Some(_), false) => (Assembler::new(scenario.clone()).forgetting(), None),
        (None, _) => (Assembler::new(scenario.clone()), None),
    };
    let assembler = if source == runtime::Source::External { assembler.without_truth() } else { assembler };
    Ok((assembler, states, resumed))
}

/// What a monitor's log says about a run.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LoggedRun {
    /// How many steps are recorded, in order from step 0 (up to the first gap).
    pub count: u64,
    /// The record of the last of them.
    pub last: Option<StepRecord>,
    /// All of them (when asked for; else empty).
    pub steps: Vec<StepRecord>,
    /// The true emitter.
    pub truth: Option<[f64; 2]>,
    /// The run's (objective, solver).
    pub names: Option<(String, String)>,
    /// What the log's first `start` event says of the run it belongs to.
    pub start: Option<RunStart>,
    /// The estimator states the logged steps' commands echoed (the last
    /// [`HISTORY_STEPS`](runtime::recovery::HISTORY_STEPS) of them, oldest first).
    pub states: Vec<StateEcho>,
}

/// The run a log belongs to, from its `start` event (fields a log of an older build lacks are `None`).
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Deserialize)]
pub struct RunStart {
    pub steps: Option<u64>,
    pub seed: Option<u64>,
    pub source: Option<String>,
    /// [`model::Scenario::fingerprint`] of the run's scenario.
    pub scenario: Option<String>,
}

impl RunStart {
    /// How a run of `steps`, `seed`, `source` and scenario `fingerprint` differs from this one
    /// (`"seed 2, not 1"`, …); empty when it is the same run.
    pub fn differences(&self, steps: u64, seed: u64, source: &str, fingerprint: &str) -> Vec<String> {
        let mut out = Vec::new();
        if self.steps.is_some_and(|s| s != steps) {
            out.push(format!("{steps} steps, not {}", self.steps.unwrap_or_default()));
        }
        if self.seed.is_some_and(|s| s != seed) {
            out.push(format!("seed {seed}, not {}", self.seed.unwrap_or_default()));
        }
        if self.source.as_deref().is_some_and(|s| s != source) {
            out.push(format!("source {source}, not {}", self.source.as_deref().unwrap_or_default()));
        }
        if out.is_empty() && self.scenario.as_deref().is_some_and(|s| s != fingerprint) {
            out.push("another scenario".into());
        }
        out
    }
}

/// A state echo as it is written in the log: its bytes in hex (exact, whatever the floats).
pub fn state_to_hex(echo: &StateEcho) -> String {
    const DIGITS: &[u8; 16] = b"0123456789abcdef";
    let mut out = String::with_capacity(2 * core::mem::size_of::<StateEcho>());
    for b in echo.as_bytes() {
        out.push(char::from(DIGITS[usize::from(b >> 4)]));
        out.push(char::from(DIGITS[usize::from(b & 15)]));
    }
    out
}

/// One line of the log: `{"event":…,"t_ns":…,` and then the fields of `fields` (a JSON object: a typed
/// struct, which is serialised without building a `serde_json::Value` tree, or a `json!` object), and a
/// newline.
fn event_line(event: &str, t_ns: u64, fields: &impl serde::Serialize) -> String {
    let mut line = serde_json::to_string(&json!({"event": event, "t_ns": t_ns})).unwrap_or_default();
    let body = serde_json::to_string(fields).unwrap_or_default();
    // An empty object adds nothing (and the monitor writes nothing but objects).
    if let Some(rest) = body.strip_prefix('{').filter(|rest| *rest != "}") {
        line.pop(); // the closing brace
        line.push(',');
        line.push_str(rest);
    }
    line.push('\n');
    line
}

/// The state echo of [`state_to_hex`]'s text; `None` for text that is not one (a state that does not pass
/// validation included).
pub fn state_from_hex(text: &str) -> Option<StateEcho> {
    if !text.is_ascii() || !text.len().is_multiple_of(2) {
        return None;
    }
    let bytes: Option<Vec<u8>> =
        (0..text.len()).step_by(2).map(|i| u8::from_str_radix(&text[i..i + 2], 16).ok()).collect();
    StateEcho::from_bytes(&bytes?).filter(|e| e.validate().is_ok() && e.decode().is_some())
}

/// The fields of a `step` line that [`read_log`] uses, parsed in one pass without a `serde_json::Value`
/// tree; the state's hex text is borrowed from the line and decoded only if it is among the last ones.
#[derive(serde::Deserialize)]
struct StepLine<'a> {
    #[serde(borrow)]
    event: std::borrow::Cow<'a, str>,
    record: StepRecord,
    /// (A coordinate that is not a number is written as `null`.)
    #[serde(default)]
    truth: Option<[Option<f64>; 2]>,
    #[serde(default)]
    planner: Option<PlannerNames>,
    #[serde(default, borrow)]
    state: Option<std::borrow::Cow<'a, str>>,
}

/// The planner's names in a `step` line.
#[derive(serde::Deserialize)]
struct PlannerNames {
    objective: Option<String>,
    solver: Option<String>,
}

/// Reads a monitor's log back, line by line (a missing file is an empty log); lines that do not parse are
/// skipped (e.g. the last one of a killed monitor). The step records are kept only with `keep_steps`.
///
/// A log grows by ≈ 3.5 kB per step (most of it the echoed estimator state, in hex), so this is written
/// for 100 000-step logs: one reused line buffer, a typed parse of the step lines only, and the state text
/// of the last [`HISTORY_STEPS`](runtime::recovery::HISTORY_STEPS) steps kept and decoded at the end.
pub fn read_log(path: &Path, keep_steps: bool) -> LoggedRun {
    use std::io::BufRead as _;
    let history = runtime::recovery::HISTORY_STEPS as usize;
    let mut run = LoggedRun::default();
    let Ok(file) = File::open(path) else { return run };
    let (mut truth, mut names) = (None, None);
    let mut hexes: std::collections::VecDeque<String> = std::collections::VecDeque::with_capacity(history + 1);
    let mut reader = std::io::BufReader::with_capacity(1 << 20, file);
    let mut line = String::new();
    loop {
        line.clear();
        match reader.read_line(&mut line) {
            Ok(0) | Err(_) => break,
            Ok(_) => {}
        }
        if run.start.is_none() && line.contains("\"event\":\"start\"") {
            run.start = serde_json::from_str::<RunStart>(&line).ok();
            continue;
        }
        if !line.contains("\"event\":\"step\"") {
            continue;
        }
        let Ok(e) = serde_json::from_str::<StepLine>(&line) else { continue };
        if e.event != "step" {
            continue;
        }
        let record = e.record;
        if record.step != run.count {
            continue; // a duplicate, or a gap: keep the steps from 0 without gaps
        }
        if truth.is_none()
            && let Some([Some(x), Some(y)]) = e.truth
        {
            truth = Some([x, y]);
        }
        if names.is_none()
            && let Some(PlannerNames { objective: Some(objective), solver: Some(solver) }) = e.planner
        {
            names = Some((objective, solver));
        }
        if let Some(hex) = e.state {
            if hexes.len() == history {
                hexes.pop_front();
            }
            hexes.push_back(hex.into_owned());
        }
        run.count += 1;
        if keep_steps {
            run.steps.push(record);
        } else {
            run.last = Some(record);
        }
    }
    if keep_steps {
        run.last = run.steps.last().cloned();
    }
    // A state that does not decode is left out (a line of a killed monitor parses only if whole).
    run.states = hexes.iter().filter_map(|h| state_from_hex(h)).collect();
    LoggedRun { truth, names, ..run }
}

#[cfg(test)]
pub(crate) mod tests {
    use std::path::PathBuf;

    use super::*;

    /// A fresh directory for a test's log (the test removes it), and the log's path in it.
    pub(crate) fn scratch_log(tag: &str) -> (PathBuf, PathBuf) {
        let dir = std::env::temp_dir().join(format!("uavloc-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("run.jsonl");
        (dir, path)
    }

    /// A log that cannot be opened is bad input (exit 2) naming the flag and the file, with the system's
    /// error kept as the cause.
    #[test]
    fn an_unopenable_log_is_bad_input_that_keeps_its_cause() {
        let path = Path::new("/nonexistent-dir-of-uavloc/run.jsonl");
        let Err(e) = EventLog::open(Some(path), false) else { panic!("opened {}", path.display()) };
        assert!(matches!(e, ProcessError::InputBecause { .. }), "{e:?}");
        assert_eq!(e.code(), 2);
        assert!(e.to_string().starts_with("--log /nonexistent-dir-of-uavloc/run.jsonl: "), "{e}");
        let io = std::error::Error::source(&e).and_then(|s| s.downcast_ref::<std::io::Error>()).expect("kept");
        assert_eq!(io.kind(), std::io::ErrorKind::NotFound);
    }

    #[test]
    fn an_event_line_is_the_event_the_time_and_the_fields() {
        #[derive(serde::Serialize)]
        struct Typed<'a> {
            step: u64,
            name: &'a str,
            value: f64,
        }
        let typed = event_line("step", 42, &Typed { step: 7, name: "a\"b", value: f64::NAN });
        assert_eq!(typed, "{\"event\":\"step\",\"t_ns\":42,\"step\":7,\"name\":\"a\\\"b\",\"value\":null}\n");
        let back: serde_json::Value = serde_json::from_str(&typed).unwrap();
        assert_eq!(back, json!({"event": "step", "t_ns": 42, "step": 7, "name": "a\"b", "value": null}));
        assert_eq!(event_line("x", 1, &json!({})), "{\"event\":\"x\",\"t_ns\":1}\n");
        assert_eq!(event_line("x", 1, &json!({"k": [1, 2]})), "{\"event\":\"x\",\"t_ns\":1,\"k\":[1,2]}\n");
    }

    #[test]
    fn read_log_keeps_a_step_whose_crlb_is_infinite() {
        // The 100k soak: a step with coincident UAVs (CRLB +∞, logged as null) ended the steps read back.
        let (dir, path) = scratch_log("read-log");
        let mut log = EventLog::open(Some(&path), false).unwrap();
        for (k, crlb) in [(0u64, 10.0), (1, f64::INFINITY), (2, 11.0)] {
            let record = record::StepRecord { step: k, crlb_true_m: Some(crlb), ..Default::default() };
            log.write("step", json!({"step": k, "record": record}));
        }
        log.flush();
        let run = read_log(&path, true);
        assert_eq!(run.count, 3);
        assert_eq!(run.steps[1].crlb_true_m, Some(f64::INFINITY));
        std::fs::remove_dir_all(&dir).ok();
    }

    /// An estimator state of step `k` with this position and covariance.
    fn state_echo(k: u64, position: [f64; 2], covariance: [[f64; 2]; 2]) -> StateEcho {
        StateEcho { step: k, kind: StateEcho::STATE, estimator: 1, position, covariance, ..StateEcho::default() }
    }

    #[test]
    fn the_states_in_the_log_read_back_bit_for_bit() {
        let (dir, path) = scratch_log("log-states");
        let mut log = EventLog::open(Some(&path), false).unwrap();
        let echo = |k: u64| state_echo(k, [0.1 + 0.2 + k as f64, -1e-300], [[4.0, 1e-12], [1e-12, 5.0]]);
        let empty = StateEcho { step: 1, kind: StateEcho::EMPTY, ..StateEcho::default() };
        for (k, e) in [(0u64, Some(echo(0))), (1, Some(empty)), (2, None), (3, Some(echo(3)))] {
            let record = record::StepRecord { step: k, crlb_true_m: Some(10.0), ..Default::default() };
            log.write("step", json!({"step": k, "record": record, "state": e.map(|e| state_to_hex(&e))}));
        }
        log.flush();
        let run = read_log(&path, false);
        assert_eq!(run.count, 4);
        assert_eq!(run.states, vec![echo(0), empty, echo(3)]);
        // Text that is not a valid state is none.
        let hex = state_to_hex(&echo(3));
        for bad in [&hex[..hex.len() - 2], "zz", "", &hex.replace("01", "07")] {
            assert_eq!(state_from_hex(bad), None, "{bad}");
        }
        let mut nan = echo(3);
        nan.covariance[0][0] = f64::NAN;
        assert_eq!(state_from_hex(&state_to_hex(&nan)), None);
        std::fs::remove_dir_all(&dir).ok();
    }

    /// A log longer than the history: the last `HISTORY_STEPS` states, oldest first; the truth of the
    /// first step that has a whole one (a coordinate that is not a number is logged as `null`); the
    /// planner's names; a line of another event that mentions a step is not a step.
    #[test]
    fn a_long_log_reads_back_the_last_states_the_truth_and_the_names() {
        let history = runtime::recovery::HISTORY_STEPS;
        let (dir, path) = scratch_log("log-long");
        let mut log = EventLog::open(Some(&path), false).unwrap();
        let echo = |k: u64| state_echo(k, [k as f64, 2.0], [[4.0, 0.0], [0.0, 5.0]]);
        let n = history + 10;
        for k in 0..n {
            let record = record::StepRecord { step: k, crlb_true_m: Some(10.0), ..Default::default() };
            let truth = if k == 0 { json!([f64::NAN, 1.0]) } else { json!([k as f64, 1.0]) };
            let planner = json!({"objective": "analytical", "solver": "pso"});
            log.write(
                "step",
                json!({"step": k, "record": record, "truth": truth, "planner": planner, "state": state_to_hex(&echo(k))}),
            );
            log.write("message", json!({"kind": "command", "step": k, "note": "\"event\":\"step\""}));
        }
        log.flush();
        for keep in [false, true] {
            let run = read_log(&path, keep);
            assert_eq!(run.count, n);
            assert_eq!(run.steps.len() as u64, if keep { n } else { 0 });
            assert_eq!(run.last.as_ref().map(|r| r.step), Some(n - 1));
            let expected: Vec<StateEcho> = (n - history..n).map(echo).collect();
            assert!(
                run.states == expected,
                "{} states, from step {:?}",
                run.states.len(),
                run.states.first().map(|e| e.step)
            );
            assert_eq!(run.truth, Some([1.0, 1.0]));
            assert_eq!(run.names, Some(("analytical".to_string(), "pso".to_string())));
        }
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn a_resume_takes_its_own_runs_log_and_refuses_another_runs() {
        let (dir, path) = scratch_log("resume");
        let sc = Scenario { steps: 5, ..Scenario::default() };
        let simulator = runtime::Source::Simulator;
        // No log, or a new run: a new record (with a log it forgets the steps, which live there).
        let (a, states, resumed) = resume(None, true, &sc, simulator).unwrap();
        assert_eq!((a.next_step(), a.has_truth(), states.len(), resumed), (0, true, 0, None));
        assert_eq!(resume(Some(&path), false, &sc, simulator).unwrap().2, None);
        // This run's log with no step yet: resumed from step 0.
        let mut log = EventLog::open(Some(&path), false).unwrap();
        let start = json!({"steps": 5, "seed": sc.seed, "source": "simulator", "scenario": sc.fingerprint()});
        log.write("start", &start);
        log.flush();
        let (a, _, resumed) = resume(Some(&path), true, &sc, simulator).unwrap();
        assert_eq!((a.next_step(), resumed), (0, Some(0)));
        // Another run's log (another seed, another source): refused, naming the difference.
        let other = Scenario { seed: sc.seed + 1, ..sc.clone() };
        let e = resume(Some(&path), true, &other, simulator).err().unwrap();
        assert!(matches!(&e, ProcessError::Input(m) if m.contains("another run") && m.contains("seed")), "{e}");
        let e = resume(Some(&path), true, &sc, runtime::Source::External).err().unwrap();
        assert!(matches!(&e, ProcessError::Input(m) if m.contains("source external")), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
