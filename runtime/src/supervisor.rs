//! What a supervised process tells its supervisor (`uavloc launch`, `uavloc swap`) on stdout: one typed
//! line per event, written by the process with [`tell`] (the record: [`tell_record`]) and read by the
//! supervisor with [`read_output`] ([`SupervisorLine::parse`] for a line) — one definition for both sides.
//!
//! | line | when |
//! |---|---|
//! | `ready` | subscribed and attached: the next process may start |
//! | `takeover {"from_step": k}` | a swapped-in process takes over from step k |
//! | `finished` | emitter-sim published the last step (it lingers for replays) |
//! | `record {json}` | the monitor's run record, at its end |
//! | `summary {json}` | the process's summary, at its end |

use std::io::{BufRead, Write as _};
use std::process::ExitCode;

use serde::Serialize;
use serde::de::DeserializeOwned;
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
    /// emitter-sim published the last step; the monitor recorded it.
    Finished,
    /// The process's summary.
    Summary(Value),
    /// Why it ends with an error (the text of its `error:` line), told before it exits: the supervisor
    /// gives it with the exit code.
    Failed(String),
}

/// What starts the run record's line (written by [`tell_record`], read by [`read_output`]).
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
            SupervisorLine::Summary(v) => format!("summary {v}"),
            SupervisorLine::Failed(why) => format!("failed {}", Value::String(why.clone())),
        }
    }

    /// Reads a line (`None`: not a supervisor line, e.g. other output; the record's line is
    /// [`read_output`]'s).
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
        if let Some(json) = line.strip_prefix("summary ") {
            return serde_json::from_str(json).ok().map(SupervisorLine::Summary);
        }
        if let Some(json) = line.strip_prefix("failed ") {
            return serde_json::from_str(json).ok().map(SupervisorLine::Failed);
        }
        None
    }
}

/// One item of a supervised process's stdout, as [`read_output`] reads it.
#[derive(Debug, PartialEq)]
pub enum Output<R> {
    /// A line that is not the run record: a [`SupervisorLine`], or other output (`None`).
    Line(Option<SupervisorLine>),
    /// The run record, deserialized as it streamed in — never held as text (a long run's record is
    /// ≈ 1.6 KB per step) — or what was wrong with it.
    Record(Result<R, String>),
}

/// Reads the next item of a supervised process's stdout (`None` at its end): a line, or the `record`
/// line ([`tell_record`]) deserialized straight from the stream into an `R`.
pub fn read_output<R: DeserializeOwned>(reader: &mut impl BufRead) -> std::io::Result<Option<Output<R>>> {
    // The start of the line, a byte at a time, until it is known whether it is the record.
    let mut head = Vec::new();
    while head.len() < RECORD_PREFIX.len() && head.last() != Some(&b'\n') {
        let mut byte = [0u8];
        if reader.read(&mut byte)? == 0 {
            break;
        }
        head.push(byte[0]);
    }
    if head.is_empty() {
        return Ok(None);
    }
    if head == RECORD_PREFIX.as_bytes() {
        let record = R::deserialize(&mut serde_json::Deserializer::from_reader(&mut *reader));
        skip_line(reader)?;
        return Ok(Some(Output::Record(record.map_err(|e| e.to_string()))));
    }
    if head.last() != Some(&b'\n') {
        reader.read_until(b'\n', &mut head)?;
    }
    let line = String::from_utf8_lossy(&head);
    Ok(Some(Output::Line(SupervisorLine::parse(line.trim_end_matches('\n').trim_end_matches('\r')))))
}

/// Consumes the rest of the current line (all of a record whose parse failed midway), holding none of it.
fn skip_line(reader: &mut impl BufRead) -> std::io::Result<()> {
    loop {
        let buf = reader.fill_buf()?;
        match buf.iter().position(|b| *b == b'\n') {
            Some(i) => {
                reader.consume(i + 1);
                return Ok(());
            }
            None if buf.is_empty() => return Ok(()),
            None => {
                let n = buf.len();
                reader.consume(n);
            }
        }
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

/// Writes the monitor's run record to stdout as one `record {json}` line ([`read_output`]) (and flushes) when
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
/// exit code is 0; on an error one `error: <role>: …` line goes to stderr, the error to the supervisor
/// ([`SupervisorLine::Failed`]), and the exit code is the error's (2 bad input, 1 failure, 3
/// unrecoverable, 130 interrupted).
pub fn exit_with<S: Serialize>(role: &str, supervised: bool, result: Result<S, ProcessError>) -> ExitCode {
    match result {
        Ok(summary) => {
            tell(supervised, &SupervisorLine::Summary(serde_json::to_value(&summary).unwrap_or(Value::Null)));
            ExitCode::SUCCESS
        }
        Err(ProcessError::Interrupted) => {
            protocol::log_line!("{role}: stopped by a signal before the end of the run");
            ExitCode::from(EXIT_INTERRUPTED)
        }
        Err(e) => fail(role, supervised, &e),
    }
}

/// A process's end with the error `e`: its `error: <role>: …` line on stderr, the error told to the
/// supervisor ([`SupervisorLine::Failed`]), and its exit code.
pub fn fail(role: &str, supervised: bool, e: &ProcessError) -> ExitCode {
    protocol::log_line!("error: {role}: {e}");
    tell(supervised, &SupervisorLine::Failed(e.to_string()));
    ExitCode::from(e.code())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_round_trip() {
        for line in [
            SupervisorLine::Ready,
            SupervisorLine::TakeOver { from_step: 41 },
            SupervisorLine::Finished,
            SupervisorLine::Summary(serde_json::json!({"role": "planner", "published": 3})),
            // An error's text, quotes, newline and all, on one line.
            SupervisorLine::Failed("step 7: no plan for \"ẑ\"\n— the run cannot go on".into()),
        ] {
            assert_eq!(line.to_line().lines().count(), 1, "{}", line.to_line());
            assert_eq!(SupervisorLine::parse(&line.to_line()), Some(line.clone()), "{}", line.to_line());
        }
        for other in ["", "readyish", "takeover {}", "summary not json", "estimator: hello", "record {}", "failed why"]
        {
            assert_eq!(SupervisorLine::parse(other), None, "{other}");
        }
    }

    #[test]
    fn a_streamed_record_is_read_from_the_stream_between_the_other_lines() {
        #[derive(Debug, PartialEq, serde::Deserialize)]
        struct Rec {
            steps: Vec<f64>,
        }
        // What a monitor prints: lines, the record (tell_record's bytes), lines; a record line that is not
        // one; a line of other output without a newline at the end.
        let mut out = b"ready\r\nsummary {\"role\":\"monitor\"}\nrec\nrecord ".to_vec();
        serde_json::to_writer(&mut out, &serde_json::json!({"steps": [1.0000000000000002, -0.0]})).unwrap();
        out.extend_from_slice(b"\nrecord {\"steps\": [1, \"x\"] and more\nfinished\nno newline");
        let mut reader = std::io::BufReader::with_capacity(4, out.as_slice());
        let mut items = Vec::new();
        while let Some(item) = read_output::<Rec>(&mut reader).unwrap() {
            items.push(item);
        }
        assert_eq!(items.len(), 7, "{items:?}");
        assert_eq!(items[0], Output::Line(Some(SupervisorLine::Ready)));
        assert_eq!(items[1], Output::Line(Some(SupervisorLine::Summary(serde_json::json!({"role": "monitor"})))));
        assert_eq!(items[2], Output::Line(None));
        // Floats exactly as written (the shortest round-trip text), −0 included.
        let Output::Record(Ok(rec)) = &items[3] else { panic!("{:?}", items[3]) };
        assert_eq!(rec.steps[0].to_bits(), 1.0000000000000002f64.to_bits());
        assert_eq!(rec.steps[1].to_bits(), (-0.0f64).to_bits());
        assert!(matches!(&items[4], Output::Record(Err(e)) if e.contains("line 1")), "{:?}", items[4]);
        assert_eq!(items[5], Output::Line(Some(SupervisorLine::Finished)));
        assert_eq!(items[6], Output::Line(None));
    }
}
