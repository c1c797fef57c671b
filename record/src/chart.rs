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
    use super::*;

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
