//! The scenario of a run, loaded from TOML: geometry, motion, noise, constraints, planner and solver
//! settings. [`Scenario::default()`] is the paper's nominal three-UAV case (Section 5.1, Table 1).
//!
//! # Conventions
//!
//! - Lengths in metres, times in seconds, speeds in m/s.
//! - **Angles**: in TOML every angle is in *degrees* and its key ends in `_deg` (`delta_alpha_deg`,
//!   `headings_deg`); in Rust every angle is in *radians* (the fields `delta_alpha`, `headings`).
//! - Every key is optional: a missing key takes its nominal value, a missing `headings_deg` means
//!   "each UAV heads straight at the emitter". Unknown keys are errors.
//! - Values the paper does not state are marked "our choice" in their doc comment.
//!
//! [`Scenario::from_toml_str`] and [`Scenario::from_file`] parse and then [`Scenario::validate`]; every
//! error names the offending key.

use std::path::{Path, PathBuf};

use nalgebra::{Matrix2, Vector2};
use tdoa::arrivals::OutlierPolicy;
use tdoa::fusion::EstimatorKind;
use tdoa::geometry::COINCIDENCE_TOLERANCE_M;
use tdoa::global::McScheme;
use tdoa::{DEFAULT_KAPPA, Dynamics, EmitterModel, MAX_EXTENT_M, MAX_UAVS, NoiseModel};
use thiserror::Error;

use crate::geo::{LatLon, LocalFrame, Origin};
use crate::kinematics::bearing;
use crate::receiver::ReceiverModel;
use crate::safety::SafetyMode;
use crate::solver_config::{AcoConfig, EarlyStop, GaConfig, GradientConfig, PsoConfig};

/// Smallest covariance (m², times the identity) handed to the planner in controlled mode: at scale
/// s = 0 the covariance `s² σ_t² I` would be zero, which no [`tdoa::Uncertainty`] accepts. (1 cm)² makes
/// every criterion equal to `single` to within ~1e-8 relative.
pub const MIN_CONTROLLED_VARIANCE_M2: f64 = 1e-4;

/// Why a scenario was refused. Every variant names the key.
#[derive(Debug, Error)]
pub enum ScenarioError {
    /// The file could not be read.
    #[error("cannot read scenario file {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// TOML syntax, an unknown key or a value of the wrong type.
    #[error("scenario{}: {message}", match (key, line) {
        (Some(k), Some(l)) => format!(" key `{k}` (line {l})"),
        (Some(k), None) => format!(" key `{k}`"),
        (None, Some(l)) => format!(" (line {l})"),
        (None, None) => String::new(),
    })]
    Parse {
        /// The key the error is about, when it can be located (`table.key` inside a table).
        key: Option<String>,
        /// 1-based line of the error, when known.
        line: Option<usize>,
        /// What is wrong.
        message: String,
    },
    /// A value outside its allowed range.
    #[error("scenario key `{key}`: {reason}")]
    Invalid {
        /// The key, e.g. `speed`, `uavs`, `pso.particles`.
        key: String,
        /// What is wrong.
        reason: String,
    },
}

impl ScenarioError {
    /// The key the error is about, if any.
    pub fn key(&self) -> Option<&str> {
        match self {
            ScenarioError::Io { .. } => None,
            ScenarioError::Parse { key, .. } => key.as_deref(),
            ScenarioError::Invalid { key, .. } => Some(key),
        }
    }
}

fn invalid(key: &str, reason: impl Into<String>) -> ScenarioError {
    ScenarioError::Invalid { key: key.to_string(), reason: reason.into() }
}

/// Range standard deviation: one value for every UAV or one per UAV (metres).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(untagged, expecting = "a range sigma in metres: one number, or a list with one number per UAV")]
pub enum RangeSigma {
    /// The same σ for every UAV.
    Uniform(f64),
    /// σ of each UAV, index 0 being the reference.
    PerUav(Vec<f64>),
}

/// Where the planner's target (ẑ, M) comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TargetMode {
    /// The live Chan estimate of each step and its covariance (paper Sections 5.1–5.5).
    #[default]
    Chan,
    /// A controlled planner-side error (paper Section 5.6): ẑ = z* + s·e0, M = s²·σ_t²·I.
    Controlled,
}

/// The planner's belief about the target: ẑ (m) and its covariance M (m²).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlannerTarget {
    /// ẑ, metres.
    pub estimate: Vector2<f64>,
    /// M, m².
    pub covariance: Matrix2<f64>,
}

/// A run's scenario. `Default` is the paper's Table 1 nominal case; see the module docs for units.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Scenario {
    /// UAV positions at step 0, metres; index 0 is the reference UAV. 3 to 8 UAVs.
    /// Paper: [1500, 500], [10000, 1500], [5000, 8500].
    pub uavs: Vec<[f64; 2]>,
    /// Initial headings, radians (TOML: `headings_deg`, degrees). `None`: each UAV heads at the
    /// emitter ([`Scenario::initial_headings`]) — our reading of "the UAVs moving toward the target".
    #[serde(rename = "headings_deg", with = "opt_degrees", skip_serializing_if = "Option::is_none")]
    pub headings: Option<Vec<f64>>,
    /// True emitter position, metres. Paper: [25000, 15000].
    pub emitter: [f64; 2],
    /// UAV speed v, m/s. Paper: 50.
    pub speed: f64,
    /// Planning interval Δt, s. Paper: 10 (so L = v·Δt = 500 m per step).
    pub dt: f64,
    /// Range noise σ per UAV, metres (a scalar or a per-UAV list) — our choice 28.7712 m, the project's
    /// nominal value (the paper states no range σ in metres).
    pub sigma: RangeSigma,
    /// Planning steps of a run — our choice 24 (the project's nominal run length).
    pub steps: usize,
    /// Half-width Δα of the heading cone around the bearing to ẑ (eq. 58), radians
    /// (TOML: `delta_alpha_deg`, degrees) — our choice 25°.
    #[serde(rename = "delta_alpha_deg", with = "degrees")]
    pub delta_alpha: f64,
    /// Minimum approach distance L_min to ẑ (eq. 57), metres — our choice 3000.
    pub l_min: f64,
    /// Minimum UAV spacing D_min (eq. 56), metres — our choice 500.
    pub d_min: f64,
    /// Minimum turn radius R_min (eq. 55), metres — our choice 1000 (a 28.6° turn per 500 m step).
    pub r_min: f64,
    /// Planner-side target standard deviation σ_t of the controlled mode, metres: M = s²·σ_t²·I —
    /// our choice 500. (In `chan` mode M is Chan's covariance and σ_t = sqrt(λ_max(M)) is derived.)
    pub sigma_t: f64,
    /// κ of eq. 36, `A = min(10 σ_t, 6 σ_t + κ r_avg)` — our choice [`tdoa::DEFAULT_KAPPA`] = 0.1.
    pub kappa: f64,
    /// Target-position samples K of the `mc` criterion (eq. 60). Paper: 200.
    pub mc_samples: usize,
    /// How the `mc` criterion draws its K points: `uniform_weighted` = the paper's eq. 60 (uniform in the
    /// square, Gaussian weights; default) or `truncated_gaussian` (points from the truncated Gaussian,
    /// equal weights; beyond the paper, a sensitivity setting).
    pub mc_scheme: McScheme,
    /// Inner TDOA-noise resamples R per RMSE point (eq. 79). Paper: 30.
    pub rmse_resamples: usize,
    /// Run seed of the seeded streams (`tdoa::rng`) — our choice 1.
    pub seed: u64,
    /// Where the planner's ẑ and M come from. Default `chan`.
    pub target: TargetMode,
    /// Controlled mode: the planner-side error e0 at scale 1, metres — our choice [300, −400] (|e0| = σ_t).
    pub e0: [f64; 2],
    /// Controlled mode: the scale s ≥ 0 (error s·e0, covariance s²·σ_t²·I). Default 1.
    pub scale: f64,
    /// The estimator: `fused` (the posterior of every snapshot so far; default) or `snapshot` (the
    /// paper's per-step Chan, with the previous estimate as prior).
    pub estimator: EstimatorKind,
    /// The fused estimator's emitter model: `static` (default; the paper) or `constant_velocity`.
    pub emitter_model: EmitterModel,
    /// Process noise σ_a of the `constant_velocity` model, m/s² (white acceleration) — our choice 0.05.
    pub process_noise_accel: f64,
    /// Standard deviation per axis of the `constant_velocity` model's initial velocity (0 ± this), m/s
    /// — our choice 20.
    pub velocity_prior_sigma: f64,
    /// The true emitter's velocity, m/s (the truth moves at constant velocity) — default [0, 0].
    pub emitter_velocity: [f64; 2],
    /// Where the plane is on the Earth (`[origin]`: `lat_deg`, `lon_deg`, `alt_m`; see `model::geo`).
    /// With an origin, `uavs_lat_lon_deg` and `emitter_lat_lon_deg` may give the positions as WGS84
    /// latitude/longitude instead of `uavs` and `emitter`, and every output that holds a position also
    /// gives it as latitude/longitude. The run itself is the same in the plane. Default: none.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub origin: Option<Origin>,
    /// Each UAV's autopilot as a MAVLink endpoint (`udpin:HOST:PORT`, `udpout:…`, `tcpout:…`,
    /// `serial:DEVICE:BAUD`), UAV0 first: what the MAVLink bridge connects to when no `--autopilot` is
    /// given (docs/flying.md). Default: none.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub autopilots: Vec<String>,
    /// The UAVs' positions at step 0 as `[lat, lon]` in degrees (needs `[origin]`; instead of `uavs`).
    /// Read from TOML only: loading converts them into `uavs` ([`Scenario::from_toml_str`]).
    #[serde(skip_serializing)]
    pub uavs_lat_lon_deg: Option<Vec<[f64; 2]>>,
    /// The emitter's position as `[lat, lon]` in degrees (needs `[origin]`; instead of `emitter`). Read from
    /// TOML only: loading converts it into `emitter`.
    #[serde(skip_serializing)]
    pub emitter_lat_lon_deg: Option<[f64; 2]>,
    /// Confidence c of the standoff chance constraint `P(|w − z| < L_min) ≤ 1 − c` under N(ẑ, M), in
    /// [0, 1) — our choice 0.99; 0 is the paper's constraint `|w − ẑ| ≥ L_min` (see
    /// `planning::constraints`).
    pub standoff_confidence: f64,
    /// How spacing and standoff are kept: `certified` (every plan certified along the flown arcs, with
    /// a backup manoeuvre for ever; see `model::safety`) or `waypoints` (the paper's constraints at the
    /// next waypoints only, traded in one fitness). Our choice: `certified`; `uavloc paper` runs
    /// `waypoints`.
    pub safety: SafetyMode,
    /// Horizon of the backup's standoff from a *moving* emitter, seconds (a static emitter is kept for
    /// ever). Our choice: 120 s.
    pub safety_horizon_s: f64,
    /// The receivers: lost arrivals, a silent emitter, multipath, GNSS and clock errors (`[receiver]`,
    /// every key 0 by default: the paper's perfect receiver; see `model::receiver`).
    pub receiver: ReceiverModel,
    /// What the fused estimator does with a burst that fails its χ² gate: `arrival` (default; drop the
    /// outlying arrivals, fuse the rest) or `snapshot` (reject the whole burst).
    pub outliers: OutlierPolicy,
    /// Early stopping shared by the solvers (`[early_stop]`).
    pub early_stop: EarlyStop,
    /// PSO settings (`[pso]`).
    pub pso: PsoConfig,
    /// GA settings (`[ga]`).
    pub ga: GaConfig,
    /// ACO settings (`[aco]`).
    pub aco: AcoConfig,
    /// Gradient solver settings (`[gradient]`).
    pub gradient: GradientConfig,
}

impl Default for Scenario {
    fn default() -> Self {
        Self {
            uavs: vec![[1500.0, 500.0], [10000.0, 1500.0], [5000.0, 8500.0]],
            headings: None,
            emitter: [25000.0, 15000.0],
            speed: 50.0,
            dt: 10.0,
            sigma: RangeSigma::Uniform(28.7712),
            steps: 24,
            delta_alpha: 25f64.to_radians(),
            l_min: 3000.0,
            d_min: 500.0,
            r_min: 1000.0,
            sigma_t: 500.0,
            kappa: DEFAULT_KAPPA,
            mc_samples: 200,
            mc_scheme: McScheme::UniformWeighted,
            rmse_resamples: 30,
            seed: 1,
            target: TargetMode::Chan,
            e0: [300.0, -400.0],
            scale: 1.0,
            estimator: EstimatorKind::Fused,
            emitter_model: EmitterModel::Static,
            process_noise_accel: 0.05,
            velocity_prior_sigma: 20.0,
            emitter_velocity: [0.0, 0.0],
            origin: None,
            autopilots: Vec::new(),
            uavs_lat_lon_deg: None,
            emitter_lat_lon_deg: None,
            standoff_confidence: 0.99,
            safety: SafetyMode::Certified,
            safety_horizon_s: 120.0,
            receiver: ReceiverModel::default(),
            outliers: OutlierPolicy::default(),
            early_stop: EarlyStop::default(),
            pso: PsoConfig::default(),
            ga: GaConfig::default(),
            aco: AcoConfig::default(),
            gradient: GradientConfig::default(),
        }
    }
}

impl Scenario {
    /// The paper's method on the nominal case: [`Scenario::default`] with the per-step Chan estimator
    /// (`snapshot`) and the approach constraint at ẑ (`standoff_confidence = 0`). `uavloc paper` runs it.
    pub fn paper() -> Self {
        Self {
            estimator: EstimatorKind::Snapshot,
            standoff_confidence: 0.0,
            safety: SafetyMode::Waypoints,
            ..Self::default()
        }
    }

    /// A certified run starts safe: no two UAVs closer than `D_min` and no UAV within `L_min` of the
    /// emitter at step 0 (a start that is safe but admits no certified plan — two UAVs converging inside
    /// their turn radii — runs, flagged uncertified from step 0).
    fn check_safe_start(&self) -> Result<(), ScenarioError> {
        let n = self.uavs.len();
        for a in 0..n {
            for b in a + 1..n {
                let d = dist(self.uavs[a], self.uavs[b]);
                if self.d_min > 0.0 && d < self.d_min {
                    return Err(invalid(
                        "uavs",
                        format!(
                            "UAV {a} and UAV {b} start {d:.1} m apart, closer than d_min = {} m: an unsafe start \
                             (safety = \"certified\"; \"waypoints\" runs it)",
                            self.d_min
                        ),
                    ));
                }
            }
        }
        for (i, p) in self.uavs.iter().enumerate() {
            let d = dist(*p, self.emitter);
            if self.l_min > 0.0 && d < self.l_min {
                return Err(invalid(
                    "uavs",
                    format!(
                        "UAV {i} starts {d:.1} m from the emitter, inside l_min = {} m: an unsafe start \
                         (safety = \"certified\"; \"waypoints\" runs it)",
                        self.l_min
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The fused estimator's motion model (validated parameters).
    pub fn dynamics(&self) -> Result<Dynamics, ScenarioError> {
        Dynamics::new(self.emitter_model, self.dt, self.process_noise_accel, self.velocity_prior_sigma).map_err(|e| {
            let key =
                if e.to_string().contains("velocity_prior") { "velocity_prior_sigma" } else { "process_noise_accel" };
            invalid(key, e.to_string())
        })
    }

    /// The true emitter position at `step`, metres: `emitter + step·dt·emitter_velocity`.
    pub fn emitter_at(&self, step: u64) -> Vector2<f64> {
        let t = step as f64 * self.dt;
        Vector2::new(self.emitter[0] + t * self.emitter_velocity[0], self.emitter[1] + t * self.emitter_velocity[1])
    }

    /// Parses TOML and validates.
    pub fn from_toml_str(text: &str) -> Result<Self, ScenarioError> {
        let mut scenario: Scenario = toml::from_str(text).map_err(|e| parse_error(text, &e))?;
        let table: toml::Table = text.parse().map_err(|e| parse_error(text, &e))?;
        scenario.resolve_geographic(&table)?;
        scenario.validate()?;
        Ok(scenario)
    }

    /// The run's local plane, when the scenario has an origin (an invalid origin is `None`; `validate`
    /// refuses it).
    pub fn frame(&self) -> Option<LocalFrame> {
        self.origin.and_then(|o| LocalFrame::new(o).ok())
    }

    /// Converts `uavs_lat_lon_deg` / `emitter_lat_lon_deg` into `uavs` / `emitter` in the origin's plane
    /// (and clears them): each position is given once, and only with an origin.
    fn resolve_geographic(&mut self, table: &toml::Table) -> Result<(), ScenarioError> {
        let geo_uavs = self.uavs_lat_lon_deg.take();
        let geo_emitter = self.emitter_lat_lon_deg.take();
        for (geo, local, given) in [
            ("uavs_lat_lon_deg", "uavs", geo_uavs.is_some()),
            ("emitter_lat_lon_deg", "emitter", geo_emitter.is_some()),
        ] {
            if given && table.contains_key(local) {
                return Err(invalid(geo, format!("give the position once: `{local}` (metres) or `{geo}`, not both")));
            }
            if given && self.origin.is_none() {
                return Err(invalid(geo, "latitude/longitude positions need an `[origin]` (lat_deg, lon_deg, alt_m)"));
            }
        }
        let Some(origin) = self.origin else { return Ok(()) };
        let frame = LocalFrame::new(origin).map_err(|e| invalid("origin", e.to_string()))?;
        let local = |key: String, p: [f64; 2]| {
            LatLon::new(p[0], p[1]).and_then(|p| frame.to_local(p)).map_err(|e| invalid(&key, e.to_string()))
        };
        if let Some(uavs) = geo_uavs {
            self.uavs = uavs
                .iter()
                .enumerate()
                .map(|(i, p)| local(format!("uavs_lat_lon_deg[{i}]"), *p))
                .collect::<Result<_, _>>()?;
        }
        if let Some(p) = geo_emitter {
            self.emitter = local("emitter_lat_lon_deg".into(), p)?;
        }
        Ok(())
    }

    /// Reads, parses and validates a TOML file.
    pub fn from_file(path: impl AsRef<Path>) -> Result<Self, ScenarioError> {
        let path = path.as_ref();
        let text =
            std::fs::read_to_string(path).map_err(|source| ScenarioError::Io { path: path.to_path_buf(), source })?;
        Self::from_toml_str(&text)
    }

    /// The scenario as TOML (angles in degrees).
    pub fn to_toml_string(&self) -> String {
        toml::to_string(self).expect("a scenario always serialises")
    }

    /// A fingerprint of every value of the scenario: the 64-bit FNV-1a hash of its TOML, in hex. Two runs
    /// with the same fingerprint ran the same scenario (steps and seed included); stable across builds
    /// and processes (not `std`'s randomised hasher).
    pub fn fingerprint(&self) -> String {
        format!("{:016x}", self.run_id())
    }

    /// [`Scenario::fingerprint`] as a number, never 0 (0 means "no scenario" on the wire:
    /// `protocol::Control::run`).
    pub fn run_id(&self) -> u64 {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for b in self.to_toml_string().bytes() {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
        h.max(1)
    }

    /// Checks every value; the error names the first offending key.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        if self.uavs_lat_lon_deg.is_some() || self.emitter_lat_lon_deg.is_some() {
            return Err(invalid(
                "uavs_lat_lon_deg",
                "latitude/longitude positions are read from TOML only (from_toml_str)",
            ));
        }
        if let Some(origin) = self.origin {
            let frame = LocalFrame::new(origin).map_err(|e| invalid("origin", e.to_string()))?;
            for (key, p) in self
                .uavs
                .iter()
                .enumerate()
                .map(|(i, p)| (format!("uavs[{i}]"), p))
                .chain([("emitter".to_string(), &self.emitter)])
            {
                frame.to_geodetic(*p).map_err(|e| invalid(&key, e.to_string()))?;
            }
        }
        let n = self.uavs.len();
        if !(3..=MAX_UAVS).contains(&n) {
            return Err(invalid("uavs", format!("need 3 to {MAX_UAVS} UAVs, got {n}")));
        }
        if !self.autopilots.is_empty() {
            if self.autopilots.len() != n {
                return Err(invalid(
                    "autopilots",
                    format!(
                        "{} endpoints for {n} UAVs: one MAVLink endpoint per UAV, UAV0 first",
                        self.autopilots.len()
                    ),
                ));
            }
            if self.origin.is_none() {
                return Err(invalid("autopilots", "aircraft need an `[origin]`: their targets are latitude/longitude"));
            }
            if let Some(i) = self.autopilots.iter().position(|e| !e.contains(':') || e.trim() != e) {
                return Err(invalid(
                    &format!("autopilots[{i}]"),
                    format!(
                        "{:?} is not an endpoint (udpin:HOST:PORT, udpout:HOST:PORT, tcpout:HOST:PORT, serial:DEVICE:BAUD)",
                        self.autopilots[i]
                    ),
                ));
            }
        }
        for (i, p) in self.uavs.iter().enumerate() {
            within_extent(&format!("uavs[{i}]"), p)?;
        }
        for a in 0..n {
            for b in a + 1..n {
                let d = dist(self.uavs[a], self.uavs[b]);
                if d < COINCIDENCE_TOLERANCE_M {
                    return Err(invalid("uavs", format!("UAV {a} and UAV {b} coincide (distance {d:.3e} m)")));
                }
            }
        }
        within_extent("emitter", &self.emitter)?;
        for (i, p) in self.uavs.iter().enumerate() {
            if dist(*p, self.emitter) < COINCIDENCE_TOLERANCE_M {
                return Err(invalid("emitter", format!("the emitter sits on UAV {i}")));
            }
        }
        if let Some(h) = &self.headings {
            if h.len() != n {
                return Err(invalid("headings_deg", format!("expected {n} headings (one per UAV), got {}", h.len())));
            }
            finite_all("headings_deg", h)?;
        }
        positive("speed", self.speed)?;
        positive("dt", self.dt)?;
        length("speed", "the distance flown per step, speed × dt", self.speed * self.dt)?;
        match &self.sigma {
            RangeSigma::Uniform(s) => positive("sigma", *s)?,
            RangeSigma::PerUav(s) => {
                if s.len() != n {
                    return Err(invalid("sigma", format!("expected {n} values (one per UAV), got {}", s.len())));
                }
                for v in s {
                    positive("sigma", *v)?;
                }
            }
        }
        self.noise_model()?;
        count("steps", self.steps, 1, MAX_STEPS)?;
        finite("delta_alpha_deg", self.delta_alpha)?;
        if !(self.delta_alpha > 0.0 && self.delta_alpha <= std::f64::consts::PI) {
            return Err(invalid(
                "delta_alpha_deg",
                format!("must be in (0, 180] degrees, got {}", self.delta_alpha.to_degrees()),
            ));
        }
        for (key, v) in [("l_min", self.l_min), ("d_min", self.d_min), ("r_min", self.r_min)] {
            non_negative(key, v)?;
            length(key, key, v)?;
        }
        positive("sigma_t", self.sigma_t)?;
        length("sigma_t", "sigma_t", self.sigma_t)?;
        non_negative("kappa", self.kappa)?;
        count("mc_samples", self.mc_samples, 2, MAX_COUNT)?;
        count("rmse_resamples", self.rmse_resamples, 1, MAX_COUNT)?;
        within_extent("e0", &self.e0)?;
        non_negative("scale", self.scale)?;
        length(
            "scale",
            "the controlled error scale × max(|e0|, sigma_t)",
            self.scale * self.sigma_t.max(norm(self.e0)),
        )?;
        non_negative("process_noise_accel", self.process_noise_accel)?;
        positive("velocity_prior_sigma", self.velocity_prior_sigma)?;
        self.dynamics()?;
        finite_all("emitter_velocity", &self.emitter_velocity)?;
        length(
            "emitter_velocity",
            "the distance the emitter moves per step, |emitter_velocity| × dt",
            norm(self.emitter_velocity) * self.dt,
        )?;
        finite("standoff_confidence", self.standoff_confidence)?;
        positive("safety_horizon_s", self.safety_horizon_s)?;
        if self.safety == SafetyMode::Certified {
            self.check_safe_start()?;
        }
        if !(0.0..1.0).contains(&self.standoff_confidence) {
            return Err(invalid(
                "standoff_confidence",
                format!(
                    "must be in [0, 1) (0: the paper's constraint at the estimate), got {}",
                    self.standoff_confidence
                ),
            ));
        }
        self.receiver.validate().map_err(|(key, reason)| invalid(&key, reason))?;
        non_negative("early_stop.tolerance", self.early_stop.tolerance)?;
        count("pso.particles", self.pso.particles, 1, MAX_COUNT)?;
        count("pso.iterations", self.pso.iterations, 1, MAX_COUNT)?;
        positive("pso.v_max_fraction", self.pso.v_max_fraction)?;
        count("ga.population", self.ga.population, 2, MAX_COUNT)?;
        count("ga.generations", self.ga.generations, 1, MAX_COUNT)?;
        count("ga.tournament", self.ga.tournament, 1, MAX_COUNT)?;
        probability("ga.crossover_rate", self.ga.crossover_rate)?;
        non_negative("ga.blx_alpha", self.ga.blx_alpha)?;
        probability("ga.mutation_rate", self.ga.mutation_rate)?;
        non_negative("ga.mutation_scale", self.ga.mutation_scale)?;
        if self.ga.elites >= self.ga.population {
            return Err(invalid("ga.elites", format!("must be below ga.population ({})", self.ga.population)));
        }
        count("aco.archive", self.aco.archive, 1, MAX_COUNT)?;
        count("aco.ants", self.aco.ants, 1, MAX_COUNT)?;
        count("aco.iterations", self.aco.iterations, 1, MAX_COUNT)?;
        positive("aco.evaporation", self.aco.evaporation)?;
        positive("aco.elite_fraction", self.aco.elite_fraction)?;
        count("gradient.starts", self.gradient.starts, 1, MAX_COUNT)?;
        count("gradient.iterations", self.gradient.iterations, 1, MAX_COUNT)?;
        positive("gradient.tolerance", self.gradient.tolerance)?;
        if self.gradient.tolerance > std::f64::consts::PI {
            return Err(invalid(
                "gradient.tolerance",
                format!("must be at most π rad (half a turn of heading), got {:e}", self.gradient.tolerance),
            ));
        }
        Ok(())
    }

    /// Number of UAVs.
    pub fn uav_count(&self) -> usize {
        self.uavs.len()
    }

    /// UAV positions at step 0, metres.
    pub fn uav_positions(&self) -> Vec<Vector2<f64>> {
        self.uavs.iter().map(|p| Vector2::new(p[0], p[1])).collect()
    }

    /// True emitter position, metres.
    pub fn emitter_position(&self) -> Vector2<f64> {
        Vector2::new(self.emitter[0], self.emitter[1])
    }

    /// Initial headings, radians: the given ones, or each UAV's bearing to the emitter.
    pub fn initial_headings(&self) -> Vec<f64> {
        match &self.headings {
            Some(h) => h.clone(),
            None => {
                let z = self.emitter_position();
                self.uav_positions().into_iter().map(|p| bearing(p, z)).collect()
            }
        }
    }

    /// Per-UAV range σ, metres.
    pub fn range_sigmas(&self) -> Vec<f64> {
        match &self.sigma {
            RangeSigma::Uniform(s) => vec![*s; self.uavs.len()],
            RangeSigma::PerUav(s) => s.clone(),
        }
    }

    /// The noise model of the range differences (eq. 19).
    pub fn noise_model(&self) -> Result<NoiseModel, ScenarioError> {
        NoiseModel::from_range_sigmas(&self.range_sigmas()).map_err(|e| invalid("sigma", e.to_string()))
    }

    /// Arc length flown per step, `L = v·Δt`, metres.
    pub fn arc_length(&self) -> f64 {
        self.speed * self.dt
    }

    /// In controlled mode, the planner's target for the true emitter `truth`: ẑ = truth + s·e0 and
    /// M = max(s²·σ_t², [`MIN_CONTROLLED_VARIANCE_M2`])·I (paper Section 5.6). `None` in `chan` mode.
    pub fn controlled_target(&self, truth: Vector2<f64>) -> Option<PlannerTarget> {
        (self.target == TargetMode::Controlled).then(|| {
            let s = self.scale;
            let var = (s * s * self.sigma_t * self.sigma_t).max(MIN_CONTROLLED_VARIANCE_M2);
            PlannerTarget {
                estimate: truth + Vector2::new(self.e0[0], self.e0[1]) * s,
                covariance: Matrix2::identity() * var,
            }
        })
    }
}

/// The scenario of a process: `path` (or the default) with `--steps` / `--seed` applied, validated —
/// the same rule as `uavloc simulate`, so every process of a run agrees on it.
pub fn load_scenario(path: Option<&Path>, steps: Option<usize>, seed: Option<u64>) -> Result<Scenario, ScenarioError> {
    let mut sc = match path {
        Some(p) => Scenario::from_file(p)?,
        None => Scenario::default(),
    };
    if let Some(n) = steps {
        sc.steps = n;
    }
    if let Some(s) = seed {
        sc.seed = s;
    }
    sc.validate()?;
    sc.check_path()?;
    sc.check_start()?;
    Ok(sc)
}

/// The factor of [`Scenario::check_start`]: a start whose CRLB at the truth is this many times the UAVs'
/// mean distance to the emitter or more is refused.
pub const START_CRLB_FACTOR: f64 = 100.0;

impl Scenario {
    /// Whether the emitter stays within the plane model's extent (±[`MAX_EXTENT_M`]) to the last step: its
    /// whole path is known (`emitter + k·dt·emitter_velocity`), and the extent is convex, so the end of the
    /// path decides. Checked by [`load_scenario`] once `--steps` is applied (a file may be fine for fewer
    /// steps than its own).
    pub fn check_path(&self) -> Result<(), ScenarioError> {
        let end = self.emitter_at(self.steps as u64);
        if end.iter().all(|c| c.abs() <= MAX_EXTENT_M) {
            return Ok(());
        }
        let speed = norm(self.emitter_velocity) * self.dt;
        let first = (1..=self.steps as u64).find(|&k| self.emitter_at(k).iter().any(|c| c.abs() > MAX_EXTENT_M));
        Err(invalid(
            "emitter_velocity",
            format!(
                "the emitter ({speed:e} m per step) leaves the plane model's extent, ±{MAX_EXTENT_M:e} m, at step \
                 {} of {}: slow it down or shorten the run",
                first.unwrap_or(self.steps as u64),
                self.steps
            ),
        ))
    }

    /// Whether the run can localise the emitter from its start: Chan must solve the noise-free step 0
    /// (it refuses three collinear UAVs, for one), and the CRLB at the true emitter must be below
    /// [`START_CRLB_FACTOR`] = 100 times the UAVs' mean distance to it. The bound of n fused snapshots of
    /// one geometry shrinks like 1/√n, so beyond that factor not even 10 000 snapshots would bring it
    /// below the range: no fix can mean anything, and Chan has no physical root for most draws. A run that fails here would fail at step 0 every time: it is refused up front,
    /// naming the key to change (`uavloc simulate` and `launch`, and every process, through
    /// [`load_scenario`]).
    pub fn check_start(&self) -> Result<(), ScenarioError> {
        let noise = self.noise_model()?;
        let sensors = tdoa::Sensors::new(&self.uavs, noise).map_err(|e| invalid("uavs", e.to_string()))?;
        let z = self.emitter_position();
        let d = sensors.range_differences(&z);
        let why = |what: String| {
            invalid(
                "uavs",
                format!(
                    "the emitter cannot be localised from the start of the run: {what}; move the UAVs (or the emitter)"
                ),
            )
        };
        tdoa::chan(&sensors, &d, Some(z)).map_err(|e| why(e.to_string()))?;
        let bound = tdoa::crlb(&sensors, &z).map_err(|e| why(e.to_string()))?.crlb_m;
        let range = sensors.mean_range(&z);
        if bound.is_nan() || bound >= START_CRLB_FACTOR * range {
            return Err(invalid(
                "sigma",
                format!(
                    "the emitter cannot be localised from the start of the run: the CRLB at the true emitter \
                     ({bound:.3e} m) is not below {START_CRLB_FACTOR} times the UAVs' mean distance to it \
                     ({range:.0} m); lower sigma"
                ),
            ));
        }
        Ok(())
    }
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

fn finite(key: &str, v: f64) -> Result<(), ScenarioError> {
    if v.is_finite() { Ok(()) } else { Err(invalid(key, format!("must be a finite number, got {v}"))) }
}

fn finite_all(key: &str, v: &[f64]) -> Result<(), ScenarioError> {
    v.iter().try_for_each(|x| finite(key, *x))
}

/// Every coordinate of a point within ±[`MAX_EXTENT_M`] (finite first).
fn within_extent(key: &str, v: &[f64]) -> Result<(), ScenarioError> {
    finite_all(key, v)?;
    match v.iter().find(|x| x.abs() > MAX_EXTENT_M) {
        Some(x) => Err(invalid(
            key,
            format!("coordinates must be within ±{MAX_EXTENT_M:e} m (the plane model's extent), got {x:e}"),
        )),
        None => Ok(()),
    }
}

/// A length `what` (metres) at most [`MAX_EXTENT_M`].
fn length(key: &str, what: &str, v: f64) -> Result<(), ScenarioError> {
    if v <= MAX_EXTENT_M {
        Ok(())
    } else {
        Err(invalid(key, format!("{what} must be at most {MAX_EXTENT_M:e} m (the plane model's extent), got {v:e} m")))
    }
}

fn norm(v: [f64; 2]) -> f64 {
    v[0].hypot(v[1])
}

fn positive(key: &str, v: f64) -> Result<(), ScenarioError> {
    finite(key, v)?;
    if v > 0.0 { Ok(()) } else { Err(invalid(key, format!("must be > 0, got {v}"))) }
}

fn non_negative(key: &str, v: f64) -> Result<(), ScenarioError> {
    finite(key, v)?;
    if v >= 0.0 { Ok(()) } else { Err(invalid(key, format!("must be ≥ 0, got {v}"))) }
}

fn probability(key: &str, v: f64) -> Result<(), ScenarioError> {
    finite(key, v)?;
    if (0.0..=1.0).contains(&v) { Ok(()) } else { Err(invalid(key, format!("must be in [0, 1], got {v}"))) }
}

/// The most steps a run may have: the run record is held in memory at its end (≈ 1.5 KB per step).
pub const MAX_STEPS: usize = 1_000_000;

/// The most of any solver's population or iterations, of the `mc` criterion's samples and of the RMSE's
/// resamples: the criterion is evaluated for every candidate of every step, and a population is held in
/// memory; beyond this a step takes hours, or the allocation fails (a count of 10¹¹ aborted the run).
pub const MAX_COUNT: usize = 100_000;

/// A count `v` of `key` within `min..=max`.
fn count(key: &str, v: usize, min: usize, max: usize) -> Result<(), ScenarioError> {
    if (min..=max).contains(&v) { Ok(()) } else { Err(invalid(key, format!("must be in {min}..={max}, got {v}"))) }
}

/// Turns a TOML error into [`ScenarioError::Parse`], locating the key from the error's byte span.
fn parse_error(text: &str, err: &toml::de::Error) -> ScenarioError {
    let span = err.span();
    let line = span.as_ref().map(|s| text[..s.start.min(text.len())].matches('\n').count() + 1);
    let key = span.and_then(|s| key_at(text, s.start));
    ScenarioError::Parse { key, line, message: err.message().trim().to_string() }
}

/// The dotted key whose value (or name) contains byte `pos`: the nearest `key =` at or above that line,
/// prefixed by the enclosing `[table]`.
fn key_at(text: &str, pos: usize) -> Option<String> {
    let pos = pos.min(text.len());
    let upto_line_end = text[pos..].find('\n').map_or(text.len(), |i| pos + i);
    let mut key: Option<String> = None;
    for raw in text[..upto_line_end].lines().rev() {
        let line = raw.trim();
        if let Some(table) = table_header(line) {
            return Some(match key {
                Some(k) => format!("{table}.{k}"),
                None => table.to_string(),
            });
        }
        if key.is_none()
            && let Some((lhs, _)) = line.split_once('=')
        {
            let lhs = lhs.trim().trim_matches('"');
            if !lhs.is_empty() && lhs.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-' || c == '.') {
                key = Some(lhs.to_string());
            }
        }
    }
    key
}

/// The name of a `[table]` or `[[array]]` header line (not a row of an inline array such as `[1.0, 2.0],`).
fn table_header(line: &str) -> Option<&str> {
    let line = line.split('#').next()?.trim();
    let inner = line.strip_prefix('[')?.strip_suffix(']')?;
    let inner = inner.trim_start_matches('[').trim_end_matches(']').trim();
    let is_key = |c: char| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.' | ' ' | '"');
    (!inner.is_empty() && inner.chars().all(is_key) && inner.chars().any(|c| c.is_ascii_alphabetic())).then_some(inner)
}

/// Serde adapter: radians in Rust, degrees in TOML.
mod degrees {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(rad: &f64, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_f64(rad.to_degrees())
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        f64::deserialize(d).map(f64::to_radians)
    }
}

/// Serde adapter for an optional list of angles: radians in Rust, degrees in TOML.
mod opt_degrees {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(rad: &Option<Vec<f64>>, s: S) -> Result<S::Ok, S::Error> {
        rad.as_ref().map(|v| v.iter().map(|r| r.to_degrees()).collect::<Vec<_>>()).serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Vec<f64>>, D::Error> {
        Option::<Vec<f64>>::deserialize(d).map(|v| v.map(|v| v.into_iter().map(f64::to_radians).collect()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const NOMINAL: &str = include_str!("../../scenarios/nominal.toml");

    #[test]
    fn a_start_that_cannot_be_localised_is_refused() {
        Scenario::default().check_start().unwrap();
        Scenario { sigma: RangeSigma::Uniform(500.0), ..Scenario::default() }.check_start().unwrap();
        let collinear = Scenario { uavs: vec![[0.0, 0.0], [5000.0, 0.0], [10000.0, 0.0]], ..Scenario::default() };
        assert_eq!(collinear.check_start().unwrap_err().key(), Some("uavs"));
        let noisy = Scenario { sigma: RangeSigma::Uniform(1e9), ..Scenario::default() };
        assert_eq!(noisy.check_start().unwrap_err().key(), Some("sigma"));
    }

    #[test]
    fn nominal_file_is_the_default() {
        let s = Scenario::from_toml_str(NOMINAL).unwrap();
        assert_eq!(s, Scenario::default());
        Scenario::default().validate().unwrap();
    }

    const GEO: &str = include_str!("../../scenarios/geo.toml");

    /// `scenarios/geo.toml` is the nominal case given in latitude/longitude: its positions are the
    /// nominal ones to within 0.1 mm, it keeps its origin, and it reads back from its own TOML (in metres)
    /// as the same scenario.
    #[test]
    fn positions_in_latitude_longitude_are_the_nominal_ones_in_the_plane() {
        let s = Scenario::from_toml_str(GEO).unwrap();
        let d = Scenario::default();
        for (a, b) in s.uavs.iter().chain([&s.emitter]).zip(d.uavs.iter().chain([&d.emitter])) {
            assert!(dist(*a, *b) < 1e-4, "{a:?} vs {b:?}");
        }
        assert_eq!(s.origin.map(|o| o.lat_deg), Some(47.3977));
        assert!(s.uavs_lat_lon_deg.is_none() && s.emitter_lat_lon_deg.is_none(), "resolved into the plane");
        let text = s.to_toml_string();
        assert!(text.contains("[origin]") && !text.contains("lat_lon"), "{text}");
        assert_eq!(Scenario::from_toml_str(&text).unwrap(), s);
        // An origin alone changes nothing of the run's values but the fingerprint.
        let placed = Scenario { origin: s.origin, ..Scenario::default() };
        assert_ne!(placed.fingerprint(), d.fingerprint());
        assert_eq!(Scenario { origin: None, ..placed }, d);
    }

    #[test]
    fn bad_geographic_positions_are_named() {
        let origin = "[origin]\nlat_deg = 47.0\nlon_deg = 8.0\n";
        assert_eq!(key_of("emitter_lat_lon_deg = [47.1, 8.2]"), "emitter_lat_lon_deg", "no origin");
        assert_eq!(
            key_of(&format!("emitter = [1.0, 2.0]\nemitter_lat_lon_deg = [47.1, 8.2]\n{origin}")),
            "emitter_lat_lon_deg"
        );
        assert_eq!(
            key_of(&format!("uavs = [[0,0],[1,1],[2,0]]\nuavs_lat_lon_deg = [[47.1, 8.2]]\n{origin}")),
            "uavs_lat_lon_deg"
        );
        let e = Scenario::from_toml_str(&format!("emitter_lat_lon_deg = [95.0, 8.2]\n{origin}")).unwrap_err();
        assert_eq!(e.key(), Some("emitter_lat_lon_deg"));
        assert!(e.to_string().contains("latitude 95"), "{e}");
        let far = format!("uavs_lat_lon_deg = [[47.0, 8.0], [47.0, 8.1], [60.0, 8.0]]\n{origin}");
        let e = Scenario::from_toml_str(&far).unwrap_err();
        assert_eq!(e.key(), Some("uavs_lat_lon_deg[2]"));
        assert!(e.to_string().contains("from the origin"), "{e}");
        assert_eq!(key_of("[origin]\nlat_deg = 89.9\nlon_deg = 0.0"), "origin");
        assert_eq!(key_of("[origin]\nlat_deg = 10.0\nlon_deg = 0.0\nalt_m = nan"), "origin");
        assert_eq!(key_of("[origin]\nlat_deg = 10.0"), "origin");
        assert_eq!(key_of("[origin]\nlat_deg = 10.0\nlon_deg = 0.0\nheight = 3"), "origin.height");
        // Autopilot endpoints: one per UAV, with an origin, each an endpoint.
        let geo = |extra: &str| format!("autopilots = {extra}\n{GEO}");
        let ok =
            Scenario::from_toml_str(&geo(r#"["udpin:0.0.0.0:14550", "udpin:0.0.0.0:14551", "tcpout:10.0.0.2:5760"]"#))
                .unwrap();
        assert_eq!(ok.autopilots.len(), 3);
        assert_eq!(key_of(&geo(r#"["udpin:0.0.0.0:14550"]"#)), "autopilots");
        assert_eq!(key_of(&geo(r#"["udpin:0.0.0.0:14550", "x", "udpin:0.0.0.0:14552"]"#)), "autopilots[1]");
        assert_eq!(key_of(r#"autopilots = ["udpin:a:1", "udpin:a:2", "udpin:a:3"]"#), "autopilots", "no origin");
    }

    #[test]
    fn empty_file_is_the_default() {
        assert_eq!(Scenario::from_toml_str("").unwrap(), Scenario::default());
    }

    #[test]
    fn default_headings_point_at_the_emitter() {
        let s = Scenario::default();
        let h = s.initial_headings();
        let z = s.emitter_position();
        for (p, h) in s.uav_positions().iter().zip(h) {
            let d = (z - p).normalize();
            assert!((d.x - h.cos()).abs() < 1e-12 && (d.y - h.sin()).abs() < 1e-12);
        }
    }

    #[test]
    fn degrees_in_toml_radians_in_rust() {
        let s = Scenario::from_toml_str("delta_alpha_deg = 30\nheadings_deg = [0, 90, -180]").unwrap();
        assert!((s.delta_alpha - std::f64::consts::FRAC_PI_6).abs() < 1e-15);
        let h = s.headings.clone().unwrap();
        assert!((h[1] - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
        assert_eq!(s.initial_headings(), h);
        let back = Scenario::from_toml_str(&s.to_toml_string()).unwrap();
        assert!((back.delta_alpha - s.delta_alpha).abs() < 1e-15);
    }

    #[test]
    fn sigma_scalar_or_list() {
        let s = Scenario::from_toml_str("sigma = [10.0, 20.0, 30.0]").unwrap();
        assert_eq!(s.range_sigmas(), vec![10.0, 20.0, 30.0]);
        assert_eq!(s.noise_model().unwrap().sigmas(), &[10.0, 20.0, 30.0]);
        assert_eq!(Scenario::default().range_sigmas(), vec![28.7712; 3]);
        let e = Scenario::from_toml_str("sigma = [10.0, 20.0]").unwrap_err();
        assert_eq!(e.key(), Some("sigma"));
    }

    fn key_of(text: &str) -> String {
        let e = Scenario::from_toml_str(text).unwrap_err();
        let key = e.key().unwrap_or_else(|| panic!("no key in {e}")).to_string();
        assert!(e.to_string().contains(&key), "{e}");
        key
    }

    #[test]
    fn unknown_keys_are_named() {
        assert_eq!(key_of("speed = 50\nsped = 3"), "sped");
        assert_eq!(key_of("[pso]\nparticles = 40\nparticle = 3"), "pso.particle");
        let e = Scenario::from_toml_str("sped = 3").unwrap_err();
        assert!(e.to_string().contains("unknown field"), "{e}");
    }

    #[test]
    fn wrong_types_are_named() {
        assert_eq!(key_of("speed = \"fast\""), "speed");
        assert_eq!(key_of("dt = 10\nsteps = 2.5"), "steps");
        assert_eq!(key_of("[aco]\nants = \"many\""), "aco.ants");
        assert_eq!(key_of("uavs = [\n  [0.0, 0.0],\n  [1.0, \"x\"],\n]"), "uavs");
        assert_eq!(key_of("target = \"oracle\""), "target");
        assert_eq!(key_of("sigma = \"x\""), "sigma");
        assert_eq!(key_of("[early_stop]\nwindow = -1"), "early_stop.window");
    }

    #[test]
    fn the_fingerprint_tells_scenarios_apart_and_is_stable() {
        let a = Scenario::default();
        assert_eq!(a.fingerprint(), Scenario::from_toml_str("").unwrap().fingerprint());
        assert_eq!(a.fingerprint().len(), 16);
        for b in [
            Scenario { seed: 2, ..Scenario::default() },
            Scenario { steps: 25, ..Scenario::default() },
            Scenario { emitter: [25000.0, 15000.5], ..Scenario::default() },
        ] {
            assert_ne!(a.fingerprint(), b.fingerprint());
        }
    }

    #[test]
    fn an_unsafe_start_is_refused_naming_the_uavs_unless_the_waypoint_planner_flies_it() {
        let close = "uavs = [[0.0, 0.0], [300.0, 0.0], [0.0, 5000.0]]\nemitter = [40000.0, 0.0]\n";
        let e = Scenario::from_toml_str(close).unwrap_err().to_string();
        assert!(e.contains("UAV 0 and UAV 1") && e.contains("d_min = 500") && e.contains("unsafe start"), "{e}");
        let inside = "uavs = [[0.0, 0.0], [3000.0, 0.0], [0.0, 5000.0]]\nemitter = [1000.0, 1000.0]\n";
        let e = Scenario::from_toml_str(inside).unwrap_err().to_string();
        assert!(e.contains("UAV 0 starts") && e.contains("l_min = 3000"), "{e}");
        // The paper's planner keeps its constraints at the waypoints and runs such a start.
        Scenario::from_toml_str(&format!("{close}safety = \"waypoints\"\n")).unwrap();
        // A safe start is not refused.
        Scenario::from_toml_str("uavs = [[0.0, 0.0], [600.0, 0.0], [0.0, 5000.0]]\nemitter = [40000.0, 0.0]\n")
            .unwrap();
    }

    #[test]
    fn invalid_values_are_named() {
        let cases = [
            ("uavs = [[0.0, 0.0], [1.0, 0.0]]", "uavs"),
            ("uavs = [[0,0],[1,0],[2,0],[3,0],[4,0],[5,0],[6,0],[7,0],[8,0]]", "uavs"),
            ("uavs = [[0.0, 0.0], [1000.0, 0.0], [0.0, 0.0]]", "uavs"),
            ("uavs = [[0.0, 0.0], [1000.0, 0.0], [0.0, inf]]", "uavs[2]"),
            ("uavs = [[0.0, 0.0], [1000.0, 0.0], [0.0, 1e400]]", "uavs"),
            ("emitter = [1500.0, 500.0]", "emitter"),
            ("emitter = [nan, 0.0]", "emitter"),
            ("speed = 0", "speed"),
            ("speed = -5.0", "speed"),
            ("speed = inf", "speed"),
            ("dt = 0", "dt"),
            ("steps = 0", "steps"),
            ("sigma = 0.0", "sigma"),
            ("sigma = [1.0, -1.0, 1.0]", "sigma"),
            ("delta_alpha_deg = 0", "delta_alpha_deg"),
            ("delta_alpha_deg = 181", "delta_alpha_deg"),
            ("l_min = -1", "l_min"),
            ("d_min = -1", "d_min"),
            ("r_min = -1", "r_min"),
            ("sigma_t = 0", "sigma_t"),
            ("kappa = -0.1", "kappa"),
            ("mc_samples = 1", "mc_samples"),
            ("mc_samples = 100001", "mc_samples"),
            ("steps = 1000001", "steps"),
            ("[pso]\nparticles = 100001", "pso.particles"),
            ("[gradient]\niterations = 100001", "gradient.iterations"),
            ("rmse_resamples = 0", "rmse_resamples"),
            ("scale = -1", "scale"),
            ("headings_deg = [0.0, 1.0]", "headings_deg"),
            ("[pso]\nparticles = 0", "pso.particles"),
            ("[pso]\niterations = 0", "pso.iterations"),
            ("[ga]\npopulation = 0", "ga.population"),
            ("[ga]\nmutation_rate = 2.0", "ga.mutation_rate"),
            ("[ga]\nelites = 40", "ga.elites"),
            ("[aco]\nants = 0", "aco.ants"),
            ("[gradient]\nstarts = 0", "gradient.starts"),
            ("[gradient]\ntolerance = 0", "gradient.tolerance"),
            ("[aco]\nevaporation = 0", "aco.evaporation"),
            ("[early_stop]\ntolerance = -1", "early_stop.tolerance"),
            // Finite but beyond the model's lengths: refused, never a panic or a NaN in the run.
            ("uavs = [[1500.0, 500.0], [10000.0, 1500.0], [5000.0, 2e7]]", "uavs[2]"),
            ("emitter = [-2e7, 15000.0]", "emitter"),
            ("speed = 1e300", "speed"),
            ("dt = 1e300", "speed"),
            ("l_min = 1e300", "l_min"),
            ("d_min = 2e7", "d_min"),
            ("r_min = 1e300", "r_min"),
            ("sigma_t = 1e300", "sigma_t"),
            ("sigma = 1e300", "sigma"),
            ("sigma = 1e-300", "sigma"),
            ("e0 = [1e300, 0.0]", "e0"),
            ("scale = 1e300", "scale"),
            ("emitter_velocity = [1e300, 0.0]", "emitter_velocity"),
            ("velocity_prior_sigma = 1e300", "velocity_prior_sigma"),
            ("process_noise_accel = 1e300", "process_noise_accel"),
            ("[gradient]\ntolerance = 1e300", "gradient.tolerance"),
        ];
        for (text, key) in cases {
            let e = Scenario::from_toml_str(text).unwrap_err();
            assert_eq!(e.key(), Some(key), "{text}: {e}");
        }
    }

    #[test]
    fn an_emitter_that_leaves_the_extent_before_the_last_step_is_refused_for_that_run_only() {
        // 50 km/s × 10 s per step: within the per-step bound; out of ±1e7 m at step 20 (x = 25 km + 20 · 500 km).
        let s = Scenario::from_toml_str("emitter_velocity = [50000.0, 0.0]").unwrap();
        let e = s.check_path().unwrap_err();
        assert_eq!(e.key(), Some("emitter_velocity"), "{e}");
        assert!(e.to_string().contains("at step 20 of 24"), "{e}");
        let short = Scenario { steps: 19, ..s };
        assert!(short.check_path().is_ok());
    }

    #[test]
    fn controlled_target_scales_error_and_covariance() {
        let mut s = Scenario::from_toml_str("target = \"controlled\"\ne0 = [30.0, 40.0]\nscale = 0.5").unwrap();
        let truth = s.emitter_position();
        let t = s.controlled_target(truth).unwrap();
        assert_eq!(t.estimate, truth + Vector2::new(15.0, 20.0));
        assert_eq!(t.covariance, Matrix2::identity() * (0.25 * 500.0 * 500.0));
        s.scale = 0.0;
        let t0 = s.controlled_target(truth).unwrap();
        assert_eq!(t0.estimate, truth);
        assert_eq!(t0.covariance, Matrix2::identity() * MIN_CONTROLLED_VARIANCE_M2);
        assert!(Scenario::default().controlled_target(truth).is_none());
    }

    #[test]
    fn from_file_reports_missing_files() {
        let e = Scenario::from_file("/nonexistent/scenario.toml").unwrap_err();
        assert!(matches!(e, ScenarioError::Io { .. }));
    }
}
