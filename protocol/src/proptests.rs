//! Property tests: validation of arbitrary bytes never panics and never accepts a non-finite used float.

use core::mem::size_of;

use proptest::prelude::*;

use crate::messages::{
    AnyBitPattern, Command, Control, Estimate, EstimateStatus, Fix, Measurement, Message, PlanInfo, Truth,
};
use crate::validate::{Rejection, is_symmetric_positive_definite};
use crate::{MAX_UAVS, MIN_UAVS};

fn bytes_of<T: AnyBitPattern>() -> impl Strategy<Value = Vec<u8>> {
    proptest::collection::vec(any::<u8>(), size_of::<T>())
}

/// Non-finite values, and a few finite ones so that "poisoning" is not always effective.
fn bad_float() -> impl Strategy<Value = f64> {
    prop_oneof![Just(f64::NAN), Just(f64::INFINITY), Just(f64::NEG_INFINITY), Just(-f64::NAN)]
}

/// The floats `validate` must look at, by an independent reading of the spec (`None` if the count is bad).
fn used_floats<T: Message>(msg: &T) -> Option<Vec<f64>> {
    let any = msg as &dyn core::any::Any;
    let n_of = |count: u32| {
        let n = count as usize;
        (MIN_UAVS..=MAX_UAVS).contains(&n).then_some(n)
    };
    if let Some(m) = any.downcast_ref::<Measurement>() {
        let n = n_of(m.count)?;
        let mut v: Vec<f64> = m.uavs[..n].iter().flatten().copied().collect();
        v.extend((0..n).filter(|&i| m.heard & (1u8 << i) != 0).map(|i| m.arrivals[i]));
        v.extend(&m.sigmas[..n]);
        v.extend(&m.headings[..n]);
        v.extend(&m.position_sigmas[..n]);
        v.extend(&m.position_bias_sigmas[..n]);
        v.extend(&m.clock_sigmas_ns[..n]);
        v.extend(&m.clock_bias_sigmas_ns[..n]);
        Some(v)
    } else if let Some(e) = any.downcast_ref::<Estimate>() {
        let n = n_of(e.count)?;
        let mut v: Vec<f64> = e.uavs[..n].iter().flatten().copied().collect();
        v.extend(&e.headings[..n]);
        if e.status != EstimateStatus::Failed as u8 {
            v.extend(&e.position);
            v.extend(e.covariance.iter().flatten());
        }
        v.extend(e.bias_cov.iter().flatten());
        Some(v)
    } else if let Some(c) = any.downcast_ref::<Command>() {
        let n = n_of(c.count)?;
        let mut v = vec![c.objective];
        v.extend(&c.headings[..n]);
        v.extend(c.waypoints[..n].iter().flatten());
        Some(v)
    } else if let Some(t) = any.downcast_ref::<Truth>() {
        Some(t.position.to_vec())
    } else if any.downcast_ref::<Control>().is_some() {
        Some(Vec::new())
    } else {
        unreachable!()
    }
}

/// Validation of arbitrary content: never panics; an accepted message has every used float finite, the
/// right version, a sequence number above `last`, and passes the type's own invariants.
fn check_arbitrary<T: Message>(msg: &T, last: Option<u64>) -> Result<(), TestCaseError> {
    let verdict = msg.validate(last);
    if let Err(r) = &verdict {
        let _ = (r.kind(), r.to_string());
    }
    let used = used_floats(msg);
    if let Some(used) = &used
        && used.iter().any(|v| !v.is_finite())
    {
        prop_assert!(verdict.is_err(), "accepted a non-finite used float: {msg:?}");
    }
    if verdict.is_ok() {
        prop_assert_eq!(msg.header().version, T::VERSION);
        prop_assert!(last.is_none_or(|l| msg.header().seq > l));
        prop_assert!(used.is_some_and(|u| u.iter().all(|v| v.is_finite())));
        let any = msg as &dyn core::any::Any;
        if let Some(m) = any.downcast_ref::<Measurement>() {
            prop_assert!(m.sigmas().iter().all(|&s| s > 0.0));
            prop_assert_eq!(m.arrivals().len(), m.uavs().len());
        }
        if let Some(e) = any.downcast_ref::<Estimate>() {
            let status = e.status();
            prop_assert!(status.is_some());
            if status != Some(EstimateStatus::Failed) {
                prop_assert!(is_symmetric_positive_definite(&e.covariance));
            }
        }
        if let Some(c) = any.downcast_ref::<Command>() {
            prop_assert!(c.solver().is_some() && c.objective_name().is_some());
        }
        if let Some(c) = any.downcast_ref::<Control>() {
            prop_assert!(c.kind().is_some() && c.role().is_some());
        }
        if let Some(t) = any.downcast_ref::<Truth>() {
            prop_assert!(t.previous_command().is_some());
        }
    }
    Ok(())
}

/// Makes the header and count plausible so validation gets past the first checks.
fn patch<T: Message>(msg: &mut T, count: u32, status: u8) {
    msg.header_mut().version = T::VERSION;
    let any = msg as &mut dyn core::any::Any;
    if let Some(m) = any.downcast_mut::<Measurement>() {
        m.count = count;
    } else if let Some(e) = any.downcast_mut::<Estimate>() {
        e.count = count;
        e.status = status;
    } else if let Some(c) = any.downcast_mut::<Command>() {
        c.count = count;
        c.solver = crate::Name16::new("s", "pso").unwrap();
        c.objective_name = crate::Name16::new("o", "trace").unwrap();
    } else if let Some(t) = any.downcast_mut::<Truth>() {
        // 0, 1 and 2 are the known outcomes; 3 is not.
        t.previous_command = u32::from(status);
    }
}

/// Sets the `index`-th used float (modulo their number) to `bad`.
fn poison<T: Message>(msg: &mut T, index: usize, bad: f64) {
    let any = msg as &mut dyn core::any::Any;
    let mut slots: Vec<&mut f64> = if let Some(m) = any.downcast_mut::<Measurement>() {
        let n = m.count as usize;
        let heard = m.heard;
        let mut v: Vec<&mut f64> = m.uavs[..n].iter_mut().flatten().collect();
        v.extend(m.arrivals[..n].iter_mut().enumerate().filter(|(i, _)| heard & (1u8 << i) != 0).map(|(_, a)| a));
        v.extend(&mut m.sigmas[..n]);
        v.extend(&mut m.headings[..n]);
        v.extend(&mut m.position_sigmas[..n]);
        v.extend(&mut m.position_bias_sigmas[..n]);
        v.extend(&mut m.clock_sigmas_ns[..n]);
        v.extend(&mut m.clock_bias_sigmas_ns[..n]);
        v
    } else if let Some(e) = any.downcast_mut::<Estimate>() {
        let n = e.count as usize;
        let mut v: Vec<&mut f64> = e.uavs[..n].iter_mut().flatten().collect();
        v.extend(&mut e.headings[..n]);
        if e.status != EstimateStatus::Failed as u8 {
            // A failed estimate's position and covariance are not used: poisoning them proves nothing.
            v.extend(&mut e.position);
            v.extend(e.covariance.iter_mut().flatten());
        }
        v.extend(e.bias_cov.iter_mut().flatten());
        v
    } else if let Some(c) = any.downcast_mut::<Command>() {
        let n = c.count as usize;
        let mut v: Vec<&mut f64> = vec![&mut c.objective];
        v.extend(&mut c.headings[..n]);
        v.extend(c.waypoints[..n].iter_mut().flatten());
        v
    } else if let Some(t) = any.downcast_mut::<Truth>() {
        t.position.iter_mut().collect()
    } else {
        unreachable!()
    };
    let len = slots.len();
    *slots[index % len] = bad;
}

/// Poisoned, otherwise plausible messages are rejected, as NotFinite (or an earlier structural reason).
fn check_poisoned<T: Message>(
    bytes: &[u8],
    count: u32,
    status: u8,
    index: usize,
    bad: f64,
    last: Option<u64>,
) -> Result<(), TestCaseError> {
    let mut msg = T::from_bytes(bytes).expect("the strategy gives size_of::<T>() bytes");
    patch(&mut msg, count, status);
    poison(&mut msg, index, bad);
    check_arbitrary(&msg, last)?;
    let is_estimate = (&msg as &dyn core::any::Any).is::<Estimate>();
    let is_truth = (&msg as &dyn core::any::Any).is::<Truth>();
    match msg.validate(last) {
        Err(Rejection::NotFinite { .. }) => {}
        Err(Rejection::UnknownStatus { .. }) if is_estimate && EstimateStatus::from_u8(status).is_none() => {}
        Err(Rejection::UnknownKind { field: "previous_command", .. }) if is_truth && status > 2 => {}
        other => prop_assert!(false, "poisoned message gave {other:?}: {msg:?}"),
    }
    Ok(())
}

fn finite() -> impl Strategy<Value = f64> {
    -1e6..1e6f64
}

proptest! {
    // A fixed seed: a failure is reproduced by running the test again (no regression files).
    #![proptest_config(ProptestConfig {
        cases: 512,
        rng_seed: proptest::test_runner::RngSeed::Fixed(0x0D0C_0A5E_ED01),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn arbitrary_measurement(bytes in bytes_of::<Measurement>(), last in any::<Option<u64>>()) {
        check_arbitrary(&Measurement::from_bytes(&bytes).unwrap(), last)?;
    }

    #[test]
    fn arbitrary_estimate(bytes in bytes_of::<Estimate>(), last in any::<Option<u64>>()) {
        check_arbitrary(&Estimate::from_bytes(&bytes).unwrap(), last)?;
    }

    #[test]
    fn arbitrary_command(bytes in bytes_of::<Command>(), last in any::<Option<u64>>()) {
        check_arbitrary(&Command::from_bytes(&bytes).unwrap(), last)?;
    }

    #[test]
    fn arbitrary_control(bytes in bytes_of::<Control>(), last in any::<Option<u64>>()) {
        check_arbitrary(&Control::from_bytes(&bytes).unwrap(), last)?;
    }

    #[test]
    fn arbitrary_truth(bytes in bytes_of::<Truth>(), last in any::<Option<u64>>()) {
        check_arbitrary(&Truth::from_bytes(&bytes).unwrap(), last)?;
    }

    #[test]
    fn patched_arbitrary_messages(
        m in bytes_of::<Measurement>(),
        e in bytes_of::<Estimate>(),
        c in bytes_of::<Command>(),
        t in bytes_of::<Truth>(),
        count in 0u32..12,
        status in 0u8..6,
        last in any::<Option<u64>>(),
    ) {
        let mut m = Measurement::from_bytes(&m).unwrap();
        patch(&mut m, count, status);
        check_arbitrary(&m, last)?;
        let mut e = Estimate::from_bytes(&e).unwrap();
        patch(&mut e, count, status);
        check_arbitrary(&e, last)?;
        let mut c = Command::from_bytes(&c).unwrap();
        patch(&mut c, count, status);
        check_arbitrary(&c, last)?;
        let mut t = Truth::from_bytes(&t).unwrap();
        patch(&mut t, count, status);
        check_arbitrary(&t, last)?;
    }

    #[test]
    fn poisoned_messages_are_rejected(
        m in bytes_of::<Measurement>(),
        e in bytes_of::<Estimate>(),
        c in bytes_of::<Command>(),
        t in bytes_of::<Truth>(),
        count in 3u32..=8,
        status in 0u8..6,
        index in any::<usize>(),
        bad in bad_float(),
        last in any::<Option<u64>>(),
    ) {
        check_poisoned::<Measurement>(&m, count, status, index, bad, last)?;
        check_poisoned::<Estimate>(&e, count, status, index, bad, last)?;
        check_poisoned::<Command>(&c, count, status, index, bad, last)?;
        check_poisoned::<Truth>(&t, count, status, index, bad, last)?;
    }

    #[test]
    fn sane_messages_are_accepted(
        n in 3usize..=8,
        uavs in proptest::collection::vec([finite(), finite()], 8),
        vals in proptest::collection::vec(finite(), 8),
        sigma in 1e-3..1e3f64,
        var in (1e-6..1e6f64, 1e-6..1e6f64, -0.99..0.99f64),
        seq in 1u64..u64::MAX,
    ) {
        let (vx, vy, rho) = var;
        let cov = [[vx, rho * (vx * vy).sqrt()], [rho * (vx * vy).sqrt(), vy]];
        let m = Measurement::new(0, seq, &uavs[..n], &vals[..n - 1], &vec![sigma; n], &vals[..n]).unwrap();
        prop_assert_eq!(m.validate(Some(seq - 1)), Ok(()));
        let e = Estimate::from_measurement(&m, 1, seq, 1, Fix::Ok { position: uavs[0], covariance: cov }).unwrap();
        prop_assert_eq!(e.validate(Some(seq - 1)), Ok(()));
        let plan = PlanInfo {
            headings: &vals[..n],
            waypoints: &uavs[..n],
            objective: sigma,
            solver: "pso",
            objective_name: "trace",
            plan_time_us: 1,
            active_constraints: 0,
            violated_constraints: 0,
        };
        let c = Command::from_estimate(&e, 2, seq, 1, &plan).unwrap();
        prop_assert_eq!(c.validate(Some(seq - 1)), Ok(()));
        prop_assert_eq!(Truth::new(0, seq, uavs[1]).validate(Some(seq - 1)), Ok(()));
        prop_assert_eq!(c.validate(Some(seq)), Err(Rejection::Stale { seq, last: seq }));
    }
}
