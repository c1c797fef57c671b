//! What a plan is certified against: the scenario's limits (`L_min`, `D_min`, `R_min`, the chance
//! bound, the horizon), the backup's turn and circle, and how the planner keeps safety at all.

use nalgebra::Vector2;
use serde::{Deserialize, Serialize};

use crate::backup::BackupPath;
use crate::kinematics::max_turn;

/// Standard deviations of the relative position error two UAVs' spacing is certified beyond: `D_min`
/// holds between the true positions unless their GNSS errors along the pair's line exceed 5 σ
/// (one-sided probability 3·10⁻⁷ per pair and step). The planner's margin is `5 √2 σ` for a position σ
/// per axis of each UAV ([`position_sigma_of_reach`] states a quiet link's reach that way).
pub const SPACING_POSITION_SIGMAS: f64 = 5.0;

/// The position σ per axis whose spacing margin (`SPACING_POSITION_SIGMAS · √2 · σ`) is `reach` metres:
/// how far a UAV whose link has been quiet may be from its last fix (its speed times the fix's age).
pub fn position_sigma_of_reach(reach_m: f64) -> f64 {
    reach_m / (SPACING_POSITION_SIGMAS * std::f64::consts::SQRT_2)
}

/// Most the backup turns per step, radians: below π so that the commanded heading `ψ − θ_b` cannot wrap
/// into a left turn.
pub const BACKUP_MAX_TURN: f64 = 0.9 * std::f64::consts::PI;

/// The backup's turn per step `θ_b = min(θ_max, 0.9π)` for the largest turn `θ_max` (radians).
pub fn backup_turn(theta_max: f64) -> f64 {
    theta_max.min(BACKUP_MAX_TURN)
}

/// Relative turn beyond `θ_max` that is rounding (a heading clamped onto the bound), not a violation.
pub const TURN_ROUNDING: f64 = 1e-9;

/// How the planner keeps spacing and standoff (`safety` in the scenario).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SafetyMode {
    /// Every plan certified along the arcs with a backup for ever (this module); the default.
    #[default]
    Certified,
    /// The paper's constraints at the next waypoints only (eqs. 55–59), traded in one penalised
    /// fitness; what `uavloc paper` runs.
    Waypoints,
}

impl SafetyMode {
    /// The TOML / CLI name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Certified => "certified",
            Self::Waypoints => "waypoints",
        }
    }
}

/// The limits a plan is certified against.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SafetyLimits {
    /// Arc length per step `L = v·Δt`, metres.
    pub arc_len: f64,
    /// Planning interval Δt, seconds.
    pub dt: f64,
    /// `R_min`, metres (0: off).
    pub r_min: f64,
    /// `D_min`, metres (0: off), between the positions the planner knows.
    pub d_min: f64,
    /// The part of `d_min` that covers the UAVs' own position errors (0: exact positions): a pair closer
    /// than `d_min` breaks the certificate; closer than `d_min − position_margin_m`, it is a collision
    /// (the first tier, [`super::SafetyReport::collision_deficit`]). So a plan never buys back a few metres of
    /// that margin with a UAV deep inside the standoff ring.
    pub position_margin_m: f64,
    /// `L_min`, metres (0: off).
    pub l_min: f64,
    /// `k = Φ⁻¹(c)` of the standoff chance bound (0: at ẑ).
    pub standoff_k: f64,
    /// Horizon H of the backup's standoff for a moving emitter, seconds.
    pub horizon_s: f64,
}

impl SafetyLimits {
    /// The backup's turn per step `θ_b = min(L/R_min, 0.9π)`, radians.
    pub fn backup_turn(&self) -> f64 {
        backup_turn(max_turn(self.arc_len, self.r_min))
    }

    /// The backup circle's radius `R_b = L/θ_b ≥ R_min`, metres.
    pub fn backup_radius(&self) -> f64 {
        self.arc_len / self.backup_turn()
    }

    /// The backup circle from `end` with heading `phi`: clockwise at radius `R_b` and the UAVs' speed.
    pub fn backup_circle(&self, end: Vector2<f64>, phi: f64) -> BackupPath {
        BackupPath::circle(end, phi, self.backup_radius(), self.arc_len / self.dt)
    }

    /// The backup's commanded headings from `headings`: every UAV turns right by `θ_b`.
    pub fn backup_headings(&self, headings: &[f64]) -> Vec<f64> {
        let turn = self.backup_turn();
        headings.iter().map(|h| h - turn).collect()
    }
}
