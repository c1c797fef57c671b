//! What a supervised process tells its supervisor (`uavloc launch`, `uavloc swap`) on stdout: one typed
//! line per event, written by the process with [`tell`] and read by the supervisor with
//! [`SupervisorLine::parse`] — one definition for both sides.
//!
//! | line | when |
//! |---|---|
//! | `ready` | subscribed and attached: the next process may start |
//! | `takeover {"from_step": k}` | a swapped-in process takes over from step k |
//! | `finished` | emitter-sim published the last step (it lingers for replays) |
//! | `record {json}` | the monitor's run record, at its end |
//! | `summary {json}` | the process's summary, at its end |

use std::io::Write as _;
use std::process::ExitCode;

use serde::Serialize;
use serde_json::Value;

use crate::exit::{EXIT_INTERRUPTED, ProcessError};

/// What every data process (estimator, planner) reports at its end, flattened into its summary line:
/// the JSON keys are the same for both, and a supervisor reads them without knowing the role.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct NodeSummary {
    /// The role (`"estimator"`, `"planner"`).
    pub role: &'static str,
    /// This process's instance id (in every message it sends).
    pub instance: u64,
    /// Valid messages received.
    pub accepted: u64,
    /// Invalid messages ignored.
    pub rejected: u64,
    /// Answers published.
    pub published: u64,
    /// Answers sent again for a message seen before (a replay).
    pub resent: u64,
    /// With `--takeover`: the first step this process handled (it took over there).
    pub took_over_at: Option<u64>,
    /// The step from which a newer instance took over (this one exited then).
    pub handed_over_at: Option<u64>,
    /// CPU time this process used, seconds.
    pub cpu_s: f64,
}

impl NodeSummary {
    /// The summary of a fresh instance of `role`.
    pub fn new(role: &'static str, instance: u64) -> Self {
        Self { role, instance, ..Self::default() }
    }
}

/// One line from a supervised process.
#[derive(Debug, Clone, PartialEq)]
pub enum SupervisorLine {
    /// Ready: subscribed and attached.
    Ready,
    /// A swapped-in process takes over from this step.
    TakeOver {
        /// The first step it handles.
        from_step: u64,
    },
    /// emitter-sim published the last step.
    Finished,
    /// The monitor's run record (JSON text, kept verbatim: the launcher re-reads its floats exactly).
    Record(String),
    /// The process's summary.
    Summary(Value),
}

/// What starts a [`SupervisorLine::Record`] line (written by [`SupervisorLine::to_line`] and
/// [`tell_record`], read by [`SupervisorLine::parse`] and [`SupervisorLine::parse_owned`]).
const RECORD_PREFIX: &str = "record ";

impl SupervisorLine {
    /// The line as written.
    pub fn to_line(&self) -> String {
        match self {
            SupervisorLine::Ready => "ready".into(),
            SupervisorLine::TakeOver { from_step } => {
                format!("takeover {}", serde_json::json!({"from_step": from_step}))
            }
            SupervisorLine::Finished => "finished".into(),
            SupervisorLine::Record(json) => format!("{RECORD_PREFIX}{json}"),
            SupervisorLine::Summary(v) => format!("summary {v}"),
        }
    }

    /// [`parse`](Self::parse) of a line the caller owns: a [`SupervisorLine::Record`] keeps the line's
    /// own text (a long run's record is tens of MB: not copied).
    pub fn parse_owned(mut line: String) -> Option<Self> {
        if line.starts_with(RECORD_PREFIX) {
            line.drain(..RECORD_PREFIX.len());
            return Some(SupervisorLine::Record(line));
        }
        Self::parse(&line)
    }

    /// Reads a line (`None`: not a supervisor line, e.g. other output).
    pub fn parse(line: &str) -> Option<Self> {
        match line {
            "ready" => return Some(SupervisorLine::Ready),
            "finished" => return Some(SupervisorLine::Finished),
            _ => {}
        }
        if let Some(json) = line.strip_prefix("takeover ") {
            let v: Value = serde_json::from_str(json).ok()?;
            return Some(SupervisorLine::TakeOver { from_step: v["from_step"].as_u64()? });
        }
        if let Some(json) = line.strip_prefix(RECORD_PREFIX) {
            return Some(SupervisorLine::Record(json.to_string()));
        }
        if let Some(json) = line.strip_prefix("summary ") {
            return serde_json::from_str(json).ok().map(SupervisorLine::Summary);
        }
        None
    }
}

/// Writes `line` to stdout (and flushes) when `supervised`.
pub fn tell(supervised: bool, line: &SupervisorLine) {
    if supervised {
        let mut out = std::io::stdout().lock();
        let _ = writeln!(out, "{}", line.to_line());
        let _ = out.flush();
    }
}

/// Writes the monitor's run record to stdout as one [`SupervisorLine::Record`] line (and flushes) when
/// `supervised`, serialised straight into stdout: a long run's record is not held a second time as text
/// (≈ 0.6 KB per step).
pub fn tell_record(supervised: bool, record: &impl Serialize) {
    if supervised {
        let mut out = std::io::BufWriter::new(std::io::stdout().lock());
        let _ = out
            .write_all(RECORD_PREFIX.as_bytes())
            .and_then(|()| serde_json::to_writer(&mut out, record).map_err(std::io::Error::other))
            .and_then(|()| out.write_all(b"\n"))
            .and_then(|()| out.flush());
    }
}

/// Ends a process's `main`: on success the summary goes to the supervisor (`summary {json}`) and the
/// exit code is 0; on an error one `error: <role>: …` line goes to stderr and the exit code is the
/// error's (2 bad input, 1 failure, 3 unrecoverable, 130 interrupted).
pub fn exit_with<S: Serialize>(role: &str, supervised: bool, result: Result<S, ProcessError>) -> ExitCode {
    match result {
        Ok(summary) => {
            tell(supervised, &SupervisorLine::Summary(serde_json::to_value(&summary).unwrap_or(Value::Null)));
            ExitCode::SUCCESS
        }
        Err(ProcessError::Interrupted) => {
            eprintln!("{role}: stopped by a signal before the end of the run");
            ExitCode::from(EXIT_INTERRUPTED)
        }
        Err(e) => {
            eprintln!("error: {role}: {e}");
            ExitCode::from(e.code())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_round_trip() {
        // A record streamed by tell_record reads back as the record's JSON.
        let mut streamed = b"record ".to_vec();
        serde_json::to_writer(&mut streamed, &serde_json::json!({"steps": [1.0000000000000002, -0.0]})).unwrap();
        assert_eq!(
            SupervisorLine::parse_owned(String::from_utf8(streamed).unwrap()),
            Some(SupervisorLine::Record("{\"steps\":[1.0000000000000002,-0.0]}".into()))
        );
        for line in [
            SupervisorLine::Ready,
            SupervisorLine::TakeOver { from_step: 41 },
            SupervisorLine::Finished,
            SupervisorLine::Record("{\"steps\":[1.0000000000000002]}".into()),
            SupervisorLine::Summary(serde_json::json!({"role": "planner", "published": 3})),
        ] {
            assert_eq!(SupervisorLine::parse(&line.to_line()), Some(line.clone()), "{}", line.to_line());
            assert_eq!(SupervisorLine::parse_owned(line.to_line()), Some(line.clone()), "{}", line.to_line());
        }
        for other in ["", "readyish", "takeover {}", "summary not json", "estimator: hello"] {
            assert_eq!(SupervisorLine::parse_owned(other.to_string()), None, "{other}");
            assert_eq!(SupervisorLine::parse(other), None, "{other}");
        }
    }
}
