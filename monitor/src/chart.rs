//! Generic figures for the research report (`uavloc paper`): curves with optional confidence bands
//! ([`plot_curves`]) and grouped bar charts with optional error whiskers ([`plot_bars`]).
//!
//! They share the machinery of [`crate::plot`]: the format follows the file extension (`.svg` or `.png`,
//! [`crate::plot::FIGURE_SIZE`] pixels), the text uses the embedded DejaVu Sans, one palette colour per
//! series, and the legend is drawn in a panel right of the chart. The charts know nothing about units:
//! values are in whatever unit the caller gives, and the caller's axis labels should name it.
//!
//! Robustness: drawing never panics. Non-finite values are skipped (so are magnitudes beyond 1e300, which
//! could overflow an axis span), and so are non-positive ones on a log axis. With nothing left to draw (no series, no groups, or no usable value) the figure is still
//! written — axes, legend, title marked "(no data)". Data of inconsistent lengths is
//! [`PlotError::InvalidData`] and writes nothing.

use std::ops::Range;
use std::path::Path;

use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, DefaultFormatting, KeyPointHint, ValueFormatter};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use crate::plot::{
    CHART_MARGIN, DESC_PX, DrawResult, Figure, Glyph, LABEL_PX, LEGEND_WIDTH, LegendEntry, MARKER_EDGE, PlotError,
    TITLE_PX, X_LABEL_AREA, Y_LABEL_AREA, draw_legend, fmt_axis, font, log_ticks, palette, render,
};

/// Opacity of a confidence band.
const BAND_ALPHA: f64 = 0.2;
/// A series with more drawable points than this is drawn as a line without point markers.
const MAX_MARKERS: usize = 60;
/// Share of a group's slot (1 unit of the x axis) taken by its bars.
const GROUP_WIDTH: f64 = 0.8;
/// Share of a bar's slot that is filled (the rest separates neighbouring bars).
const BAR_FILL: f64 = 0.85;
const GRID_LIGHT: RGBColor = RGBColor(0xf0, 0xf0, 0xf0);
const GRID_BOLD: RGBColor = RGBColor(0xd8, 0xd8, 0xd8);

/// One line of a curve chart ([`plot_curves`]): `y` over `x`, optionally with a shaded confidence band
/// `[lo, hi]` per point. Units are whatever the caller uses (name them in the axis labels).
///
/// `x`, `y` and, when present, both band vectors must have the same length; a non-finite coordinate
/// (or a non-positive value on a log axis) leaves a gap in the line or the band.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Abscissae, in the caller's unit (e.g. the planning step).
    pub x: Vec<f64>,
    /// Values at `x`, in the caller's unit.
    pub y: Vec<f64>,
    /// Lower and upper bounds of the band at each `x` (e.g. a 95 % confidence interval of the mean), in
    /// the unit of `y`; the order of the two bounds at a point does not matter.
    pub band: Option<(Vec<f64>, Vec<f64>)>,
}

impl Series {
    /// A series without a band.
    pub fn new(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Series { label: label.into(), x, y, band: None }
    }

    /// The series with the band `[lo, hi]` per point.
    pub fn with_band(mut self, lo: Vec<f64>, hi: Vec<f64>) -> Self {
        self.band = Some((lo, hi));
        self
    }
}

/// One group of a grouped bar chart ([`plot_bars`]), e.g. one parameter value or one scenario.
///
/// `values` holds one bar per series (`None` draws no bar); `errors` is either empty (no whiskers) or
/// holds one optional whisker `(lo, hi)` per series, drawn over the bar when both are present. Units are
/// the caller's (name them in the y label).
#[derive(Debug, Clone, PartialEq)]
pub struct BarGroup {
    /// The group's label under the x axis.
    pub label: String,
    /// One value per series, in the caller's unit.
    pub values: Vec<Option<f64>>,
    /// Empty, or one error interval `(lo, hi)` per series, in the unit of `values` (absolute bounds, not
    /// offsets from the value; their order does not matter).
    pub errors: Vec<Option<(f64, f64)>>,
}

/// Plots curves — e.g. the mean CRLB per planning step of each method with a 95 % confidence band —
/// into `path` (`.svg` or `.png`).
///
/// Each series is a 2 px line of its palette colour (with point markers unless it is dense); its band
/// is a translucent polygon of the same colour under the line. The x axis spans the finite `x` values
/// of all series; the y axis is logarithmic when `log_y` (non-positive values are then skipped), and is
/// padded so that the lines and bands fit. Values are in the caller's units; `x_label` and `y_label`
/// should name them.
///
/// Errors: [`PlotError::InvalidData`] when a series' `x`, `y` and band lengths differ, otherwise the
/// errors of writing a figure ([`PlotError::UnsupportedFormat`], [`PlotError::Draw`], ...).
pub fn plot_curves(
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    log_y: bool,
    path: &Path,
) -> Result<(), PlotError> {
    let invalid = |message: String| PlotError::InvalidData { path: path.to_path_buf(), message };
    for s in series {
        if s.x.len() != s.y.len() {
            return Err(invalid(format!("series {:?}: {} x values but {} y values", s.label, s.x.len(), s.y.len())));
        }
        if let Some((lo, hi)) = &s.band
            && (lo.len() != s.x.len() || hi.len() != s.x.len())
        {
            return Err(invalid(format!(
                "series {:?}: {} points but a band of {} lower and {} upper bounds",
                s.label,
                s.x.len(),
                lo.len(),
                hi.len()
            )));
        }
    }
    let curves = Curves { title: title.to_owned(), x_label, y_label, series, log_y };
    let figure = Curves { title: with_no_data_mark(title, curves.y_values().next().is_none()), ..curves };
    render(path, &figure)
}

/// Plots a grouped bar chart into `path` (`.svg` or `.png`): the `groups` along the x axis, in each one
/// bar per series of `series_labels` (one palette colour per series, the same in every group), with an
/// error whisker over the bars that have one.
///
/// The y axis is linear from 0 (lower if a value is negative) or, when `log_y`, logarithmic with the
/// bars rising from its bottom (non-positive values are then skipped). It is padded so that bars and
/// whiskers fit. Values are in the caller's units; `y_label` should name them.
///
/// Errors: [`PlotError::InvalidData`] when a group has not exactly one value per series, or errors that
/// are neither empty nor one per series; otherwise the errors of writing a figure.
pub fn plot_bars(
    title: &str,
    y_label: &str,
    series_labels: &[String],
    groups: &[BarGroup],
    log_y: bool,
    path: &Path,
) -> Result<(), PlotError> {
    let n = series_labels.len();
    for g in groups {
        let errors_ok = g.errors.is_empty() || g.errors.len() == n;
        if g.values.len() != n || !errors_ok {
            return Err(PlotError::InvalidData {
                path: path.to_path_buf(),
                message: format!(
                    "group {:?}: {} values and {} errors for {n} series (errors must be empty or one per series)",
                    g.label,
                    g.values.len(),
                    g.errors.len()
                ),
            });
        }
    }
    let bars = Bars { title: title.to_owned(), y_label, series_labels, groups, log_y };
    let figure = Bars { title: with_no_data_mark(title, bars.bars().next().is_none()), ..bars };
    render(path, &figure)
}

fn with_no_data_mark(title: &str, empty: bool) -> String {
    if empty { format!("{title} (no data)") } else { title.to_owned() }
}

/// Largest magnitude drawn: beyond it, the span of an axis could overflow (plotters needs it finite).
const MAX_ABS: f64 = 1e300;

/// Whether `v` can be placed on an axis: finite and at most [`MAX_ABS`] in magnitude.
fn plottable(v: f64) -> bool {
    v.is_finite() && v.abs() <= MAX_ABS
}

/// `v` if it can be drawn on the y axis: [`plottable`], and positive on a log axis.
fn usable(v: f64, log: bool) -> Option<f64> {
    (plottable(v) && (!log || v > 0.0)).then_some(v)
}

/// The smallest and largest of `values` (`None` when there are none).
fn extent(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    values.fold(None, |e, v| Some(e.map_or((v, v), |(lo, hi): (f64, f64)| (lo.min(v), hi.max(v)))))
}

/// `lo..hi` grown by `share` of its span on both sides (a degenerate range by 10 % of its magnitude, or
/// by 1 at 0), kept finite.
fn padded(lo: f64, hi: f64, share: f64) -> Range<f64> {
    let span = hi - lo;
    let pad = if span > 0.0 && span.is_finite() {
        share * span
    } else if span > 0.0 {
        0.0
    } else if lo != 0.0 {
        0.1 * lo.abs()
    } else {
        1.0
    };
    (lo - pad).max(f64::MIN)..(hi + pad).min(f64::MAX)
}

/// The bounds of a log axis on the positive `extent`, divided / multiplied by `below` / `above`; `1..10`
/// without data.
fn log_bounds(extent: Option<(f64, f64)>, below: f64, above: f64) -> (f64, f64) {
    match extent {
        Some((lo, hi)) => {
            let lo = (lo / below).max(f64::MIN_POSITIVE);
            let hi = (hi * above).min(f64::MAX);
            // Subnormal data could leave an empty range.
            if hi > lo { (lo, hi) } else { (lo, 10.0 * lo) }
        }
        None => (1.0, 10.0),
    }
}

// ---------------------------------------------------------------------------------------------------
// Curves
// ---------------------------------------------------------------------------------------------------

struct Curves<'a> {
    title: String,
    x_label: &'a str,
    y_label: &'a str,
    series: &'a [Series],
    log_y: bool,
}

impl Curves<'_> {
    /// The drawable `(x, y)` points of `s`, `None` where the point is not drawable.
    fn points(&self, s: &Series) -> Vec<Option<(f64, f64)>> {
        let log = self.log_y;
        s.x.iter().zip(&s.y).map(|(&x, &y)| plottable(x).then_some(()).and(usable(y, log)).map(|y| (x, y))).collect()
    }

    /// The drawable band of `s`: `(x, lower, upper)` per point, `None` where it is not drawable.
    fn band(&self, s: &Series) -> Vec<Option<(f64, f64, f64)>> {
        let log = self.log_y;
        let Some((lo, hi)) = &s.band else { return vec![] };
        s.x.iter()
            .zip(lo.iter().zip(hi))
            .map(|(&x, (&a, &b))| match (plottable(x), usable(a, log), usable(b, log)) {
                (true, Some(a), Some(b)) => Some((x, a.min(b), a.max(b))),
                _ => None,
            })
            .collect()
    }

    /// Every drawn y value (points and band bounds).
    fn y_values(&self) -> impl Iterator<Item = f64> + '_ {
        self.series.iter().flat_map(|s| {
            let points = self.points(s).into_iter().flatten().map(|p| p.1);
            let band = self.band(s).into_iter().flatten().flat_map(|(_, lo, hi)| [lo, hi]);
            points.chain(band)
        })
    }

    fn draw_chart<DB, Y>(&self, area: &DrawingArea<DB, Shift>, x: Range<f64>, y: Y) -> DrawResult<DB>
    where
        DB: DrawingBackend,
        Y: AsRangedCoord<Value = f64>,
        Y::CoordDescType: ValueFormatter<f64>,
    {
        let mut chart = ChartBuilder::on(area)
            .margin(CHART_MARGIN)
            .x_label_area_size(X_LABEL_AREA)
            .y_label_area_size(Y_LABEL_AREA)
            .build_cartesian_2d(x, y)?;
        chart
            .configure_mesh()
            .x_desc(self.x_label)
            .y_desc(if self.log_y { format!("{}, log scale", self.y_label) } else { self.y_label.to_owned() })
            .label_style(font(LABEL_PX))
            .axis_desc_style(font(DESC_PX))
            .x_label_formatter(&|v| fmt_axis(*v))
            .y_label_formatter(&|v| fmt_axis(*v))
            .max_light_lines(4)
            .light_line_style(GRID_LIGHT)
            .bold_line_style(GRID_BOLD)
            .draw()?;
        // Bands first, so that every line is drawn over them.
        for (i, s) in self.series.iter().enumerate() {
            let color = palette(i);
            for run in runs(&self.band(s)) {
                if let [(x, lo, hi)] = run[..] {
                    chart.draw_series(std::iter::once(PathElement::new(
                        vec![(x, lo), (x, hi)],
                        color.stroke_width(2),
                    )))?;
                } else {
                    let upper = run.iter().map(|&(x, _, hi)| (x, hi));
                    let lower = run.iter().rev().map(|&(x, lo, _)| (x, lo));
                    let outline: Vec<(f64, f64)> = upper.chain(lower).collect();
                    chart.draw_series(std::iter::once(Polygon::new(outline, color.mix(BAND_ALPHA).filled())))?;
                }
            }
        }
        for (i, s) in self.series.iter().enumerate() {
            let color = palette(i);
            let points = self.points(s);
            let markers = points.iter().flatten().count() <= MAX_MARKERS;
            for run in runs(&points) {
                if run.len() >= 2 {
                    chart.draw_series(LineSeries::new(run.iter().copied(), color.stroke_width(2)))?;
                }
                if markers || run.len() == 1 {
                    chart.draw_series(run.iter().map(|&p| Circle::new(p, 3, color.filled())))?;
                }
            }
        }
        Ok(())
    }
}

/// The runs of consecutive `Some` items of `items`.
fn runs<T: Copy>(items: &[Option<T>]) -> Vec<Vec<T>> {
    items
        .split(Option::is_none)
        .filter(|run| !run.is_empty())
        .map(|run| run.iter().flatten().copied().collect())
        .collect()
}

impl Figure for Curves<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
        root.fill(&WHITE)?;
        let body = root.titled(&self.title, font(TITLE_PX))?;
        let (w, _) = body.dim_in_pixel();
        let (chart_area, legend_area) = body.split_horizontally(w.saturating_sub(LEGEND_WIDTH));

        let x = match extent(self.series.iter().flat_map(|s| s.x.iter().copied().filter(|x| plottable(*x)))) {
            Some((lo, hi)) => padded(lo, hi, 0.02),
            None => 0.0..1.0,
        };
        let y = extent(self.y_values());
        if self.log_y {
            let (lo, hi) = log_bounds(y, 1.3, 1.3);
            let (bold, light) = log_ticks(lo, hi);
            self.draw_chart(&chart_area, x, (lo..hi).log_scale().with_key_points(bold).with_light_points(light))?;
        } else {
            let y = match y {
                // Non-negative data keeps a non-negative axis.
                Some((lo, hi)) => {
                    let r = padded(lo, hi, 0.05);
                    if lo >= 0.0 { r.start.max(0.0)..r.end } else { r }
                }
                None => 0.0..1.0,
            };
            self.draw_chart(&chart_area, x, y)?;
        }
        let entries: Vec<LegendEntry> = self
            .series
            .iter()
            .enumerate()
            .map(|(i, s)| LegendEntry { glyph: Glyph::LineDot(palette(i)), label: s.label.clone() })
            .collect();
        draw_legend(&legend_area, &entries)
    }
}

// ---------------------------------------------------------------------------------------------------
// Grouped bars
// ---------------------------------------------------------------------------------------------------

struct Bars<'a> {
    title: String,
    y_label: &'a str,
    series_labels: &'a [String],
    groups: &'a [BarGroup],
    log_y: bool,
}

/// The x axis of a bar chart of `.0` groups: group `g` is centred on `g`, its ticks are the groups.
struct GroupAxis(usize);

impl Ranged for GroupAxis {
    // The tick labels come from the chart's label formatter (the groups' labels).
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        RangedCoordf64::from(self.range()).map(value, limit)
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        if hint.weight().allow_light_points() { vec![] } else { (0..self.0).map(|g| g as f64).collect() }
    }

    fn range(&self) -> Range<f64> {
        -0.5..self.0.max(1) as f64 - 0.5
    }
}

/// One drawable bar.
struct Bar {
    group: usize,
    series: usize,
    value: f64,
    /// The whisker's bounds, ordered; on a log axis a non-positive lower bound is `None` (the whisker
    /// then reaches the bottom of the axis).
    whisker: Option<(Option<f64>, f64)>,
}

impl Bars<'_> {
    /// The drawable bars, group by group.
    fn bars(&self) -> impl Iterator<Item = Bar> + '_ {
        let log = self.log_y;
        self.groups.iter().enumerate().flat_map(move |(group, g)| {
            g.values.iter().enumerate().filter_map(move |(series, v)| {
                let value = usable((*v)?, log)?;
                let whisker = g.errors.get(series).copied().flatten().and_then(|(a, b)| {
                    let (lo, hi) = (a.min(b), a.max(b));
                    (plottable(a) && plottable(b)).then_some(())?;
                    Some((usable(lo, log), usable(hi, log)?))
                });
                Some(Bar { group, series, value, whisker })
            })
        })
    }

    /// The x extent `[left, right]` of `bar` (group `g` is centred on `g`).
    fn x_extent(&self, bar: &Bar) -> (f64, f64) {
        let slot = GROUP_WIDTH / self.series_labels.len().max(1) as f64;
        let left = bar.group as f64 - 0.5 * GROUP_WIDTH + bar.series as f64 * slot + 0.5 * (1.0 - BAR_FILL) * slot;
        (left, left + BAR_FILL * slot)
    }

    fn draw_chart<DB, Y>(&self, area: &DrawingArea<DB, Shift>, y: Y, base: f64) -> DrawResult<DB>
    where
        DB: DrawingBackend,
        Y: AsRangedCoord<Value = f64>,
        Y::CoordDescType: ValueFormatter<f64>,
    {
        let n = self.groups.len();
        let x = GroupAxis(n);
        let mut chart = ChartBuilder::on(area)
            .margin(CHART_MARGIN)
            .x_label_area_size(X_LABEL_AREA)
            .y_label_area_size(Y_LABEL_AREA)
            .build_cartesian_2d(x, y)?;
        let group_label = |v: &f64| {
            let g = v.round();
            if g >= 0.0 && (g as usize) < n { self.groups[g as usize].label.clone() } else { String::new() }
        };
        chart
            .configure_mesh()
            .disable_x_mesh()
            .y_desc(if self.log_y { format!("{}, log scale", self.y_label) } else { self.y_label.to_owned() })
            .label_style(font(LABEL_PX))
            .axis_desc_style(font(DESC_PX))
            .x_label_formatter(&group_label)
            .y_label_formatter(&|v| fmt_axis(*v))
            .max_light_lines(4)
            .light_line_style(GRID_LIGHT)
            .bold_line_style(GRID_BOLD)
            .draw()?;
        for bar in self.bars() {
            let (left, right) = self.x_extent(&bar);
            chart.draw_series(std::iter::once(Rectangle::new(
                [(left, base), (right, bar.value)],
                palette(bar.series).filled(),
            )))?;
        }
        for bar in self.bars() {
            let Some((lo, hi)) = bar.whisker else { continue };
            let lo = lo.unwrap_or(base);
            let (left, right) = self.x_extent(&bar);
            let (mid, cap) = (0.5 * (left + right), 0.25 * (right - left));
            let whisker =
                vec![(mid - cap, hi), (mid + cap, hi), (mid, hi), (mid, lo), (mid - cap, lo), (mid + cap, lo)];
            chart.draw_series(std::iter::once(PathElement::new(whisker, MARKER_EDGE.stroke_width(1))))?;
        }
        Ok(())
    }
}

impl Figure for Bars<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
        root.fill(&WHITE)?;
        let body = root.titled(&self.title, font(TITLE_PX))?;
        let (w, _) = body.dim_in_pixel();
        let (chart_area, legend_area) = body.split_horizontally(w.saturating_sub(LEGEND_WIDTH));

        let values = extent(self.bars().flat_map(|b| {
            let (lo, hi) = b.whisker.map_or((None, None), |(lo, hi)| (lo, Some(hi)));
            [Some(b.value), lo, hi].into_iter().flatten()
        }));
        if self.log_y {
            let (lo, hi) = log_bounds(values, 2.0, 1.3);
            let (bold, light) = log_ticks(lo, hi);
            self.draw_chart(&chart_area, (lo..hi).log_scale().with_key_points(bold).with_light_points(light), lo)?;
        } else {
            // From 0 (or below, for negative values), padded above (and below) the data.
            let (lo, hi) = values.map_or((0.0, 1.0), |(lo, hi)| (lo.min(0.0), hi.max(0.0)));
            let r = padded(lo, hi, 0.05);
            let y = if lo >= 0.0 {
                0.0..r.end
            } else if hi <= 0.0 {
                r.start..0.0
            } else {
                r
            };
            self.draw_chart(&chart_area, y, 0.0)?;
        }
        let entries: Vec<LegendEntry> = self
            .series_labels
            .iter()
            .enumerate()
            .map(|(i, label)| LegendEntry { glyph: Glyph::Line(palette(i)), label: label.clone() })
            .collect();
        draw_legend(&legend_area, &entries)
    }
}

#[cfg(test)]
mod tests {
    use std::fs;
    use std::path::PathBuf;

    use super::*;
    use crate::plot::FIGURE_SIZE;

    /// A fresh, empty directory for one test.
    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("uavloc-monitor-chart-{}-{name}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn read(path: &Path) -> String {
        fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
    }

    /// Decodes a PNG, checks its size and that it is not a single colour.
    fn check_png(path: &Path) {
        let img = crate::png::read(path).unwrap();
        assert_eq!(img.dimensions(), FIGURE_SIZE);
        let first = img.pixel(0, 0);
        assert!(img.pixels().any(|(_, _, p)| p != first), "{} is a single colour", path.display());
    }

    fn steps(n: usize) -> Vec<f64> {
        (0..n).map(|k| k as f64).collect()
    }

    /// Two methods, 20 steps, CRLB falling from 2 km, the first with a CI95 band.
    fn crlb_series() -> Vec<Series> {
        let x = steps(20);
        let a: Vec<f64> = x.iter().map(|k| 2000.0 * 0.8f64.powf(*k) + 20.0).collect();
        let b: Vec<f64> = a.iter().map(|v| 1.4 * v).collect();
        let lo = a.iter().map(|v| 0.8 * v).collect();
        let hi = a.iter().map(|v| 1.25 * v).collect();
        vec![Series::new("A-optimal", x.clone(), a).with_band(lo, hi), Series::new("D-optimal", x, b)]
    }

    fn count(svg: &str, needle: &str) -> usize {
        svg.matches(needle).count()
    }

    /// The number of `<polyline>` elements with `attribute` (the axes and ticks are 1 px black polylines).
    fn polylines(svg: &str, attribute: &str) -> usize {
        svg.split("<polyline").skip(1).filter(|el| el.split('>').next().unwrap_or("").contains(attribute)).count()
    }

    #[test]
    fn curves_svg_has_title_labels_and_a_translucent_band() {
        let dir = scratch("curves-svg");
        for log_y in [false, true] {
            let path = dir.join(format!("curves-{log_y}.svg"));
            plot_curves("Mean CRLB per step", "step", "CRLB (m)", &crlb_series(), log_y, &path).unwrap();
            let svg = read(&path);
            for text in ["Mean CRLB per step", "A-optimal", "D-optimal", "step", "CRLB (m)"] {
                assert!(svg.contains(text), "{text} missing");
            }
            assert!(!svg.contains("(no data)"));
            // The band is one filled, translucent polygon; the lines are 2 px polylines.
            let bands: Vec<&str> = svg.lines().filter(|l| l.contains("<polygon")).collect();
            assert_eq!(bands.len(), 1, "{bands:?}");
            assert!(bands[0].contains(r#"opacity="0.2""#) && bands[0].contains(r##"fill="#1F77B4""##), "{}", bands[0]);
            assert_eq!(polylines(&svg, r#"stroke-width="2""#), 2);
        }
        // Without a band, no polygon.
        let path = dir.join("no-band.svg");
        let plain: Vec<Series> = crlb_series().into_iter().map(|s| Series { band: None, ..s }).collect();
        plot_curves("t", "x", "y", &plain, false, &path).unwrap();
        assert_eq!(count(&read(&path), "<polygon"), 0);
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn curves_and_bars_png_decode_to_the_figure_size() {
        let dir = scratch("png");
        let path = dir.join("curves.png");
        plot_curves("Mean CRLB per step", "step", "CRLB (m)", &crlb_series(), true, &path).unwrap();
        check_png(&path);
        let path = dir.join("bars.PNG");
        plot_bars("Final CRLB", "CRLB (m)", &labels(2), &bar_groups(), false, &path).unwrap();
        check_png(&path);
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn bad_values_and_empty_inputs_still_write_figures() {
        let dir = scratch("robust");
        let nan = f64::NAN;
        let messy = vec![
            Series::new("gappy", vec![0.0, 1.0, nan, 3.0, 4.0, f64::INFINITY], vec![5.0, nan, 2.0, 0.0, -1.0, 3.0])
                .with_band(vec![4.0, 1.0, 1.0, nan, -2.0, 1.0], vec![6.0, 2.0, 3.0, 1.0, 0.0, f64::NEG_INFINITY]),
            Series::new("single", vec![2.0], vec![1.0]).with_band(vec![0.5], vec![2.0]),
            Series::new("all NaN", vec![nan, nan], vec![nan, nan]),
            Series::new("empty", vec![], vec![]),
            Series::new("huge", vec![-1e308, 1e308], vec![1e308, f64::MIN_POSITIVE]),
            Series::new("wide", vec![-1e300, 1e300], vec![1e300, 1e-300]),
            Series::new("close", vec![1e15, 1e15 + 1.0], vec![1e10, 1e10 + 1e-5]),
        ];
        let all_nan = vec![Series::new("nan", vec![nan, 1.0], vec![nan, nan]).with_band(vec![nan; 2], vec![nan; 2])];
        let zeros = vec![Series::new("zeros", steps(3), vec![0.0; 3]).with_band(vec![0.0; 3], vec![1.0; 3])];
        let cases: [(&str, &[Series], bool); 3] =
            [("messy", &messy, false), ("all-nan", &all_nan, true), ("zeros", &zeros, true)];
        for (name, series, no_data) in cases {
            for log_y in [false, true] {
                for ext in ["svg", "png"] {
                    let path = dir.join(format!("{name}-{log_y}.{ext}"));
                    plot_curves("Messy", "x", "y", series, log_y, &path).unwrap();
                    if ext == "svg" {
                        let svg = read(&path);
                        assert_eq!(
                            svg.contains("Messy (no data)"),
                            no_data && (log_y || name == "all-nan"),
                            "{name} {log_y}"
                        );
                    } else {
                        check_png(&path);
                    }
                }
            }
        }
        for log_y in [false, true] {
            let path = dir.join(format!("empty-curves-{log_y}.svg"));
            plot_curves("Nothing", "x", "y", &[], log_y, &path).unwrap();
            assert!(read(&path).contains("Nothing (no data)"));
            let path = dir.join(format!("empty-bars-{log_y}.svg"));
            plot_bars("No bars", "y", &[], &[], log_y, &path).unwrap();
            assert!(read(&path).contains("No bars (no data)"));
            let path = dir.join(format!("empty-bars-{log_y}.png"));
            plot_bars("No bars", "y", &labels(3), &[], log_y, &path).unwrap();
            check_png(&path);
            let groups = vec![BarGroup {
                label: "g".to_owned(),
                values: vec![Some(nan), None, Some(0.0), Some(-3.0), Some(1e308)],
                errors: vec![
                    Some((nan, 1.0)),
                    Some((1.0, 2.0)),
                    Some((-1.0, 1.0)),
                    Some((-4.0, -2.0)),
                    Some((0.0, f64::MAX)),
                ],
            }];
            let path = dir.join(format!("messy-bars-{log_y}.svg"));
            plot_bars("Messy bars", "y", &labels(5), &groups, log_y, &path).unwrap();
        }
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn mismatched_lengths_are_invalid_data() {
        let dir = scratch("invalid");
        let path = dir.join("c.svg");
        let short_y = [Series::new("s", steps(3), vec![1.0, 2.0])];
        let short_band = [Series::new("s", steps(2), vec![1.0, 2.0]).with_band(vec![0.5], vec![1.5, 2.5])];
        for series in [&short_y[..], &short_band[..]] {
            let err = plot_curves("t", "x", "y", series, false, &path).unwrap_err();
            assert!(matches!(err, PlotError::InvalidData { .. }), "{err:?}");
        }
        let mut groups = bar_groups();
        groups[1].values.pop();
        let err = plot_bars("t", "y", &labels(2), &groups, false, &path).unwrap_err();
        assert!(matches!(err, PlotError::InvalidData { .. }), "{err:?}");
        let mut groups = bar_groups();
        groups[0].errors.push(None);
        assert!(matches!(plot_bars("t", "y", &labels(2), &groups, false, &path), Err(PlotError::InvalidData { .. })));
        assert!(!path.exists());
        let bad_ext = dir.join("c.pdf");
        assert!(matches!(
            plot_curves("t", "x", "y", &crlb_series(), false, &bad_ext),
            Err(PlotError::UnsupportedFormat { .. })
        ));
        let _ = fs::remove_dir_all(&dir);
    }

    fn labels(n: usize) -> Vec<String> {
        (0..n).map(|i| format!("method {i}")).collect()
    }

    /// Three groups of two series; 5 finite values, one whisker missing.
    fn bar_groups() -> Vec<BarGroup> {
        vec![
            BarGroup {
                label: "s = 0.25".to_owned(),
                values: vec![Some(120.0), Some(150.0)],
                errors: vec![Some((100.0, 140.0)), Some((130.0, 170.0))],
            },
            BarGroup { label: "s = 0.5".to_owned(), values: vec![Some(80.0), None], errors: vec![] },
            BarGroup {
                label: "s = 1".to_owned(),
                values: vec![Some(60.0), Some(90.0)],
                errors: vec![None, Some((70.0, 110.0))],
            },
        ]
    }

    #[test]
    fn bar_chart_draws_one_rectangle_per_finite_value() {
        let dir = scratch("bars");
        let labels = labels(2);
        let groups = bar_groups();
        let none: Vec<BarGroup> =
            groups.iter().map(|g| BarGroup { values: vec![None; 2], errors: vec![], ..g.clone() }).collect();
        for log_y in [false, true] {
            let path = dir.join(format!("bars-{log_y}.svg"));
            plot_bars("Final CRLB", "CRLB (m)", &labels, &groups, log_y, &path).unwrap();
            let svg = read(&path);
            for text in ["Final CRLB", "CRLB (m)", "method 0", "method 1", "s = 0.25", "s = 0.5", "s = 1"] {
                assert!(svg.contains(text), "{text} missing");
            }
            let empty_path = dir.join(format!("none-{log_y}.svg"));
            plot_bars("Final CRLB", "CRLB (m)", &labels, &none, log_y, &empty_path).unwrap();
            let empty = read(&empty_path);
            assert!(empty.contains("Final CRLB (no data)"));
            assert_eq!(count(&svg, "<rect") - count(&empty, "<rect"), 5);
            // Series colours are consistent across groups: 3 bars of the first colour, 2 of the second.
            assert_eq!(count(&svg, r##"fill="#1F77B4""##) - count(&empty, r##"fill="#1F77B4""##), 3);
            assert_eq!(count(&svg, r##"fill="#FF7F0E""##) - count(&empty, r##"fill="#FF7F0E""##), 2);
            // Three whiskers.
            assert_eq!(polylines(&svg, r##"stroke="#202020""##), 3);
        }
        // Zero and negative values: bars in linear mode, skipped in log mode.
        let signed = vec![BarGroup { label: "g".to_owned(), values: vec![Some(0.0), Some(-2.0)], errors: vec![] }];
        let empty = vec![BarGroup { label: "g".to_owned(), values: vec![None, None], errors: vec![] }];
        for (log_y, bars) in [(false, 2), (true, 0)] {
            let path = dir.join(format!("signed-{log_y}.svg"));
            plot_bars("Signed", "y", &labels, &signed, log_y, &path).unwrap();
            let empty_path = dir.join(format!("signed-none-{log_y}.svg"));
            plot_bars("Signed", "y", &labels, &empty, log_y, &empty_path).unwrap();
            assert_eq!(count(&read(&path), "<rect") - count(&read(&empty_path), "<rect"), bars);
        }
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn padding_and_extent() {
        assert_eq!(extent([3.0, -1.0, 2.0].into_iter()), Some((-1.0, 3.0)));
        assert_eq!(extent(std::iter::empty()), None);
        assert_eq!(padded(0.0, 10.0, 0.05), -0.5..10.5);
        assert_eq!(padded(0.0, 0.0, 0.05), -1.0..1.0);
        let huge = padded(-f64::MAX, f64::MAX, 0.05);
        assert!(huge.start.is_finite() && huge.end.is_finite());
        assert_eq!(runs(&[None, Some(1), Some(2), None, None, Some(3)]), vec![vec![1, 2], vec![3]]);
    }
}
