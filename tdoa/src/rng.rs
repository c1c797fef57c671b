//! Seeded random streams: one independent ChaCha8 stream per (run seed, step, purpose), so that a run
//! through the processes and a run in one process draw the same numbers.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// What a random stream is used for; each purpose gets its own stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u64)]
pub enum Purpose {
    /// TDOA measurement noise of the world.
    MeasurementNoise = 1,
    /// Noise resamples for RMSE evaluation.
    RmseResamples = 2,
    /// Monte Carlo objective samples.
    ObjectiveSamples = 3,
    /// The planner's solver (PSO/GA/ACO).
    Solver = 4,
    /// Planner-side target error of controlled experiments.
    PlannerError = 5,
    /// The seed of one outer Monte Carlo run of an experiment (`uavloc paper`; the run index is the step).
    OuterRun = 6,
    /// Timing and fixed-geometry draws of an experiment that are not tied to a run's step.
    Experiment = 7,
    /// The planner's standoff search (the second search of a step whose cone search found no feasible plan).
    StandoffSolver = 8,
}

/// SplitMix64 finaliser: a bijective 64-bit mix.
pub fn mix64(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

/// The seed of the stream for (`seed`, `step`, `purpose`).
pub fn derive_seed(seed: u64, step: u64, purpose: Purpose) -> u64 {
    mix64(mix64(mix64(seed) ^ step) ^ purpose as u64)
}

/// The stream for (`seed`, `step`, `purpose`).
pub fn stream(seed: u64, step: u64, purpose: Purpose) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(derive_seed(seed, step, purpose))
}
