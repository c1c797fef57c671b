//! # uavloc-record — a run as data: the record, its metrics, files, plots and MCAP recording
//!
//! What `uavloc simulate`, the monitor process, `uavloc paper` and `uavloc replay` share about a run,
//! as plain data and pure functions (no IPC):
//!
//! - [`record`]: the run record ([`RunRecord`], [`StepRecord`]), the JSON shape of every run;
//! - [`metrics`]: per-step metrics against the truth (CRLB at the truth, RMSE, the running PCRLB) and the
//!   run's totals ([`annotate`]); [`along_arcs`]: spacing and standoff along the arcs flown;
//! - [`geographic`]: a run's positions as latitude/longitude when it has an origin;
//! - [`export`]: a run's files (run.json, steps.csv, trajectory.csv, figures);
//! - [`plot`], [`chart`]: a run's figures and generic report charts (curves with confidence bands,
//!   grouped bars), SVG and PNG ([`png`]);
//! - [`map`]: a map of a run placed on the Earth, from its recording's map layer;
//! - [`recording`]: a run's messages as MCAP, with [`foxglove`]'s channels for Foxglove's own panels.
//!
//! Units: metres, seconds, radians.

pub mod along_arcs;
mod canvas;
pub mod chart;
pub mod export;
pub mod foxglove;
pub mod geographic;
pub mod map;
pub mod metrics;
pub mod plot;
pub mod png;
pub mod record;
pub mod recording;

pub use along_arcs::safety_warnings;
pub use chart::{BarGroup, Series, plot_bars, plot_curves};
pub use export::{ExportError, write_run, write_steps_csv, write_trajectory_csv};
pub use metrics::{RunningBound, StepMetrics, annotate, crlb_at, step_metrics};
pub use plot::{Metric, PlotError, PlotFormat, plot_comparison, plot_metrics, plot_trajectories};
pub use record::{ReceiverTotals, RunRecord, StepReceiver, StepRecord, StepSafety};
