//! Rejections logged at a bounded rate: a flood of bad messages (100 000 a second from a broken or
//! hostile client) would otherwise write a line each — tens of megabytes a second of log. The first
//! [`LogBudget::PER_SECOND`] of each second are logged one by one; the rest of that second are counted,
//! and the next line logged says how many were not. The rejection counts themselves stay exact (they are
//! kept elsewhere: `protocol::RejectionCounter`).
//!
//! Pure: the clock comes in.

use std::time::{Duration, Instant};

/// What to do with one more line ([`LogBudget::admit`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Admit {
    /// Log it; `unlogged` lines were left out before it (0: none), to be said first.
    Log {
        /// Lines counted but not logged since the last one logged.
        unlogged: u64,
    },
    /// Count it only.
    Quiet,
}

/// The budget of one process's rejection lines; see the module docs.
#[derive(Debug, Clone, Default)]
pub struct LogBudget {
    window: Option<Instant>,
    logged: u64,
    unlogged: u64,
}

impl LogBudget {
    /// Lines logged one by one per second.
    pub const PER_SECOND: u64 = 100;

    /// Whether the line at `now` is logged.
    pub fn admit(&mut self, now: Instant) -> Admit {
        if self.window.is_none_or(|w| now.saturating_duration_since(w) >= Duration::from_secs(1)) {
            self.window = Some(now);
            self.logged = 0;
        }
        if self.logged < Self::PER_SECOND {
            self.logged += 1;
            Admit::Log { unlogged: std::mem::take(&mut self.unlogged) }
        } else {
            self.unlogged += 1;
            Admit::Quiet
        }
    }

    /// Lines counted but not logged so far (to say at the end).
    pub fn unlogged(&self) -> u64 {
        self.unlogged
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flood_is_logged_at_a_bounded_rate_and_the_left_out_lines_are_said() {
        let t0 = Instant::now();
        let mut b = LogBudget::default();
        let mut logged = 0;
        // 100 000 in one second.
        for k in 0..100_000u64 {
            if let Admit::Log { unlogged } = b.admit(t0 + Duration::from_micros(k * 9)) {
                assert_eq!(unlogged, 0);
                logged += 1;
            }
        }
        assert_eq!(logged, LogBudget::PER_SECOND);
        assert_eq!(b.unlogged(), 100_000 - LogBudget::PER_SECOND);
        // The next second's first line says how many were left out; the count starts again.
        assert_eq!(b.admit(t0 + Duration::from_secs(1)), Admit::Log { unlogged: 100_000 - LogBudget::PER_SECOND });
        assert_eq!(b.unlogged(), 0);
        // A trickle is logged line by line.
        let mut t = LogBudget::default();
        for k in 0..1000 {
            assert_eq!(t.admit(t0 + Duration::from_millis(20 * k)), Admit::Log { unlogged: 0 });
        }
    }
}
