//! The MAVLink side: one connection per UAV (the `mavlink` crate's UDP/TCP/serial endpoints, MAVLink 2),
//! a reader thread per connection that hands each telemetry message to the process with its arrival time,
//! and the messages the bridge sends (its heartbeat, the guided targets).

use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::mpsc::Sender;
use std::time::{Duration, Instant};

use mavlink::dialects::common::{
    GLOBAL_POSITION_INT_DATA, HEARTBEAT_DATA, MavAutopilot, MavFrame, MavMessage, MavModeFlag, MavState, MavType,
    PositionTargetTypemask, SET_POSITION_TARGET_GLOBAL_INT_DATA,
};
use mavlink::{MavConnection, MavHeader, MavlinkVersion};

use crate::target::Target;

/// The bridge's own MAVLink system id (a ground station's).
pub const GCS_SYSTEM_ID: u32 = 255;
/// The bridge's component id (`MAV_COMP_ID_MISSIONPLANNER`).
pub const GCS_COMPONENT_ID: u8 = 190;

/// One telemetry message the bridge acts on.
#[derive(Debug, Clone, PartialEq)]
pub enum Telemetry {
    /// `HEARTBEAT` of an autopilot (a GCS's or another component's is not passed on).
    Heartbeat {
        /// Sender system id.
        system: u8,
        /// `base_mode` bits.
        base_mode: u8,
    },
    /// `GLOBAL_POSITION_INT`.
    Position {
        /// Sender system id.
        system: u8,
        /// The message.
        data: GLOBAL_POSITION_INT_DATA,
    },
    /// `ATTITUDE`'s yaw, radians clockwise from north.
    Attitude {
        /// Sender system id.
        system: u8,
        /// Yaw.
        yaw: f32,
    },
}

/// What a reader thread passes on.
#[derive(Debug, Clone)]
pub struct Incoming {
    /// The UAV whose connection it came on.
    pub uav: usize,
    /// When it was read.
    pub at: Instant,
    /// The message, or a read error in words.
    pub what: Result<Telemetry, String>,
}

/// One UAV's MAVLink connection.
pub struct Autopilot {
    /// Its endpoint, as given.
    pub endpoint: String,
    conn: Arc<mavlink::Connection<MavMessage>>,
    sequence: AtomicU8,
}

impl std::fmt::Debug for Autopilot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Autopilot").field("endpoint", &self.endpoint).finish_non_exhaustive()
    }
}

/// Opens UAV `uav`'s connection at `endpoint` and starts its reader thread, which sends on `tx` until the
/// receiving end is gone. An endpoint that cannot be opened (a bad address, a TCP peer refusing) is an
/// error naming it.
pub fn open(uav: usize, endpoint: &str, tx: Sender<Incoming>) -> Result<Autopilot, String> {
    let mut conn = mavlink::connect::<MavMessage>(endpoint)
        .map_err(|e| format!("--autopilot {endpoint} (UAV {uav}): cannot open it: {e}"))?;
    conn.set_protocol_version(MavlinkVersion::V2);
    conn.set_allow_recv_any_version(true);
    let conn = Arc::new(conn);
    let reader = Arc::clone(&conn);
    std::thread::Builder::new()
        .name(format!("mavlink-uav{uav}"))
        .spawn(move || read_loop(uav, &reader, &tx))
        .map_err(|e| format!("UAV {uav}: cannot start its reader thread: {e}"))?;
    Ok(Autopilot { endpoint: endpoint.to_string(), conn, sequence: AtomicU8::new(0) })
}

fn read_loop(uav: usize, conn: &mavlink::Connection<MavMessage>, tx: &Sender<Incoming>) {
    loop {
        let what = match conn.recv() {
            Ok((h, msg)) => match decode(&h, msg) {
                Some(t) => Ok(t),
                None => continue,
            },
            Err(mavlink::error::MessageReadError::Io(e))
                if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) =>
            {
                continue;
            }
            Err(e) => {
                // A refused datagram (nobody at a udpout peer yet), a closed TCP peer: say so, then wait a
                // little instead of spinning on the error.
                std::thread::sleep(Duration::from_millis(200));
                Err(e.to_string())
            }
        };
        if tx.send(Incoming { uav, at: Instant::now(), what }).is_err() {
            return; // the process is ending
        }
    }
}

fn decode(h: &MavHeader, msg: MavMessage) -> Option<Telemetry> {
    let system = u8::try_from(h.system_id).ok()?;
    match msg {
        MavMessage::HEARTBEAT(hb) if !matches!(hb.mavtype, MavType::MAV_TYPE_GCS) => {
            Some(Telemetry::Heartbeat { system, base_mode: hb.base_mode.bits() })
        }
        MavMessage::GLOBAL_POSITION_INT(data) => Some(Telemetry::Position { system, data }),
        MavMessage::ATTITUDE(a) => Some(Telemetry::Attitude { system, yaw: a.yaw }),
        _ => None,
    }
}

impl Autopilot {
    fn header(&self) -> MavHeader {
        MavHeader {
            system_id: GCS_SYSTEM_ID,
            component_id: GCS_COMPONENT_ID,
            sequence: self.sequence.fetch_add(1, Ordering::Relaxed),
        }
    }

    /// Sends the bridge's `HEARTBEAT` (a ground station's).
    pub fn heartbeat(&self) -> Result<(), String> {
        let msg = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode: 0,
            mavtype: MavType::MAV_TYPE_GCS,
            autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
            base_mode: MavModeFlag::empty(),
            system_status: MavState::MAV_STATE_ACTIVE,
            mavlink_version: 3,
        });
        self.conn.send(&self.header(), &msg).map(|_| ()).map_err(|e| e.to_string())
    }

    /// Sends `SET_POSITION_TARGET_GLOBAL_INT` to `system`: the target's position and yaw, at `altitude_m`
    /// above home; velocity, acceleration and yaw rate ignored.
    pub fn send_target(&self, system: u8, target: &Target, altitude_m: f64, time_boot_ms: u32) -> Result<(), String> {
        let ignore = PositionTargetTypemask::POSITION_TARGET_TYPEMASK_VX_IGNORE
            | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_VY_IGNORE
            | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_VZ_IGNORE
            | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_AX_IGNORE
            | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_AY_IGNORE
            | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_AZ_IGNORE
            | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE;
        let msg = MavMessage::SET_POSITION_TARGET_GLOBAL_INT(SET_POSITION_TARGET_GLOBAL_INT_DATA {
            time_boot_ms,
            lat_int: target.lat_e7,
            lon_int: target.lon_e7,
            alt: altitude_m as f32,
            vx: 0.0,
            vy: 0.0,
            vz: 0.0,
            afx: 0.0,
            afy: 0.0,
            afz: 0.0,
            yaw: target.yaw,
            yaw_rate: 0.0,
            type_mask: ignore,
            target_system: system,
            target_component: 1,
            coordinate_frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
        });
        self.conn.send(&self.header(), &msg).map(|_| ()).map_err(|e| e.to_string())
    }
}
