//! `uavloc locate`: the emitter position from measured range differences (Chan's estimator).

use clap::Args;
use nalgebra::Vector2;
use serde::Serialize;
use tdoa::{RangeDiffs, Sensors};

use crate::args::{NumList, Point, SensorArgs, parse_list, parse_point};
use crate::error::CliError;
use crate::output::{Diagnostic, Report, Table, matrix, num, pair, rows};

/// Description shown by `uavloc locate --help`.
pub const LONG_ABOUT: &str = "\
Locates the emitter from measured range differences d_i = r_i − r_0 (metres) with Chan's
closed-form estimator, and reports its covariance F⁻¹ at the estimate (m²), whether the 3-UAV
two-solution ambiguity remained, and all physically valid candidates.";

/// Help text shown after the options of `uavloc locate --help`.
pub const AFTER_HELP: &str = "\
Conventions: positions in metres; the first --uav is the reference UAV0; --range-diff lists
d_i = r_i − r_0 for i = 1..N−1 in --uav order (r_i = distance from UAV i to the emitter), i.e. one value
per non-reference UAV. --sigma/--sigma-ns set the noise used for the covariance of the estimate
(cov = F⁻¹ at the estimate, m²).

With 3 UAVs two positions can fit the same range differences: without --prior the first is reported,
\"ambiguous\": true, both are listed in \"candidates\" and a warning goes to stderr; with --prior the
candidate nearer to it is chosen. With 4 or more UAVs the solution is unique: the maximum likelihood of
the range differences, by Gauss–Newton from Chan's two-step WLS (which alone can be kilometres off when
four UAVs form a rectangle with the emitter near its centre or on an axis of symmetry).

Examples:
  # the paper's nominal geometry; these range differences come from an emitter at (25000, 15000)
  uavloc locate --uav 1500,500 --uav 10000,1500 --uav 5000,8500 --range-diff -7432.966,-6583.662 --sigma 28.7712
  # 4 UAVs, negative coordinates and range differences, JSON (emitter near (-4000, -3000))
  uavloc locate --uav -1500,200 --uav 0,0 --uav 800,-900 --uav 300,700 --range-diff 939.2,1178.5,1612 \\
      --sigma-ns 30 --json
  # UAVs as latitude/longitude (WGS84) around an origin; the fix also as latitude/longitude
  uavloc locate --origin 47.3977,8.5456,488 --uav-lat-lon 47.4021952,8.5654704 \\
      --uav-lat-lon 47.4111142,8.6780919 --uav-lat-lon 47.4741281,8.6119250 \\
      --range-diff -7432.966,-6583.662 --sigma 28.7712

Fusing recorded snapshots (--fuse FILE): one snapshot per line, in time order, either CSV
  x0,y0,x1,y1,...,x{N-1},y{N-1},d1,...,d{N-1},sigma        (a header line starting with a letter is skipped)
or JSON lines
  {\"uavs\": [[x0,y0],..], \"range_diffs\": [d1,..], \"sigma\": s}   (sigma: one value or one per UAV)
(N = 3..8 may change between lines; metres). The first snapshot Chan can solve starts the posterior
(--prior resolves its 3-UAV ambiguity); every later one is fused by the χ²-gated iterated EKF of the
`fused` estimator (static emitter); a snapshot failing the gate is reported and not fused. Output:
the fused position and its covariance, the steps fused and rejected, and the estimate after each line.
  uavloc locate --fuse recorded.csv --prior 20000,20000 --json

Exit codes: 0 success; 2 bad input (a malformed line names its number), collinear UAVs, or range
differences no emitter can produce.";

/// Arguments of `uavloc locate`.
#[derive(Args, Debug, Clone, PartialEq)]
pub struct LocateArgs {
    #[command(flatten)]
    pub sensors: SensorArgs,
    /// Measured range differences d_i = r_i − r_0 in metres, one per non-reference UAV (N−1 values).
    #[arg(
        long = "range-diff",
        value_name = "D1,D2,..",
        allow_hyphen_values = true,
        value_parser = parse_list,
        required_unless_present = "fuse",
        help_heading = "Measurements"
    )]
    pub range_diff: Option<NumList>,
    /// Fuse recorded snapshots instead: a CSV or JSON-lines FILE, one snapshot per line (see below),
    /// giving the posterior of the emitter position from all of them (the `fused` estimator).
    #[arg(long, value_name = "FILE", conflicts_with_all = ["range_diff", "uavs", "sigma", "sigma_ns"], help_heading = "Measurements")]
    pub fuse: Option<std::path::PathBuf>,
    /// Rough emitter position X,Y in metres that picks between the two 3-UAV solutions.
    #[arg(long, value_name = "X,Y", allow_hyphen_values = true, value_parser = parse_point, help_heading = "Measurements")]
    pub prior: Option<Point>,
}

/// Chan's estimate of the emitter position.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LocateReport {
    /// Estimated x, metres.
    pub x: f64,
    /// Estimated y, metres.
    pub y: f64,
    /// Covariance of the estimate (`F⁻¹` at it), m², row-major.
    pub cov: [[f64; 2]; 2],
    /// Two solutions fit and no prior chose between them.
    pub ambiguous: bool,
    /// Every physically valid solution, metres.
    pub candidates: Vec<[f64; 2]>,
    /// With `--origin`: the estimate as latitude/longitude and its 95 % ellipse (absent otherwise).
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub geo: Option<GeoFix>,
}

/// A fix placed on the Earth (`--origin`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GeoFix {
    /// Latitude of the estimate, degrees.
    pub lat_deg: f64,
    /// Longitude of the estimate, degrees.
    pub lon_deg: f64,
    /// The 95 % confidence ellipse of the estimate, a closed polygon of `[lat, lon]` (degrees).
    pub ellipse_95_lat_lon_deg: Option<Vec<[f64; 2]>>,
}

impl GeoFix {
    /// The fix at `xy` with covariance `cov` (metres, m²) in `frame`; `None` when it is too far.
    pub fn of(frame: &model::geo::LocalFrame, xy: [f64; 2], cov: [[f64; 2]; 2]) -> Option<Self> {
        let at = frame.to_geodetic(xy).ok()?;
        let ring = record::geographic::ellipse_95_lat_lon(frame, xy, cov);
        Some(Self { lat_deg: at.lat_deg, lon_deg: at.lon_deg, ellipse_95_lat_lon_deg: ring })
    }

    /// Its rows of a table.
    pub fn rows(&self, t: Table) -> Table {
        t.row("lat, lon", format!("{:.7}°, {:.7}°", self.lat_deg, self.lon_deg))
    }
}

/// Locates the emitter from range differences `d` (`d_i = r_i − r_0`, metres).
pub fn compute(sensors: &Sensors, d: &[f64], prior: Option<Vector2<f64>>) -> Result<LocateReport, CliError> {
    let expected = sensors.len() - 1;
    if d.len() != expected {
        return Err(CliError::Input(format!(
            "--range-diff has {} value(s) but {} UAVs need {expected} (d_i = r_i − r_0 for i = 1..{expected})",
            d.len(),
            sensors.len()
        )));
    }
    let diffs = RangeDiffs::from_slice(d).map_err(CliError::tdoa_in("--range-diff"))?;
    // The maximum likelihood from Chan's estimate: near a rectangle's axes Chan's WLS loses the emitter.
    let sol = tdoa::maximum_likelihood(sensors, &diffs, prior)?;
    Ok(LocateReport {
        x: sol.position.x,
        y: sol.position.y,
        cov: rows(&sol.covariance),
        ambiguous: sol.ambiguous,
        candidates: sol.candidates.iter().map(|c| [c.x, c.y]).collect(),
        geo: None,
    })
}

/// What `uavloc locate` prints: one Chan fix, or the fused posterior of a file of snapshots.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum LocateOutput {
    /// One snapshot, Chan.
    Snapshot(LocateReport),
    /// `--fuse FILE`.
    Fused(crate::fuse::FuseReport),
}

/// Runs `uavloc locate`.
pub fn run(args: &LocateArgs) -> Result<LocateOutput, CliError> {
    if let Some(path) = &args.fuse {
        return crate::fuse::run(path, args.prior.map(|p| p.vector())).map(LocateOutput::Fused);
    }
    // Without --fuse, clap requires --uav, --range-diff and one of --sigma/--sigma-ns (see `cli::Command`).
    let d = args.range_diff.as_ref().ok_or_else(|| CliError::Input("--range-diff is required".into()))?;
    let mut report = compute(&args.sensors.sensors()?, &d.0, args.prior.map(|p| p.vector()))?;
    if let Some(frame) = args.sensors.uav.frame()? {
        report.geo = GeoFix::of(&frame, [report.x, report.y], report.cov);
    }
    Ok(LocateOutput::Snapshot(report))
}

impl Report for LocateOutput {
    fn table(&self) -> Table {
        match self {
            LocateOutput::Snapshot(r) => r.table(),
            LocateOutput::Fused(r) => r.table(),
        }
    }

    fn diagnostics(&self) -> Vec<Diagnostic> {
        match self {
            LocateOutput::Snapshot(r) => r.diagnostics(),
            LocateOutput::Fused(r) => r.diagnostics(),
        }
    }
}

/// The rows of a position estimate: x, y, their standard deviations and the covariance (m, m²).
pub(crate) fn position_rows(t: Table, x: f64, y: f64, cov: [[f64; 2]; 2]) -> Table {
    let sd = [cov[0][0].max(0.0).sqrt(), cov[1][1].max(0.0).sqrt()];
    t.row("x", format!("{} m", num(x)))
        .row("y", format!("{} m", num(y)))
        .row("std x, y", format!("{} m, {} m", num(sd[0]), num(sd[1])))
        .row("cov", format!("{} m²", matrix(cov)))
}

impl Report for LocateReport {
    fn table(&self) -> Table {
        let mut t = position_rows(Table::new(), self.x, self.y, self.cov);
        if let Some(g) = &self.geo {
            t = g.rows(t);
        }
        t = t.row("ambiguous", if self.ambiguous { "yes" } else { "no" });
        for (i, c) in self.candidates.iter().enumerate() {
            t = t.row(format!("candidate {}", i + 1), format!("{} m", pair(*c)));
        }
        t
    }

    fn diagnostics(&self) -> Vec<Diagnostic> {
        if self.ambiguous {
            vec![Diagnostic::Warning(format!(
                "{} positions fit these range differences; reporting the first, give --prior X,Y to choose",
                self.candidates.len()
            ))]
        } else {
            Vec::new()
        }
    }
}
