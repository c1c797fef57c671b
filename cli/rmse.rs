//! `uavloc rmse`: Monte Carlo RMSE of Chan's estimator against the CRLB at one geometry (eq. 79).

use clap::Args;
use nalgebra::Vector2;
use serde::Serialize;
use tdoa::Sensors;

use crate::args::{Point, SensorArgs, parse_count, parse_point};
use crate::error::CliError;
use crate::output::{Diagnostic, Report, Table, num};

/// Description shown by `uavloc rmse --help`.
pub const LONG_ABOUT: &str = "\
Monte Carlo RMSE of Chan's estimator over --draws seeded noisy measurements of an emitter at
--target, compared with the CRLB there (paper eq. 79).";

/// Help text shown after the options of `uavloc rmse --help`.
pub const AFTER_HELP: &str = "\
Each draw adds independent Gaussian noise N(0, s_i²) to every UAV's range (s_i from --sigma/--sigma-ns),
forms d_i = r_i − r_0 and runs Chan's estimator; rmse_m = sqrt(mean |estimate − target|²) over the
successful draws, crlb_m = sqrt(tr F⁻¹(target)), ratio = rmse_m / crlb_m (≈ 1 for an efficient
estimator). A draw fails when Chan finds no solution or, with 3 UAVs and no --prior, two.
The same --seed gives the same numbers.

Conventions: positions in metres; the first --uav is the reference UAV0.

Examples:
  uavloc rmse --uav 1500,500 --uav 10000,1500 --uav 5000,8500 --target 25000,15000 --sigma 28.7712 \\
      --draws 2000 --seed 3
  uavloc rmse --uav 1500,500 --uav 10000,1500 --uav 5000,8500 --target 25000,15000 --sigma-ns 96 \\
      --draws 500 --prior 24000,14000 --json

Exit codes: 0 when at least one draw succeeded (failures are reported and warned about); 1 when every
draw failed (rmse_m and ratio are null); 2 bad input, including a target where the CRLB is singular.";

/// Arguments of `uavloc rmse`.
#[derive(Args, Debug, Clone, PartialEq)]
pub struct RmseArgs {
    #[command(flatten)]
    pub sensors: SensorArgs,
    /// True emitter position X,Y in metres.
    #[arg(long, value_name = "X,Y", allow_hyphen_values = true, value_parser = parse_point, help_heading = "Geometry")]
    pub target: Point,
    /// Number of noisy measurements to draw (at least 1).
    #[arg(
        long,
        value_name = "R",
        allow_hyphen_values = true,
        value_parser = parse_count::<usize>,
        help_heading = "Monte Carlo"
    )]
    pub draws: usize,
    /// Seed of the noise.
    #[arg(
        long,
        value_name = "N",
        default_value_t = 1,
        allow_hyphen_values = true,
        value_parser = parse_count::<u64>,
        help_heading = "Monte Carlo"
    )]
    pub seed: u64,
    /// Rough emitter position X,Y in metres that resolves the 3-UAV two-solution ambiguity.
    #[arg(long, value_name = "X,Y", allow_hyphen_values = true, value_parser = parse_point, help_heading = "Monte Carlo")]
    pub prior: Option<Point>,
}

/// RMSE of Chan's estimator against the CRLB.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RmseReport {
    /// RMSE over the successful draws, metres; `None` (null) if every draw failed.
    pub rmse_m: Option<f64>,
    /// Single-point CRLB at the target, metres.
    pub crlb_m: f64,
    /// `rmse_m / crlb_m`; `None` if every draw failed.
    pub ratio: Option<f64>,
    /// Draws where Chan failed or stayed ambiguous.
    pub failures: usize,
    /// Draws attempted.
    pub draws: usize,
}

/// RMSE of Chan over `draws` seeded noisy measurements of an emitter at `target`.
pub fn compute(
    sensors: &Sensors,
    target: &Vector2<f64>,
    draws: usize,
    seed: u64,
    prior: Option<Vector2<f64>>,
) -> Result<RmseReport, CliError> {
    crate::args::require_count("--draws", draws, 1, tdoa::montecarlo::MAX_SAMPLES)?;
    let r = tdoa::montecarlo::rmse(sensors, target, draws, seed, prior)
        .map_err(CliError::tdoa_in(format!("--target {},{}", target.x, target.y)))?;
    let ok = r.failures < r.draws;
    Ok(RmseReport {
        rmse_m: ok.then_some(r.rmse_m),
        crlb_m: r.crlb_m,
        ratio: ok.then_some(r.ratio),
        failures: r.failures,
        draws: r.draws,
    })
}

/// Runs `uavloc rmse`.
pub fn run(args: &RmseArgs) -> Result<RmseReport, CliError> {
    let sensors = args.sensors.sensors()?;
    compute(&sensors, &args.target.vector(), args.draws, args.seed, args.prior.map(|p| p.vector()))
}

impl Report for RmseReport {
    fn table(&self) -> Table {
        let or_none = |v: Option<f64>, unit: &str| v.map_or("none (every draw failed)".to_string(), |v| num(v) + unit);
        Table::new()
            .row("RMSE", or_none(self.rmse_m, " m"))
            .row("CRLB", format!("{} m", num(self.crlb_m)))
            .row("RMSE / CRLB", or_none(self.ratio, ""))
            .row("failures", format!("{} of {} draws", self.failures, self.draws))
    }

    fn diagnostics(&self) -> Vec<Diagnostic> {
        let hint = "Chan found no solution or, with 3 UAVs and no --prior, two; try --prior X,Y";
        if self.rmse_m.is_none() {
            vec![Diagnostic::Failure(format!("all {} draws failed ({hint})", self.draws))]
        } else if self.failures > 0 {
            vec![Diagnostic::Warning(format!(
                "{} of {} draws failed and are left out of the RMSE ({hint})",
                self.failures, self.draws
            ))]
        } else {
            Vec::new()
        }
    }
}
