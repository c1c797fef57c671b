//! The figures of the experiments: curves with CI95 bands (the paper's Figures 5–9, 15), grouped bar
//! charts (Figures 10–13, 16, 17) and trajectories (Figure 4), drawn by the monitor's pure-Rust plotters
//! code as SVG or PNG by extension.

use std::path::Path;

use record::RunRecord;
use record::chart::{BarGroup, Series, plot_bars, plot_curves};
use record::plot::{PlotError, plot_trajectories};

use crate::stats::Summary;

/// One figure of a report.
#[derive(Debug, Clone)]
pub enum Figure {
    /// Curves over x (steps, scales), optionally with bands.
    Curves { name: String, title: String, x_label: String, y_label: String, series: Vec<Series>, log_y: bool },
    /// Grouped bars.
    Bars { name: String, title: String, y_label: String, series: Vec<String>, groups: Vec<BarGroup>, log_y: bool },
    /// The UAV paths of one run.
    Trajectories { name: String, run: Box<RunRecord> },
}

impl Figure {
    /// File-name part (`crlb`, `trajectories-mc`).
    pub fn name(&self) -> &str {
        match self {
            Figure::Curves { name, .. } | Figure::Bars { name, .. } | Figure::Trajectories { name, .. } => name,
        }
    }

    /// Draws into `path` (`.svg` or `.png`).
    pub fn draw(&self, path: &Path) -> Result<(), PlotError> {
        match self {
            Figure::Curves { title, x_label, y_label, series, log_y, .. } => {
                plot_curves(title, x_label, y_label, series, *log_y, path)
            }
            Figure::Bars { title, y_label, series, groups, log_y, .. } => {
                plot_bars(title, y_label, series, groups, *log_y, path)
            }
            Figure::Trajectories { run, .. } => plot_trajectories(run, path),
        }
    }
}

/// A curve of per-step summaries: the mean with its CI95 band, x = step index.
pub fn band_series(label: &str, curve: &[Summary]) -> Series {
    let x = (0..curve.len()).map(|k| k as f64).collect();
    let y = curve.iter().map(|s| s.mean).collect();
    let lo = curve.iter().map(|s| if s.ci95.is_finite() { s.mean - s.ci95 } else { s.mean }).collect();
    let hi = curve.iter().map(|s| if s.ci95.is_finite() { s.mean + s.ci95 } else { s.mean }).collect();
    Series { label: label.to_string(), x, y, band: Some((lo, hi)) }
}

/// A plain curve.
pub fn line_series(label: &str, x: Vec<f64>, y: Vec<f64>) -> Series {
    Series { label: label.to_string(), x, y, band: None }
}

/// A bar group from summaries (mean with CI95 whiskers).
pub fn summary_group(label: &str, values: &[Summary]) -> BarGroup {
    BarGroup {
        label: label.to_string(),
        values: values.iter().map(|s| Some(s.mean)).collect(),
        errors: values.iter().map(|s| s.ci95.is_finite().then_some((s.mean - s.ci95, s.mean + s.ci95))).collect(),
    }
}

/// A bar group of plain values.
pub fn value_group(label: &str, values: &[f64]) -> BarGroup {
    BarGroup {
        label: label.to_string(),
        values: values.iter().map(|v| Some(*v)).collect(),
        errors: vec![None; values.len()],
    }
}
