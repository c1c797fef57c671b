//! Parsing shared by the subcommands: coordinate pairs, number lists, the UAV list with its noise
//! (`--uav`, `--sigma`, `--sigma-ns`) and the conversion to [`tdoa::Sensors`].
//!
//! All numeric flags accept values that start with a hyphen (`--uav -1500,200`, `--sigma -1` reaches our
//! own check and gets a clear message instead of clap's "unexpected argument").

use clap::Args;
use nalgebra::{Matrix2, Vector2};
use tdoa::{MAX_UAVS, NoiseModel, Sensors};

use crate::error::CliError;

/// Smallest number of UAVs a TDOA fix needs.
pub const MIN_UAVS: usize = 3;

/// A position `X,Y` in metres, parsed from the command line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point(pub [f64; 2]);

impl Point {
    /// As a nalgebra vector.
    pub fn vector(&self) -> Vector2<f64> {
        Vector2::new(self.0[0], self.0[1])
    }
}

/// A comma-separated list of finite numbers, parsed from the command line.
#[derive(Debug, Clone, PartialEq)]
pub struct NumList(pub Vec<f64>);

/// Parses one finite number; `what` describes it in the error.
fn parse_number(text: &str, what: &str) -> Result<f64, String> {
    let t = text.trim();
    if t.is_empty() {
        return Err(format!("{what} is empty"));
    }
    let v: f64 = t.parse().map_err(|_| format!("{what} '{t}' is not a number"))?;
    if v.is_finite() { Ok(v) } else { Err(format!("{what} '{t}' is not a finite number")) }
}

/// Splits `text` at commas into exactly `n` finite numbers (or any positive count if `n` is `None`).
fn parse_numbers(text: &str, n: Option<usize>, shape: &str) -> Result<Vec<f64>, String> {
    if text.trim().is_empty() {
        return Err(format!("empty value, expected {shape}"));
    }
    let parts: Vec<&str> = text.split(',').collect();
    if let Some(n) = n
        && parts.len() != n
    {
        return Err(format!("expected {shape} ({n} comma-separated numbers), got {} value(s)", parts.len()));
    }
    parts.iter().enumerate().map(|(i, p)| parse_number(p, &format!("value {}", i + 1))).collect()
}

/// clap value parser for `X,Y`.
pub fn parse_point(text: &str) -> Result<Point, String> {
    let v = parse_numbers(text, Some(2), "X,Y")?;
    if let Some(x) = v.iter().find(|x| x.abs() > tdoa::MAX_EXTENT_M) {
        return Err(format!(
            "{x:e} m is beyond the plane model's extent (coordinates within ±{:e} m)",
            tdoa::MAX_EXTENT_M
        ));
    }
    Ok(Point([v[0], v[1]]))
}

/// clap value parser for `V0,V1,..` (one or more numbers).
pub fn parse_list(text: &str) -> Result<NumList, String> {
    parse_numbers(text, None, "a number or a comma-separated list").map(NumList)
}

/// clap value parser for one finite number.
pub fn parse_finite(text: &str) -> Result<f64, String> {
    parse_number(text, "value")
}

/// clap value parser for a whole number ≥ 0 (counts and seeds).
pub fn parse_count<T: std::str::FromStr>(text: &str) -> Result<T, String> {
    text.trim().parse().map_err(|_| format!("'{}' is not a whole number >= 0", text.trim()))
}

/// clap value parser for the 2×2 covariance `VXX,VXY,VYY` (m²). Positive definiteness is checked later
/// by the maths core, which names the matrix.
pub fn parse_cov(text: &str) -> Result<Matrix2<f64>, String> {
    let v = parse_numbers(text, Some(3), "VXX,VXY,VYY")?;
    Ok(Matrix2::new(v[0], v[1], v[1], v[2]))
}

/// A count flag within `min..=max` (the upper bounds: what can be held in memory or computed, the
/// scenario's `model::scenario::MAX_STEPS` and `MAX_COUNT`); checked before any work starts.
pub fn require_count(flag: &str, value: usize, min: usize, max: usize) -> Result<usize, CliError> {
    if (min..=max).contains(&value) {
        Ok(value)
    } else {
        Err(CliError::Input(format!("{flag} must be in {min}..={max}, got {value}")))
    }
}

/// `value > 0`, else an input error naming `flag`.
pub fn require_positive(flag: &str, value: f64, unit: &str) -> Result<f64, CliError> {
    if value > 0.0 { Ok(value) } else { Err(CliError::Input(format!("{flag} must be > 0 {unit}(got {value})"))) }
}

/// The UAV positions (`--uav`, repeated).
#[derive(Args, Debug, Clone, PartialEq)]
pub struct UavArgs {
    /// UAV position X,Y in metres; repeat 3 to 8 times. The first --uav is the reference UAV0.
    ///
    /// Negative coordinates are fine: `--uav -1500,200` or `--uav=-1500,200`.
    #[arg(
        long = "uav",
        value_name = "X,Y",
        required_unless_present = "uav_lat_lon",
        allow_hyphen_values = true,
        value_parser = parse_point,
        help_heading = "Geometry"
    )]
    pub uavs: Vec<Point>,
    /// UAV position as WGS84 LAT,LON in degrees, instead of --uav (needs --origin); repeat 3 to 8 times.
    #[arg(
        long = "uav-lat-lon",
        value_name = "LAT,LON",
        conflicts_with = "uavs",
        requires = "origin",
        allow_hyphen_values = true,
        value_parser = parse_lat_lon,
        help_heading = "Geometry"
    )]
    pub uav_lat_lon: Vec<model::geo::LatLon>,
    /// The origin of the local plane, `LAT,LON[,ALT]` (degrees, metres above the WGS84 ellipsoid): x is
    /// metres east of it, y metres north. With it, results also give positions as latitude/longitude.
    #[arg(long, value_name = "LAT,LON[,ALT]", allow_hyphen_values = true, value_parser = parse_origin, help_heading = "Geometry")]
    pub origin: Option<model::geo::Origin>,
}

impl UavArgs {
    /// The positions in the plane (metres), after checking the count (3..=8).
    pub fn positions(&self) -> Result<Vec<[f64; 2]>, CliError> {
        let (n, flag) = if self.uav_lat_lon.is_empty() {
            (self.uavs.len(), "--uav X,Y")
        } else {
            (self.uav_lat_lon.len(), "--uav-lat-lon LAT,LON")
        };
        if !(MIN_UAVS..=MAX_UAVS).contains(&n) {
            return Err(CliError::Input(format!(
                "{} given {n} time(s); need between {MIN_UAVS} and {MAX_UAVS} UAVs (repeat {flag} once per UAV)",
                flag.split(' ').next().unwrap_or(flag)
            )));
        }
        if self.uav_lat_lon.is_empty() {
            return Ok(self.uavs.iter().map(|p| p.0).collect());
        }
        let frame = self.frame()?.ok_or_else(|| CliError::Input("--uav-lat-lon needs --origin".into()))?;
        self.uav_lat_lon
            .iter()
            .enumerate()
            .map(|(i, p)| {
                frame.to_local(*p).map_err(|e| CliError::input_because(format!("--uav-lat-lon (UAV {i})"), e))
            })
            .collect()
    }

    /// The local plane of `--origin`, if given.
    pub fn frame(&self) -> Result<Option<model::geo::LocalFrame>, CliError> {
        self.origin
            .map(|o| model::geo::LocalFrame::new(o).map_err(|e| CliError::input_because("--origin", e)))
            .transpose()
    }
}

/// clap value parser for `LAT,LON` in degrees.
pub fn parse_lat_lon(text: &str) -> Result<model::geo::LatLon, String> {
    let v = parse_numbers(text, Some(2), "LAT,LON")?;
    model::geo::LatLon::new(v[0], v[1]).map_err(|e| e.to_string())
}

/// clap value parser for `LAT,LON[,ALT]` (degrees, metres; the altitude 0 when not given).
pub fn parse_origin(text: &str) -> Result<model::geo::Origin, String> {
    let v = parse_numbers(text, None, "LAT,LON[,ALT]")?;
    if !(2..=3).contains(&v.len()) {
        return Err(format!("expected LAT,LON or LAT,LON,ALT, got {} value(s)", v.len()));
    }
    let origin = model::geo::Origin { lat_deg: v[0], lon_deg: v[1], alt_m: v.get(2).copied().unwrap_or(0.0) };
    model::geo::LocalFrame::new(origin).map_err(|e| e.to_string())?;
    Ok(origin)
}

/// The measurement noise: exactly one of `--sigma` (metres) or `--sigma-ns` (nanoseconds).
#[derive(Args, Debug, Clone, PartialEq)]
#[group(required = true, multiple = false)]
pub struct SigmaArgs {
    /// Range standard deviation in metres: one value for all UAVs, or one per UAV (S0 is UAV0).
    ///
    /// A list must have exactly as many values as there are --uav, in the same order. Every value must be > 0.
    #[arg(long, value_name = "S|S0,S1,..", allow_hyphen_values = true, value_parser = parse_list, help_heading = "Noise")]
    pub sigma: Option<NumList>,
    /// Time-of-arrival standard deviation in ns: one value for all UAVs, or one per UAV.
    ///
    /// Converted to a range standard deviation with c = 299792458 m/s (1 ns ≈ 0.2998 m). A list must have
    /// exactly as many values as there are --uav, in the same order. Every value must be > 0.
    #[arg(
        long = "sigma-ns",
        value_name = "T|T0,T1,..",
        allow_hyphen_values = true,
        value_parser = parse_list,
        help_heading = "Noise"
    )]
    pub sigma_ns: Option<NumList>,
}

impl SigmaArgs {
    /// The noise model for `n` UAVs.
    pub fn noise(&self, n: usize) -> Result<NoiseModel, CliError> {
        let (flag, list, unit, time) = match (&self.sigma, &self.sigma_ns) {
            (Some(s), None) => ("--sigma", s, "m", false),
            (None, Some(t)) => ("--sigma-ns", t, "ns", true),
            _ => {
                return Err(CliError::Input("give exactly one of --sigma (metres) or --sigma-ns (nanoseconds)".into()));
            }
        };
        let values = per_uav(flag, list, n)?;
        for (i, &v) in values.iter().enumerate() {
            if v <= 0.0 {
                let which = if list.0.len() == 1 { String::new() } else { format!(" (UAV {i})") };
                return Err(CliError::Input(format!("{flag} must be > 0 {unit}{which}, got {v}")));
            }
        }
        let model =
            if time { NoiseModel::from_time_sigmas_ns(&values) } else { NoiseModel::from_range_sigmas(&values) };
        model.map_err(CliError::tdoa_in(flag))
    }
}

/// `list` for `n` UAVs: one value for all, or exactly one per UAV.
fn per_uav(flag: &str, list: &NumList, n: usize) -> Result<Vec<f64>, CliError> {
    match list.0.len() {
        1 => Ok(vec![list.0[0]; n]),
        k if k == n => Ok(list.0.clone()),
        k => Err(CliError::Input(format!(
            "{flag} has {k} values but there are {n} UAVs (give one value for all UAVs, or exactly one per UAV)"
        ))),
    }
}

/// The UAVs' GNSS and clock errors beyond the range noise (docs/receiver.md): each one value for all
/// UAVs or one per UAV, ≥ 0, default 0.
#[derive(Args, Debug, Clone, PartialEq, Default)]
pub struct SensorErrorArgs {
    /// GNSS position error per axis that changes every step, metres (one value or one per UAV).
    ///
    /// Adds its variance to every arrival's: the bound and the estimate use the effective range σ
    /// sqrt(σ² + σ_gnss² + (c·σ_clock)² + the biases' variances) (exact to first order: the GNSS error is
    /// isotropic, so its projection on any line of sight has variance σ_gnss²).
    #[arg(long = "gnss-sigma", value_name = "M|M0,M1,..", value_parser = parse_list, help_heading = "Sensor errors")]
    pub gnss: Option<NumList>,
    /// GNSS position bias per axis that lasts the whole flight, metres (one value or one per UAV).
    ///
    /// Counted in the effective σ as above and, for `crlb`, reported as the floor no number of snapshots
    /// averages out: bias_floor_m = sqrt(tr B), B = (Hᵀ Q_b⁻¹ H)⁻¹ of the biases alone.
    #[arg(long = "gnss-bias-sigma", value_name = "M|M0,M1,..", value_parser = parse_list, help_heading = "Sensor errors")]
    pub gnss_bias: Option<NumList>,
    /// Clock error that changes every step, nanoseconds (one value or one per UAV).
    #[arg(long = "clock-sigma-ns", value_name = "T|T0,T1,..", allow_hyphen_values = true, value_parser = parse_list, help_heading = "Sensor errors")]
    pub clock_ns: Option<NumList>,
    /// Clock bias that lasts the whole flight, nanoseconds (one value or one per UAV).
    #[arg(long = "clock-bias-sigma-ns", value_name = "T|T0,T1,..", value_parser = parse_list, help_heading = "Sensor errors")]
    pub clock_bias_ns: Option<NumList>,
}

impl SensorErrorArgs {
    /// The errors of `n` UAVs (all zero when no flag is given).
    pub fn errors(&self, n: usize) -> Result<Vec<tdoa::SensorErrors>, CliError> {
        const C_M_PER_NS: f64 = tdoa::SPEED_OF_LIGHT * 1e-9;
        let get = |flag: &str, list: &Option<NumList>, scale: f64| -> Result<Vec<f64>, CliError> {
            let Some(list) = list else { return Ok(vec![0.0; n]) };
            let v = per_uav(flag, list, n)?;
            if let Some((i, x)) = v.iter().enumerate().find(|(_, x)| !(x.is_finite() && **x >= 0.0)) {
                return Err(CliError::Input(format!("{flag} must be finite and ≥ 0 (UAV {i}), got {x}")));
            }
            Ok(v.into_iter().map(|x| x * scale).collect())
        };
        let g = get("--gnss-sigma", &self.gnss, 1.0)?;
        let gb = get("--gnss-bias-sigma", &self.gnss_bias, 1.0)?;
        let c = get("--clock-sigma-ns", &self.clock_ns, C_M_PER_NS)?;
        let cb = get("--clock-bias-sigma-ns", &self.clock_bias_ns, C_M_PER_NS)?;
        Ok((0..n)
            .map(|i| tdoa::SensorErrors { gnss_m: g[i], gnss_bias_m: gb[i], clock_m: c[i], clock_bias_m: cb[i] })
            .collect())
    }
}

/// UAVs and their noise: everything needed to build [`tdoa::Sensors`].
#[derive(Args, Debug, Clone, PartialEq)]
pub struct SensorArgs {
    #[command(flatten)]
    pub uav: UavArgs,
    #[command(flatten)]
    pub sigma: SigmaArgs,
    #[command(flatten)]
    pub errors: SensorErrorArgs,
}

impl SensorArgs {
    /// Validated sensors (count, σ, distinct positions), with the effective range σ of the GNSS and
    /// clock errors when any is given.
    pub fn sensors(&self) -> Result<Sensors, CliError> {
        let positions = self.uav.positions()?;
        let noise = self.sigma.noise(positions.len())?;
        let errors = self.errors.errors(positions.len())?;
        let noise = if errors.iter().all(|e| *e == tdoa::SensorErrors::default()) {
            noise
        } else {
            let sigmas: Vec<f64> = noise.sigmas().iter().zip(&errors).map(|(s, e)| e.effective_sigma(*s)).collect();
            tdoa::NoiseModel::from_range_sigmas(&sigmas).map_err(CliError::tdoa_in("--sigma"))?
        };
        Sensors::new(&positions, noise).map_err(CliError::tdoa_in("--uav"))
    }

    /// The persistent biases' covariance of one snapshot's estimate at `target`, m²: zero without biases
    /// (`tdoa::arrivals::bias_covariance`).
    pub fn bias_covariance(&self, target: &nalgebra::Vector2<f64>) -> Result<nalgebra::Matrix2<f64>, CliError> {
        let positions: Vec<nalgebra::Vector2<f64>> =
            self.uav.positions()?.iter().map(|p| nalgebra::Vector2::new(p[0], p[1])).collect();
        let errors = self.errors.errors(positions.len())?;
        let sig: Vec<f64> = errors.iter().map(|e| e.bias_variance().sqrt()).collect();
        tdoa::arrivals::bias_covariance(&positions, &sig, target).ok_or_else(|| {
            CliError::Input(format!("no bias bound at --target {},{}: a singular geometry", target.x, target.y))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_and_lists() {
        assert_eq!(parse_point("-1500,200.5").unwrap(), Point([-1500.0, 200.5]));
        assert_eq!(parse_point(" 1 , 2 ").unwrap(), Point([1.0, 2.0]));
        for bad in ["1,2,3", "1", "a,b", "", "nan,0", "0,inf", "1,", ",1", "1e400,0"] {
            assert!(parse_point(bad).is_err(), "{bad} should be rejected");
        }
        assert_eq!(parse_list("1").unwrap(), NumList(vec![1.0]));
        assert_eq!(parse_list("-1,2.5,3e2").unwrap(), NumList(vec![-1.0, 2.5, 300.0]));
        assert!(parse_list("1,,2").is_err());
        assert!(parse_cov("1,0").is_err());
        assert_eq!(parse_count::<usize>(" 12 "), Ok(12));
        assert!(parse_count::<usize>("-1").is_err());
        assert!(parse_count::<u64>("1.5").is_err());
        assert_eq!(parse_cov("4,1,9").unwrap(), Matrix2::new(4.0, 1.0, 1.0, 9.0));
    }

    #[test]
    fn sigma_expansion_and_errors() {
        let s = SigmaArgs { sigma: Some(NumList(vec![2.0])), sigma_ns: None };
        assert_eq!(s.noise(4).unwrap().sigmas(), &[2.0; 4]);
        let s = SigmaArgs { sigma: Some(NumList(vec![1.0, 2.0])), sigma_ns: None };
        assert!(matches!(s.noise(3), Err(CliError::Input(m)) if m.contains("--sigma")));
        let s = SigmaArgs { sigma: None, sigma_ns: Some(NumList(vec![0.0])) };
        assert!(matches!(s.noise(3), Err(CliError::Input(m)) if m.contains("--sigma-ns")));
        let s = SigmaArgs { sigma: None, sigma_ns: Some(NumList(vec![10.0])) };
        let m = s.noise(3).unwrap();
        assert!((m.sigmas()[0] - 10.0 * tdoa::SPEED_OF_LIGHT / 1e9).abs() < 1e-12);
    }
}

/// The run both `simulate` and `launch` make: scenario, objective, solver, steps, seed, estimator.
#[derive(clap::Args, Debug, Clone, PartialEq)]
pub struct RunChoice {
    /// Scenario TOML file (default: the paper's nominal case; see scenarios/nominal.toml).
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<std::path::PathBuf>,
    /// Planning objective: single | mc | analytical | cubature | posterior | posterior-cubature |
    /// formation (the fixed-formation baseline).
    #[arg(long, default_value = "analytical")]
    pub objective: planning::ObjectiveKind,
    /// Solver: gradient (ours: each UAV's own constraints settled exactly, then projected quasi-Newton
    /// on the criterion; deterministic) | pso | ga | aco (the paper's). Ignored by the formation baseline.
    #[arg(long, default_value = "gradient")]
    pub solver: planning::SolverKind,
    /// Number of planning steps (default: the scenario's, 24 for the paper).
    #[arg(long, value_name = "N")]
    pub steps: Option<usize>,
    /// Run seed: measurement noise, RMSE resamples, MC samples and the solver all derive from it
    /// (default: the scenario's seed).
    #[arg(long, value_name = "N")]
    pub seed: Option<u64>,
    /// The estimator: fused (the posterior of every measurement so far) or snapshot (the paper's Chan
    /// per step); default: the scenario's `estimator` (fused).
    #[arg(long, value_name = "KIND")]
    pub estimator: Option<estimation::EstimatorKind>,
}

impl RunChoice {
    /// The scenario of these flags (file or default) with `--steps`, `--seed` and `--estimator` applied,
    /// validated.
    pub fn scenario(&self) -> Result<model::Scenario, crate::error::CliError> {
        let mut sc = crate::simulate::scenario_from(self.scenario.as_ref(), self.steps, self.seed)?;
        if let Some(kind) = self.estimator {
            sc.estimator = kind;
        }
        Ok(sc)
    }
}
