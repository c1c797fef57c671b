//! Plots of a run: the UAV trajectories (the paper's Figure 4), the per-step metrics (CRLB at the truth
//! and RMSE, the paper's Figure 5) and a comparison of several runs on one metric.
//!
//! The format follows the file extension: `.svg` or `.png` (case-insensitive), anything else is
//! [`PlotError::UnsupportedFormat`]. Both are [`FIGURE_SIZE`] pixels. Rendering is pure Rust: the text
//! is laid out (SVG) and rasterised (PNG) with DejaVu Sans, embedded in the library and registered
//! with plotters on first use, so no system font or font library is needed.
//!
//! Robustness: non-finite coordinates and values are skipped (never a panic). A record with zero
//! steps — or with no finite value to show — still gives a valid, empty figure (axes, title marked
//! "(no steps)", legend) rather than an error, so [`crate::export::write_run`] works on any record.
//! The legend is drawn in a panel right of the chart, so it never covers data. Data lines are drawn
//! 2 px wide (SVG `<polyline stroke-width="2">`), axes and ticks 1 px; legend samples and markers are
//! rectangles, circles and polygons.

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::register_font;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use thiserror::Error;

use crate::canvas::Canvas;
use crate::record::{RunRecord, StepRecord};

/// Width and height of every figure, pixels (PNG) or SVG user units.
pub const FIGURE_SIZE: (u32, u32) = (900, 700);

/// DejaVu Sans 2.37 (Bitstream Vera / Arev licence, see `assets/LICENSE-DejaVu.txt`).
static DEJAVU_SANS: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

/// The font family every text of the figures uses; the embedded font is registered under it.
const FAMILY: &str = "sans-serif";

pub(crate) const TITLE_PX: f64 = 22.0;
pub(crate) const LABEL_PX: f64 = 15.0;
pub(crate) const DESC_PX: f64 = 17.0;
const LEGEND_PX: f64 = 15.0;

/// Width of the legend panel right of the chart, pixels.
pub(crate) const LEGEND_WIDTH: u32 = 200;
/// Margin around the chart inside its area, pixels.
pub(crate) const CHART_MARGIN: u32 = 12;
/// Height of the x-axis label area (tick labels + "x (m)"), pixels.
pub(crate) const X_LABEL_AREA: u32 = 55;
/// Width of the y-axis label area (tick labels + rotated "y (m)"), pixels.
pub(crate) const Y_LABEL_AREA: u32 = 85;

/// UAV / series colours: the Tableau 10 palette without its red (the emitter) and grey (estimates).
const PALETTE: [RGBColor; 8] = [
    RGBColor(0x1f, 0x77, 0xb4),
    RGBColor(0xff, 0x7f, 0x0e),
    RGBColor(0x2c, 0xa0, 0x2c),
    RGBColor(0x94, 0x67, 0xbd),
    RGBColor(0x8c, 0x56, 0x4b),
    RGBColor(0xe3, 0x77, 0xc2),
    RGBColor(0x17, 0xbe, 0xcf),
    RGBColor(0xbc, 0xbd, 0x22),
];
pub(crate) const EMITTER_RED: RGBColor = RGBColor(0xd6, 0x27, 0x28);
const ESTIMATE_GREY: RGBColor = RGBColor(0x80, 0x80, 0x80);
pub(crate) const MARKER_EDGE: RGBColor = RGBColor(0x20, 0x20, 0x20);

/// The colour of UAV / series `i` (the palette cycles).
pub(crate) fn palette(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

/// Why a plot could not be written.
#[derive(Debug, Error)]
pub enum PlotError {
    /// The path's extension is neither `.svg` nor `.png`.
    #[error("{}: unsupported plot format (the extension must be .svg or .png)", path.display())]
    UnsupportedFormat { path: PathBuf },
    /// The embedded font could not be registered (a corrupted build).
    #[error("cannot register the embedded DejaVu Sans font with plotters")]
    Font,
    /// Drawing or writing the file failed.
    #[error("cannot draw {}: {message}", path.display())]
    Draw { path: PathBuf, message: String },
    /// The data given to a chart is inconsistent (e.g. lengths that do not match); nothing was written.
    #[error("{}: invalid chart data: {message}", path.display())]
    InvalidData { path: PathBuf, message: String },
}

/// Output format of a figure, from the file extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlotFormat {
    Svg,
    Png,
}

impl PlotFormat {
    /// `.svg` / `.png` (case-insensitive); `None` for anything else.
    pub fn from_path(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?;
        if ext.eq_ignore_ascii_case("svg") {
            Some(Self::Svg)
        } else if ext.eq_ignore_ascii_case("png") {
            Some(Self::Png)
        } else {
            None
        }
    }
}

/// The per-step metric a comparison plot shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Metric {
    /// Single-point CRLB at the true emitter, `StepRecord::crlb_true_m`.
    CrlbTrue,
    /// RMSE of Chan over the noise resamples, `StepRecord::rmse_m`.
    Rmse,
    /// Posterior CRLB at the truth from every snapshot so far, `StepRecord::pcrlb_m`.
    Pcrlb,
    /// The run's estimate error `|ẑ − z|`, `StepRecord::estimate_error_m`.
    EstimateError,
}

impl Metric {
    /// The metric's value at a step, metres (`None` when not recorded).
    pub fn value(self, step: &StepRecord) -> Option<f64> {
        match self {
            Metric::CrlbTrue => step.crlb_true_m,
            Metric::Rmse => step.rmse_m,
            Metric::Pcrlb => step.pcrlb_m,
            Metric::EstimateError => step.estimate_error_m,
        }
    }

    /// Human-readable name, used in titles and axis labels.
    pub fn label(self) -> &'static str {
        match self {
            Metric::CrlbTrue => "CRLB at the truth",
            Metric::Rmse => "RMSE",
            Metric::Pcrlb => "PCRLB at the truth",
            Metric::EstimateError => "estimate error |ẑ − z|",
        }
    }
}

/// Registers the embedded font with plotters, once per process.
fn ensure_font() -> Result<(), PlotError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| register_font(FAMILY, FontStyle::Normal, DEJAVU_SANS).is_ok());
    if ok { Ok(()) } else { Err(PlotError::Font) }
}

pub(crate) fn font(px: f64) -> TextStyle<'static> {
    (FAMILY, px).into_font().color(&BLACK)
}

pub(crate) type DrawResult<DB> = Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// A figure that can be drawn on any plotters backend.
pub(crate) trait Figure {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB>;
}

/// Draws `figure` into `path` in the format of its extension.
pub(crate) fn render(path: &Path, figure: &impl Figure) -> Result<(), PlotError> {
    let format =
        PlotFormat::from_path(path).ok_or_else(|| PlotError::UnsupportedFormat { path: path.to_path_buf() })?;
    ensure_font()?;
    let draw_error = |e: &dyn std::fmt::Display| PlotError::Draw { path: path.to_path_buf(), message: e.to_string() };
    let mut rgb = Vec::new();
    let canvas = match format {
        PlotFormat::Svg => Canvas::Svg(SVGBackend::new(path, FIGURE_SIZE)),
        PlotFormat::Png => {
            rgb = vec![0; 3 * FIGURE_SIZE.0 as usize * FIGURE_SIZE.1 as usize];
            Canvas::Bitmap(BitMapBackend::with_buffer(&mut rgb, FIGURE_SIZE))
        }
    };
    {
        let root = canvas.into_drawing_area();
        figure.draw(&root).map_err(|e| draw_error(&e))?;
        root.present().map_err(|e| draw_error(&e))?;
    }
    match format {
        PlotFormat::Svg => Ok(()),
        PlotFormat::Png => crate::png::write(path, FIGURE_SIZE, &rgb).map_err(|e| draw_error(&e)),
    }
}

/// Plots the UAV trajectories of `run` (the paper's Figure 4) into `path` (`.svg` or `.png`).
///
/// Each UAV's path is a coloured line (one line per UAV with at least two finite positions), with a
/// triangle at its start and a dot at its end; the true emitter is a red star, the estimate ẑ of each
/// step a small grey dot. The axes are x/y in metres at equal scale, framed on the UAV paths and the
/// emitter; estimates outside that frame are counted in the legend ("n off-chart") instead of drawn.
pub fn plot_trajectories(run: &RunRecord, path: &Path) -> Result<(), PlotError> {
    render(path, &Trajectories { run })
}

/// Plots the CRLB at the truth, the RMSE of a Chan snapshot, the run's estimate error `|ẑ − z|` and the
/// posterior CRLB (the bound on that error from every snapshot so far) of each step of `run` into `path`
/// (`.svg` or `.png`).
///
/// The y axis is logarithmic when the positive values span more than a factor 10, linear from 0
/// otherwise. Steps without a value (no RMSE, no truth) break the line.
pub fn plot_metrics(run: &RunRecord, path: &Path) -> Result<(), PlotError> {
    let lines = vec![
        MetricLine::of(run, Metric::CrlbTrue, "CRLB (snapshot)".to_owned(), palette(0)),
        MetricLine::of(run, Metric::Rmse, "RMSE (Chan)".to_owned(), palette(1)),
        MetricLine::of(run, Metric::EstimateError, format!("|ẑ−z| {}", run.estimator), palette(2)),
        MetricLine::of(run, Metric::Pcrlb, "PCRLB".to_owned(), palette(3)),
    ];
    let mut title = format!("Errors and bounds per step: {} / {}, seed {}", run.objective, run.solver, run.seed);
    if run.steps.is_empty() {
        title.push_str(" (no steps)");
    }
    render(path, &MetricChart { title, y_desc: "error (m)".to_owned(), lines })
}

/// Plots `metric` per step for several runs into `path` (`.svg` or `.png`), one line per run labelled
/// `<objective>/<solver>` (with `, seed N` appended when two runs would otherwise share a label).
/// An empty `runs` gives an empty figure.
pub fn plot_comparison(runs: &[&RunRecord], metric: Metric, path: &Path) -> Result<(), PlotError> {
    let base_label = |r: &RunRecord| format!("{}/{}", r.objective, r.solver);
    let lines = runs
        .iter()
        .enumerate()
        .map(|(i, run)| {
            let label = base_label(run);
            let shared = runs.iter().filter(|other| base_label(other) == label).count() > 1;
            let label = if shared { format!("{label}, seed {}", run.seed) } else { label };
            MetricLine::of(run, metric, label, palette(i))
        })
        .collect();
    let mut title = format!("{} per step", metric.label());
    if runs.is_empty() {
        title.push_str(" (no runs)");
    }
    render(path, &MetricChart { title, y_desc: format!("{} (m)", metric.label()), lines })
}

// ---------------------------------------------------------------------------------------------------
// Markers (pixel-sized, anchored at a data coordinate) and axis labels
// ---------------------------------------------------------------------------------------------------

// The markers are macros, not functions: a composed element's type names the backend, and boxing it
// (`DynElement`) would require a `'static` backend.

/// The start marker at `$at`: a filled triangle with a dark edge (two SVG `<polygon>`s, no polyline).
macro_rules! start_marker {
    ($at:expr, $color:expr) => {
        EmptyElement::at($at)
            + TriangleMarker::new((0, 0), 9, MARKER_EDGE.filled())
            + TriangleMarker::new((0, 0), 6, $color.filled())
    };
}

/// The end marker at `$at`: a filled dot with a dark edge.
macro_rules! end_marker {
    ($at:expr, $color:expr) => {
        EmptyElement::at($at) + Circle::new((0, 0), 6, MARKER_EDGE.filled()) + Circle::new((0, 0), 4, $color.filled())
    };
}

/// The true-emitter marker at `$at`: a red star with a dark edge.
macro_rules! star_marker {
    ($at:expr) => {
        EmptyElement::at($at)
            + Polygon::new(star_points(12.5), MARKER_EDGE.filled())
            + Polygon::new(star_points(10.0), EMITTER_RED.filled())
    };
}

/// The vertices of a five-pointed star of outer radius `r` (pixels) centred on the origin, point up.
pub(crate) fn star_points(r: f64) -> Vec<(i32, i32)> {
    (0..10)
        .map(|k| {
            let radius = if k % 2 == 0 { r } else { 0.42 * r };
            let angle = -std::f64::consts::FRAC_PI_2 + f64::from(k) * std::f64::consts::PI / 5.0;
            ((radius * angle.cos()).round() as i32, (radius * angle.sin()).round() as i32)
        })
        .collect()
}

/// Formats an axis value in metres compactly: integers where they are exact enough, otherwise up to
/// three significant digits, scientific notation for very large or small magnitudes.
pub(crate) fn fmt_axis(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".to_owned()
    } else if !(1e-3..1e6).contains(&a) {
        let s = format!("{v:.2e}");
        match s.split_once('e') {
            Some((mantissa, exp)) if mantissa.contains('.') => {
                format!("{}e{exp}", mantissa.trim_end_matches('0').trim_end_matches('.'))
            }
            _ => s,
        }
    } else if a >= 100.0 || (v - v.round()).abs() < 1e-9 * a.max(1.0) {
        format!("{v:.0}")
    } else {
        let digits = (2 - a.log10().floor() as i32).clamp(0, 6) as usize;
        let s = format!("{v:.digits$}");
        if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_owned() } else { s }
    }
}

// ---------------------------------------------------------------------------------------------------
// Legend panel
// ---------------------------------------------------------------------------------------------------

#[derive(Debug, Clone, Copy)]
pub(crate) enum Glyph {
    /// A line sample.
    Line(RGBColor),
    /// A line sample with a dot in the middle.
    LineDot(RGBColor),
    /// The start marker.
    Triangle(RGBColor),
    /// The end marker.
    Dot(RGBColor),
    /// The emitter marker.
    Star,
    /// A small estimate dot.
    SmallDot(RGBColor),
}

pub(crate) struct LegendEntry {
    pub(crate) glyph: Glyph,
    pub(crate) label: String,
}

const LEGEND_ROW: i32 = 24;

/// Draws the legend entries top-down in `area` (a panel of its own), with a frame around them.
/// Entries that do not fit are summarised in a last "… n more" row.
pub(crate) fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[LegendEntry],
) -> DrawResult<DB> {
    if entries.is_empty() {
        return Ok(());
    }
    let (w, h) = area.dim_in_pixel();
    let (top, left) = (CHART_MARGIN as i32 + 4, 6);
    let capacity = ((h as i32 - 2 * top) / LEGEND_ROW).max(1) as usize;
    let (shown, hidden) =
        if entries.len() > capacity { (capacity - 1, entries.len() - (capacity - 1)) } else { (entries.len(), 0) };
    let rows = shown + usize::from(hidden > 0);
    let bottom = top + 8 + rows as i32 * LEGEND_ROW;
    let right = w as i32 - 6;
    area.draw(&Rectangle::new([(left, top), (right, bottom)], WHITE.filled()))?;
    area.draw(&Rectangle::new([(left, top), (right, bottom)], RGBColor(0xb0, 0xb0, 0xb0).stroke_width(1)))?;
    let text_style = font(LEGEND_PX).pos(Pos::new(HPos::Left, VPos::Center));
    for (row, entry) in entries.iter().take(shown).enumerate() {
        let y = top + 4 + LEGEND_ROW / 2 + row as i32 * LEGEND_ROW;
        let x = left + 8;
        draw_glyph(area, entry.glyph, (x + 14, y))?;
        area.draw(&Text::new(entry.label.clone(), (x + 36, y), text_style.clone()))?;
    }
    if hidden > 0 {
        let y = top + 4 + LEGEND_ROW / 2 + shown as i32 * LEGEND_ROW;
        area.draw(&Text::new(format!("… {hidden} more"), (left + 44, y), text_style))?;
    }
    Ok(())
}

/// Draws a legend glyph centred on `c` (pixels of `area`).
fn draw_glyph<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, glyph: Glyph, c: (i32, i32)) -> DrawResult<DB> {
    let (x, y) = c;
    // Line samples are thin filled rectangles, not paths: the only SVG polylines of a figure are its
    // data lines.
    let line = |color: RGBColor| Rectangle::new([(x - 13, y - 1), (x + 13, y + 1)], color.filled());
    match glyph {
        Glyph::Line(color) => area.draw(&line(color)),
        Glyph::LineDot(color) => {
            area.draw(&line(color))?;
            area.draw(&Circle::new(c, 3, color.filled()))
        }
        Glyph::Triangle(color) => area.draw(&start_marker!(c, color)),
        Glyph::Dot(color) => area.draw(&end_marker!(c, color)),
        Glyph::Star => area.draw(&star_marker!(c)),
        Glyph::SmallDot(color) => area.draw(&Circle::new(c, 2, color.filled())),
    }
}

// ---------------------------------------------------------------------------------------------------
// Trajectories
// ---------------------------------------------------------------------------------------------------

struct Trajectories<'a> {
    run: &'a RunRecord,
}

/// The colour of the estimate's confidence ellipses.
pub(crate) const ELLIPSE_COLOR: RGBColor = RGBColor(0x9a, 0x40, 0xc0);

/// The 95 % confidence ellipse `{ẑ + sqrt(χ²₂(0.95)) M^{1/2} u : |u| = 1}` of an estimate (72 points,
/// closed), or `None` for a covariance that is not positive definite or numbers that are not finite.
pub fn ellipse95(center: [f64; 2], cov: [[f64; 2]; 2]) -> Option<Vec<(f64, f64)>> {
    let m = tdoa::matrix_from_rows(&cov);
    if center.iter().chain(m.iter()).any(|v| !v.is_finite()) {
        return None;
    }
    let eig = nalgebra::SymmetricEigen::new(0.5 * (m + m.transpose()));
    if eig.eigenvalues.iter().any(|l| l.is_nan() || *l <= 0.0) {
        return None;
    }
    let k = tdoa::dist::chi2_quantile(2.0, 0.95).sqrt();
    let axes = [
        eig.eigenvectors.column(0) * (k * eig.eigenvalues[0].sqrt()),
        eig.eigenvectors.column(1) * (k * eig.eigenvalues[1].sqrt()),
    ];
    Some(
        (0..=72)
            .map(|i| {
                let t = i as f64 * std::f64::consts::TAU / 72.0;
                let p = axes[0] * t.cos() + axes[1] * t.sin();
                (center[0] + p.x, center[1] + p.y)
            })
            .collect(),
    )
}

fn finite_point(p: [f64; 2]) -> Option<(f64, f64)> {
    (p[0].is_finite() && p[1].is_finite()).then_some((p[0], p[1]))
}

/// An axis-aligned box of points.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Bounds {
    pub(crate) x: (f64, f64),
    pub(crate) y: (f64, f64),
}

impl Bounds {
    pub(crate) fn of(points: impl IntoIterator<Item = (f64, f64)>) -> Option<Self> {
        points.into_iter().fold(None, |b: Option<Bounds>, (x, y)| {
            Some(match b {
                None => Bounds { x: (x, x), y: (y, y) },
                Some(b) => Bounds { x: (b.x.0.min(x), b.x.1.max(x)), y: (b.y.0.min(y), b.y.1.max(y)) },
            })
        })
    }

    /// The larger side, metres.
    fn span(&self) -> f64 {
        (self.x.1 - self.x.0).max(self.y.1 - self.y.0)
    }

    /// The box grown by `m` on every side.
    fn grown(&self, m: f64) -> Bounds {
        Bounds { x: (self.x.0 - m, self.x.1 + m), y: (self.y.0 - m, self.y.1 + m) }
    }

    fn contains(&self, (x, y): (f64, f64)) -> bool {
        (self.x.0..=self.x.1).contains(&x) && (self.y.0..=self.y.1).contains(&y)
    }

    /// Pads the box by 6 % of its larger side (at least 250 m) on every side, then widens the shorter
    /// dimension so that one metre has the same length in pixels on both axes of a `w`×`h` area.
    pub(crate) fn equal_aspect(&self, w: u32, h: u32) -> Bounds {
        let pad = (0.06 * self.span()).max(250.0);
        let (dx, dy) = (self.x.1 - self.x.0 + 2.0 * pad, self.y.1 - self.y.0 + 2.0 * pad);
        let (w, h) = (f64::from(w.max(1)), f64::from(h.max(1)));
        let metres_per_px = (dx / w).max(dy / h);
        let (half_x, half_y) = (0.5 * metres_per_px * w, 0.5 * metres_per_px * h);
        let (cx, cy) = (0.5 * (self.x.0 + self.x.1), 0.5 * (self.y.0 + self.y.1));
        Bounds { x: (cx - half_x, cx + half_x), y: (cy - half_y, cy + half_y) }
    }
}

/// The axes of a chart of the plane at equal scale: descriptions, tick labels, the number of x labels
/// and of light grid lines between them (`None`: plotters' default).
pub(crate) struct PlaneAxes<'f> {
    pub(crate) x_desc: &'f str,
    pub(crate) y_desc: &'f str,
    pub(crate) x_label: &'f dyn Fn(&f64) -> String,
    pub(crate) y_label: &'f dyn Fn(&f64) -> String,
    pub(crate) x_labels: usize,
    pub(crate) light_lines: Option<usize>,
}

/// A chart of the plane, metres on both axes.
pub(crate) type PlaneChart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// A chart of the plane in `area` (the body of a `w`×`h` figure, legend panel aside) framing `frame` at
/// equal scale on both axes, its mesh drawn; the chart and the range it shows.
pub(crate) fn plane_chart<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    (w, h): (u32, u32),
    frame: Bounds,
    axes: &PlaneAxes<'_>,
) -> Result<(PlaneChart<'a, DB>, Bounds), DrawingAreaErrorKind<DB::ErrorType>> {
    let plot_w = (w.saturating_sub(LEGEND_WIDTH)).saturating_sub(2 * CHART_MARGIN + Y_LABEL_AREA);
    let plot_h = h.saturating_sub(2 * CHART_MARGIN + X_LABEL_AREA);
    let range = frame.equal_aspect(plot_w, plot_h);
    let mut chart = ChartBuilder::on(area)
        .margin(CHART_MARGIN)
        .x_label_area_size(X_LABEL_AREA)
        .y_label_area_size(Y_LABEL_AREA)
        .build_cartesian_2d(range.x.0..range.x.1, range.y.0..range.y.1)?;
    let mut mesh = chart.configure_mesh();
    mesh.x_desc(axes.x_desc)
        .y_desc(axes.y_desc)
        .label_style(font(LABEL_PX))
        .axis_desc_style(font(DESC_PX))
        .x_label_formatter(axes.x_label)
        .y_label_formatter(axes.y_label)
        .x_labels(axes.x_labels)
        .y_labels(8);
    if let Some(n) = axes.light_lines {
        mesh.max_light_lines(n);
    }
    mesh.light_line_style(RGBColor(0xf0, 0xf0, 0xf0)).bold_line_style(RGBColor(0xd8, 0xd8, 0xd8)).draw()?;
    Ok((chart, range))
}

impl Figure for Trajectories<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
        let run = self.run;
        root.fill(&WHITE)?;
        let mut title = format!("{} / {}, seed {}", run.objective, run.solver, run.seed);
        if run.steps.is_empty() {
            title.push_str(" (no steps)");
        }
        let body = root.titled(&title, font(TITLE_PX))?;
        let (w, h) = body.dim_in_pixel();
        let (chart_area, legend_area) = body.split_horizontally(w.saturating_sub(LEGEND_WIDTH));

        let n_uavs = run.steps.iter().map(|s| s.uavs.len()).max().unwrap_or(0);
        let paths: Vec<Vec<(f64, f64)>> = (0..n_uavs)
            .map(|i| run.steps.iter().filter_map(|s| s.uavs.get(i).copied().and_then(finite_point)).collect())
            .collect();
        let emitter = run.emitter.and_then(finite_point);
        let estimates: Vec<(f64, f64)> = run.steps.iter().filter_map(|s| finite_point(s.estimate)).collect();

        // Frame on the UAVs and the emitter, plus the estimates near them (a failed estimate may be
        // anywhere); with neither, on the estimates.
        let frame = match Bounds::of(paths.iter().flatten().copied().chain(emitter)) {
            Some(core) => {
                let zone = core.grown(0.25 * core.span().max(1000.0));
                let near = estimates.iter().copied().filter(|&p| zone.contains(p));
                Bounds::of(near.chain([(core.x.0, core.y.0), (core.x.1, core.y.1)])).unwrap_or(core)
            }
            None => {
                Bounds::of(estimates.iter().copied()).unwrap_or(Bounds { x: (-1000.0, 1000.0), y: (-1000.0, 1000.0) })
            }
        };
        let axes = PlaneAxes {
            x_desc: "x (m)",
            y_desc: "y (m)",
            x_label: &|v| fmt_axis(*v),
            y_label: &|v| fmt_axis(*v),
            x_labels: 8,
            light_lines: Some(4),
        };
        let (mut chart, range) = plane_chart(&chart_area, (w, h), frame, &axes)?;
        let (on_chart, off_chart): (Vec<_>, Vec<_>) = estimates.iter().partition(|&&p| range.contains(p));

        chart.draw_series(on_chart.iter().map(|&&p| Circle::new(p, 2, ESTIMATE_GREY.filled())))?;
        // The estimate track and its 95 % ellipses every few steps (about eight per run).
        let track: Vec<(f64, f64)> = estimates.iter().copied().filter(|&p| range.contains(p)).collect();
        if track.len() >= 2 {
            chart.draw_series(LineSeries::new(track, ESTIMATE_GREY.stroke_width(1)))?;
        }
        let every = run.steps.len().div_ceil(8).max(1);
        let limit = 2.0 * range.span();
        let ellipses: Vec<Vec<(f64, f64)>> = run
            .steps
            .iter()
            .enumerate()
            .filter(|(k, _)| k % every == 0 || *k + 1 == run.steps.len())
            .filter_map(|(_, s)| ellipse95(s.estimate, s.estimate_cov))
            .filter(|e| e.iter().all(|p| (p.0 - e[0].0).abs() < limit && (p.1 - e[0].1).abs() < limit))
            .filter(|e| e.iter().any(|&p| range.contains(p)))
            .collect();
        for e in &ellipses {
            chart.draw_series(std::iter::once(PathElement::new(e.clone(), ELLIPSE_COLOR.stroke_width(1))))?;
        }
        for (i, path) in paths.iter().enumerate() {
            if path.len() >= 2 {
                chart.draw_series(LineSeries::new(path.iter().copied(), palette(i).stroke_width(2)))?;
            }
        }
        for (i, path) in paths.iter().enumerate() {
            if let Some(&first) = path.first() {
                chart.draw_series(std::iter::once(start_marker!(first, palette(i))))?;
            }
            if path.len() >= 2 {
                let last = path[path.len() - 1];
                chart.draw_series(std::iter::once(end_marker!(last, palette(i))))?;
            }
        }
        if let Some(e) = emitter {
            chart.draw_series(std::iter::once(star_marker!(e)))?;
        }

        let mut entries: Vec<LegendEntry> =
            (0..n_uavs).map(|i| LegendEntry { glyph: Glyph::Line(palette(i)), label: format!("UAV{i}") }).collect();
        if n_uavs > 0 {
            entries.push(LegendEntry { glyph: Glyph::Triangle(ESTIMATE_GREY), label: "start".to_owned() });
            entries.push(LegendEntry { glyph: Glyph::Dot(ESTIMATE_GREY), label: "end".to_owned() });
        }
        if emitter.is_some() {
            entries.push(LegendEntry { glyph: Glyph::Star, label: "true emitter".to_owned() });
        }
        if !ellipses.is_empty() {
            entries.push(LegendEntry { glyph: Glyph::Line(ELLIPSE_COLOR), label: "95 % ellipse".to_owned() });
        }
        if !estimates.is_empty() {
            let label = if off_chart.is_empty() {
                "estimates".to_owned()
            } else {
                format!("estimates ({} off-chart)", off_chart.len())
            };
            entries.push(LegendEntry { glyph: Glyph::SmallDot(ESTIMATE_GREY), label });
        }
        draw_legend(&legend_area, &entries)
    }
}

// ---------------------------------------------------------------------------------------------------
// Metric charts (metrics of one run, comparison of runs)
// ---------------------------------------------------------------------------------------------------

/// One line of a metric chart: `(step, value)` points, `None` (or non-finite) values break the line.
struct MetricLine {
    label: String,
    color: RGBColor,
    points: Vec<(i64, Option<f64>)>,
}

impl MetricLine {
    fn of(run: &RunRecord, metric: Metric, label: String, color: RGBColor) -> Self {
        let points = run
            .steps
            .iter()
            .map(|s| (i64::try_from(s.step).unwrap_or(i64::MAX), metric.value(s).filter(|v| v.is_finite())))
            .collect();
        MetricLine { label, color, points }
    }

    /// Runs of consecutive valid points (a `None`, or a non-positive value on a log axis, ends a run).
    fn segments(&self, log: bool) -> Vec<Vec<(i64, f64)>> {
        let mut out = vec![];
        let mut current = vec![];
        for &(x, v) in &self.points {
            match v.filter(|v| !log || *v > 0.0) {
                Some(v) => current.push((x, v)),
                None => {
                    if !current.is_empty() {
                        out.push(std::mem::take(&mut current));
                    }
                }
            }
        }
        if !current.is_empty() {
            out.push(current);
        }
        out
    }
}

struct MetricChart {
    title: String,
    y_desc: String,
    lines: Vec<MetricLine>,
}

impl Figure for MetricChart {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
        root.fill(&WHITE)?;
        let body = root.titled(&self.title, font(TITLE_PX))?;
        let (w, _) = body.dim_in_pixel();
        let (chart_area, legend_area) = body.split_horizontally(w.saturating_sub(LEGEND_WIDTH));

        let steps = self.lines.iter().flat_map(|l| l.points.iter().map(|p| p.0));
        let x_lo = steps.clone().min().unwrap_or(0);
        let x_hi = steps.max().unwrap_or(1).max(x_lo + 1);
        let values = self.lines.iter().flat_map(|l| l.points.iter().filter_map(|p| p.1));
        let positive = values.clone().filter(|v| *v > 0.0);
        let (lo, hi) = (positive.clone().fold(f64::INFINITY, f64::min), positive.fold(0.0, f64::max));
        if lo.is_finite() && hi > 10.0 * lo {
            let (lo, hi) = (lo / 1.5, hi * 1.5);
            let (bold, light) = log_ticks(lo, hi);
            let y = (lo..hi).log_scale().with_key_points(bold).with_light_points(light);
            draw_metric_lines(&chart_area, x_lo..x_hi, y, &self.y_desc, &self.lines, true)?;
        } else {
            let y_min = values.fold(0.0, f64::min);
            let y_max = if hi > 0.0 { hi * 1.1 } else { 1.0 };
            draw_metric_lines(&chart_area, x_lo..x_hi, y_min..y_max, &self.y_desc, &self.lines, false)?;
        }
        if self.lines.iter().all(|l| l.points.iter().all(|p| p.1.is_none())) {
            // The centre of the plotting area (the chart area minus its margin and label areas).
            let (cw, ch) = chart_area.dim_in_pixel();
            let plot_w = cw.saturating_sub(2 * CHART_MARGIN + Y_LABEL_AREA);
            let plot_h = ch.saturating_sub(2 * CHART_MARGIN + X_LABEL_AREA);
            let centre = ((CHART_MARGIN + Y_LABEL_AREA + plot_w / 2) as i32, (CHART_MARGIN + plot_h / 2) as i32);
            let style = font(DESC_PX).color(&ESTIMATE_GREY).pos(Pos::new(HPos::Center, VPos::Center));
            chart_area.draw(&Text::new("no data", centre, style))?;
        }
        let entries: Vec<LegendEntry> =
            self.lines.iter().map(|l| LegendEntry { glyph: Glyph::LineDot(l.color), label: l.label.clone() }).collect();
        draw_legend(&legend_area, &entries)
    }
}

/// Tick values of a log axis over `lo..hi` (`0 < lo < hi`): labelled ones (1-2-5, 1-3 or powers of 10
/// per decade, depending on the number of decades) and the light grid (1…9 per decade).
pub(crate) fn log_ticks(lo: f64, hi: f64) -> (Vec<f64>, Vec<f64>) {
    let decades = (hi / lo).log10();
    let mantissas: &[f64] = if decades <= 2.5 {
        &[1.0, 2.0, 5.0]
    } else if decades <= 5.0 {
        &[1.0, 3.0]
    } else {
        &[1.0]
    };
    let every = ((decades / 8.0).ceil() as i32).max(1); // at most ~8 labelled powers of 10
    let (k0, k1) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    let in_range = |v: &f64| (lo..=hi).contains(v);
    let bold = (k0..=k1)
        .filter(|k| (k - k0) % every == 0)
        .flat_map(|k| mantissas.iter().map(move |m| m * 10f64.powi(k)))
        .filter(in_range)
        .collect();
    let light = if decades <= 6.0 {
        (k0..=k1).flat_map(|k| (1..=9).map(move |m| f64::from(m) * 10f64.powi(k))).filter(in_range).collect()
    } else {
        (k0..=k1).map(|k| 10f64.powi(k)).filter(in_range).collect()
    };
    (bold, light)
}

/// Draws the axes and lines of a metric chart; `y` is a linear or a log range (`log` says which).
fn draw_metric_lines<DB, Y>(
    area: &DrawingArea<DB, Shift>,
    x: Range<i64>,
    y: Y,
    y_desc: &str,
    lines: &[MetricLine],
    log: bool,
) -> DrawResult<DB>
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
        .x_desc("step")
        .y_desc(if log { format!("{y_desc}, log scale") } else { y_desc.to_owned() })
        .label_style(font(LABEL_PX))
        .axis_desc_style(font(DESC_PX))
        .y_label_formatter(&|v| fmt_axis(*v))
        .max_light_lines(4)
        .light_line_style(RGBColor(0xf0, 0xf0, 0xf0))
        .bold_line_style(RGBColor(0xd8, 0xd8, 0xd8))
        .draw()?;
    for line in lines {
        for segment in line.segments(log) {
            if segment.len() >= 2 {
                chart.draw_series(LineSeries::new(segment.iter().copied(), line.color.stroke_width(2)))?;
            }
            chart.draw_series(segment.iter().map(|&p| Circle::new(p, 3, line.color.filled())))?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_95_ellipse_holds_95_percent_of_gaussian_draws() {
        // Points on the ellipse have Mahalanobis distance² = χ²₂(0.95) = 5.991; draws inside it are 95 %.
        let cov = [[4.0e4, 1.5e4], [1.5e4, 1.0e4]];
        let e = ellipse95([100.0, -50.0], cov).unwrap();
        let inv = tdoa::matrix_from_rows(&cov).try_inverse().unwrap();
        for (x, y) in &e {
            let d = nalgebra::Vector2::new(x - 100.0, y + 50.0);
            assert!((d.dot(&(inv * d)) - 5.991_464_547_107_979).abs() < 1e-6);
        }
        assert!(ellipse95([0.0, 0.0], [[1.0, 2.0], [2.0, 1.0]]).is_none(), "indefinite");
        assert!(ellipse95([f64::NAN, 0.0], cov).is_none());
    }

    #[test]
    fn axis_labels_are_compact() {
        assert_eq!(fmt_axis(0.0), "0");
        assert_eq!(fmt_axis(25000.0), "25000");
        assert_eq!(fmt_axis(-500.0), "-500");
        assert_eq!(fmt_axis(10.0), "10");
        assert_eq!(fmt_axis(2.5), "2.5");
        assert_eq!(fmt_axis(0.05), "0.05");
        assert_eq!(fmt_axis(1e6), "1e6");
        assert_eq!(fmt_axis(2e-4), "2e-4");
    }

    #[test]
    fn equal_aspect_has_the_same_metres_per_pixel_on_both_axes() {
        let b = Bounds { x: (0.0, 30000.0), y: (0.0, 10000.0) }.equal_aspect(600, 500);
        let (mx, my) = ((b.x.1 - b.x.0) / 600.0, (b.y.1 - b.y.0) / 500.0);
        assert!((mx - my).abs() < 1e-9 * mx, "{mx} vs {my}");
        assert!(b.x.0 < 0.0 && b.x.1 > 30000.0 && b.y.0 < 0.0 && b.y.1 > 10000.0);
        // A single point gets a non-degenerate frame.
        let p = Bounds { x: (5.0, 5.0), y: (7.0, 7.0) }.equal_aspect(600, 500);
        assert!(p.x.1 - p.x.0 > 400.0 && p.y.1 - p.y.0 > 400.0);
    }

    #[test]
    fn log_ticks_cover_the_range() {
        let (bold, light) = log_ticks(20.0, 3000.0);
        assert_eq!(bold, vec![20.0, 50.0, 100.0, 200.0, 500.0, 1000.0, 2000.0]);
        assert!(light.iter().all(|v| (20.0..=3000.0).contains(v)) && light.len() > 15);
        let (bold, _) = log_ticks(1e-3, 1e12);
        assert!(bold.len() <= 9 && bold.iter().all(|v| (1e-3..=1e12).contains(v)), "{bold:?}");
    }

    #[test]
    fn star_has_ten_vertices_point_up() {
        let s = star_points(10.0);
        assert_eq!(s.len(), 10);
        assert_eq!(s[0], (0, -10));
    }

    #[test]
    fn format_from_extension() {
        assert_eq!(PlotFormat::from_path(Path::new("a/b.svg")), Some(PlotFormat::Svg));
        assert_eq!(PlotFormat::from_path(Path::new("b.PNG")), Some(PlotFormat::Png));
        assert_eq!(PlotFormat::from_path(Path::new("b.pdf")), None);
        assert_eq!(PlotFormat::from_path(Path::new("svg")), None);
    }
}
