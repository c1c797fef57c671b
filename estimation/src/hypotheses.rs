//! Two hypotheses of one fused track and how the bursts decide between them: Chan's two roots after an
//! ambiguous fix of three arrivals, or — after [`crate::REJECTED_RUN_RESTART`] rejections in a row — the
//! new fix beside the track it replaced, where the burst that restarted it cannot vouch for itself
//! (three arrivals, or an outlier its own residual shows: it is the burst the track rejected, and where
//! arrivals come by reflections it is as likely to be corrupted as the track to be lost). Every burst
//! is fused into both; the track moves to the other hypothesis only when it fits a burst of three or
//! more arrivals decisively better ([`RESOLVE_NIS_MARGIN`]), and a near tie keeps both.

use tdoa::consider::BiasSensitivity;
use tdoa::{Arrivals, Posterior, TdoaError};

use crate::{EstimateOut, EstimateStatus, Estimator, outliers};

/// How much larger (χ², one burst) the NIS of one of an ambiguous fix's two roots must be than the
/// other's for the burst to drop it: a likelihood ratio of `e^(9/2)` ≈ 90. Below it both roots stay
/// pending. (Decided by the smaller NIS alone, one of 200 random three-UAV runs kept the mirror root
/// 170 km out, whose NIS was 3.2 against the true root's 4.0, and flew its 120 steps on it.)
pub const RESOLVE_NIS_MARGIN: f64 = 9.0;

/// The posterior of Chan's other root after an ambiguous fix, with its bias sensitivity: pending until
/// the next burst decides between the two roots.
pub type PendingRoot = (Posterior, Option<BiasSensitivity>);

impl Estimator {
    /// After an ambiguous start: fuses the snapshot into both roots' posteriors. The track stays on the
    /// root it follows (`first`) unless the other's innovation is smaller by at least
    /// [`RESOLVE_NIS_MARGIN`] (the likelier root given both snapshots, decisively); the status is that
    /// of the update of the root kept. The other root is dropped only when the burst decides: three or
    /// more arrivals, and its NIS at least [`RESOLVE_NIS_MARGIN`] above the kept root's. Otherwise (a burst
    /// heard by two UAVs only — one range difference, a hyperbola that may pass near both roots — or
    /// two roots that both fit the burst, as the mirror root of three UAVs far away does for many steps)
    /// it is updated too and stays pending (returned beside the estimate), and the next burst chooses
    /// again: a near tie never locks the track onto the wrong root for good.
    pub(crate) fn resolve(
        &self,
        first: (&Posterior, &BiasSensitivity),
        other: (&Posterior, &BiasSensitivity),
        a: &Arrivals,
    ) -> Result<(EstimateOut, Option<PendingRoot>), TdoaError> {
        let nis = |o: &EstimateOut| match o.status {
            EstimateStatus::Rejected { nis, .. } => nis,
            _ => o.nis.unwrap_or(f64::INFINITY),
        };
        match (self.fuse(first.0, first.1, a), self.fuse(other.0, other.1, a)) {
            (Ok(x), Ok(y)) => {
                // The root the track follows (`first`) is kept until the other fits decisively better.
                let switch = nis(&y) + RESOLVE_NIS_MARGIN <= nis(&x);
                let (kept, other) = if switch { (y, x) } else { (x, y) };
                // (Two roots without a finite NIS give NaN: nothing to keep the other for.)
                let gap = nis(&other) - nis(&kept);
                let decides = a.heard_count() >= 3 && (gap.is_nan() || gap >= RESOLVE_NIS_MARGIN);
                let pending = if decides { None } else { other.posterior.map(|p| (p, other.sensitivity)) };
                Ok((kept, pending))
            }
            (Ok(x), Err(_)) => Ok((x, None)),
            (Err(_), Ok(y)) => Ok((y, None)),
            (Err(e), Err(_)) => Err(e),
        }
    }

    /// Whether the burst `a`, whose Chan fix is `fix`, vouches for that fix by itself: the arrivals the
    /// fix kept (its own outliers dropped) are four or more and their residual is within the gate
    /// (`χ²_{m−2}`, one or more degrees of freedom of redundancy).
    pub(crate) fn vouches_for_itself(&self, a: &Arrivals, fix: &EstimateOut) -> bool {
        let kept = a.without_all(fix.outliers);
        kept.heard_count() >= 4 && !outliers::shows_an_outlier(&kept, None, |m| self.config.gate(m))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::*;
    use crate::*;
    use tdoa::Dynamics;
    use tdoa::{Sensors, chan};

    #[test]
    fn fused_start_resolves_the_ambiguity_with_the_next_snapshot() {
        let (uavs, z, other) = ambiguous_case();
        let d = diffs(&uavs, z);
        // A second geometry, noise-free: it agrees with the truth, not with the other root.
        let moved: Vec<Vector2<f64>> = uavs.iter().map(|p| p + Vector2::new(500.0, 300.0)).collect();
        let d2 = diffs(&moved, z);
        let mut est = Estimator::with_config(EstimatorConfig::fused(Dynamics::fixed()));
        let first = est.estimate(0, &uavs, &d, &noise(3)).unwrap();
        assert_eq!(first.status, EstimateStatus::Ambiguous);
        assert!(est.alternative.is_some());
        let second = est.estimate(1, &moved, &d2, &noise(3)).unwrap();
        assert!((second.position - z).norm() < 1e-3, "picked {:?}, truth {z:?}, other {other:?}", second.position);
        assert_eq!(second.status, EstimateStatus::Ok);
        assert!(est.alternative.is_none());
    }

    #[test]
    fn a_near_tie_keeps_both_roots_until_a_burst_decides() {
        // UAVs that do not move: both roots fit every noise-free burst equally, so no burst decides and
        // the track stays on the root it started on, the other pending. (Decided by the smaller NIS
        // alone, the first such burst dropped one of them: a coin flip that can keep the mirror root for
        // good.) Then a burst from a geometry that tells them apart takes the track to the truth.
        let (uavs, z, other) = ambiguous_case();
        let d = diffs(&uavs, z);
        let mut est = Estimator::with_config(EstimatorConfig::fused(Dynamics::fixed()));
        let first = est.estimate(0, &uavs, &d, &noise(3)).unwrap();
        assert_eq!(first.status, EstimateStatus::Ambiguous);
        for step in 1..6 {
            let out = est.estimate(step, &uavs, &d, &noise(3)).unwrap();
            assert!(est.alternative.is_some(), "step {step}: a tie dropped a root");
            assert!((out.position - first.position).norm() < 1.0, "step {step}: the track jumped roots on a tie");
        }
        let moved: Vec<Vector2<f64>> = uavs.iter().map(|p| p + Vector2::new(500.0, 300.0)).collect();
        let decided = est.estimate(6, &moved, &diffs(&moved, z), &noise(3)).unwrap();
        assert!((decided.position - z).norm() < 1e-3, "picked {:?}, truth {z:?}, other {other:?}", decided.position);
        assert!(est.alternative.is_none());
    }

    #[test]
    fn a_burst_of_two_arrivals_leaves_both_roots_pending() {
        // One range difference is a hyperbola that may pass near both roots: it does not decide, the next
        // burst of three arrivals does.
        let (uavs, z, other) = ambiguous_case();
        let burst = |pos: &[Vector2<f64>], heard: u8| {
            let p: Vec<[f64; 2]> = pos.iter().map(|u| [u.x, u.y]).collect();
            let r: Vec<f64> = pos.iter().map(|u| (z - u).norm()).collect();
            Arrivals::new(&p, &r, heard, &[28.7712; 3], &[0.0; 3]).unwrap()
        };
        let mut est = Estimator::with_config(EstimatorConfig::fused(Dynamics::fixed()));
        let first = est.estimate_burst(0, &burst(&uavs, 0b111)).unwrap();
        assert_eq!(first.status, EstimateStatus::Ambiguous);
        let moved: Vec<Vector2<f64>> = uavs.iter().map(|p| p + Vector2::new(500.0, 300.0)).collect();
        est.estimate_burst(1, &burst(&moved, 0b011)).unwrap();
        let (pending, _) = est.alternative().expect("two arrivals do not decide");
        let roots = [est.posterior().unwrap().position(), pending.position()];
        assert!(roots.iter().any(|r| (r - z).norm() < 50.0), "{roots:?} vs truth {z:?}");
        assert!(roots.iter().any(|r| (r - other).norm() < 50.0), "{roots:?} vs other root {other:?}");
        let third = est.estimate_burst(2, &burst(&moved, 0b111)).unwrap();
        assert!(est.alternative().is_none());
        assert!((third.position - z).norm() < 1e-3, "picked {:?}, truth {z:?}", third.position);
    }

    #[test]
    fn a_track_lost_on_the_wrong_root_restarts_with_both_roots_pending() {
        // Three UAVs, a tight posterior on the mirror root: bursts from a geometry that tells the roots
        // apart reject it; the restart's burst comes from a geometry where both roots fit, so Chan's fix is
        // ambiguous. Resolved by the lost track's position it would find the mirror root again; without a
        // prior both stay pending and the next telling burst takes the track to the truth.
        let (uavs, z, other) = ambiguous_case();
        let moved: Vec<Vector2<f64>> = uavs.iter().map(|p| p + Vector2::new(500.0, 300.0)).collect();
        let post = static_at(other, 100.0);
        let config = EstimatorConfig::fused(Dynamics::fixed());
        let mut est = Estimator::resume(config, 0, other, Matrix2::identity() * 100.0, Some(post));
        for k in 1..=2u64 {
            let out = est.estimate(k, &moved, &diffs(&moved, z), &noise(3)).unwrap();
            assert!(matches!(out.status, EstimateStatus::Rejected { .. }), "{:?}", out.status);
        }
        // The restart's burst: from a geometry where Chan's fix is ambiguous, its mirror root nearer the
        // lost track than the truth is, and the lost track rejected.
        let sensors_at =
            |pos: &[Vector2<f64>]| Sensors::new(&pos.iter().map(|u| [u.x, u.y]).collect::<Vec<_>>(), noise(3)).unwrap();
        let mirror_of = |pos: &[Vector2<f64>]| {
            let sol = chan(&sensors_at(pos), &diffs(pos, z), None).ok()?;
            let far = sol.candidates.iter().copied().find(|c| (c - z).norm() > 1000.0)?;
            (sol.ambiguous && sol.candidates.len() == 2).then_some(far)
        };
        let telling = (0..400)
            .map(|k| {
                let a = 0.37 * k as f64;
                let shift = Vector2::new(a.cos(), a.sin()) * (100.0 + 10.0 * k as f64);
                uavs.iter().map(|p| p + shift).collect::<Vec<_>>()
            })
            .find(|pos| {
                let rejected = tdoa::fusion::fuse(&post, &sensors_at(pos), &diffs(pos, z), config.gate(2))
                    .is_ok_and(|u| matches!(u.outcome, tdoa::fusion::Outcome::Rejected { .. }));
                rejected && mirror_of(pos).is_some_and(|m| (m - other).norm() < (z - other).norm())
            })
            .expect("a geometry whose mirror root lies nearer the lost track, which it rejects");
        let restart = est.estimate(3, &telling, &diffs(&telling, z), &noise(3)).unwrap();
        assert_eq!(restart.status, EstimateStatus::Ambiguous, "the restart chose a root: {:?}", restart.position);
        assert!(est.alternative.is_some());
        let next = est.estimate(4, &moved, &diffs(&moved, z), &noise(3)).unwrap();
        assert!((next.position - z).norm() < 1e-3, "picked {:?}, truth {z:?}, mirror {other:?}", next.position);
    }

    #[test]
    fn a_lost_posterior_restarts_from_chan_after_three_rejections() {
        // A posterior 5 km off with a tight covariance (e.g. a jump of the emitter): noise-free snapshots
        // of the truth are rejected twice, the third rejection in a row restarts from Chan (4 UAVs: unique).
        let z = Vector2::new(25000.0, 15000.0);
        let mut uavs = nominal();
        uavs.push(Vector2::new(0.0, 9000.0));
        let wrong = z + Vector2::new(5000.0, -3000.0);
        let post = static_at(wrong, 100.0);
        let mut est = Estimator::resume(
            EstimatorConfig::fused(Dynamics::fixed()),
            0,
            wrong,
            Matrix2::identity() * 100.0,
            Some(post),
        );
        let d = diffs(&uavs, z);
        for k in 1..=2u8 {
            let out = est.estimate(u64::from(k), &uavs, &d, &noise(4)).unwrap();
            assert!(matches!(out.status, EstimateStatus::Rejected { .. }), "{:?}", out.status);
            assert_eq!(out.track.rejected_run, k);
            assert_eq!(out.position, wrong, "a rejected snapshot leaves the posterior");
        }
        let restart = est.estimate(3, &uavs, &d, &noise(4)).unwrap();
        assert_eq!(restart.status, EstimateStatus::Ok);
        assert_eq!(restart.track.rejected_run, 0);
        assert!((restart.position - z).norm() < 1e-6);
        // Four arrivals whose own residual fits vouch for the fix: the lost track is not kept pending
        // (`a_good_track_restarted_by_reflected_bursts_is_kept_pending_and_wins_back`: three do not).
        assert!(restart.alternative.is_none(), "nothing kept pending beside a fix its own burst vouches for");
        // And it fuses from there.
        let next = est.estimate(4, &uavs, &d, &noise(4)).unwrap();
        assert_eq!((next.status, next.track.rejected_run), (EstimateStatus::Ok, 0));
        assert!((next.position - z).norm() < 1e-6);
        // The count rides the state: an estimator resumed with 2 rejections behind it restarts at the next.
        let mut resumed = Estimator::resume(
            EstimatorConfig::fused(Dynamics::fixed()),
            0,
            wrong,
            Matrix2::identity() * 100.0,
            Some(post),
        )
        .with_track(TrackCounters { rejected_run: 2, ..TrackCounters::default() });
        assert_eq!(resumed.estimate(1, &uavs, &d, &noise(4)).unwrap().track.rejected_run, 0);
    }

    #[test]
    fn a_good_track_restarted_by_reflected_bursts_is_kept_pending_and_wins_back() {
        // Three UAVs, a confirmed track on the truth: three bursts in a row with two of their three
        // arrivals late (reflections of 500 and 800 m) are rejected, and the third restarts from its own
        // fix — which those reflections corrupted, and which three arrivals cannot show. The old track
        // stays pending beside it, and the next clean burst brings it back.
        let z = Vector2::new(25000.0, 15000.0);
        let uavs = nominal();
        let post = static_at(z, 25.0);
        let confirmed = TrackCounters { confirmed: CONFIRM_BURSTS, ..TrackCounters::default() };
        let resumed = || {
            Estimator::resume(EstimatorConfig::fused(Dynamics::fixed()), 0, z, Matrix2::identity() * 25.0, Some(post))
                .with_track(confirmed)
        };
        let clean = diffs(&uavs, z);
        let c = clean.as_slice();
        let late = RangeDiffs::from_slice(&[c[0] + 500.0, c[1] + 800.0]).unwrap();
        let mut est = resumed();
        for k in 1..=2u64 {
            let out = est.estimate(k, &uavs, &late, &noise(3)).unwrap();
            assert!(matches!(out.status, EstimateStatus::Rejected { .. }), "{:?}", out.status);
        }
        let restart = est.estimate(3, &uavs, &late, &noise(3)).unwrap();
        assert!((restart.position - z).norm() > 300.0, "the restart's fix is the corrupted burst's");
        let (pending, _) = restart.alternative.expect("the old track is kept pending");
        assert!((pending.position() - z).norm() < 1e-6);
        let back = est.estimate(4, &uavs, &clean, &noise(3)).unwrap();
        assert_eq!(back.status, EstimateStatus::Ok);
        assert!((back.position - z).norm() < 1.0, "the clean burst took the old track back: {:?}", back.position);
        assert!(back.alternative.is_none(), "a clean burst of three arrivals decides");
    }

    #[test]
    fn a_confirmed_track_that_drops_the_same_uav_burst_after_burst_is_made_provisional_and_restarted() {
        // A confirmed track 3 km off on the hyperbola of UAVs 1 and 2 through the truth (inside the
        // triangle of the UAVs, where a burst sees 3 km clearly): every clean burst
        // fails its gate, and dropping UAV0's (direct) arrival makes the other two fit the wrong track.
        let z = Vector2::new(6000.0, 4000.0);
        let uavs = nominal();
        let rd12 = |w: Vector2<f64>| (w - uavs[1]).norm() - (w - uavs[2]).norm();
        let config = EstimatorConfig::fused(Dynamics::fixed());
        let track_at = |w: Vector2<f64>| {
            let post = static_at(w, 100.0);
            Estimator::resume(config, 0, w, Matrix2::identity() * 100.0, Some(post))
                .with_track(TrackCounters { confirmed: CONFIRM_BURSTS, ..TrackCounters::default() })
        };
        let d = diffs(&uavs, z);
        // The points 3 km from the truth on that hyperbola (bisection of rd12 around the circle); the one
        // whose first burst drops UAV0 is the wrong track of a corrupted first fix.
        let on_circle = |t: f64| z + Vector2::new(t.cos(), t.sin()) * 3000.0;
        let wrong = (0..360)
            .filter_map(|k| {
                let (mut lo, mut hi) = (k as f64 * 1f64.to_radians(), (k + 1) as f64 * 1f64.to_radians());
                let f = |t| rd12(on_circle(t)) - rd12(z);
                if f(lo) * f(hi) > 0.0 {
                    return None;
                }
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    if f(lo) * f(mid) <= 0.0 { hi = mid } else { lo = mid }
                }
                Some(on_circle(lo))
            })
            .find(|&w| track_at(w).estimate(1, &uavs, &d, &noise(3)).is_ok_and(|o| o.outliers == 0b001))
            .expect("a point of the hyperbola whose track drops UAV0");
        let mut est = track_at(wrong);
        for k in 1..DEMOTE_DROP_RUN {
            let out = est.estimate(u64::from(k), &uavs, &d, &noise(3)).unwrap();
            assert_eq!((out.status.clone(), out.outliers), (EstimateStatus::Ok, 0b001), "burst {k}");
            assert_eq!(
                (out.track.confirmed, out.track.drop_streak),
                (CONFIRM_BURSTS, DropStreak { uavs: 0b001, run: k })
            );
            assert!((out.position - wrong).norm() < 50.0, "the wrong track holds: {:?}", out.position);
        }
        let demoted = est.estimate(u64::from(DEMOTE_DROP_RUN), &uavs, &d, &noise(3)).unwrap();
        assert_eq!((demoted.track.confirmed, demoted.track.drop_streak), (0, DropStreak::default()));
        // Provisional, it drops no arrival: rejected, then restarted from Chan of the clean burst.
        let mut k = u64::from(DEMOTE_DROP_RUN);
        for run in 1..REJECTED_RUN_RESTART {
            k += 1;
            let out = est.estimate(k, &uavs, &d, &noise(3)).unwrap();
            assert!(matches!(out.status, EstimateStatus::Rejected { .. }), "{:?}", out.status);
            assert_eq!(out.track.rejected_run, run);
        }
        let restart = est.estimate(k + 1, &uavs, &d, &noise(3)).unwrap();
        let near = |p: Vector2<f64>| (p - z).norm() < 1e-3;
        assert!(
            near(restart.position) || restart.alternative.is_some_and(|(p, _)| near(p.position())),
            "restarted at {:?} (alternative {:?}), truth {z:?}",
            restart.position,
            restart.alternative.map(|(p, _)| p.position())
        );
        // A resumed estimator carries the streak.
        let resumed = track_at(wrong);
        let streak = DropStreak { uavs: 0b001, run: DEMOTE_DROP_RUN - 1 };
        let resumed = resumed.clone().with_track(TrackCounters { drop_streak: streak, ..resumed.track() });
        let mut resumed = resumed;
        let out = resumed.estimate(1, &uavs, &d, &noise(3)).unwrap();
        assert_eq!(out.track.confirmed, 0, "the streak's last drop demotes the resumed track");
    }
}
