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
