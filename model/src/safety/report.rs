//! The certificate of one plan: whether it is certified, its margins, the tightest limit, and the
//! tiers the planner ranks plans by.

use serde::{Deserialize, Serialize};

/// Which limit a margin belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SafetyLimit {
    /// A turn tighter than `R_min`.
    TurnRadius,
    /// Two UAVs closer than `D_min` along their arcs.
    Spacing,
    /// A UAV closer than the standoff bound along its arc.
    Standoff,
    /// Two UAVs' backup circles come closer than `D_min`.
    BackupSpacing,
    /// A UAV's backup circle comes closer than the standoff bound.
    BackupStandoff,
}

/// The tightest limit of a plan: which, and for which UAVs.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Tightest {
    /// The limit.
    pub limit: SafetyLimit,
    /// The UAV.
    pub uav: usize,
    /// The other UAV of a pair.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub other: Option<usize>,
    /// Normalised deficit (bound − value)/bound; ≤ 0 when the limit holds.
    pub deficit: f64,
}

/// The certificate of one plan.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SafetyReport {
    /// Every limit holds (see the module docs).
    pub certified: bool,
    /// The normalised deficits of every limit that does not hold, summed (0 when certified).
    pub total_deficit: f64,
    /// The mean normalised shortfall of the standoff margins below their *reserve*
    /// `k·σ_p + |v̂|·(Δt + πR_b/v)` (each UAV's along its arc and on its backup, each in [0, 1]; with
    /// GNSS errors also the backup circles' spacing below one position margin more), 0 when every one
    /// keeps it: what the planner keeps, where it can, beyond the bounds — one more estimate update's
    /// worth, and how far a moving emitter comes while a UAV turns its backup circle away from it — so
    /// that the next step's certificate does not start without slack. A plan inside the reserve is
    /// still certified. The mean, not the largest: with one UAV short of its reserve, the others do not
    /// give theirs up for free (with the largest, `uavloc paper safety --runs 200` measured 230
    /// uncertified steps, 26 of them late in a run; with the mean 223 and 17).
    pub reserve_deficit: f64,
    /// The largest normalised deficit of the turn radius, the spacing along the arcs and the spacing
    /// of the backup circles (0 when they hold): a collision now or one that no continuation could
    /// avoid, ranked before everything else. The spacing does not depend on the emitter, so it is kept
    /// by induction from a safe start: the backup step of a plan whose backup circles keep `D_min`
    /// flies those circles, and its own backup circles are the same ones.
    pub collision_deficit: f64,
    /// The largest normalised deficit of the step's own limits — turn radius, spacing and standoff
    /// along the arcs — (0 when they hold): what the step itself flies, ranked before the backup.
    pub step_deficit: f64,
    /// Smallest distance between two UAVs along the arcs (certified lower bound), metres; `null` with
    /// spacing off. In threshold mode only known to be at least `D_min` when it holds.
    pub min_pair_m: Option<f64>,
    /// Smallest `distance to ẑ(τ) − (L_min + k·σ̄)` along the arcs, metres (≥ 0 when it holds); `null`
    /// with the standoff off.
    pub standoff_margin_m: Option<f64>,
    /// Smallest pair distance on the backup circles for ever, metres.
    pub backup_pair_m: Option<f64>,
    /// Smallest standoff margin on the backup circles (for ever, or over the horizon), metres.
    pub backup_standoff_margin_m: Option<f64>,
    /// The limit closest to (or furthest beyond) its bound.
    pub tightest: Option<Tightest>,
}

impl SafetyReport {
    /// The largest normalised deficit, 0 when certified (the plan with the largest minimum margin,
    /// relative to each bound, wins among uncertified plans).
    pub fn deficit(&self) -> f64 {
        self.tightest.map_or(0.0, |t| t.deficit.max(0.0))
    }

    /// The certificate's ranking of a plan, most important first: a collision now or one no
    /// continuation avoids, the step's own limits, the largest deficit, their sum, the reserve.
    pub fn tiers(&self) -> [f64; 5] {
        [self.collision_deficit, self.step_deficit, self.deficit(), self.total_deficit, self.reserve_deficit]
    }
}
