//! The validation rules, message by message: each rejection kind from a message that breaks one rule.

use super::*;
use crate::messages::{Fix, MessageKind, PlanInfo};

const UAVS: [[f64; 2]; 4] = [[0.0, 0.0], [1000.0, 0.0], [0.0, 1000.0], [1000.0, 1000.0]];

fn measurement() -> Measurement {
    Measurement::new(3, 10, &UAVS, &[10.0, -5.0, 2.5], &[3.0; 4], &[0.1, 0.2, 0.3, 0.4]).unwrap()
}

fn estimate() -> Estimate {
    let fix = Fix::Ok { position: [500.0, 400.0], covariance: [[4.0, 1.0], [1.0, 9.0]] };
    Estimate::new(3, 10, 42, &UAVS, &[0.1, 0.2, 0.3, 0.4], fix).unwrap()
}

fn command() -> Command {
    Command::new(
        3,
        10,
        7,
        &PlanInfo {
            headings: &[0.5; 4],
            waypoints: &UAVS,
            objective: 12.5,
            solver: "pso",
            objective_name: "trace-crlb",
            plan_time_us: 120,
            active_constraints: 0,
            violated_constraints: 0,
        },
    )
    .unwrap()
}

fn truth() -> Truth {
    Truth::new(3, 10, [480.0, 410.0])
}

#[test]
fn accepts_good_messages() {
    for last in [None, Some(0), Some(9)] {
        assert_eq!(measurement().validate(last), Ok(()));
        assert_eq!(estimate().validate(last), Ok(()));
        assert_eq!(command().validate(last), Ok(()));
        assert_eq!(truth().validate(last), Ok(()));
    }
    let ambiguous = Fix::Ambiguous { position: [1.0, 2.0], covariance: [[1.0, 0.0], [0.0, 1.0]] };
    assert_eq!(Estimate::new(0, 0, 1, &UAVS[..3], &[0.0; 3], ambiguous).unwrap().validate(None), Ok(()));
    let failed = Estimate::new(0, 0, 1, &UAVS[..3], &[0.0; 3], Fix::Failed).unwrap();
    assert!(failed.position[0].is_nan());
    assert_eq!(failed.validate(None), Ok(()), "a failed estimate's NaN position is not used");
    assert_eq!(failed.plan_from(), None, "no standing estimate yet");
    // A failed estimate that carries the standing estimate: it must be a valid one.
    let standing = failed.with_standing(Some(([5.0, 6.0], [[4.0, 1.0], [1.0, 3.0]])));
    assert_eq!(standing.validate(None), Ok(()));
    assert_eq!(standing.plan_from(), Some(([5.0, 6.0], [[4.0, 1.0], [1.0, 3.0]])));
    let bad = failed.with_standing(Some(([5.0, 6.0], [[1.0, 3.0], [3.0, 1.0]])));
    assert_eq!(bad.validate(None), Err(Rejection::NotPositiveDefinite));
    let mut half = failed;
    half.position[0] = 1.0;
    assert!(half.validate(None).is_err(), "a half-NaN standing estimate is rejected");
    let usable = Estimate::new(0, 0, 1, &UAVS[..3], &[0.0; 3], ambiguous).unwrap();
    assert_eq!(usable.with_standing(Some(([0.0; 2], [[1.0, 0.0], [0.0, 1.0]]))), usable, "only a failed one");
    let mut eight = [[0.0; 2]; 8];
    for (i, p) in eight.iter_mut().enumerate() {
        *p = [i as f64, 1.0];
    }
    assert_eq!(Measurement::new(0, 0, &eight, &[1.0; 7], &[1.0; 8], &[0.0; 8]).unwrap().validate(None), Ok(()));
}

#[test]
fn ignores_unused_entries() {
    let mut m = measurement();
    m.uavs[7] = [f64::NAN; 2];
    m.arrivals[6] = f64::INFINITY;
    m.sigmas[5] = -1.0;
    m.headings[4] = f64::NAN;
    m.reserved = [7, 7];
    assert_eq!(m.validate(None), Ok(()));
}

#[test]
fn rejects_bad_version() {
    let mut m = measurement();
    m.header.version = 1;
    assert_eq!(m.validate(None), Err(Rejection::BadVersion { expected: 2, got: 1 }));
    let mut e = estimate();
    e.header.version = 0;
    assert_eq!(e.validate(None).unwrap_err().kind(), "bad_version");
    let mut c = command();
    c.header.version = u32::MAX;
    assert_eq!(c.validate(None).unwrap_err().kind(), "bad_version");
    let mut t = truth();
    t.header.version = 9;
    assert_eq!(t.validate(None).unwrap_err().kind(), "bad_version");
}

#[test]
fn rejects_bad_count() {
    for count in [0, 1, 2, 9, 1000, u32::MAX] {
        let mut m = measurement();
        m.count = count;
        assert_eq!(m.validate(None), Err(Rejection::BadCount { count }));
        let mut e = estimate();
        e.count = count;
        assert_eq!(e.validate(None), Err(Rejection::BadCount { count }));
        let mut c = command();
        c.count = count;
        assert_eq!(c.validate(None), Err(Rejection::BadCount { count }));
        assert!(m.len() <= MAX_UAVS && m.arrivals().len() <= MAX_UAVS, "accessors clamp");
    }
}

#[test]
fn rejects_not_finite() {
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let cases = [
            ("uavs", with(measurement(), |m| m.uavs[3][1] = bad).validate(None)),
            ("arrivals", with(measurement(), |m| m.arrivals[2] = bad).validate(None)),
            ("sigmas", with(measurement(), |m| m.sigmas[0] = bad).validate(None)),
            ("headings", with(measurement(), |m| m.headings[1] = bad).validate(None)),
            ("uavs", with(estimate(), |e| e.uavs[0][0] = bad).validate(None)),
            ("headings", with(estimate(), |e| e.headings[3] = bad).validate(None)),
            ("position", with(estimate(), |e| e.position[1] = bad).validate(None)),
            ("covariance", with(estimate(), |e| e.covariance[1][0] = bad).validate(None)),
            ("objective", with(command(), |c| c.objective = bad).validate(None)),
            ("headings", with(command(), |c| c.headings[2] = bad).validate(None)),
            ("waypoints", with(command(), |c| c.waypoints[3][0] = bad).validate(None)),
            ("position", with(truth(), |t| t.position[0] = bad).validate(None)),
        ];
        for (field, case) in cases {
            assert_eq!(case, Err(Rejection::NotFinite { field }), "{field} = {bad}");
        }
    }
}

#[test]
fn rejects_non_positive_sigma() {
    for s in [0.0, -0.0, -1.0, -f64::MIN_POSITIVE] {
        let m = with(measurement(), |m| m.sigmas[2] = s);
        assert_eq!(m.validate(None), Err(Rejection::NonPositiveSigma { index: 2 }));
    }
    assert_eq!(with(measurement(), |m| m.sigmas[0] = MIN_SIGMA_M).validate(None), Ok(()));
}

/// Values every later check would pass, but the estimator or the planner could not use — so that the
/// step would never be commanded: refused at the wire, with the field named.
#[test]
fn rejects_what_the_maths_cannot_take() {
    let field = |m: Measurement| match m.validate(None) {
        Err(Rejection::BadField { field }) => field.split(' ').next().unwrap_or_default().to_string(),
        other => format!("{other:?}"),
    };
    // Each UAV's stated σ (range σ with GNSS and clock σ) within 1e-6..1e7 m.
    assert_eq!(field(with(measurement(), |m| m.sigmas[0] = f64::MIN_POSITIVE)), "stated");
    assert_eq!(field(with(measurement(), |m| m.sigmas[1] = 1.0001e7)), "stated");
    assert_eq!(with(measurement(), |m| m.sigmas[1] = MAX_SIGMA_M).validate(None), Ok(()));
    // A clock σ of 1e12 ns is 3e11 m of range; a GNSS σ of 1e8 m; the squares of 1e200 overflow.
    assert_eq!(field(with(measurement(), |m| m.clock_sigmas_ns[0] = 1.0e12)), "stated");
    assert_eq!(field(with(measurement(), |m| m.clock_bias_sigmas_ns[3] = 1.0e12)), "stated");
    assert_eq!(field(with(measurement(), |m| m.position_sigmas[2] = 1.0e8)), "stated");
    assert_eq!(field(with(measurement(), |m| m.position_bias_sigmas[1] = 1.0e200)), "stated");
    assert_eq!(with(measurement(), |m| m.clock_sigmas_ns[0] = 1.0e5).validate(None), Ok(()));
    // A GNSS σ beside a tiny range σ lifts the stated σ into range.
    let lifted = with(measurement(), |m| {
        m.sigmas[0] = 1.0e-9;
        m.position_sigmas[0] = 1.0;
    });
    assert_eq!(lifted.validate(None), Ok(()));
    // Positions within the plane's extent.
    assert_eq!(field(with(measurement(), |m| m.uavs[1][0] = 1.0e9)), "uavs");
    assert_eq!(field(with(measurement(), |m| m.uavs[3][1] = -SWARM_EXTENT_M * 1.0001)), "uavs");
    assert_eq!(with(measurement(), |m| m.uavs[3][1] = -SWARM_EXTENT_M).validate(None), Ok(()));
    // Arrivals near their epoch; only the heard ones count.
    assert_eq!(field(with(measurement(), |m| m.arrivals[2] = 5.0e17)), "arrivals");
    assert_eq!(field(with(measurement(), |m| m.arrivals[0] = -1.0e300)), "arrivals");
    assert_eq!(with(measurement(), |m| m.arrivals[2] = MAX_ARRIVAL_M).validate(None), Ok(()));
    // An estimate's stated σ, which the planner plans with, the same.
    let stated = |s: f64| {
        let mut e = estimate();
        e.sigmas[..4].fill(30.0);
        e.sigmas[1] = s;
        e.validate(None)
    };
    assert_eq!(stated(30.0), Ok(()));
    assert_eq!(stated(MAX_SIGMA_M), Ok(()));
    assert!(matches!(stated(1.0e8), Err(Rejection::BadField { .. })));
    assert!(matches!(stated(1.0e-9), Err(Rejection::BadField { .. })));
    let unheard = with(measurement(), |m| {
        m.heard &= !(1 << 2);
        m.arrivals[2] = 5.0e17;
    });
    assert_eq!(unheard.validate(None), Ok(()));
}

#[test]
fn rejects_not_positive_definite() {
    for cov in [
        [[0.0, 0.0], [0.0, 1.0]],
        [[-1.0, 0.0], [0.0, 1.0]],
        [[1.0, 0.0], [0.0, -1.0]],
        [[1.0, 1.0], [1.0, 1.0]],                               // singular
        [[1.0, 2.0], [2.0, 1.0]],                               // indefinite
        [[4.0, 1.0], [1.1, 9.0]],                               // not symmetric
        [[1e300, 1e300], [1e300, 1e300]],                       // singular, where the determinant would overflow
        [[1e-310, 0.0], [0.0, 1e-310]],                         // subnormal variances: no inverse in floating point
        [[1e-307, -9.9999999e-308], [-9.9999999e-308, 1e-307]], // an inverse beyond the floats
        [[1e308, 0.0], [0.0, 1e308]],                           // a trace beyond the floats
    ] {
        let e = with(estimate(), |e| e.covariance = cov);
        assert_eq!(e.validate(None), Err(Rejection::NotPositiveDefinite), "{cov:?}");
    }
    for cov in [
        [[1e300, 0.0], [0.0, 1e300]],
        [[1e-300, 0.0], [0.0, 1e-300]],
        [[4.0, 1.0], [1.0 + 1e-12, 9.0]],
        [[2.0, -1.999], [-1.999, 2.0]],
    ] {
        assert!(is_symmetric_positive_definite(&cov), "{cov:?}");
    }
}

/// What the planner plans with — the covariance plus the biases' `bias_cov` — must be a covariance
/// it takes: a `bias_cov` that is not positive semi-definite, or a sum beyond the floats, is refused.
#[test]
fn the_covariance_planned_with_is_one_the_planner_takes() {
    let field = |e: Estimate| e.validate(None).map_err(|r| r.kind());
    assert_eq!(field(with(estimate(), |e| e.bias_cov = [[4.0, 2.0], [2.0, 1.0]])), Ok(())); // rank one
    assert_eq!(field(with(estimate(), |e| e.bias_cov = [[0.0; 2]; 2])), Ok(()));
    for bad in [[[-1.0, 0.0], [0.0, 1.0]], [[1.0, 2.0], [2.0, 1.0]], [[1.0, 0.5], [0.4, 1.0]]] {
        assert_eq!(field(with(estimate(), |e| e.bias_cov = bad)), Err("bad_field"), "{bad:?}");
    }
    let huge = with(estimate(), |e| {
        e.covariance = [[1e308, 0.0], [0.0, 1.0]];
        e.bias_cov = [[1e308, 0.0], [0.0, 0.0]];
    });
    assert_eq!(field(huge), Err("not_positive_definite"));
}

#[test]
fn checks_the_fused_state_fields() {
    assert_eq!(with(estimate(), |e| e.status = 3).fix().map(|f| f.status()), Some(EstimateStatus::Rejected));
    assert_eq!(with(estimate(), |e| e.status = 3).validate(None), Ok(()));
    assert_eq!(
        with(estimate(), |e| e.estimator = 2).validate(None),
        Err(Rejection::UnknownKind { field: "estimator", kind: 2 })
    );
    assert_eq!(
        with(estimate(), |e| e.model = 7).validate(None),
        Err(Rejection::UnknownKind { field: "model", kind: 7 })
    );
    let cv = |e: &mut Estimate| {
        e.estimator = 1;
        e.model = 1;
    };
    assert_eq!(with(estimate(), cv).validate(None), Ok(()));
    assert_eq!(
        with(estimate(), |e| {
            cv(e);
            e.velocity[1] = f64::NAN;
        })
        .validate(None),
        Err(Rejection::NotFinite { field: "velocity" })
    );
}

#[test]
fn rejects_unknown_status() {
    for status in [5u8, 6, 128, 255] {
        let e = with(estimate(), |e| e.status = status);
        assert_eq!(e.validate(None), Err(Rejection::UnknownStatus { status }));
        assert_eq!(e.fix(), None);
    }
}

#[test]
fn checks_the_previous_command_of_a_truth() {
    use crate::messages::CommandOutcome;
    assert_eq!(truth().previous_command(), Some(CommandOutcome::None));
    for outcome in [CommandOutcome::None, CommandOutcome::Flown, CommandOutcome::Missed] {
        let t = truth().with_previous_command(outcome);
        assert_eq!((t.validate(None), t.previous_command()), (Ok(()), Some(outcome)));
        assert_eq!(CommandOutcome::from_u32(outcome as u32), Some(outcome));
    }
    assert_eq!(CommandOutcome::Missed.name(), "missed");
    for bad in [3u32, 17, u32::MAX] {
        let t = with(truth(), |t| t.previous_command = bad);
        assert_eq!(t.validate(None), Err(Rejection::UnknownKind { field: "previous_command", kind: bad }));
        assert_eq!(t.previous_command(), None);
    }
    // The multipath mask: one bit per UAV (at most 8).
    assert_eq!(with(truth(), |t| t.multipath = 0b101).validate(None), Ok(()));
    assert_eq!(
        with(truth(), |t| t.multipath = 0x100).validate(None),
        Err(Rejection::UnknownKind { field: "multipath", kind: 0x100 })
    );
}

#[test]
fn rejects_stale() {
    assert_eq!(measurement().validate(Some(10)), Err(Rejection::Stale { seq: 10, last: 10 }));
    assert_eq!(estimate().validate(Some(11)), Err(Rejection::Stale { seq: 10, last: 11 }));
    assert_eq!(command().validate(Some(u64::MAX)), Err(Rejection::Stale { seq: 10, last: u64::MAX }));
    assert_eq!(truth().validate(Some(10)).unwrap_err().kind(), "stale");
}

#[test]
fn the_echoed_state_is_the_estimate_planned_from_and_is_checked_like_it() {
    use crate::messages::{EchoedState, StateEcho};
    // A usable estimate: its fix and posterior fields.
    let e = estimate().with_extra(&crate::PosteriorExtra {
        estimator: 1,
        model: 1,
        rejected_run: 2,
        confirmed: 3,
        drop_uavs: 0b100,
        drop_run: 2,
        velocity: [1.0, -2.0],
        cross_cov: [[0.1, 0.2], [0.3, 0.4]],
        velocity_cov: [[5.0, 0.5], [0.5, 6.0]],
        bias_sensitivity: [[0.5; crate::MAX_UAVS]; 4],
        alternative: 1,
        alt_mean: [1.0, 2.0, 0.0, 0.0],
        alt_cov: [[4.0, 0.0, 0.0, 0.0], [0.0, 4.0, 0.0, 0.0], [0.0; 4], [0.0; 4]],
        alt_bias_sensitivity: [[0.25; crate::MAX_UAVS]; 4],
        window: crate::TrackWindow {
            open: 1,
            count: 1,
            base_matrix: [[1e-4, 0.0], [0.0, 2e-4]],
            base_vector: [2.5, 3.0],
            bursts: [crate::WindowBurst {
                step: 2,
                count: 4,
                heard: 0b1011,
                positions: [[1000.0, 2000.0]; crate::MAX_UAVS],
                arrivals: [5.0, 7.0, 0.0, 9.0, 0.0, 0.0, 0.0, 0.0],
                sigmas: [30.0; crate::MAX_UAVS],
                bias_sigmas: [0.0; crate::MAX_UAVS],
                ..crate::WindowBurst::default()
            }; crate::MAX_WINDOW_BURSTS],
            ..crate::TrackWindow::default()
        },
    });
    let c = command().with_state_of(&e);
    assert_eq!(c.validate(None), Ok(()));
    match c.state.decode() {
        Some(EchoedState::State { step, estimate: (p, m), extra }) => {
            assert_eq!((step, p, m), (3, e.position, e.covariance));
            assert_eq!(extra, e.extra());
        }
        other => panic!("{other:?}"),
    }
    // A failed one: its standing estimate, or no state yet.
    let failed = Estimate::new(4, 11, 42, &UAVS, &[0.1; 4], Fix::Failed).unwrap();
    let standing = failed.with_standing(Some(([7.0, 8.0], [[2.0, 0.0], [0.0, 2.0]])));
    assert!(matches!(
        StateEcho::of(&standing).unwrap().decode(),
        Some(EchoedState::State { step: 4, estimate: ([7.0, 8.0], _), .. })
    ));
    assert_eq!(
        StateEcho::of(&failed).unwrap().decode(),
        Some(EchoedState::Empty { step: 4, held: crate::HeldBursts::default() })
    );
    // A hold echoes nothing; a bad echo is rejected with the command.
    assert_eq!(command().state.decode(), None);
    assert_eq!(command().validate(None), Ok(()));
    let bad = |f: fn(&mut StateEcho)| with(c, |c| f(&mut c.state)).validate(None).unwrap_err().kind();
    assert_eq!(bad(|s| s.position[1] = f64::NAN), "not_finite");
    assert_eq!(bad(|s| s.covariance[1][1] = -1.0), "not_positive_definite");
    assert_eq!(bad(|s| s.kind = 3), "unknown_kind");
    assert_eq!(bad(|s| s.velocity_cov[0][0] = f64::INFINITY), "not_finite");
    assert_eq!(bad(|s| s.bias_sensitivity[3][7] = f64::NAN), "not_finite");
    assert_eq!(bad(|s| s.alt_cov[2][1] = f64::NAN), "not_finite");
    // The window: its summary, each burst's arrivals where kept, its σ, its mask and count.
    assert_eq!(bad(|s| s.window.base_vector[1] = f64::NAN), "not_finite");
    assert_eq!(bad(|s| s.window.bursts[0].arrivals[3] = f64::NAN), "not_finite");
    assert_eq!(bad(|s| s.window.bursts[0].sigmas[2] = 0.0), "bad_field");
    assert_eq!(bad(|s| s.window.bursts[0].heard = 0b1_0000), "bad_field");
    assert_eq!(bad(|s| s.window.count = 9), "bad_field");
    assert_eq!(bad(|s| s.window.open = 2), "unknown_kind");
    // An arrival not kept is not read, and a closed window not at all.
    assert_eq!(with(c, |c| c.state.window.bursts[0].arrivals[2] = f64::NAN).validate(None), Ok(()));
    assert_eq!(
        with(c, |c| {
            c.state.window.open = 0;
            c.state.window.count = 200
        })
        .validate(None),
        Ok(())
    );
    assert_eq!(bad(|s| s.alternative = 2), "unknown_kind");

    // The monitor's answer to a state request carries the echo, checked the same way; a hold is no
    // state to send.
    let answer = crate::EstimatorState::new(c.state, 7, 1);
    assert_eq!((answer.header.step, answer.validate(Some(6))), (3, Ok(())));
    assert_eq!(answer.validate(Some(7)).unwrap_err().kind(), "stale");
    assert_eq!(crate::EstimatorState::new(command().state, 7, 1).validate(None).unwrap_err().kind(), "unknown_kind");
    let mut bad_answer = answer;
    bad_answer.state.covariance[0][0] = f64::NAN;
    assert_eq!(bad_answer.validate(None).unwrap_err().kind(), "not_finite");
}

#[test]
fn checks_control_messages() {
    let c = Control::new(ControlKind::Hello, 0, 5, 9, 100, "planner", "ga/analytical").unwrap();
    assert_eq!(c.validate(Some(4)), Ok(()));
    assert_eq!((c.kind(), c.role(), c.detail()), (Some(ControlKind::Hello), Some("planner"), "ga/analytical"));
    // A planner's `solver/objective` longer than the field is cut, not refused (it stopped the
    // planner of `--solver gradient` and of `--objective posterior-cubature` at start).
    let long = Control::new(ControlKind::Hello, 0, 1, 7, 1, "planner", "gradient/posterior-cubature").unwrap();
    assert_eq!((long.validate(None), long.detail()), (Ok(()), "gradient/posteri"));
    let plain = Control::new(ControlKind::Shutdown, 0, 5, 9, 100, "launcher", "").unwrap();
    assert_eq!((plain.validate(None), plain.detail()), (Ok(()), ""));
    assert_eq!(c.validate(Some(5)).unwrap_err().kind(), "stale");
    assert_eq!(with(c, |c| c.kind = 5).validate(None), Ok(()), "5 is a status (v3)");
    assert_eq!(with(c, |c| c.kind = 6).validate(None), Ok(()), "6 asks for a state (v4)");
    assert_eq!(with(c, |c| c.kind = 7).validate(None), Ok(()), "7 tells a process of another run to leave (v5)");
    assert_eq!(with(c, |c| c.kind = 8).validate(None), Err(Rejection::UnknownKind { field: "control kind", kind: 8 }));
    // Any run: a fingerprint, or 0 for a sender without a scenario.
    assert_eq!((c.run, c.with_run(u64::MAX).validate(None)), (0, Ok(())));
    assert_eq!(with(c, |c| c.role.bytes = [0; 16]).validate(None), Err(Rejection::BadName { field: "role" }));
    assert_eq!(with(c, |c| c.detail.bytes[0] = 0x80).validate(None).unwrap_err().kind(), "bad_name");
    assert_eq!(with(c, |c| c.header.version = 1).validate(None).unwrap_err().kind(), "bad_version");
    let replay = Control::new(ControlKind::Replay, ControlKind::IN_FLIGHT, 6, 9, 100, "planner", "").unwrap();
    assert_eq!((replay.validate(None), replay.kind()), (Ok(()), Some(ControlKind::Replay)));
}

#[test]
fn rejects_bad_name() {
    let c = with(command(), |c| c.solver.bytes = [0; 16]);
    assert_eq!(c.validate(None), Err(Rejection::BadName { field: "solver" }));
    let c = with(command(), |c| c.objective_name.bytes[0] = 0xC3);
    assert_eq!(c.validate(None), Err(Rejection::BadName { field: "objective_name" }));
    let c = with(command(), |c| c.solver.bytes[15] = b'\n');
    assert_eq!(c.validate(None).unwrap_err().kind(), "bad_name");
}

#[test]
fn a_receiver_that_knows_its_run_rejects_data_of_another_run_and_moves_nothing() {
    let mut counter = RejectionCounter::new();
    let of_run = |run: u32, seq: u64| with(truth(), |t| (t.header.run, t.header.seq) = (run, seq));
    // No run known: any run is accepted.
    let mut last = None;
    assert_eq!(counter.check(&of_run(0xAB, 5), &mut last), Ok(()));
    counter.set_run(0x1234);
    // Another run (with a newer sequence number) is rejected before its number is looked at: the
    // stream's last accepted number stays.
    let r = counter.check(&of_run(0x9999, u64::MAX), &mut last).unwrap_err();
    assert_eq!((r, r.kind()), (Rejection::OtherRun { expected: 0x1234, got: 0x9999 }, "other_run"));
    assert_eq!(last, Some(5));
    // This run, and no run stated (a foreign front end), are accepted.
    assert_eq!(counter.check(&of_run(0x1234, 6), &mut last), Ok(()));
    assert_eq!(counter.check(&of_run(0, 7), &mut last), Ok(()));
    assert_eq!(last, Some(7));
    assert_eq!(counter.count(MessageKind::Truth, "other_run"), 1);
    // Control messages state their run themselves (how another run is told to leave): exempt.
    let mut c = Control::new(ControlKind::Hello, 0, 1, 7, 1, "planner", "").unwrap();
    c.header.run = 0x9999;
    assert_eq!(counter.check(&c, &mut None), Ok(()));
    // adopt_run takes a run only while none is known.
    let mut fresh = RejectionCounter::new();
    fresh.adopt_run(0);
    fresh.adopt_run(0x77);
    fresh.adopt_run(0x88);
    assert_eq!(fresh.run(), 0x77);
}

#[test]
fn run_tags_are_never_zero_for_a_run() {
    assert_eq!(crate::run_tag(0), 0);
    assert_eq!(crate::run_tag(0xFFFF_FFFF_FFFF_FFFF), 1);
    assert_eq!(crate::run_tag(0x0000_0001_0000_0001), 1);
    assert_eq!(crate::run_tag(0x1234_5678_0000_0000), 0x1234_5678);
}

#[test]
fn kinds_are_stable_and_distinct() {
    let all = [
        Rejection::BadVersion { expected: 1, got: 2 },
        Rejection::BadCount { count: 0 },
        Rejection::NotFinite { field: "x" },
        Rejection::NonPositiveSigma { index: 0 },
        Rejection::NotPositiveDefinite,
        Rejection::UnknownStatus { status: 9 },
        Rejection::Stale { seq: 1, last: 2 },
        Rejection::BadName { field: "solver" },
        Rejection::UnknownKind { field: "control kind", kind: 7 },
        Rejection::OtherRun { expected: 1, got: 2 },
    ];
    for (i, r) in all.iter().enumerate() {
        assert_eq!(r.kind_index(), i);
        assert_eq!(r.kind(), Rejection::KINDS[i]);
        assert!(!r.to_string().is_empty());
    }
}

#[test]
fn counter_tracks_seq_and_counts() {
    let mut counter = RejectionCounter::new();
    assert_eq!(counter.to_string(), "rejected 0");
    let mut last = None;
    assert!(counter.check(&measurement(), &mut last).is_ok());
    assert_eq!(last, Some(10));
    assert_eq!(counter.check(&measurement(), &mut last), Err(Rejection::Stale { seq: 10, last: 10 }));
    let mut next = measurement();
    next.header.seq = 11;
    next.count = 1;
    assert_eq!(counter.check(&next, &mut last).unwrap_err().kind(), "bad_count");
    assert_eq!(last, Some(10), "a rejected message does not advance the stream");
    next.count = 4;
    assert!(counter.check(&next, &mut last).is_ok());
    assert_eq!(last, Some(11));
    let mut cmd_last = None;
    let bad = with(command(), |c| c.objective = f64::NAN);
    assert!(counter.check(&bad, &mut cmd_last).is_err());
    assert_eq!(cmd_last, None);

    assert_eq!(counter.accepted(MessageKind::Measurement), 2);
    assert_eq!(counter.rejected(MessageKind::Measurement), 2);
    assert_eq!(counter.count(MessageKind::Measurement, "stale"), 1);
    assert_eq!(counter.count(MessageKind::Command, "not_finite"), 1);
    assert_eq!(counter.count(MessageKind::Command, "no_such_kind"), 0);
    assert_eq!(counter.total(), 3);
    assert_eq!(counter.to_string(), "rejected 3 (measurement: bad_count 1, stale 1; command: not_finite 1)");
}

fn with<T>(mut msg: T, f: impl FnOnce(&mut T)) -> T {
    f(&mut msg);
    msg
}
