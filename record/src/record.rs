//! The record of one run, step by step: what `uavloc simulate --json` prints and what the monitor
//! rebuilds from the messages it receives in the process pipeline (same shape, so the two compare).
//!
//! Units: metres, m², radians, milliseconds.

use model::Scenario;
use serde::{Deserialize, Serialize};

/// One planning step. Step 0 is the initial geometry; the last step has no plan.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct StepRecord {
    /// Planning step index.
    pub step: u64,
    /// The step's positions as latitude/longitude, when the run has an origin (absent otherwise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub geo: Option<crate::geographic::StepGeo>,
    /// UAV positions at this step, metres (`[x, y]` per UAV, UAV0 first).
    pub uavs: Vec<[f64; 2]>,
    /// Headings chosen at this step for the next interval, radians (current headings on the last step,
    /// and on a step whose command was missed: the UAVs kept them).
    pub headings_rad: Vec<f64>,
    /// The estimator's ẑ at this step, metres (`null`s before the first fix: written as JSON null, read
    /// back as NaN).
    #[serde(deserialize_with = "nulls_as_nan")]
    pub estimate: [f64; 2],
    /// The covariance M of ẑ, m² (`[[xx, xy], [yx, yy]]`; `null`s before the first fix).
    #[serde(deserialize_with = "rows_nulls_as_nan")]
    pub estimate_cov: [[f64; 2]; 2],
    /// `ok`, `ambiguous`, `rejected` (fused: the snapshot failed the χ² gate and was not fused; ẑ is
    /// the prediction) or `failed` (on failure ẑ is the previous estimate).
    pub estimate_status: String,
    /// Fused, constant-velocity model: the velocity estimate, m/s (absent otherwise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimate_velocity: Option<[f64; 2]>,
    /// Fused, constant-velocity model: the velocity's covariance, m²/s² (absent otherwise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimate_velocity_cov: Option<[[f64; 2]; 2]>,
    /// The true emitter position at this step, metres (`null` without a truth).
    #[serde(default)]
    pub truth: Option<[f64; 2]>,
    /// `|ẑ − z|`, metres (`null` without a truth).
    #[serde(default)]
    pub estimate_error_m: Option<f64>,
    /// Normalised estimation error squared `(ẑ − z)ᵀ M⁻¹ (ẑ − z)` of the reported position covariance
    /// (2 degrees of freedom; mean 2 for a consistent estimator; `null` without a truth).
    #[serde(default)]
    pub nees: Option<f64>,
    /// Posterior CRLB at the truth from every snapshot so far, metres: `sqrt(tr (Σ F_k)⁻¹)` for a
    /// static emitter, Tichavský's recursion for `constant_velocity` (`null` without a truth, or while
    /// the information is singular).
    #[serde(default)]
    pub pcrlb_m: Option<f64>,
    /// The smallest distance of a UAV to the true emitter at this step, metres (`null` without a truth).
    #[serde(default)]
    pub min_true_distance_m: Option<f64>,
    /// Single-point CRLB `sqrt(tr F⁻¹)` at the TRUE emitter for this geometry, metres (paper's Figure 5);
    /// `+∞` for a geometry that cannot localise (e.g. two UAVs on top of each other), written `null` in
    /// JSON (which has no infinity) and read back as `+∞`. Absent (`None`, no key) without a truth (an
    /// external front end): an error column that is absent, not zero.
    #[serde(default, skip_serializing_if = "Option::is_none", deserialize_with = "null_as_infinity")]
    pub crlb_true_m: Option<f64>,
    /// Single-point CRLB `sqrt(tr F⁻¹(ẑ))` at the step's *estimate* for this geometry, metres: what a run
    /// without a truth can tell about its geometry (`null` where F is singular there or ẑ is unknown).
    #[serde(default)]
    pub crlb_at_estimate_m: Option<f64>,
    /// Posterior CRLB along the estimates, metres: the recursion of `pcrlb_m` with each snapshot's
    /// information taken at that step's estimate instead of the truth (the scenario's σ) — what a run
    /// without a truth can say about the information gathered (`null` while singular, or without an
    /// estimate).
    #[serde(default)]
    pub pcrlb_at_estimate_m: Option<f64>,
    /// RMSE of Chan over R noise resamples at this geometry (paper Section 5.3), metres.
    pub rmse_m: Option<f64>,
    /// Objective value of the chosen headings (the planner's criterion, as `sqrt` of its trace, m);
    /// `None` on the last step (nothing is planned), when infinite, or when the command was missed.
    pub objective_value: Option<f64>,
    /// Wall-clock time of the planning step, milliseconds (`None` on the last step and when the command
    /// was missed).
    pub plan_ms: Option<f64>,
    /// Constraints active (violated or within 0.1 % of their bound) at the chosen headings; in a pipeline
    /// run in real-time mode, `["command_missed"]` when no command arrived before the next step was due
    /// (the UAVs flew the hold of a step without a plan: `headings_rad` and `safety.certified` are the
    /// hold's; `objective_value`, `plan_ms` and `planner` are then null).
    pub active_constraints: Vec<String>,
    /// The range noise σ per UAV of this step's measurement, metres, when it is not the scenario's (an
    /// external front end states its own): what `pcrlb_m`, `pcrlb_at_estimate_m` and the planner used.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub range_sigmas_m: Option<Vec<f64>>,
    /// The estimator that made this step's estimate (`fused` or `snapshot`): the run's, or — after
    /// `uavloc swap estimator --estimator KIND` — the one swapped in (`uavloc replay` replays each step
    /// with it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimator: Option<String>,
    /// The planner process that chose the headings (pipeline runs only; absent from `simulate` and on
    /// the last step).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub planner: Option<PlannerRef>,
    /// Kish's effective sample size of the `mc` criterion's weighted points at this step (`mc` runs of
    /// `simulate` only; absent otherwise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub criterion_ess: Option<f64>,
    /// The safety of the interval from this step to the next: the planner's certificate and the margins
    /// along the arcs the UAVs flew ([`crate::annotate`]; absent on the last step).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub safety: Option<StepSafety>,
    /// What the receivers gave at this step: who heard the burst, which arrivals the estimator dropped
    /// as outliers, a silent emitter (absent when every UAV heard it and nothing was dropped).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub receiver: Option<StepReceiver>,
}

/// One step's burst as the receivers gave it and the estimator used it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct StepReceiver {
    /// The UAVs whose arrival the step held.
    pub heard: Vec<usize>,
    /// The arrivals the estimator dropped as outliers.
    pub outliers: Vec<usize>,
    /// The emitter did not transmit (`null`: not known, e.g. an external front end's step heard by
    /// fewer than two UAVs).
    pub silent: Option<bool>,
    /// The arrivals that truly came by a reflection (`null` without a truth).
    pub multipath: Option<Vec<usize>>,
}

impl StepReceiver {
    /// From the masks (bit i: UAV i) of a swarm of `n` UAVs.
    pub fn from_masks(n: usize, heard: u8, outliers: u8, silent: Option<bool>, multipath: Option<u8>) -> Self {
        let list = |m: u8| (0..n).filter(|i| m & (1u8 << i) != 0).collect::<Vec<_>>();
        Self { heard: list(heard), outliers: list(outliers), silent, multipath: multipath.map(list) }
    }

    /// `None` for a complete burst with nothing dropped (and no reflection): today's perfect step.
    pub fn unless_complete(self, n: usize) -> Option<Self> {
        let complete = self.heard.len() == n
            && self.outliers.is_empty()
            && self.silent != Some(true)
            && self.multipath.as_ref().is_none_or(|m| m.is_empty());
        (!complete).then_some(self)
    }
}

/// A run's receiver totals ([`crate::annotate`], from the steps' [`StepReceiver`]).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ReceiverTotals {
    /// Arrivals not received (a UAV that did not hear a burst that was sent; silent steps excluded).
    pub arrivals_lost: u64,
    /// Steps the emitter was silent.
    pub silent_steps: u64,
    /// Steps with fewer than two arrivals (silent or lost): the estimate was predicted.
    pub steps_without_fix: u64,
    /// Arrivals dropped as outliers, per UAV.
    pub outliers_by_uav: Vec<u64>,
    /// Arrivals that truly came by a reflection (`null` without a truth).
    pub multipath_arrivals: Option<u64>,
    /// Of those, the ones the estimator dropped (`null` without a truth).
    pub multipath_dropped: Option<u64>,
    /// Good arrivals (no reflection) the estimator dropped (`null` without a truth).
    pub good_arrivals_dropped: Option<u64>,
    /// Reflected arrivals in bursts where the reflections are a minority of the arrivals heard — the
    /// only ones any estimator that keeps a majority can identify (`null` without a truth).
    #[serde(default)]
    pub multipath_minority_arrivals: Option<u64>,
    /// Of those, the ones the estimator dropped (`null` without a truth).
    #[serde(default)]
    pub multipath_minority_dropped: Option<u64>,
}

/// The safety of one interval (from a step to the next), along the arcs the UAVs flew.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct StepSafety {
    /// The planner's word: `true` certified, `false` no certified plan existed (the UAVs flew the plan
    /// with the largest minimum margin), `null` not certified by design (`safety = "waypoints"`). A
    /// step without a plan (a hold, a missed command) carries its hold's spacing certificate.
    pub certified: Option<bool>,
    /// The smallest distance between two UAVs along the arcs, metres (certified lower bound, within
    /// 0.25 m of the true minimum).
    pub min_pair_m: Option<f64>,
    /// The smallest standoff margin along the arcs to the estimate as predicted over the interval:
    /// `distance − (L_min + k·σ̄)` with the chance bound of `standoff_confidence`, metres (`null` with
    /// `l_min = 0`).
    pub standoff_margin_m: Option<f64>,
    /// The smallest distance of a UAV to the TRUE emitter along the arcs, metres (`null` without a
    /// truth).
    pub min_true_distance_m: Option<f64>,
}

impl StepSafety {
    /// The planner's word `certified` alone (a plan's or a hold's certificate); the margins are filled
    /// in along the arcs flown ([`crate::annotate`]).
    pub fn of_word(certified: bool) -> Self {
        Self { certified: Some(certified), ..Self::default() }
    }
}

/// A pair that serde_json wrote with `null`s for NaN (no estimate yet), read back as NaN.
fn nulls_as_nan<'de, D: serde::Deserializer<'de>>(d: D) -> Result<[f64; 2], D::Error> {
    let v = <[Option<f64>; 2]>::deserialize(d)?;
    Ok(v.map(|x| x.unwrap_or(f64::NAN)))
}

/// [`nulls_as_nan`] for a 2 × 2 matrix.
fn rows_nulls_as_nan<'de, D: serde::Deserializer<'de>>(d: D) -> Result<[[f64; 2]; 2], D::Error> {
    let v = <[[Option<f64>; 2]; 2]>::deserialize(d)?;
    Ok(v.map(|r| r.map(|x| x.unwrap_or(f64::NAN))))
}

/// A present `f64` that serde_json wrote as `null` because it was not finite (only `+∞` is possible
/// here); an absent key is `None` (the field's default).
fn null_as_infinity<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
    Ok(Some(Option::<f64>::deserialize(d)?.unwrap_or(f64::INFINITY)))
}

/// A planner process instance, as recorded per step by the monitor.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct PlannerRef {
    /// Solver name.
    pub solver: String,
    /// Objective name.
    pub objective: String,
    /// Its instance id (pid in the high 32 bits).
    pub instance: u64,
}

/// A whole run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunRecord {
    /// The scenario as run.
    pub scenario: Scenario,
    /// Objective name (`single`, `mc`, `analytical`, `cubature`, `formation`).
    pub objective: String,
    /// Solver name (`pso`, `ga`, `aco`).
    pub solver: String,
    /// Run seed.
    pub seed: u64,
    /// True emitter position (at step 0), metres; `null` without a truth (an external front end).
    #[serde(default)]
    pub emitter: Option<[f64; 2]>,
    /// The estimator (`fused` or `snapshot`).
    #[serde(default)]
    pub estimator: String,
    /// Snapshots the fused estimator did not fuse because they failed its χ² gate (steps with
    /// `estimate_status` `rejected`).
    #[serde(default)]
    pub rejected_snapshots: u64,
    /// (UAV, interval) pairs that came closer than `L_min` to the TRUE emitter anywhere along the arcs
    /// flown (`null` without a truth).
    #[serde(default)]
    pub true_standoff_violations: Option<u64>,
    /// (pair, interval) counts of two UAVs closer than `D_min` anywhere along the arcs flown.
    #[serde(default)]
    pub true_spacing_violations: u64,
    /// Planned steps whose command said that no certified plan existed.
    #[serde(default)]
    pub uncertified_steps: u64,
    /// The smallest distance between two UAVs along the arcs over the run, metres.
    #[serde(default)]
    pub min_pair_m: Option<f64>,
    /// The smallest distance of a UAV to the TRUE emitter along the arcs over the run, metres (`null`
    /// without a truth).
    #[serde(default)]
    pub min_true_distance_m: Option<f64>,
    /// The receivers' totals: arrivals lost, silent steps, outliers by UAV (absent when every step was
    /// complete).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub receiver: Option<ReceiverTotals>,
    /// Step 0 (initial geometry) to the final step.
    pub steps: Vec<StepRecord>,
}

impl RunRecord {
    /// A run's record before [`crate::annotate`]: the run's identity and its steps, every total 0 or
    /// unknown (`annotate` fills them).
    pub fn new(
        scenario: Scenario,
        (objective, solver): (&str, &str),
        seed: u64,
        emitter: Option<[f64; 2]>,
        estimator: &str,
        steps: Vec<StepRecord>,
    ) -> Self {
        Self {
            scenario,
            objective: objective.to_string(),
            solver: solver.to_string(),
            seed,
            emitter,
            estimator: estimator.to_string(),
            rejected_snapshots: 0,
            true_standoff_violations: None,
            true_spacing_violations: 0,
            uncertified_steps: 0,
            min_pair_m: None,
            min_true_distance_m: None,
            receiver: None,
            steps,
        }
    }

    /// CRLB at the truth on the last step, metres.
    pub fn final_crlb_m(&self) -> Option<f64> {
        self.steps.last().and_then(|s| s.crlb_true_m)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A record of three UAVs (two on one point) with CRLB `crlb`.
    pub(crate) fn record(step: u64, crlb: f64) -> StepRecord {
        StepRecord {
            step,
            geo: None,
            uavs: vec![[0.0, 0.0], [0.0, 0.0], [1.0, 0.0]],
            headings_rad: vec![0.0; 3],
            estimate: [1.0, 2.0],
            estimate_cov: [[1.0, 0.0], [0.0, 1.0]],
            estimate_status: "failed".into(),
            estimate_velocity: None,
            estimate_velocity_cov: None,
            truth: None,
            estimate_error_m: None,
            nees: None,
            pcrlb_m: None,
            min_true_distance_m: None,
            crlb_true_m: Some(crlb),
            crlb_at_estimate_m: None,
            pcrlb_at_estimate_m: None,
            rmse_m: None,
            objective_value: None,
            plan_ms: None,
            active_constraints: vec![],
            planner: None,
            criterion_ess: None,
            range_sigmas_m: None,
            estimator: None,
            safety: None,
            receiver: None,
        }
    }

    #[test]
    fn an_infinite_crlb_survives_a_json_round_trip() {
        // Two coincident UAVs: the CRLB is +∞, which JSON can only write as null.
        let json = serde_json::to_string(&record(7, f64::INFINITY)).unwrap();
        assert!(json.contains("\"crlb_true_m\":null"), "{json}");
        let back: StepRecord = serde_json::from_str(&json).unwrap();
        assert_eq!(back.crlb_true_m, Some(f64::INFINITY));
        let finite: StepRecord = serde_json::from_str(&serde_json::to_string(&record(7, 12.5)).unwrap()).unwrap();
        assert_eq!(finite.crlb_true_m, Some(12.5));
    }

    #[test]
    fn without_a_truth_the_crlb_at_the_truth_is_absent_not_zero_nor_infinite() {
        let r = StepRecord { crlb_true_m: None, ..record(3, 1.0) };
        let json = serde_json::to_string(&r).unwrap();
        assert!(!json.contains("crlb_true_m"), "{json}");
        let back: StepRecord = serde_json::from_str(&json).unwrap();
        assert_eq!(back.crlb_true_m, None);
    }
}
