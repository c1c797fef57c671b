//! The planning criteria: what a candidate set of next waypoints is worth (paper eqs. 51–52, 60, 74).
//!
//! | name | criterion | paper |
//! |---|---|---|
//! | `single` | `tr F⁻¹(ẑ)` at the next waypoints | single-point method |
//! | `mc` | eq. 60 with K uniform points in the support, drawn once per step | MC method |
//! | `analytical` | `tr F⁻¹(ẑ) + ½ tr(M H(ẑ))` | eq. 74 |
//! | `cubature` | 25-point Gauss–Hermite rule (beyond the paper) | — |
//! | `posterior` | `tr((M⁻¹ + F(ẑ))⁻¹)`: A-optimal on the posterior after the next snapshot | — |
//! | `posterior-cubature` | `E[tr((M⁻¹ + F(z))⁻¹)]` over N(ẑ, M), the `cubature` nodes | — |
//! | `formation` | no criterion: the fixed-formation baseline of [`crate::formation`] | traditional method |
//!
//! The posterior criteria plan for a sequential (fused) estimator: the information the next snapshot
//! *adds* to what is known (`M⁻¹`), not the snapshot alone. They are finite everywhere (M⁻¹ is positive
//! definite), so a candidate on the singular locus is merely uninformative, not infeasible.
//! [`PosteriorObjective`] is their adapter; [`prepare`] builds any criterion.
//!
//! The paper's criteria are the one adapter [`CrlbObjective`] over `tdoa`'s [`GlobalCrlb`] methods: prepared
//! once per planning step for the uncertainty `(ẑ, M, A)`, then evaluated for every candidate. The `mc`
//! samples come from `derive_seed(run_seed, step, Purpose::ObjectiveSamples)`, so every candidate of a
//! step sees the same points (common random numbers).

use std::fmt;
use std::str::FromStr;

use nalgebra::Vector2;
use tdoa::global::{GlobalCrlb, McScheme, Method, MonteCarlo, PreparedObjective};
use tdoa::loss::ArrivalOdds;
use tdoa::rng::{Purpose, derive_seed};
use tdoa::singular::singular_report;
use tdoa::{MAX_UAVS, NoiseModel, Sensors, TdoaError, Uncertainty};

/// The planning choices accepted on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ObjectiveKind {
    /// `tr F⁻¹(ẑ)`.
    Single,
    /// Monte Carlo global CRLB (eq. 60).
    Mc,
    /// Second-order analytical global CRLB (eq. 74).
    Analytical,
    /// 25-point Gauss–Hermite global CRLB (beyond the paper).
    Cubature,
    /// The fixed-formation baseline (no optimisation).
    Formation,
    /// A-optimal on the posterior after the next snapshot, at ẑ.
    Posterior,
    /// The posterior criterion averaged over N(ẑ, M) with the cubature nodes.
    #[serde(rename = "posterior-cubature")]
    PosteriorCubature,
}

impl ObjectiveKind {
    /// All planning choices.
    pub const ALL: [ObjectiveKind; 7] = [
        ObjectiveKind::Single,
        ObjectiveKind::Mc,
        ObjectiveKind::Analytical,
        ObjectiveKind::Cubature,
        ObjectiveKind::Formation,
        ObjectiveKind::Posterior,
        ObjectiveKind::PosteriorCubature,
    ];

    /// The lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            ObjectiveKind::Single => "single",
            ObjectiveKind::Mc => "mc",
            ObjectiveKind::Analytical => "analytical",
            ObjectiveKind::Cubature => "cubature",
            ObjectiveKind::Formation => "formation",
            ObjectiveKind::Posterior => "posterior",
            ObjectiveKind::PosteriorCubature => "posterior-cubature",
        }
    }

    /// The global-CRLB method this choice optimises; `formation` optimises nothing and reports the
    /// single-point criterion `tr F⁻¹(ẑ)` of its plan. The posterior criteria average over the nodes of
    /// `single` (ẑ) and `cubature`.
    pub fn criterion(self) -> Method {
        match self {
            ObjectiveKind::Single | ObjectiveKind::Formation | ObjectiveKind::Posterior => Method::Single,
            ObjectiveKind::PosteriorCubature => Method::Cubature,
            ObjectiveKind::Mc => Method::Mc,
            ObjectiveKind::Analytical => Method::Analytical,
            ObjectiveKind::Cubature => Method::Cubature,
        }
    }

    /// Whether the headings come from a solver (false for `formation`).
    pub fn is_optimised(self) -> bool {
        self != ObjectiveKind::Formation
    }
}

impl fmt::Display for ObjectiveKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for ObjectiveKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        ObjectiveKind::ALL.into_iter().find(|k| k.name() == s).ok_or_else(|| {
            format!(
                "unknown objective '{s}' (expected one of: single, mc, analytical, cubature, formation, posterior, \
                 posterior-cubature)"
            )
        })
    }
}

/// How a sampled criterion draws its points: `mc_samples` (K ≥ 2) of `mc_scheme`, seeded by planning
/// step `step` of run `run_seed` (see [`CrlbObjective::prepare`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sampling {
    /// K, the `mc` criterion's points.
    pub mc_samples: usize,
    /// How they are drawn.
    pub mc_scheme: McScheme,
    /// The run's seed.
    pub run_seed: u64,
    /// The planning step.
    pub step: u64,
}

/// Any criterion of `kind`, prepared for one planning step: the uncertainty `unc`, the UAVs' range
/// noise `noise`, and the receiver's odds `odds` — arrivals lost, the emitter silent — that the
/// posterior criteria count (`None` or perfect: every arrival; see [`tdoa::loss`]). The CRLB criteria
/// plan on every arrival whatever the odds: the expectation of `tr F⁻¹` over lost arrivals is infinite
/// as soon as fewer than three arrivals have a positive probability.
pub fn prepare(
    kind: ObjectiveKind,
    unc: &Uncertainty,
    noise: NoiseModel,
    odds: Option<ArrivalOdds>,
    sampling: Sampling,
) -> Result<Box<dyn StepObjective>, TdoaError> {
    let Sampling { mc_samples, mc_scheme, run_seed, step } = sampling;
    Ok(match kind {
        ObjectiveKind::Posterior | ObjectiveKind::PosteriorCubature => {
            Box::new(PosteriorObjective::prepare(kind, unc, noise)?.with_odds(odds))
        }
        _ => Box::new(CrlbObjective::prepare(kind.criterion(), unc, noise, mc_samples, mc_scheme, run_seed, step)?),
    })
}

/// A prepared criterion of a planning step with what the step reports about it.
pub trait StepObjective: PlanObjective {
    /// Kish's effective sample size of a sampled criterion's points (`None` otherwise).
    fn effective_samples(&self) -> Option<f64> {
        None
    }
}

/// The posterior criteria: `Σ_k ω_k tr((M⁻¹ + F(p_k))⁻¹)` over nodes `p_k` (ẑ alone for `posterior`, the
/// 25-point cubature of N(ẑ, M) for `posterior-cubature`), m². With a receiver that loses arrivals or
/// falls silent, each node's term is the expected posterior trace over what is received
/// ([`tdoa::loss::expected_posterior_trace`]).
pub struct PosteriorObjective {
    points: Vec<Vector2<f64>>,
    weights: Vec<f64>,
    prior_info: nalgebra::Matrix2<f64>,
    noise: NoiseModel,
    odds: Option<ArrivalOdds>,
}

impl fmt::Debug for PosteriorObjective {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("PosteriorObjective").field("nodes", &self.points.len()).finish_non_exhaustive()
    }
}

impl PosteriorObjective {
    /// Prepares `kind` (`posterior` or `posterior-cubature`) for the uncertainty `unc`.
    pub fn prepare(kind: ObjectiveKind, unc: &Uncertainty, noise: NoiseModel) -> Result<Self, TdoaError> {
        let m = unc.cov();
        let prior_info = tdoa::support::covariance_inverse(&m).ok_or(TdoaError::CovarianceNotPositiveDefinite {
            xx: m[(0, 0)],
            xy: m[(0, 1)],
            yy: m[(1, 1)],
        })?;
        let (points, weights) = match kind {
            ObjectiveKind::PosteriorCubature => {
                let rule = tdoa::global::Cubature::rule(unc);
                (rule.points().to_vec(), rule.weights().to_vec())
            }
            _ => (vec![unc.estimate()], vec![1.0]),
        };
        Ok(Self { points, weights, prior_info, noise, odds: None })
    }

    /// The same criterion for a receiver with the odds `odds` (`None` or perfect: every arrival).
    pub fn with_odds(self, odds: Option<ArrivalOdds>) -> Self {
        Self { odds: odds.filter(|o| !o.is_perfect()), ..self }
    }
}

impl PlanObjective for PosteriorObjective {
    fn evaluate(&self, next: &[Vector2<f64>]) -> f64 {
        let Some(sensors) = sensors_at(next, &self.noise) else { return f64::INFINITY };
        let mut sum = 0.0;
        for (p, w) in self.points.iter().zip(&self.weights) {
            let trace = match &self.odds {
                Some(odds) => tdoa::loss::expected_posterior_trace(&self.prior_info, &sensors, p, odds),
                None => (self.prior_info + tdoa::fim(&sensors, p).unwrap_or_else(nalgebra::Matrix2::zeros))
                    .try_inverse()
                    .map(|post| post.trace()),
            };
            let Some(trace) = trace else { return f64::INFINITY };
            sum += w * trace;
        }
        sum
    }
}

impl StepObjective for PosteriorObjective {}

impl StepObjective for CrlbObjective {
    fn effective_samples(&self) -> Option<f64> {
        CrlbObjective::effective_samples(self)
    }
}

/// The sensing geometry of candidate waypoints `next` (on the stack): `None` — the criterion's `+∞` —
/// for more than [`MAX_UAVS`], coincident UAVs or a wrong count.
fn sensors_at(next: &[Vector2<f64>], noise: &NoiseModel) -> Option<Sensors> {
    if next.len() > MAX_UAVS {
        return None;
    }
    let mut uavs = [[0.0; 2]; MAX_UAVS];
    for (u, p) in uavs.iter_mut().zip(next) {
        *u = [p.x, p.y];
    }
    Sensors::new(&uavs[..next.len()], noise.clone()).ok()
}

/// A criterion prepared for one planning step, evaluated at candidate next waypoints.
pub trait PlanObjective: Send + Sync {
    /// The criterion's value for UAVs at `next` (metres), m²; `+∞` — the explicit infeasible value —
    /// when the geometry is invalid (coincident UAVs, wrong count), the FIM is singular at ẑ (single,
    /// analytical), or the support square reaches the FIM's singular locus (mc, cubature: the global
    /// CRLB integral diverges there).
    fn evaluate(&self, next: &[Vector2<f64>]) -> f64;
}

/// The one adapter from a `tdoa` global-CRLB method to a [`PlanObjective`].
pub struct CrlbObjective {
    method: Method,
    prepared: Box<dyn PreparedObjective>,
    noise: NoiseModel,
    effective_samples: Option<f64>,
    /// For the sampled criteria (mc, cubature, quadrature): the support, checked against the candidate's
    /// singular locus (a support that reaches it has an infinite global CRLB, which samples would
    /// estimate as a large but finite, random number).
    support: Option<Uncertainty>,
}

impl fmt::Debug for CrlbObjective {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("CrlbObjective").field("method", &self.method).finish_non_exhaustive()
    }
}

impl CrlbObjective {
    /// Prepares `method` for the uncertainty `unc` of planning step `step` of run `run_seed`; the UAVs
    /// have range noise `noise`. `mc_samples` (K ≥ 2) and `mc_scheme` are used by `mc` only, whose points
    /// are drawn from `derive_seed(run_seed, step, Purpose::ObjectiveSamples)`.
    pub fn prepare(
        method: Method,
        unc: &Uncertainty,
        noise: NoiseModel,
        mc_samples: usize,
        mc_scheme: McScheme,
        run_seed: u64,
        step: u64,
    ) -> Result<Self, TdoaError> {
        let seed = derive_seed(run_seed, step, Purpose::ObjectiveSamples);
        if method == Method::Mc {
            let mc = MonteCarlo::new(mc_samples, seed, mc_scheme)?;
            // The weights depend only on the uncertainty, so the ESS is one number per step.
            let effective_samples = Some(mc.rule(unc).effective_sample_size());
            return Ok(Self { method, prepared: mc.prepare(unc), noise, effective_samples, support: Some(*unc) });
        }
        let built: Box<dyn GlobalCrlb> = method.build(mc_samples, seed)?;
        let support = matches!(method, Method::Cubature | Method::Quadrature).then_some(*unc);
        Ok(Self { method, prepared: built.prepare(unc), noise, effective_samples: None, support })
    }

    /// Kish's effective sample size `1/Σω²` of the `mc` criterion's K weighted points (`None` for the
    /// other methods). Small values (a handful) mean the criterion is dominated by a few points and is
    /// noisy from one step's draw to the next.
    pub fn effective_samples(&self) -> Option<f64> {
        self.effective_samples
    }

    /// Which method this is.
    pub fn method(&self) -> Method {
        self.method
    }
}

impl PlanObjective for CrlbObjective {
    fn evaluate(&self, next: &[Vector2<f64>]) -> f64 {
        match sensors_at(next, &self.noise) {
            Some(sensors)
                if self.support.as_ref().is_some_and(|unc| singular_report(&sensors, unc).intersects_support) =>
            {
                f64::INFINITY
            }
            Some(sensors) => self.prepared.evaluate(&sensors).trace_m2,
            None => f64::INFINITY,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix2;

    fn sampling() -> Sampling {
        Sampling { mc_samples: 200, mc_scheme: McScheme::UniformWeighted, run_seed: 1, step: 0 }
    }

    fn setup() -> (Uncertainty, NoiseModel, Vec<Vector2<f64>>) {
        let z = Vector2::new(25000.0, 15000.0);
        let unc = Uncertainty::with_eq36_side(z, Matrix2::new(4e5, 1e5, 1e5, 2e5), 20000.0, 0.1).unwrap();
        let noise = NoiseModel::uniform(3, 28.7712).unwrap();
        let uavs = vec![Vector2::new(1500.0, 500.0), Vector2::new(10000.0, 1500.0), Vector2::new(5000.0, 8500.0)];
        (unc, noise, uavs)
    }

    #[test]
    fn adapter_matches_tdoa() {
        let (unc, noise, uavs) = setup();
        let pts: Vec<[f64; 2]> = uavs.iter().map(|p| [p.x, p.y]).collect();
        let sensors = Sensors::new(&pts, noise.clone()).unwrap();
        for kind in [ObjectiveKind::Single, ObjectiveKind::Mc, ObjectiveKind::Analytical, ObjectiveKind::Cubature] {
            let obj =
                CrlbObjective::prepare(kind.criterion(), &unc, noise.clone(), 200, McScheme::UniformWeighted, 5, 2)
                    .unwrap();
            let seed = derive_seed(5, 2, Purpose::ObjectiveSamples);
            let direct = kind.criterion().build(200, seed).unwrap().prepare(&unc).evaluate(&sensors).trace_m2;
            assert_eq!(obj.evaluate(&uavs).to_bits(), direct.to_bits(), "{kind}");
            assert!(direct.is_finite() && direct > 0.0);
        }
    }

    #[test]
    fn mc_samples_are_common_within_a_step_and_differ_between_steps() {
        let (unc, noise, uavs) = setup();
        let a = CrlbObjective::prepare(Method::Mc, &unc, noise.clone(), 200, McScheme::UniformWeighted, 5, 2).unwrap();
        let b = CrlbObjective::prepare(Method::Mc, &unc, noise.clone(), 200, McScheme::UniformWeighted, 5, 2).unwrap();
        let c = CrlbObjective::prepare(Method::Mc, &unc, noise, 200, McScheme::UniformWeighted, 5, 3).unwrap();
        assert_eq!(a.evaluate(&uavs), b.evaluate(&uavs));
        assert_ne!(a.evaluate(&uavs), c.evaluate(&uavs));
    }

    #[test]
    fn invalid_geometry_is_infinite() {
        let (unc, noise, mut uavs) = setup();
        uavs[2] = uavs[1];
        let obj =
            CrlbObjective::prepare(Method::Analytical, &unc, noise, 200, McScheme::UniformWeighted, 0, 0).unwrap();
        assert_eq!(obj.evaluate(&uavs), f64::INFINITY);
        assert_eq!(obj.evaluate(&uavs[..2]), f64::INFINITY);
    }

    /// Degenerate geometry never panics and gives the explicit infeasible value `+∞` for every
    /// criterion — coincident UAVs; collinear UAVs with the estimate on their line; the estimate on a
    /// baseline extension; a UAV on top of the estimate. (The uncertainty square around ẑ then reaches
    /// the singular locus of F, where tr F⁻¹ is not integrable, so the global criteria are +∞ too.)
    #[test]
    fn degenerate_geometry_is_infinite_for_every_criterion() {
        let z = Vector2::new(5000.0, 0.0);
        let unc = Uncertainty::with_eq36_side(z, Matrix2::new(4e4, 0.0, 0.0, 4e4), 5000.0, 0.1).unwrap();
        let noise = NoiseModel::uniform(3, 28.7712).unwrap();
        let v = |x: f64, y: f64| Vector2::new(x, y);
        let cases: [(&str, Vec<Vector2<f64>>); 4] = [
            ("coincident", vec![v(0.0, 0.0), v(0.0, 0.0), v(1000.0, 3000.0)]),
            ("collinear through the estimate", vec![v(0.0, 0.0), v(1000.0, 0.0), v(2500.0, 0.0)]),
            ("estimate on a baseline extension", vec![v(0.0, 0.0), v(2000.0, 0.0), v(1000.0, 4000.0)]),
            ("UAV on top of the estimate", vec![v(5000.0, 0.0), v(0.0, 3000.0), v(1000.0, -4000.0)]),
        ];
        for kind in [ObjectiveKind::Single, ObjectiveKind::Mc, ObjectiveKind::Analytical, ObjectiveKind::Cubature] {
            let obj =
                CrlbObjective::prepare(kind.criterion(), &unc, noise.clone(), 200, McScheme::UniformWeighted, 1, 0)
                    .unwrap();
            for (what, uavs) in &cases {
                assert_eq!(obj.evaluate(uavs), f64::INFINITY, "{kind}: {what}");
            }
            // A regular geometry next to them is finite: the value is not infinite by accident.
            let fine = [v(0.0, 5000.0), v(10000.0, 4000.0), v(5000.0, -6000.0)];
            assert!(obj.evaluate(&fine).is_finite(), "{kind}");
        }
    }

    #[test]
    fn posterior_criteria_against_direct_formulas() {
        let (unc, noise, uavs) = setup();
        let pts: Vec<[f64; 2]> = uavs.iter().map(|p| [p.x, p.y]).collect();
        let sensors = Sensors::new(&pts, noise.clone()).unwrap();
        let z = unc.estimate();
        let m = unc.cov();
        let direct = (m.try_inverse().unwrap() + tdoa::fim(&sensors, &z).unwrap()).try_inverse().unwrap().trace();
        let post = prepare(ObjectiveKind::Posterior, &unc, noise.clone(), None, sampling()).unwrap();
        assert!((post.evaluate(&uavs) - direct).abs() <= 1e-12 * direct);
        // Adding information can only shrink the posterior: below both M's trace and tr F⁻¹(ẑ).
        assert!(direct < m.trace() && direct < tdoa::trace_crlb(&sensors, &z));
        // A vague prior (M → ∞·I) gives back the single-point criterion tr F⁻¹(ẑ).
        let vague = Uncertainty::new(z, Matrix2::identity() * 1e14, 1e6).unwrap();
        let v = prepare(ObjectiveKind::Posterior, &vague, noise.clone(), None, sampling()).unwrap();
        let single = tdoa::trace_crlb(&sensors, &z);
        assert!((v.evaluate(&uavs) - single).abs() < 1e-6 * single);
        // The cubature form: a weighted mean over the 25 nodes, each by the same formula.
        let rule = tdoa::global::Cubature::rule(&unc);
        let mean: f64 = rule
            .points()
            .iter()
            .zip(rule.weights())
            .map(|(p, w)| {
                w * (m.try_inverse().unwrap() + tdoa::fim(&sensors, p).unwrap()).try_inverse().unwrap().trace()
            })
            .sum();
        let pc = prepare(ObjectiveKind::PosteriorCubature, &unc, noise.clone(), None, sampling()).unwrap();
        assert!((pc.evaluate(&uavs) - mean).abs() <= 1e-12 * mean);
        // Finite even on the singular locus (collinear UAVs through ẑ), infinite for coincident UAVs.
        let v2 = |x: f64, y: f64| Vector2::new(x, y);
        let line = [
            v2(0.0, 15000.0 - 25000.0 * 0.6),
            v2(10000.0, 15000.0 - 15000.0 * 0.6),
            v2(20000.0, 15000.0 - 5000.0 * 0.6),
        ];
        assert!(post.evaluate(&line).is_finite());
        assert_eq!(post.evaluate(&[uavs[0], uavs[0], uavs[2]]), f64::INFINITY);
    }

    #[test]
    fn names_round_trip() {
        for k in ObjectiveKind::ALL {
            assert_eq!(k.name().parse::<ObjectiveKind>().unwrap(), k);
        }
        assert!("quadrature".parse::<ObjectiveKind>().is_err());
    }
}
