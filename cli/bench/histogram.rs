//! Latency histograms of `uavloc bench`: nanosecond samples (differences of CLOCK_MONOTONIC stamps) in an
//! [`hdrhistogram::Histogram`], summarised as p50/p90/p99/p99.9/max in microseconds ([`Percentiles`]),
//! exported as a CSV of the recorded buckets ([`LatencyHistogram::csv`]) and as a percentile spectrum for
//! the "latency by percentile" plot ([`LatencyHistogram::percentile_spectrum`]).
//!
//! Resolution: 3 significant figures (a recorded value is known to within 0.1 %), over 0 ns .. 60 s.
//! A sample of 0 ns is recorded as 0 (it has a bucket of its own; the lowest discernible value is 1 ns).
//! A sample above 60 s is recorded as 60 s and counted in [`LatencyHistogram::saturated`]. The maximum is
//! tracked exactly, beside the histogram, and every reported quantile is capped at it.

use hdrhistogram::Histogram;
use serde::{Deserialize, Serialize};

/// Largest recordable latency, nanoseconds (60 s); larger samples are clamped to it.
pub const MAX_NS: u64 = 60_000_000_000;
/// Significant decimal figures kept by the histogram (relative resolution ≤ 0.1 %).
pub const SIGNIFICANT_FIGURES: u8 = 3;
/// Resolution of [`LatencyHistogram::percentile_spectrum`]: quantile ticks per half of the remaining
/// distance to 100 % (HdrHistogram's usual 5: 0 %, 10 %, …, 50 %, 55 %, …, 75 %, 77.5 %, …).
pub const SPECTRUM_TICKS_PER_HALF_DISTANCE: u32 = 5;

/// The usual latency summary of one histogram, microseconds (`n` is the number of samples).
///
/// The JSON keys are exactly `p50_us`, `p90_us`, `p99_us`, `p999_us`, `max_us` and `n`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Percentiles {
    /// Median, µs.
    pub p50_us: f64,
    /// 90th percentile, µs.
    pub p90_us: f64,
    /// 99th percentile, µs.
    pub p99_us: f64,
    /// 99.9th percentile, µs.
    pub p999_us: f64,
    /// Largest sample (exact, not bucketed), µs.
    pub max_us: f64,
    /// Number of samples.
    pub n: u64,
}

/// A latency distribution in nanoseconds (see the module documentation for range and resolution).
#[derive(Debug, Clone)]
pub struct LatencyHistogram {
    hist: Histogram<u64>,
    /// Samples above [`MAX_NS`] (recorded as [`MAX_NS`]).
    saturated: u64,
    /// Largest sample recorded (after clamping), ns; 0 when empty.
    max_ns: u64,
}

impl Default for LatencyHistogram {
    fn default() -> Self {
        Self::new()
    }
}

/// Nanoseconds to microseconds.
fn us(ns: u64) -> f64 {
    ns as f64 / 1000.0
}

impl LatencyHistogram {
    /// An empty histogram: 1 ns .. 60 s ([`MAX_NS`]), 3 significant figures, no auto-resize.
    pub fn new() -> Self {
        let mut hist = Histogram::new_with_bounds(1, MAX_NS, SIGNIFICANT_FIGURES)
            .expect("constant bounds 1 ns .. 60 s with 3 significant figures are valid");
        hist.auto(false);
        LatencyHistogram { hist, saturated: 0, max_ns: 0 }
    }

    /// Records one latency sample, nanoseconds. 0 is recorded as 0; a sample above [`MAX_NS`] (60 s) is
    /// recorded as [`MAX_NS`] and counted in [`Self::saturated`].
    pub fn record(&mut self, ns: u64) {
        let ns = if ns > MAX_NS {
            self.saturated += 1;
            MAX_NS
        } else {
            ns
        };
        // In range by construction; saturating_record cannot fail (and would clamp rather than panic).
        self.hist.saturating_record(ns);
        self.max_ns = self.max_ns.max(ns);
    }

    /// Number of samples recorded (saturated ones included).
    pub fn len(&self) -> u64 {
        self.hist.len()
    }

    /// Whether no sample was recorded.
    pub fn is_empty(&self) -> bool {
        self.hist.is_empty()
    }

    /// Number of samples that were above [`MAX_NS`] (60 s) and recorded as [`MAX_NS`].
    pub fn saturated(&self) -> u64 {
        self.saturated
    }

    /// The largest sample, exact, nanoseconds (`None` when empty).
    pub fn max_ns(&self) -> Option<u64> {
        (!self.is_empty()).then_some(self.max_ns)
    }

    /// Mean of the samples (bucket midpoints), µs (`None` when empty).
    pub fn mean_us(&self) -> Option<f64> {
        (!self.is_empty()).then(|| self.hist.mean() / 1000.0)
    }

    /// Adds every sample of `other` to this histogram (as if they had been recorded here); the
    /// saturation counts add up and the maximum is the larger one.
    pub fn merge(&mut self, other: &LatencyHistogram) {
        // Both histograms have the same bounds (only `new` constructs them), so adding cannot fail.
        self.hist.add(&other.hist).expect("latency histograms share their bounds");
        self.saturated += other.saturated;
        self.max_ns = self.max_ns.max(other.max_ns);
    }

    /// The value at quantile `q` (0 ..= 1, clamped), µs: the upper end of the bucket holding the
    /// ⌈q·n⌉-th smallest sample (within 0.1 % above it), capped at the exact maximum. `None` when empty
    /// or when `q` is NaN.
    pub fn value_at_quantile_us(&self, q: f64) -> Option<f64> {
        if self.is_empty() || q.is_nan() {
            return None;
        }
        Some(us(self.value_at_quantile_ns(q.clamp(0.0, 1.0))))
    }

    fn value_at_quantile_ns(&self, q: f64) -> u64 {
        self.hist.value_at_quantile(q).min(self.max_ns)
    }

    /// p50/p90/p99/p99.9 (as [`Self::value_at_quantile_us`]) and the exact maximum, µs, with the
    /// number of samples; `None` when empty.
    pub fn percentiles(&self) -> Option<Percentiles> {
        if self.is_empty() {
            return None;
        }
        let at = |q: f64| us(self.value_at_quantile_ns(q));
        Some(Percentiles {
            p50_us: at(0.5),
            p90_us: at(0.9),
            p99_us: at(0.99),
            p999_us: at(0.999),
            max_us: us(self.max_ns),
            n: self.len(),
        })
    }

    /// The recorded distribution, ascending: one `(upper bound of the bucket, ns; samples in it)` pair per
    /// non-empty bucket (the bucket holds the values from 0.1 % below its upper bound up to it).
    pub fn buckets(&self) -> Vec<(u64, u64)> {
        self.hist.iter_recorded().map(|v| (v.value_iterated_to(), v.count_at_value())).collect()
    }

    /// The recorded buckets as CSV: the header `value_us,count,cumulative_count,percentile`, then one row
    /// per non-empty bucket ([`Self::buckets`]): its upper bound in µs (3 decimals, i.e. ns), its
    /// samples, the samples up to it, and that as a percentage of all samples (6 decimals; the last row
    /// is 100). Only the header when empty.
    pub fn csv(&self) -> String {
        let total = self.len();
        let mut out = String::from("value_us,count,cumulative_count,percentile\n");
        let mut cumulative = 0u64;
        for (value_ns, count) in self.buckets() {
            cumulative += count;
            let percentile = cumulative as f64 / total as f64 * 100.0;
            out.push_str(&format!("{:.3},{count},{cumulative},{percentile:.6}\n", us(value_ns)));
        }
        out
    }

    /// The latency by percentile, for plotting: `(percentile, 0 ..= 100; value, µs)` pairs with the
    /// percentile rising in steps that halve every time half of the remaining distance to 100 % is
    /// covered ([`SPECTRUM_TICKS_PER_HALF_DISTANCE`] steps each), ending at 100 % = the exact maximum.
    /// Values are as [`Self::value_at_quantile_us`]. Empty when the histogram is.
    pub fn percentile_spectrum(&self) -> Vec<(f64, f64)> {
        if self.is_empty() {
            return vec![];
        }
        self.hist
            .iter_quantiles(SPECTRUM_TICKS_PER_HALF_DISTANCE)
            .map(|v| (v.quantile_iterated_to() * 100.0, us(v.value_iterated_to().min(self.max_ns))))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` latency-like samples, log-uniform over 100 ns .. ~100 ms (ns), from a seeded SplitMix64.
    fn samples(seed: u64, n: usize) -> Vec<u64> {
        let mut rng = tdoa::rng::SplitMix64::new(seed);
        (0..n)
            .map(|_| {
                let u = (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
                (100.0 * 10f64.powf(6.0 * u)) as u64
            })
            .collect()
    }

    fn histogram(values: &[u64]) -> LatencyHistogram {
        let mut h = LatencyHistogram::new();
        for &v in values {
            h.record(v);
        }
        h
    }

    /// The nearest-rank quantile of sorted values, as hdrhistogram counts ranks.
    fn exact_quantile(sorted: &[u64], q: f64) -> u64 {
        let rank = ((q * sorted.len() as f64).ceil() as usize).max(1);
        sorted[rank - 1]
    }

    #[test]
    fn quantiles_match_sorted_values_within_resolution() {
        for (seed, n) in [(1, 1), (2, 7), (3, 1000), (4, 100_003)] {
            let mut values = samples(seed, n);
            let h = histogram(&values);
            values.sort_unstable();
            assert_eq!(h.len(), n as u64);
            for q in [0.0, 0.1, 0.5, 0.9, 0.99, 0.999, 0.9999, 1.0] {
                let exact = exact_quantile(&values, q) as f64 / 1000.0;
                let got = h.value_at_quantile_us(q).unwrap();
                assert!(got >= exact * (1.0 - 1e-3) - 1e-3 && got <= exact * (1.0 + 1e-3) + 1e-3, "{q}: {got} {exact}");
            }
            let p = h.percentiles().unwrap();
            let max = *values.last().unwrap();
            assert_eq!(p.max_us, max as f64 / 1000.0);
            assert_eq!(h.max_ns(), Some(max));
            assert_eq!(p.n, n as u64);
            assert!(p.p50_us <= p.p90_us && p.p90_us <= p.p99_us && p.p99_us <= p.p999_us && p.p999_us <= p.max_us);
            for (q, v) in [(0.5, p.p50_us), (0.9, p.p90_us), (0.99, p.p99_us), (0.999, p.p999_us)] {
                let exact = exact_quantile(&values, q) as f64 / 1000.0;
                assert!((v - exact).abs() <= exact * 1e-3 + 1e-3, "{q}: {v} {exact}");
            }
        }
    }

    #[test]
    fn max_is_exact() {
        let h = histogram(&[5, 123_456_789, 1000]);
        assert_eq!(h.percentiles().unwrap().max_us, 123_456.789);
        assert_eq!(h.value_at_quantile_us(1.0), Some(123_456.789));
        assert_eq!(h.percentile_spectrum().last().copied(), Some((100.0, 123_456.789)));
        let zero = histogram(&[0, 0]);
        assert_eq!(
            zero.percentiles().unwrap(),
            Percentiles { p50_us: 0.0, p90_us: 0.0, p99_us: 0.0, p999_us: 0.0, max_us: 0.0, n: 2 }
        );
    }

    #[test]
    fn merge_equals_recording_everything_in_one() {
        let (a, b) = (samples(10, 5000), samples(11, 3000));
        let mut merged = histogram(&a);
        merged.record(MAX_NS + 1);
        let mut second = histogram(&b);
        second.record(u64::MAX);
        merged.merge(&second);
        let mut all: Vec<u64> = a.iter().chain(&b).copied().collect();
        all.push(MAX_NS + 1);
        all.push(u64::MAX);
        let one = histogram(&all);
        assert_eq!(merged.len(), 8002);
        assert_eq!(merged.saturated(), 2);
        assert_eq!(merged.percentiles(), one.percentiles());
        assert_eq!(merged.buckets(), one.buckets());
        assert_eq!(merged.csv(), one.csv());
        assert_eq!(merged.percentile_spectrum(), one.percentile_spectrum());
        // Merging an empty histogram changes nothing; merging into an empty one copies.
        let before = merged.csv();
        merged.merge(&LatencyHistogram::new());
        assert_eq!(merged.csv(), before);
        let mut empty = LatencyHistogram::new();
        empty.merge(&one);
        assert_eq!(empty.percentiles(), one.percentiles());
    }

    #[test]
    fn csv_rows_sum_to_the_count_and_end_at_100() {
        let h = histogram(&samples(20, 10_000));
        let csv = h.csv();
        let mut lines = csv.lines();
        assert_eq!(lines.next(), Some("value_us,count,cumulative_count,percentile"));
        let rows: Vec<Vec<f64>> =
            lines.map(|l| l.split(',').map(|f| f.parse::<f64>().unwrap()).collect::<Vec<_>>()).collect();
        assert_eq!(rows.len(), h.buckets().len());
        assert!(rows.iter().all(|r| r.len() == 4 && r[1] >= 1.0));
        let sum: f64 = rows.iter().map(|r| r[1]).sum();
        assert_eq!(sum, 10_000.0);
        let last = rows.last().unwrap();
        assert_eq!((last[2], last[3]), (10_000.0, 100.0));
        // Values, cumulative counts and percentiles rise.
        assert!(rows.windows(2).all(|w| w[0][0] < w[1][0] && w[0][2] < w[1][2] && w[0][3] <= w[1][3]));
        let buckets: u64 = h.buckets().iter().map(|b| b.1).sum();
        assert_eq!(buckets, h.len());
    }

    #[test]
    fn empty_histogram_has_no_percentiles() {
        let h = LatencyHistogram::new();
        assert!(h.is_empty());
        assert_eq!(h.len(), 0);
        assert_eq!(h.percentiles(), None);
        assert_eq!(h.value_at_quantile_us(0.5), None);
        assert_eq!(h.max_ns(), None);
        assert_eq!(h.mean_us(), None);
        assert!(h.buckets().is_empty());
        assert!(h.percentile_spectrum().is_empty());
        assert_eq!(h.csv(), "value_us,count,cumulative_count,percentile\n");
        assert_eq!(histogram(&[10]).value_at_quantile_us(f64::NAN), None);
    }

    #[test]
    fn samples_above_60_s_saturate() {
        let mut h = histogram(&[1000, 2000]);
        h.record(MAX_NS);
        assert_eq!(h.saturated(), 0);
        h.record(MAX_NS + 1);
        h.record(u64::MAX);
        assert_eq!(h.saturated(), 2);
        assert_eq!(h.len(), 5);
        let p = h.percentiles().unwrap();
        assert_eq!(p.max_us, MAX_NS as f64 / 1000.0);
        assert_eq!(h.value_at_quantile_us(0.99), Some(60_000_000.0));
    }

    #[test]
    fn spectrum_rises_to_100_percent() {
        let h = histogram(&samples(30, 50_000));
        let s = h.percentile_spectrum();
        assert!(s.len() > 50, "{}", s.len());
        assert_eq!(s[0].0, 0.0);
        assert_eq!(s.last().unwrap().0, 100.0);
        assert!(s.windows(2).all(|w| w[0].0 <= w[1].0 && w[0].1 <= w[1].1));
        assert!(s.iter().any(|p| (99.9..100.0).contains(&p.0)));
        let one = histogram(&[42]).percentile_spectrum();
        assert_eq!(one.last().copied(), Some((100.0, 0.042)));
    }

    #[test]
    fn percentiles_serialise_with_the_documented_keys() {
        let p = Percentiles { p50_us: 1.5, p90_us: 2.0, p99_us: 3.0, p999_us: 4.0, max_us: 5.0, n: 7 };
        let json = serde_json::to_value(p).unwrap();
        let keys: Vec<&str> = json.as_object().unwrap().keys().map(String::as_str).collect();
        let mut expected = vec!["p50_us", "p90_us", "p99_us", "p999_us", "max_us", "n"];
        let mut keys = keys;
        keys.sort_unstable();
        expected.sort_unstable();
        assert_eq!(keys, expected);
        assert_eq!(serde_json::from_value::<Percentiles>(json).unwrap(), p);
    }
}
