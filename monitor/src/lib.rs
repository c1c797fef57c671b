//! # uavloc-monitor
//!
//! The monitor's logic, free of IPC: per-step metrics against the truth, the run record (the JSON shape
//! shared by `uavloc simulate` and the process pipeline), and plots of a run.

pub mod export;
pub mod metrics;
pub mod plot;
pub mod record;

pub use export::{ExportError, write_run, write_steps_csv, write_trajectory_csv};
pub use metrics::{StepMetrics, step_metrics};
pub use plot::{Metric, PlotError, PlotFormat, plot_comparison, plot_metrics, plot_trajectories};
pub use record::{RunRecord, StepRecord};
