//! The count a receiver keeps of what it accepted and rejected, per message type and rejection kind,
//! with the run it belongs to (the monitor's report, every process's exit line).

use core::fmt;

use super::Rejection;
use crate::messages::{Message, MessageKind};

/// Counts accepted messages and rejections per message type and rejection kind (for the monitor).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RejectionCounter {
    rejected: [[u64; Rejection::KINDS.len()]; MessageKind::ALL.len()],
    accepted: [u64; MessageKind::ALL.len()],
    /// The receiver's run tag ([`crate::run_tag`]); 0: none known yet (every run accepted).
    run: u32,
}

impl RejectionCounter {
    /// All counts zero.
    pub fn new() -> Self {
        Self::default()
    }

    /// Sets the receiver's run tag ([`crate::run_tag`] of its scenario's fingerprint): data messages of
    /// another run are rejected from now on ([`Rejection::OtherRun`]).
    pub fn set_run(&mut self, tag: u32) {
        self.run = tag;
    }

    /// Takes `tag` as the receiver's run if it knows none yet (a process without a scenario, the
    /// estimator, belongs to the run of the first measurement it accepts).
    pub fn adopt_run(&mut self, tag: u32) {
        if self.run == 0 {
            self.run = tag;
        }
    }

    /// The receiver's run tag (0: none).
    pub fn run(&self) -> u32 {
        self.run
    }

    /// Validates `msg` against the receiver's run and the stream's last accepted sequence number, counts
    /// the outcome and, on acceptance, advances `last_seq`. A message of another run (both runs stated and
    /// different) is rejected before its sequence number is looked at, so it moves nothing; control
    /// messages are exempt (they state their run themselves: that is how another run is told to leave).
    pub fn check<T: Message>(&mut self, msg: &T, last_seq: &mut Option<u64>) -> Result<(), Rejection> {
        match self.verdict(msg, *last_seq) {
            Ok(()) => {
                *last_seq = Some(msg.header().seq);
                self.record_accepted(T::KIND);
                Ok(())
            }
            Err(r) => {
                self.record(T::KIND, &r);
                Err(r)
            }
        }
    }

    /// [`check`](Self::check)'s verdict on `msg`, counting nothing and moving nothing.
    pub fn verdict<T: Message>(&self, msg: &T, last_seq: Option<u64>) -> Result<(), Rejection> {
        let got = msg.header().run;
        if T::KIND != MessageKind::Control && self.run != 0 && got != 0 && got != self.run {
            Err(Rejection::OtherRun { expected: self.run, got })
        } else {
            msg.validate(last_seq)
        }
    }

    /// Counts one rejection.
    pub fn record(&mut self, msg: MessageKind, rejection: &Rejection) {
        self.rejected[msg.index()][rejection.kind_index()] += 1;
    }

    /// Counts one accepted message.
    pub fn record_accepted(&mut self, msg: MessageKind) {
        self.accepted[msg.index()] += 1;
    }

    /// Rejections of `msg` messages for reason `kind` (a [`Rejection::kind`] string; 0 if unknown).
    pub fn count(&self, msg: MessageKind, kind: &str) -> u64 {
        Rejection::KINDS.iter().position(|k| *k == kind).map_or(0, |i| self.rejected[msg.index()][i])
    }

    /// All rejections of `msg` messages.
    pub fn rejected(&self, msg: MessageKind) -> u64 {
        self.rejected[msg.index()].iter().sum()
    }

    /// Accepted `msg` messages.
    pub fn accepted(&self, msg: MessageKind) -> u64 {
        self.accepted[msg.index()]
    }

    /// Accepted messages of every kind.
    pub fn accepted_total(&self) -> u64 {
        self.accepted.iter().sum()
    }

    /// All rejections.
    pub fn total(&self) -> u64 {
        self.rejected.iter().flatten().sum()
    }

    /// The non-zero rejection counts as (message type, kind, count), in index order.
    pub fn iter(&self) -> impl Iterator<Item = (MessageKind, &'static str, u64)> + '_ {
        MessageKind::ALL.into_iter().flat_map(move |m| {
            Rejection::KINDS
                .iter()
                .enumerate()
                .map(move |(i, k)| (m, *k, self.rejected[m.index()][i]))
                .filter(|&(_, _, c)| c > 0)
        })
    }
}

impl fmt::Display for RejectionCounter {
    /// E.g. `rejected 3 (measurement: stale 2, bad_count 1)` or `rejected 0`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "rejected {}", self.total())?;
        let mut open = false;
        for m in MessageKind::ALL {
            if self.rejected(m) == 0 {
                continue;
            }
            f.write_str(if open { "; " } else { " (" })?;
            open = true;
            write!(f, "{m}:")?;
            let mut first = true;
            for (_, kind, count) in self.iter().filter(|&(mk, _, _)| mk == m) {
                write!(f, "{}{kind} {count}", if first { " " } else { ", " })?;
                first = false;
            }
        }
        if open {
            f.write_str(")")?;
        }
        Ok(())
    }
}
