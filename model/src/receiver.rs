//! The receivers of the simulated world: what a real front end does to each burst before uavloc sees it.
//!
//! Scenario table `[receiver]`; every key defaults to 0, the perfect receiver of the paper:
//!
//! | key | meaning | unit |
//! |---|---|---|
//! | `loss` | probability that one UAV's arrival of a burst is lost (each UAV, each step) | [0, 1) |
//! | `silence` | probability that the emitter does not transmit at a step | [0, 1) |
//! | `multipath` | probability that one arrival comes by a reflection | [0, 1) |
//! | `multipath_bias_m` | the reflection's extra path, uniform in `[min, max]` (default [200, 1000]) | m |
//! | `gnss_sigma_m` | GNSS position error per axis, new each step | m |
//! | `gnss_bias_sigma_m` | GNSS position bias per axis, drawn once per flight | m |
//! | `clock_sigma_ns` | clock error, new each step | ns |
//! | `clock_bias_sigma_ns` | clock bias, drawn once per flight | ns |
//!
//! The arrival of UAV i is timed at its **true** position: `a_i = |z − s_i| + n_i + c·δ_i (+ b_i)` with
//! the range noise `n_i ~ N(0, σ_i²)` drawn exactly as the perfect world draws it (so a perfect receiver
//! gives today's range differences bit for bit), the clock error `c·δ_i` (white + flight bias), and a
//! multipath bias `b_i`. The UAV reports `ŝ_i = s_i + e_i` (GNSS white + flight bias). Every draw comes
//! from the seeded streams: `(seed, step, Receiver)` for the step's draws in a fixed order, `(seed, 0,
//! FlightBias)` for the biases, so `launch` and `simulate` draw the same numbers.
//!
//! The stated σ of each arrival ([`tdoa::arrivals`]): `sqrt(σ_i² + σ_g² + σ_gb² + σ_c² + σ_cb²)`, the
//! persistent part `sqrt(σ_gb² + σ_cb²)`. Multipath is not in the stated σ: it is an outlier, for the
//! estimator to find.

use nalgebra::Vector2;
use rand::Rng;
use rand_distr::{Distribution, Normal};
use tdoa::arrivals::bit;
use tdoa::rng::{Purpose, stream};
use tdoa::{MAX_UAVS, SPEED_OF_LIGHT, SensorErrors};

/// The scenario's receiver model (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReceiverModel {
    /// Probability that one UAV's arrival is lost, per UAV and step.
    pub loss: f64,
    /// Probability that the emitter is silent at a step.
    pub silence: f64,
    /// Probability that one arrival comes by a reflection.
    pub multipath: f64,
    /// The reflection's extra path, uniform in `[min, max]`, metres.
    pub multipath_bias_m: [f64; 2],
    /// GNSS position error per axis, new each step, metres.
    pub gnss_sigma_m: f64,
    /// GNSS position bias per axis, once per flight, metres.
    pub gnss_bias_sigma_m: f64,
    /// Clock error, new each step, nanoseconds.
    pub clock_sigma_ns: f64,
    /// Clock bias, once per flight, nanoseconds.
    pub clock_bias_sigma_ns: f64,
}

impl Default for ReceiverModel {
    fn default() -> Self {
        Self {
            loss: 0.0,
            silence: 0.0,
            multipath: 0.0,
            multipath_bias_m: [200.0, 1000.0],
            gnss_sigma_m: 0.0,
            gnss_bias_sigma_m: 0.0,
            clock_sigma_ns: 0.0,
            clock_bias_sigma_ns: 0.0,
        }
    }
}

/// Metres of range per nanosecond.
pub const METRES_PER_NS: f64 = SPEED_OF_LIGHT * 1e-9;

impl ReceiverModel {
    /// `Err((key, reason))` for a value out of its range.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let key = |k: &str| format!("receiver.{k}");
        for (k, p) in [("loss", self.loss), ("silence", self.silence), ("multipath", self.multipath)] {
            if !(0.0..1.0).contains(&p) {
                return Err((key(k), format!("must be a probability in [0, 1), got {p}")));
            }
        }
        for (k, v) in [
            ("gnss_sigma_m", self.gnss_sigma_m),
            ("gnss_bias_sigma_m", self.gnss_bias_sigma_m),
            ("clock_sigma_ns", self.clock_sigma_ns),
            ("clock_bias_sigma_ns", self.clock_bias_sigma_ns),
        ] {
            if !(v.is_finite() && (0.0..=1.0e5).contains(&v)) {
                return Err((key(k), format!("must be between 0 and 1e5, got {v}")));
            }
        }
        let [lo, hi] = self.multipath_bias_m;
        if !(lo.is_finite() && hi.is_finite() && 0.0 <= lo && lo <= hi && hi <= 1.0e5) {
            return Err((
                key("multipath_bias_m"),
                format!("must be [min, max] with 0 ≤ min ≤ max ≤ 1e5 m, got {lo}, {hi}"),
            ));
        }
        Ok(())
    }

    /// No loss, no silence, no multipath, exact positions and clocks: the paper's receiver.
    pub fn is_perfect(&self) -> bool {
        self.loss == 0.0
            && self.silence == 0.0
            && self.multipath == 0.0
            && self.gnss_sigma_m == 0.0
            && self.gnss_bias_sigma_m == 0.0
            && self.clock_sigma_ns == 0.0
            && self.clock_bias_sigma_ns == 0.0
    }

    /// Each UAV's sensor errors in metres.
    pub fn sensor_errors(&self) -> SensorErrors {
        SensorErrors {
            gnss_m: self.gnss_sigma_m,
            gnss_bias_m: self.gnss_bias_sigma_m,
            clock_m: self.clock_sigma_ns * METRES_PER_NS,
            clock_bias_m: self.clock_bias_sigma_ns * METRES_PER_NS,
        }
    }
}

/// The biases that last the flight: per UAV a GNSS offset (m) and a clock offset (as range, m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlightBias {
    gnss: [Vector2<f64>; MAX_UAVS],
    clock_m: [f64; MAX_UAVS],
}

impl FlightBias {
    /// The biases of the run `seed` (drawn once, from `(seed, 0, FlightBias)`).
    pub fn draw(model: &ReceiverModel, seed: u64) -> Self {
        let mut rng = stream(seed, 0, Purpose::FlightBias);
        let e = model.sensor_errors();
        let mut b = Self { gnss: [Vector2::zeros(); MAX_UAVS], clock_m: [0.0; MAX_UAVS] };
        for i in 0..MAX_UAVS {
            b.gnss[i] = Vector2::new(normal(&mut rng, e.gnss_bias_m), normal(&mut rng, e.gnss_bias_m));
            b.clock_m[i] = normal(&mut rng, e.clock_bias_m);
        }
        b
    }
}

fn normal<R: Rng + ?Sized>(rng: &mut R, sigma: f64) -> f64 {
    // Always draw (a fixed count per step keeps the streams aligned whatever the σ); σ = 0 gives 0.
    let x: f64 = Normal::new(0.0, 1.0).map_or(0.0, |n| n.sample(rng));
    x * sigma
}

/// What the receivers made of one step's burst.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Burst {
    /// The emitter did not transmit.
    pub silent: bool,
    /// The UAVs whose arrival reached uavloc (bit i: UAV i).
    pub heard: u8,
    /// The arrivals that came by a reflection (the truth; a subset of `heard`).
    pub multipath: u8,
    /// Arrivals as ranges, metres (0 where not heard).
    pub arrivals: [f64; MAX_UAVS],
    /// The positions the UAVs report, metres.
    pub reported: [Vector2<f64>; MAX_UAVS],
}

/// The burst of step `step` of run `seed` from an emitter at `z`, received by UAVs truly at `positions`
/// with range σ `range_sigmas` (see the module documentation).
pub fn receive(
    model: &ReceiverModel,
    bias: &FlightBias,
    seed: u64,
    step: u64,
    positions: &[Vector2<f64>],
    z: &Vector2<f64>,
    range_sigmas: &[f64],
) -> Burst {
    let n = positions.len().min(MAX_UAVS);
    let mut noise = stream(seed, step, Purpose::MeasurementNoise);
    let mut rng = stream(seed, step, Purpose::Receiver);
    let e = model.sensor_errors();
    let silent = rng.random::<f64>() < model.silence;
    let mut burst =
        Burst { silent, heard: 0, multipath: 0, arrivals: [0.0; MAX_UAVS], reported: [Vector2::zeros(); MAX_UAVS] };
    let [lo, hi] = model.multipath_bias_m;
    for i in 0..n {
        // The range noise exactly as `tdoa::montecarlo::noisy_range_diffs` draws it.
        let n_i = Normal::new(0.0, range_sigmas[i]).map_or(0.0, |d| d.sample(&mut noise));
        let lost = rng.random::<f64>() < model.loss;
        let reflected = rng.random::<f64>() < model.multipath;
        let extra = lo + (hi - lo) * rng.random::<f64>();
        let gnss = Vector2::new(normal(&mut rng, e.gnss_m), normal(&mut rng, e.gnss_m));
        let clock = normal(&mut rng, e.clock_m);
        burst.reported[i] = positions[i] + gnss + bias.gnss[i];
        if silent || lost {
            continue;
        }
        let mut a = (z - positions[i]).norm() + n_i;
        if model.clock_sigma_ns > 0.0 || model.clock_bias_sigma_ns > 0.0 {
            a += clock + bias.clock_m[i];
        }
        if reflected {
            a += extra;
            burst.multipath |= bit(i);
        }
        burst.arrivals[i] = a;
        burst.heard |= bit(i);
    }
    burst
}

#[cfg(test)]
mod tests {
    use super::*;
    use tdoa::montecarlo::noisy_range_diffs;
    use tdoa::{NoiseModel, Sensors};

    fn swarm() -> Vec<Vector2<f64>> {
        vec![Vector2::new(1500.0, 500.0), Vector2::new(10000.0, 1500.0), Vector2::new(5000.0, 8500.0)]
    }

    #[test]
    fn a_perfect_receiver_gives_todays_differences_bit_for_bit() {
        let z = Vector2::new(25000.0, 15000.0);
        let m = ReceiverModel::default();
        let s = [28.7712, 10.0, 40.0];
        for step in 0..20 {
            let b = receive(&m, &FlightBias::draw(&m, 3), 3, step, &swarm(), &z, &s);
            assert_eq!((b.heard, b.multipath, b.silent), (0b111, 0, false));
            let pts: Vec<[f64; 2]> = swarm().iter().map(|p| [p.x, p.y]).collect();
            let sensors = Sensors::new(&pts, NoiseModel::from_range_sigmas(&s).unwrap()).unwrap();
            let d = noisy_range_diffs(&sensors, &z, &mut stream(3, step, Purpose::MeasurementNoise));
            for i in 1..3 {
                assert_eq!(b.arrivals[i] - b.arrivals[0], d.as_slice()[i - 1]);
            }
            assert_eq!(&b.reported[..3], &swarm()[..]);
        }
    }

    #[test]
    fn the_rates_and_the_biases_are_drawn_as_stated() {
        let z = Vector2::new(25000.0, 15000.0);
        let m = ReceiverModel { loss: 0.2, silence: 0.1, multipath: 0.15, ..ReceiverModel::default() };
        let bias = FlightBias::draw(&m, 9);
        let (mut silent, mut lost, mut reflected, mut heard, mut slots) = (0, 0, 0, 0, 0);
        let steps = 4000;
        for step in 0..steps {
            let b = receive(&m, &bias, 9, step, &swarm(), &z, &[20.0; 3]);
            if b.silent {
                silent += 1;
                assert_eq!(b.heard, 0);
                continue;
            }
            for i in 0..3 {
                slots += 1;
                if b.heard & bit(i) == 0 {
                    lost += 1;
                } else {
                    heard += 1;
                    if b.multipath & bit(i) != 0 {
                        reflected += 1;
                        let clean = (z - swarm()[i]).norm();
                        let excess = b.arrivals[i] - clean;
                        assert!((200.0 - 100.0..=1000.0 + 100.0).contains(&excess), "{excess}");
                    }
                }
            }
        }
        let rate = |k: i32, n: i32| k as f64 / n as f64;
        assert!((rate(silent, steps as i32) - 0.1).abs() < 0.015);
        assert!((rate(lost, slots) - 0.2).abs() < 0.015);
        assert!((rate(reflected, heard) - 0.15).abs() < 0.015);
    }

    #[test]
    fn gnss_and_clock_errors_have_their_sigmas() {
        let z = Vector2::new(25000.0, 15000.0);
        let m = ReceiverModel { gnss_sigma_m: 5.0, clock_sigma_ns: 10.0, ..ReceiverModel::default() };
        let bias = FlightBias::draw(&m, 4);
        let (mut gx, mut clock) = (Vec::new(), Vec::new());
        for step in 0..4000 {
            let b = receive(&m, &bias, 4, step, &swarm(), &z, &[1e-3; 3]);
            gx.push(b.reported[1].x - swarm()[1].x);
            clock.push(b.arrivals[2] - (z - swarm()[2]).norm());
        }
        let sd = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
        assert!((sd(&gx) - 5.0).abs() < 0.2, "{}", sd(&gx));
        assert!((sd(&clock) - 10.0 * METRES_PER_NS).abs() < 0.1, "{}", sd(&clock));
        // A flight bias is the same at every step and differs between runs.
        let mb = ReceiverModel { gnss_bias_sigma_m: 5.0, ..ReceiverModel::default() };
        let (b1, b2) = (FlightBias::draw(&mb, 1), FlightBias::draw(&mb, 2));
        let r = |b: &FlightBias, k| receive(&mb, b, 1, k, &swarm(), &z, &[1.0; 3]).reported[0];
        assert_eq!(r(&b1, 3), r(&b1, 7));
        assert_ne!(r(&b1, 3), r(&b2, 3));
    }

    #[test]
    fn bad_values_are_named() {
        let bad = [
            ReceiverModel { loss: 1.0, ..ReceiverModel::default() },
            ReceiverModel { silence: -0.1, ..ReceiverModel::default() },
            ReceiverModel { multipath: f64::NAN, ..ReceiverModel::default() },
            ReceiverModel { gnss_sigma_m: -1.0, ..ReceiverModel::default() },
            ReceiverModel { clock_bias_sigma_ns: f64::INFINITY, ..ReceiverModel::default() },
            ReceiverModel { multipath_bias_m: [500.0, 200.0], ..ReceiverModel::default() },
        ];
        for m in bad {
            assert!(m.validate().is_err(), "{m:?}");
        }
        assert!(ReceiverModel::default().validate().is_ok());
        assert!(ReceiverModel::default().is_perfect());
    }
}
