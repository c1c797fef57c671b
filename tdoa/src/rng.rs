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
    /// The receiver model's draws of one step: which arrivals are lost, whether the emitter is silent,
    /// multipath, and the white GNSS and clock errors ([`crate::arrivals`]).
    Receiver = 9,
    /// The receiver model's per-flight GNSS and clock biases (drawn once per run, at step 0).
    FlightBias = 10,
    /// The world of an open-loop control: a run's paths flown again with other draws
    /// (`closed_loop::estimate_along`, `uavloc paper receiver`).
    OpenLoopControl = 11,
}

/// SplitMix64's increment (2^64 / φ).
const GOLDEN_GAMMA: u64 = 0x9E37_79B9_7F4A_7C15;

/// SplitMix64 finaliser: a bijective 64-bit mix.
pub fn mix64(mut x: u64) -> u64 {
    x = x.wrapping_add(GOLDEN_GAMMA);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

/// SplitMix64 as a sequence: a tiny seeded generator for test schedules and synthetic samples (the run's
/// numbers come from [`stream`]).
#[derive(Debug, Clone)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// The generator seeded with `seed`.
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// The next number of the sequence.
    pub fn next_u64(&mut self) -> u64 {
        let out = mix64(self.0);
        self.0 = self.0.wrapping_add(GOLDEN_GAMMA);
        out
    }
}

/// The seed of the stream for (`seed`, `step`, `purpose`).
pub fn derive_seed(seed: u64, step: u64, purpose: Purpose) -> u64 {
    mix64(mix64(mix64(seed) ^ step) ^ purpose as u64)
}

/// The stream for (`seed`, `step`, `purpose`).
pub fn stream(seed: u64, step: u64, purpose: Purpose) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(derive_seed(seed, step, purpose))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splitmix64_gives_the_reference_sequence() {
        // The reference implementation's first outputs for seed 0.
        let mut g = SplitMix64::new(0);
        assert_eq!(
            [g.next_u64(), g.next_u64(), g.next_u64()],
            [0xE220_A839_7B1D_CDAF, 0x6E78_9E6A_A1B9_65F4, 0x06C4_5D18_8009_454F]
        );
    }
}
