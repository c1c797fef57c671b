//! The one error type of the maths core.

use thiserror::Error;

/// Everything that can make a TDOA computation refuse its input.
///
/// Every variant names the offending quantity so that a command-line user sees one clear line.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum TdoaError {
    /// Fewer than `min` (3; 2 for the arrivals of one burst) or more than [`crate::MAX_UAVS`] UAVs.
    #[error("need between {min} and {max} UAVs, got {got}")]
    UavCount { got: usize, min: usize, max: usize },
    /// A coordinate, σ or covariance entry is NaN or infinite.
    #[error("{what} is not a finite number ({value})")]
    NotFinite { what: String, value: f64 },
    /// Two UAVs closer than the coincidence tolerance.
    #[error("UAV {a} and UAV {b} coincide (distance {distance:.3e} m)")]
    CoincidentUavs { a: usize, b: usize, distance: f64 },
    /// A standard deviation that is zero or negative.
    #[error("{what} must be > 0 (got {value})")]
    NonPositive { what: String, value: f64 },
    /// A finite value outside the range the model takes (e.g. a length beyond [`crate::MAX_EXTENT_M`]).
    #[error("{what} must be between {min:e} and {max:e}, got {value:e}")]
    OutOfRange { what: String, value: f64, min: f64, max: f64 },
    /// Two lists that must have matching lengths do not.
    #[error("{what}: expected {expected} values, got {got}")]
    LengthMismatch { what: String, expected: usize, got: usize },
    /// A covariance matrix that is not symmetric positive definite.
    #[error("covariance [[{xx:e}, {xy:e}], [{xy:e}, {yy:e}]] m² is not positive definite")]
    CovarianceNotPositiveDefinite { xx: f64, xy: f64, yy: f64 },
    /// The geometry makes the quantity undefined (e.g. all UAVs on one line for Chan,
    /// the emitter on top of a UAV, a singular FIM).
    #[error("degenerate geometry: {0}")]
    Degenerate(String),
    /// The measurements have no physically consistent solution (e.g. |r_i − r_0| larger than the baseline).
    #[error("no physical solution: {0}")]
    NoSolution(String),
}
