//! The simulated world of one run: the truth (the emitter, the UAVs' positions and headings), the range
//! noise, the speed and interval, the run seed and the step counter.
//!
//! Each step [`World`] produces one noisy TDOA measurement ([`World::measure`], noise from the stream
//! `(seed, step, MeasurementNoise)`, so a measurement is a pure function of the world's state) and then
//! moves the UAVs along the commanded headings ([`World::apply`], the planner's circular-arc kinematics,
//! eq. 54). The world enforces physics only: it flies whatever finite heading it is given; the planner's
//! constraints are the planner's business. The emitter-sim process and the in-process closed loop both
//! run one.
//!
//! Units: metres, seconds, radians.

use crate::kinematics::{next_position, wrap_angle};
use crate::receiver::{FlightBias, ReceiverModel, receive};
use crate::scenario::{Scenario, ScenarioError};
use nalgebra::Vector2;
use tdoa::{Arrivals, NoiseModel, RangeDiffs, Sensors, TdoaError};
use thiserror::Error;

/// Why the world refused an input.
#[derive(Debug, Error)]
pub enum WorldError {
    /// The scenario is invalid.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// Not one heading per UAV.
    #[error("headings: expected {expected} values (one per UAV), got {got}")]
    HeadingCount {
        /// UAV count.
        expected: usize,
        /// Headings given.
        got: usize,
    },
    /// A heading is NaN or infinite.
    #[error("heading of UAV {uav} is not a finite number ({value})")]
    HeadingNotFinite {
        /// The UAV.
        uav: usize,
        /// Its heading.
        value: f64,
    },
    /// The current UAV geometry cannot measure (e.g. two UAVs coincide).
    #[error("cannot measure: {0}")]
    Geometry(#[from] TdoaError),
}

/// One step's TDOA measurement as the receivers give it.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    /// The step it belongs to.
    pub step: u64,
    /// UAV positions as the UAVs report them (the truth plus any GNSS error), metres.
    pub uavs: Vec<Vector2<f64>>,
    /// The burst: who heard it, the arrivals, the stated σ (see [`tdoa::arrivals`]). With a perfect
    /// receiver every UAV hears it and the differences to UAV0 are `d̂_i = (r_i + e_i) − (r_0 + e_0)`.
    pub arrivals: Arrivals,
    /// The emitter did not transmit at this step.
    pub silent: bool,
    /// The arrivals that came by a reflection (the truth; bit i: UAV i).
    pub multipath: u8,
}

impl Measurement {
    /// The range differences to UAV0 when every UAV heard the burst (a perfect receiver's step).
    pub fn range_diffs(&self) -> Option<RangeDiffs> {
        let h = self.arrivals.heard().ok()??;
        (h.uavs.len() == self.uavs.len()).then_some(h.diffs)
    }
}

/// The moving part of a [`World`] (everything else comes from the scenario): what emitter-sim checkpoints.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Snapshot {
    /// The step about to be measured.
    pub step: u64,
    /// UAV positions, metres.
    pub positions: Vec<[f64; 2]>,
    /// UAV headings, radians.
    pub headings: Vec<f64>,
}

/// The simulated world of one run.
#[derive(Debug, Clone, PartialEq)]
pub struct World {
    emitter: Vector2<f64>,
    velocity: Vector2<f64>,
    positions: Vec<Vector2<f64>>,
    headings: Vec<f64>,
    noise: NoiseModel,
    receiver: ReceiverModel,
    bias: FlightBias,
    speed: f64,
    dt: f64,
    seed: u64,
    step: u64,
    /// UAVs whose arrival of the current burst cannot be timed or placed (bit i: UAV i) — a UAV flown by
    /// an autopilot whose link is quiet ([`World::place`]); 0 otherwise.
    unheard: u8,
}

impl World {
    /// The world at step 0 of `scenario` (validated), seeded with `scenario.seed`.
    pub fn from_scenario(scenario: &Scenario) -> Result<Self, WorldError> {
        scenario.validate()?;
        Ok(Self {
            emitter: scenario.emitter_position(),
            velocity: Vector2::new(scenario.emitter_velocity[0], scenario.emitter_velocity[1]),
            positions: scenario.uav_positions(),
            headings: scenario.initial_headings().into_iter().map(wrap_angle).collect(),
            noise: scenario.noise_model()?,
            receiver: scenario.receiver,
            bias: FlightBias::draw(&scenario.receiver, scenario.seed),
            speed: scenario.speed,
            dt: scenario.dt,
            seed: scenario.seed,
            step: 0,
            unheard: 0,
        })
    }

    /// Puts the UAVs where their autopilots report them (`positions`, `headings`) for the current step:
    /// the world then measures from there instead of from the arcs it flew. `unheard` (bit i: UAV i) marks
    /// UAVs without a fresh fix — their arrivals of this burst are lost, as a receiver whose position and
    /// time are unknown cannot contribute. Refuses a wrong count or a value that is not finite (leaving the
    /// world unchanged).
    pub fn place(&mut self, positions: &[[f64; 2]], headings: &[f64], unheard: u8) -> Result<(), WorldError> {
        let n = self.positions.len();
        if positions.len() != n || headings.len() != n {
            return Err(WorldError::HeadingCount { expected: n, got: positions.len().min(headings.len()) });
        }
        if let Some((uav, &value)) = headings.iter().enumerate().find(|(_, h)| !h.is_finite()) {
            return Err(WorldError::HeadingNotFinite { uav, value });
        }
        if let Some(&value) = positions.iter().flatten().find(|v| !v.is_finite()) {
            return Err(WorldError::Geometry(TdoaError::NotFinite { what: "a reported UAV position".into(), value }));
        }
        self.positions = positions.iter().map(|p| Vector2::new(p[0], p[1])).collect();
        self.headings = headings.iter().copied().map(wrap_angle).collect();
        self.unheard = unheard;
        Ok(())
    }

    /// The true emitter position at the current step, metres: the scenario's `emitter` moved by
    /// `emitter_velocity · step · dt` (constant velocity; fixed by default).
    pub fn truth(&self) -> Vector2<f64> {
        self.truth_at(self.step)
    }

    /// The true emitter position at `step`, metres.
    pub fn truth_at(&self, step: u64) -> Vector2<f64> {
        self.emitter + self.velocity * (step as f64 * self.dt)
    }

    /// Current UAV positions, metres.
    pub fn positions(&self) -> &[Vector2<f64>] {
        &self.positions
    }

    /// Current headings, radians in (−π, π].
    pub fn headings(&self) -> &[f64] {
        &self.headings
    }

    /// The current step (0 before the first [`World::apply`]).
    pub fn step(&self) -> u64 {
        self.step
    }

    /// The run seed.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// The range noise model.
    pub fn noise(&self) -> &NoiseModel {
        &self.noise
    }

    /// The current sensing geometry.
    pub fn sensors(&self) -> Result<Sensors, TdoaError> {
        let pts: Vec<[f64; 2]> = self.positions.iter().map(|p| [p.x, p.y]).collect();
        Sensors::new(&pts, self.noise.clone())
    }

    /// The receiver model.
    pub fn receiver(&self) -> &ReceiverModel {
        &self.receiver
    }

    /// The σ each UAV states for its arrivals: the range noise with every sensor error, and its
    /// persistent part (see [`tdoa::arrivals`]), metres.
    pub fn stated_sigmas(&self) -> (Vec<f64>, Vec<f64>) {
        let e = self.receiver.sensor_errors();
        let eff = self.noise.sigmas().iter().map(|s| e.effective_sigma(*s)).collect();
        (eff, vec![e.bias_variance().sqrt(); self.positions.len()])
    }

    /// The measurement of the current step, drawn from the streams `(seed, step, MeasurementNoise)` and
    /// `(seed, step, Receiver)` (see [`crate::receiver`]): calling it twice gives the same measurement.
    pub fn measure(&self) -> Result<Measurement, WorldError> {
        // The true geometry must be able to measure (two UAVs may not coincide).
        self.sensors()?;
        let b = receive(
            &self.receiver,
            &self.bias,
            self.seed,
            self.step,
            &self.positions,
            &self.truth(),
            self.noise.sigmas(),
        );
        let n = self.positions.len();
        let reported: Vec<[f64; 2]> = b.reported[..n].iter().map(|p| [p.x, p.y]).collect();
        let (sigmas, bias) = self.stated_sigmas();
        let arrivals = Arrivals::new(&reported, &b.arrivals[..n], b.heard & !self.unheard, &sigmas, &bias)?;
        Ok(Measurement {
            step: self.step,
            uavs: b.reported[..n].to_vec(),
            arrivals,
            silent: b.silent,
            multipath: b.multipath,
        })
    }

    /// The world's moving part (see [`Snapshot`]).
    pub fn snapshot(&self) -> Snapshot {
        Snapshot {
            step: self.step,
            positions: self.positions.iter().map(|p| [p.x, p.y]).collect(),
            headings: self.headings.clone(),
        }
    }

    /// The world of `scenario` (validated) at the state of `snapshot` — the world that took the snapshot,
    /// bit for bit. Refuses a snapshot with another UAV count or non-finite numbers.
    pub fn restore(scenario: &Scenario, snapshot: &Snapshot) -> Result<Self, WorldError> {
        let mut world = Self::from_scenario(scenario)?;
        let n = world.positions.len();
        if snapshot.positions.len() != n || snapshot.headings.len() != n {
            return Err(WorldError::HeadingCount { expected: n, got: snapshot.headings.len() });
        }
        if let Some((uav, &value)) = snapshot.headings.iter().enumerate().find(|(_, h)| !h.is_finite()) {
            return Err(WorldError::HeadingNotFinite { uav, value });
        }
        if let Some(&value) = snapshot.positions.iter().flatten().find(|v| !v.is_finite()) {
            return Err(WorldError::Geometry(TdoaError::NotFinite { what: "a snapshot's UAV position".into(), value }));
        }
        world.positions = snapshot.positions.iter().map(|p| Vector2::new(p[0], p[1])).collect();
        world.headings = snapshot.headings.clone();
        world.step = snapshot.step;
        world.unheard = 0;
        Ok(world)
    }

    /// Flies every UAV for one interval along the circular arc to its commanded heading (radians) and
    /// advances the step. Refuses (leaving the world unchanged) a wrong count or a non-finite heading.
    pub fn apply(&mut self, headings: &[f64]) -> Result<(), WorldError> {
        if headings.len() != self.positions.len() {
            return Err(WorldError::HeadingCount { expected: self.positions.len(), got: headings.len() });
        }
        if let Some((uav, &value)) = headings.iter().enumerate().find(|(_, h)| !h.is_finite()) {
            return Err(WorldError::HeadingNotFinite { uav, value });
        }
        for ((p, psi), &phi) in self.positions.iter_mut().zip(self.headings.iter_mut()).zip(headings) {
            *p = next_position(*p, *psi, phi, self.speed, self.dt);
            *psi = wrap_angle(phi);
        }
        self.step += 1;
        self.unheard = 0;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn world() -> World {
        World::from_scenario(&Scenario::default()).unwrap()
    }

    #[test]
    fn starts_at_the_scenario() {
        let w = world();
        let sc = Scenario::default();
        assert_eq!(w.truth(), sc.emitter_position());
        assert_eq!(w.positions(), sc.uav_positions().as_slice());
        assert_eq!(w.headings(), sc.initial_headings().as_slice());
        assert_eq!((w.step(), w.seed()), (0, sc.seed));
    }

    #[test]
    fn a_restored_snapshot_is_the_same_world() {
        let mut w = world();
        for k in 0..5 {
            w.apply(&[0.1 * k as f64, -0.2, 1.0]).unwrap();
        }
        let back = World::restore(&Scenario::default(), &w.snapshot()).unwrap();
        assert_eq!(back, w);
        assert_eq!(back.measure().unwrap(), w.measure().unwrap());
        let mut bad = w.snapshot();
        bad.headings.pop();
        assert!(World::restore(&Scenario::default(), &bad).is_err());
        bad = w.snapshot();
        bad.positions[1][0] = f64::NAN;
        assert!(World::restore(&Scenario::default(), &bad).is_err());
    }

    #[test]
    fn invalid_scenario_is_refused() {
        let sc = Scenario { speed: -1.0, ..Scenario::default() };
        assert!(matches!(World::from_scenario(&sc), Err(WorldError::Scenario(_))));
    }

    #[test]
    fn measurement_is_deterministic_and_noisy() {
        let w = world();
        let a = w.measure().unwrap();
        let b = w.measure().unwrap();
        assert_eq!(a, b);
        assert_eq!(World::from_scenario(&Scenario::default()).unwrap().measure().unwrap(), a);
        let exact = w.sensors().unwrap().range_differences(&w.truth());
        let sigma = 28.7712;
        for (m, e) in a.range_diffs().unwrap().as_slice().iter().zip(exact.as_slice()) {
            assert!(m != e && (m - e).abs() < 8.0 * sigma * std::f64::consts::SQRT_2, "{m} vs {e}");
        }
        // Another seed, another draw.
        let other = World::from_scenario(&Scenario { seed: 2, ..Scenario::default() }).unwrap();
        assert_ne!(other.measure().unwrap().range_diffs(), a.range_diffs());
    }

    #[test]
    fn noise_has_the_model_covariance() {
        // Over many steps (each its own stream), the errors of d̂ have covariance Q (eq. 19).
        let mut w = world();
        let exact = w.sensors().unwrap().range_differences(&w.truth());
        let n = 4000;
        let mut sum = [[0.0; 2]; 2];
        for k in 0..n {
            w.step = k;
            let d = w.measure().unwrap().range_diffs().unwrap();
            let e: Vec<f64> = d.as_slice().iter().zip(exact.as_slice()).map(|(a, b)| a - b).collect();
            for i in 0..2 {
                for j in 0..2 {
                    sum[i][j] += e[i] * e[j] / n as f64;
                }
            }
        }
        let q = w.noise().q();
        for i in 0..2 {
            for j in 0..2 {
                assert!((sum[i][j] - q[(i, j)]).abs() < 0.1 * q[(0, 0)], "{i}{j}: {} vs {}", sum[i][j], q[(i, j)]);
            }
        }
    }

    #[test]
    fn apply_moves_along_arcs_and_advances() {
        let mut w = world();
        let start = w.positions().to_vec();
        let straight = w.headings().to_vec();
        w.apply(&straight).unwrap();
        assert_eq!(w.step(), 1);
        for (p, q) in start.iter().zip(w.positions()) {
            assert!(((q - p).norm() - 500.0).abs() < 1e-9);
        }
        let m1 = w.measure().unwrap();
        assert_eq!(m1.step, 1);
        assert_eq!(m1.uavs, w.positions());
        // A turn: the world follows the planner's kinematics exactly and stores the wrapped heading.
        let before = w.positions().to_vec();
        let psi = w.headings().to_vec();
        let cmd = [psi[0] + 0.3, psi[1] - 0.2 + std::f64::consts::TAU, psi[2]];
        w.apply(&cmd).unwrap();
        for i in 0..3 {
            assert_eq!(w.positions()[i], next_position(before[i], psi[i], cmd[i], 50.0, 10.0));
            assert_eq!(w.headings()[i], wrap_angle(cmd[i]));
        }
    }

    #[test]
    fn bad_headings_are_refused_and_change_nothing() {
        let mut w = world();
        let before = w.clone();
        assert!(matches!(w.apply(&[0.0, 0.0]), Err(WorldError::HeadingCount { expected: 3, got: 2 })));
        assert!(matches!(w.apply(&[0.0, f64::NAN, 0.0]), Err(WorldError::HeadingNotFinite { uav: 1, .. })));
        assert!(matches!(w.apply(&[0.0, 0.0, f64::INFINITY]), Err(WorldError::HeadingNotFinite { uav: 2, .. })));
        assert_eq!(w, before);
    }

    #[test]
    fn coincident_uavs_cannot_measure() {
        let mut w = world();
        w.positions[2] = w.positions[1];
        assert!(matches!(w.measure(), Err(WorldError::Geometry(TdoaError::CoincidentUavs { .. }))));
    }

    /// A UAV placed where its autopilot reports it is measured from there; one without a fresh fix is not
    /// heard; a bad report changes nothing; the next step hears every UAV again.
    #[test]
    fn placed_uavs_are_measured_where_reported_and_a_quiet_one_is_not_heard() {
        let mut w = world();
        let at = [[1600.0, 450.0], [10100.0, 1500.0], [5000.0, 8700.0]];
        w.place(&at, &[0.1, 0.2, 0.3], 0b010).unwrap();
        let m = w.measure().unwrap();
        assert_eq!(m.uavs.iter().map(|p| [p.x, p.y]).collect::<Vec<_>>(), at);
        assert_eq!(m.arrivals.heard_mask(), 0b101, "UAV 1's link is quiet");
        let before = w.clone();
        assert!(w.place(&at[..2], &[0.0, 0.0], 0).is_err());
        assert!(w.place(&[[f64::NAN, 0.0], at[1], at[2]], &[0.0; 3], 0).is_err());
        assert_eq!(w, before, "refused: unchanged");
        w.apply(&[0.1, 0.2, 0.3]).unwrap();
        assert_eq!(w.measure().unwrap().arrivals.heard_mask(), 0b111);
    }
}
