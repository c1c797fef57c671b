//! `uavloc locate --fuse FILE`: the fused posterior of recorded TDOA snapshots (the `fused` estimator of
//! a run, over a file instead of the pipeline). The parsing is a pure function of the text
//! ([`parse_snapshots`]); every malformed line is an error naming its number.

use std::path::Path;

use estimation::{EstimateStatus, Estimator, EstimatorConfig};
use nalgebra::Vector2;
use serde::Serialize;
use tdoa::{Dynamics, NoiseModel, RangeDiffs, SPEED_OF_LIGHT};

use crate::error::CliError;
use crate::output::{Diagnostic, Table, pair, rows};

/// One recorded snapshot.
#[derive(Debug, Clone, PartialEq)]
pub struct Snapshot {
    /// 1-based line of the file.
    pub line: usize,
    /// UAV positions, metres (index 0 the reference).
    pub uavs: Vec<Vector2<f64>>,
    /// Range differences `d_i = r_i − r_0`, metres.
    pub range_diffs: Vec<f64>,
    /// Range σ per UAV, metres.
    pub sigmas: Vec<f64>,
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct JsonSnapshot {
    uavs: Vec<[f64; 2]>,
    range_diffs: Vec<f64>,
    #[serde(default)]
    sigma: Option<serde_json::Value>,
    #[serde(default)]
    sigma_ns: Option<serde_json::Value>,
}

fn bad(line: usize, what: impl std::fmt::Display) -> CliError {
    CliError::Input(format!("--fuse: line {line}: {what}"))
}

fn sigmas_of(line: usize, n: usize, v: &serde_json::Value, scale: f64) -> Result<Vec<f64>, CliError> {
    let list: Vec<f64> = match v {
        serde_json::Value::Number(x) => vec![x.as_f64().unwrap_or(f64::NAN); n],
        serde_json::Value::Array(a) => a.iter().map(|x| x.as_f64().unwrap_or(f64::NAN)).collect(),
        _ => return Err(bad(line, "sigma must be a number or a list of numbers")),
    };
    if list.len() != n {
        return Err(bad(line, format!("{} sigma values for {n} UAVs", list.len())));
    }
    Ok(list.into_iter().map(|s| s * scale).collect())
}

/// Parses the snapshots of a CSV or JSON-lines text (see `uavloc locate --help`). Blank lines and lines
/// starting with `#` are skipped, as is a CSV header (a first line starting with a letter).
pub fn parse_snapshots(text: &str) -> Result<Vec<Snapshot>, CliError> {
    let mut out = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let t = raw.trim();
        if t.is_empty() || t.starts_with('#') || (out.is_empty() && t.starts_with(|c: char| c.is_ascii_alphabetic())) {
            continue;
        }
        let snap = if t.starts_with('{') {
            let j: JsonSnapshot = serde_json::from_str(t).map_err(|e| bad(line, e))?;
            let n = j.uavs.len();
            let sigmas = match (&j.sigma, &j.sigma_ns) {
                (Some(s), None) => sigmas_of(line, n, s, 1.0)?,
                (None, Some(s)) => sigmas_of(line, n, s, 1e-9 * SPEED_OF_LIGHT)?,
                _ => return Err(bad(line, "give exactly one of \"sigma\" (m) or \"sigma_ns\" (ns)")),
            };
            Snapshot { line, uavs: tdoa::points_from_arrays(&j.uavs), range_diffs: j.range_diffs, sigmas }
        } else {
            let values: Vec<f64> = t
                .split(',')
                .map(|c| c.trim().parse::<f64>().map_err(|_| bad(line, format!("'{}' is not a number", c.trim()))))
                .collect::<Result<_, _>>()?;
            // 2N + (N − 1) + 1 = 3N values.
            if !values.len().is_multiple_of(3) || !(9..=3 * tdoa::MAX_UAVS).contains(&values.len()) {
                return Err(bad(
                    line,
                    format!(
                        "{} values; a CSV snapshot of N UAVs (3..8) has 3N: x0,y0,..,d1,..,d(N-1),sigma",
                        values.len()
                    ),
                ));
            }
            let n = values.len() / 3;
            let uavs = (0..n).map(|k| Vector2::new(values[2 * k], values[2 * k + 1])).collect();
            Snapshot { line, uavs, range_diffs: values[2 * n..3 * n - 1].to_vec(), sigmas: vec![values[3 * n - 1]; n] }
        };
        if let Some(v) =
            snap.uavs.iter().flat_map(|p| [p.x, p.y]).chain(snap.range_diffs.iter().copied()).find(|v| !v.is_finite())
        {
            return Err(bad(line, format!("{v} is not a finite number")));
        }
        if snap.range_diffs.len() + 1 != snap.uavs.len() {
            return Err(bad(
                line,
                format!("{} range differences for {} UAVs (need N − 1)", snap.range_diffs.len(), snap.uavs.len()),
            ));
        }
        out.push(snap);
    }
    if out.is_empty() {
        return Err(CliError::Input("--fuse: the file holds no snapshot".into()));
    }
    Ok(out)
}

/// The fused estimate after one snapshot.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FusedLine {
    /// The file's line.
    pub line: usize,
    /// `ok` (fused; the first is Chan's), `ambiguous`, `rejected` (failed the χ² gate) or `failed`.
    pub status: String,
    /// The estimate after it, metres.
    pub estimate: [f64; 2],
    /// Its covariance, m².
    pub cov: [[f64; 2]; 2],
    /// The UAVs whose arrival was dropped as an outlier (a late, multipath arrival; the rest fused).
    pub outliers: Vec<usize>,
}

/// `uavloc locate --fuse` output.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FuseReport {
    /// The fused x, metres.
    pub x: f64,
    /// The fused y, metres.
    pub y: f64,
    /// Its covariance, m².
    pub cov: [[f64; 2]; 2],
    /// Snapshots read.
    pub snapshots: usize,
    /// Snapshots fused (the first included).
    pub fused: usize,
    /// Snapshots not fused: they failed the χ² gate.
    pub rejected_snapshots: usize,
    /// Snapshots that could not be used (e.g. collinear UAVs before the start).
    pub failed: usize,
    /// Arrivals dropped as outliers (their snapshots fused without them).
    pub outlier_arrivals: usize,
    /// The estimate after each snapshot.
    pub steps: Vec<FusedLine>,
}

/// Fuses the snapshots of the file at `path` (`prior` resolves the first fix's 3-UAV ambiguity).
pub fn run(path: &Path, prior: Option<Vector2<f64>>) -> Result<FuseReport, CliError> {
    let text =
        std::fs::read_to_string(path).map_err(|e| CliError::input_because(format!("--fuse {}", path.display()), e))?;
    fuse(&parse_snapshots(&text)?, prior)
}

/// Fuses `snapshots` in order with the `fused` estimator (static emitter).
pub fn fuse(snapshots: &[Snapshot], prior: Option<Vector2<f64>>) -> Result<FuseReport, CliError> {
    let mut est = match prior {
        Some(p) => {
            Estimator::resume(EstimatorConfig::fused(Dynamics::fixed()), 0, p, nalgebra::Matrix2::identity(), None)
        }
        None => Estimator::with_config(EstimatorConfig::fused(Dynamics::fixed())),
    };
    // A prior only picks Chan's root: the resumed estimator holds no posterior, so the first fix starts it.
    let mut steps = Vec::with_capacity(snapshots.len());
    let (mut fused, mut rejected, mut failed, mut outliers) = (0, 0, 0, 0);
    let mut last = None;
    for (k, s) in snapshots.iter().enumerate() {
        let noise = NoiseModel::from_range_sigmas(&s.sigmas).map_err(|e| bad(s.line, e))?;
        let d = RangeDiffs::from_slice(&s.range_diffs).map_err(|e| bad(s.line, e))?;
        match est.estimate(k as u64 + 1, &s.uavs, &d, &noise) {
            Ok(out) => {
                match out.status {
                    EstimateStatus::Ok | EstimateStatus::Ambiguous => fused += 1,
                    EstimateStatus::Rejected { .. } => rejected += 1,
                    EstimateStatus::Failed { .. } | EstimateStatus::Predicted => failed += 1,
                }
                let line = FusedLine {
                    line: s.line,
                    status: out.status.name().to_string(),
                    estimate: [out.position.x, out.position.y],
                    cov: rows(&out.covariance),
                    outliers: (0..s.uavs.len()).filter(|i| out.outliers & (1u8 << i) != 0).collect(),
                };
                outliers += line.outliers.len();
                if !matches!(out.status, EstimateStatus::Failed { .. }) {
                    last = Some((line.estimate, line.cov));
                }
                steps.push(line);
            }
            Err(e) => {
                failed += 1;
                if k + 1 == snapshots.len() {
                    return Err(bad(s.line, e));
                }
            }
        }
    }
    let Some((position, cov)) = last else {
        return Err(CliError::Input("--fuse: no snapshot could be solved (is the geometry degenerate?)".into()));
    };
    Ok(FuseReport {
        x: position[0],
        y: position[1],
        cov,
        snapshots: snapshots.len(),
        fused,
        rejected_snapshots: rejected,
        failed,
        outlier_arrivals: outliers,
        steps,
    })
}

impl FuseReport {
    /// The report as a table.
    pub fn table(&self) -> Table {
        let mut t = crate::locate::position_rows(Table::new(), self.x, self.y, self.cov).row(
            "snapshots",
            format!(
                "{} read, {} fused, {} rejected (χ² gate), {} failed",
                self.snapshots, self.fused, self.rejected_snapshots, self.failed
            ),
        );
        for s in &self.steps {
            t = t.row(format!("line {}", s.line), format!("{} m  {}", pair(s.estimate), s.status));
        }
        t
    }

    /// Warnings: rejected or failed snapshots.
    pub fn diagnostics(&self) -> Vec<Diagnostic> {
        let mut out = Vec::new();
        if self.rejected_snapshots > 0 {
            out.push(Diagnostic::Warning(format!(
                "{} snapshot(s) failed the χ² gate and were not fused (status \"rejected\")",
                self.rejected_snapshots
            )));
        }
        if self.failed > 0 {
            out.push(Diagnostic::Warning(format!("{} snapshot(s) could not be used (status \"failed\")", self.failed)));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(uavs: &[[f64; 2]], z: [f64; 2], noise: [f64; 2]) -> String {
        let r = |p: &[f64; 2]| (p[0] - z[0]).hypot(p[1] - z[1]);
        let d: Vec<f64> = uavs[1..].iter().zip(noise).map(|(p, e)| r(p) - r(&uavs[0]) + e).collect();
        let mut v: Vec<String> = uavs.iter().flat_map(|p| [p[0].to_string(), p[1].to_string()]).collect();
        v.extend(d.iter().map(|x| x.to_string()));
        v.push("28.7712".into());
        v.join(",")
    }

    #[test]
    fn noise_free_snapshots_fuse_to_the_truth_and_a_late_arrival_is_dropped_a_wild_snapshot_rejected() {
        let z = [25_000.0, 15_000.0];
        let mut text = String::from("x0,y0,x1,y1,x2,y2,d1,d2,sigma\n");
        for k in 0..6 {
            let t = 500.0 * k as f64;
            text += &line(&[[1500.0 + t, 500.0], [10_000.0 + t, 1500.0 + t], [5000.0, 8500.0 + t]], z, [0.0, 0.0]);
            text += "\n";
        }
        // UAV1's arrival 3 km late (a reflection): dropped, the other two fused.
        text += &line(&[[5000.0, 500.0], [13_000.0, 4500.0], [5000.0, 11_500.0]], z, [3000.0, 0.0]);
        text += "\n";
        // UAV1 3 km early, UAV2 2 km late: no single late arrival explains it; the snapshot is rejected.
        text += &line(&[[5000.0, 500.0], [13_000.0, 4500.0], [5000.0, 11_500.0]], z, [-3000.0, 2000.0]);
        text += "\n";
        let snaps = parse_snapshots(&text).unwrap();
        assert_eq!(snaps.len(), 8);
        let r = fuse(&snaps, Some(Vector2::new(20_000.0, 20_000.0))).unwrap();
        assert!((r.x - z[0]).hypot(r.y - z[1]) < 1e-3, "{r:?}");
        assert_eq!((r.fused, r.rejected_snapshots, r.failed, r.outlier_arrivals), (7, 1, 0, 1));
        assert_eq!(r.steps[6].outliers, vec![1]);
        assert_eq!(r.steps.last().unwrap().status, "rejected");
        // The covariance shrank with every fused snapshot.
        let tr: Vec<f64> = r.steps.iter().map(|s| s.cov[0][0] + s.cov[1][1]).collect();
        assert!(tr.windows(2).take(5).all(|w| w[1] < w[0]), "{tr:?}");
    }

    #[test]
    fn json_lines_and_bad_lines() {
        let ok = r#"{"uavs": [[1500,500],[10000,1500],[5000,8500]], "range_diffs": [-7432.966,-6583.662], "sigma": 28.7712}"#;
        assert_eq!(parse_snapshots(ok).unwrap()[0].sigmas, vec![28.7712; 3]);
        let ns = r#"{"uavs": [[1500,500],[10000,1500],[5000,8500]], "range_diffs": [-7432.966,-6583.662], "sigma_ns": [1,2,3]}"#;
        assert!((parse_snapshots(ns).unwrap()[0].sigmas[2] - 3e-9 * SPEED_OF_LIGHT).abs() < 1e-12);
        for (text, needle) in [
            ("1,2,3,4,5,6,7,8\n", "line 1"),
            ("1,2,3,4,5,6,7,x,9\n", "'x'"),
            ("1,2,3,4,5,6,7,nan,9\n", "finite"),
            ("# c\n\n{\"uavs\": [[0,0]], \"range_diffs\": [], \"sigma\": 1, \"extra\": 2}\n", "line 3"),
            (r#"{"uavs": [[0,0],[1,1],[2,0]], "range_diffs": [1], "sigma": 1}"#, "range differences"),
            ("", "no snapshot"),
        ] {
            let e = parse_snapshots(text).unwrap_err().to_string();
            assert!(e.contains(needle), "{text:?}: {e}");
        }
    }
}
