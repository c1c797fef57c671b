//! The recovery timing rules of `runtime::recovery` under random event orders: each state machine is fed
//! a random sequence of (time step, inputs) and its answers are checked against the rules it states,
//! tracked here independently — never an answer without its cause, never two for one thing within the
//! retry interval, and always the next one once the interval has passed while the cause persists.

use std::time::{Duration, Instant};

use proptest::prelude::*;
use runtime::recovery::{
    Ask, LostMessages, NO_HOLDER_FALLBACK, REASK, STALL_GRACE, STATE_GRACE, STATE_RETRY, StalledStep, StateRequests,
};

fn config() -> ProptestConfig {
    ProptestConfig {
        cases: 256,
        rng_seed: proptest::test_runner::RngSeed::Fixed(0x4EC0_BE41),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

/// Time steps of 0–1.5 s (many below every interval, some above), with the inputs of each poll.
fn events<T: std::fmt::Debug>(input: impl Strategy<Value = T>) -> impl Strategy<Value = Vec<(u64, T)>> {
    prop::collection::vec((prop_oneof![0u64..50, 0u64..1500], input), 1..120)
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn lost_messages_asks_only_for_a_cause_and_again_only_after_reask(
        evs in events((0u64..3, prop::option::of(5u64..9), prop::option::of(0u64..3))),
    ) {
        let t0 = Instant::now();
        let mut now = t0;
        let mut m = LostMessages::default();
        // Since when the same state has been wanted; the last ask (step, time).
        let mut waited: Option<(u64, Instant)> = None;
        let mut asked: Option<(u64, Instant)> = None;
        for (dt, (next, newer, wanted)) in evs {
            now += Duration::from_millis(dt);
            waited = match (wanted, waited) {
                (None, _) => None,
                (Some(w), Some((s, at))) if s == w => Some((s, at)),
                (Some(w), _) => Some((w, now)),
            };
            let state_cause = waited.filter(|(_, at)| now - *at >= STATE_GRACE).map(|(w, _)| w);
            let cause = newer.is_some() || state_cause.is_some();
            let blocked = asked.is_some_and(|(s, at)| s == next && now - at < REASK);
            let got = m.poll(now, next, newer, wanted);
            prop_assert_eq!(got.is_some(), cause && !blocked, "at {:?}: next {}, newer {:?}, wanted {:?}, asked {:?}",
                now - t0, next, newer, wanted, asked.map(|(s, at)| (s, at - t0)));
            if let Some(why) = got {
                match newer {
                    Some(n) => prop_assert_eq!(why, runtime::recovery::Lost::NewerStep(n)),
                    None => prop_assert_eq!(why, runtime::recovery::Lost::StateWanted(state_cause.unwrap())),
                }
                asked = Some((next, now));
            }
        }
    }

    #[test]
    fn a_stalled_step_is_given_again_after_the_grace_and_then_every_reask(
        evs in events((0u64..3, any::<bool>())),
    ) {
        let mut now = Instant::now();
        let mut s = StalledStep::default();
        // The step measured continuously, since when, and when it was last given again.
        let mut waiting: Option<(u64, Instant, Option<Instant>)> = None;
        for (dt, (next, measured)) in evs {
            now += Duration::from_millis(dt);
            let expected = if !measured {
                waiting = None;
                false
            } else {
                match waiting {
                    Some((step, since, given)) if step == next => {
                        let due = now - since >= STALL_GRACE && given.is_none_or(|g| now - g >= REASK);
                        if due {
                            waiting = Some((step, since, Some(now)));
                        }
                        due
                    }
                    _ => {
                        waiting = Some((next, now, None));
                        false
                    }
                }
            };
            prop_assert_eq!(s.poll(now, next, measured), expected);
        }
    }

    #[test]
    fn state_requests_retry_after_the_interval_and_fall_back_once_per_state(
        evs in events((prop::option::of(0u64..3), any::<bool>())),
    ) {
        let mut now = Instant::now();
        let mut r = StateRequests::default();
        let mut asked: Option<(u64, Instant)> = None;
        let mut alone_since: Option<Instant> = None;
        let mut from_start: Vec<u64> = Vec::new();
        let mut last_fallback: Option<u64> = None;
        for (dt, (wanted, alone)) in evs {
            now += Duration::from_millis(dt);
            let mut looked = false;
            let got = r.poll(now, wanted, || {
                looked = true;
                Ok::<_, ()>(alone)
            }).unwrap();
            let Some(step) = wanted else {
                prop_assert_eq!(got, None);
                asked = None;
                continue;
            };
            let due = asked.is_none_or(|(s, at)| s != step || now - at >= STATE_RETRY);
            prop_assert_eq!(got.is_some(), due);
            // Whether a monitor is there is looked at only when a request is due.
            prop_assert_eq!(looked, due);
            if !due {
                continue;
            }
            alone_since = if alone { Some(alone_since.unwrap_or(now)) } else { None };
            asked = Some((step, now));
            let fallback = alone_since.is_some_and(|t| now - t >= NO_HOLDER_FALLBACK) && last_fallback != Some(step);
            if fallback {
                prop_assert_eq!(got, Some(Ask::ReplayFromStart(step)));
                last_fallback = Some(step);
                from_start.push(step);
            } else {
                prop_assert_eq!(got, Some(Ask::State(step)));
            }
        }
        // A replay from step 0 is asked once per state wanted in a row.
        prop_assert!(from_start.windows(2).all(|w| w[0] != w[1]), "{from_start:?}");
    }
}
