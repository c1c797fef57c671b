//! # uavloc-monitor
//!
//! The monitor's logic: per-step metrics against the truth, the run record (the JSON shape shared by
//! `uavloc simulate` and the process pipeline), plots of a run, generic report charts ([`chart`]: curves
//! with confidence bands, grouped bars); and the monitor process of the pipeline: [`assemble`] rebuilds
//! the record from the pipeline's messages (no IPC), [`process`] is its handler on the node runtime
//! over what it keeps of the run (`session`, also without IPC; with [`runlog`], [`stamps`] and
//! [`latency`]: its log, stamp file and latency statistics), [`front_end`] tells whether an external
//! front end is still there, and [`recording`] writes the run as MCAP.

/// The role name (node name suffix, `uavloc process monitor`).
pub const ROLE: &str = "monitor";

pub mod along_arcs;
pub mod args;
pub mod assemble;
mod canvas;
pub mod chart;
pub mod export;
pub mod front_end;
pub mod latency;
mod lines;
pub mod metrics;
pub mod plot;
pub mod png;
pub mod process;
pub mod record;
pub mod recording;
pub mod runlog;
mod session;
pub mod stamps;
mod status;
pub mod summary;

pub use along_arcs::safety_warnings;
pub use assemble::{Assembler, CompletedStep};
pub use chart::{BarGroup, Series, plot_bars, plot_curves};
pub use export::{ExportError, write_run, write_steps_csv, write_trajectory_csv};
pub use metrics::{RunningBound, StepMetrics, annotate, crlb_at, step_metrics};
pub use plot::{Metric, PlotError, PlotFormat, plot_comparison, plot_metrics, plot_trajectories};
pub use record::{RunRecord, StepRecord, StepSafety};
