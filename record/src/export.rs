//! Export of a run record: CSV tables, the plots of [`crate::plot`] and the record itself as JSON.
//!
//! CSV conventions: comma-separated, `\n` line ends, a header row; numbers in Rust's shortest
//! round-trip form (`inf` / `NaN` for non-finite values); an empty cell for `None` (or for a missing
//! entry, e.g. a heading a step did not record); text cells quoted (RFC 4180) only when they contain
//! a comma, a quote or a line break.

use std::fs::{self, File};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use thiserror::Error;

use crate::plot::{PlotError, plot_metrics, plot_trajectories};
use crate::record::RunRecord;

/// File names written by [`write_run`], in the order of its returned paths.
pub const RUN_FILES: [&str; 7] =
    ["trajectory.csv", "steps.csv", "trajectories.svg", "trajectories.png", "metrics.svg", "metrics.png", "run.json"];

/// Why an export failed; every variant names the path concerned.
#[derive(Debug, Error)]
pub enum ExportError {
    /// Creating the directory or writing a CSV file failed.
    #[error("cannot write {}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    /// Serialising the record to JSON failed.
    #[error("cannot write {}: {source}", path.display())]
    Json {
        path: PathBuf,
        #[source]
        source: serde_json::Error,
    },
    /// A plot could not be drawn or written.
    #[error(transparent)]
    Plot(#[from] PlotError),
}

/// Writes one row per step and UAV: `step,uav,x_m,y_m,heading_rad`, and `lat_deg,lon_deg` when the run
/// has an origin.
pub fn write_trajectory_csv(run: &RunRecord, path: &Path) -> io::Result<()> {
    let mut out = BufWriter::new(File::create(path)?);
    let geo = run.scenario.origin.is_some();
    writeln!(out, "step,uav,x_m,y_m,heading_rad{}", if geo { ",lat_deg,lon_deg" } else { "" })?;
    for step in &run.steps {
        for (i, [x, y]) in step.uavs.iter().enumerate() {
            let heading = opt(step.headings_rad.get(i).copied());
            write!(out, "{},{i},{x},{y},{heading}", step.step)?;
            if geo {
                let at = step.geo.as_ref().and_then(|g| g.uavs_lat_lon_deg.get(i));
                write!(out, ",{},{}", opt(at.map(|p| p[0])), opt(at.map(|p| p[1])))?;
            }
            writeln!(out)?;
        }
    }
    out.flush()
}

/// Writes one row per step: `step,crlb_true_m,rmse_m,estimate_x_m,estimate_y_m,estimate_status,
/// objective_value_m,plan_ms,active_constraints,pcrlb_m,estimate_error_m,nees,min_true_distance_m,
/// estimate_cov_xx_m2,estimate_cov_xy_m2,estimate_cov_yy_m2,crlb_at_estimate_m,pcrlb_at_estimate_m,certified,
/// min_pair_m,standoff_margin_m,min_true_distance_along_m` (the last four: the interval's safety along
/// the arcs flown to the next step, [`crate::StepSafety`]; `certified` is `true`, `false` or empty; the active constraints
/// joined with `;`; the truth-based columns empty without a truth). A run with an origin adds
/// `estimate_lat_deg,estimate_lon_deg`.
pub fn write_steps_csv(run: &RunRecord, path: &Path) -> io::Result<()> {
    let mut out = BufWriter::new(File::create(path)?);
    let geo = run.scenario.origin.is_some();
    writeln!(
        out,
        "step,crlb_true_m,rmse_m,estimate_x_m,estimate_y_m,estimate_status,objective_value_m,plan_ms,active_constraints,\
         pcrlb_m,estimate_error_m,nees,min_true_distance_m,estimate_cov_xx_m2,estimate_cov_xy_m2,estimate_cov_yy_m2,crlb_at_estimate_m,\
         pcrlb_at_estimate_m,certified,min_pair_m,standoff_margin_m,min_true_distance_along_m{}",
        if geo { ",estimate_lat_deg,estimate_lon_deg" } else { "" }
    )?;
    for s in &run.steps {
        write_step_row(&mut out, s)?;
        if geo {
            let at = s.geo.as_ref().and_then(|g| g.estimate_lat_lon_deg);
            write!(out, ",{},{}", opt(at.map(|p| p[0])), opt(at.map(|p| p[1])))?;
        }
        writeln!(out)?;
    }
    out.flush()
}

/// The columns of one step of `steps.csv` that every run has (no line end).
fn write_step_row(out: &mut impl Write, s: &crate::StepRecord) -> io::Result<()> {
    write!(
        out,
        "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
        s.step,
        opt(s.crlb_true_m),
        opt(s.rmse_m),
        s.estimate[0],
        s.estimate[1],
        csv_text(&s.estimate_status),
        opt(s.objective_value),
        opt(s.plan_ms),
        csv_text(&s.active_constraints.join(";")),
        opt(s.pcrlb_m),
        opt(s.estimate_error_m),
        opt(s.nees),
        opt(s.min_true_distance_m),
        s.estimate_cov[0][0],
        s.estimate_cov[0][1],
        s.estimate_cov[1][1],
        opt(s.crlb_at_estimate_m),
        opt(s.pcrlb_at_estimate_m),
        s.safety.and_then(|x| x.certified).map_or(String::new(), |c| c.to_string()),
        opt(s.safety.and_then(|x| x.min_pair_m)),
        opt(s.safety.and_then(|x| x.standoff_margin_m)),
        opt(s.safety.and_then(|x| x.min_true_distance_m)),
    )
}

/// Writes the whole run into `dir` (created if needed): the files of [`RUN_FILES`] — both CSV tables,
/// the trajectory and metric plots as SVG and PNG, and `run.json` (the record, pretty-printed).
/// Returns the paths written, in that order. Existing files are overwritten.
///
/// Note: JSON has no non-finite numbers, so serde_json writes an infinite `crlb_true_m` as `null`.
pub fn write_run(run: &RunRecord, dir: &Path) -> Result<Vec<PathBuf>, ExportError> {
    fs::create_dir_all(dir).map_err(|source| ExportError::Io { path: dir.to_path_buf(), source })?;
    let paths: Vec<PathBuf> = RUN_FILES.iter().map(|name| dir.join(name)).collect();
    let io_error = |path: &Path, source| ExportError::Io { path: path.to_path_buf(), source };

    write_trajectory_csv(run, &paths[0]).map_err(|e| io_error(&paths[0], e))?;
    write_steps_csv(run, &paths[1]).map_err(|e| io_error(&paths[1], e))?;
    plot_trajectories(run, &paths[2])?;
    plot_trajectories(run, &paths[3])?;
    plot_metrics(run, &paths[4])?;
    plot_metrics(run, &paths[5])?;
    write_json(run, &paths[6])?;
    Ok(paths)
}

fn write_json(run: &RunRecord, path: &Path) -> Result<(), ExportError> {
    let file = File::create(path).map_err(|source| ExportError::Io { path: path.to_path_buf(), source })?;
    let mut out = BufWriter::new(file);
    serde_json::to_writer_pretty(&mut out, run)
        .map_err(|source| ExportError::Json { path: path.to_path_buf(), source })?;
    out.write_all(b"\n")
        .and_then(|()| out.flush())
        .map_err(|source| ExportError::Io { path: path.to_path_buf(), source })
}

/// A number, or the empty cell.
fn opt(v: Option<f64>) -> String {
    v.map(|v| v.to_string()).unwrap_or_default()
}

/// A text cell, quoted when it contains a delimiter, a quote or a line break.
fn csv_text(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) { format!("\"{}\"", s.replace('"', "\"\"")) } else { s.to_owned() }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_cells_are_quoted_only_when_needed() {
        assert_eq!(csv_text("ok"), "ok");
        assert_eq!(csv_text("d_min;l_min"), "d_min;l_min");
        assert_eq!(csv_text("a,b"), "\"a,b\"");
        assert_eq!(csv_text("say \"hi\""), "\"say \"\"hi\"\"\"");
        assert_eq!(csv_text(""), "");
    }

    #[test]
    fn none_is_an_empty_cell() {
        assert_eq!(opt(None), "");
        assert_eq!(opt(Some(1.5)), "1.5");
        assert_eq!(opt(Some(f64::INFINITY)), "inf");
    }
}
