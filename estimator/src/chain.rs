//! The estimator as a function of the messages it receives: the chain of states from step to step.
//!
//! The estimate of step k depends on the state after step k − 1 (the fused posterior, or the previous
//! estimate as the prior that resolves Chan's two-root ambiguity). [`StepEstimator`] keeps no file and no
//! answer: it continues its own chain (step k right after step k − 1, or step 0, which starts a new run),
//! and for any other step it takes the state after k − 1 from the messages ([`runtime::recovery`]): every
//! command echoes the state of the estimate it was planned from ([`protocol::StateEcho`]), and the monitor
//! sends the ones asked for. A step seen again — a replay for a restarted monitor, a world rewound to an
//! older emitter-sim snapshot — is estimated again from the state before it, bit for bit the estimate it
//! had ([`Answer::Again`]). A step whose predecessor's state is not known is held ([`Answer::OutOfChain`],
//! at most [`MAX_HELD`]) until it is ([`StepEstimator::wanted`], [`StepEstimator::release`]).
//!
//! Also the wire form of the library's output ([`estimate_measurement`], [`reply_of`]) and of the fused
//! posterior ([`extra_of`], [`posterior_of`]), which `uavloc simulate` and `uavloc replay` share with the
//! process. Pure functions over plain data: no IPC.

use std::collections::BTreeMap;

use nalgebra::{Matrix4, Vector4};
use protocol::{
    EchoedState, Estimate, Fix, HeldBurst, HeldBursts, Measurement, PosteriorExtra, StateEcho, TrackWindow, WindowBurst,
};
use runtime::recovery::StateStore;
use tdoa::consider::BiasSensitivity;
use tdoa::{Arrivals, Posterior};

use estimation::{DropStreak, EmitterModel, EstimateStatus, Estimator, EstimatorConfig, PendingRoot, TrackCounters};

/// The wire form of the fused posterior beyond the position, with its bias sensitivity `sensitivity`,
/// the pending second root `alternative` and the track's window `window`.
pub fn extra_of(
    posterior: Option<&Posterior>,
    sensitivity: Option<&BiasSensitivity>,
    alternative: Option<&PendingRoot>,
    track: TrackCounters,
    window: Option<&estimation::window::Window>,
) -> PosteriorExtra {
    let Some(p) = posterior else { return PosteriorExtra::default() };
    let mut extra = PosteriorExtra {
        estimator: 1,
        model: p.model().code(),
        rejected_run: track.rejected_run,
        confirmed: track.confirmed,
        drop_uavs: track.drop_streak.uavs,
        drop_run: track.drop_streak.run,
        window: window_of(window),
        ..PosteriorExtra::default()
    };
    if let Some(s) = sensitivity {
        extra.bias_sensitivity = s.rows();
    }
    if let Some((alt, s)) = alternative {
        let (m, c) = (alt.mean(), alt.cov());
        extra.alternative = 1;
        extra.alt_mean = [m[0], m[1], m[2], m[3]];
        extra.alt_cov = std::array::from_fn(|i| std::array::from_fn(|j| c[(i, j)]));
        extra.alt_bias_sensitivity = s.map_or([[0.0; protocol::MAX_UAVS]; 4], |s| s.rows());
    }
    if p.model() == EmitterModel::ConstantVelocity {
        let (m, c) = (p.mean(), p.cov());
        extra.velocity = [m[2], m[3]];
        extra.cross_cov = [[c[(0, 2)], c[(0, 3)]], [c[(1, 2)], c[(1, 3)]]];
        extra.velocity_cov = [[c[(2, 2)], c[(2, 3)]], [c[(3, 2)], c[(3, 3)]]];
    }
    extra
}

/// The fused posterior of a usable estimate (`position`, `covariance`, `extra`); `None` for a snapshot
/// estimate or numbers that do not form a posterior.
pub fn posterior_of(position: &[f64; 2], covariance: &[[f64; 2]; 2], extra: &PosteriorExtra) -> Option<Posterior> {
    if extra.estimator != 1 {
        return None;
    }
    let model = EmitterModel::from_code(extra.model)?;
    let mean = Vector4::new(position[0], position[1], extra.velocity[0], extra.velocity[1]);
    let (c, x, v) = (covariance, extra.cross_cov, extra.velocity_cov);
    let cov = Matrix4::new(
        c[0][0], c[0][1], x[0][0], x[0][1], //
        c[1][0], c[1][1], x[1][0], x[1][1], //
        x[0][0], x[1][0], v[0][0], v[0][1], //
        x[0][1], x[1][1], v[1][0], v[1][1],
    );
    Posterior::new(model, mean, cov).ok()
}

/// The pending second root an estimate carries (`alternative` = 1), `None` otherwise or for numbers that
/// do not form a posterior.
pub fn pending_of(extra: &PosteriorExtra) -> Option<PendingRoot> {
    if extra.estimator != 1 || extra.alternative != 1 {
        return None;
    }
    let model = EmitterModel::from_code(extra.model)?;
    let mean = Vector4::from(extra.alt_mean);
    let cov = Matrix4::from_fn(|i, j| extra.alt_cov[i][j]);
    let posterior = Posterior::new(model, mean, cov).ok()?;
    let zero = [[0.0; protocol::MAX_UAVS]; 4];
    let s = (extra.alt_bias_sensitivity != zero)
        .then(|| BiasSensitivity::from_rows(&extra.alt_bias_sensitivity).ok())
        .flatten();
    Some((posterior, s))
}

/// Measurements held for the state before them (the newest are kept beyond).
pub const MAX_HELD: usize = 64;

/// Where the estimator's chain is: the library estimator and the last step it estimated.
#[derive(Debug, Default)]
struct Chain {
    estimator: Estimator,
    last_step: Option<u64>,
}

impl Chain {
    /// A fresh estimator of `config`, before any step.
    fn fresh(config: EstimatorConfig) -> Self {
        Self { estimator: Estimator::with_config(config), last_step: None }
    }

    /// The chain of an estimator of `config` after `step`, as `state` says it was.
    fn from_echo(config: EstimatorConfig, state: &EchoedState) -> Self {
        match *state {
            EchoedState::State { step, estimate: (position, covariance), extra } => {
                let (z, m) = tdoa::estimate_from_arrays(&position, &covariance);
                let posterior = posterior_of(&position, &covariance, &extra);
                // A sensitivity that is not finite was refused with its message; all zeros is none yet.
                let sensitivity =
                    (extra.estimator == 1).then(|| BiasSensitivity::from_rows(&extra.bias_sensitivity).ok()).flatten();
                let estimator = Estimator::resume(config, step, z, m, posterior)
                    .with_track(TrackCounters {
                        rejected_run: extra.rejected_run,
                        confirmed: extra.confirmed,
                        drop_streak: DropStreak { uavs: extra.drop_uavs, run: extra.drop_run },
                    })
                    .with_sensitivity(sensitivity)
                    .with_alternative(pending_of(&extra))
                    .with_window(library_window(&extra.window));
                Self { estimator, last_step: Some(step) }
            }
            EchoedState::Empty { step, held } => Self {
                estimator: Estimator::with_config(config).with_held(&library_held(&held)),
                last_step: Some(step),
            },
        }
    }
}

/// An estimator of `config` taking over from `estimate` (a usable one): the next step it estimates is the
/// one after it, from the posterior the estimate carries — what `uavloc swap estimator` does.
pub fn resumed(config: EstimatorConfig, estimate: &protocol::Estimate) -> Estimator {
    let extra = estimate.extra();
    let state =
        EchoedState::State { step: estimate.header.step, estimate: (estimate.position, estimate.covariance), extra };
    Chain::from_echo(config, &state).estimator
}

/// A measurement held until the state before it is known, with the time it was received.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Held {
    /// The measurement.
    pub measurement: Measurement,
    /// When it was received ([`protocol::now_ns`]).
    pub received_ns: u64,
}

/// The estimator's per-run state: its chain, the states after earlier steps that the messages carried
/// (each command echoes the state it was planned from, [`protocol::StateEcho`]; the monitor sends the ones
/// asked for), and the measurements held for a state not yet known. A step seen again — a replay, or a
/// world rewound to an older snapshot — is estimated again from the state before it, giving the same
/// estimate bit for bit. No answer is kept.
#[derive(Debug, Default)]
pub struct StepEstimator {
    config: EstimatorConfig,
    chain: Chain,
    states: StateStore,
    held: BTreeMap<u64, Held>,
    /// The highest step estimated (a step at or below it is estimated again).
    highest: Option<u64>,
}

/// The estimate of one step as it goes on the wire: the fix, the fused state beyond the position, and
/// for a failed fix the standing estimate (the last usable one, what the step is planned from).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reply {
    /// The fix of this step.
    pub fix: Fix,
    /// The fused posterior beyond the position.
    pub extra: PosteriorExtra,
    /// Failed: the standing estimate (position, covariance), if any.
    pub standing: Option<([f64; 2], [[f64; 2]; 2])>,
    /// The arrivals dropped as outliers (bit i: UAV i).
    pub outliers: u8,
    /// The persistent errors' consider covariance at the estimate, m².
    pub bias_cov: [[f64; 2]; 2],
    /// Before the first fix: the two-arrival bursts the estimator holds for it.
    pub held: HeldBursts,
}

impl Reply {
    /// The wire estimate of measurement `m` with this answer (received at `received_ns`, sequence number
    /// `seq`, from estimator instance `instance`): the fix, the fused state and the standing estimate.
    pub fn to_estimate(
        &self,
        m: &Measurement,
        received_ns: u64,
        seq: u64,
        instance: u64,
    ) -> Result<Estimate, protocol::ProtocolError> {
        Ok(Estimate::from_measurement(m, received_ns, seq, instance, self.fix)?
            .with_extra(&self.extra)
            .with_standing(self.standing)
            .with_receiver(self.outliers, self.bias_cov)
            .with_held(self.held))
    }
}

/// What [`StepEstimator::handle`] did with a measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Answer {
    /// A step estimated for the first time.
    New(Reply),
    /// A step estimated again (a replay, a rewound world), from the state before it.
    Again(Reply),
    /// Not estimated yet: the state after the step before it is not known; the measurement is held
    /// until it is (see [`StepEstimator::wanted`]).
    OutOfChain,
}

impl StepEstimator {
    /// A fresh state of a snapshot estimator.
    pub fn new() -> Self {
        Self::default()
    }

    /// A fresh state of an estimator of `config`.
    pub fn with_config(config: EstimatorConfig) -> Self {
        Self { config, chain: Chain::fresh(config), ..Self::default() }
    }

    /// The state of an estimator of `config` whose estimate of `step` was `position` with `covariance`
    /// and the fused state `extra` (taking over from it): the next step it estimates is `step + 1`.
    pub fn resume(
        config: EstimatorConfig,
        step: u64,
        position: [f64; 2],
        covariance: [[f64; 2]; 2],
        extra: &PosteriorExtra,
    ) -> Self {
        let state = EchoedState::State { step, estimate: (position, covariance), extra: *extra };
        Self { config, chain: Chain::from_echo(config, &state), highest: Some(step), ..Self::default() }
    }

    /// The last step estimated.
    pub fn last_step(&self) -> Option<u64> {
        self.chain.last_step
    }

    /// Keeps a state a message carried (a command's echo, the monitor's answer; the first one per step).
    pub fn remember(&mut self, state: StateEcho) {
        self.states.keep(state);
    }

    /// The step whose state the oldest held measurement waits for (to ask for it), if any.
    pub fn wanted(&self) -> Option<u64> {
        self.held.keys().next().map(|&k| k - 1)
    }

    /// The answer to a (validated) measurement received at `received_ns`; see the module docs. An
    /// out-of-chain measurement is held.
    pub fn handle(&mut self, m: &Measurement, received_ns: u64) -> Answer {
        let step = m.header.step;
        let again = self.highest.is_some_and(|h| step <= h);
        if step == 0 {
            // A new run (or the run replayed from its start).
            self.chain = Chain::fresh(self.config);
        } else if self.chain.last_step != Some(step - 1) {
            match self.states.get(step - 1) {
                Some(state) => self.chain = Chain::from_echo(self.config, &state),
                None => {
                    self.held.insert(step, Held { measurement: *m, received_ns });
                    while self.held.len() > MAX_HELD {
                        self.held.pop_first();
                    }
                    return Answer::OutOfChain;
                }
            }
        }
        self.held.remove(&step);
        let reply = estimate_measurement(&mut self.chain.estimator, m);
        self.chain.last_step = Some(step);
        self.highest = self.highest.max(Some(step));
        if again { Answer::Again(reply) } else { Answer::New(reply) }
    }

    /// The held measurements whose predecessor's state is known now, estimated in step order (each with
    /// its answer); the others stay held.
    pub fn release(&mut self) -> Vec<(Held, Answer)> {
        let mut out = Vec::new();
        let steps: Vec<u64> = self.held.keys().copied().collect();
        for step in steps {
            let known = self.chain.last_step == Some(step - 1) || self.states.get(step - 1).is_some();
            if let Some(h) = known.then(|| self.held.remove(&step)).flatten() {
                let answer = self.handle(&h.measurement, h.received_ns);
                out.push((h, answer));
            }
        }
        out
    }
}

/// The estimate of one measurement as it goes on the wire (`Fix::Failed` when the step could not be
/// estimated; it then carries the standing estimate the library keeps, if any).
pub fn estimate_measurement(estimator: &mut Estimator, m: &Measurement) -> Reply {
    let outcome = match arrivals_of(m) {
        Ok(a) => estimator.estimate_burst(m.header.step, &a).ok(),
        Err(_) => None,
    };
    match outcome {
        Some(out) => reply_of(&out),
        // The standing estimate and the posterior beyond it: the state the next step goes on from.
        None => Reply {
            fix: Fix::Failed,
            extra: extra_of(
                estimator.posterior().as_ref(),
                estimator.sensitivity().as_ref(),
                estimator.alternative().as_ref(),
                estimator.track(),
                estimator.window(),
            ),
            standing: estimator.previous().map(|(p, c)| tdoa::estimate_to_arrays(&p, &c)),
            outliers: 0,
            bias_cov: [[0.0; 2]; 2],
            held: held_of(estimator.held()),
        },
    }
}

/// The burst a measurement carries, with the stated σ of each arrival (range noise, GNSS and clock,
/// see [`Measurement::stated_sigmas`]).
pub fn arrivals_of(m: &Measurement) -> Result<Arrivals, tdoa::TdoaError> {
    let (sigmas, bias) = m.stated_sigmas();
    Arrivals::new(m.uavs(), m.arrivals(), m.heard, &sigmas, &bias)
}

/// The wire form of the library estimator's output.
pub fn reply_of(out: &estimation::EstimateOut) -> Reply {
    let (position, covariance) = tdoa::estimate_to_arrays(&out.position, &out.covariance);
    let extra = extra_of(
        out.posterior.as_ref(),
        out.sensitivity.as_ref(),
        out.alternative.as_ref(),
        out.track,
        out.window.as_ref(),
    );
    let fix = match out.status {
        EstimateStatus::Ok => Fix::Ok { position, covariance },
        EstimateStatus::Ambiguous => Fix::Ambiguous { position, covariance },
        EstimateStatus::Rejected { .. } => Fix::Rejected { position, covariance },
        EstimateStatus::Predicted => Fix::Predicted { position, covariance },
        EstimateStatus::Failed { .. } => {
            // The library returned its previous estimate: the standing one.
            return Reply {
                fix: Fix::Failed,
                extra,
                standing: Some((position, covariance)),
                outliers: 0,
                bias_cov: [[0.0; 2]; 2],
                held: held_of(&out.held),
            };
        }
    };
    Reply {
        fix,
        extra,
        standing: None,
        outliers: out.outliers,
        bias_cov: tdoa::matrix_to_rows(&out.bias_cov),
        held: held_of(&out.held),
    }
}

// The wire holds as many bursts as the estimator keeps.
const _: () = assert!(protocol::MAX_HELD_BURSTS == estimation::MAX_HELD_BURSTS);
const _: () = assert!(protocol::MAX_WINDOW_BURSTS == estimation::window::WINDOW_BURSTS);

/// The wire form of a track's window (`open` 0 for none).
pub fn window_of(window: Option<&estimation::window::Window>) -> TrackWindow {
    let Some(w) = window else { return TrackWindow::default() };
    let (base_vector, base_matrix) = tdoa::estimate_to_arrays(&w.base.vector, &w.base.matrix);
    let mut wire = TrackWindow {
        open: 1,
        count: w.bursts.len().min(protocol::MAX_WINDOW_BURSTS) as u8,
        base_matrix,
        base_vector,
        ..TrackWindow::default()
    };
    for (slot, (step, a)) in wire.bursts.iter_mut().zip(&w.bursts) {
        let n = a.len();
        *slot = WindowBurst { step: *step, count: n as u8, heard: a.heard_mask(), ..WindowBurst::default() };
        for i in 0..n {
            slot.positions[i] = [a.positions()[i].x, a.positions()[i].y];
            slot.arrivals[i] = a.arrival(i).unwrap_or(0.0);
            slot.sigmas[i] = a.sigmas()[i];
            slot.bias_sigmas[i] = a.bias_sigmas()[i];
        }
    }
    wire
}

/// The library form of a track's window (as [`window_of`] wrote it; `None` when not open, a burst
/// that does not form arrivals is left out — validation refuses such a message before it gets here).
pub fn library_window(wire: &TrackWindow) -> Option<estimation::window::Window> {
    if wire.open != 1 {
        return None;
    }
    let bursts = wire
        .as_slice()
        .iter()
        .filter_map(|b| {
            let n = usize::from(b.count);
            let a = Arrivals::new(
                b.positions.get(..n)?,
                b.arrivals.get(..n)?,
                b.heard,
                b.sigmas.get(..n)?,
                b.bias_sigmas.get(..n)?,
            );
            a.ok().map(|a| (b.step, a))
        })
        .collect();
    let (vector, matrix) = tdoa::estimate_from_arrays(&wire.base_vector, &wire.base_matrix);
    Some(estimation::window::Window { base: tdoa::window::Information { matrix, vector }, bursts })
}

/// The wire form of the two-arrival bursts an estimator holds for its first fix (a burst not heard by
/// exactly two UAVs is not one it holds, and is left out).
pub fn held_of(held: &[estimation::HeldBurst]) -> HeldBursts {
    let wire: Vec<HeldBurst> = held
        .iter()
        .filter_map(|(step, a)| {
            let uavs: Vec<usize> = (0..a.len()).filter(|&i| a.arrival(i).is_some()).collect();
            let [i, j] = uavs[..] else { return None };
            let (p, s, b) = (a.positions(), a.sigmas(), a.bias_sigmas());
            Some(HeldBurst {
                step: *step,
                count: a.len() as u8,
                uavs: [i as u8, j as u8],
                reserved: [0; 5],
                positions: [[p[i].x, p[i].y], [p[j].x, p[j].y]],
                arrival_diff: a.arrival(j)? - a.arrival(i)?,
                sigmas: [s[i], s[j]],
                bias_sigmas: [b[i], b[j]],
            })
        })
        .collect();
    HeldBursts::new(&wire)
}

/// The library form of held bursts (as [`held_of`] wrote them; a burst that does not form arrivals is
/// left out — validation refuses such a message before it gets here). The UAVs that did not hear a
/// burst get placeholder geometry that nothing reads.
pub fn library_held(held: &HeldBursts) -> Vec<estimation::HeldBurst> {
    held.as_slice()
        .iter()
        .filter_map(|b| {
            let n = usize::from(b.count);
            let [i, j] = b.uavs.map(usize::from);
            if i >= j || j >= n {
                return None;
            }
            let mut positions = vec![[0.0; 2]; n];
            let mut arrivals = vec![0.0; n];
            let mut sigmas = vec![1.0; n];
            let mut bias = vec![0.0; n];
            positions[i] = b.positions[0];
            positions[j] = b.positions[1];
            arrivals[j] = b.arrival_diff;
            sigmas[i] = b.sigmas[0];
            sigmas[j] = b.sigmas[1];
            bias[i] = b.bias_sigmas[0];
            bias[j] = b.bias_sigmas[1];
            let mask = tdoa::arrivals::bit(i) | tdoa::arrivals::bit(j);
            Arrivals::new(&positions, &arrivals, mask, &sigmas, &bias).ok().map(|a| (b.step, a))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector2;
    use tdoa::Dynamics;

    use super::*;
    use estimation::EstimatorKind;

    /// What the wire accepts is what the maths takes: the protocol's bounds (it depends on no maths crate)
    /// are tdoa's, so that no accepted measurement fails the estimator or the planner at every replay.
    #[test]
    fn the_wire_bounds_are_the_maths_bounds() {
        use protocol::validate::{MAX_SIGMA_M, MIN_SIGMA_M, SWARM_EXTENT_M};
        assert_eq!(SWARM_EXTENT_M, tdoa::MAX_EXTENT_M);
        assert_eq!(MAX_SIGMA_M, tdoa::MAX_EXTENT_M);
        assert_eq!(MIN_SIGMA_M, tdoa::MIN_SIGMA_M);
        assert_eq!(protocol::MAX_UAVS, tdoa::MAX_UAVS);
        // A measurement's stated σ is the one the maths computes from its parts, bit for bit.
        let m = measurement(1).with_sensor_errors([3.0, 1.5], [10.0, 2.0]);
        let e = tdoa::SensorErrors {
            gnss_m: 3.0,
            gnss_bias_m: 1.5,
            clock_m: 10.0 * (tdoa::SPEED_OF_LIGHT * 1e-9),
            clock_bias_m: 2.0 * (tdoa::SPEED_OF_LIGHT * 1e-9),
        };
        assert_eq!(m.stated_sigmas().0[0].to_bits(), e.effective_sigma(28.7712).to_bits());
        // An estimate's covariance passes the wire exactly when the planner can take it, over the
        // floats' whole range of variances and correlations.
        assert_eq!(protocol::validate::MIN_EIGENVALUE_M2, tdoa::support::MIN_EIGENVALUE_M2);
        let mut taken = 0;
        for ea in (-310..=308).step_by(7) {
            for ed in (-310..=308).step_by(9) {
                for rho in [-0.999_999_99, -0.9, 0.0, 0.4, 0.999_999_99, 1.0] {
                    let (a, d) = (10f64.powi(ea), 10f64.powi(ed));
                    let b = rho * a.sqrt() * d.sqrt();
                    let wire = protocol::validate::is_symmetric_positive_definite(&[[a, b], [b, d]]);
                    let m = nalgebra::Matrix2::new(a, b, b, d);
                    assert_eq!(wire, tdoa::support::is_positive_definite(&m), "{m:?}");
                    let planned = tdoa::Uncertainty::new(Vector2::zeros(), m, 1.0).is_ok();
                    assert_eq!(wire, planned, "{m:?}");
                    taken += usize::from(wire);
                }
            }
        }
        assert!(taken > 10_000, "{taken}");
    }

    /// Noisy-free measurements of a fixed emitter by three UAVs flying east, one per step.
    fn measurement(step: u64) -> Measurement {
        let z = Vector2::new(25_000.0, 15_000.0);
        let t = step as f64 * 500.0;
        let uavs = [[1500.0 + t, 500.0], [10_000.0 + t, 1500.0], [5000.0 + t, 8500.0]];
        let r = |p: [f64; 2]| (Vector2::new(p[0], p[1]) - z).norm();
        // A small deterministic "noise" so that the prior matters and the estimates differ per step.
        let e = |i: u64| ((step * 7 + i * 3) % 11) as f64 - 5.0;
        let diffs = [r(uavs[1]) - r(uavs[0]) + e(1), r(uavs[2]) - r(uavs[0]) + e(2)];
        Measurement::new(step, step + 1, &uavs, &diffs, &[28.7712; 3], &[0.0; 3]).unwrap()
    }

    /// Step `step` of [`measurement`]'s world heard by the UAVs of `mask` only.
    fn partial(step: u64, mask: u8) -> Measurement {
        let full = measurement(step);
        Measurement::heard(step, step + 1, full.uavs(), mask, full.arrivals(), &[28.7712; 3], &[0.0; 3]).unwrap()
    }

    #[test]
    fn an_estimator_restarted_before_its_first_fix_goes_on_from_the_bursts_the_echo_holds() {
        // Three two-arrival bursts, then complete ones: the first fix (step 3) folds the three in.
        let masks = [0b011u8, 0b110, 0b101, 0b111, 0b111, 0b011, 0b111];
        let m = |k: usize| if masks[k] == 0b111 { measurement(k as u64) } else { partial(k as u64, masks[k]) };
        let cv = Dynamics::new(EmitterModel::ConstantVelocity, 10.0, 0.05, 20.0).unwrap();
        for config in [EstimatorConfig::fused(Dynamics::fixed()), EstimatorConfig::fused(cv)] {
            let mut straight = StepEstimator::with_config(config);
            let mut replies = Vec::new();
            let mut echoes = Vec::new();
            for k in 0..masks.len() {
                let r = reply(straight.handle(&m(k), k as u64));
                let estimate = r.to_estimate(&m(k), 0, k as u64 + 1, 1).unwrap();
                estimate.validate(None).unwrap();
                let echo = protocol::StateEcho::of(&estimate).unwrap();
                echo.validate().unwrap();
                echoes.push(echo);
                replies.push(r);
            }
            assert_eq!(replies[2].held.count, 3, "three bursts held before the fix");
            assert_eq!(replies[3].held.count, 0, "folded into the first fix");
            assert!(matches!(replies[3].fix, Fix::Ok { .. } | Fix::Ambiguous { .. }));
            // A fresh estimator (no file) given the echo of step 2: every later estimate bit for bit.
            for after in 0..3 {
                let mut restarted = StepEstimator::with_config(config);
                assert_eq!(restarted.handle(&m(after + 1), 99), Answer::OutOfChain);
                restarted.remember(echoes[after]);
                assert_eq!(reply(restarted.release()[0].1), replies[after + 1], "{config:?} restart after {after}");
                for (k, expected) in replies.iter().enumerate().skip(after + 2) {
                    assert_eq!(reply(restarted.handle(&m(k), k as u64)), *expected, "{config:?} step {k}");
                }
            }
        }
    }

    #[test]
    fn steps_seen_again_are_estimated_again_from_the_states_the_messages_carry() {
        let cv = Dynamics::new(EmitterModel::ConstantVelocity, 10.0, 0.05, 20.0).unwrap();
        for config in
            [EstimatorConfig::snapshot(), EstimatorConfig::fused(Dynamics::fixed()), EstimatorConfig::fused(cv)]
        {
            echo_case(config);
        }
    }

    fn reply(a: Answer) -> Reply {
        match a {
            Answer::New(r) | Answer::Again(r) => r,
            Answer::OutOfChain => panic!("out of chain"),
        }
    }

    /// Replays, restarts and rewinds of one estimator configuration give the undisturbed estimates bit for
    /// bit, with no answer and no file kept: every step seen again is estimated again from the state before
    /// it, which a command echoed or the monitor sent (fused: the posterior, velocity block included).
    fn echo_case(config: EstimatorConfig) {
        let label = format!("{:?}", config.kind);
        let mut straight = StepEstimator::with_config(config);
        let (mut reference, mut echoes) = (Vec::new(), Vec::new());
        for k in 0..=12 {
            let answer = straight.handle(&measurement(k), k);
            assert!(matches!(answer, Answer::New(..)), "{label} step {k}");
            let r = reply(answer);
            if config.kind == EstimatorKind::Fused && k > 0 {
                assert_eq!(r.extra.estimator, 1, "{label} step {k}");
            }
            // What the planner's command of step k echoes.
            let estimate = r.to_estimate(&measurement(k), 0, k + 1, 1).unwrap();
            echoes.push(protocol::StateEcho::of(&estimate).unwrap());
            reference.push(r);
        }

        // A replay of steps 5..=12 to an estimator that saw every command: the same estimates again.
        let mut live = StepEstimator::with_config(config);
        for k in 0..=12 {
            live.handle(&measurement(k), k);
            live.remember(echoes[k as usize]);
        }
        for k in 5..=12 {
            let answer = live.handle(&measurement(k), k);
            assert!(matches!(answer, Answer::Again(..)), "{label} step {k}");
            assert_eq!(reply(answer), reference[k as usize], "{label} step {k} replayed");
        }
        assert_eq!(live.wanted(), None);

        // Restarted (a fresh state, no file): the step in flight is held until the state before it comes.
        let mut restarted = StepEstimator::with_config(config);
        assert_eq!(restarted.handle(&measurement(8), 80), Answer::OutOfChain, "{label}");
        assert_eq!(restarted.handle(&measurement(9), 90), Answer::OutOfChain, "{label}");
        assert_eq!(restarted.wanted(), Some(7));
        assert!(restarted.release().is_empty(), "{label}: nothing known yet");
        restarted.remember(echoes[7]);
        let released = restarted.release();
        assert_eq!(
            released.iter().map(|(h, _)| (h.measurement.header.step, h.received_ns)).collect::<Vec<_>>(),
            vec![(8, 80), (9, 90)]
        );
        for (h, answer) in released {
            let k = h.measurement.header.step;
            assert_eq!(reply(answer), reference[k as usize], "{label} step {k} after the restart");
        }
        assert_eq!(restarted.wanted(), None);
        // … then the world rewound to step 4 (an older emitter-sim snapshot, before anything this instance
        // saw): held until the monitor sends the state after step 3, then every estimate as the
        // undisturbed one past step 12.
        assert_eq!(restarted.handle(&measurement(4), 4), Answer::OutOfChain, "{label}");
        assert_eq!(restarted.wanted(), Some(3));
        restarted.remember(echoes[3]);
        assert_eq!(reply(restarted.release()[0].1), reference[4], "{label} step 4 rewound");
        for k in 5..=12 {
            assert_eq!(reply(restarted.handle(&measurement(k), k)), reference[k as usize], "{label} step {k} rewound");
        }
        assert_eq!(restarted.last_step(), Some(12));

        // Held measurements are bounded: the newest are kept.
        let mut bare = StepEstimator::with_config(config);
        for k in 1..=MAX_HELD as u64 + 10 {
            assert_eq!(bare.handle(&measurement(100 + 2 * k), k), Answer::OutOfChain);
        }
        assert_eq!(bare.wanted(), Some(100 + 2 * 11 - 1));
    }

    /// A receiver's step `step` of four UAVs flying north-east: silent steps, lost arrivals, a late
    /// (reflected) arrival, GNSS and clock errors stated per step and for the flight.
    fn impaired(step: u64) -> Measurement {
        let z = Vector2::new(25_000.0, 15_000.0);
        let t = step as f64 * 400.0;
        let uavs = [[1500.0 + t, 500.0 + t], [10_000.0 + t, 1500.0], [5000.0, 8500.0 + t], [-3000.0 + t, 4000.0]];
        let headings = [0.8, 0.0, 1.5, 0.0];
        let sigmas = [28.7712; 4];
        if step % 7 == 3 {
            return Measurement::silent(step, step + 1, &uavs, &sigmas, &headings).unwrap();
        }
        let e = |i: u64| ((step * 7 + i * 3) % 11) as f64 * 6.0 - 30.0;
        let mut arrivals: Vec<f64> =
            (0..4).map(|i| (Vector2::new(uavs[i][0], uavs[i][1]) - z).norm() + e(i as u64)).collect();
        if step % 5 == 2 {
            arrivals[(step as usize / 5) % 4] += 600.0; // a reflection
        }
        let heard = if step.is_multiple_of(3) { 0b1111 & !(1u8 << (step % 4)) } else { 0b1111 };
        Measurement::heard(step, step + 1, &uavs, heard, &arrivals, &sigmas, &headings)
            .unwrap()
            .with_sensor_errors([5.0, 2.0], [10.0, 3.0])
    }

    /// Three UAVs whose first burst has two physical roots (Chan is ambiguous), then silent and heard
    /// steps as the swarm flies on: `(the emitter, the measurement of step k)`.
    fn ambiguous_run() -> (Vector2<f64>, impl Fn(u64) -> Measurement) {
        let at = |step: u64| {
            let t = step as f64;
            [[300.0 * t, 100.0 * t], [4000.0 + 300.0 * t, 100.0 * t], [300.0 * t, 4000.0 + 100.0 * t]]
        };
        let r = |p: [f64; 2], z: Vector2<f64>| (Vector2::new(p[0], p[1]) - z).norm();
        let uavs0 = at(0);
        let sensors = tdoa::Sensors::new(&uavs0, tdoa::NoiseModel::uniform(3, 28.7712).unwrap()).unwrap();
        let z = (-20..=20)
            .flat_map(|i| (-20..=20).map(move |j| Vector2::new(1000.0 * i as f64 + 137.0, 1000.0 * j as f64 + 71.0)))
            .find(|z| {
                let d = sensors.range_differences(z);
                tdoa::chan(&sensors, &d, None).is_ok_and(|sol| {
                    sol.ambiguous
                        && sol.candidates.len() == 2
                        && (sol.candidates[0] - sol.candidates[1]).norm() > 1000.0
                })
            })
            .expect("an ambiguous geometry");
        let measure = move |step: u64| {
            let uavs = at(step);
            if step % 4 == 1 {
                return Measurement::silent(step, step + 1, &uavs, &[28.7712; 3], &[0.3; 3]).unwrap();
            }
            let e = |i: u64| ((step * 5 + i * 3) % 7) as f64 * 4.0 - 12.0;
            let diffs = [r(uavs[1], z) - r(uavs[0], z) + e(1), r(uavs[2], z) - r(uavs[0], z) + e(2)];
            Measurement::new(step, step + 1, &uavs, &diffs, &[28.7712; 3], &[0.3; 3]).unwrap()
        };
        (z, measure)
    }

    /// An estimator restarted after any step of `measure(0..=last)`, told only the state the command of
    /// that step echoed, gives every later estimate bit for bit as the undisturbed one; returns the
    /// undisturbed replies.
    fn restarts_continue(config: EstimatorConfig, measure: &dyn Fn(u64) -> Measurement, last: u64) -> Vec<Reply> {
        let mut straight = StepEstimator::with_config(config);
        let (mut reference, mut echoes) = (Vec::new(), Vec::new());
        for k in 0..=last {
            let r = reply(straight.handle(&measure(k), k));
            echoes.push(protocol::StateEcho::of(&r.to_estimate(&measure(k), 0, k + 1, 1).unwrap()).unwrap());
            reference.push(r);
        }
        for after in 0..last {
            let mut restarted = StepEstimator::with_config(config);
            restarted.remember(echoes[after as usize]);
            for k in after + 1..=last {
                let got = reply(restarted.handle(&measure(k), k));
                assert_eq!(got, reference[k as usize], "{:?}: restarted after {after}, step {k}", config.kind);
            }
        }
        reference
    }

    /// A restart between an ambiguous fix and the burst that decides between its two roots goes on from
    /// both: the pending root travels in the messages.
    #[test]
    fn a_restart_while_a_second_root_is_pending_continues_bit_for_bit() {
        let (_, measure) = ambiguous_run();
        let cv = Dynamics::new(EmitterModel::ConstantVelocity, 10.0, 0.05, 20.0).unwrap();
        for config in [EstimatorConfig::fused(Dynamics::fixed()), EstimatorConfig::fused(cv)] {
            let reference = restarts_continue(config, &measure, 12);
            assert!(matches!(reference[0].fix, Fix::Ambiguous { .. }), "{:?}", reference[0].fix);
            assert_eq!(reference[0].extra.alternative, 1, "the second root is pending after step 0");
        }
    }

    /// With every receiver impairment, an estimator restarted after any step — told only the state the
    /// command of that step echoed — gives every later estimate bit for bit as the undisturbed one: the
    /// posterior, the track's confirmation, the bias sensitivity, a pending second root and the track's
    /// window all travel in the messages.
    #[test]
    fn a_restart_after_any_step_of_an_impaired_receiver_continues_bit_for_bit() {
        let cv = Dynamics::new(EmitterModel::ConstantVelocity, 10.0, 0.05, 20.0).unwrap();
        for config in [EstimatorConfig::fused(Dynamics::fixed()), EstimatorConfig::fused(cv)] {
            let reference = restarts_continue(config, &impaired, 30);
            assert!(reference.iter().any(|r| r.extra.bias_sensitivity != [[0.0; protocol::MAX_UAVS]; 4]));
            // A static emitter's track re-linearises a full window of raw bursts: it travels too.
            let full = reference.iter().any(|r| usize::from(r.extra.window.count) == protocol::MAX_WINDOW_BURSTS);
            assert_eq!(full, config.dynamics.model() == EmitterModel::Static);
            assert!(reference.iter().any(|r| r.bias_cov != [[0.0; 2]; 2]));
        }
    }
}
