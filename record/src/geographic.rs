//! A run's positions as WGS84 latitude/longitude, for a run whose scenario has an origin
//! (`model::geo`): each step's UAVs, estimate, truth and the estimate's 95 % ellipse as a polygon.
//! Filled by [`crate::annotate`]; absent without an origin.

use model::geo::{LocalFrame, confidence_ellipse};
use serde::{Deserialize, Serialize};

/// Probability of the ellipse drawn around an estimate.
pub const ELLIPSE_PROBABILITY: f64 = 0.95;
/// Points of a drawn ellipse or circle (the polygon closes with a 65th point, the first again).
pub const POLYGON_POINTS: usize = 64;

/// One step's positions as `[lat, lon]` in degrees.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct StepGeo {
    /// Each UAV, UAV0 first.
    pub uavs_lat_lon_deg: Vec<[f64; 2]>,
    /// The estimate ẑ (`null` before the first fix).
    pub estimate_lat_lon_deg: Option<[f64; 2]>,
    /// The estimate's 95 % confidence ellipse (`(x − ẑ)ᵀ M⁻¹ (x − ẑ) = χ²₂(0.95)`), a closed polygon
    /// (`null` before the first fix).
    pub ellipse_95_lat_lon_deg: Option<Vec<[f64; 2]>>,
    /// The true emitter (`null` without a truth).
    pub truth_lat_lon_deg: Option<[f64; 2]>,
}

impl StepGeo {
    /// The positions of one step in `frame`.
    pub fn of(
        frame: &LocalFrame,
        uavs: &[[f64; 2]],
        estimate: [f64; 2],
        cov: [[f64; 2]; 2],
        truth: Option<[f64; 2]>,
    ) -> Self {
        let at = |p: [f64; 2]| frame.to_geodetic(p).ok().map(|q| q.pair());
        Self {
            uavs_lat_lon_deg: uavs.iter().filter_map(|p| at(*p)).collect(),
            estimate_lat_lon_deg: at(estimate),
            ellipse_95_lat_lon_deg: ellipse_95_lat_lon(frame, estimate, cov),
            truth_lat_lon_deg: truth.and_then(at),
        }
    }
}

/// The 95 % ellipse of an estimate at `centre` with covariance `cov` (plane, m²) as a closed polygon of
/// `[lat, lon]` (degrees); `None` for a covariance that is not positive semi-definite or a place off the
/// plane.
pub fn ellipse_95_lat_lon(frame: &LocalFrame, centre: [f64; 2], cov: [[f64; 2]; 2]) -> Option<Vec<[f64; 2]>> {
    confidence_ellipse(centre, cov, ELLIPSE_PROBABILITY, POLYGON_POINTS).and_then(|ring| frame.pairs(&ring))
}

/// Fills every step's [`StepGeo`] when the run's scenario has an origin (clears them otherwise).
pub fn annotate_geographic(run: &mut crate::RunRecord) {
    let frame = run.scenario.frame();
    for s in &mut run.steps {
        s.geo = frame.as_ref().map(|f| StepGeo::of(f, &s.uavs, s.estimate, s.estimate_cov, s.truth));
    }
}
