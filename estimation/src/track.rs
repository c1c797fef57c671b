//! The standing of a fused track: how many snapshots it rejected in a row, how many bursts it fused
//! whole, and which UAV's arrival it has dropped burst after burst — what decides whether a track is
//! provisional, confirmed, demoted or restarted from Chan. Plain data that travels in the estimator's
//! state (`Estimate::extra`, the state echo), so a resumed estimator goes on exactly where it was.

/// The fused estimator restarts from Chan's fix of the current snapshot after this many snapshots
/// rejected in a row by its χ² gate: the posterior has lost the emitter (a wrong root, a jump), and
/// gating alone would keep it lost forever.
pub const REJECTED_RUN_RESTART: u8 = 3;

/// A fused track is provisional until it has fused this many bursts whole (no arrival dropped): until
/// then a burst that fails the gate is never made to fit by dropping the arrivals that disagree with the
/// track — a first fix that a reflection corrupted (three UAVs leave no redundancy to see it) is not kept
/// alive by the subsets that happen to agree with it, and is restarted after [`REJECTED_RUN_RESTART`]
/// rejections. Only arrivals the burst itself shows to be outliers (its own Chan residual, five or more
/// arrivals: [`crate::outliers::fuse_self_checked`]), or a late minority of a burst that shows an outlier by
/// itself ([`crate::outliers::shows_an_outlier`], [`crate::outliers::fuse_without_late`]), are dropped from a
/// provisional track's bursts.
pub const CONFIRM_BURSTS: u8 = 3;

/// A confirmed track that drops the same UAV's arrival from this many fused bursts in a row (bursts
/// that heard it) is made provisional again: a reflection lasts one burst (independent per burst, 15 %
/// at the worst cell studied: four in a row from one UAV is a 5·10⁻⁴ event), a track confirmed on a
/// corrupted first fix disagrees with the same direct arrival burst after burst and would otherwise
/// drop it for the rest of the run. Made provisional, the track fuses only whole bursts and is
/// restarted from Chan after [`REJECTED_RUN_RESTART`] rejections.
pub const DEMOTE_DROP_RUN: u8 = 4;

/// The UAVs whose arrival a track has dropped from every fused burst that heard them, and for how many
/// bursts in a row (see [`DEMOTE_DROP_RUN`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DropStreak {
    /// The UAVs dropped in each of the last `run` bursts that heard them (bit i: UAV i).
    pub uavs: u8,
    /// How many fused bursts in a row dropped them.
    pub run: u8,
}

impl DropStreak {
    /// The streak after a fused burst that heard `heard` and dropped `dropped` (bit masks).
    pub fn after(self, heard: u8, dropped: u8) -> Self {
        let common = self.uavs & dropped;
        if common != 0 {
            Self { uavs: common, run: self.run.saturating_add(1) }
        } else if dropped != 0 {
            Self { uavs: dropped, run: 1 }
        } else if self.uavs & heard != 0 {
            // A streak UAV heard and kept: the streak ends.
            Self::default()
        } else {
            self
        }
    }
}

/// The counters of one fused track (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct TrackCounters {
    /// Snapshots rejected in a row (0 after a fused one or a restart).
    pub rejected_run: u8,
    /// Bursts fused whole since the track started, saturating at [`CONFIRM_BURSTS`].
    pub confirmed: u8,
    /// The arrivals dropped burst after burst ([`DEMOTE_DROP_RUN`]).
    pub drop_streak: DropStreak,
}

impl TrackCounters {
    /// These counters with `confirmed` clamped to [`CONFIRM_BURSTS`] (a resumed state).
    pub fn clamped(self) -> Self {
        Self { confirmed: self.confirmed.min(CONFIRM_BURSTS), ..self }
    }

    /// Whether the track is still provisional (fewer than [`CONFIRM_BURSTS`] bursts fused whole).
    pub fn provisional(&self) -> bool {
        self.confirmed < CONFIRM_BURSTS
    }

    /// After a rejected snapshot: whether the track has now been rejected [`REJECTED_RUN_RESTART`]
    /// times in a row and is to be restarted from Chan.
    pub fn rejected(&mut self) -> bool {
        self.rejected_run = self.rejected_run.saturating_add(1);
        self.rejected_run >= REJECTED_RUN_RESTART
    }

    /// After a fused burst that heard `heard` and dropped `dropped` (bit masks), or a new Chan fix
    /// (`fix`): a burst fused whole confirms the track, a fix starts one, and the same UAV dropped
    /// [`DEMOTE_DROP_RUN`] bursts in a row makes it provisional again.
    pub fn fused(&mut self, fix: bool, heard: u8, dropped: u8) {
        if fix {
            *self = Self::default();
            return;
        }
        self.rejected_run = 0;
        if dropped == 0 {
            self.confirmed = self.confirmed.saturating_add(1).min(CONFIRM_BURSTS);
        }
        // The same UAV dropped burst after burst: the track, not the arrival, is wrong.
        self.drop_streak = self.drop_streak.after(heard, dropped);
        if self.drop_streak.run >= DEMOTE_DROP_RUN {
            self.confirmed = 0;
            self.drop_streak = DropStreak::default();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_drop_streak_follows_one_uav_and_ends_when_it_is_kept() {
        let s = DropStreak::default().after(0b111, 0b001);
        assert_eq!(s, DropStreak { uavs: 0b001, run: 1 });
        // Not heard: the streak waits; heard and kept: it ends; another UAV dropped: a new streak.
        assert_eq!(s.after(0b110, 0), s);
        assert_eq!(s.after(0b111, 0), DropStreak::default());
        assert_eq!(s.after(0b111, 0b010), DropStreak { uavs: 0b010, run: 1 });
        assert_eq!(s.after(0b111, 0b011), DropStreak { uavs: 0b001, run: 2 });
    }

    #[test]
    fn a_track_is_confirmed_by_whole_bursts_and_demoted_by_one_uav_dropped_four_times() {
        let mut t = TrackCounters::default();
        assert!(t.provisional());
        for _ in 0..CONFIRM_BURSTS {
            t.fused(false, 0b111, 0);
        }
        assert!(!t.provisional());
        // UAV 1 dropped three times: still confirmed; a fourth time: provisional again.
        for k in 1..DEMOTE_DROP_RUN {
            t.fused(false, 0b111, 0b010);
            assert_eq!((t.confirmed, t.drop_streak.run), (CONFIRM_BURSTS, k));
        }
        t.fused(false, 0b111, 0b010);
        assert!(t.provisional());
        assert_eq!(t.drop_streak, DropStreak::default());
        // Rejections: a restart on the third in a row, a fused burst resets the run.
        assert!(!t.rejected() && !t.rejected());
        t.fused(false, 0b111, 0);
        assert_eq!(t.rejected_run, 0);
        assert!(!t.rejected() && !t.rejected() && t.rejected());
        // A new fix starts the track again.
        t.fused(true, 0b111, 0);
        assert_eq!(t, TrackCounters::default());
    }
}
