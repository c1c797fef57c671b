//! `uavloc crlb`: the single-point Cramér–Rao lower bound of the emitter position (paper eq. 49).

use clap::Args;
use nalgebra::Vector2;
use serde::Serialize;
use tdoa::Sensors;

use crate::args::{Point, SensorArgs, parse_point};
use crate::error::CliError;
use crate::output::{Report, Table, matrix, num, rows};

/// Description shown by `uavloc crlb --help`.
pub const LONG_ABOUT: &str = "\
Single-point Cramér–Rao lower bound (paper eq. 49) of an emitter at --target seen by the --uav
UAVs with range noise --sigma (m) or --sigma-ns (ns). Reports crlb_m = sqrt(tr F⁻¹) in metres, tr F⁻¹
in m², the condition number of F and the Fisher information matrix F in 1/m².";

/// Help text shown after the options of `uavloc crlb --help`.
pub const AFTER_HELP: &str = "\
Conventions: positions in metres; the first --uav is the reference UAV0; range differences are
d_i = r_i − r_0. The CRLB is sqrt(tr F⁻¹) in metres, F = Jᵀ Q⁻¹ J the Fisher information of the
N−1 range differences with Q_ii = s_i² + s_0², Q_ij = s_0².

Examples:
  # the paper's nominal geometry, range sigma 28.7712 m for every UAV (CRLB ≈ 1655.58 m)
  uavloc crlb --uav 1500,500 --uav 10000,1500 --uav 5000,8500 --target 25000,15000 --sigma 28.7712
  # the same noise as a time-of-arrival sigma of about 96 ns, JSON output
  uavloc crlb --uav 1500,500 --uav 10000,1500 --uav 5000,8500 --target 25000,15000 --sigma-ns 95.97 --json
  # GNSS (5 m per axis) and clock (10 ns) errors per step, and flight-long biases: the bound of the
  # effective range sigma, and the floor the biases leave however many snapshots are fused
  uavloc crlb --uav 1500,500 --uav 10000,1500 --uav 5000,8500 --target 25000,15000 --sigma 28.7712 --gnss-sigma 5 --clock-sigma-ns 10 --gnss-bias-sigma 5 --clock-bias-sigma-ns 10
  # per-UAV sigmas and negative coordinates
  uavloc crlb --uav -1500,200 --uav 0,0 --uav 800,-900 --target -3000,-4000 --sigma 10,20,15

Exit codes: 0 success; 2 bad input, including a singular point (the emitter on a UAV or on the
extension of a baseline, where the bound is infinite).";

/// Arguments of `uavloc crlb`.
#[derive(Args, Debug, Clone, PartialEq)]
pub struct CrlbArgs {
    #[command(flatten)]
    pub sensors: SensorArgs,
    /// Emitter position X,Y in metres.
    #[arg(long, value_name = "X,Y", allow_hyphen_values = true, value_parser = parse_point, help_heading = "Geometry")]
    pub target: Point,
}

/// The single-point CRLB at one emitter position.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CrlbReport {
    /// `sqrt(tr F⁻¹)`, metres.
    pub crlb_m: f64,
    /// `tr F⁻¹`, m².
    pub trace_m2: f64,
    /// 2-norm condition number of `F`.
    pub cond: f64,
    /// The Fisher information matrix `F`, 1/m², row-major.
    pub fim: [[f64; 2]; 2],
    /// With flight-long GNSS/clock biases (`--gnss-bias-sigma`, `--clock-bias-sigma-ns`): `sqrt(tr B)`,
    /// the error the biases alone cause, which no number of snapshots averages out, metres; else absent.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bias_floor_m: Option<f64>,
}

/// The CRLB of an emitter at `target` seen by `sensors`.
pub fn compute(sensors: &Sensors, target: &Vector2<f64>) -> Result<CrlbReport, CliError> {
    let c = tdoa::crlb(sensors, target).map_err(CliError::tdoa_in(format!("--target {},{}", target.x, target.y)))?;
    Ok(CrlbReport { crlb_m: c.crlb_m, trace_m2: c.trace_m2, cond: c.cond, fim: rows(&c.fim), bias_floor_m: None })
}

/// Runs `uavloc crlb`.
pub fn run(args: &CrlbArgs) -> Result<CrlbReport, CliError> {
    let target = args.target.vector();
    let mut report = compute(&args.sensors.sensors()?, &target)?;
    let b = args.sensors.bias_covariance(&target)?;
    if b != nalgebra::Matrix2::zeros() {
        report.bias_floor_m = Some(b.trace().sqrt());
    }
    Ok(report)
}

impl Report for CrlbReport {
    fn table(&self) -> Table {
        let t = Table::new()
            .row("CRLB", format!("{} m", num(self.crlb_m)))
            .row("trace F^-1", format!("{} m²", num(self.trace_m2)))
            .row("cond(F)", num(self.cond))
            .row("FIM F", format!("{} 1/m²", matrix(self.fim)));
        match self.bias_floor_m {
            Some(b) => t.row("bias floor (flight-long GNSS/clock)", format!("{} m", num(b))),
            None => t,
        }
    }
}
