//! The transport's policies, as enums: which transport carries the topics (`--transport`) and how a
//! process waits for its next message (`--wait`, `--spin-us`).

use core::fmt;
use core::str::FromStr;
use core::time::Duration;

/// Which transport carries the topics' messages (`--transport iceoryx2|uds`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub enum TransportKind {
    /// iceoryx2 publish/subscribe, zero-copy shared memory, with event services for wake-ups.
    #[default]
    Iceoryx2,
    /// Unix-domain datagram sockets carrying the bytes of the `#[repr(C)]` messages (the baseline).
    Uds,
}

impl TransportKind {
    /// Both, in the order benchmarks report them.
    pub const ALL: [TransportKind; 2] = [TransportKind::Iceoryx2, TransportKind::Uds];

    /// `"iceoryx2"` or `"uds"` (the flag value).
    pub fn name(self) -> &'static str {
        match self {
            TransportKind::Iceoryx2 => "iceoryx2",
            TransportKind::Uds => "uds",
        }
    }
}

impl fmt::Display for TransportKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for TransportKind {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "iceoryx2" | "iox2" => Ok(TransportKind::Iceoryx2),
            "uds" => Ok(TransportKind::Uds),
            _ => Err(format!("unknown transport {s:?} (expected iceoryx2 or uds)")),
        }
    }
}

/// How a process waits for its next message (`--wait`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub enum WaitMode {
    /// Block in the kernel at once (no CPU while idle; each wake-up costs the scheduler's latency).
    #[default]
    Block,
    /// Busy-poll (yielding the CPU between polls) for the whole timeout; never blocks. Lowest latency
    /// while every process has a core; burns a core per process when idle.
    Spin,
    /// Busy-poll for `--spin-us`, then block.
    SpinThenBlock,
}

impl WaitMode {
    /// All three, in the order benchmarks report them.
    pub const ALL: [WaitMode; 3] = [WaitMode::Block, WaitMode::SpinThenBlock, WaitMode::Spin];

    /// `"block"`, `"spin"` or `"spin-then-block"` (the flag value).
    pub fn name(self) -> &'static str {
        match self {
            WaitMode::Block => "block",
            WaitMode::Spin => "spin",
            WaitMode::SpinThenBlock => "spin-then-block",
        }
    }

    /// How a wait of at most `timeout` is split into (busy-poll, then block) for this mode, with `spin` the
    /// busy-poll budget of [`WaitMode::SpinThenBlock`].
    pub fn split(self, spin: Duration, timeout: Duration) -> (Duration, Duration) {
        match self {
            WaitMode::Block => (Duration::ZERO, timeout),
            WaitMode::Spin => (timeout, Duration::ZERO),
            WaitMode::SpinThenBlock => (spin.min(timeout), timeout.saturating_sub(spin)),
        }
    }
}

impl fmt::Display for WaitMode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for WaitMode {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "block" => Ok(WaitMode::Block),
            "spin" => Ok(WaitMode::Spin),
            "spin-then-block" => Ok(WaitMode::SpinThenBlock),
            _ => Err(format!("unknown wait mode {s:?} (expected block, spin or spin-then-block)")),
        }
    }
}

/// How a process waits: the mode and the busy-poll budget of [`WaitMode::SpinThenBlock`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct WaitPolicy {
    /// The mode.
    pub mode: WaitMode,
    /// Busy-poll budget of [`WaitMode::SpinThenBlock`] (ignored by the other modes).
    pub spin: Duration,
}

impl WaitPolicy {
    /// The policy of the `--wait MODE --spin-us US` flags.
    pub fn new(mode: WaitMode, spin_us: u64) -> Self {
        WaitPolicy { mode, spin: Duration::from_micros(spin_us) }
    }

    /// (busy-poll, then block) for a wait of at most `timeout`; see [`WaitMode::split`].
    pub fn split(&self, timeout: Duration) -> (Duration, Duration) {
        self.mode.split(self.spin, timeout)
    }
}
