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

mod load;
mod validate;

pub use load::load_scenario;
pub use validate::{MAX_COUNT, MAX_STEPS, START_CRLB_FACTOR};

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

    /// The run's local plane, when the scenario has an origin (an invalid origin is `None`; `validate`
    /// refuses it).
    pub fn frame(&self) -> Option<LocalFrame> {
        self.origin.and_then(|o| LocalFrame::new(o).ok())
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

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

fn norm(v: [f64; 2]) -> f64 {
    v[0].hypot(v[1])
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
