//! The information a burst is expected to bring when each UAV's arrival may be lost and the emitter
//! may be silent: what a planner ranks candidate geometries by on a real receiver.
//!
//! ## The information of any subset of arrivals
//! UAV i's arrival, as a range with the burst's unknown epoch, is `a_i = r_i + τ + n_i` with
//! `n_i ~ N(0, s_i²)` independent ([`crate::arrivals`]). The differences to any reference of a subset
//! `S` of the UAVs are eq. 19's model for `S`, and eliminating the nuisance `τ` gives the same
//! information (Schur complement of `τ` in the information of `(z, τ)`):
//!
//! ```text
//! F_S = Σ_{i∈S} w_i u_i u_iᵀ − b_S b_Sᵀ / W_S,   w_i = 1/s_i²,  b_S = Σ_{i∈S} w_i u_i,  W_S = Σ_{i∈S} w_i
//! ```
//!
//! (`u_i` the unit vector from UAV i to the emitter); `F_S = 0` for fewer than two arrivals. For `S` the
//! whole swarm this is eq. 48, `Jᵀ Q⁻¹ J` — the tests check it against [`crate::fim()`].
//!
//! ## The expected posterior
//! With arrival i kept with probability `p_i` independently and the emitter silent with probability
//! `q`, the posterior covariance after the step is `(P⁻¹ + F_S)⁻¹` for the subset `S` received (the
//! prior `P` alone when silent). Its expected trace, m²,
//!
//! ```text
//! E tr P⁺ = q tr P + (1 − q) Σ_S Π_{i∈S} p_i Π_{i∉S} (1 − p_i) tr (P⁻¹ + F_S)⁻¹
//! ```
//!
//! is summed exactly over the `2^N` subsets (256 for eight UAVs). It is finite for every loss, unlike
//! the expectation of the single-step CRLB `tr F_S⁻¹`, which is infinite as soon as fewer than three
//! arrivals have a positive probability: only a criterion with a prior can count lost arrivals.
//!
//! Units: metres, 1/m² (information), m² (traces).

use nalgebra::{Matrix2, Vector2};

use crate::{MAX_UAVS, Sensors, TdoaError};

/// The receiver's odds for one burst: per UAV the probability its arrival is received, and the
/// probability the emitter is silent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArrivalOdds {
    keep: [f64; MAX_UAVS],
    n: usize,
    silence: f64,
}

impl ArrivalOdds {
    /// `n` UAVs whose arrivals are each lost with probability `loss`, the emitter silent with probability
    /// `silence` (both in [0, 1]; a silence of 1 is refused: no burst ever, nothing to plan for).
    pub fn uniform(n: usize, loss: f64, silence: f64) -> Result<Self, TdoaError> {
        Self::new(&vec![1.0 - loss; n.min(MAX_UAVS + 1)], silence)
    }

    /// Per UAV the probability its arrival is received, and the probability the emitter is silent.
    pub fn new(keep: &[f64], silence: f64) -> Result<Self, TdoaError> {
        let n = keep.len();
        if !(2..=MAX_UAVS).contains(&n) {
            return Err(TdoaError::UavCount { got: n, min: 2, max: MAX_UAVS });
        }
        let mut k = [0.0; MAX_UAVS];
        for (i, &p) in keep.iter().enumerate() {
            if !(0.0..=1.0).contains(&p) {
                return Err(TdoaError::OutOfRange {
                    what: format!("the probability that UAV {i}'s arrival is received"),
                    value: p,
                    min: 0.0,
                    max: 1.0,
                });
            }
            k[i] = p;
        }
        if !(0.0..1.0).contains(&silence) {
            return Err(TdoaError::OutOfRange {
                what: "the probability the emitter is silent".into(),
                value: silence,
                min: 0.0,
                max: 1.0,
            });
        }
        Ok(Self { keep: k, n, silence })
    }

    /// Whether every arrival is received and the emitter never silent (the paper's receiver).
    pub fn is_perfect(&self) -> bool {
        self.silence == 0.0 && self.keep[..self.n].iter().all(|p| *p == 1.0)
    }

    /// Number of UAVs.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Always false: at least two UAVs.
    pub fn is_empty(&self) -> bool {
        false
    }
}

/// Unit vectors from the UAVs to `z` and the weights `1/s_i²`; `None` if `z` sits on a UAV.
fn rays(sensors: &Sensors, z: &Vector2<f64>) -> Option<([Vector2<f64>; MAX_UAVS], [f64; MAX_UAVS])> {
    let rays = crate::fim::Rays::new(sensors, z)?;
    let mut w = [0.0; MAX_UAVS];
    for (w, s) in w.iter_mut().zip(sensors.noise().sigmas()) {
        *w = 1.0 / (s * s);
    }
    Some((rays.u, w))
}

/// `F_S` of the subset `mask` (bit i: UAV i's arrival received), 1/m²; zero for fewer than two
/// arrivals, `None` if `z` sits on a UAV.
pub fn subset_fim(sensors: &Sensors, z: &Vector2<f64>, mask: u32) -> Option<Matrix2<f64>> {
    let (u, w) = rays(sensors, z)?;
    Some(fim_of(&u, &w, sensors.len(), mask))
}

fn fim_of(u: &[Vector2<f64>; MAX_UAVS], w: &[f64; MAX_UAVS], n: usize, mask: u32) -> Matrix2<f64> {
    if (mask & ((1u32 << n) - 1)).count_ones() < 2 {
        return Matrix2::zeros();
    }
    let mut a = Matrix2::zeros();
    let mut b = Vector2::zeros();
    let mut total = 0.0;
    for i in (0..n).filter(|i| mask & (1 << i) != 0) {
        a += w[i] * u[i] * u[i].transpose();
        b += w[i] * u[i];
        total += w[i];
    }
    let f = a - b * b.transpose() / total;
    0.5 * (f + f.transpose())
}

/// `E tr P⁺` (module docs) for the prior information `prior_info` (`P⁻¹`, 1/m², positive definite),
/// the UAVs `sensors` and the emitter at `z`, m². `None` if `z` sits on a UAV, the odds are for another
/// number of UAVs, or the prior is not positive definite.
pub fn expected_posterior_trace(
    prior_info: &Matrix2<f64>,
    sensors: &Sensors,
    z: &Vector2<f64>,
    odds: &ArrivalOdds,
) -> Option<f64> {
    let n = sensors.len();
    if odds.n != n {
        return None;
    }
    let prior_trace = crate::fim::inverse_spd(prior_info)?.trace();
    let (u, w) = rays(sensors, z)?;
    let mut heard = 0.0;
    for mask in 0..(1u32 << n) {
        let mut p = 1.0;
        for i in 0..n {
            p *= if mask & (1 << i) != 0 { odds.keep[i] } else { 1.0 - odds.keep[i] };
        }
        if p == 0.0 {
            continue;
        }
        let trace = if mask.count_ones() < 2 {
            prior_trace
        } else {
            crate::fim::inverse_spd(&(prior_info + fim_of(&u, &w, n, mask)))?.trace()
        };
        heard += p * trace;
    }
    Some(odds.silence * prior_trace + (1.0 - odds.silence) * heard)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::NoiseModel;
    use rand::{Rng, SeedableRng};

    fn swarm(n: usize) -> (Sensors, Vector2<f64>) {
        let uavs: Vec<[f64; 2]> =
            (0..n).map(|i| [1500.0 + 4000.0 * i as f64, 500.0 + 1800.0 * ((i * 7) % 5) as f64]).collect();
        let sigmas: Vec<f64> = (0..n).map(|i| 20.0 + 7.5 * i as f64).collect();
        (Sensors::new(&uavs, NoiseModel::from_range_sigmas(&sigmas).unwrap()).unwrap(), Vector2::new(25000.0, 15000.0))
    }

    fn prior() -> Matrix2<f64> {
        Matrix2::new(4e5, 1e5, 1e5, 2e5).try_inverse().unwrap()
    }

    /// The offset-eliminated form equals eq. 48's `Jᵀ Q⁻¹ J` for the whole swarm and, for every subset
    /// of two or more, the FIM of the differences to that subset's first UAV.
    #[test]
    fn subset_information_is_eq_48_for_the_subset() {
        for n in [3, 5, 8] {
            let (s, z) = swarm(n);
            let all = subset_fim(&s, &z, (1 << n) - 1).unwrap();
            let paper = crate::fim(&s, &z).unwrap();
            assert!((all - paper).norm() <= 1e-12 * paper.norm(), "{all} vs {paper}");
            for mask in 0..(1u32 << n) {
                let f = subset_fim(&s, &z, mask).unwrap();
                let idx: Vec<usize> = (0..n).filter(|i| mask & (1 << i) != 0).collect();
                if idx.len() < 2 {
                    assert_eq!(f, Matrix2::zeros());
                    continue;
                }
                let pos: Vec<[f64; 2]> = idx.iter().map(|&i| [s.positions()[i].x, s.positions()[i].y]).collect();
                let sig: Vec<f64> = idx.iter().map(|&i| s.noise().sigmas()[i]).collect();
                let sub = Sensors::heard(&pos, NoiseModel::heard(&sig).unwrap()).unwrap();
                let want = crate::fim(&sub, &z).unwrap();
                assert!((f - want).norm() <= 1e-10 * want.norm().max(1e-30), "mask {mask:b}: {f} vs {want}");
            }
        }
    }

    /// Without loss or silence the expectation is the posterior of every arrival; with every arrival
    /// lost (or the emitter always silent in the limit) it is the prior.
    #[test]
    fn the_limits_are_the_full_posterior_and_the_prior() {
        let (s, z) = swarm(4);
        let info = prior();
        let full = (info + crate::fim(&s, &z).unwrap()).try_inverse().unwrap().trace();
        let got = expected_posterior_trace(&info, &s, &z, &ArrivalOdds::uniform(4, 0.0, 0.0).unwrap()).unwrap();
        assert!((got - full).abs() <= 1e-9 * full, "{got} vs {full}");
        let prior_trace = info.try_inverse().unwrap().trace();
        let none = expected_posterior_trace(&info, &s, &z, &ArrivalOdds::uniform(4, 1.0, 0.0).unwrap()).unwrap();
        assert!((none - prior_trace).abs() <= 1e-9 * prior_trace);
        let silent = expected_posterior_trace(&info, &s, &z, &ArrivalOdds::uniform(4, 0.0, 0.5).unwrap()).unwrap();
        assert!((silent - 0.5 * (prior_trace + full)).abs() <= 1e-9 * prior_trace);
    }

    /// The exact sum against a Monte Carlo of the receiver itself: arrivals drawn lost, the emitter drawn
    /// silent, the posterior of what was received — within four standard errors.
    #[test]
    fn the_expectation_matches_a_monte_carlo_of_the_receiver() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        for (n, keep, silence) in [(3, vec![0.7, 0.9, 0.5], 0.0), (5, vec![0.7; 5], 0.3), (6, vec![0.95; 6], 0.1)] {
            let (s, z) = swarm(n);
            let info = prior();
            let odds = ArrivalOdds::new(&keep, silence).unwrap();
            let exact = expected_posterior_trace(&info, &s, &z, &odds).unwrap();
            let draws = 100_000;
            let (mut sum, mut sum2) = (0.0, 0.0);
            for _ in 0..draws {
                let t = if rng.random::<f64>() < silence {
                    info.try_inverse().unwrap().trace()
                } else {
                    let mask = (0..n).filter(|&i| rng.random::<f64>() < keep[i]).fold(0u32, |m, i| m | (1 << i));
                    (info + subset_fim(&s, &z, mask).unwrap()).try_inverse().unwrap().trace()
                };
                sum += t;
                sum2 += t * t;
            }
            let mean = sum / draws as f64;
            let se = ((sum2 / draws as f64 - mean * mean) / draws as f64).sqrt();
            assert!((mean - exact).abs() <= 4.0 * se, "n {n}: MC {mean} ± {se} vs exact {exact}");
            // More loss never helps.
            let worse = ArrivalOdds::new(&keep.iter().map(|p| p * 0.8).collect::<Vec<_>>(), silence).unwrap();
            assert!(expected_posterior_trace(&info, &s, &z, &worse).unwrap() > exact);
        }
    }

    #[test]
    fn bad_odds_are_refused() {
        assert!(ArrivalOdds::new(&[1.0], 0.0).is_err());
        assert!(ArrivalOdds::new(&[1.0, 1.2, 1.0], 0.0).is_err());
        assert!(ArrivalOdds::new(&[1.0, f64::NAN, 1.0], 0.0).is_err());
        assert!(ArrivalOdds::new(&[1.0; 3], 1.0).is_err());
        assert!(ArrivalOdds::new(&[1.0; 9], 0.0).is_err());
        let (s, z) = swarm(3);
        assert_eq!(expected_posterior_trace(&prior(), &s, &z, &ArrivalOdds::uniform(4, 0.1, 0.0).unwrap()), None);
        assert_eq!(expected_posterior_trace(&-prior(), &s, &z, &ArrivalOdds::uniform(3, 0.1, 0.0).unwrap()), None);
    }
}
