//! The four motion constraints by name, and one active (violated or binding) instance of a plan: what
//! a plan reports and a command carries ([`crate::active_mask`]). The checks are in `uavloc-planning`.

use std::fmt;

/// Which of the four constraints.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ConstraintKind {
    /// Turn radius ≥ `R_min` (eq. 55).
    TurnRadius,
    /// Pairwise UAV spacing ≥ `D_min` (eq. 56).
    Spacing,
    /// Distance to ẑ ≥ `L_min` (eq. 57).
    Approach,
    /// Heading within `α_i ± Δα` (eq. 58).
    HeadingCone,
}

impl ConstraintKind {
    /// All four, in [`index`](Self::index) order.
    pub const ALL: [ConstraintKind; 4] =
        [ConstraintKind::TurnRadius, ConstraintKind::Spacing, ConstraintKind::Approach, ConstraintKind::HeadingCone];

    /// Position in [`ConstraintKind::ALL`] (0..4).
    pub fn index(self) -> usize {
        self as usize
    }

    /// The snake-case name used in reports: `turn_radius`, `spacing`, `approach`, `heading_cone`.
    pub fn name(self) -> &'static str {
        match self {
            ConstraintKind::TurnRadius => "turn_radius",
            ConstraintKind::Spacing => "spacing",
            ConstraintKind::Approach => "approach",
            ConstraintKind::HeadingCone => "heading_cone",
        }
    }
}

impl fmt::Display for ConstraintKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// One constraint that is violated or binding (within the planner's `BINDING_TOLERANCE` of its bound).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ActiveConstraint {
    /// Which constraint.
    pub kind: ConstraintKind,
    /// The UAV it concerns (the first of the pair for `spacing`).
    pub uav: usize,
    /// The second UAV of a `spacing` pair.
    pub other: Option<usize>,
    /// The constrained quantity: turn radius (m), spacing (m), distance to ẑ (m) or the heading's
    /// offset from the bearing to ẑ (rad, absolute).
    pub value: f64,
    /// Its bound: `R_min`, `D_min`, `L_min` (m) or `Δα` (rad).
    pub bound: f64,
    /// Normalised violation (0 when the constraint holds and is only binding).
    pub violation: f64,
}

impl ActiveConstraint {
    /// Whether the constraint is violated (not merely binding).
    pub fn is_violated(&self) -> bool {
        self.violation > 0.0
    }
}

impl fmt::Display for ActiveConstraint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.other {
            Some(b) => write!(f, "{}(UAV {}, UAV {})", self.kind, self.uav, b)?,
            None => write!(f, "{}(UAV {})", self.kind, self.uav)?,
        }
        if self.is_violated() { write!(f, " violated by {:.3e}", self.violation) } else { f.write_str(" binding") }
    }
}
