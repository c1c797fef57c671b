//! emitter-sim's schedule (`emitter_sim::schedule`) under random event orders: a pipeline that answers
//! the steps published — late, out of order, twice, or never (a lost message) — with processes joining
//! and asking for replays at random. Checked after every event:
//! - every step is published once, in order, from the first to the last; a step is published again only
//!   once published and while kept;
//! - lock-step: step k + 1 only after the command of step k was applied; real time: a step is flown
//!   (command applied) or missed (flown straight), never both, and never before its time;
//! - the steps counted flown are the commands applied plus the steps missed;
//! - the run finishes after the last step (the process stops there);
//! - a pipeline that loses nothing finishes the run (lock-step: within the steps' answers; real time:
//!   within the steps' intervals).

use std::time::{Duration, Instant};

use emitter_sim::schedule::{Action, Config, Other, Pacing, Schedule};
use proptest::prelude::*;

/// One thing that happens to the schedule.
#[derive(Debug, Clone, Copy)]
enum Event {
    /// Time passes (ms).
    Wait(u64),
    /// The answer (command) to the newest step (re)published arrives.
    AnswerNewest,
    /// A command for a random recent step arrives (a duplicate or a stray).
    Stray(u64),
    /// A process joins and asks for a replay from this many steps back (or the step in flight).
    Join(Option<u64>),
}

fn event() -> impl Strategy<Value = Event> {
    prop_oneof![
        4 => (0u64..400).prop_map(Event::Wait),
        6 => Just(Event::AnswerNewest),
        1 => (0u64..5).prop_map(Event::Stray),
        1 => prop::option::of(0u64..5).prop_map(Event::Join),
    ]
}

fn config(realtime: bool, last: u64) -> Config {
    Config {
        first: 0,
        last,
        pacing: if realtime {
            Pacing::Realtime { interval: Duration::from_millis(200) }
        } else {
            Pacing::Lockstep { step_delay: Duration::ZERO, window: 0, monitor_expected: false }
        },
        retry: Duration::from_millis(300),
        timeout: Duration::from_secs(3600),
        linger: false,
    }
}

/// What the checks keep: the steps published, the newest (re)published, the commands applied, the steps
/// missed, whether it finished.
#[derive(Default)]
struct Seen {
    published: Vec<u64>,
    newest: Option<u64>,
    applied: Vec<u64>,
    missed: Vec<u64>,
    finished: bool,
    t0: Option<Instant>,
}

impl Seen {
    fn take(&mut self, actions: Vec<Action>, realtime: bool, last: u64, now: Instant) -> Result<(), TestCaseError> {
        for a in actions {
            match a {
                Action::Publish(k) => {
                    prop_assert_eq!(k, self.published.len() as u64, "published out of order");
                    prop_assert!(k <= last);
                    if realtime {
                        let t0 = *self.t0.get_or_insert(now);
                        prop_assert!(now >= t0 + Duration::from_millis(200) * k as u32, "step {k} before its time");
                    } else if k > 0 {
                        prop_assert!(self.applied.contains(&(k - 1)), "step {k} before step {}'s command", k - 1);
                    }
                    self.published.push(k);
                    self.newest = Some(k);
                }
                Action::Republish(k) => {
                    prop_assert!(k < self.published.len() as u64, "step {k} published again before it was");
                    self.newest = Some(k);
                }
                Action::Missed(k) => {
                    prop_assert!(realtime, "a step missed in lock-step");
                    prop_assert!(!self.applied.contains(&k) && !self.missed.contains(&k), "step {k} flown twice");
                    self.missed.push(k);
                }
                Action::Finished => {
                    prop_assert_eq!(self.published.last().copied(), Some(last), "finished before the last step");
                    self.finished = true;
                }
                Action::Fail(why) => prop_assert!(false, "failed: {why}"),
            }
        }
        Ok(())
    }
}

/// Feeds `events` (then, if `settle`, a pipeline that answers every step at once) and checks as above.
fn run(realtime: bool, last: u64, events: &[Event], settle: bool) -> Result<(), TestCaseError> {
    let mut now = Instant::now();
    let mut s = Schedule::new(config(realtime, last), now);
    let mut seen = Seen::default();
    let actions = s.poll(now);
    seen.take(actions, realtime, last, now)?;
    let answer = |s: &mut Schedule, seen: &mut Seen, step: u64| {
        if s.wants(step) {
            s.applied(step);
            seen.applied.push(step);
        } else {
            let other = s.other_command(step);
            if other == Other::Late {
                assert!(seen.missed.contains(&step), "a late command for step {step}, which was not missed");
            }
        }
    };
    for e in events {
        match *e {
            Event::Wait(ms) => now += Duration::from_millis(ms),
            Event::AnswerNewest => {
                if let Some(k) = seen.newest {
                    answer(&mut s, &mut seen, k);
                }
            }
            Event::Stray(back) => {
                if let Some(k) = seen.newest {
                    answer(&mut s, &mut seen, k.saturating_sub(back));
                }
            }
            Event::Join(back) => {
                let from = match (back, seen.newest) {
                    (None, _) => protocol::ControlKind::IN_FLIGHT,
                    (Some(b), Some(k)) => k.saturating_sub(b),
                    (Some(_), None) => 0,
                };
                s.joined(from).map_err(TestCaseError::fail)?;
            }
        }
        let actions = s.poll(now);
        seen.take(actions, realtime, last, now)?;
        // (Real time counts a step flown when its interval is over: the command applied in the current
        // interval is not counted yet.)
        let done = (seen.applied.len() + seen.missed.len()) as u64;
        let counted = s.counts().steps;
        prop_assert!(counted == done || realtime && counted + 1 == done, "{counted} counted, {done} flown");
        if seen.finished {
            return Ok(()); // the process stops at the first `Finished`
        }
    }
    if settle {
        // A pipeline that loses nothing: every (re)published step answered at once, time going on.
        for _ in 0..(20 * (last + 2)) {
            if seen.finished {
                break;
            }
            if let Some(k) = seen.newest {
                answer(&mut s, &mut seen, k);
            }
            let actions = s.poll(now);
            seen.take(actions, realtime, last, now)?;
            now = s.deadline().map_or(now, |d| d.max(now));
            let actions = s.poll(now);
            seen.take(actions, realtime, last, now)?;
        }
        prop_assert!(seen.finished, "a pipeline that loses nothing did not finish: {:?}", seen.published);
        prop_assert_eq!(seen.published, (0..=last).collect::<Vec<_>>());
        prop_assert_eq!(s.counts().steps, (seen.applied.len() + seen.missed.len()) as u64);
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 256,
        rng_seed: proptest::test_runner::RngSeed::Fixed(0x5C4E_D01E),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn lockstep_under_random_events(events in prop::collection::vec(event(), 0..150), last in 1u64..12) {
        run(false, last, &events, true)?;
    }

    #[test]
    fn realtime_under_random_events(events in prop::collection::vec(event(), 0..150), last in 1u64..12) {
        run(true, last, &events, true)?;
    }
}
