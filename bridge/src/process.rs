//! The bridge process: a handler on the node runtime ([`runtime::node`]) woken by commands and by its
//! own tick (`--rate-hz`, a deadline of the event loop).
//!
//! Every tick it takes the telemetry its reader threads passed on (each message into the UAV's
//! [`UavLink`]; a refused one counted and logged), sends each autopilot the bridge's heartbeat (once a
//! second) and, to each UAV that flies guided with a fix, the target of the newest command (the same
//! target again every tick: autopilots leave guided/offboard control when the stream stops), and
//! publishes the swarm's state. A command of an older step than the one flown is not flown. Nothing is
//! sent to an autopilot that is quiet, disarmed or not guided. Every UAV must be flying within
//! `--ready-timeout-ms` of the start, or the bridge ends with an error naming the UAV and why.
//!
//! The bridge keeps no state of the run but what the autopilots report: a restarted bridge opens the
//! same endpoints, hears the autopilots again and flies the next command.

use std::process::ExitCode;
use std::sync::mpsc::{Receiver, channel};
use std::time::{Duration, Instant};

use model::geo::LocalFrame;
use model::load_scenario;
use protocol::{Command, LinkState, SwarmState, Topic, TopicPublisher, TopicSubscriber, services};
use runtime::{Flow, Handler, Join, Node, ProcessError};

use crate::ROLE;
use crate::args::BridgeArgs;
use crate::link::{LinkConfig, UavLink};
use crate::mav::{Autopilot, Incoming, Telemetry};
use crate::summary::{BridgeSummary, LinkSummary};
use crate::target::{Target, targets};

/// Refused telemetry lines logged per UAV before only every 100th is.
const LOGGED_REFUSALS: u64 = 5;

struct Bridge<'a> {
    args: &'a BridgeArgs,
    frame: LocalFrame,
    links: Vec<UavLink>,
    autopilots: Vec<Autopilot>,
    rx: Receiver<Incoming>,
    commands: &'a TopicSubscriber<Command>,
    swarm: &'a TopicPublisher<SwarmState>,
    last_seq: Option<u64>,
    /// The newest command's step and targets.
    current: Option<(u64, Vec<Option<Target>>)>,
    started: Instant,
    next_tick: Instant,
    next_heartbeat: Instant,
    ready: bool,
    states: Vec<LinkState>,
    summary: BridgeSummary,
}

impl Bridge<'_> {
    fn take_telemetry(&mut self, node: &Node) {
        while let Ok(Incoming { uav, at, what }) = self.rx.try_recv() {
            let (link, sum) = (&mut self.links[uav], &mut self.summary.links[uav]);
            let result = match what {
                Ok(Telemetry::Heartbeat { system, base_mode }) => link.on_heartbeat(system, base_mode, at),
                Ok(Telemetry::Position { system, data: d }) => {
                    link.on_position(system, d.lat, d.lon, d.alt, d.vx, d.vy, d.hdg, at)
                }
                Ok(Telemetry::Attitude { system, yaw }) => link.on_attitude(system, yaw, at),
                Err(e) => {
                    sum.read_errors += 1;
                    if sum.read_errors <= LOGGED_REFUSALS {
                        node.warn(format_args!("UAV {uav} ({}): read error: {e}", sum.endpoint));
                    }
                    continue;
                }
            };
            match result {
                Ok(()) => sum.telemetry += 1,
                Err(why) => {
                    sum.rejected += 1;
                    if sum.rejected <= LOGGED_REFUSALS || sum.rejected % 100 == 0 {
                        node.warn(format_args!(
                            "UAV {uav} ({}): refused telemetry ({} so far): {why}",
                            sum.endpoint, sum.rejected
                        ));
                    }
                }
            }
        }
    }

    fn take_commands(&mut self, node: &mut Node) -> Result<(), ProcessError> {
        let (batch, _) = node.receive(self.commands, &mut self.last_seq, "a command")?;
        for cmd in batch {
            let step = cmd.header.step;
            if cmd.len() != self.links.len() {
                node.summary().rejected += 1;
                node.warn(format_args!(
                    "step {step}: a command for {} UAVs, this run has {}; not flown",
                    cmd.len(),
                    self.links.len()
                ));
                continue;
            }
            if self.current.as_ref().is_some_and(|(s, _)| *s >= step) {
                continue; // a replay or an older step: the newest command stays
            }
            let t = targets(&self.frame, &cmd);
            if let Some(i) = t.iter().position(Option::is_none) {
                node.summary().rejected += 1;
                node.warn(format_args!("step {step}: UAV {i}'s waypoint has no place on the map; not flown"));
                continue;
            }
            self.current = Some((step, t));
            self.summary.last_command_step = Some(step);
        }
        Ok(())
    }

    fn tick(&mut self, node: &mut Node, now: Instant) -> Result<(), ProcessError> {
        let heartbeat = now >= self.next_heartbeat;
        if heartbeat {
            self.next_heartbeat = now + Duration::from_secs(1);
        }
        let time_boot_ms = now.saturating_duration_since(self.started).as_millis() as u32;
        let step = self.current.as_ref().map_or(0, |(s, _)| *s);
        let mut state = SwarmState::new(step, node.next_seq(), self.links.len())
            .map_err(|e| ProcessError::Failed(e.to_string()))?;
        for i in 0..self.links.len() {
            let link_state = self.links[i].state(now);
            if link_state != self.states[i] {
                let endpoint = &self.summary.links[i].endpoint;
                match link_state {
                    LinkState::Quiet => node.warn(format_args!(
                        "UAV {i} ({endpoint}): link quiet (nothing for {} ms): no targets sent, its last fix ages",
                        self.args.link_timeout_ms
                    )),
                    _ => node.say(format_args!("UAV {i} ({endpoint}): {}", link_state.name())),
                }
                self.states[i] = link_state;
                self.summary.links[i].quiet_periods = u64::from(self.links[i].quiet_periods);
            }
            if heartbeat && let Err(e) = self.autopilots[i].heartbeat() {
                self.summary.links[i].read_errors += 1;
                if self.summary.links[i].read_errors <= LOGGED_REFUSALS {
                    node.warn(format_args!("UAV {i}: cannot send the heartbeat: {e}"));
                }
            }
            if link_state == LinkState::Flying
                && let Some(target) = self.current.as_ref().and_then(|(_, t)| t[i])
            {
                let system = self.args.system_id(i);
                match self.autopilots[i].send_target(system, &target, self.args.altitude_m, time_boot_ms) {
                    Ok(()) => self.summary.links[i].targets_sent += 1,
                    Err(e) => node.warn(format_args!("UAV {i}: cannot send its target: {e}")),
                }
            }
            state.link[i] = link_state as u32;
            state.rejected[i] = self.links[i].rejected;
            if let Some(fix) = self.links[i].fix() {
                state.positions[i] = fix.xy;
                state.lat_lon_deg[i] = fix.lat_lon;
                state.altitude_m[i] = fix.altitude_m;
                state.velocities[i] = fix.velocity;
                state.headings[i] = self.links[i].heading().unwrap_or(0.0);
                // The fix's age on the shared monotonic clock.
                let age = now.saturating_duration_since(fix.at).as_nanos() as u64;
                state.fix_ns[i] = protocol::now_ns().saturating_sub(age).max(1);
            }
        }
        self.swarm.send(&state)?;
        node.summary().published += 1;
        self.summary.swarm_states += 1;
        if !self.ready {
            if self.states.iter().all(|s| *s == LinkState::Flying) {
                self.ready = true;
                node.say(format_args!("all {} UAVs fly guided", self.links.len()));
            } else if now.saturating_duration_since(self.started) > Duration::from_millis(self.args.ready_timeout_ms) {
                let i = self.states.iter().position(|s| *s != LinkState::Flying).unwrap_or(0);
                return Err(ProcessError::Failed(format!(
                    "UAV {i} (--autopilot {}, system {}) is not flying {} ms after the start: {}",
                    self.summary.links[i].endpoint,
                    self.args.system_id(i),
                    self.args.ready_timeout_ms,
                    self.links[i].why_not_flying()
                )));
            }
        }
        Ok(())
    }
}

impl Handler for Bridge<'_> {
    fn on_wake(&mut self, node: &mut Node) -> Result<Flow, ProcessError> {
        self.take_telemetry(node);
        self.take_commands(node)?;
        let now = Instant::now();
        if now >= self.next_tick {
            self.tick(node, now)?;
            self.next_tick += self.args.period();
            if self.next_tick < now {
                self.next_tick = now + self.args.period();
            }
        }
        Ok(Flow::Continue)
    }

    fn deadline(&self) -> Option<Instant> {
        Some(self.next_tick)
    }
}

/// Runs the bridge until SIGINT/SIGTERM or a shutdown.
pub fn run(args: &BridgeArgs) -> Result<BridgeSummary, ProcessError> {
    let scenario = load_scenario(args.process.run.scenario.as_deref(), args.process.run.steps, args.process.run.seed)
        .map_err(|e| ProcessError::input_because("--scenario", e))?;
    // The endpoints: the flags', else the scenario's.
    let args = &BridgeArgs {
        autopilots: if args.autopilots.is_empty() { scenario.autopilots.clone() } else { args.autopilots.clone() },
        ..args.clone()
    };
    args.check(&scenario).map_err(ProcessError::Input)?;
    let frame = scenario.frame().ok_or_else(|| ProcessError::Input("--scenario: no [origin]".into()))?;
    let (tx, rx) = channel();
    let autopilots = args
        .autopilots
        .iter()
        .enumerate()
        .map(|(i, e)| crate::mav::open(i, e, tx.clone()))
        .collect::<Result<Vec<_>, _>>()
        .map_err(ProcessError::Input)?;
    drop(tx);
    let Some(mut node) = Node::open(ROLE, &args.process.node)? else {
        return Ok(BridgeSummary { node: runtime::NodeSummary::new(ROLE, 0), ..BridgeSummary::default() });
    };
    node.set_run(scenario.run_id());
    let domain = node.domain().clone();
    let commands = Topic::<Command>::subscriber(node.link(), &services::command(&domain))?;
    let swarm = Topic::<SwarmState>::publisher(node.link(), &services::swarm(&domain))?;
    let links: Vec<UavLink> = scenario
        .uavs
        .iter()
        .enumerate()
        .map(|(i, start)| {
            let cfg = LinkConfig {
                system_id: args.system_id(i),
                start: *start,
                // A restarted bridge finds the UAVs anywhere they could have flown in the run.
                max_start_offset_m: args.max_start_offset_m
                    + if args.rejoin { scenario.speed * scenario.dt * scenario.steps as f64 } else { 0.0 },
                speed_per_real_s: scenario.speed * args.time_scale,
                timeout: Duration::from_millis(args.link_timeout_ms),
            };
            UavLink::new(cfg, frame)
        })
        .collect();
    node.join(Join::Hello, "mavlink")?;
    node.say(format_args!(
        "domain {domain}, {} autopilots ({}), targets at {} Hz, instance {:#x}",
        args.autopilots.len(),
        args.autopilots.join(", "),
        args.rate_hz,
        node.instance()
    ));
    let now = Instant::now();
    let n = links.len();
    let mut bridge = Bridge {
        args,
        frame,
        links,
        autopilots,
        rx,
        commands: &commands,
        swarm: &swarm,
        last_seq: None,
        current: None,
        started: now,
        next_tick: now,
        next_heartbeat: now,
        ready: false,
        states: vec![LinkState::Unknown; n],
        summary: BridgeSummary {
            links: args
                .autopilots
                .iter()
                .map(|e| LinkSummary { endpoint: e.clone(), ..LinkSummary::default() })
                .collect(),
            ..BridgeSummary::default()
        },
    };
    node.run(&[&commands], &mut bridge)?;
    let sent: u64 = bridge.summary.links.iter().map(|l| l.targets_sent).sum();
    node.say(format_args!("stopped after {sent} targets and {} swarm states", bridge.summary.swarm_states));
    Ok(BridgeSummary { node: node.finish(), ..bridge.summary })
}

/// Runs the bridge and maps the outcome to an exit code (errors as one `error:` line on stderr); in
/// supervised mode the summary goes to stdout as `summary {json}`.
pub fn main_with(args: &BridgeArgs) -> ExitCode {
    runtime::exit_with(ROLE, args.process.node.supervised, run(args))
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;
    use model::Scenario;

    #[derive(Parser, Debug)]
    struct Cli {
        #[command(flatten)]
        args: BridgeArgs,
    }

    /// The launcher writes the bridge's command line from its own type: nothing is lost on the way.
    #[test]
    fn the_flags_round_trip() {
        let cli = Cli::parse_from([
            "bridge",
            "--autopilot",
            "udpin:127.0.0.1:14550",
            "--autopilot=tcpout:10.0.0.2:5760",
            "--autopilot",
            "udpout:10.0.0.3:14550",
            "--system-ids",
            "4,5,6",
            "--rate-hz",
            "12.5",
            "--time-scale",
            "20",
            "--rejoin",
        ]);
        assert_eq!(cli.args.autopilots.len(), 3);
        assert_eq!(cli.args.system_id(1), 5);
        assert_eq!(runtime::flags::round_trip(&cli.args).unwrap(), cli.args);
        let geo = Scenario::from_toml_str(include_str!("../../scenarios/geo.toml")).unwrap();
        cli.args.check(&geo).unwrap();
        assert!(cli.args.check(&Scenario::default()).unwrap_err().contains("[origin]"));
        let four = BridgeArgs { autopilots: vec!["udpin:127.0.0.1:1".into(); 4], ..cli.args.clone() };
        assert!(four.check(&geo).unwrap_err().contains("--autopilot given 4"));
        let slow = BridgeArgs { rate_hz: 1.0, ..cli.args.clone() };
        assert!(slow.check(&geo).unwrap_err().contains("--rate-hz"));
        let broadcast = BridgeArgs { system_ids: vec![0, 1, 2], ..cli.args };
        assert!(broadcast.check(&geo).unwrap_err().contains("broadcast"));
    }
}
