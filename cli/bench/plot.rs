//! The "latency by percentile" chart of `uavloc bench latency` (HdrHistogram's classic plot): the latency
//! of each series, µs on a log axis, over the percentile on a log scale of 1/(1 − q), so that the tail
//! (99 %, 99.9 %, 99.99 %) gets as much room as the body.
//!
//! Drawn with [`record::plot_curves`] (format from the extension, `.svg` or `.png`, embedded font). Its x
//! axis is linear, so the x coordinate is the number of "nines", log10(1/(1 − q)) ([`nines`]): 0 = 0 %,
//! 1 = 90 %, 2 = 99 %, 3 = 99.9 %, 4 = 99.99 %; the axis label spells that out.

use std::path::Path;

use record::Series;

use super::histogram::LatencyHistogram;

/// The x coordinate of quantile `q` (0 ..= 1) on the chart: log10(1/(1 − q)), "the number of nines"
/// (0.9 → 1, 0.99 → 2, 0.999 → 3), for a histogram of `n` samples. It is capped at log10(n) (n ≥ 2),
/// where its largest sample lies — quantile 1 (the maximum) would be infinitely far otherwise. NaN and
/// values outside 0 ..= 1 are clamped (NaN to 0).
pub fn nines(q: f64, n: u64) -> f64 {
    let q = if q.is_nan() { 0.0 } else { q.clamp(0.0, 1.0) };
    let floor = 1.0 / n.max(2) as f64;
    -(1.0 - q).max(floor).log10()
}

/// The percentile at `nines` ([`nines`]) as a tick label: 0 → "0%", 1 → "90%", 2 → "99%", 3 → "99.9%",
/// 4 → "99.99%", 2.5 → "99.7%" (as many decimals as the nines need). Empty for a negative or non-finite
/// value.
pub fn percentile_label(nines: f64) -> String {
    if !nines.is_finite() || nines < -1e-9 {
        return String::new();
    }
    let nines = nines.max(0.0);
    let percent = 100.0 * (1.0 - 10f64.powf(-nines));
    // As many decimals as the nines need, more if rounding would read 100 below 100 %.
    let mut decimals = (nines.ceil() as i64 - 2).clamp(0, 12) as usize;
    while decimals < 12 && percent < 100.0 && format!("{percent:.decimals$}").starts_with("100") {
        decimals += 1;
    }
    format!("{percent:.decimals$}%")
}

/// The x axis label: what the "nines" coordinate means.
const X_LABEL: &str = "percentile, as nines: 0 = 0%, 1 = 90%, 2 = 99%, 3 = 99.9%, 4 = 99.99%";
/// The y axis label (`record::plot_curves` adds ", log scale").
const Y_LABEL: &str = "latency (µs)";

/// Plots the latency by percentile of each histogram of `series` (legend label, histogram) into `path`
/// (`.svg` or `.png`): one line per non-empty histogram through its
/// [`LatencyHistogram::percentile_spectrum`], x the percentile as [`nines`] (see the module
/// documentation), y the latency in µs on a log axis (0 µs samples are not drawn there).
///
/// Empty histograms are skipped (no line, no legend entry). With nothing to draw the figure is still
/// written, its title marked "(no data)". Errors (as one sentence): an extension other than `.svg` /
/// `.png`, or a file that cannot be written.
pub fn plot_latency_distributions(
    path: &Path,
    title: &str,
    series: &[(String, &LatencyHistogram)],
) -> Result<(), String> {
    let curves: Vec<Series> = series
        .iter()
        .filter(|(_, h)| !h.is_empty())
        .map(|(label, h)| {
            let n = h.len();
            let (x, y) = h.percentile_spectrum().into_iter().map(|(p, us)| (nines(p / 100.0, n), us)).unzip();
            Series::new(label.clone(), x, y)
        })
        .collect();
    record::plot_curves(title, X_LABEL, Y_LABEL, &curves, true, path).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    /// A fresh directory under the system temp dir, unique to this process and test.
    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("uavloc-bench-plot-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn histogram(scale: u64, n: u64) -> LatencyHistogram {
        let mut h = LatencyHistogram::new();
        for i in 0..n {
            // A body around `scale` ns with a long tail.
            let tail = if i % 100 == 0 {
                50
            } else if i % 10 == 0 {
                5
            } else {
                1
            };
            h.record(scale * tail + (i * 7919) % scale);
        }
        h
    }

    #[test]
    fn nines_and_labels() {
        assert_eq!(nines(0.0, 1000), 0.0);
        assert!((nines(0.9, 1000) - 1.0).abs() < 1e-12);
        assert!((nines(0.999, 1000) - 3.0).abs() < 1e-9);
        assert!((nines(1.0, 1000) - 3.0).abs() < 1e-12);
        assert!((nines(0.99999, 1000) - 3.0).abs() < 1e-12);
        assert!((nines(1.0, 1) - 2f64.log10()).abs() < 1e-12);
        assert_eq!(nines(f64::NAN, 10), 0.0);
        assert_eq!(nines(-1.0, 10), 0.0);
        let labels: Vec<String> = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0].map(percentile_label).to_vec();
        assert_eq!(labels, ["0%", "90%", "99%", "99.9%", "99.99%", "99.999%"]);
        assert_eq!(percentile_label(2.5), "99.7%");
        assert_eq!(percentile_label(0.5), "68%");
        assert_eq!(percentile_label(-0.1), "");
        assert_eq!(percentile_label(f64::INFINITY), "");
        assert!(!percentile_label(1.999_999_9).starts_with("100"));
        assert!(!percentile_label(13.0).starts_with("100"), "{}", percentile_label(13.0));
    }

    #[test]
    fn writes_svg_and_png() {
        let dir = scratch("figures");
        let (ipc, uds, empty) = (histogram(20_000, 20_000), histogram(35_000, 5_000), LatencyHistogram::new());
        let series = vec![
            ("iceoryx2 block".to_owned(), &ipc),
            ("uds block".to_owned(), &uds),
            ("nothing here".to_owned(), &empty),
        ];
        let svg_path = dir.join("latency.svg");
        plot_latency_distributions(&svg_path, "Hop latency", &series).unwrap();
        let svg = std::fs::read_to_string(&svg_path).unwrap();
        assert!(svg.contains("<svg"));
        for text in ["Hop latency", "iceoryx2 block", "uds block", "latency (µs)", "99.9%"] {
            assert!(svg.contains(text), "{text} missing");
        }
        assert!(!svg.contains("nothing here") && !svg.contains("(no data)"));
        let png_path = dir.join("latency.PNG");
        plot_latency_distributions(&png_path, "Hop latency", &series).unwrap();
        let png = record::png::read(&png_path).unwrap();
        assert!(png.width > 100 && png.height > 100);

        // Nothing to draw: still a figure, marked.
        for (name, series) in [("none", vec![]), ("empty", vec![("e".to_owned(), &empty)])] {
            let path = dir.join(format!("{name}.svg"));
            plot_latency_distributions(&path, "Idle", &series).unwrap();
            assert!(std::fs::read_to_string(&path).unwrap().contains("(no data)"));
            let path = dir.join(format!("{name}.png"));
            plot_latency_distributions(&path, "Idle", &series).unwrap();
            record::png::read(&path).unwrap();
        }

        // Odd data: one sample, zeros only (nothing on a log axis), saturated samples.
        let mut one = LatencyHistogram::new();
        one.record(1);
        let mut zeros = LatencyHistogram::new();
        zeros.record(0);
        zeros.record(0);
        let mut huge = LatencyHistogram::new();
        huge.record(u64::MAX);
        huge.record(0);
        let odd = vec![("one".to_owned(), &one), ("zeros".to_owned(), &zeros), ("huge".to_owned(), &huge)];
        for ext in ["svg", "png"] {
            plot_latency_distributions(&dir.join(format!("odd.{ext}")), "Odd", &odd).unwrap();
        }
        let only_zeros = dir.join("zeros.svg");
        plot_latency_distributions(&only_zeros, "Zeros", &[("zeros".to_owned(), &zeros)]).unwrap();
        assert!(std::fs::read_to_string(&only_zeros).unwrap().contains("(no data)"));

        let err = plot_latency_distributions(&dir.join("latency.pdf"), "t", &series).unwrap_err();
        assert!(err.contains("unsupported"), "{err}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
