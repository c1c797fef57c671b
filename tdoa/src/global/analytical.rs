//! `analytical`: the paper's second-order surrogate (eq. 74),
//! `tr F⁻¹(ẑ) + ½ tr(M H(ẑ))` with `H` the exact Hessian of `h(z) = tr F⁻¹(z)` (eqs. 67–73).

use nalgebra::{Matrix2, Vector2};

use super::{GlobalCrlb, GlobalValue, Method, PreparedObjective};
use crate::fim::trace_derivatives;
use crate::{Sensors, Uncertainty};

/// The Taylor surrogate of eq. 74. It is local: it does not see a singular locus inside the support.
#[derive(Debug, Clone, Copy, Default)]
pub struct Analytical;

struct Prepared {
    estimate: Vector2<f64>,
    cov: Matrix2<f64>,
}

impl PreparedObjective for Prepared {
    fn evaluate(&self, sensors: &Sensors) -> GlobalValue {
        let trace_m2 = trace_derivatives(sensors, &self.estimate)
            .map_or(f64::INFINITY, |d| d.value + 0.5 * (self.cov * d.hessian).trace());
        GlobalValue { trace_m2, stderr_m2: None, evaluations: 1, effective_samples: None }
    }
}

impl GlobalCrlb for Analytical {
    fn method(&self) -> Method {
        Method::Analytical
    }
    fn estimates_integral(&self) -> bool {
        false
    }
    fn prepare(&self, unc: &Uncertainty) -> Box<dyn PreparedObjective> {
        Box::new(Prepared { estimate: unc.estimate(), cov: unc.cov() })
    }
}
