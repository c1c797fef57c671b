//! `uavloc global`: the global CRLB over the uncertainty of the target position (paper eqs. 51–52),
//! computed by one of five methods.

use clap::{Args, ValueEnum};
use nalgebra::{Matrix2, Vector2};
use serde::Serialize;
use tdoa::{Method, Sensors, Uncertainty};

use crate::args::{Point, SensorArgs, parse_count, parse_cov, parse_finite, parse_point, require_positive};
use crate::error::CliError;
use crate::output::{Diagnostic, Report, Table, num};

/// Description shown by `uavloc global --help`.
pub const LONG_ABOUT: &str = "\
Global CRLB (paper eqs. 51–52): the mean of tr F⁻¹ over the target's position uncertainty
N(--estimate, --cov) truncated to a square of side --side, computed by --method. Reports the value in
m² and its square root in metres, the support side, whether the support reaches the singular locus
of the FIM, and the number of tr F⁻¹ evaluations spent.";

/// Help text shown after the options of `uavloc global --help`.
pub const AFTER_HELP: &str = "\
The global CRLB is the Gaussian-weighted mean of tr F⁻¹(z) over a square support of side A centred
on the estimate (target ~ N(estimate, cov) truncated to the square); crlb_m is its square root.
Without --side, A follows eq. 36: A = min(10 σ_t, 6 σ_t + κ·r_avg), σ_t = sqrt(λ_max(cov)) and r_avg
the mean UAV–estimate distance.

Singular locus: for 3 UAVs the FIM is singular on the extensions of the baselines (and on the UAVs).
If the support reaches it, the exact global CRLB is infinite: the integrating methods (mc, quadrature,
cubature) then report trace_m2 = crlb_m = null in JSON, 'infinite' in the table, a warning on stderr,
and exit code 0. single and analytical only look at the estimate and stay finite.

Conventions: positions in metres, covariance in m²; the first --uav is the reference UAV0.

Examples:
  uavloc global --uav 1500,500 --uav 10000,1500 --uav 5000,8500 --sigma 28.7712 \\
      --estimate 25000,15000 --cov 250000,100000,160000 --method quadrature
  uavloc global --uav 1500,500 --uav 10000,1500 --uav 5000,8500 --sigma-ns 96 \\
      --estimate 25000,15000 --cov 250000,0,250000 --side 5000 --method mc --samples 1000 --seed 7 --json";

/// The method names accepted by `--method`.
#[derive(ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum MethodArg {
    /// tr F⁻¹ at the estimate only (the paper's baseline criterion)
    Single,
    /// Monte Carlo: --samples uniform points in the square, Gaussian weights (eq. 60), seeded by --seed
    Mc,
    /// Second-order Taylor surrogate tr F⁻¹ + ½ tr(M H) at the estimate (eq. 74)
    Analytical,
    /// Adaptive tensor Gauss–Legendre over the square: the reference value
    Quadrature,
    /// 5×5 Gauss–Hermite cubature in the eigenbasis of the covariance, truncated to the square
    Cubature,
}

impl From<MethodArg> for Method {
    fn from(m: MethodArg) -> Self {
        match m {
            MethodArg::Single => Method::Single,
            MethodArg::Mc => Method::Mc,
            MethodArg::Analytical => Method::Analytical,
            MethodArg::Quadrature => Method::Quadrature,
            MethodArg::Cubature => Method::Cubature,
        }
    }
}

/// Arguments of `uavloc global`.
#[derive(Args, Debug, Clone, PartialEq)]
pub struct GlobalArgs {
    #[command(flatten)]
    pub sensors: SensorArgs,
    /// Estimated emitter position X,Y in metres (centre of the uncertainty).
    #[arg(long, value_name = "X,Y", allow_hyphen_values = true, value_parser = parse_point, help_heading = "Uncertainty")]
    pub estimate: Point,
    /// Covariance of the estimate in m², given as VXX,VXY,VYY; must be positive definite.
    #[arg(
        long,
        value_name = "VXX,VXY,VYY",
        allow_hyphen_values = true,
        value_parser = parse_cov,
        help_heading = "Uncertainty"
    )]
    pub cov: Matrix2<f64>,
    /// Side of the square support in metres [default: eq. 36, see below].
    #[arg(long, value_name = "A", allow_hyphen_values = true, value_parser = parse_finite, help_heading = "Uncertainty")]
    pub side: Option<f64>,
    /// κ of eq. 36 (metres of support per metre of mean UAV–estimate distance); ignored with --side.
    #[arg(
        long,
        value_name = "K",
        default_value_t = tdoa::DEFAULT_KAPPA,
        allow_hyphen_values = true,
        value_parser = parse_finite,
        help_heading = "Uncertainty"
    )]
    pub kappa: f64,
    /// How to compute the global CRLB.
    #[arg(long, value_enum, value_name = "METHOD", help_heading = "Method")]
    pub method: MethodArg,
    /// Number of Monte Carlo samples (mc only), at least 2.
    #[arg(
        long,
        value_name = "K",
        default_value_t = 200,
        allow_hyphen_values = true,
        value_parser = parse_count::<usize>,
        help_heading = "Method"
    )]
    pub samples: usize,
    /// Seed of the Monte Carlo samples (mc only); the same seed gives the same value.
    #[arg(
        long,
        value_name = "N",
        default_value_t = 1,
        allow_hyphen_values = true,
        value_parser = parse_count::<u64>,
        help_heading = "Method"
    )]
    pub seed: u64,
}

/// One global-CRLB evaluation with its singular-locus diagnosis.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GlobalReport {
    /// The method used.
    pub method: Method,
    /// The global `tr Cr_Φ`, m²; `None` (JSON null) when infinite.
    pub trace_m2: Option<f64>,
    /// `sqrt(trace_m2)`, metres; `None` when infinite.
    pub crlb_m: Option<f64>,
    /// Side `A` of the square support, metres.
    pub side_m: f64,
    /// The support reaches the singular locus of the FIM (the exact global CRLB is infinite).
    pub singular_locus: bool,
    /// Distance from the estimate to the singular locus, metres; `None` if there is no singular set.
    pub singular_distance_m: Option<f64>,
    /// Monte Carlo standard error of `trace_m2`, m² (key present for `mc` only; null when infinite).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stderr_trace_m2: Option<Option<f64>>,
    /// Number of `tr F⁻¹` evaluations spent.
    pub evaluations: usize,
    /// Kish's effective sample size of the `mc` weights (key present for `mc` only): its standard error
    /// means little when this is a handful.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub effective_samples: Option<f64>,
    /// Estimated error of a quadrature that stopped before converging, m² (diagnostic, not in JSON).
    #[serde(skip)]
    pub unconverged_m2: Option<f64>,
}

fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

/// The global CRLB of `unc` seen by `sensors` with `method` (`samples`, `seed`: mc only).
pub fn compute(
    sensors: &Sensors,
    unc: &Uncertainty,
    method: Method,
    samples: usize,
    seed: u64,
) -> Result<GlobalReport, CliError> {
    if samples < 2 {
        return Err(CliError::Input(format!("--samples must be at least 2 (got {samples})")));
    }
    let built = method.build(samples, seed).map_err(CliError::tdoa_in("--samples"))?;
    let r = tdoa::global_crlb(built.as_ref(), sensors, unc);
    let trace_m2 = finite(r.value.trace_m2);
    let stderr = r.value.stderr_m2.and_then(finite);
    Ok(GlobalReport {
        method,
        trace_m2,
        crlb_m: trace_m2.map(f64::sqrt),
        side_m: unc.side(),
        singular_locus: r.singular.intersects_support,
        singular_distance_m: finite(r.singular.distance_m),
        stderr_trace_m2: (method == Method::Mc).then_some(trace_m2.and(stderr)),
        evaluations: r.value.evaluations,
        effective_samples: r.value.effective_samples,
        unconverged_m2: if method == Method::Quadrature { trace_m2.and(stderr) } else { None },
    })
}

/// The uncertainty described by the arguments (eq. 36 side unless `--side`).
pub fn uncertainty(args: &GlobalArgs, sensors: &Sensors) -> Result<Uncertainty, CliError> {
    let estimate: Vector2<f64> = args.estimate.vector();
    let unc = match args.side {
        Some(side) => {
            require_positive("--side", side, "m ")?;
            Uncertainty::new(estimate, args.cov, side)
        }
        None => {
            if args.kappa < 0.0 {
                return Err(CliError::Input(format!("--kappa must be >= 0 (got {})", args.kappa)));
            }
            Uncertainty::with_eq36_side(estimate, args.cov, sensors.mean_range(&estimate), args.kappa)
        }
    };
    unc.map_err(CliError::tdoa_in("--cov"))
}

/// Runs `uavloc global`.
pub fn run(args: &GlobalArgs) -> Result<GlobalReport, CliError> {
    let sensors = args.sensors.sensors()?;
    let unc = uncertainty(args, &sensors)?;
    compute(&sensors, &unc, args.method.into(), args.samples, args.seed)
}

impl GlobalReport {
    fn infinite_reason(&self) -> String {
        match (self.singular_locus, self.singular_distance_m) {
            (true, Some(d)) => format!("support reaches the singular locus at distance {} m", num(d)),
            (true, None) => "support reaches the singular locus".into(),
            (false, _) => "the FIM is singular at an evaluation point".into(),
        }
    }
}

impl Report for GlobalReport {
    fn table(&self) -> Table {
        let mut t = Table::new().row("method", self.method.name());
        t = match (self.crlb_m, self.trace_m2) {
            (Some(c), Some(tr)) => {
                let t = t.row("global CRLB", format!("{} m", num(c))).row("trace", format!("{} m²", num(tr)));
                match self.stderr_trace_m2 {
                    Some(Some(se)) => t.row("trace stderr", format!("{} m²", num(se))),
                    _ => t,
                }
            }
            _ => t.row("global CRLB", format!("infinite ({})", self.infinite_reason())).row("trace", "infinite"),
        };
        let locus = match (self.singular_locus, self.singular_distance_m) {
            (_, None) => "none (the FIM is regular everywhere off the UAVs)".to_string(),
            (true, Some(d)) => format!("inside the support, {} m from the estimate", num(d)),
            (false, Some(d)) => format!("outside the support, {} m from the estimate", num(d)),
        };
        t.row("support side", format!("{} m", num(self.side_m)))
            .row("singular locus", locus)
            .row("evaluations", self.evaluations.to_string())
            .row_opt("effective samples", self.effective_samples.map(num))
    }

    fn diagnostics(&self) -> Vec<Diagnostic> {
        let mut out = Vec::new();
        if self.trace_m2.is_none() {
            out.push(Diagnostic::Warning(format!(
                "the global CRLB is infinite for method {}: {}",
                self.method.name(),
                self.infinite_reason()
            )));
        } else if self.singular_locus {
            out.push(Diagnostic::Warning(format!(
                "the support reaches the singular locus{}: the exact global CRLB is infinite; method {} only looks \
                 at the estimate and does not see it",
                self.singular_distance_m.map(|d| format!(" at distance {} m", num(d))).unwrap_or_default(),
                self.method.name()
            )));
        }
        if let Some(e) = self.unconverged_m2 {
            out.push(Diagnostic::Warning(format!(
                "quadrature stopped before converging; estimated error of trace {} m²",
                num(e)
            )));
        }
        out
    }
}
