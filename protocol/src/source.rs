//! One measurement source per run, and one measurement per step.
//!
//! The measurement topic is the run's input: emitter-sim's world, or an external front end. A receiver
//! (the estimator, the monitor) keeps, besides validation:
//!
//! - a [`SourceLock`]: the first publisher whose valid measurement it accepts is the run's *source*; a
//!   measurement from any other publisher is refused ([`Rejection::SecondSource`], counted) for as long
//!   as the source is on the topic and its process alive. A publisher that comes after the source has
//!   gone (a restarted emitter-sim, a front end that comes back) is its *successor* and takes over. The
//!   sequence numbers are a stream per source: a message of another publisher moves nothing, so one
//!   with `seq = u64::MAX` cannot make the source's later measurements stale.
//! - [`StepDigests`]: a digest of each step's accepted measurement (the data, not the header); a later
//!   copy of that step with other data is refused ([`Rejection::Conflict`], counted), an identical copy
//!   (a replay) passes. So the estimator, the planner, the monitor and the recording all use the first
//!   copy: what is recorded is what was estimated.
//!
//! Pure: the publisher ids and the source's liveness come in (the transport's
//! [`SubscribePort::receive_sourced`](crate::transport::SubscribePort::receive_sourced) and
//! [`publisher_alive`](crate::transport::SubscribePort::publisher_alive)); the verdicts go out.

use std::collections::VecDeque;

use crate::messages::{Measurement, Message};
use crate::validate::{Rejection, RejectionCounter};

/// How a measurement was admitted by [`SourceLock::check`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Admitted {
    /// From the run's source.
    Source,
    /// The first valid measurement: its publisher is the run's source from now on.
    First,
    /// From a successor: the previous source had gone (`previous`), this publisher took over.
    Successor {
        /// The source before.
        previous: u128,
    },
}

/// The run's measurement source as one receiver sees it; see the module docs.
#[derive(Debug, Default, Clone)]
pub struct SourceLock {
    source: Option<u128>,
    last_seq: Option<u64>,
    /// Publishers refused so far (the first few), so each is logged once.
    refused: Vec<u128>,
}

/// How many refused publishers a [`SourceLock`] remembers for logging once each.
const REMEMBERED: usize = 16;

impl SourceLock {
    /// The run's source, once one is known.
    pub fn source(&self) -> Option<u128> {
        self.source
    }

    /// Validates `msg` from the publisher `origin` (counted in `counter`): when another publisher is the
    /// source and `alive(source)` says it is still there, rejected for what is wrong with it, or — valid —
    /// refused as [`Rejection::SecondSource`]; otherwise validated against this source's stream (a
    /// successor starts a new one).
    pub fn check<T: Message>(
        &mut self,
        counter: &mut RejectionCounter,
        msg: &T,
        origin: u128,
        alive: impl FnOnce(u128) -> bool,
    ) -> Result<Admitted, Rejection> {
        match self.source {
            Some(source) if source == origin => counter.check(msg, &mut self.last_seq).map(|()| Admitted::Source),
            Some(source) if alive(source) => {
                // A malformed message is rejected for what is wrong with it; a valid one as a second source.
                let r = counter
                    .verdict(msg, None)
                    .err()
                    .unwrap_or(Rejection::SecondSource { current: source, got: origin });
                counter.record(T::KIND, &r);
                Err(r)
            }
            previous => {
                let mut last = None;
                counter.check(msg, &mut last)?;
                self.source = Some(origin);
                self.last_seq = last;
                Ok(previous.map_or(Admitted::First, |previous| Admitted::Successor { previous }))
            }
        }
    }

    /// Whether `origin` is refused for the first time (to log it once; the count stays exact).
    pub fn first_refusal(&mut self, origin: u128) -> bool {
        if self.refused.contains(&origin) {
            return false;
        }
        if self.refused.len() < REMEMBERED {
            self.refused.push(origin);
        }
        true
    }
}

/// The digest of a measurement's data — count, heard mask, flags, positions, arrivals, every σ and the
/// headings of the used entries, bit for bit (FNV-1a, 64 bits); the header (step, seq, stamps) is not
/// part of it.
pub fn measurement_digest(m: &Measurement) -> u64 {
    let n = (m.count as usize).min(crate::MAX_UAVS);
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bits: u64| {
        for b in bits.to_le_bytes() {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    eat(u64::from(m.count));
    eat(u64::from(m.heard) | u64::from(m.flags) << 8);
    for i in 0..n {
        eat(m.uavs[i][0].to_bits());
        eat(m.uavs[i][1].to_bits());
        eat(m.sigmas[i].to_bits());
        eat(m.headings[i].to_bits());
        eat(m.arrivals[i].to_bits());
        eat(m.position_sigmas[i].to_bits());
        eat(m.position_bias_sigmas[i].to_bits());
        eat(m.clock_sigmas_ns[i].to_bits());
        eat(m.clock_bias_sigmas_ns[i].to_bits());
    }
    h
}

/// The digests of the last [`StepDigests::WINDOW`] steps' accepted measurements; see the module docs.
#[derive(Debug, Default, Clone)]
pub struct StepDigests {
    steps: VecDeque<(u64, u64)>,
}

impl StepDigests {
    /// How many steps are remembered (a copy of an older step is not compared).
    pub const WINDOW: usize = 256;

    /// Checks `m` (already validated) against the copy of its step accepted before, if any: a different
    /// one is [`Rejection::Conflict`] (counted in `counter`); a first copy is remembered.
    pub fn check(&mut self, counter: &mut RejectionCounter, m: &Measurement) -> Result<(), Rejection> {
        let (step, digest) = (m.header.step, measurement_digest(m));
        match self.steps.iter().find(|(s, _)| *s == step) {
            Some((_, d)) if *d == digest => Ok(()),
            Some(_) => {
                let r = Rejection::Conflict { step };
                counter.record(Measurement::KIND, &r);
                Err(r)
            }
            None => {
                if self.steps.len() == Self::WINDOW {
                    self.steps.pop_front();
                }
                self.steps.push_back((step, digest));
                Ok(())
            }
        }
    }
}

/// What a receiver of measurements keeps: the run's source and the digests of the steps accepted.
#[derive(Debug, Default, Clone)]
pub struct MeasurementGate {
    /// The run's source.
    pub source: SourceLock,
    /// The steps' digests.
    pub digests: StepDigests,
}

impl MeasurementGate {
    /// Validates `m` from the publisher `origin`: the source first ([`SourceLock::check`]), then the
    /// copy of its step ([`StepDigests::check`]); counted in `counter` either way.
    pub fn check(
        &mut self,
        counter: &mut RejectionCounter,
        m: &Measurement,
        origin: u128,
        alive: impl FnOnce(u128) -> bool,
    ) -> Result<Admitted, Rejection> {
        let admitted = self.source.check(counter, m, origin, alive)?;
        self.digests.check(counter, m)?;
        Ok(admitted)
    }

    /// Validates `m`, a copy the monitor gives again ([`crate::services::measurement_replay`]): a uavloc
    /// process, not a source, and a copy, not a stream (no sequence check) — but it must be the step's
    /// measurement as accepted before, if this receiver accepted one ([`StepDigests::check`]).
    pub fn check_copy(&mut self, counter: &mut RejectionCounter, m: &Measurement) -> Result<(), Rejection> {
        counter.check(m, &mut None)?;
        self.digests.check(counter, m)
    }

    /// The log line of a rejection, or `None` when it is a refused publisher already logged (the count
    /// stays exact; a second source's every message would otherwise be a line).
    pub fn log_line(&mut self, r: &Rejection) -> Option<String> {
        match r {
            Rejection::SecondSource { got, .. } if !self.source.first_refusal(*got) => None,
            Rejection::SecondSource { .. } => Some(format!(
                "refused a measurement: {r} — one measurement source per run; its further messages are \
                 counted, not logged"
            )),
            _ => Some(format!("rejected a measurement: {r}")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::messages::MessageKind;

    fn measurement(step: u64, seq: u64) -> Measurement {
        let uavs = [[0.0, 0.0], [1000.0, 0.0], [0.0, 1000.0]];
        Measurement::new(step, seq, &uavs, &[10.0, -20.0], &[30.0; 3], &[0.1, 0.2, 0.3]).unwrap()
    }

    #[test]
    fn a_second_publisher_is_refused_while_the_source_is_there_and_takes_over_after_it() {
        let mut counter = RejectionCounter::new();
        let mut lock = SourceLock::default();
        assert_eq!(lock.check(&mut counter, &measurement(0, 10), 1, |_| true), Ok(Admitted::First));
        assert_eq!(lock.check(&mut counter, &measurement(1, 11), 1, |_| true), Ok(Admitted::Source));
        // Another publisher, source alive: refused, counted, nothing moved.
        let refused = lock.check(&mut counter, &measurement(2, 500), 2, |s| s == 1);
        assert_eq!(refused, Err(Rejection::SecondSource { current: 1, got: 2 }));
        assert_eq!(counter.count(MessageKind::Measurement, "second_source"), 1);
        assert!(lock.first_refusal(2) && !lock.first_refusal(2));
        assert_eq!(lock.check(&mut counter, &measurement(2, 12), 1, |_| true), Ok(Admitted::Source));
        // The source gone: the next publisher is its successor, with a stream of its own.
        assert_eq!(lock.check(&mut counter, &measurement(3, 5), 3, |_| false), Ok(Admitted::Successor { previous: 1 }));
        assert_eq!(lock.source(), Some(3));
        assert_eq!(lock.check(&mut counter, &measurement(4, 5), 3, |_| true).unwrap_err().kind(), "stale");
    }

    /// A valid measurement with `seq = u64::MAX` from another client cannot make the source's later
    /// measurements stale: streams are per source, and the other client's message moves nothing.
    #[test]
    fn a_foreign_sequence_number_cannot_poison_the_source_stream() {
        let mut counter = RejectionCounter::new();
        let mut lock = SourceLock::default();
        lock.check(&mut counter, &measurement(0, 10), 1, |_| true).unwrap();
        assert!(lock.check(&mut counter, &measurement(1, u64::MAX), 9, |_| true).is_err());
        for k in 1..5 {
            assert_eq!(lock.check(&mut counter, &measurement(k, 10 + k), 1, |_| true), Ok(Admitted::Source));
        }
    }

    /// An invalid first message does not make its publisher the source.
    #[test]
    fn an_invalid_message_locks_nothing() {
        let mut counter = RejectionCounter::new();
        let mut lock = SourceLock::default();
        let mut bad = measurement(0, 10);
        bad.arrivals[1] = f64::NAN;
        assert!(lock.check(&mut counter, &bad, 7, |_| true).is_err());
        assert_eq!(lock.source(), None);
        assert_eq!(lock.check(&mut counter, &measurement(0, 11), 1, |_| true), Ok(Admitted::First));
        // A malformed message of a second publisher is rejected for what is wrong with it.
        assert_eq!(lock.check(&mut counter, &bad, 7, |_| true).unwrap_err().kind(), "not_finite");
    }

    #[test]
    fn a_different_copy_of_a_step_conflicts_and_an_identical_one_passes() {
        let mut counter = RejectionCounter::new();
        let mut digests = StepDigests::default();
        let first = measurement(5, 10);
        assert_eq!(digests.check(&mut counter, &first), Ok(()));
        // A replay: same data, another header.
        let mut replay = first;
        replay.header.seq = 99;
        replay.header.stamps.published_ns = 0;
        assert_eq!(digests.check(&mut counter, &replay), Ok(()));
        // Unused entries are not data.
        let mut padded = first;
        padded.arrivals[7] = 1.0;
        padded.uavs[7] = [f64::NAN, 3.0];
        assert_eq!(digests.check(&mut counter, &padded), Ok(()));
        let mut other = first;
        other.arrivals[2] += 0.5;
        assert_eq!(digests.check(&mut counter, &other), Err(Rejection::Conflict { step: 5 }));
        assert_eq!(counter.count(MessageKind::Measurement, "conflict"), 1);
        // −0 and +0 differ bit for bit: a copy is the same measurement only when it is bit-identical.
        let mut signed = first;
        signed.uavs[0][0] = -0.0;
        assert!(digests.check(&mut counter, &signed).is_err());
    }

    #[test]
    fn the_window_is_bounded() {
        let mut counter = RejectionCounter::new();
        let mut digests = StepDigests::default();
        for k in 0..(StepDigests::WINDOW as u64 + 10) {
            digests.check(&mut counter, &measurement(k, k + 1)).unwrap();
        }
        assert_eq!(digests.steps.len(), StepDigests::WINDOW);
        // Step 0 is forgotten: a different copy of it is not compared.
        let mut old = measurement(0, 1);
        old.arrivals[1] = 1.0;
        assert_eq!(digests.check(&mut counter, &old), Ok(()));
    }
}
