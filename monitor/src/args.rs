//! The monitor's flags (`monitor [FLAGS]`, `uavloc process monitor [FLAGS]`) and the outputs they name:
//! checked before the run, written at its end.

use std::path::PathBuf;

use clap::Args;
use runtime::ProcessError;

use record::record::RunRecord;

/// What `monitor --help` shows after the flags.
pub const AFTER_HELP: &str = "\
The monitor subscribes to <domain>/measurement, /estimate, /command and /truth and needs the run's
--scenario, --steps and --seed (for the RMSE resamples and the record). Start it before emitter-sim.
It exits after the last step (or on Ctrl-C, writing what it has).

Examples:
  monitor --domain lab1 --log run.jsonl --record run.json
  monitor --domain lab1 --steps 6 --seed 3 --out runs/lab1 --quiet";

/// Flags of the monitor process (`monitor [FLAGS]` or `uavloc process monitor [FLAGS]`).
/// Also `Serialize`: [`runtime::flags::to_flags`] writes the command line of these flags.
#[derive(Args, serde::Serialize, Debug, Clone, PartialEq)]
pub struct MonitorArgs {
    /// The node (domain, link, quiet, supervised) and the run (scenario, steps, seed).
    #[command(flatten)]
    #[serde(flatten)]
    pub process: runtime::ProcessArgs,
    /// Where the measurements come from: simulator (emitter-sim, which also publishes the truth) or
    /// external (a front end outside uavloc; no truth: the columns that need one are absent, not zero).
    #[arg(long, value_name = "SOURCE", default_value = "simulator")]
    pub source: runtime::Source,
    /// Write the raw stamps of every recorded step to FILE as CSV (one row per step, CLOCK_MONOTONIC
    /// nanoseconds; 0 = missing): the chain's publish/receive stamps, when emitter-sim received the step's
    /// command (from the next step's messages) and when the monitor received each of the step's messages.
    /// What `uavloc bench latency` reads.
    #[arg(long, value_name = "FILE")]
    pub stamps: Option<PathBuf>,
    /// Write every event as one JSON object per line to FILE.
    #[arg(long, value_name = "FILE")]
    pub log: Option<PathBuf>,
    /// Record every message of the run to FILE as MCAP (JSON channels with JSON schemas: Foxglove and the
    /// Python `mcap` package open it; `uavloc replay FILE` runs the estimator and planner on it again).
    /// With --resume the messages already in FILE are kept.
    #[arg(long, value_name = "FILE")]
    pub mcap: Option<PathBuf>,
    /// Write the run record (the JSON of `uavloc simulate --json`) to FILE at the end.
    #[arg(long, value_name = "FILE")]
    pub record: Option<PathBuf>,
    /// Write trajectory.csv, steps.csv, run.json and the plots into DIR at the end.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Print the run record as JSON on stdout at the end.
    #[arg(long)]
    pub print_record: bool,
    /// A restart: append to --log instead of truncating it, take the steps recorded there, and have
    /// emitter-sim replay the rest of the run.
    #[arg(long)]
    pub resume: bool,
    /// With aircraft (`launch --autopilot`): follow the MAVLink bridge's swarm state and log each change of
    /// a UAV's link (`link` events: flying, not_guided, quiet; the live view shows them).
    #[arg(long)]
    pub links: bool,
}

impl MonitorArgs {
    /// Checks the outputs written at the end before the run starts: a run is never recorded for nothing.
    pub fn check_outputs(&self) -> Result<(), ProcessError> {
        // No two outputs on one file either (one would overwrite the other, or the log read back another's
        // lines).
        let files = [
            ("--log", self.log.as_deref()),
            ("--stamps", self.stamps.as_deref()),
            ("--mcap", self.mcap.as_deref()),
            ("--record", self.record.as_deref()),
        ];
        runtime::output::check_outputs(&files, ("--out", self.out.as_deref(), &record::export::RUN_FILES))
            .map_err(ProcessError::Input)
    }

    /// Writes the run record to `--record` and the run's files into `--out`.
    pub(crate) fn write_outputs(&self, run: &RunRecord) -> Result<(), ProcessError> {
        if let Some(path) = &self.record {
            let text = serde_json::to_string_pretty(run).map_err(|e| ProcessError::failed_because("--record", e))?;
            std::fs::write(path, text + "\n")
                .map_err(|e| ProcessError::failed_because(format!("--record {}", path.display()), e))?;
        }
        if let Some(dir) = &self.out {
            record::export::write_run(run, dir)
                .map_err(|e| ProcessError::failed_because(format!("--out {}", dir.display()), e))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_flags_round_trip() {
        let link = runtime::LinkArgs { transport: protocol::TransportKind::Uds, wait: None, spin_us: Some(30) };
        let m = MonitorArgs {
            process: runtime::ProcessArgs {
                node: runtime::NodeArgs {
                    domain: Some("d".into()),
                    link,
                    quiet: true,
                    supervised: true,
                    watch_pid: None,
                },
                run: runtime::RunArgs { scenario: Some("a b.toml".into()), steps: Some(7), seed: Some(9) },
            },
            source: runtime::Source::External,
            mcap: Some("run.mcap".into()),
            stamps: Some("s.csv".into()),
            log: Some("l.jsonl".into()),
            record: Some("r.json".into()),
            // A value that begins with `-` (written `--out=-o`, not taken for a flag).
            out: Some("-o".into()),
            print_record: true,
            resume: true,
            links: true,
        };
        assert_eq!(runtime::flags::round_trip(&m).unwrap(), m);
    }
}
