//! The `estimator` process: receive a [`Measurement`] → [`Estimator::estimate`] → publish an [`Estimate`].
//!
//! One loop over the pipeline's measurement topic (blocking, event-driven; optionally busy-polling for
//! `--spin-us` first). It needs no scenario: the UAV positions, range differences and their σ all come
//! with the measurement (σ gives the noise model of eq. 19, exactly the one the world drew the noise
//! with). The estimate carries the measurement's UAV geometry and stamps forward
//! ([`Estimate::from_measurement`]).
//!
//! - A step-0 measurement starts a new run: the estimator forgets its prior (as `uavloc simulate` starts
//!   with a fresh [`Estimator`]).
//! - When Chan fails the library keeps its previous estimate; on the wire that is a `failed` estimate
//!   (no position), and the receivers fall back to the last usable one they saw — the same numbers.
//! - Invalid measurements are counted (per rejection kind) and ignored.
//! - SIGINT/SIGTERM end the loop cleanly (exit 0).

use std::io::Write as _;
use std::process::ExitCode;
use std::time::Duration;

use clap::Args;
use iceoryx2::prelude::*;
use nalgebra::Vector2;
use protocol::services::{self, Domain};
use protocol::{Estimate, Fix, Measurement, RejectionCounter, Topic, TopicSubscriber, TransportError, now_ns};
use tdoa::{NoiseModel, RangeDiffs};

use crate::{EstimateStatus, Estimator};

/// The role name (node name suffix, `uavloc process estimator`).
pub const ROLE: &str = "estimator";

/// How long a blocking wait lasts before the loop re-checks for a termination request that arrived
/// between two waits (a signal during a wait interrupts it at once).
pub const IDLE_WAKEUP: Duration = Duration::from_secs(1);

/// What `estimator --help` shows after the flags.
pub const AFTER_HELP: &str = "\
The estimator subscribes to <domain>/measurement and publishes <domain>/estimate. It needs no scenario:
positions, range differences and their sigmas come with each measurement.

Examples:
  estimator --domain lab1
  UAVLOC_DOMAIN=lab1 estimator --spin-us 50";

/// Flags of the estimator process (`estimator [FLAGS]` or `uavloc process estimator [FLAGS]`).
#[derive(Args, Debug, Clone, PartialEq)]
pub struct EstimatorArgs {
    /// Pipeline domain: prefix of every service name (default: $UAVLOC_DOMAIN, else "uavloc").
    #[arg(long, value_name = "NAME")]
    pub domain: Option<String>,
    /// Busy-poll this many microseconds for the next measurement before blocking (0: block at once).
    #[arg(long, value_name = "US", default_value_t = 0)]
    pub spin_us: u64,
    /// Print nothing but errors.
    #[arg(long)]
    pub quiet: bool,
    /// Under a launcher: print `ready` on stdout once subscribed, and `summary {json}` at exit.
    #[arg(long, hide = true)]
    pub supervised: bool,
}

/// Why the process stopped with an error.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ProcessError {
    /// Bad flags (exit code 2).
    Input(String),
    /// A runtime failure, e.g. iceoryx2 (exit code 1).
    Failed(String),
}

impl ProcessError {
    /// The exit code: 2 for bad input, 1 for a runtime failure.
    pub fn code(&self) -> u8 {
        match self {
            ProcessError::Input(_) => 2,
            ProcessError::Failed(_) => 1,
        }
    }
}

impl std::fmt::Display for ProcessError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ProcessError::Input(m) | ProcessError::Failed(m) => f.write_str(m),
        }
    }
}

impl From<TransportError> for ProcessError {
    fn from(e: TransportError) -> Self {
        ProcessError::Failed(e.to_string())
    }
}

/// What the estimator did, printed as its `summary` line.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct EstimatorSummary {
    /// `"estimator"`.
    pub role: &'static str,
    /// This process's instance id (in every estimate).
    pub instance: u64,
    /// Valid measurements received.
    pub accepted: u64,
    /// Invalid measurements ignored.
    pub rejected: u64,
    /// Estimates published.
    pub published: u64,
    /// Estimates published as `failed` (Chan failed; the previous estimate stands).
    pub failed: u64,
}

/// A process instance id: the pid in the high 32 bits, the start time's low bits below.
pub fn instance_id() -> u64 {
    (u64::from(std::process::id()) << 32) | (now_ns() & 0xffff_ffff)
}

/// Blocks (after busy-polling `spin`) until messages arrive; `None` when SIGINT/SIGTERM asks to stop.
fn next_batch<T: protocol::Message>(
    node: &Node<ipc::Service>,
    sub: &TopicSubscriber<T>,
    spin: Duration,
    timeout: Duration,
) -> Result<Option<Vec<T>>, ProcessError> {
    if node.wait(Duration::ZERO).is_err() {
        return Ok(None);
    }
    match sub.wait(spin, timeout) {
        Ok(batch) => Ok(Some(batch)),
        // A signal interrupted the wait: stop if it was SIGINT/SIGTERM, else carry on.
        Err(TransportError::Interrupted) => {
            Ok(if node.wait(Duration::ZERO).is_err() { None } else { Some(Vec::new()) })
        }
        Err(e) => Err(e.into()),
    }
}

fn announce(supervised: bool, line: &str) {
    if supervised {
        let mut out = std::io::stdout().lock();
        let _ = writeln!(out, "{line}");
        let _ = out.flush();
    }
}

/// The estimate of one measurement as a wire [`Fix`] (`Fix::Failed` when Chan failed, whether or not the
/// library had a previous estimate to keep).
pub fn estimate_measurement(estimator: &mut Estimator, m: &Measurement) -> Fix {
    let uavs: Vec<Vector2<f64>> = m.uavs().iter().map(|p| Vector2::new(p[0], p[1])).collect();
    let (Ok(noise), Ok(diffs)) = (NoiseModel::from_range_sigmas(m.sigmas()), RangeDiffs::from_slice(m.diffs())) else {
        return Fix::Failed;
    };
    match estimator.estimate(&uavs, &diffs, &noise) {
        Ok(out) => {
            let position = [out.position.x, out.position.y];
            let c = out.covariance;
            let covariance = [[c[(0, 0)], c[(0, 1)]], [c[(1, 0)], c[(1, 1)]]];
            match out.status {
                EstimateStatus::Ok => Fix::Ok { position, covariance },
                EstimateStatus::Ambiguous => Fix::Ambiguous { position, covariance },
                EstimateStatus::Failed { .. } => Fix::Failed,
            }
        }
        Err(_) => Fix::Failed,
    }
}

/// Runs the estimator until SIGINT/SIGTERM.
pub fn run(args: &EstimatorArgs) -> Result<EstimatorSummary, ProcessError> {
    protocol::transport::quiet_logs();
    let domain = Domain::resolve(args.domain.as_deref()).map_err(|e| ProcessError::Input(e.to_string()))?;
    let node = protocol::node(&services::node_name(&domain, ROLE))?;
    // The first wait installs iceoryx2's SIGINT/SIGTERM handler, so a signal ends the loop cleanly.
    if node.wait(Duration::ZERO).is_err() {
        return Ok(EstimatorSummary { role: ROLE, ..EstimatorSummary::default() });
    }
    let measurements = Topic::<Measurement>::subscriber(&node, &services::measurement(&domain))?;
    let estimates = Topic::<Estimate>::publisher(&node, &services::estimate(&domain))?;
    let instance = instance_id();
    let mut summary = EstimatorSummary { role: ROLE, instance, ..EstimatorSummary::default() };
    announce(args.supervised, "ready");
    if !args.quiet {
        eprintln!("estimator: domain {domain}, instance {instance:#x}");
    }

    let spin = Duration::from_micros(args.spin_us);
    let mut counter = RejectionCounter::new();
    let mut last_seq = None;
    let mut seq = now_ns();
    let mut estimator = Estimator::new();
    while let Some(batch) = next_batch(&node, &measurements, spin, IDLE_WAKEUP)? {
        let received_ns = now_ns();
        for m in batch {
            if let Err(r) = counter.check(&m, &mut last_seq) {
                summary.rejected += 1;
                eprintln!("estimator: rejected a measurement: {r}");
                continue;
            }
            summary.accepted += 1;
            if m.header.step == 0 {
                estimator = Estimator::new(); // a new run
            }
            let fix = estimate_measurement(&mut estimator, &m);
            if fix == Fix::Failed {
                summary.failed += 1;
                eprintln!("estimator: step {}: no fix (the previous estimate stands)", m.header.step);
            }
            seq += 1;
            let estimate = Estimate::from_measurement(&m, received_ns, seq, instance, fix)
                .map_err(|e| ProcessError::Failed(format!("step {}: estimate: {e}", m.header.step)))?;
            estimates.send(&estimate)?;
            summary.published += 1;
        }
    }
    if !args.quiet {
        eprintln!("estimator: stopped after {} estimates ({counter})", summary.published);
    }
    Ok(summary)
}

/// Runs the estimator and maps the outcome to an exit code (errors as one `error:` line on stderr); in
/// supervised mode the summary goes to stdout as `summary {json}`.
pub fn main_with(args: &EstimatorArgs) -> ExitCode {
    match run(args) {
        Ok(summary) => {
            announce(args.supervised, &format!("summary {}", serde_json::to_string(&summary).unwrap_or_default()));
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: estimator: {e}");
            ExitCode::from(e.code())
        }
    }
}
