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
candidate nearer to it is chosen. With 4 or more UAVs the solution is unique (two-step WLS).

Examples:
  # the paper's nominal geometry; these range differences come from an emitter at (25000, 15000)
  uavloc locate --uav 1500,500 --uav 10000,1500 --uav 5000,8500 --range-diff -7432.966,-6583.662 --sigma 28.7712
  # 4 UAVs, negative coordinates and range differences, JSON (emitter near (-4000, -3000))
  uavloc locate --uav -1500,200 --uav 0,0 --uav 800,-900 --uav 300,700 --range-diff 939.2,1178.5,1612 \\
      --sigma-ns 30 --json

Exit codes: 0 success; 2 bad input, collinear UAVs, or range differences no emitter can produce.";

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
        help_heading = "Measurements"
    )]
    pub range_diff: NumList,
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
    let sol = tdoa::chan(sensors, &diffs, prior)?;
    Ok(LocateReport {
        x: sol.position.x,
        y: sol.position.y,
        cov: rows(&sol.covariance),
        ambiguous: sol.ambiguous,
        candidates: sol.candidates.iter().map(|c| [c.x, c.y]).collect(),
    })
}

/// Runs `uavloc locate`.
pub fn run(args: &LocateArgs) -> Result<LocateReport, CliError> {
    compute(&args.sensors.sensors()?, &args.range_diff.0, args.prior.map(|p| p.vector()))
}

impl Report for LocateReport {
    fn table(&self) -> Table {
        let sd = [self.cov[0][0].max(0.0).sqrt(), self.cov[1][1].max(0.0).sqrt()];
        let mut t = Table::new()
            .row("x", format!("{} m", num(self.x)))
            .row("y", format!("{} m", num(self.y)))
            .row("std x, y", format!("{} m, {} m", num(sd[0]), num(sd[1])))
            .row("cov", format!("{} m²", matrix(self.cov)))
            .row("ambiguous", if self.ambiguous { "yes" } else { "no" });
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
