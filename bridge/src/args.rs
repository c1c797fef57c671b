//! The bridge's flags (`bridge [FLAGS]`, `uavloc process bridge [FLAGS]`) and their checks.

use std::time::Duration;

use runtime::ProcessArgs;

/// Help text shown after the options of `bridge --help`.
pub const AFTER_HELP: &str = "\
One --autopilot per UAV of the scenario, in the scenario's order (UAV0 first), each a MAVLink 2
endpoint as the mavlink crate spells it:
  udpin:0.0.0.0:14550    listen for the autopilot's datagrams (it sends to this port)
  udpout:10.0.0.2:14550  send to the autopilot's port
  tcpout:10.0.0.2:5760   connect to the autopilot (SITL's TCP port)
  serial:/dev/ttyACM0:57600
The scenario needs an [origin]: targets go to the autopilots as latitude/longitude.

What the bridge does, per UAV: it sends a GCS HEARTBEAT every second; it reads HEARTBEAT (system id,
armed, guided), GLOBAL_POSITION_INT and ATTITUDE; once the autopilot is armed in a guided mode
(MAV_MODE_FLAG_GUIDED_ENABLED: ArduPilot GUIDED, PX4 OFFBOARD) and its position is known, it streams
SET_POSITION_TARGET_GLOBAL_INT with the last command's waypoint and heading at --rate-hz. Every
--rate-hz tick it publishes the swarm's state on <domain>/swarm.

Telemetry refused (counted, logged): another system id than --system-ids gives, a NaN or
out-of-range value, a first fix farther than --max-start-offset-m from the scenario's start, a fix
that jumps farther than the UAV can fly. A link silent for --link-timeout-ms is quiet: no target is
sent on it, the swarm state says so, and the last fix ages. A UAV not flying (armed, guided, with a
fix) within --ready-timeout-ms of the start is an error (exit 1) naming the UAV, its endpoint and why.

Examples:
  bridge --scenario scenarios/geo.toml --autopilot udpin:0.0.0.0:14550 \\
      --autopilot udpin:0.0.0.0:14551 --autopilot udpin:0.0.0.0:14552
  uavloc launch --scenario scenarios/geo.toml --uavs autopilots \\
      --autopilot udpin:127.0.0.1:14550 --autopilot udpin:127.0.0.1:14551 --autopilot udpin:127.0.0.1:14552";

/// The bridge's flags.
#[derive(clap::Args, serde::Serialize, Debug, Clone, PartialEq)]
pub struct BridgeArgs {
    /// Node and run flags.
    #[command(flatten)]
    #[serde(flatten)]
    pub process: ProcessArgs,
    /// A UAV's MAVLink endpoint (see below); once per UAV, UAV0 first (default: the scenario's
    /// `autopilots`).
    #[arg(long = "autopilot", value_name = "ENDPOINT", value_delimiter = ',')]
    #[serde(rename = "autopilot")]
    pub autopilots: Vec<String>,
    /// The MAVLink system id of each UAV's autopilot, comma-separated (default 1, 2, 3, … in UAV order).
    #[arg(long, value_name = "ID,ID,..", value_delimiter = ',')]
    pub system_ids: Vec<u8>,
    /// Rate of the target stream and of the swarm state, Hz (autopilots drop out of guided/offboard
    /// control below 2 Hz).
    #[arg(long, value_name = "HZ", default_value_t = 10.0)]
    #[serde(serialize_with = "runtime::flags::finite")]
    pub rate_hz: f64,
    /// A link with nothing heard for this long is quiet, ms.
    #[arg(long, value_name = "MS", default_value_t = 1500)]
    pub link_timeout_ms: u64,
    /// Every UAV must be flying (armed, guided, with a fix) this long after the start, ms.
    #[arg(long, value_name = "MS", default_value_t = 15_000)]
    pub ready_timeout_ms: u64,
    /// A first fix farther than this from the scenario's start position is refused, metres.
    #[arg(long, value_name = "M", default_value_t = 5_000.0)]
    #[serde(serialize_with = "runtime::flags::finite")]
    pub max_start_offset_m: f64,
    /// Target altitude above the autopilot's home, metres (MAV_FRAME_GLOBAL_RELATIVE_ALT).
    #[arg(long, value_name = "M", default_value_t = 120.0)]
    #[serde(serialize_with = "runtime::flags::finite")]
    pub altitude_m: f64,
    /// A bridge restarted during a run (the launcher passes it): the UAVs have flown, so a first fix is
    /// refused only farther from the scenario's start than --max-start-offset-m plus the whole run's
    /// flight (speed · dt · steps).
    #[arg(long)]
    pub rejoin: bool,
    /// Simulated time per real second of the autopilots (SITL's speed-up): scales the expected speed
    /// of the jump check. 1 for real aircraft.
    #[arg(long, value_name = "X", default_value_t = 1.0)]
    #[serde(serialize_with = "runtime::flags::finite")]
    pub time_scale: f64,
}

impl BridgeArgs {
    /// Checks the values clap cannot against the run's scenario (also what `uavloc launch` checks of the
    /// bridge it starts); the error names the flag.
    pub fn check(&self, scenario: &model::Scenario) -> Result<(), String> {
        if scenario.frame().is_none() {
            return Err("--scenario: the bridge needs an [origin] (lat_deg, lon_deg, alt_m): autopilots take \
                        latitude/longitude targets (see scenarios/geo.toml)"
                .into());
        }
        let uavs = scenario.uavs.len();
        if self.autopilots.len() != uavs {
            return Err(format!(
                "--autopilot given {} time(s); the scenario has {uavs} UAVs (one endpoint per UAV, UAV0 first, with \
                 --autopilot or the scenario's `autopilots`)",
                self.autopilots.len()
            ));
        }
        if !self.system_ids.is_empty() && self.system_ids.len() != uavs {
            return Err(format!("--system-ids has {} ids; the scenario has {uavs} UAVs", self.system_ids.len()));
        }
        if self.system_ids.contains(&0) {
            return Err("--system-ids: 0 is MAVLink's broadcast id, not an autopilot's".into());
        }
        if !(self.rate_hz.is_finite() && (2.0..=100.0).contains(&self.rate_hz)) {
            return Err(format!("--rate-hz must be in 2..=100 (autopilots need ≥ 2 Hz), got {}", self.rate_hz));
        }
        if self.link_timeout_ms == 0 || self.ready_timeout_ms == 0 {
            return Err("--link-timeout-ms and --ready-timeout-ms must be > 0".into());
        }
        for (flag, v) in [("--max-start-offset-m", self.max_start_offset_m), ("--time-scale", self.time_scale)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{flag} must be a number > 0, got {v}"));
            }
        }
        if !(self.altitude_m.is_finite() && (0.0..=10_000.0).contains(&self.altitude_m)) {
            return Err(format!("--altitude-m must be in 0..=10000, got {}", self.altitude_m));
        }
        Ok(())
    }

    /// The system id expected of UAV `i`.
    pub fn system_id(&self, i: usize) -> u8 {
        self.system_ids.get(i).copied().unwrap_or((i + 1) as u8)
    }

    /// The period of the target stream and the swarm state.
    pub fn period(&self) -> Duration {
        Duration::from_secs_f64(1.0 / self.rate_hz)
    }
}
