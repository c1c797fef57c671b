//! The global CRLB (paper eqs. 51–52): the truncated-Gaussian-weighted mean of `tr F⁻¹(z)` over the
//! square support around `ẑ`, computed five ways behind one trait.
//!
//! | method | what | paper |
//! |---|---|---|
//! | `single` | `tr F⁻¹(ẑ)` | eq. 52 with a point mass |
//! | `mc` | K uniform points, Gaussian self-normalised weights | eq. 60 |
//! | `analytical` | `tr F⁻¹(ẑ) + ½ tr(M H(ẑ))` | eq. 74 |
//! | `quadrature` | composite tensor Gauss–Legendre, refined until converged | ground truth |
//! | `cubature` | 5×5 Gauss–Hermite in the eigenbasis of `M`, truncated to the support | beyond the paper |
//!
//! A method is prepared once per uncertainty ([`GlobalCrlb::prepare`]) and the prepared objective is then
//! evaluated for many UAV geometries; the `mc` samples are drawn at preparation, so every candidate of a
//! planning step sees the same points (common random numbers).

mod analytical;
mod cubature;
mod mc;
mod nodes;
mod quadrature;
mod single;

use std::fmt;
use std::str::FromStr;

pub use analytical::Analytical;
pub use cubature::Cubature;
pub use mc::{McScheme, MonteCarlo};
pub use nodes::NodeRule;
pub use quadrature::{Quadrature, gauss_hermite, gauss_legendre};
pub use single::SinglePoint;

use crate::singular::{SingularReport, singular_report};
use crate::{Sensors, TdoaError, Uncertainty};

/// One evaluation of a global-CRLB method.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GlobalValue {
    /// Approximation of `tr Cr_Φ` (eq. 52), m²; +∞ where the integrand is infinite at a node.
    pub trace_m2: f64,
    /// Error estimate of `trace_m2` (m²): the sampling standard error for `mc`; for `quadrature` only when
    /// it stopped at its finest level without converging (the change between the last two levels).
    pub stderr_m2: Option<f64>,
    /// Number of `tr F⁻¹` evaluations spent.
    pub evaluations: usize,
    /// Kish's effective sample size `1/Σω²` of sampling methods. The standard error is only
    /// trustworthy when this is large (tens or more): eq. 60's uniform points in a wide square around a
    /// narrow Gaussian can leave one point carrying nearly all the weight.
    pub effective_samples: Option<f64>,
}

/// A method prepared for one uncertainty, ready to evaluate many UAV geometries.
pub trait PreparedObjective: Send + Sync {
    /// `tr Cr_Φ` for these UAVs (m²).
    fn evaluate(&self, sensors: &Sensors) -> GlobalValue;
}

/// A way to compute (or approximate) the global CRLB.
pub trait GlobalCrlb: Send + Sync {
    /// Which method this is.
    fn method(&self) -> Method;
    /// Whether the method estimates the integral of eq. 51 itself (so that a singular locus inside
    /// the support makes its exact value +∞), rather than a local surrogate of it.
    fn estimates_integral(&self) -> bool;
    /// Fixes everything that depends only on the uncertainty (nodes, samples, weights).
    fn prepare(&self, unc: &Uncertainty) -> Box<dyn PreparedObjective>;
}

/// The method names accepted on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    Single,
    Mc,
    Analytical,
    Quadrature,
    Cubature,
}

impl Method {
    /// All methods, in the order of the paper then ours.
    pub const ALL: [Method; 5] = [Method::Single, Method::Mc, Method::Analytical, Method::Quadrature, Method::Cubature];

    /// The lower-case name used by the CLI and in JSON.
    pub fn name(self) -> &'static str {
        match self {
            Method::Single => "single",
            Method::Mc => "mc",
            Method::Analytical => "analytical",
            Method::Quadrature => "quadrature",
            Method::Cubature => "cubature",
        }
    }

    /// The method with its default settings; `samples` and `seed` are used by `mc` only.
    pub fn build(self, samples: usize, seed: u64) -> Result<Box<dyn GlobalCrlb>, TdoaError> {
        Ok(match self {
            Method::Single => Box::new(SinglePoint),
            Method::Mc => Box::new(MonteCarlo::new(samples, seed, McScheme::UniformWeighted)?),
            Method::Analytical => Box::new(Analytical),
            Method::Quadrature => Box::new(Quadrature::default()),
            Method::Cubature => Box::new(Cubature),
        })
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Method {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Method::ALL.into_iter().find(|m| m.name() == s).ok_or_else(|| {
            format!("unknown method '{s}' (expected one of: single, mc, analytical, quadrature, cubature)")
        })
    }
}

/// A global CRLB with its singular-locus diagnosis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GlobalReport {
    /// The method's value. For methods that estimate the integral it is +∞ when the support reaches
    /// the singular locus (the exact value is infinite; a finite number there would be noise).
    pub value: GlobalValue,
    /// Where the singular locus is relative to the support.
    pub singular: SingularReport,
}

/// Evaluates `method` once for `sensors` and `unc`, with the singular-locus check.
pub fn global_crlb(method: &dyn GlobalCrlb, sensors: &Sensors, unc: &Uncertainty) -> GlobalReport {
    let singular = singular_report(sensors, unc);
    let value = if singular.intersects_support && method.estimates_integral() {
        // The exact value is +∞; whatever a finite rule would return here is noise, so don't compute it.
        GlobalValue { trace_m2: f64::INFINITY, stderr_m2: None, evaluations: 0, effective_samples: None }
    } else {
        method.prepare(unc).evaluate(sensors)
    };
    GlobalReport { value, singular }
}
