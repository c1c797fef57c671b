//! bridge → emitter-sim, monitor, external front ends: the UAVs as their autopilots report them.

use super::*;

wire_enum! {
    /// The state of one UAV's autopilot link, as the bridge sees it ([`SwarmState::link`]).
    pub enum LinkState : u32, decoded by from_u32 {
        /// Nothing heard from the autopilot yet.
        Unknown = 0, "unknown";
        /// Heartbeats and positions come; the autopilot is armed and in a guided (offboard) mode: it flies
        /// the commanded targets.
        Flying = 1, "flying";
        /// Heard, but not armed or not in a guided mode: no target is sent to it.
        NotGuided = 2, "not_guided";
        /// Nothing heard for longer than the bridge's `--link-timeout-ms`: the position is the last one
        /// reported, `fix_ns` says how old.
        Quiet = 3, "quiet";
    }
}

/// bridge → emitter-sim, monitor, external front ends: each UAV's last reported position, heading and
/// velocity (from its autopilot's `GLOBAL_POSITION_INT` and `ATTITUDE`), both in the run's plane and as
/// WGS84 latitude/longitude, when it was received, and the state of its link ([`LinkState`]). Published
/// at the bridge's rate (`--rate-hz`) whatever the autopilots do; `header.step` is the step of the last
/// command the bridge sent on (0 before the first).
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("uavloc::SwarmState/v1")]
#[repr(C)]
pub struct SwarmState {
    /// Common header.
    pub header: Header,
    /// Number of UAVs (3..=8).
    pub count: u32,
    /// Explicit padding; 0 when sent.
    pub reserved: u32,
    /// Position in the run's plane (x east, y north), metres; used when `fix_ns` is not 0.
    pub positions: [[f64; 2]; MAX_UAVS],
    /// The same position as WGS84 `[lat, lon]`, degrees.
    pub lat_lon_deg: [[f64; 2]; MAX_UAVS],
    /// Altitude above the WGS84 ellipsoid, metres.
    pub altitude_m: [f64; MAX_UAVS],
    /// Heading in the plane, radians counter-clockwise from east (the autopilot's yaw, converted).
    pub headings: [f64; MAX_UAVS],
    /// Ground velocity (east, north), m/s.
    pub velocities: [[f64; 2]; MAX_UAVS],
    /// When the position was received (`CLOCK_MONOTONIC` ns, [`now_ns`]); 0: never.
    pub fix_ns: [u64; MAX_UAVS],
    /// [`LinkState`] of each UAV, as `u32`.
    pub link: [u32; MAX_UAVS],
    /// Telemetry messages of each UAV the bridge refused so far (another system id, a NaN, a jump).
    pub rejected: [u32; MAX_UAVS],
}

impl_message!(SwarmState, MessageKind::Swarm, 1, "uavloc::SwarmState/v1");

impl SwarmState {
    /// An empty state of `count` UAVs (nothing heard: every link [`LinkState::Unknown`]).
    pub fn new(step: u64, seq: u64, count: usize) -> Result<Self, ProtocolError> {
        let n = check_count(count)?;
        Ok(SwarmState {
            header: Header::new(Self::VERSION, step, seq),
            count: n as u32,
            reserved: 0,
            positions: [[0.0; 2]; MAX_UAVS],
            lat_lon_deg: [[0.0; 2]; MAX_UAVS],
            altitude_m: [0.0; MAX_UAVS],
            headings: [0.0; MAX_UAVS],
            velocities: [[0.0; 2]; MAX_UAVS],
            fix_ns: [0; MAX_UAVS],
            link: [LinkState::Unknown as u32; MAX_UAVS],
            rejected: [0; MAX_UAVS],
        })
    }

    /// Number of UAVs in use.
    pub fn len(&self) -> usize {
        (self.count as usize).min(MAX_UAVS)
    }

    /// Never empty once validated (3..=8 UAVs).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The decoded link state of UAV `i` (`None` for an unknown wire value).
    pub fn link_of(&self, i: usize) -> Option<LinkState> {
        self.link.get(i).and_then(|v| LinkState::from_u32(*v))
    }

    /// Whether UAV `i` has reported a position.
    pub fn has_fix(&self, i: usize) -> bool {
        self.fix_ns.get(i).is_some_and(|t| *t != 0)
    }
}
