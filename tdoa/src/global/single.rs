//! `single`: the single-point objective `tr F⁻¹(ẑ)` (the paper's baseline planner criterion).

use super::{GlobalCrlb, Method, NodeRule, PreparedObjective};
use crate::Uncertainty;

/// `tr F⁻¹(ẑ)`, m²: the uncertainty is ignored except for its centre.
#[derive(Debug, Clone, Copy, Default)]
pub struct SinglePoint;

impl GlobalCrlb for SinglePoint {
    fn method(&self) -> Method {
        Method::Single
    }
    fn estimates_integral(&self) -> bool {
        false
    }
    fn prepare(&self, unc: &Uncertainty) -> Box<dyn PreparedObjective> {
        Box::new(NodeRule::new(vec![unc.estimate()], vec![1.0], false))
    }
}
