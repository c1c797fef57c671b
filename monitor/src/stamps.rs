//! The monitor's `--stamps` CSV: the raw CLOCK_MONOTONIC stamps of every recorded step (what
//! `uavloc bench latency` reads), kept across a monitor restart.

use std::fs::File;
use std::io::Write as _;
use std::path::Path;

use crate::lines::LineFile;

use protocol::Stamps;
use runtime::ProcessError;

/// The `--stamps` CSV file: one row per recorded step, flushed ([`LineFile`]) before the log's lines of
/// the same wake-up.
pub(crate) struct StampsCsv {
    out: LineFile,
}

/// Header of the `--stamps` CSV (see [`crate::args::MonitorArgs::stamps`]).
pub const STAMPS_HEADER: &str = "step,trigger_command_published_ns,trigger_command_received_ns,\
measurement_published_ns,measurement_received_ns,estimate_published_ns,estimate_received_ns,command_published_ns,\
command_received_ns,monitor_measurement_ns,monitor_estimate_ns,monitor_command_ns,monitor_truth_ns";

/// The rows of an existing stamps file for steps before `next` (header first); a restarted monitor keeps
/// them — and drops a row its predecessor wrote for a step it did not log, which it records again.
pub(crate) fn stamps_kept(text: &str, next: u64) -> String {
    let mut out = String::from(STAMPS_HEADER);
    out.push('\n');
    for line in text.lines().skip(1) {
        if line.split(',').next().and_then(|s| s.parse::<u64>().ok()).is_some_and(|k| k < next) {
            out.push_str(line);
            out.push('\n');
        }
    }
    out
}

impl StampsCsv {
    /// A new file (header only), or with `resume_at` the rows of an existing one for steps before it.
    pub(crate) fn create(path: &Path, resume_at: Option<u64>) -> Result<Self, ProcessError> {
        // A file that cannot be opened is a bad flag (exit 2); one that cannot be written, a run that
        // cannot be measured (exit 3): neither is worth a restart.
        let msg = |e: std::io::Error| format!("--stamps {}: {e}", path.display());
        let start = match resume_at {
            Some(next) => stamps_kept(&std::fs::read_to_string(path).unwrap_or_default(), next),
            None => format!("{STAMPS_HEADER}\n"),
        };
        let mut out =
            File::create(path).map_err(|e| ProcessError::input_because(format!("--stamps {}", path.display()), e))?;
        out.write_all(start.as_bytes()).map_err(|e| ProcessError::Unrecoverable(msg(e)))?;
        Ok(StampsCsv { out: LineFile::new(out, path, "--stamps", "") })
    }

    pub(crate) fn row(&mut self, step: u64, s: &Stamps, command_received_ns: u64, rx: [u64; 4]) {
        let line = format!(
            "{step},{},{},{},{},{},{},{},{command_received_ns},{},{},{},{}\n",
            s.trigger_command_published_ns,
            s.trigger_command_received_ns,
            s.measurement_published_ns,
            s.measurement_received_ns,
            s.estimate_published_ns,
            s.estimate_received_ns,
            s.command_published_ns,
            rx[0],
            rx[1],
            rx[2],
            rx[3]
        );
        self.out.push(&line);
    }

    /// Writes the rows added since the last flush.
    pub(crate) fn flush(&mut self) {
        self.out.flush();
    }

    /// The first write error, as the unrecoverable end of the run.
    pub(crate) fn check(&self) -> Result<(), ProcessError> {
        self.out.check()
    }

    pub(crate) fn finish(mut self) -> Result<(), ProcessError> {
        self.flush();
        self.check()
    }
}
