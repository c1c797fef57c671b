//! The messages' layouts, constructors and accessors.

use super::*;

#[test]
fn layout_is_stable() {
    use core::mem::{align_of, size_of};
    // Changing any of these changes the wire format: bump the type names and VERSION constants.
    assert_eq!((size_of::<Stamps>(), align_of::<Stamps>()), (64, 8));
    assert_eq!((size_of::<Header>(), align_of::<Header>()), (88, 8));
    assert_eq!((size_of::<Name16>(), align_of::<Name16>()), (16, 1));
    assert_eq!((size_of::<Measurement>(), align_of::<Measurement>()), (672, 8));
    assert_eq!((size_of::<Estimate>(), align_of::<Estimate>()), (4304, 8));
    assert_eq!((size_of::<Command>(), align_of::<Command>()), (4280, 8));
    assert_eq!((size_of::<StateEcho>(), align_of::<StateEcho>()), (3920, 8));
    assert_eq!((size_of::<HeldBurst>(), align_of::<HeldBurst>()), (88, 8));
    assert_eq!((size_of::<HeldBursts>(), align_of::<HeldBursts>()), (360, 8));
    assert_eq!((size_of::<WindowBurst>(), align_of::<WindowBurst>()), (336, 8));
    assert_eq!((size_of::<TrackWindow>(), align_of::<TrackWindow>()), (2744, 8));
    assert_eq!((size_of::<Truth>(), align_of::<Truth>()), (112, 8));
    assert_eq!((size_of::<Control>(), align_of::<Control>()), (152, 8));
    assert_eq!((size_of::<EstimatorState>(), align_of::<EstimatorState>()), (4016, 8));
    assert_eq!((size_of::<SwarmState>(), align_of::<SwarmState>()), (736, 8));
}

#[test]
fn layout_has_no_implicit_padding() {
    use core::mem::{offset_of, size_of};
    // Every byte belongs to a field: offsets are contiguous.
    assert_eq!(offset_of!(Header, stamps) + size_of::<Stamps>(), size_of::<Header>());
    assert_eq!(offset_of!(Header, step), 8);
    assert_eq!(offset_of!(Measurement, clock_bias_sigmas_ns) + 8 * MAX_UAVS, size_of::<Measurement>());
    assert_eq!(offset_of!(Measurement, uavs), 96);
    assert_eq!(offset_of!(Estimate, position), 88 + 8 + 8 + 8);
    assert_eq!(offset_of!(Estimate, headings) + 8 * MAX_UAVS, offset_of!(Estimate, velocity));
    assert_eq!(offset_of!(Estimate, velocity_cov) + 32, offset_of!(Estimate, sigmas));
    assert_eq!(offset_of!(Estimate, bias_cov) + 32, offset_of!(Estimate, bias_sensitivity));
    assert_eq!(offset_of!(Estimate, bias_sensitivity) + 4 * 8 * MAX_UAVS, offset_of!(Estimate, alt_mean));
    assert_eq!(offset_of!(Estimate, alt_bias_sensitivity) + 4 * 8 * MAX_UAVS, offset_of!(Estimate, held));
    assert_eq!(offset_of!(Estimate, held) + size_of::<HeldBursts>(), offset_of!(Estimate, window));
    assert_eq!(offset_of!(Estimate, window) + size_of::<TrackWindow>(), size_of::<Estimate>());
    assert_eq!(offset_of!(Estimate, drop_run) + 1, offset_of!(Estimate, reserved));
    assert_eq!(offset_of!(Estimate, reserved) + 2, offset_of!(Estimate, position));
    assert_eq!(offset_of!(Command, objective), 88 + 40);
    assert_eq!(offset_of!(Command, objective_name) + 16, offset_of!(Command, state));
    assert_eq!(offset_of!(Command, state) + size_of::<StateEcho>(), size_of::<Command>());
    assert_eq!(offset_of!(StateEcho, drop_run) + 1, offset_of!(StateEcho, position));
    assert_eq!(offset_of!(StateEcho, velocity_cov) + 32, offset_of!(StateEcho, bias_sensitivity));
    assert_eq!(offset_of!(StateEcho, bias_sensitivity) + 4 * 8 * MAX_UAVS, offset_of!(StateEcho, alt_mean));
    assert_eq!(offset_of!(StateEcho, alt_bias_sensitivity) + 4 * 8 * MAX_UAVS, offset_of!(StateEcho, held));
    assert_eq!(offset_of!(StateEcho, held) + size_of::<HeldBursts>(), offset_of!(StateEcho, window));
    assert_eq!(offset_of!(StateEcho, window) + size_of::<TrackWindow>(), size_of::<StateEcho>());
    assert_eq!(offset_of!(HeldBurst, bias_sigmas) + 16, size_of::<HeldBurst>());
    assert_eq!(offset_of!(HeldBursts, bursts), 8);
    assert_eq!(offset_of!(WindowBurst, bias_sigmas) + 8 * MAX_UAVS, size_of::<WindowBurst>());
    assert_eq!(offset_of!(WindowBurst, positions), 16);
    assert_eq!(offset_of!(TrackWindow, base_matrix), 8);
    assert_eq!(offset_of!(TrackWindow, bursts), 56);
    assert_eq!(offset_of!(Truth, position) + 16, offset_of!(Truth, previous_command));
    assert_eq!(offset_of!(Truth, multipath) + 4, size_of::<Truth>());
    assert_eq!(offset_of!(Control, run), 88 + 24);
    assert_eq!(offset_of!(Control, role), 88 + 32);
    assert_eq!(offset_of!(Control, detail) + 16, size_of::<Control>());
}

#[test]
fn type_names_are_pinned_and_versioned() {
    fn check<T: Message>() {
        // SAFETY: `type_name` is an `unsafe fn` of the ZeroCopySend trait only because implementors must
        // keep it unique; calling it has no preconditions.
        let pinned = unsafe { <T as ZeroCopySend>::type_name() };
        assert_eq!(pinned, T::TYPE_NAME);
        assert!(pinned.starts_with("uavloc::"), "{pinned}");
        assert!(pinned.ends_with(&format!("/v{}", T::VERSION)), "{pinned} vs version {}", T::VERSION);
    }
    check::<Measurement>();
    check::<Estimate>();
    check::<Command>();
    check::<Truth>();
    check::<Control>();
}

#[test]
fn constructors_check_shapes() {
    let uavs = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
    assert!(Measurement::new(0, 0, &uavs, &[1.0, 2.0], &[1.0; 3], &[0.0; 3]).is_ok());
    assert_eq!(Measurement::new(0, 0, &uavs[..2], &[1.0], &[1.0; 2], &[0.0; 2]), Err(ProtocolError::BadCount(2)));
    assert_eq!(
        Measurement::new(0, 0, &uavs, &[1.0; 3], &[1.0; 3], &[0.0; 3]),
        Err(ProtocolError::LengthMismatch { field: "diffs", expected: 2, got: 3 })
    );
    assert!(matches!(Estimate::new(0, 0, 0, &[[0.0; 2]; 9], &[0.0; 9], Fix::Failed), Err(ProtocolError::BadCount(9))));
    let plan = PlanInfo {
        headings: &[0.0; 3],
        waypoints: &uavs,
        objective: 1.0,
        solver: "a-solver-name-too-long",
        objective_name: "trace",
        plan_time_us: 0,
        active_constraints: 0,
        violated_constraints: 0,
    };
    assert!(matches!(Command::new(0, 0, 0, &plan), Err(ProtocolError::BadName { field: "solver", .. })));
}

#[test]
fn names_round_trip_and_reject_bad_bytes() {
    let n = Name16::new("x", "trace-crlb").unwrap();
    assert_eq!(n.as_str(), Some("trace-crlb"));
    assert_eq!(Name16::new("x", "0123456789abcdef").unwrap().as_str(), Some("0123456789abcdef"));
    assert!(Name16::new("x", "").is_err());
    assert!(Name16::new("x", "ümlaut").is_err());
    assert!(Name16::new("x", "tab\there").is_err());
    assert_eq!(Name16::default().as_str(), None);
    let mut gap = n;
    gap.bytes[12] = b'x'; // a byte after the NUL terminator
    assert_eq!(gap.as_str(), None);
}

#[test]
fn stamps_carry_forward_and_give_latencies() {
    let uavs = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
    let mut cmd0 = Command::new(
        0,
        1,
        7,
        &PlanInfo {
            headings: &[0.0; 3],
            waypoints: &uavs,
            objective: 1.0,
            solver: "pso",
            objective_name: "trace",
            plan_time_us: 5,
            active_constraints: 0,
            violated_constraints: 0,
        },
    )
    .unwrap();
    cmd0.header.stamps.mark_published(MessageKind::Command, 100);
    let mut m = Measurement::new(1, 1, &uavs, &[1.0, 2.0], &[1.0; 3], &[0.0; 3]).unwrap().carrying(&cmd0, 110);
    m.header.stamps.mark_published(MessageKind::Measurement, 150);
    let mut e = Estimate::from_measurement(
        &m,
        160,
        1,
        9,
        Fix::Ok { position: [1.0, 2.0], covariance: [[1.0, 0.0], [0.0, 1.0]] },
    )
    .unwrap();
    assert_eq!(e.header.step, 1);
    assert_eq!(e.uavs(), m.uavs());
    e.header.stamps.mark_published(MessageKind::Estimate, 200);
    let mut c = Command::from_estimate(&e, 210, 2, 7, &cmd0_plan(&uavs)).unwrap();
    c.header.stamps.mark_published(MessageKind::Command, 300);
    let l = c.header.stamps.latencies();
    assert_eq!(
        l,
        Latencies {
            trigger_hop_ns: Some(10),
            emitter_ns: Some(40),
            measurement_hop_ns: Some(10),
            estimator_ns: Some(40),
            estimate_hop_ns: Some(10),
            planner_ns: Some(90),
            end_to_end_ns: Some(150),
            cycle_ns: Some(200),
        }
    );
    assert_eq!(c.header.stamps.age_ns(305), Some(5));
    // The next measurement starts a new chain.
    let next = Measurement::new(2, 2, &uavs, &[1.0, 2.0], &[1.0; 3], &[0.0; 3]).unwrap().carrying(&c, 320);
    assert_eq!(
        next.header.stamps,
        Stamps { trigger_command_published_ns: 300, trigger_command_received_ns: 320, ..Stamps::default() }
    );
    assert_eq!(Stamps::default().latencies(), Latencies::default());
    assert_eq!(span_ns(5, 3), None);
}

fn cmd0_plan(uavs: &[[f64; 2]]) -> PlanInfo<'_> {
    PlanInfo {
        headings: &[0.1, 0.2, 0.3],
        waypoints: uavs,
        objective: 2.0,
        solver: "pso",
        objective_name: "trace",
        plan_time_us: 80,
        active_constraints: 0b101,
        violated_constraints: 0,
    }
}

#[test]
fn now_ns_is_monotonic_and_nonzero() {
    let a = now_ns();
    let b = now_ns();
    assert!(a > 0 && b >= a);
}

/// Every wire enum decodes each of its values to its variant and nothing else to anything, and its
/// names are distinct lower-case words.
#[test]
fn wire_enums_decode_exactly_their_values() {
    fn check<T: Copy + PartialEq + fmt::Debug>(
        variants: &[T],
        code: impl Fn(T) -> u32,
        decode: impl Fn(u32) -> Option<T>,
        name: impl Fn(T) -> &'static str,
    ) {
        for &v in variants {
            assert_eq!(decode(code(v)), Some(v));
            assert!(name(v).chars().all(|c| c.is_ascii_lowercase() || c == '_'), "{}", name(v));
        }
        let codes: Vec<u32> = variants.iter().map(|v| code(*v)).collect();
        for c in 0..1000u32 {
            assert_eq!(decode(c).is_some(), codes.contains(&c), "{c}");
        }
        let mut names: Vec<&str> = variants.iter().map(|v| name(*v)).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), variants.len());
    }
    check(
        EstimateStatus::VARIANTS,
        |v| v as u32,
        |c| u8::try_from(c).ok().and_then(EstimateStatus::from_u8),
        EstimateStatus::name,
    );
    check(CommandOutcome::VARIANTS, |v| v as u32, CommandOutcome::from_u32, CommandOutcome::name);
    check(ControlKind::VARIANTS, |v| v as u32, ControlKind::from_u32, ControlKind::name);
    assert_eq!(
        (EstimateStatus::VARIANTS.len(), CommandOutcome::VARIANTS.len(), ControlKind::VARIANTS.len()),
        (5, 3, 8)
    );
}

/// A swarm state is checked like every message: count, link states, and the values of UAVs with a fix
/// (a UAV without one may hold anything).
#[test]
fn a_swarm_state_with_a_bad_fix_or_link_is_refused() {
    let mut s = SwarmState::new(3, 1, 3).unwrap();
    s.validate(None).unwrap();
    s.positions[1] = [f64::NAN, 0.0];
    s.validate(None).unwrap();
    s.fix_ns[1] = 5;
    assert!(matches!(s.validate(None), Err(Rejection::NotFinite { field: "positions" })));
    s.positions[1] = [1.0e8, 0.0];
    assert!(s.validate(None).is_err(), "beyond the plane");
    s.positions[1] = [100.0, 0.0];
    s.lat_lon_deg[1] = [95.0, 8.0];
    assert!(s.validate(None).is_err(), "latitude beyond 90");
    s.lat_lon_deg[1] = [47.0, 8.0];
    s.validate(None).unwrap();
    s.link[2] = 9;
    assert!(matches!(s.validate(None), Err(Rejection::UnknownKind { field: "link", kind: 9 })));
    s.link[2] = LinkState::Quiet as u32;
    assert_eq!(s.link_of(2), Some(LinkState::Quiet));
    assert!(matches!(s.validate(Some(1)), Err(Rejection::Stale { .. })));
    s.count = 9;
    assert!(matches!(s.validate(None), Err(Rejection::BadCount { count: 9 })));
    assert!(SwarmState::new(0, 0, 2).is_err());
}
