//! A map of a run placed on the Earth, drawn from its recording's map layer (the `foxglove.GeoJSON`
//! messages of [`crate::foxglove`]): the tracks flown, the estimate's 95 % ellipse, the L_min circle
//! around it and the true emitter, on latitude/longitude axes at equal ground scale (an equirectangular
//! view about the layer's centre: a degree of longitude is `cos(lat)` of a degree of latitude). What
//! `uavloc map FILE.mcap` draws, where Foxglove's Map panel is not at hand.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use serde_json::Value;

use crate::plot::{
    Bounds, ELLIPSE_COLOR, EMITTER_RED, Figure, Glyph, LEGEND_WIDTH, LegendEntry, MARKER_EDGE, PlaneAxes, PlotError,
    TITLE_PX, draw_legend, font, palette, plane_chart, render, star_points,
};

/// Metres per degree of latitude (WGS84, mid-latitudes; the view's scale, not a measurement).
const METRES_PER_DEGREE: f64 = 111_200.0;
const STANDOFF_GREY: RGBColor = RGBColor(0x70, 0x70, 0x70);

/// One feature of the layer, projected to metres east/north of the view's centre.
enum Shape {
    Track(String, Vec<(f64, f64)>),
    Ring(String, Vec<(f64, f64)>),
    Point(String, (f64, f64)),
}

/// The view: its centre and the projection.
struct View {
    lat0: f64,
    lon0: f64,
}

impl View {
    fn to_xy(&self, lon: f64, lat: f64) -> (f64, f64) {
        ((lon - self.lon0) * METRES_PER_DEGREE * self.lat0.to_radians().cos(), (lat - self.lat0) * METRES_PER_DEGREE)
    }
    fn lon(&self, x: f64) -> f64 {
        self.lon0 + x / (METRES_PER_DEGREE * self.lat0.to_radians().cos())
    }
    fn lat(&self, y: f64) -> f64 {
        self.lat0 + y / METRES_PER_DEGREE
    }
}

struct MapFigure {
    title: String,
    view: View,
    shapes: Vec<Shape>,
}

fn lon_lat(v: &Value) -> Option<(f64, f64)> {
    let (lon, lat) = (v.get(0)?.as_f64()?, v.get(1)?.as_f64()?);
    (lon.is_finite() && lat.is_finite()).then_some((lon, lat))
}

/// Why a layer cannot be drawn.
fn bad(what: &str) -> PlotError {
    PlotError::Draw { path: Default::default(), message: format!("the map layer {what}") }
}

/// Draws `layer` (a GeoJSON FeatureCollection of LineStrings, Polygons and Points, coordinates
/// `[lon, lat]`) into `path` (`.svg` or `.png`) with `title`.
pub fn plot_map(layer: &Value, title: &str, path: &Path) -> Result<(), PlotError> {
    let features = layer["features"].as_array().ok_or_else(|| bad("is not a FeatureCollection"))?;
    let mut all = Vec::new();
    let mut raw = Vec::new();
    for f in features {
        let name = f["properties"]["name"].as_str().unwrap_or("").to_string();
        let g = &f["geometry"];
        let points: Vec<(f64, f64)> = match g["type"].as_str() {
            Some("LineString") => g["coordinates"].as_array().map(|c| c.iter().filter_map(lon_lat).collect()),
            Some("Polygon") => g["coordinates"][0].as_array().map(|c| c.iter().filter_map(lon_lat).collect()),
            Some("Point") => lon_lat(&g["coordinates"]).map(|p| vec![p]),
            _ => None,
        }
        .unwrap_or_default();
        all.extend(points.iter().copied());
        raw.push((g["type"].as_str().unwrap_or("").to_string(), name, points));
    }
    let n = all.len().max(1) as f64;
    let (lon0, lat0) = all.iter().fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let view = View { lat0, lon0 };
    let shapes = raw
        .into_iter()
        .filter(|(_, _, p)| !p.is_empty())
        .map(|(kind, name, p)| {
            let xy: Vec<(f64, f64)> = p.iter().map(|&(lon, lat)| view.to_xy(lon, lat)).collect();
            match kind.as_str() {
                "LineString" => Shape::Track(name, xy),
                "Polygon" => Shape::Ring(name, xy),
                _ => Shape::Point(name, xy[0]),
            }
        })
        .collect();
    render(path, &MapFigure { title: title.to_string(), view, shapes })
}

impl Figure for MapFigure {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
    ) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
        root.fill(&WHITE)?;
        let body = root.titled(&self.title, font(TITLE_PX))?;
        let (w, h) = body.dim_in_pixel();
        let (chart_area, legend_area) = body.split_horizontally(w.saturating_sub(LEGEND_WIDTH));
        let points = self.shapes.iter().flat_map(|s| match s {
            Shape::Track(_, p) | Shape::Ring(_, p) => p.clone(),
            Shape::Point(_, p) => vec![*p],
        });
        let frame = Bounds::of(points).unwrap_or(Bounds { x: (-1000.0, 1000.0), y: (-1000.0, 1000.0) });
        let axes = PlaneAxes {
            x_desc: "longitude (°E)",
            y_desc: "latitude (°N)",
            x_label: &|x| format!("{:.3}", self.view.lon(*x)),
            y_label: &|y| format!("{:.3}", self.view.lat(*y)),
            x_labels: 6,
            light_lines: None,
        };
        let (mut chart, _) = plane_chart(&chart_area, (w, h), frame, &axes)?;
        let mut entries = Vec::new();
        let mut tracks = 0;
        for s in &self.shapes {
            match s {
                Shape::Track(name, p) => {
                    let c = palette(tracks);
                    tracks += 1;
                    chart.draw_series(LineSeries::new(p.iter().copied(), c.stroke_width(2)))?;
                    if let Some(&last) = p.last() {
                        chart.draw_series(std::iter::once(
                            EmptyElement::at(last)
                                + Circle::new((0, 0), 6, MARKER_EDGE.filled())
                                + Circle::new((0, 0), 4, c.filled()),
                        ))?;
                    }
                    entries.push(LegendEntry { glyph: Glyph::LineDot(c), label: name.replace(" track", "") });
                }
                Shape::Ring(name, p) => {
                    let c = if name.contains("L_min") { STANDOFF_GREY } else { ELLIPSE_COLOR };
                    chart.draw_series(std::iter::once(PathElement::new(p.clone(), c.stroke_width(2))))?;
                    entries.push(LegendEntry { glyph: Glyph::Line(c), label: name.clone() });
                }
                Shape::Point(name, p) => {
                    chart.draw_series(std::iter::once(
                        EmptyElement::at(*p)
                            + Polygon::new(star_points(12.5), MARKER_EDGE.filled())
                            + Polygon::new(star_points(10.0), EMITTER_RED.filled()),
                    ))?;
                    entries.push(LegendEntry { glyph: Glyph::Star, label: name.clone() });
                }
            }
        }
        draw_legend(&legend_area, &entries)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn a_layer_draws_and_a_bad_one_is_an_error() {
        let dir = std::env::temp_dir().join(format!("uavloc-map-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let layer = json!({"type": "FeatureCollection", "features": [
            {"type": "Feature", "properties": {"name": "UAV 0 track"}, "geometry": {"type": "LineString", "coordinates": [[8.56, 47.40], [8.60, 47.42]]}},
            {"type": "Feature", "properties": {"name": "95 % ellipse"}, "geometry": {"type": "Polygon", "coordinates": [[[8.87, 47.53], [8.88, 47.53], [8.88, 47.54], [8.87, 47.53]]]}},
            {"type": "Feature", "properties": {"name": "emitter (truth)"}, "geometry": {"type": "Point", "coordinates": [8.8776, 47.5321]}},
        ]});
        let svg = dir.join("map.svg");
        plot_map(&layer, "t", &svg).unwrap();
        let text = std::fs::read_to_string(&svg).unwrap();
        assert!(text.contains("latitude") && text.contains("UAV 0") && text.contains("95 % ellipse"));
        // The axes are labelled in degrees: 47.4xx on the latitude axis.
        assert!(text.contains("47.4") && text.contains("8.7"), "degree labels");
        plot_map(&layer, "t", &dir.join("map.png")).unwrap();
        assert!(plot_map(&json!({"type": "Feature"}), "t", &svg).is_err());
        std::fs::remove_dir_all(&dir).ok();
    }

    /// Equal ground scale: a degree of longitude is cos(lat) of a degree of latitude.
    #[test]
    fn the_view_keeps_ground_distances() {
        let v = View { lat0: 60.0, lon0: 10.0 };
        let (x, _) = v.to_xy(11.0, 60.0);
        let (_, y) = v.to_xy(10.0, 61.0);
        assert!((x / y - 0.5).abs() < 1e-12);
        assert!((v.lon(x) - 11.0).abs() < 1e-12 && (v.lat(y) - 61.0).abs() < 1e-12);
    }
}
