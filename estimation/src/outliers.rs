//! Which arrival of a burst is the outlier: a multipath arrival is late by hundreds of metres of range,
//! and one late arrival must cost that arrival, not the whole burst.
//!
//! Two policies ([`OutlierPolicy`], scenario key `outliers`):
//! - `snapshot`: a burst whose innovation fails the χ² gate is not fused at all (every arrival of it lost);
//! - `arrival` (default): in a burst that passes the gate, an arrival whose own share of the NIS
//!   (`NIS(all) − NIS(all but it)`, χ²₁) exceeds the one-degree gate and that is late is dropped; a burst
//!   that fails the gate is fused without the smallest set of arrivals whose removal makes the rest pass
//!   its own gate against the same prediction, every arrival removed being **late** against the rest's
//!   fit (a reflection only lengthens the path) — exhaustive over the sets of each size, the best fit
//!   among those of the smallest size ([`fuse_without_late`]). A confirmed track may keep as few as two
//!   arrivals of K: beyond a minority, each arrival removed must be late beyond the one-degree gate
//!   ([`lateness_score`]), so that a burst whose majority came by reflections keeps its earliest,
//!   direct arrivals. Chan's first fix of a burst heard by four or more UAVs is checked the same way
//!   against its own residual (`m − 2` degrees of freedom). A provisional track (see the estimator)
//!   drops arrivals only from a burst that shows an outlier by itself ([`shows_an_outlier`]), and at
//!   most a minority of them: a wrong first fix is not kept alive by dropping the arrivals of clean
//!   bursts that disagree with it.
//!
//! Pure functions over plain data.

use nalgebra::Vector2;
pub use tdoa::arrivals::OutlierPolicy;
use tdoa::arrivals::bit;
use tdoa::fusion::{self, Outcome, Posterior, Update};
use tdoa::{Arrivals, ChanSolution, Heard, TdoaError, chan};

/// The fusion of one burst: the update, and the arrivals dropped as outliers (bit i: UAV i).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BurstUpdate {
    /// The update (of the arrivals kept).
    pub update: Update,
    /// The arrivals dropped.
    pub dropped: u8,
}

/// How well `x` fits χ²_dof, as a p-value that does not underflow far in the tail: the Wilson–Hilferty
/// normal score `z` of `x` mapped to `−z` (larger is better; monotone in the p-value `1 − CDF`).
fn fit_score(dof: usize, x: f64) -> f64 {
    let k = dof.max(1) as f64;
    let v = 2.0 / (9.0 * k);
    -(((x.max(0.0) / k).cbrt() - (1.0 - v)) / v.sqrt())
}

/// The residual of UAV `j`'s arrival against the position `z` in the frame of the other arrivals heard
/// (`(a_j − a_r) − (|z − s_j| − |z − s_r|)` with `r` the first UAV heard other than `j`), metres:
/// positive when the arrival is late.
fn lateness(a: &Arrivals, j: usize, z: &Vector2<f64>) -> Option<f64> {
    let r = (0..a.len()).find(|&i| i != j && a.heard_mask() & bit(i) != 0)?;
    let (aj, ar) = (a.arrival(j)?, a.arrival(r)?);
    let p = a.positions();
    Some((aj - ar) - ((z - p[j]).norm() - (z - p[r]).norm()))
}

/// Fuses the burst `a` (≥ 2 arrivals) into the **predicted** posterior, gating each subset of `m` range
/// differences at `gate(m)`, with the outlier `policy` (see the module documentation).
pub fn fuse_burst(
    predicted: &Posterior,
    a: &Arrivals,
    gate: impl Fn(usize) -> f64,
    policy: OutlierPolicy,
) -> Result<BurstUpdate, TdoaError> {
    let fuse = |a: &Arrivals| -> Result<Option<(Update, usize)>, TdoaError> {
        let Some(h) = a.heard()? else { return Ok(None) };
        let m = h.diffs.as_slice().len();
        Ok(Some((fusion::fuse(predicted, &h.sensors, &h.diffs, gate(m))?, m)))
    };
    let (whole, _) = fuse(a)?.ok_or_else(|| TdoaError::Degenerate("a burst heard by fewer than two UAVs".into()))?;
    if policy == OutlierPolicy::Snapshot || a.heard_count() < 3 {
        return Ok(BurstUpdate { update: whole, dropped: 0 });
    }
    if let Outcome::Fused { nis, .. } = whole.outcome {
        // The burst passes as a whole, but one late arrival may still stand out: the part of the NIS that
        // arrival j alone contributes, NIS(all) − NIS(all but j), is χ²₁ given the prediction and the other
        // arrivals (exact for the linearised update); above gate(1) and late, arrival j is the outlier
        // (fault detection and exclusion, as RAIM does it for GNSS).
        let mut worst: Option<(f64, usize, Update)> = None;
        for j in (0..a.len()).filter(|&j| a.heard_mask() & bit(j) != 0) {
            let Some((up, _)) = fuse(&a.without(j))? else { continue };
            let Outcome::Fused { nis: nis_j, .. } = up.outcome else { continue };
            let t = nis - nis_j;
            let late = lateness(a, j, &up.posterior.position()).is_some_and(|r| r > 0.0);
            if late && t > gate(1) && worst.as_ref().is_none_or(|(w, ..)| t > *w) {
                worst = Some((t, j, up));
            }
        }
        return Ok(match worst {
            Some((_, j, update)) => BurstUpdate { update, dropped: bit(j) },
            None => BurstUpdate { update: whole, dropped: 0 },
        });
    }
    // The burst fails as a whole.
    let minority = (a.heard_count() - 1) / 2;
    let all_but_two = a.heard_count().saturating_sub(2);
    Ok(fuse_without_late(predicted, a, gate, minority, all_but_two)?
        .unwrap_or(BurstUpdate { update: whole, dropped: 0 }))
}

/// Fuses the burst `a`, which fails its gate as a whole, without the smallest set of arrivals whose
/// removal makes the rest pass its own gate, every arrival removed being late against the rest's fit:
/// exhaustive over the sets of each size up to `max_drop` (at most K − 2 of K arrivals, so that one
/// range difference is kept), the best fit among the sets of the smallest size that works. Sets larger
/// than `loose_up_to` (a minority of the burst, for a confirmed track; 0 for a provisional one) must
/// have each arrival late beyond the one-degree gate ([`lateness_score`]), not merely late: a reflection
/// only lengthens the path, so the earliest arrivals that agree with the prediction are the direct ones
/// even when most of the burst is reflected. `None` when no set works.
pub fn fuse_without_late(
    predicted: &Posterior,
    a: &Arrivals,
    gate: impl Fn(usize) -> f64,
    loose_up_to: usize,
    max_drop: usize,
) -> Result<Option<BurstUpdate>, TdoaError> {
    let heard = a.heard_mask();
    let max_drop = max_drop.min(a.heard_count().saturating_sub(2));
    let threshold = gate(1).sqrt();
    for size in 1..=max_drop {
        let mut best: Option<(f64, u8, Update)> = None;
        for drop in subsets_of(heard, size) {
            let kept = a.without_all(drop);
            let Some(h) = kept.heard()? else { continue };
            let m = h.diffs.as_slice().len();
            let up = fusion::fuse(predicted, &h.sensors, &h.diffs, gate(m))?;
            let Outcome::Fused { nis, .. } = up.outcome else { continue };
            let z = up.posterior.position();
            let pos_cov = up.posterior.position_cov();
            let late_enough = (0..a.len()).filter(|&j| drop & bit(j) != 0).all(|j| {
                lateness_score(a, kept.heard_mask(), j, &z, &pos_cov)
                    .is_some_and(|t| if size <= loose_up_to { t > 0.0 } else { t > threshold })
            });
            let p = fit_score(m, nis);
            if late_enough && best.as_ref().is_none_or(|(q, ..)| p > *q) {
                best = Some((p, drop, up));
            }
        }
        if let Some((_, drop, update)) = best {
            return Ok(Some(BurstUpdate { update, dropped: drop }));
        }
    }
    Ok(None)
}

/// Every subset of the bits of `mask` with exactly `size` bits, in increasing order.
fn subsets_of(mask: u8, size: usize) -> impl Iterator<Item = u8> {
    (1u16..256).map(|s| s as u8).filter(move |s| s & !mask == 0 && s.count_ones() as usize == size)
}

/// How late UAV `j`'s arrival is against the arrivals of `kept` (a heard mask) fitted at `z`, in units of
/// its standard deviation: `(e_j − t̂₀) / σ`, with `e_i = a_i − |z − s_i|` (metres; the common offset plus
/// the noise, plus a reflection's bias) and `t̂₀` the σ⁻²-weighted mean of the kept `e_i`. The variance
/// is that of the difference: `σ_j² + 1/Σσ_i⁻² + gᵀ P g`, `g = u_j − ū` (unit vectors from the UAVs to
/// `z`, `ū` their weighted mean over the kept UAVs) and `P` the fit's position covariance (m²).
pub fn lateness_score(
    a: &Arrivals,
    kept: u8,
    j: usize,
    z: &Vector2<f64>,
    pos_cov: &nalgebra::Matrix2<f64>,
) -> Option<f64> {
    let p = a.positions();
    let unit = |i: usize| {
        let d = z - p[i];
        let r = d.norm();
        (r > 0.0 && r.is_finite()).then(|| d / r)
    };
    let (mut w_sum, mut t0, mut u_bar) = (0.0, 0.0, Vector2::zeros());
    for i in (0..a.len()).filter(|&i| kept & bit(i) != 0) {
        let w = a.sigmas()[i].powi(-2);
        w_sum += w;
        t0 += w * (a.arrival(i)? - (z - p[i]).norm());
        u_bar += w * unit(i)?;
    }
    if w_sum <= 0.0 {
        return None;
    }
    t0 /= w_sum;
    u_bar /= w_sum;
    let g = unit(j)? - u_bar;
    let var = a.sigmas()[j].powi(2) + 1.0 / w_sum + (g.transpose() * pos_cov * g)[(0, 0)];
    Some((a.arrival(j)? - (z - p[j]).norm() - t0) / var.sqrt())
}

/// Fuses the burst `a` into the predicted posterior without the arrivals the burst **itself** shows to
/// be outliers: Chan's fix of the burst alone, checked against its own residual ([`chan_burst`], five or
/// more arrivals so that the residual has two or more degrees of freedom and one late arrival is
/// identifiable, not only detectable). `None` when the burst shows no outlier, has too few arrivals, or
/// its remaining arrivals still fail the gate against the prediction. The identification does not look
/// at the track, so a wrong track cannot make a good arrival look like an outlier.
pub fn fuse_self_checked(
    predicted: &Posterior,
    a: &Arrivals,
    gate: impl Fn(usize) -> f64 + Copy,
) -> Result<Option<BurstUpdate>, TdoaError> {
    if a.heard_count() < 5 {
        return Ok(None);
    }
    let Ok((_, _, dropped)) = chan_burst(a, Some(predicted.position()), gate, OutlierPolicy::Arrival) else {
        return Ok(None);
    };
    if dropped == 0 {
        return Ok(None);
    }
    let update = fuse_burst(predicted, &a.without_all(dropped), gate, OutlierPolicy::Snapshot)?.update;
    Ok(matches!(update.outcome, Outcome::Fused { .. }).then_some(BurstUpdate { update, dropped }))
}

/// Whether the burst `a` shows an outlier by itself: four or more arrivals whose Chan fix (with `prior`
/// for the two-root case) fails its own residual gate `gate(m − 2)`. A burst that does not (or cannot,
/// with three arrivals) is no evidence against any of its arrivals.
pub fn shows_an_outlier(a: &Arrivals, prior: Option<Vector2<f64>>, gate: impl Fn(usize) -> f64) -> bool {
    if a.heard_count() < 4 {
        return false;
    }
    let Ok((sol, h, _)) = chan_burst(a, prior, &gate, OutlierPolicy::Snapshot) else { return false };
    let dof = h.diffs.as_slice().len().saturating_sub(2);
    dof > 0 && residual_chi2(&h, &sol.position) > gate(dof)
}

/// `rᵀ Q⁻¹ r` of the residual `r = d − h(z)` of the heard arrivals at `z` (χ²_{m−2} at Chan's fix).
pub fn residual_chi2(h: &Heard, z: &Vector2<f64>) -> f64 {
    let exact = h.sensors.range_differences(z);
    let r: Vec<f64> = h.diffs.as_slice().iter().zip(exact.as_slice()).map(|(d, e)| d - e).collect();
    h.sensors.noise().quadratic_form(&r)
}

/// Chan's fix of the burst `a` (≥ 3 arrivals) with `prior` for the two-root case; with four or more
/// arrivals and the `arrival` policy, a fix whose residual fails `gate(m − 2)` is replaced by the fix
/// without the outlying arrivals (leave-one-out, at most `⌊(K − 1)/2⌋`, each left-out arrival late).
/// Returns the fix, the geometry it used and the arrivals dropped.
pub fn chan_burst(
    a: &Arrivals,
    prior: Option<Vector2<f64>>,
    gate: impl Fn(usize) -> f64,
    policy: OutlierPolicy,
) -> Result<(ChanSolution, Heard, u8), TdoaError> {
    let solve = |a: &Arrivals| -> Result<(ChanSolution, Heard), TdoaError> {
        let h = a.heard()?.ok_or_else(|| TdoaError::Degenerate("a burst heard by fewer than two UAVs".into()))?;
        let sol = chan(&h.sensors, &h.diffs, prior)?;
        Ok((sol, h))
    };
    let (sol, h) = solve(a)?;
    let dof = |h: &Heard| h.diffs.as_slice().len().saturating_sub(2);
    if policy == OutlierPolicy::Snapshot || dof(&h) == 0 {
        return Ok((sol, h, 0));
    }
    let chi_all = residual_chi2(&h, &sol.position);
    if chi_all <= gate(dof(&h)) {
        // Passes as a whole; an arrival whose own share of the residual (χ²₁) exceeds gate(1) and that
        // is late is still excluded, as in [`fuse_burst`].
        let mut worst: Option<(f64, usize, ChanSolution, Heard)> = None;
        if dof(&h) >= 2 {
            for j in (0..a.len()).filter(|&j| a.heard_mask() & bit(j) != 0) {
                let Ok((s, hj)) = solve(&a.without(j)) else { continue };
                let t = chi_all - residual_chi2(&hj, &s.position);
                let late = lateness(a, j, &s.position).is_some_and(|r| r > 0.0);
                if late && t > gate(1) && worst.as_ref().is_none_or(|(w, ..)| t > *w) {
                    worst = Some((t, j, s, hj));
                }
            }
        }
        return Ok(match worst {
            Some((_, j, s, hj)) => (s, hj, bit(j)),
            None => (sol, h, 0),
        });
    }
    let max_drop = (a.heard_count() - 1) / 2;
    let mut current = *a;
    let mut dropped = 0u8;
    for _ in 0..max_drop {
        let mut passed: Option<(f64, usize, ChanSolution, Heard)> = None;
        let mut best: Option<(f64, usize)> = None;
        for j in (0..current.len()).filter(|&j| current.heard_mask() & bit(j) != 0) {
            let without = current.without(j);
            let Ok((s, hj)) = solve(&without) else { continue };
            let k = dof(&hj);
            let chi = residual_chi2(&hj, &s.position);
            let p = if k == 0 { 1.0 } else { fit_score(k, chi) };
            let late = lateness(&current, j, &s.position).is_some_and(|r| r > 0.0);
            if late && (k == 0 || chi <= gate(k)) && passed.as_ref().is_none_or(|(q, ..)| p > *q) {
                passed = Some((p, j, s, hj));
            } else if best.is_none_or(|(q, _)| p > q) {
                best = Some((p, j));
            }
        }
        if let Some((_, j, s, hj)) = passed {
            return Ok((s, hj, dropped | bit(j)));
        }
        let Some((_, j)) = best else { break };
        current = current.without(j);
        dropped |= bit(j);
        if dof(&current.heard()?.ok_or_else(|| TdoaError::Degenerate("no arrivals left".into()))?) == 0 {
            break;
        }
    }
    Ok((sol, h, 0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix4, Vector4};
    use tdoa::EmitterModel;

    fn swarm() -> Vec<[f64; 2]> {
        vec![[1500.0, 500.0], [10000.0, 1500.0], [5000.0, 8500.0], [-3000.0, 4000.0], [2000.0, -6000.0]]
    }

    fn arrivals(z: Vector2<f64>, late: &[(usize, f64)]) -> Arrivals {
        let pos = swarm();
        let mut a: Vec<f64> = pos.iter().map(|p| (z - Vector2::new(p[0], p[1])).norm()).collect();
        for &(j, b) in late {
            a[j] += b;
        }
        Arrivals::new(&pos, &a, 0b11111, &[20.0; 5], &[0.0; 5]).unwrap()
    }

    fn gate(m: usize) -> f64 {
        fusion::gate_threshold(m, fusion::DEFAULT_GATE_PROBABILITY)
    }

    /// A static prediction at `z + offset` with σ `sigma` (m) per axis.
    fn prediction(z: Vector2<f64>, offset: [f64; 2], sigma: f64) -> Posterior {
        let mut cov = Matrix4::zeros();
        cov[(0, 0)] = sigma * sigma;
        cov[(1, 1)] = sigma * sigma;
        Posterior::new(EmitterModel::Static, Vector4::new(z.x + offset[0], z.y + offset[1], 0.0, 0.0), cov).unwrap()
    }

    fn predicted(z: Vector2<f64>) -> Posterior {
        prediction(z, [50.0, -80.0], 200.0)
    }

    #[test]
    fn one_late_arrival_is_dropped_not_the_burst() {
        let z = Vector2::new(25000.0, 15000.0);
        for j in 0..5 {
            let a = arrivals(z, &[(j, 600.0)]);
            let whole = fuse_burst(&predicted(z), &a, gate, OutlierPolicy::Snapshot).unwrap();
            assert!(matches!(whole.update.outcome, Outcome::Rejected { .. }), "UAV {j}");
            let up = fuse_burst(&predicted(z), &a, gate, OutlierPolicy::Arrival).unwrap();
            assert_eq!(up.dropped, bit(j), "UAV {j}");
            assert!(matches!(up.update.outcome, Outcome::Fused { .. }));
            // Noise-free otherwise: the fused estimate moves towards the truth.
            assert!((up.update.posterior.position() - z).norm() < 20.0, "UAV {j}");
        }
    }

    #[test]
    fn a_late_arrival_below_the_burst_gate_is_still_excluded() {
        // 95 m late (≈ 5 σ) in one arrival of five: the burst as a whole passes its χ²₄ gate, the arrival's
        // own χ²₁ share does not.
        let z = Vector2::new(25000.0, 15000.0);
        let tight = |z: Vector2<f64>| prediction(z, [0.0, 0.0], 30.0);
        for j in 0..5 {
            let a = arrivals(z, &[(j, 95.0)]);
            let whole = fuse_burst(&tight(z), &a, gate, OutlierPolicy::Snapshot).unwrap();
            let Outcome::Fused { nis, .. } = whole.update.outcome else { panic!("UAV {j}: {whole:?}") };
            assert!(nis < gate(4), "UAV {j}: the burst must pass as a whole ({nis})");
            let up = fuse_burst(&tight(z), &a, gate, OutlierPolicy::Arrival).unwrap();
            assert_eq!(up.dropped, bit(j), "UAV {j}");
            // Without the late arrival the update is exact (noise-free, the prediction at the truth).
            assert!((up.update.posterior.position() - z).norm() < 1.0, "UAV {j}");
            assert!((whole.update.posterior.position() - z).norm() > 1.0, "UAV {j}");
        }
        // Noise-free arrivals: nothing is excluded.
        let up = fuse_burst(&tight(z), &arrivals(z, &[]), gate, OutlierPolicy::Arrival).unwrap();
        assert_eq!(up.dropped, 0);
    }

    #[test]
    fn a_burst_names_its_own_outlier_but_does_not_rescue_a_wrong_track() {
        let z = Vector2::new(25000.0, 15000.0);
        for j in 0..5 {
            let a = arrivals(z, &[(j, 400.0)]);
            let up = fuse_self_checked(&predicted(z), &a, gate).unwrap().expect("identified by the burst itself");
            assert_eq!(up.dropped, bit(j), "UAV {j}");
            assert!((up.update.posterior.position() - z).norm() < 20.0, "UAV {j}");
            // A track 3 km off: the burst still names the same arrival, but the rest does not fit the track.
            let wrong =
                Posterior::new(EmitterModel::Static, Vector4::new(z.x + 3000.0, z.y, 0.0, 0.0), predicted(z).cov())
                    .unwrap();
            assert_eq!(fuse_self_checked(&wrong, &a, gate).unwrap(), None, "UAV {j}");
        }
        // Nothing late, or four arrivals only: nothing to say.
        assert_eq!(fuse_self_checked(&predicted(z), &arrivals(z, &[]), gate).unwrap(), None);
        let four = arrivals(z, &[(1, 400.0)]).without(4);
        assert_eq!(fuse_self_checked(&predicted(z), &four, gate).unwrap(), None);
    }

    #[test]
    fn two_late_arrivals_of_five_are_dropped() {
        let z = Vector2::new(25000.0, 15000.0);
        let a = arrivals(z, &[(1, 700.0), (3, 400.0)]);
        let up = fuse_burst(&predicted(z), &a, gate, OutlierPolicy::Arrival).unwrap();
        assert_eq!(up.dropped, bit(1) | bit(3));
        assert!((up.update.posterior.position() - z).norm() < 20.0);
    }

    fn tight(z: Vector2<f64>) -> Posterior {
        prediction(z, [20.0, -10.0], 30.0)
    }

    #[test]
    fn a_reflected_majority_leaves_the_earliest_arrivals_to_a_confirmed_track() {
        // Three of five arrivals came by reflections: no majority of the burst is direct, but each reflected
        // arrival is late against the two direct ones at a tight prediction.
        let z = Vector2::new(25000.0, 15000.0);
        for late in [[0usize, 2, 3], [1, 3, 4], [0, 1, 4]] {
            let a = arrivals(z, &[(late[0], 400.0), (late[1], 700.0), (late[2], 300.0)]);
            let want = late.iter().fold(0u8, |m, &j| m | bit(j));
            let up = fuse_burst(&tight(z), &a, gate, OutlierPolicy::Arrival).unwrap();
            assert_eq!(up.dropped, want, "{late:?}");
            assert!(matches!(up.update.outcome, Outcome::Fused { .. }));
            assert!((up.update.posterior.position() - z).norm() < 30.0, "{late:?}");
            // Limited to a minority (a provisional track), the burst is not made to fit.
            assert!(fuse_without_late(&tight(z), &a, gate, 0, 2).unwrap().is_none(), "{late:?}");
        }
    }

    #[test]
    fn lateness_is_measured_against_the_arrivals_kept() {
        let z = Vector2::new(25000.0, 15000.0);
        let a = arrivals(z, &[(1, 500.0), (4, 300.0)]);
        let kept = 0b01101;
        let cov = nalgebra::Matrix2::identity() * 100.0;
        // Noise-free at the truth: a reflected arrival is late by its bias over its σ (20 m, the offset's
        // own variance and the position's added); a direct one is not late at all.
        let t1 = lateness_score(&a, kept, 1, &z, &cov).unwrap();
        let t4 = lateness_score(&a, kept, 4, &z, &cov).unwrap();
        assert!(t1 > 500.0 / 40.0 && t1 < 500.0 / 20.0, "{t1}");
        assert!(t4 > 300.0 / 40.0 && t4 < 300.0 / 20.0, "{t4}");
        assert!(lateness_score(&a, 0b01100 | bit(1), 0, &z, &cov).unwrap() < 0.0, "direct against a reflected one");
    }

    #[test]
    fn only_a_burst_that_disagrees_with_itself_shows_an_outlier() {
        let z = Vector2::new(25000.0, 15000.0);
        assert!(!shows_an_outlier(&arrivals(z, &[]), None, gate));
        assert!(shows_an_outlier(&arrivals(z, &[(2, 400.0)]), None, gate));
        assert!(shows_an_outlier(&arrivals(z, &[(0, 300.0), (3, 700.0)]), None, gate));
        // Three arrivals fit any point: no evidence either way.
        let three = arrivals(z, &[(1, 600.0)]).without(3).without(4);
        assert!(!shows_an_outlier(&three, None, gate));
    }

    #[test]
    fn an_early_arrival_is_not_taken_for_multipath() {
        // A reflection only delays: an arrival 600 m *early* (a wrong prediction, not multipath) is not
        // dropped as an outlier.
        let z = Vector2::new(25000.0, 15000.0);
        let a = arrivals(z, &[(2, -600.0)]);
        let up = fuse_burst(&predicted(z), &a, gate, OutlierPolicy::Arrival).unwrap();
        assert_eq!(up.dropped & bit(2), 0);
    }

    #[test]
    fn chan_drops_the_late_arrival_of_its_first_fix() {
        let z = Vector2::new(25000.0, 15000.0);
        let a = arrivals(z, &[(4, 800.0)]);
        let (bad, ..) = chan_burst(&a, None, gate, OutlierPolicy::Snapshot).unwrap();
        let (good, h, dropped) = chan_burst(&a, None, gate, OutlierPolicy::Arrival).unwrap();
        assert_eq!(dropped, bit(4));
        assert_eq!(h.uavs, vec![0, 1, 2, 3]);
        assert!((good.position - z).norm() < 1e-3, "{}", (good.position - z).norm());
        assert!((bad.position - z).norm() > 100.0);
    }
}
