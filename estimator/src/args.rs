//! The estimator's flags (`estimator [FLAGS]`, `uavloc process estimator [FLAGS]`) and the estimator
//! configuration they give.

use clap::Args;
use tdoa::Dynamics;

use estimation::{EmitterModel, EstimatorConfig, EstimatorKind};
use runtime::ProcessError;

/// What `estimator --help` shows after the flags.
pub const AFTER_HELP: &str = "\
The estimator subscribes to <domain>/measurement and publishes <domain>/estimate. It needs no scenario:
positions, range differences and their sigmas come with each measurement. It keeps no file: the state
each step goes on from rides the messages (every command on <domain>/command echoes it); a step whose
predecessor's state it has not seen (after a restart) is held while it asks the monitor for that state
(answered on <domain>/state).

Examples:
  estimator --domain lab1
  UAVLOC_DOMAIN=lab1 estimator --spin-us 50";

/// Flags of the estimator process (`estimator [FLAGS]` or `uavloc process estimator [FLAGS]`).
/// Also `Serialize`: [`runtime::flags::to_flags`] writes the command line of these flags.
#[derive(Args, serde::Serialize, Debug, Clone, PartialEq)]
pub struct EstimatorArgs {
    /// The node: domain, link (transport and waiting), quiet, supervised.
    #[command(flatten)]
    #[serde(flatten)]
    pub node: runtime::NodeArgs,
    /// Take over from the running estimator at the next step (see `uavloc swap estimator`).
    #[arg(long)]
    pub takeover: bool,
    /// The estimator: fused (the posterior of every measurement so far, χ²-gated) or snapshot (the
    /// paper's Chan fix of each measurement alone).
    #[arg(long, value_name = "KIND", default_value = "fused")]
    #[serde(serialize_with = "runtime::flags::display")]
    pub estimator: EstimatorKind,
    /// The fused estimator's emitter model: static or constant_velocity.
    #[arg(long, value_name = "MODEL", default_value = "static")]
    #[serde(serialize_with = "runtime::flags::display")]
    pub emitter_model: EmitterModel,
    /// constant_velocity: white-acceleration process noise σ_a, m/s² (≥ 0).
    #[arg(long, value_name = "M/S2", default_value_t = 0.05)]
    #[serde(serialize_with = "runtime::flags::finite")]
    pub process_noise_accel: f64,
    /// constant_velocity: σ per axis of the initial velocity (0 ± this), m/s (> 0).
    #[arg(long, value_name = "M/S", default_value_t = 20.0)]
    #[serde(serialize_with = "runtime::flags::finite")]
    pub velocity_prior_sigma: f64,
    /// constant_velocity: the time between two steps' measurements, s (the scenario's dt).
    #[arg(long, value_name = "S", default_value_t = 10.0)]
    #[serde(serialize_with = "runtime::flags::finite")]
    pub interval_s: f64,
}

impl EstimatorArgs {
    /// The estimator configuration of the flags; errors name the flag.
    pub fn config(&self) -> Result<EstimatorConfig, ProcessError> {
        let dynamics =
            Dynamics::new(self.emitter_model, self.interval_s, self.process_noise_accel, self.velocity_prior_sigma)
                .map_err(|e| {
                    let text = e.to_string();
                    let product = matches!(e, tdoa::TdoaError::OutOfRange { .. });
                    let flag = match () {
                        () if product && text.contains("process_noise_accel") => "--process-noise-accel, --interval-s",
                        () if product => "--velocity-prior-sigma, --interval-s",
                        () if text.contains("process_noise_accel") => "--process-noise-accel",
                        () if text.contains("velocity_prior") => "--velocity-prior-sigma",
                        _ => "--interval-s",
                    };
                    ProcessError::input_because(flag, e)
                })?;
        Ok(EstimatorConfig::new(self.estimator, dynamics))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_flags_round_trip() {
        let a = EstimatorArgs {
            node: runtime::NodeArgs { domain: Some("lab".into()), quiet: true, ..runtime::NodeArgs::default() },
            takeover: true,
            estimator: EstimatorKind::Snapshot,
            emitter_model: EmitterModel::ConstantVelocity,
            process_noise_accel: 0.1 + 0.2,
            velocity_prior_sigma: 7.5,
            interval_s: 1.0 / 3.0,
        };
        assert_eq!(runtime::flags::round_trip(&a).unwrap(), a);
    }
}
