//! The active constraints of a plan as the 64-bit mask carried by `protocol::Command::active_constraints`.
//!
//! The protocol leaves the bit meanings to the planner; they are defined here, for up to
//! [`MAX_UAVS`] = 8 UAVs:
//!
//! | bits | meaning |
//! |---|---|
//! | 0–7 | `turn_radius` of UAV i (bit i) |
//! | 8–15 | `heading_cone` of UAV i |
//! | 16–23 | `approach` of UAV i |
//! | 24–51 | `spacing` of the pair (i, j), i < j, in the order (0,1), (0,2), …, (0,7), (1,2), … (28 pairs) |
//! | 56–59 | at least one constraint of kind `turn_radius`, `spacing`, `approach`, `heading_cone` is violated |
//!
//! A second mask of the same layout ([`encode_violated`], `Command::violated_constraints`) marks the
//! active constraints that are violated, not merely binding. [`decode`] gives back the strings of
//! [`ActiveConstraint`]'s `Display`, in the planner's order (per UAV: turn radius, heading cone, approach,
//! then its spacing pairs), e.g. `heading_cone(UAV 0) binding` — without the violation magnitude, which
//! the masks do not carry: `spacing(UAV 0, UAV 1) violated`. [`labels`] is that wire form of a plan's
//! constraints: what a run record holds, in `simulate` as in the pipeline, so the two are equal.

use crate::constraint::{ActiveConstraint, ConstraintKind};
use tdoa::MAX_UAVS;

const TURN_BASE: u32 = 0;
const CONE_BASE: u32 = 8;
const APPROACH_BASE: u32 = 16;
const SPACING_BASE: u32 = 24;
const VIOLATED_BASE: u32 = 56;

// The 28 spacing bits end before the violation flags.
const _: () = assert!(SPACING_BASE + 28 <= VIOLATED_BASE);

/// Index of the pair (i, j), i < j < 8, among the 28 pairs in lexicographic order.
fn pair_index(i: usize, j: usize) -> u32 {
    debug_assert!(i < j && j < MAX_UAVS);
    (i * (2 * MAX_UAVS - 1 - i) / 2 + (j - i - 1)) as u32
}

fn kind_index(kind: ConstraintKind) -> u32 {
    match kind {
        ConstraintKind::TurnRadius => 0,
        ConstraintKind::Spacing => 1,
        ConstraintKind::Approach => 2,
        ConstraintKind::HeadingCone => 3,
    }
}

fn bit(active: &ActiveConstraint) -> Option<u32> {
    if active.uav >= MAX_UAVS {
        return None;
    }
    match active.kind {
        ConstraintKind::TurnRadius => Some(TURN_BASE + active.uav as u32),
        ConstraintKind::HeadingCone => Some(CONE_BASE + active.uav as u32),
        ConstraintKind::Approach => Some(APPROACH_BASE + active.uav as u32),
        ConstraintKind::Spacing => match active.other {
            Some(j) if active.uav < j && j < MAX_UAVS => Some(SPACING_BASE + pair_index(active.uav, j)),
            _ => None,
        },
    }
}

/// The mask of `active` (entries that do not fit the layout — UAV index ≥ 8 — are dropped).
pub fn encode(active: &[ActiveConstraint]) -> u64 {
    let mut mask = 0u64;
    for a in active {
        if let Some(b) = bit(a) {
            mask |= 1 << b;
            if a.is_violated() {
                mask |= 1 << (VIOLATED_BASE + kind_index(a.kind));
            }
        }
    }
    mask
}

/// The mask of the violated constraints among `active`, in the layout of [`encode`] (bits 0–51).
pub fn encode_violated(active: &[ActiveConstraint]) -> u64 {
    active.iter().filter(|a| a.is_violated()).filter_map(bit).fold(0, |m, b| m | 1 << b)
}

/// The record labels of a plan's active constraints: their wire form ([`decode`] of both masks).
pub fn labels(active: &[ActiveConstraint], n: usize) -> Vec<String> {
    decode(encode(active), encode_violated(active), n)
}

/// The active constraints of `mask` for `n` UAVs as report strings, `violated` where `violated` has the
/// constraint's bit, else `binding` (see the module docs).
pub fn decode(mask: u64, violated: u64, n: usize) -> Vec<String> {
    let n = n.min(MAX_UAVS);
    let is_set = |b: u32| mask & (1 << b) != 0;
    let state = |b: u32| if violated & (1 << b) != 0 { "violated" } else { "binding" };
    let mut out = Vec::new();
    for i in 0..n {
        for (kind, base) in [
            (ConstraintKind::TurnRadius, TURN_BASE),
            (ConstraintKind::HeadingCone, CONE_BASE),
            (ConstraintKind::Approach, APPROACH_BASE),
        ] {
            if is_set(base + i as u32) {
                out.push(format!("{kind}(UAV {i}) {}", state(base + i as u32)));
            }
        }
        for j in i + 1..n {
            let b = SPACING_BASE + pair_index(i, j);
            if is_set(b) {
                out.push(format!("{}(UAV {i}, UAV {j}) {}", ConstraintKind::Spacing, state(b)));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn active(kind: ConstraintKind, uav: usize, other: Option<usize>, violation: f64) -> ActiveConstraint {
        ActiveConstraint { kind, uav, other, value: 1.0, bound: 1.0, violation }
    }

    #[test]
    fn pairs_fill_28_distinct_bits() {
        let mut seen = std::collections::BTreeSet::new();
        for i in 0..MAX_UAVS {
            for j in i + 1..MAX_UAVS {
                assert!(seen.insert(pair_index(i, j)));
            }
        }
        assert_eq!(seen.into_iter().collect::<Vec<_>>(), (0..28).collect::<Vec<_>>());
    }

    #[test]
    fn binding_constraints_round_trip_to_the_display_strings() {
        // In the planner's visiting order.
        let list = vec![
            active(ConstraintKind::TurnRadius, 0, None, 0.0),
            active(ConstraintKind::HeadingCone, 0, None, 0.0),
            active(ConstraintKind::Spacing, 0, Some(2), 0.0),
            active(ConstraintKind::HeadingCone, 1, None, 0.0),
            active(ConstraintKind::Approach, 2, None, 0.0),
            active(ConstraintKind::Spacing, 6, Some(7), 0.0),
        ];
        let mask = encode(&list);
        let expected: Vec<String> = list.iter().map(|a| a.to_string()).collect();
        assert_eq!(decode(mask, encode_violated(&list), 8), expected);
        assert_eq!(decode(0, 0, 3), Vec::<String>::new());
    }

    #[test]
    fn violations_are_flagged_per_instance() {
        // Two approach constraints of one kind: one violated, one binding (the launch once labelled both
        // "violated": the mask had one violation flag per kind).
        let list = vec![
            active(ConstraintKind::Spacing, 0, Some(1), 0.25),
            active(ConstraintKind::Approach, 1, None, 0.05),
            active(ConstraintKind::HeadingCone, 2, None, 0.0),
            active(ConstraintKind::Approach, 2, None, 0.0),
        ];
        assert_eq!(
            labels(&list, 3),
            vec![
                "spacing(UAV 0, UAV 1) violated".to_string(),
                "approach(UAV 1) violated".into(),
                "heading_cone(UAV 2) binding".into(),
                "approach(UAV 2) binding".into(),
            ]
        );
        assert!(list[0].to_string().starts_with("spacing(UAV 0, UAV 1) violated by"));
    }
}
