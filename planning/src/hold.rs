//! What the swarm flies in a step it has no plan for: no estimate to plan from yet (no first fix: a
//! silent emitter, lost arrivals, a burst without a physical solution; see [`crate::FIRST_FIX_STEPS`]),
//! the step's estimate missed the planner's deadline (`planner --estimate-deadline-ms`), or — in a
//! real-time run — the step's command reached the world too late (emitter-sim flies this hold, from
//! the positions its measurement reported, and the monitor records it).
//!
//! With the certified planner (`safety = "certified"`) the UAVs **loiter**: each flies one step of its
//! backup circle (a right turn of `θ_b = min(L/R_min, 0.9π)` per step, radius `R_b ≥ R_min`). Two
//! reasons, one per limit:
//!
//! - *Spacing.* The backup circles of a certified state keep `D_min` for ever (same speed and radius:
//!   each pair's relative motion is periodic and its minimum is computed in closed form,
//!   [`model::safety`]); flying them keeps the same circles, so the spacing holds by induction however
//!   long the hold lasts. Holding course does not: two UAVs heading at the same emitter converge on
//!   it, and nothing checks them while no plan is made.
//! - *Standoff.* Where the emitter is, nobody knows before the first fix; a UAV on its circle stays
//!   within `2·R_b` of where it was when the hold began, one holding course flies on, over the emitter
//!   if it is ahead. After a certified plan the circle is the backup that plan's certificate kept off
//!   the emitter (for ever for a static one; a moving one's plan may have preferred a fly-away, which
//!   the next plan takes up).
//!
//! The hold is certified for the spacing only (the same certificate as a plan's, with the standoff
//! off); its standoff margin is not computed (`null`). Where the loiter is not certified
//! (a start whose circles conflict) but holding course is, the swarm holds course; where neither is, it
//! flies the one with the larger minimum margin and the hold is flagged uncertified. With
//! `safety = "waypoints"` (the paper's behaviour) the swarm holds course, as the paper's planner would.

use model::Scenario;
use model::safety::{EmitterPrediction, SafetyLimits, SafetyMode, SafetyReport, certify};
use nalgebra::{Matrix2, Vector2};

/// The commanded headings of a step without a plan, and the spacing certificate of
/// what they fly (`None` with `safety = "waypoints"`: not checked, as the paper's planner does not).
#[derive(Debug, Clone, PartialEq)]
pub struct Hold {
    /// Radians, one per UAV: the backup circle's next step, or the current headings.
    pub headings: Vec<f64>,
    /// The spacing certificate of the step and of the backup circles after it (standoff not checked).
    pub safety: Option<SafetyReport>,
}

impl Hold {
    /// Whether the UAVs loiter (fly their backup circles) rather than hold course.
    pub fn loiters(&self, headings: &[f64]) -> bool {
        self.headings != headings
    }

    /// The ends of the hold's arcs (metres) for the UAVs at `positions` heading `headings`: one interval
    /// of the scenario's speed to the hold's headings. `None` unless there is one position and one
    /// heading per UAV of the hold (at most [`tdoa::MAX_UAVS`]).
    pub fn waypoints(
        &self,
        positions: &[Vector2<f64>],
        headings: &[f64],
        scenario: &Scenario,
    ) -> Option<Vec<Vector2<f64>>> {
        let n = self.headings.len();
        if positions.len() != n || headings.len() != n || n > tdoa::MAX_UAVS {
            return None;
        }
        Some(crate::step::waypoints_of(positions, headings, &self.headings, scenario)[..n].to_vec())
    }
}

/// The hold of UAVs at `positions` with headings `headings` (radians) under `scenario`'s limits and
/// safety mode (module docs). A pure function of its inputs, shared by the pipeline's planner, the
/// in-process closed loop, emitter-sim (a missed command) and the monitor, so all fly and record the
/// same hold.
pub fn without_plan(positions: &[Vector2<f64>], headings: &[f64], scenario: &Scenario) -> Hold {
    if scenario.safety == SafetyMode::Waypoints {
        return Hold { headings: headings.to_vec(), safety: None };
    }
    // The standoff is off: the emitter is unknown. Its prediction is then never looked at.
    let limits = SafetyLimits { l_min: 0.0, ..crate::shield::safety_limits(scenario) };
    let nowhere = EmitterPrediction::fixed(Vector2::zeros(), &Matrix2::zeros());
    let check = |phi: &[f64]| certify(positions, headings, phi, &nowhere, &limits, true);
    let loiter = limits.backup_headings(headings);
    let circling = check(&loiter);
    if circling.certified {
        return Hold { headings: loiter, safety: Some(circling) };
    }
    let course = check(headings);
    if course.certified || course.deficit() < circling.deficit() {
        return Hold { headings: headings.to_vec(), safety: Some(course) };
    }
    Hold { headings: loiter, safety: Some(circling) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::kinematics::next_position;

    /// Three UAVs, two of them head-on 6 km apart, and no fix for 60 steps: holding course brings the
    /// pair together (they would meet at step 6), loitering keeps every pair above `D_min` at every
    /// step, each hold is certified, and no UAV strays further than the circle's diameter.
    #[test]
    fn a_swarm_without_a_fix_loiters_on_its_backup_circles_and_keeps_its_spacing() {
        let sc = Scenario { d_min: 500.0, r_min: 1000.0, speed: 50.0, dt: 10.0, ..Scenario::default() };
        let mut at = vec![Vector2::new(0.0, 0.0), Vector2::new(6000.0, 0.0), Vector2::new(3000.0, 8000.0)];
        let mut psi = vec![0.0, std::f64::consts::PI, -std::f64::consts::FRAC_PI_2];
        let start = at.clone();
        let radius = crate::shield::safety_limits(&sc).backup_radius();
        // Holding course: the head-on pair meets.
        let course_min = (1..=6)
            .map(|k| {
                let a = next_position(at[0], psi[0], psi[0], sc.speed, sc.dt * k as f64);
                let b = next_position(at[1], psi[1], psi[1], sc.speed, sc.dt * k as f64);
                (a - b).norm()
            })
            .fold(f64::INFINITY, f64::min);
        assert!(course_min < 1.0, "{course_min}");
        for step in 0..60 {
            let hold = without_plan(&at, &psi, &sc);
            let report = hold.safety.unwrap();
            assert!(report.certified, "step {step}: {report:?}");
            assert!(hold.loiters(&psi), "step {step}");
            assert!(report.min_pair_m.unwrap() >= sc.d_min, "step {step}: {report:?}");
            for i in 0..3 {
                at[i] = next_position(at[i], psi[i], hold.headings[i], sc.speed, sc.dt);
                assert!((at[i] - start[i]).norm() <= 2.0 * radius + 1e-6, "step {step}, UAV {i}");
            }
            psi = hold.headings;
        }
    }

    /// The paper's behaviour (`safety = "waypoints"`): the swarm holds course and nothing is checked.
    #[test]
    fn with_the_waypoint_planner_the_swarm_holds_course() {
        let sc = Scenario { safety: SafetyMode::Waypoints, ..Scenario::default() };
        let at = [Vector2::new(0.0, 0.0), Vector2::new(6000.0, 0.0), Vector2::new(3000.0, 8000.0)];
        let psi = [0.3, 1.0, -2.0];
        assert_eq!(without_plan(&at, &psi, &sc), Hold { headings: psi.to_vec(), safety: None });
    }

    /// A start whose backup circles conflict but whose straight legs do not: the swarm holds course,
    /// certified. UAV 0 heads north from the origin, UAV 1 south from (2 km, 2 km): their right-hand
    /// circles (radius 1 km) have centres 2 km apart and opposite phases, so they meet once a lap; their
    /// courses stay 2 km apart.
    #[test]
    fn where_the_circles_conflict_but_the_courses_do_not_the_swarm_holds_course() {
        let sc = Scenario { d_min: 500.0, r_min: 1000.0, speed: 50.0, dt: 10.0, ..Scenario::default() };
        let at = [Vector2::new(0.0, 0.0), Vector2::new(2000.0, 2000.0), Vector2::new(0.0, 20_000.0)];
        let psi = [std::f64::consts::FRAC_PI_2, -std::f64::consts::FRAC_PI_2, 0.0];
        let limits = SafetyLimits { l_min: 0.0, ..crate::shield::safety_limits(&sc) };
        let nowhere = EmitterPrediction::fixed(Vector2::zeros(), &Matrix2::zeros());
        let circling = certify(&at, &psi, &limits.backup_headings(&psi), &nowhere, &limits, true);
        assert!(!circling.certified && circling.backup_pair_m.unwrap() < sc.d_min, "{circling:?}");
        let hold = without_plan(&at, &psi, &sc);
        assert_eq!(hold.headings, psi.to_vec());
        assert!(!hold.loiters(&psi));
        let report = hold.safety.unwrap();
        assert!(report.certified && report.min_pair_m.unwrap() >= 2000.0 - 1e-6, "{report:?}");
    }

    /// The induction of the module docs over random states: 3–8 UAVs anywhere in 12 km, any headings,
    /// other speeds and radii; whenever a hold loiters certified, the hold after it (the next step of
    /// the same circles) is certified and loiters too, five steps on.
    #[test]
    fn a_certified_loiter_is_followed_by_a_certified_loiter() {
        let mut seed = 0x5eed_u64;
        let mut next = move || {
            seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut loitering = 0;
        for _ in 0..3000 {
            let n = 3 + (next() * 6.0) as usize;
            let sc = Scenario {
                d_min: 200.0 + next() * 800.0,
                r_min: 500.0 + next() * 1500.0,
                speed: 30.0 + next() * 50.0,
                uavs: vec![[0.0, 0.0]; n],
                ..Scenario::default()
            };
            let mut at: Vec<Vector2<f64>> = (0..n).map(|_| Vector2::new(next() * 12e3, next() * 12e3)).collect();
            let mut psi: Vec<f64> = (0..n).map(|_| (next() - 0.5) * std::f64::consts::TAU).collect();
            let first = without_plan(&at, &psi, &sc);
            if !(first.loiters(&psi) && first.safety.is_some_and(|r| r.certified)) {
                continue;
            }
            loitering += 1;
            let mut hold = first;
            for step in 0..5 {
                for i in 0..n {
                    at[i] = next_position(at[i], psi[i], hold.headings[i], sc.speed, sc.dt);
                }
                psi = hold.headings;
                hold = without_plan(&at, &psi, &sc);
                let report = hold.safety.unwrap();
                assert!(report.certified && hold.loiters(&psi), "step {step}: {report:?}");
            }
        }
        assert!(loitering > 300, "only {loitering} certified loiters");
    }
}
