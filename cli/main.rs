//! The `uavloc` command-line interface: parse, dispatch, print, map errors to exit codes.

use std::io::Write;
use std::process::ExitCode;

use clap::error::ErrorKind;
use clap::{CommandFactory, FromArgMatches};
use uavloc::{
    Cli, CliError, Command, Diagnostic, Report, bench, crlb, global, launch, locate, one_line_clap_error, paper,
    process_cmd, replay, rmse, simulate, swap,
};

fn main() -> ExitCode {
    let parsed = Cli::command().try_get_matches().and_then(|m| Cli::from_arg_matches(&m).map(|cli| (cli, m)));
    let (cli, matches) = match parsed {
        Ok(parsed) => parsed,
        Err(e) => {
            return match e.kind() {
                ErrorKind::DisplayHelp
                | ErrorKind::DisplayVersion
                | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => {
                    let _ = e.print();
                    ExitCode::from(if e.use_stderr() { 2 } else { 0 })
                }
                _ => {
                    protocol::log_line!("{}", one_line_clap_error(&e));
                    ExitCode::from(2)
                }
            };
        }
    };
    let json = cli.json;
    match &cli.command {
        Command::Crlb(a) => emit(crlb::run(a), json),
        Command::Global(a) => emit(global::run(a), json),
        Command::Locate(a) => emit(locate::run(a), json),
        Command::Rmse(a) => emit(rmse::run(a), json),
        Command::Simulate(a) => {
            emit(simulate::run(&simulate::SimulateArgs { live: a.live && !json, ..a.clone() }), json)
        }
        Command::Launch(a) => emit(launch::run_from_cli(a, json), json),
        Command::Swap(a) => emit(swap::run(a, &swap::given_flags(&matches)), json),
        Command::Replay(a) => emit(replay::run(a), json),
        Command::Map(a) => emit(uavloc::map::run(a), json),
        Command::Paper(a) => emit(paper::run(a), json),
        Command::Bench(a) => match &a.what {
            bench::BenchCommand::Latency(a) => emit(bench::latency::run_latency(a), json),
            bench::BenchCommand::Compare(a) => emit(bench::latency::run_compare(a), json),
            bench::BenchCommand::Planner(a) => emit(bench::planner::run(a), json),
            bench::BenchCommand::Ipc(a) => emit(bench::ipc::run(a), json),
        },
        Command::Process(a) => process_cmd::run_process(a),
    }
}

/// Prints a result (JSON or table) and its diagnostics, or the error; returns the exit code.
fn emit<R: Report>(result: Result<R, CliError>, json: bool) -> ExitCode {
    let report = match result {
        Ok(r) => r,
        Err(e) => {
            protocol::log_line!("error: {e}");
            return e.exit_code();
        }
    };
    if json {
        // Streamed: a long run's record is not held a second time as text (158 MB for 100 000 steps).
        let mut out = std::io::BufWriter::new(std::io::stdout().lock());
        match serde_json::to_writer_pretty(&mut out, &report) {
            Ok(()) => {
                // A closed pipe (e.g. `| head`) is not an error worth a panic.
                let _ = out.write_all(b"\n").and_then(|()| out.flush());
            }
            Err(e) if e.is_io() => {} // a closed pipe, as above
            Err(e) => {
                drop(out);
                protocol::log_line!("error: cannot encode the result as JSON: {e}");
                return ExitCode::FAILURE;
            }
        }
    } else {
        // A closed pipe (e.g. `| head`) is not an error worth a panic.
        let _ = std::io::stdout().lock().write_all(report.text().as_bytes());
    }
    let mut code = ExitCode::SUCCESS;
    for d in report.diagnostics() {
        match d {
            Diagnostic::Warning(m) => protocol::log_line!("warning: {m}"),
            Diagnostic::Failure(m) => {
                protocol::log_line!("error: {m}");
                code = ExitCode::from(uavloc::error::EXIT_FAILED);
            }
        }
    }
    code
}
