//! A static emitter's track re-linearised over its last bursts ([`tdoa::window`]): the arrivals each
//! fused burst kept, raw, beside a Gaussian summary of the bursts before them. The track's estimate is
//! the maximum a posteriori of the two, so a burst fused while the posterior was wide and bent does
//! not leave the error of its first linearisation in the estimate for the rest of the run.
//!
//! Plain data: it travels in the estimator's state (the state echo), so a resumed estimator goes on
//! from the same window.

use nalgebra::{Matrix2, Vector2};
use tdoa::window::{Information, refit};
use tdoa::{Arrivals, Posterior, TdoaError};

use crate::{EmitterModel, EstimateOut, EstimateStatus, EstimatorKind, HeldBurst};

/// The bursts a window keeps raw (the newest); an older one is folded into the summary, linearised at
/// the estimate of the step it leaves.
pub const WINDOW_BURSTS: usize = 8;

/// The summary and the raw bursts of a track's window.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Window {
    /// The bursts before the window, in information form (none at a track's first fix).
    pub base: Information,
    /// The arrivals each burst of the window kept, with their steps, oldest first.
    pub bursts: Vec<(u64, Arrivals)>,
}

impl Window {
    /// A window that starts from the Gaussian `posterior` (its position block) with no raw burst.
    pub fn from_posterior(posterior: &Posterior) -> Option<Self> {
        let inv = posterior.position_cov().try_inverse()?;
        Some(Self { base: Information { matrix: inv, vector: inv * posterior.position() }, bursts: Vec::new() })
    }

    /// A window of raw bursts alone, no summary: the bursts `held` for a first fix (two arrivals each,
    /// oldest first) and the fix's own burst `fix`, the newest [`WINDOW_BURSTS`] of them.
    pub fn raw(held: &[(u64, Arrivals)], fix: (u64, Arrivals)) -> Self {
        let mut bursts: Vec<(u64, Arrivals)> = held.to_vec();
        bursts.push(fix);
        bursts.drain(..bursts.len().saturating_sub(WINDOW_BURSTS));
        Self { base: Information::none(), bursts }
    }

    /// Whether the window holds more than a fix: not just the fix's burst raw, nor just its posterior
    /// (a window just opened, whose covariance is the fix's own).
    pub fn holds_more_than_a_fix(&self) -> bool {
        let no_base = self.base == Information::none();
        !(self.bursts.is_empty() || (no_base && self.bursts.len() == 1))
    }

    /// This window with the arrivals `kept` of the burst of `step`; beyond [`WINDOW_BURSTS`] the oldest
    /// burst is folded into the summary at `at` (metres, the estimate of this step). `None` when `at` is
    /// on a UAV.
    pub fn pushed(&self, step: u64, kept: Arrivals, at: &Vector2<f64>) -> Option<Self> {
        let mut next = self.clone();
        next.bursts.push((step, kept));
        while next.bursts.len() > WINDOW_BURSTS {
            let (_, oldest) = next.bursts.remove(0);
            if let Some(h) = oldest.heard().ok().flatten() {
                next.base = next.base.with_burst(&(&h.sensors, h.diffs.as_slice()), at)?;
            }
        }
        Some(next)
    }

    /// The arrivals `a` as the window keeps them: a burst of two arrivals (one range difference) with
    /// the noise it was fused with — its linearisation noise over the prediction `predicted` added
    /// ([`tdoa::fusion::update_noise`]) to the later UAV's σ — so that re-linearising it does not weigh a
    /// hyperbola the filter tempered more than the filter did. Other bursts as they are.
    pub fn kept_as_fused(a: Arrivals, predicted: &Posterior) -> Arrivals {
        if a.heard_count() != 2 {
            return a;
        }
        let tempered = || -> Option<Arrivals> {
            let h = a.heard().ok()??;
            let r =
                tdoa::linearisation::linearisation_noise(&h.sensors, &predicted.position(), &predicted.position_cov())?
                    [(0, 0)];
            let later = *h.uavs.last()?;
            a.with_sigma(later, (a.sigmas()[later].powi(2) + r.max(0.0)).sqrt()).ok()
        };
        tempered().unwrap_or(a)
    }

    /// The maximum a posteriori of the summary and the raw bursts from `start` (metres), with the
    /// Gauss–Newton covariance there (m²).
    pub fn estimate(&self, start: &Vector2<f64>) -> Result<(Vector2<f64>, Matrix2<f64>), TdoaError> {
        let heard: Vec<tdoa::Heard> = self.bursts.iter().filter_map(|(_, a)| a.heard().ok().flatten()).collect();
        let bursts: Vec<tdoa::window::Burst<'_>> = heard.iter().map(|h| (&h.sensors, h.diffs.as_slice())).collect();
        refit(&self.base, &bursts, start)
    }
}

impl crate::Estimator {
    /// Fused, static emitter, one hypothesis: moves the track's window on with the burst `a` of `step`
    /// (the arrivals `out` kept) and makes `out`'s estimate the window's maximum a posteriori and its
    /// position covariance the window's Gauss–Newton covariance there (`(Λ_b + Σ JᵀQ⁻¹J)⁻¹` at the
    /// estimate: the covariance of the estimate reported, every burst linearised where the estimate is,
    /// not where the filter was when it came). A window of the fix's burst alone keeps the fix's own
    /// covariance (sigma points for three arrivals).
    ///
    /// A new fix opens a window: a fix of four or more arrivals (its outliers dropped) with its burst
    /// raw, after the two-arrival bursts `held` for it; a fix of three at its posterior (a lone, exactly
    /// determined fix re-linearised raw makes a worse estimate where the later bursts are poor: three
    /// UAVs at loss 0.3, the RMSE at step 5 828 → 1016 m). A fused burst with no window open opens one at
    /// the posterior; `predicted` is the posterior before the burst (a single range difference enters
    /// the window with the linearisation noise it was fused with over it). Other steps leave the window;
    /// a moving emitter or a failed refit close it.
    ///
    /// Two roots of one ambiguous fix: the window opens with the fix's burst raw — the same for either
    /// root — and takes every burst fused while both are pending without a refit; the burst that decides
    /// refits it from the root kept ([`Self::window_through_ambiguity`]). Two hypotheses of a restarted
    /// track (the old posterior pending beside a new fix) close it.
    pub(crate) fn relinearise(
        &mut self,
        step: u64,
        a: &Arrivals,
        out: &mut EstimateOut,
        predicted: Option<Posterior>,
        held: &[HeldBurst],
    ) {
        let Some(post) = out.posterior else { return };
        let fused_static = self.config.kind == EstimatorKind::Fused && post.model() == EmitterModel::Static;
        let kept = a.without_all(out.outliers);
        if fused_static && self.alternative.is_some() {
            self.window = self.window_through_ambiguity((step, kept), out, &post, predicted, held);
            return;
        }
        if !fused_static {
            self.window = None;
            return;
        }
        let next = match (&out.status, out.nis) {
            // A new fix of four or more arrivals (its outliers dropped, so redundant enough to have been
            // checked): its burst raw, after those held for it.
            (EstimateStatus::Ok, None) if kept.heard_count() >= 4 => Some(Window::raw(held, (step, kept))),
            // A fix of three: summarised as its posterior, whose covariance is the fix's own (sigma
            // points): a burst a reflection corrupted weighs no more than the filter lets it.
            (EstimateStatus::Ok | EstimateStatus::Ambiguous, None) => Window::from_posterior(&post),
            (EstimateStatus::Ok, Some(_)) => match (&self.window, predicted) {
                (Some(w), Some(pred)) => w.pushed(step, Window::kept_as_fused(kept, &pred), &post.position()),
                // No window open (a new track, two hypotheses before): it opens at this posterior.
                _ => Window::from_posterior(&post),
            },
            _ => return,
        };
        let refitted = next.and_then(|w| {
            let (x, c) = w.estimate(&post.position()).ok()?;
            let mut cov = post.cov();
            if w.holds_more_than_a_fix() {
                cov.fixed_view_mut::<2, 2>(0, 0).copy_from(&c);
            }
            let p = Posterior::new(post.model(), nalgebra::Vector4::new(x.x, x.y, 0.0, 0.0), cov).ok()?;
            Some((p, w))
        });
        match refitted {
            Some((p, w)) => {
                out.position = p.position();
                out.covariance = p.position_cov();
                out.posterior = Some(p);
                self.window = Some(w);
            }
            _ => self.window = None,
        }
    }

    /// The window while two roots of one ambiguous fix are pending: at the fix, its burst raw (the
    /// arrivals `kept`, those `out` did not drop; no summary, which would have to be of one root) after
    /// the two-arrival bursts `held` for it, raw too; a burst fused while both stay pending is pushed raw
    /// as in [`Self::relinearise`], not refitted (the estimate is the root the track is on, `post`).
    /// `None` for two hypotheses of a restarted track — its old window is of the old root only — or once
    /// a fold beyond [`WINDOW_BURSTS`] would need one root's estimate.
    ///
    /// Why: a lone three-arrival fix is an exactly determined, strongly curved solution; summarised
    /// as a Gaussian at one root it stays in the track's estimate for good. Kept raw, the burst that
    /// decides the roots re-linearises it at the estimate of the root kept. Measured on 1 600 runs of
    /// five UAVs at loss 0.3 and silence 0.3, the tracks that start on an ambiguous fix: mean NEES of
    /// steps 4–14 2.29 → 2.10, RMSE unchanged (EXPERIMENTS.md, the receiver study).
    pub(crate) fn window_through_ambiguity(
        &self,
        (step, kept): (u64, Arrivals),
        out: &EstimateOut,
        post: &Posterior,
        predicted: Option<Posterior>,
        held: &[HeldBurst],
    ) -> Option<Window> {
        match (&out.status, out.nis) {
            (EstimateStatus::Ambiguous, None) => Some(Window::raw(held, (step, kept))),
            // Both roots still pending after a fused burst: the burst joins the window raw.
            (EstimateStatus::Ok, Some(_)) => {
                let (w, pred) = (self.window.as_ref()?, predicted?);
                if w.bursts.len() >= WINDOW_BURSTS {
                    return None;
                }
                w.pushed(step, Window::kept_as_fused(kept, &pred), &post.position())
            }
            // A new fix beside the old track (a restart), or a step that fused nothing.
            (EstimateStatus::Ok, None) => None,
            _ => self.window.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::*;
    use crate::*;
    use tdoa::Dynamics;

    #[test]
    fn a_redundant_fix_opens_a_raw_window_whose_covariance_is_reported() {
        // Five UAVs, noisy arrivals. The fix (five arrivals) opens a window of its burst alone and keeps
        // the fix's covariance; the next burst (UAV 3 lost) is refitted with it raw, and the covariance
        // reported is the inverse of both bursts' Fisher information at the estimate reported.
        let z = Vector2::new(25_000.0, 15_000.0);
        let start = [[1500.0, 500.0], [10_000.0, 1500.0], [5000.0, 8500.0], [-2000.0, 6000.0], [8000.0, -4000.0]];
        let offsets = [12.0, -35.0, 20.0, 41.0, -8.0];
        let burst = |shift: [f64; 2], heard: u8, k: usize| {
            let p: Vec<[f64; 2]> = start.iter().map(|u| [u[0] + shift[0], u[1] + shift[1]]).collect();
            let r: Vec<f64> = p
                .iter()
                .enumerate()
                .map(|(i, u)| (z - Vector2::new(u[0], u[1])).norm() + offsets[(i + k) % 5])
                .collect();
            Arrivals::new(&p, &r, heard, &[28.7712; 5], &[0.0; 5]).unwrap()
        };
        let mut est = Estimator::with_config(EstimatorConfig::fused(Dynamics::fixed()));
        let fix = est.estimate_burst(0, &burst([0.0, 0.0], 0b11111, 0)).unwrap();
        assert_eq!(fix.status, EstimateStatus::Ok);
        assert!(!est.window().unwrap().holds_more_than_a_fix(), "{:?}", est.window());
        assert_eq!(fix.covariance, fix.posterior.unwrap().position_cov());
        let second = burst([2000.0, 1500.0], 0b10111, 1);
        let out = est.estimate_burst(1, &second).unwrap();
        assert_eq!(out.status, EstimateStatus::Ok);
        let w = est.window().unwrap();
        assert_eq!((w.base, w.bursts.len()), (tdoa::window::Information::none(), 2));
        let (map, _) = w.estimate(&out.position).unwrap();
        assert!((map - out.position).norm() < 1e-6);
        let info = |a: &Arrivals| tdoa::fim::fim(&a.heard().unwrap().unwrap().sensors, &out.position).unwrap();
        let expected = (info(&burst([0.0, 0.0], 0b11111, 0)) + info(&second)).try_inverse().unwrap();
        assert!((out.covariance - expected).norm() < 1e-9 * expected.norm(), "{} vs {expected}", out.covariance);
        assert_eq!(out.covariance, out.posterior.unwrap().position_cov());
    }

    #[test]
    fn the_window_spans_an_ambiguity_raw_and_the_deciding_burst_refits_it() {
        // Noisy arrivals: the fix's burst enters the window raw (no summary of one root) and stays there
        // through a two-arrival burst that leaves both roots pending; the burst that decides refits the
        // three raw bursts, so the estimate is their maximum a posteriori — not the filter's mean, which
        // linearised the fix at Chan's root.
        let (uavs, z, other) = ambiguous_case();
        let noisy = [0.0, 23.0, -31.0];
        let burst = |pos: &[Vector2<f64>], heard: u8, k: usize| {
            let p: Vec<[f64; 2]> = pos.iter().map(|u| [u.x, u.y]).collect();
            let r: Vec<f64> = pos.iter().enumerate().map(|(i, u)| (z - u).norm() + noisy[(i + k) % 3]).collect();
            Arrivals::new(&p, &r, heard, &[28.7712; 3], &[0.0; 3]).unwrap()
        };
        let mut est = Estimator::with_config(EstimatorConfig::fused(Dynamics::fixed()));
        let first = est.estimate_burst(0, &burst(&uavs, 0b111, 0)).unwrap();
        assert_eq!(first.status, EstimateStatus::Ambiguous);
        let w = est.window().expect("a window opens on an ambiguous fix");
        assert_eq!((w.base, w.bursts.len()), (tdoa::window::Information::none(), 1));
        let moved: Vec<Vector2<f64>> = uavs.iter().map(|p| p + Vector2::new(500.0, 300.0)).collect();
        let pending = est.estimate_burst(1, &burst(&moved, 0b011, 1)).unwrap();
        assert!(est.alternative().is_some(), "two arrivals do not decide");
        assert_eq!(est.window().map(|w| w.bursts.len()), Some(2), "the pending burst joins the window");
        assert_eq!(pending.position, est.posterior().unwrap().position(), "no refit while both are pending");
        let far: Vec<Vector2<f64>> = uavs.iter().map(|p| p + Vector2::new(-900.0, 1400.0)).collect();
        let decided = est.estimate_burst(2, &burst(&far, 0b111, 2)).unwrap();
        assert!(est.alternative().is_none());
        let w = est.window().expect("the window goes on after the decision");
        assert_eq!(w.bursts.iter().map(|(k, _)| *k).collect::<Vec<_>>(), vec![0, 1, 2]);
        let (map, _) = w.estimate(&decided.position).unwrap();
        assert!((map - decided.position).norm() < 1e-6, "{map} vs {}", decided.position);
        assert!(
            (decided.position - z).norm() < (decided.position - other).norm(),
            "picked {:?}, truth {z:?}, other {other:?}",
            decided.position
        );
    }

    #[test]
    fn a_static_track_s_estimate_is_the_map_of_its_fix_and_its_last_bursts() {
        // Three UAVs flying, each burst with its own range errors: after the first fix, the estimate of
        // every step is the maximum a posteriori of the fix's posterior and the raw bursts since,
        // computed here from scratch; beyond eight bursts the oldest leave the window for its summary.
        let z = Vector2::new(25_000.0, 15_000.0);
        let at = |k: f64| -> Vec<Vector2<f64>> {
            nominal()
                .iter()
                .enumerate()
                .map(|(i, p)| p + Vector2::new(350.0 * k, (120.0 + 90.0 * i as f64) * k))
                .collect()
        };
        let noisy = |k: usize| {
            let uavs = at(k as f64);
            let d = diffs(&uavs, z);
            let e = [[31.0, -12.0], [-25.0, 40.0], [8.0, -36.0], [-44.0, 17.0], [20.0, 29.0]][k % 5];
            (uavs, RangeDiffs::from_slice(&[d.as_slice()[0] + e[0], d.as_slice()[1] + e[1]]).unwrap())
        };
        let mut est = Estimator::with_config(EstimatorConfig::fused(Dynamics::fixed()));
        let (uavs0, d0) = noisy(0);
        let fix = est.estimate(0, &uavs0, &d0, &noise(3)).unwrap();
        let base = Window::from_posterior(&fix.posterior.unwrap()).unwrap().base;
        let mut raw: Vec<(Vec<Vector2<f64>>, RangeDiffs)> = Vec::new();
        for k in 1..=12 {
            let (uavs, d) = noisy(k);
            let out = est.estimate(k as u64, &uavs, &d, &noise(3)).unwrap();
            assert_eq!(out.status, EstimateStatus::Ok);
            raw.push((uavs, d));
            let w = est.window().expect("a static track has a window");
            assert_eq!(w.bursts.len(), k.min(WINDOW_BURSTS));
            if k <= WINDOW_BURSTS {
                assert_eq!(w.base, base, "nothing folded before the window is full");
                let sensors: Vec<tdoa::Sensors> = raw
                    .iter()
                    .map(|(u, _)| {
                        let pts: Vec<[f64; 2]> = u.iter().map(|p| [p.x, p.y]).collect();
                        tdoa::Sensors::new(&pts, noise(3)).unwrap()
                    })
                    .collect();
                let bursts: Vec<tdoa::window::Burst<'_>> =
                    sensors.iter().zip(&raw).map(|(s, (_, d))| (s, d.as_slice())).collect();
                let (map, cov) = tdoa::window::refit(&base, &bursts, &z).unwrap();
                assert!((out.position - map).norm() < 1e-3, "step {k}: {:?} vs the MAP {map:?}", out.position);
                assert!((out.covariance - cov).norm() < 1e-6 * cov.norm(), "step {k}: {} vs {cov}", out.covariance);
            } else {
                assert_ne!(w.base, base, "the oldest bursts are folded into the summary");
            }
            // The window's mean and covariance, in the estimate and the posterior the next step starts from.
            assert_eq!(out.covariance, out.posterior.unwrap().position_cov());
        }
        // A moving-emitter model keeps no window.
        let cv = Dynamics::new(EmitterModel::ConstantVelocity, 10.0, 0.05, 20.0).unwrap();
        let mut moving = Estimator::with_config(EstimatorConfig::fused(cv));
        for k in 0..3 {
            let (uavs, d) = noisy(k);
            moving.estimate(k as u64, &uavs, &d, &noise(3)).unwrap();
        }
        assert!(moving.window().is_none());
    }
}
