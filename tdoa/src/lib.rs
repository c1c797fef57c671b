//! # uavloc-tdoa — the TDOA maths core of uavloc
//!
//! Pure functions over plain data (no IPC): the measurement model of paper Section 2, the FIM and CRLB
//! (Section 3.3), the global CRLB over the target-position uncertainty (Sections 3.4, 4.1–4.2) computed
//! five ways behind one trait, Chan's estimator, and Monte Carlo helpers.
//!
//! Conventions: 2-D, positions in metres, times in seconds (σ may be given in ns), angles in radians;
//! `uavs[0]` is the reference UAV; range differences are `d_i = r_i − r_0`, i = 1..N−1; 3 ≤ N ≤ 8 (a burst
//! heard by only some of them: [`arrivals`]).

pub mod arrivals;
pub mod chan;
pub mod consider;
pub mod dist;
mod error;
pub mod fim;
pub mod fusion;
pub mod geometry;
pub mod global;
pub mod linearisation;
pub mod loss;
pub mod montecarlo;
pub mod motion;
pub mod pcrlb;
pub mod rng;
pub mod sigma_points;
pub mod singular;
pub mod support;
pub mod window;

pub use arrivals::{Arrivals, Heard, SensorErrors};
pub use chan::{ChanSolution, chan, maximum_likelihood};
pub use error::TdoaError;
pub use fim::{Crlb, crlb, fim, fim_derivatives, trace_crlb, trace_derivatives};
pub use fusion::{Outcome as FusionOutcome, Posterior, fuse, nees};
pub use geometry::{MAX_EXTENT_M, MIN_SIGMA_M, NoiseModel, RangeDiffs, SPEED_OF_LIGHT, Sensors};
pub use global::{GlobalCrlb, GlobalReport, GlobalValue, Method, global_crlb};
pub use motion::{Dynamics, EmitterModel};
pub use pcrlb::InformationBound;
pub use singular::{SingularReport, singular_report};
pub use support::{
    DEFAULT_KAPPA, Uncertainty, eq36_side, estimate_from_arrays, estimate_to_arrays, matrix_from_rows, matrix_to_rows,
    points_from_arrays,
};

/// Largest number of UAVs supported (fixed-capacity messages carry up to this many).
pub const MAX_UAVS: usize = 8;
