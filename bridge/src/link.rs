//! What the bridge knows of one UAV's autopilot, from its telemetry alone: a pure state machine over
//! (message, time), testable without a link.
//!
//! - A `HEARTBEAT` says whether the autopilot is armed (`MAV_MODE_FLAG_SAFETY_ARMED`) and in a guided
//!   mode (`MAV_MODE_FLAG_GUIDED_ENABLED`: ArduPilot's GUIDED, PX4's OFFBOARD).
//! - A `GLOBAL_POSITION_INT` is a fix: latitude/longitude into the run's plane, the NED velocity into
//!   (east, north). `ATTITUDE`'s yaw (clockwise from north) gives the heading in the plane
//!   (`π/2 − yaw`); without one, the fix's `hdg`, then its velocity's direction.
//! - Refused, counted ([`Refused`]): a message of another system id than the UAV's; a fix with a value out
//!   of range; a first fix farther than the start offset from where the scenario starts the UAV; a fix
//!   farther from the last one than the UAV can fly in the time between (at the scenario's speed, times
//!   the time scale, plus a margin).
//! - [`UavLink::state`]: [`LinkState::Unknown`] before anything was heard, [`LinkState::Quiet`] after the
//!   link timeout without a message, [`LinkState::Flying`] when armed, guided and with a fix, else
//!   [`LinkState::NotGuided`]. Only a flying UAV is sent targets ([`UavLink::may_command`]).

use std::time::{Duration, Instant};

use model::geo::{LatLon, LocalFrame};
use protocol::LinkState;

/// `MAV_MODE_FLAG_SAFETY_ARMED`.
pub const ARMED: u8 = 128;
/// `MAV_MODE_FLAG_GUIDED_ENABLED`.
pub const GUIDED: u8 = 8;
/// Metres a fix may be off the flyable distance (GNSS noise and the time stamps' jitter).
pub const JUMP_MARGIN_M: f64 = 200.0;

/// Why a telemetry message was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Refused {
    /// Sent by another system than the UAV's autopilot.
    #[error("from system {got}, but this UAV's autopilot is system {expected}")]
    OtherSystem {
        /// The UAV's system id.
        expected: u8,
        /// The message's.
        got: u8,
    },
    /// A value out of its range (a NaN yaw, a latitude beyond 90°, a place too far from the origin).
    #[error("a bad value: {0}")]
    BadValue(String),
    /// The first fix is far from where the scenario starts the UAV.
    #[error(
        "its first fix is {distance:.0} m from the scenario's start, more than {allowed:.0} m (the right endpoint?)"
    )]
    FarFromStart {
        /// Distance from the scenario's start, metres.
        distance: f64,
        /// The allowed offset, metres.
        allowed: f64,
    },
    /// A fix farther from the last than the UAV can fly.
    #[error("a fix {distance:.0} m from the last one {seconds:.2} s before (at most {allowed:.0} m flyable)")]
    Jump {
        /// Distance from the last fix, metres.
        distance: f64,
        /// Time since the last fix, seconds.
        seconds: f64,
        /// What the UAV could have flown, metres.
        allowed: f64,
    },
}

/// A fix of the autopilot, in the plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fix {
    /// When it was received.
    pub at: Instant,
    /// Position (x east, y north), metres.
    pub xy: [f64; 2],
    /// The same as `[lat, lon]`, degrees.
    pub lat_lon: [f64; 2],
    /// Altitude above the ellipsoid as reported (`GLOBAL_POSITION_INT.alt`, AMSL, metres).
    pub altitude_m: f64,
    /// Ground velocity (east, north), m/s.
    pub velocity: [f64; 2],
    /// Heading from the fix itself (`hdg`, or the velocity's direction), radians in the plane.
    pub heading: Option<f64>,
}

/// The settings of one UAV's link.
#[derive(Debug, Clone, Copy)]
pub struct LinkConfig {
    /// The autopilot's MAVLink system id.
    pub system_id: u8,
    /// Where the scenario starts the UAV (plane, metres).
    pub start: [f64; 2],
    /// The largest distance of a first fix from `start`, metres.
    pub max_start_offset_m: f64,
    /// The UAV's ground speed (the scenario's), m/s, times the simulation's time scale: the flyable
    /// distance per real second.
    pub speed_per_real_s: f64,
    /// Nothing heard for this long: quiet.
    pub timeout: Duration,
}

/// One UAV's link, as its telemetry tells it.
#[derive(Debug, Clone)]
pub struct UavLink {
    cfg: LinkConfig,
    frame: LocalFrame,
    heard: Option<Instant>,
    armed: bool,
    guided: bool,
    fix: Option<Fix>,
    /// The last `ATTITUDE` yaw as a plane heading.
    attitude_heading: Option<f64>,
    /// Telemetry refused so far.
    pub rejected: u32,
    /// Why the last refused message was refused.
    pub last_refusal: Option<Refused>,
    /// Times the link went quiet.
    pub quiet_periods: u32,
    was_quiet: bool,
}

impl UavLink {
    /// A link that has heard nothing yet.
    pub fn new(cfg: LinkConfig, frame: LocalFrame) -> Self {
        Self {
            cfg,
            frame,
            heard: None,
            armed: false,
            guided: false,
            fix: None,
            attitude_heading: None,
            rejected: 0,
            last_refusal: None,
            quiet_periods: 0,
            was_quiet: false,
        }
    }

    fn check_system(&mut self, system: u8) -> Result<(), Refused> {
        if system != self.cfg.system_id {
            return self.refuse(Refused::OtherSystem { expected: self.cfg.system_id, got: system });
        }
        Ok(())
    }

    fn refuse(&mut self, why: Refused) -> Result<(), Refused> {
        self.rejected += 1;
        self.last_refusal = Some(why.clone());
        Err(why)
    }

    /// A `HEARTBEAT` of `system` with `base_mode` at `now`.
    pub fn on_heartbeat(&mut self, system: u8, base_mode: u8, now: Instant) -> Result<(), Refused> {
        self.check_system(system)?;
        self.heard = Some(now);
        self.armed = base_mode & ARMED != 0;
        self.guided = base_mode & GUIDED != 0;
        Ok(())
    }

    /// A `GLOBAL_POSITION_INT` of `system` at `now`: latitude/longitude in degE7, altitude in mm, the
    /// NED velocity in cm/s, `hdg` in centidegrees (`u16::MAX`: unknown).
    #[allow(clippy::too_many_arguments)]
    pub fn on_position(
        &mut self,
        system: u8,
        lat_e7: i32,
        lon_e7: i32,
        alt_mm: i32,
        v_north_cm: i16,
        v_east_cm: i16,
        hdg_cdeg: u16,
        now: Instant,
    ) -> Result<(), Refused> {
        self.check_system(system)?;
        let p = match LatLon::new(f64::from(lat_e7) * 1e-7, f64::from(lon_e7) * 1e-7) {
            Ok(p) => p,
            Err(e) => return self.refuse(Refused::BadValue(e.to_string())),
        };
        let xy = match self.frame.to_local(p) {
            Ok(xy) => xy,
            Err(e) => return self.refuse(Refused::BadValue(e.to_string())),
        };
        match self.fix {
            None => {
                let distance = (xy[0] - self.cfg.start[0]).hypot(xy[1] - self.cfg.start[1]);
                if distance > self.cfg.max_start_offset_m {
                    return self.refuse(Refused::FarFromStart { distance, allowed: self.cfg.max_start_offset_m });
                }
            }
            Some(last) => {
                let distance = (xy[0] - last.xy[0]).hypot(xy[1] - last.xy[1]);
                let seconds = now.saturating_duration_since(last.at).as_secs_f64();
                let allowed = 1.5 * self.cfg.speed_per_real_s * seconds + JUMP_MARGIN_M;
                if distance > allowed {
                    return self.refuse(Refused::Jump { distance, seconds, allowed });
                }
            }
        }
        self.heard = Some(now);
        let velocity = [f64::from(v_east_cm) * 0.01, f64::from(v_north_cm) * 0.01];
        let heading = if hdg_cdeg != u16::MAX {
            Some(std::f64::consts::FRAC_PI_2 - (f64::from(hdg_cdeg) * 0.01).to_radians())
        } else if velocity[0].hypot(velocity[1]) > 0.5 {
            Some(velocity[1].atan2(velocity[0]))
        } else {
            None
        };
        self.fix =
            Some(Fix { at: now, xy, lat_lon: p.pair(), altitude_m: f64::from(alt_mm) * 1e-3, velocity, heading });
        Ok(())
    }

    /// An `ATTITUDE` of `system` with `yaw` (radians, clockwise from north) at `now`.
    pub fn on_attitude(&mut self, system: u8, yaw: f32, now: Instant) -> Result<(), Refused> {
        self.check_system(system)?;
        if !yaw.is_finite() {
            return self.refuse(Refused::BadValue(format!("yaw {yaw}")));
        }
        self.heard = Some(now);
        self.attitude_heading = Some(model::wrap_angle(std::f64::consts::FRAC_PI_2 - f64::from(yaw)));
        Ok(())
    }

    /// The link's state at `now` (see the module docs); counts a new quiet period.
    pub fn state(&mut self, now: Instant) -> LinkState {
        let state = match self.heard {
            None => LinkState::Unknown,
            Some(t) if now.saturating_duration_since(t) > self.cfg.timeout => LinkState::Quiet,
            Some(_) if self.armed && self.guided && self.fix.is_some() => LinkState::Flying,
            Some(_) => LinkState::NotGuided,
        };
        let quiet = state == LinkState::Quiet;
        if quiet && !self.was_quiet {
            self.quiet_periods += 1;
        }
        self.was_quiet = quiet;
        state
    }

    /// Whether a target may be sent now: the autopilot flies guided, with a fresh fix.
    pub fn may_command(&mut self, now: Instant) -> bool {
        self.state(now) == LinkState::Flying
    }

    /// The last fix.
    pub fn fix(&self) -> Option<&Fix> {
        self.fix.as_ref()
    }

    /// The heading: the attitude's, else the fix's.
    pub fn heading(&self) -> Option<f64> {
        self.attitude_heading.or(self.fix.and_then(|f| f.heading))
    }

    /// Why the UAV is not flying yet, in words (for the ready timeout's error).
    pub fn why_not_flying(&self) -> String {
        let refused = self
            .last_refusal
            .as_ref()
            .map_or(String::new(), |r| format!("; {} telemetry messages refused, the last one {r}", self.rejected));
        let why = match (self.heard, self.armed, self.guided, self.fix.is_some()) {
            (None, ..) if self.rejected > 0 => {
                format!("everything it sent was refused ({} messages: another system id or bad values)", self.rejected)
            }
            (None, ..) => "nothing heard from it (is the endpoint right, is the autopilot up?)".into(),
            (_, false, _, _) => "it never armed".into(),
            (_, _, false, _) => "it is not in a guided mode (GUIDED / OFFBOARD)".into(),
            (_, _, _, false) => "it reports no position (GLOBAL_POSITION_INT) that could be taken".into(),
            _ => "its link went quiet".into(),
        };
        format!("{why}{refused}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::geo::Origin;

    fn frame() -> LocalFrame {
        LocalFrame::new(Origin { lat_deg: 47.3977, lon_deg: 8.5456, alt_m: 488.0 }).unwrap()
    }

    fn link() -> UavLink {
        UavLink::new(
            LinkConfig {
                system_id: 2,
                start: [1500.0, 500.0],
                max_start_offset_m: 5000.0,
                speed_per_real_s: 50.0,
                timeout: Duration::from_millis(1500),
            },
            frame(),
        )
    }

    fn e7(xy: [f64; 2]) -> (i32, i32) {
        let p = frame().to_geodetic(xy).unwrap();
        ((p.lat_deg * 1e7).round() as i32, (p.lon_deg * 1e7).round() as i32)
    }

    #[test]
    fn a_uav_flies_once_armed_guided_and_placed_and_goes_quiet_without_messages() {
        let t0 = Instant::now();
        let mut l = link();
        assert_eq!(l.state(t0), LinkState::Unknown);
        l.on_heartbeat(2, ARMED, t0).unwrap();
        assert_eq!(l.state(t0), LinkState::NotGuided);
        assert!(l.why_not_flying().contains("guided"));
        l.on_heartbeat(2, ARMED | GUIDED, t0).unwrap();
        assert!(!l.may_command(t0), "no fix yet");
        let (lat, lon) = e7([1600.0, 450.0]);
        // 5 m/s north, 10 m/s east; hdg unknown: the heading is the velocity's.
        l.on_position(2, lat, lon, 600_000, 500, 1000, u16::MAX, t0).unwrap();
        assert!(l.may_command(t0));
        let f = *l.fix().unwrap();
        assert!((f.xy[0] - 1600.0).abs() < 0.02 && (f.xy[1] - 450.0).abs() < 0.02, "degE7 is 1 cm: {:?}", f.xy);
        assert_eq!(f.velocity, [10.0, 5.0]);
        assert!((l.heading().unwrap() - 0.5f64.atan2(1.0)).abs() < 1e-12);
        // ATTITUDE's yaw 90° (east, clockwise from north) is heading 0 in the plane.
        l.on_attitude(2, std::f32::consts::FRAC_PI_2, t0).unwrap();
        assert!(l.heading().unwrap().abs() < 1e-6);
        let later = t0 + Duration::from_millis(1600);
        assert_eq!(l.state(later), LinkState::Quiet);
        assert_eq!(l.state(later), LinkState::Quiet);
        assert_eq!(l.quiet_periods, 1, "one quiet period, counted once");
        l.on_heartbeat(2, ARMED | GUIDED, later).unwrap();
        assert_eq!(l.state(later), LinkState::Flying, "back");
    }

    #[test]
    fn another_system_a_far_start_a_jump_and_a_nan_are_refused_and_counted() {
        let t0 = Instant::now();
        let mut l = link();
        assert_eq!(l.on_heartbeat(7, ARMED | GUIDED, t0), Err(Refused::OtherSystem { expected: 2, got: 7 }));
        assert!(l.why_not_flying().contains("refused"));
        let (lat, lon) = e7([101_500.0, 500.0]);
        let e = l.on_position(2, lat, lon, 0, 0, 0, 0, t0).unwrap_err();
        assert!(matches!(e, Refused::FarFromStart { distance, .. } if (distance - 100_000.0).abs() < 1.0), "{e}");
        let (lat, lon) = e7([1500.0, 500.0]);
        l.on_position(2, lat, lon, 0, 0, 0, 0, t0).unwrap();
        // One second later 1 km away: more than 1.5 · 50 m + 200 m.
        let (lat, lon) = e7([2500.0, 500.0]);
        let e = l.on_position(2, lat, lon, 0, 0, 0, 0, t0 + Duration::from_secs(1)).unwrap_err();
        assert!(matches!(e, Refused::Jump { .. }), "{e}");
        // Twenty seconds later it may be there (1.5 · 50 m/s · 20 s + 200 m = 1700 m).
        l.on_position(2, lat, lon, 0, 0, 0, 0, t0 + Duration::from_secs(20)).unwrap();
        assert!(matches!(l.on_position(2, 910_000_000, 0, 0, 0, 0, 0, t0), Err(Refused::BadValue(_))));
        assert!(matches!(l.on_attitude(2, f32::NAN, t0), Err(Refused::BadValue(_))));
        assert_eq!(l.rejected, 5);
        assert!((l.fix().unwrap().xy[0] - 2500.0).abs() < 0.02, "the refused fixes left the last good one");
    }
}
