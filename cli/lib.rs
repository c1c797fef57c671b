//! # uavloc — the command-line calculator of the uavloc workspace
//!
//! Every subcommand is a module with a clap `Args` struct, a `run(&Args)` function that returns a
//! serde-serialisable report (callable without the process), and a [`output::Report`] impl that
//! renders it as an aligned table. `main.rs` only parses, dispatches and maps errors to exit codes.
//!
//! To add a subcommand: create its module, add a variant to [`Command`] (with `about`, `long_about`,
//! `after_help`), and one dispatch line in `main.rs`.

use clap::{Parser, Subcommand};

pub mod args;
pub mod bench;
pub mod crlb;
pub mod error;
pub mod fuse;
pub mod global;
pub mod launch;
pub mod live;
pub mod locate;
pub mod map;
pub mod output;
pub mod paper;
pub mod process_cmd;
pub mod replay;
pub mod rmse;
pub mod simulate;
pub mod swap;

pub use error::CliError;
pub use output::{Diagnostic, Report, Table};

const LONG_ABOUT: &str = "\
uavloc — passive TDOA localisation of a radio emitter by a UAV swarm.

3 to 8 UAVs time the arrival of the emitter's signal; the differences of arrival times give range
differences d_i = r_i − r_0 relative to the reference UAV0 (the first --uav). These calculator
subcommands evaluate the maths of the method for one geometry: the Cramér–Rao lower bound, the
global CRLB over an uncertain target position, Chan's closed-form position fix, and the Monte Carlo
RMSE of that fix.

Units: positions and range sigmas in metres, time sigmas (--sigma-ns) in nanoseconds, covariances
in m². Negative coordinates can be typed directly: --uav -1500,200.

Output: an aligned table, or JSON with --json. Exit codes: 0 success, 1 computation gave no usable
answer, 2 bad input (one 'error: ...' line on stderr).";

/// The top-level command line.
#[derive(Parser, Debug, Clone, PartialEq)]
#[command(
    name = "uavloc",
    version,
    about = "uavloc — passive TDOA localisation of a radio emitter by a UAV swarm",
    long_about = LONG_ABOUT,
    after_help = "Run 'uavloc <COMMAND> --help' for the units, conventions and an example of each command.",
    propagate_version = true,
    arg_required_else_help = true
)]
pub struct Cli {
    /// Print the result as JSON on stdout instead of a table.
    #[arg(long, global = true)]
    pub json: bool,
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands. Each variant's `about` is its one-line description in `uavloc --help`.
#[derive(Subcommand, Debug, Clone, PartialEq)]
pub enum Command {
    /// Single-point CRLB of the emitter position for given UAVs, target and noise
    #[command(
        long_about = crlb::LONG_ABOUT,
        after_help = crlb::AFTER_HELP
    )]
    Crlb(crlb::CrlbArgs),
    /// Global CRLB over an uncertain target position, by one of five methods
    #[command(
        long_about = global::LONG_ABOUT,
        after_help = global::AFTER_HELP
    )]
    Global(global::GlobalArgs),
    /// Emitter position and its covariance from measured range differences (Chan)
    #[command(
        long_about = locate::LONG_ABOUT,
        after_help = locate::AFTER_HELP,
        // --fuse FILE brings its own UAVs and noise: the geometry flags are required only without it.
        mut_arg("uavs", |a| a.required(false).required_unless_present("fuse")),
        mut_group("SigmaArgs", |g| g.required(false)),
        group(clap::ArgGroup::new("noise_or_fuse").args(["sigma", "sigma_ns", "fuse"]).required(true))
    )]
    Locate(locate::LocateArgs),
    /// Monte Carlo RMSE of Chan's estimator compared with the CRLB
    #[command(
        long_about = rmse::LONG_ABOUT,
        after_help = rmse::AFTER_HELP
    )]
    Rmse(rmse::RmseArgs),
    /// Run the paper's closed loop (emitter → Chan → planner → move) in one process.
    #[command(
        long_about = simulate::LONG_ABOUT,
        after_help = simulate::AFTER_HELP
    )]
    Simulate(simulate::SimulateArgs),
    /// Run the closed loop as the four iceoryx2 processes of the pipeline (lock-step or real time).
    #[command(
        long_about = launch::LONG_ABOUT,
        after_help = launch::AFTER_HELP
    )]
    Launch(launch::LaunchArgs),
    /// Replace the running planner or estimator of a pipeline by a new instance (e.g. another solver).
    #[command(
        long_about = swap::LONG_ABOUT,
        after_help = swap::AFTER_HELP
    )]
    Swap(swap::SwapArgs),
    /// Run the estimator and the planner again on a recorded run (`launch --record FILE.mcap`), open loop.
    #[command(
        long_about = replay::LONG_ABOUT,
        after_help = replay::AFTER_HELP
    )]
    Replay(replay::ReplayArgs),
    /// Draw the map of a recorded run placed on the Earth: tracks, 95 % ellipse, L_min circle, emitter.
    #[command(long_about = map::LONG_ABOUT, after_help = map::AFTER_HELP)]
    Map(map::MapArgs),
    /// Reproduce the paper's experiments (Tables 2–10, Figures 4–17) with the paper's numbers beside ours.
    #[command(
        long_about = paper::LONG_ABOUT,
        after_help = paper::AFTER_HELP
    )]
    Paper(paper::PaperArgs),
    /// Benchmarks: pipeline latency per hop and end to end (iceoryx2 vs sockets), planner compute time.
    #[command(long_about = bench::LONG_ABOUT)]
    Bench(bench::BenchArgs),
    /// Run one pipeline process in this binary (what `uavloc launch` starts): emitter-sim, estimator,
    /// planner, monitor.
    #[command(hide = true)]
    Process(process_cmd::ProcessArgs),
}

/// A clap parse error as one line: the first paragraph of clap's message with its lines joined
/// (e.g. `error: the following required arguments were not provided: --target <X,Y>`).
pub fn one_line_clap_error(e: &clap::Error) -> String {
    let text = e.to_string();
    let first: Vec<&str> = text
        .lines()
        .take_while(|l| !l.trim().is_empty() && !l.starts_with("Usage:"))
        .map(str::trim)
        .filter(|l| !l.starts_with("tip:"))
        .collect();
    let line = first.join(" ");
    if line.starts_with("error:") { line } else { format!("error: {line}") }
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    use super::*;

    #[test]
    fn cli_definition_is_consistent() {
        Cli::command().debug_assert();
    }

    #[test]
    fn negative_values_and_following_flags() {
        let cli = Cli::try_parse_from([
            "uavloc",
            "crlb",
            "--uav",
            "-1500,200",
            "--uav",
            "0,0",
            "--uav=-3,-4",
            "--target",
            "-3,-40",
            "--sigma",
            "1",
        ])
        .unwrap();
        let Command::Crlb(a) = cli.command else { panic!("not crlb") };
        assert_eq!(a.sensors.uav.uavs.len(), 3);
        assert_eq!(a.sensors.uav.uavs[0].0, [-1500.0, 200.0]);
        assert_eq!(a.sensors.uav.uavs[2].0, [-3.0, -4.0]);
        assert_eq!(a.target.0, [-3.0, -40.0]);
    }

    fn crlb_of(extra: &[&str]) -> Result<crlb::CrlbReport, CliError> {
        let mut argv = vec!["uavloc", "crlb", "--uav", "1500,500", "--uav", "10000,1500", "--uav", "5000,8500"];
        argv.extend(["--target", "25000,15000"]);
        argv.extend(extra);
        let Command::Crlb(a) = Cli::try_parse_from(argv).unwrap().command else { panic!("not crlb") };
        crlb::run(&a)
    }

    #[test]
    fn gnss_and_clock_errors_give_the_effective_range_sigma_and_the_bias_floor() {
        // White GNSS 20 m and clock 30 ns: the bound of σ_eff = sqrt(σ² + 20² + (30 ns · c)²) exactly.
        let with = crlb_of(&["--sigma", "28.7712", "--gnss-sigma", "20", "--clock-sigma-ns", "30"]).unwrap();
        let c_ns = tdoa::SPEED_OF_LIGHT * 1e-9;
        let eff = (28.7712f64.powi(2) + 400.0 + (30.0 * c_ns).powi(2)).sqrt();
        let plain = crlb_of(&["--sigma", &eff.to_string()]).unwrap();
        assert!((with.crlb_m - plain.crlb_m).abs() < 1e-9 * plain.crlb_m, "{} vs {}", with.crlb_m, plain.crlb_m);
        assert_eq!(with.bias_floor_m, None);
        // Biases of 3 m and 4 m·c: the floor is the CRLB of a 5 m range σ; they also widen the per-step σ.
        let b = crlb_of(&[
            "--sigma",
            "28.7712",
            "--gnss-bias-sigma",
            "3",
            "--clock-bias-sigma-ns",
            &(4.0 / c_ns).to_string(),
        ])
        .unwrap();
        let five = crlb_of(&["--sigma", "5"]).unwrap();
        assert!((b.bias_floor_m.unwrap() - five.crlb_m).abs() < 1e-6 * five.crlb_m, "{:?}", b.bias_floor_m);
        let widened = crlb_of(&["--sigma", &(28.7712f64.powi(2) + 25.0).sqrt().to_string()]).unwrap();
        assert!((b.crlb_m - widened.crlb_m).abs() < 1e-9 * widened.crlb_m);
        // Bad values: a clear error, not a bound.
        for bad in [&["--sigma", "1", "--gnss-sigma", "1,2"][..], &["--sigma", "1", "--clock-sigma-ns=-3"]] {
            let e = crlb_of(bad).unwrap_err().to_string();
            assert!(e.contains("--gnss-sigma") || e.contains("--clock-sigma-ns"), "{e}");
        }
    }

    #[test]
    fn clap_errors_fit_on_one_line() {
        let e = Cli::try_parse_from(["uavloc", "crlb", "--uav", "0,0", "--sigma", "1"]).unwrap_err();
        let line = one_line_clap_error(&e);
        assert!(line.starts_with("error:") && !line.contains('\n') && line.contains("--target"), "{line}");
        let e = Cli::try_parse_from(["uavloc", "crlb", "--uav", "1,2,3"]).unwrap_err();
        let line = one_line_clap_error(&e);
        assert!(line.contains("--uav") && line.contains("1,2,3"), "{line}");
    }
}
