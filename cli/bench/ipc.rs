//! `uavloc bench ipc`: one payload at a time from this process to an echo process, pinned to two cores,
//! over iceoryx2 (written in place in a loaned shared-memory sample: zero-copy) and over a Unix stream
//! socket (written into a buffer, copied through the kernel into the receiver's), for a sweep of payload
//! sizes; the one-way latency (send → received, from the stamps both ends take on CLOCK_MONOTONIC) and the
//! CPU per message of both processes. The ends are [`ipc_sweep`].

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};

use clap::{Args, ValueEnum};
use ipc_sweep::{self as sweep, HEADER, Receiver, STOP, Sender, Waiting};
use serde::Serialize;

use super::histogram::LatencyHistogram;
use super::sys;
use crate::error::CliError;
use crate::output::{Report, Table};

pub const LONG_ABOUT: &str = "\
Time one payload at a time from this process to an echo process, the two pinned to two cores, over
iceoryx2 (the payload written in place in a loaned shared-memory sample: zero-copy; a notification wakes
the receiver) and over a Unix stream socket (written into a buffer and copied through the kernel into
the receiver's), for each payload size of --sizes.

Per transport × size: the one-way latency (the sender stamps the payload once it is written, right
before handing it over; the receiver stamps it when it has it; both on CLOCK_MONOTONIC) p50/p99/max over
--messages payloads after a warm-up of 50, and the CPU time per message of both processes together. The
receiver answers each payload with a 32-byte acknowledgement before the next is sent (one in flight).
The ratios are uds / iceoryx2.

--wait block (the default): both ends block while they wait, so every message pays a kernel wake-up
(iceoryx2's notification, the socket's read). --wait spin: both ends busy-poll, yielding the CPU between
polls (the pipeline's --wait spin), so what is timed is the transports' own cost: iceoryx2 a look into
shared memory, the socket a read system call on a non-blocking socket.";

pub const AFTER_HELP: &str = "\
Examples:
  uavloc bench ipc
  uavloc bench ipc --sizes 256,1048576 --messages 500 --json
  uavloc bench ipc --wait spin --sizes 256,4096        (no kernel wake-up: the transports' own cost)
  uavloc bench ipc --cores 2,3 --out runs/ipc        (table, JSON and ipc.svg/.png)";

/// Payload sizes of the default sweep, bytes.
pub const DEFAULT_SIZES: [usize; 5] = [256, 4096, 65_536, 1_048_576, 4_194_304];

/// Payloads timed before the measured ones (connection set-up, page faults of the buffers).
pub const WARM_UP: u64 = 50;

/// Largest payload, bytes.
pub const MAX_SIZE: usize = 64 << 20;

/// A transport of the sweep.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Carrier {
    /// iceoryx2 publish/subscribe of `[u8]` samples, written in place.
    Iceoryx2,
    /// A Unix stream socket.
    Uds,
}

impl Carrier {
    fn name(self) -> &'static str {
        match self {
            Carrier::Iceoryx2 => "iceoryx2",
            Carrier::Uds => "uds",
        }
    }
}

/// How both ends of the sweep wait (`--wait`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum IpcWait {
    /// Block in the kernel until woken.
    #[default]
    Block,
    /// Busy-poll, yielding the CPU between polls.
    Spin,
}

impl IpcWait {
    fn name(self) -> &'static str {
        match self {
            IpcWait::Block => "block",
            IpcWait::Spin => "spin",
        }
    }

    fn waiting(self) -> Waiting {
        match self {
            IpcWait::Block => Waiting::Block,
            IpcWait::Spin => Waiting::Spin,
        }
    }
}

/// Flags of `uavloc bench ipc`.
#[derive(Args, Debug, Clone, PartialEq)]
pub struct IpcArgs {
    /// Payload sizes, bytes (each ≥ 16, ≤ 64 MiB).
    #[arg(long, value_name = "B,..", value_delimiter = ',', default_values_t = DEFAULT_SIZES)]
    pub sizes: Vec<usize>,
    /// Payloads timed per transport and size (after a warm-up of 50).
    #[arg(long, value_name = "N", default_value_t = 1000)]
    pub messages: u64,
    /// The two cores: this process on the first, the echo process on the second (default: the first two
    /// this process may run on).
    #[arg(long, value_name = "A,B")]
    pub cores: Option<String>,
    /// How both ends wait: block (a kernel wake-up per message) or spin (busy-poll; no wake-up).
    #[arg(long, value_enum, default_value_t = IpcWait::Block)]
    pub wait: IpcWait,
    /// Write ipc.svg and ipc.png (p50 and p99 against the payload size) and ipc.json into DIR.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

/// Flags of the echo end (`uavloc process ipc-echo`, started by `bench ipc`).
#[derive(Args, Debug, Clone, PartialEq)]
pub struct EchoArgs {
    /// The transport.
    #[arg(long, value_enum)]
    pub carrier: Carrier,
    /// iceoryx2: the sweep's service prefix; uds: the socket path.
    #[arg(long)]
    pub name: String,
    /// Largest payload, bytes.
    #[arg(long)]
    pub max_size: usize,
    /// The core to run on.
    #[arg(long)]
    pub core: usize,
    /// How it waits for payloads.
    #[arg(long, value_enum, default_value_t = IpcWait::Block)]
    pub wait: IpcWait,
}

/// One transport × size.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IpcRow {
    /// `iceoryx2` or `uds`.
    pub transport: &'static str,
    /// Payload size, bytes.
    pub size_bytes: usize,
    /// Payloads timed.
    pub n: u64,
    /// One-way latency, median, µs.
    pub p50_us: f64,
    /// One-way latency, 99th percentile, µs.
    pub p99_us: f64,
    /// One-way latency, largest, µs.
    pub max_us: f64,
    /// CPU time of both processes per message (payload and acknowledgement), µs.
    pub cpu_us_per_message: f64,
}

/// uds ÷ iceoryx2 at one size.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IpcRatio {
    /// Payload size, bytes.
    pub size_bytes: usize,
    /// Median latency, uds ÷ iceoryx2.
    pub p50: f64,
    /// 99th percentile, uds ÷ iceoryx2.
    pub p99: f64,
    /// CPU per message, uds ÷ iceoryx2.
    pub cpu: f64,
}

/// What `uavloc bench ipc` reports.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IpcReport {
    /// The two cores (sender, echo).
    pub cores: [usize; 2],
    /// The machine (`cpus`, `cpu_model`).
    #[serde(flatten)]
    pub machine: sys::Machine,
    /// How both ends waited: `block` or `spin`.
    pub wait: IpcWait,
    /// Payloads timed per row.
    pub messages: u64,
    /// One row per transport × size.
    pub rows: Vec<IpcRow>,
    /// uds ÷ iceoryx2 per size.
    pub ratios: Vec<IpcRatio>,
    /// Files written (--out).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub written: Vec<PathBuf>,
}

fn check(args: &IpcArgs) -> Result<[usize; 2], CliError> {
    if args.sizes.is_empty() {
        return Err(CliError::Input("--sizes: give at least one payload size".into()));
    }
    if let Some(bad) = args.sizes.iter().find(|&&s| !(HEADER..=MAX_SIZE).contains(&s)) {
        return Err(CliError::Input(format!("--sizes: {bad} bytes is outside {HEADER}..={MAX_SIZE}")));
    }
    // At most a million a row: with both ends blocking, ≈ 50 s.
    crate::args::require_count("--messages", args.messages as usize, 1, 1_000_000)?;
    let cores = match &args.cores {
        Some(s) => sys::parse_cores(s).map_err(|e| CliError::input_because("--cores", e))?,
        None => sys::allowed_cores().map_err(CliError::Failed)?,
    };
    match cores[..] {
        [a, b, ..] if args.cores.is_none() || cores.len() == 2 => Ok([a, b]),
        _ => Err(CliError::Input(format!(
            "--cores: give two cores (this process, the echo process), got {}",
            args.cores.as_deref().unwrap_or("one allowed core")
        ))),
    }
}

/// Kills the echo process when dropped (an error half-way leaves nothing behind).
struct Echo(Child);

impl Drop for Echo {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn spawn_echo(carrier: Carrier, name: &str, max_size: usize, core: usize, wait: IpcWait) -> Result<Echo, CliError> {
    let exe = std::env::current_exe().map_err(|e| CliError::failed_because("finding this program", e))?;
    let child = Command::new(exe)
        .args(["process", "ipc-echo", "--carrier", carrier.name(), "--name", name])
        .args(["--max-size", &max_size.to_string(), "--core", &core.to_string(), "--wait", wait.name()])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .spawn()
        .map_err(|e| CliError::failed_because("starting the echo process", e))?;
    Ok(Echo(child))
}

/// Times `args.messages` payloads of each size over one transport.
fn sweep_one(carrier: Carrier, args: &IpcArgs, cores: [usize; 2]) -> Result<Vec<IpcRow>, CliError> {
    let failed = |e: protocol::TransportError| CliError::failed_because(carrier.name(), e);
    let max_size = args.sizes.iter().copied().max().unwrap_or(HEADER);
    let tag = format!("uavloc-ipc-{}-{}", std::process::id(), carrier.name());
    let dir = std::env::temp_dir().join(&tag);
    let (mut sender, echo, _node): (Box<dyn Sender>, Echo, Option<protocol::transport::IpcNode>) = match carrier {
        Carrier::Iceoryx2 => {
            let node = protocol::transport::node(&format!("{tag}/sender")).map_err(failed)?;
            let sender = sweep::IoxSender::create(&node, &tag, max_size, args.wait.waiting()).map_err(failed)?;
            let echo = spawn_echo(carrier, &tag, max_size, cores[1], args.wait)?;
            (Box::new(sender), echo, Some(node))
        }
        Carrier::Uds => {
            std::fs::create_dir_all(&dir).map_err(|e| CliError::failed_because(format!("{}", dir.display()), e))?;
            let path = dir.join("ipc.sock");
            let _ = std::fs::remove_file(&path);
            let listener = std::os::unix::net::UnixListener::bind(&path)
                .map_err(|e| CliError::failed_because(format!("{}", path.display()), e))?;
            let echo = spawn_echo(carrier, path.to_str().unwrap_or_default(), max_size, cores[1], args.wait)?;
            let sender =
                sweep::SocketSender::accept(&listener, &path, max_size, args.wait.waiting()).map_err(failed)?;
            (Box::new(sender), echo, None)
        }
    };
    sweep::wait_ready(sender.as_mut()).map_err(failed)?;
    let mut rows = Vec::new();
    let mut seq = 0u64;
    for &size in &args.sizes {
        let mut latency = LatencyHistogram::new();
        let (mut cpu_start, mut echo_start) = (0, 0);
        for i in 0..WARM_UP + args.messages {
            if i == WARM_UP {
                cpu_start = protocol::cpu_ns();
            }
            sender.send(seq, size).map_err(failed)?;
            let ack = sender.ack().map_err(failed)?;
            if ack.seq != seq {
                return Err(CliError::Failed(format!("{}: ack {} for payload {seq}", carrier.name(), ack.seq)));
            }
            if i + 1 == WARM_UP {
                echo_start = ack.cpu_ns;
            }
            if i >= WARM_UP {
                latency.record(ack.received_ns.saturating_sub(ack.sent_ns));
                if i + 1 == WARM_UP + args.messages {
                    let cpu = (protocol::cpu_ns() - cpu_start) + ack.cpu_ns.saturating_sub(echo_start);
                    let p = latency.percentiles().ok_or_else(|| CliError::Failed("no samples".into()))?;
                    rows.push(IpcRow {
                        transport: carrier.name(),
                        size_bytes: size,
                        n: p.n,
                        p50_us: p.p50_us,
                        p99_us: p.p99_us,
                        max_us: p.max_us,
                        cpu_us_per_message: cpu as f64 / 1e3 / args.messages as f64,
                    });
                }
            }
            seq += 1;
        }
    }
    sender.send(STOP, HEADER).map_err(failed)?;
    drop(echo);
    let _ = std::fs::remove_dir_all(&dir);
    Ok(rows)
}

/// Runs `uavloc bench ipc`.
pub fn run(args: &IpcArgs) -> Result<IpcReport, CliError> {
    let cores = check(args)?;
    if let Some(dir) = &args.out {
        runtime::output::check_out_dir("--out", dir).map_err(CliError::Input)?;
    }
    sys::pin_current_process(&cores[..1]).map_err(|e| CliError::failed_because("--cores", e))?;
    protocol::transport::quiet_logs();
    let mut rows = sweep_one(Carrier::Iceoryx2, args, cores)?;
    rows.extend(sweep_one(Carrier::Uds, args, cores)?);
    let row = |t: &str, size: usize| rows.iter().find(|r| r.transport == t && r.size_bytes == size);
    let ratios = args
        .sizes
        .iter()
        .filter_map(|&s| {
            let (i, u) = (row("iceoryx2", s)?, row("uds", s)?);
            Some(IpcRatio {
                size_bytes: s,
                p50: u.p50_us / i.p50_us,
                p99: u.p99_us / i.p99_us,
                cpu: u.cpu_us_per_message / i.cpu_us_per_message,
            })
        })
        .collect();
    let mut report = IpcReport {
        cores,
        machine: sys::Machine::this(),
        wait: args.wait,
        messages: args.messages,
        rows,
        ratios,
        written: Vec::new(),
    };
    if let Some(dir) = &args.out {
        report.written = write_out(&report, dir)?;
    }
    Ok(report)
}

fn write_out(report: &IpcReport, dir: &std::path::Path) -> Result<Vec<PathBuf>, CliError> {
    use record::chart::{Series, plot_curves};
    let fail = |e: String| CliError::failed_because(format!("--out {}", dir.display()), e);
    let mut series = Vec::new();
    for t in ["iceoryx2", "uds"] {
        let rows: Vec<&IpcRow> = report.rows.iter().filter(|r| r.transport == t).collect();
        let x: Vec<f64> = rows.iter().map(|r| (r.size_bytes as f64).log2()).collect();
        series.push(Series::new(format!("{t} p50"), x.clone(), rows.iter().map(|r| r.p50_us).collect()));
        series.push(Series::new(format!("{t} p99"), x, rows.iter().map(|r| r.p99_us).collect()));
    }
    let mut written = Vec::new();
    for ext in ["svg", "png"] {
        let path = dir.join(format!("ipc.{ext}"));
        plot_curves("one-way latency per payload", "payload size, log2(bytes)", "latency, µs", &series, true, &path)
            .map_err(|e| fail(e.to_string()))?;
        written.push(path);
    }
    let json = dir.join("ipc.json");
    let text = serde_json::to_string_pretty(report).map_err(|e| fail(e.to_string()))?;
    std::fs::write(&json, text + "\n").map_err(|e| fail(e.to_string()))?;
    written.push(json);
    Ok(written)
}

/// Runs the echo end until told to stop (exit code 0) or an error (1).
pub fn run_echo(args: &EchoArgs) -> std::process::ExitCode {
    let result = (|| -> Result<(), String> {
        sys::pin_current_process(&[args.core])?;
        protocol::transport::quiet_logs();
        let mut receiver: Box<dyn Receiver> = match args.carrier {
            Carrier::Iceoryx2 => {
                let node = protocol::transport::node(&format!("{}/echo", args.name)).map_err(|e| e.to_string())?;
                let r =
                    sweep::IoxReceiver::create(&node, &args.name, args.wait.waiting()).map_err(|e| e.to_string())?;
                // The node lives as long as the process.
                std::mem::forget(node);
                Box::new(r)
            }
            Carrier::Uds => Box::new(
                sweep::SocketReceiver::connect(std::path::Path::new(&args.name), args.max_size, args.wait.waiting())
                    .map_err(|e| e.to_string())?,
            ),
        };
        while receiver.echo().map_err(|e| e.to_string())? {}
        Ok(())
    })();
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            protocol::log_line!("error: ipc-echo: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn size_label(bytes: usize) -> String {
    match bytes {
        b if b >= 1 << 20 && b % (1 << 20) == 0 => format!("{} MiB", b >> 20),
        b if b >= 1 << 10 && b % (1 << 10) == 0 => format!("{} KiB", b >> 10),
        b => format!("{b} B"),
    }
}

impl Report for IpcReport {
    fn table(&self) -> Table {
        let mut t = Table::new()
            .row("machine", self.machine.describe())
            .row("cores", format!("sender {}, echo {}", self.cores[0], self.cores[1]));
        t = t.row("wait", self.wait.name());
        t = t.row("messages per row", self.messages.to_string());
        for r in &self.rows {
            t = t.row(
                format!("{} {}", r.transport, size_label(r.size_bytes)),
                format!(
                    "p50 {:.1} µs, p99 {:.1} µs, max {:.1} µs, CPU {:.1} µs/message",
                    r.p50_us, r.p99_us, r.max_us, r.cpu_us_per_message
                ),
            );
        }
        for q in &self.ratios {
            t = t.row(
                format!("uds/iceoryx2 {}", size_label(q.size_bytes)),
                format!("p50 {:.2}×, p99 {:.2}×, CPU {:.2}×", q.p50, q.p99, q.cpu),
            );
        }
        for w in &self.written {
            t = t.row("wrote", w.display().to_string());
        }
        t
    }
}
