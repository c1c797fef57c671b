//! The flags every process takes: its node (domain, link: transport and waiting, quiet, supervised) and
//! the run (scenario, steps, seed).

use std::path::PathBuf;

use protocol::{TransportKind, WaitMode, WaitPolicy};

/// The run every process of a pipeline must agree on: the scenario and the overrides of its steps and
/// seed (each process loads it with `model::load_scenario`, the same rule as `uavloc simulate`).
#[derive(clap::Args, serde::Serialize, Debug, Clone, Default, PartialEq, Eq)]
pub struct RunArgs {
    /// Scenario TOML file (default: the paper's nominal case; see scenarios/nominal.toml).
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<PathBuf>,
    /// Planning steps (default: the scenario's): steps 0..N are measured, 0..N−1 planned.
    #[arg(long, value_name = "N")]
    pub steps: Option<usize>,
    /// Run seed (default: the scenario's): every random stream of step k derives from (seed, k).
    #[arg(long, value_name = "N")]
    pub seed: Option<u64>,
}

/// Where a pipeline's measurements come from (`uavloc launch --source`, `monitor --source`).
#[derive(clap::ValueEnum, Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Source {
    /// emitter-sim, the simulated world, which also publishes the truth of every step.
    #[default]
    Simulator,
    /// A front end outside uavloc (any language; the contract is docs/wire-format.md) publishes the
    /// measurements and reads the commands; there is no truth.
    External,
}

impl Source {
    /// The flag value.
    pub fn name(self) -> &'static str {
        match self {
            Source::Simulator => "simulator",
            Source::External => "external",
        }
    }
}

impl std::fmt::Display for Source {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Default busy-poll budget of `--wait spin-then-block` when `--spin-us` is not given, µs.
pub const DEFAULT_SPIN_US: u64 = 100;

/// The flags every process takes for its node: domain, link, and how it talks.
#[derive(clap::Args, serde::Serialize, Debug, Clone, Default, PartialEq, Eq)]
pub struct NodeArgs {
    /// Pipeline domain: prefix of every service name (default: $UAVLOC_DOMAIN, else "uavloc").
    #[arg(long, value_name = "NAME")]
    pub domain: Option<String>,
    /// Transport and waiting.
    #[command(flatten)]
    #[serde(flatten)]
    pub link: LinkArgs,
    /// Print nothing but errors (no status lines on stderr).
    #[arg(long)]
    pub quiet: bool,
    /// Under a launcher: print `ready` on stdout once connected and `summary {json}` at exit (and what
    /// the role tells its supervisor besides: emitter-sim's `finished`, the monitor's `record {json}`).
    #[arg(long, hide = true)]
    pub supervised: bool,
    /// Stop once the process PID has ended: what `uavloc swap` gives a swapped-in process (not the
    /// launch's child, so not stopped with it otherwise), with the pid of the launch that runs the domain.
    #[arg(long, hide = true, value_name = "PID")]
    pub watch_pid: Option<u32>,
}

/// The flags of a process that takes part in a run with a scenario (emitter-sim, the planner, the
/// monitor): its node and the run.
#[derive(clap::Args, serde::Serialize, Debug, Clone, Default, PartialEq, Eq)]
pub struct ProcessArgs {
    /// The node: domain, link (transport and waiting), quiet, supervised.
    #[command(flatten)]
    #[serde(flatten)]
    pub node: NodeArgs,
    /// The run: scenario, steps, seed.
    #[command(flatten)]
    #[serde(flatten)]
    pub run: RunArgs,
}

/// The transport and wait flags every process (and `uavloc launch`, which passes them on) takes.
#[derive(clap::Args, serde::Serialize, Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LinkArgs {
    /// Transport of the topics: iceoryx2 (zero-copy shared memory) | uds (Unix-domain datagram sockets,
    /// the benchmark baseline). Every process of a domain must use the same one.
    #[arg(long, value_name = "KIND", default_value = "iceoryx2")]
    #[serde(serialize_with = "crate::flags::display")]
    pub transport: TransportKind,
    /// How to wait for the next message: block (no CPU while idle) | spin (busy-poll, yielding the CPU;
    /// never blocks) | spin-then-block (busy-poll --spin-us, then block). Default: block, or
    /// spin-then-block when --spin-us is given.
    #[arg(long, value_name = "MODE")]
    #[serde(serialize_with = "crate::flags::display_opt")]
    pub wait: Option<WaitMode>,
    /// Busy-poll budget of spin-then-block, microseconds (default 100 with --wait spin-then-block).
    #[arg(long, value_name = "US")]
    pub spin_us: Option<u64>,
}

impl LinkArgs {
    /// The wait policy of the flags (see [`LinkArgs::wait`]).
    pub fn policy(&self) -> WaitPolicy {
        let mode = self.wait.unwrap_or(match self.spin_us {
            Some(us) if us > 0 => WaitMode::SpinThenBlock,
            _ => WaitMode::Block,
        });
        WaitPolicy::new(mode, self.spin_us.unwrap_or(DEFAULT_SPIN_US))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn link_args_policy_and_flags() {
        let a = LinkArgs::default();
        assert_eq!(a.policy().mode, WaitMode::Block);
        let a = LinkArgs { spin_us: Some(50), ..LinkArgs::default() };
        assert_eq!(a.policy(), WaitPolicy::new(WaitMode::SpinThenBlock, 50));
        let a = LinkArgs { wait: Some(WaitMode::SpinThenBlock), ..LinkArgs::default() };
        assert_eq!(a.policy().spin, Duration::from_micros(DEFAULT_SPIN_US));
        let a = LinkArgs { transport: TransportKind::Uds, wait: Some(WaitMode::Spin), spin_us: None };
        assert_eq!(crate::flags::to_flags(&a).unwrap(), ["--transport=uds", "--wait=spin"]);
    }
}
