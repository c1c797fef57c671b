//! The monitor's latency statistics: per-hop histograms of fixed size over the planned steps (the memory
//! does not grow with the run), summarised as median and maximum in microseconds.

use hdrhistogram::Histogram;
use protocol::Latencies;

/// Median and maximum of a latency, microseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct LatencyStat {
    /// Median, µs.
    pub p50_us: f64,
    /// Maximum, µs.
    pub max_us: f64,
    /// Samples.
    pub n: usize,
}

impl LatencyStat {
    pub(crate) fn of(h: &Histogram<u64>) -> Option<Self> {
        if h.is_empty() {
            return None;
        }
        Some(Self { p50_us: h.value_at_quantile(0.5) as f64 / 1e3, max_us: h.max() as f64 / 1e3, n: h.len() as usize })
    }
}

/// Latency statistics over the planned steps of a run.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct LatencySummary {
    /// Command published → received by emitter-sim.
    pub command_hop: Option<LatencyStat>,
    /// Measurement published → received by the estimator.
    pub measurement_hop: Option<LatencyStat>,
    /// Estimate published → received by the planner.
    pub estimate_hop: Option<LatencyStat>,
    /// Measurement published → command published (estimator + planner, with both hops).
    pub end_to_end: Option<LatencyStat>,
    /// Command of step k−1 published → command of step k published (one whole cycle: in lock-step mode the
    /// pipeline's round trip, in real-time mode about one step interval).
    pub cycle: Option<LatencyStat>,
}

/// The latencies of the planned steps, in histograms of fixed size (the memory does not grow with the run;
/// a median is known to 0.1 %, the maximum exactly).
#[derive(Debug)]
pub(crate) struct LatencySamples {
    command_hop: Histogram<u64>,
    measurement_hop: Histogram<u64>,
    estimate_hop: Histogram<u64>,
    end_to_end: Histogram<u64>,
    cycle: Histogram<u64>,
}

impl Default for LatencySamples {
    fn default() -> Self {
        // 1 ns .. 1 h at 3 significant figures; larger values are clamped to 1 h.
        let h = || Histogram::<u64>::new_with_bounds(1, 3_600_000_000_000, 3).expect("valid histogram bounds");
        Self { command_hop: h(), measurement_hop: h(), estimate_hop: h(), end_to_end: h(), cycle: h() }
    }
}

impl LatencySamples {
    pub(crate) fn add(&mut self, l: &Latencies) {
        for (v, s) in [
            (l.trigger_hop_ns, &mut self.command_hop),
            (l.measurement_hop_ns, &mut self.measurement_hop),
            (l.estimate_hop_ns, &mut self.estimate_hop),
            (l.end_to_end_ns, &mut self.end_to_end),
            (l.cycle_ns, &mut self.cycle),
        ] {
            if let Some(ns) = v {
                s.saturating_record(ns);
            }
        }
    }

    pub(crate) fn summary(&self) -> LatencySummary {
        LatencySummary {
            command_hop: LatencyStat::of(&self.command_hop),
            measurement_hop: LatencyStat::of(&self.measurement_hop),
            estimate_hop: LatencyStat::of(&self.estimate_hop),
            end_to_end: LatencyStat::of(&self.end_to_end),
            cycle: LatencyStat::of(&self.cycle),
        }
    }
}
