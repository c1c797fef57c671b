//! What a recording carries for Foxglove's own panels, beside uavloc's channels: messages in Foxglove's
//! published schemas (`@foxglove/schemas`, JSON encoding), which its Map and 3D panels draw without any
//! custom code.
//!
//! | topic | schema | what | when |
//! |---|---|---|---|
//! | `/map/uav<i>` | `foxglove.LocationFix` | UAV i, course clockwise from north | run with an origin |
//! | `/map/estimate` | `foxglove.LocationFix` | ẑ with its covariance (ENU, m²) | run with an origin, after a fix |
//! | `/map/truth` | `foxglove.LocationFix` | the true emitter | run with an origin and a truth |
//! | `/map/geojson` | `foxglove.GeoJSON` | the tracks flown, the 95 % ellipse, the L_min circle around ẑ | run with an origin |
//! | `/scene` | `foxglove.SceneUpdate` | the same in the local plane (frame `local`, metres) | every run |
//! | `/tf` | `foxglove.FrameTransform` | frame `uav<i>` in `local`: position and heading | every run |
//!
//! Every message is derived from a uavloc message the recording holds (an estimate: the UAVs, ẑ and M of
//! its step; a truth: the emitter), by [`FoxgloveView::derive`] — the same for a message received and for
//! one copied from a predecessor's recording on a resume, so a resumed recording is drawn the same. Times
//! are the uavloc message's publish time (CLOCK_MONOTONIC, ns).
//!
//! The schemas are the registry package's own files (`record/foxglove/`, `@foxglove/schemas` 2.1.0, MIT
//! licence), embedded as the channels' schema data.

use model::Scenario;
use model::geo::{LocalFrame, circle, confidence_ellipse, course_deg};
use serde_json::{Value, json};

use crate::geographic::ELLIPSE_PROBABILITY;

/// A Foxglove schema: its name and its JSON schema, as published in `@foxglove/schemas`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FoxgloveSchema {
    /// The schema name Foxglove recognises (`foxglove.LocationFix`, …).
    pub name: &'static str,
    /// The JSON schema.
    pub json_schema: &'static str,
}

/// `foxglove.LocationFix`.
pub const LOCATION_FIX: FoxgloveSchema =
    FoxgloveSchema { name: "foxglove.LocationFix", json_schema: include_str!("../foxglove/LocationFix.json") };
/// `foxglove.GeoJSON`.
pub const GEOJSON: FoxgloveSchema =
    FoxgloveSchema { name: "foxglove.GeoJSON", json_schema: include_str!("../foxglove/GeoJSON.json") };
/// `foxglove.SceneUpdate`.
pub const SCENE_UPDATE: FoxgloveSchema =
    FoxgloveSchema { name: "foxglove.SceneUpdate", json_schema: include_str!("../foxglove/SceneUpdate.json") };
/// `foxglove.FrameTransform`.
pub const FRAME_TRANSFORM: FoxgloveSchema =
    FoxgloveSchema { name: "foxglove.FrameTransform", json_schema: include_str!("../foxglove/FrameTransform.json") };

/// The Map panel's topic of UAV i.
pub const UAV_TOPICS: [&str; tdoa::MAX_UAVS] =
    ["/map/uav0", "/map/uav1", "/map/uav2", "/map/uav3", "/map/uav4", "/map/uav5", "/map/uav6", "/map/uav7"];
/// The estimate on the map.
pub const ESTIMATE_TOPIC: &str = "/map/estimate";
/// The true emitter on the map.
pub const TRUTH_TOPIC: &str = "/map/truth";
/// Tracks, ellipse and L_min circle on the map.
pub const GEOJSON_TOPIC: &str = "/map/geojson";
/// The 3D scene in the local plane.
pub const SCENE_TOPIC: &str = "/scene";
/// The UAVs' frames.
pub const TF_TOPIC: &str = "/tf";
/// The name of the local plane's frame (x east, y north, z up, metres, at the origin when there is one).
pub const LOCAL_FRAME: &str = "local";

/// Whether a topic is one of this module's (not a uavloc message).
pub fn is_foxglove_topic(topic: &str) -> bool {
    topic.starts_with("/map/") || topic == SCENE_TOPIC || topic == TF_TOPIC
}

/// One Foxglove message to write: its topic, schema and JSON.
#[derive(Debug, Clone, PartialEq)]
pub struct FoxgloveMessage {
    /// The channel.
    pub topic: &'static str,
    /// Its schema.
    pub schema: FoxgloveSchema,
    /// The message.
    pub json: Value,
}

/// The state the Foxglove messages are derived with: the run's plane, its L_min, the tracks so far and
/// the last truth.
#[derive(Debug, Clone)]
pub struct FoxgloveView {
    frame: Option<LocalFrame>,
    l_min: f64,
    /// The UAVs' positions by step, in step order (a step seen again is not drawn again, see
    /// `drawn_estimate`): indexed, so that a thinned track and the newest segment cost no walk over the
    /// run.
    tracks: Vec<(u64, Vec<[f64; 2]>)>,
    truth: Option<[f64; 2]>,
    /// The newest step drawn from the truth: a copy of a step already drawn (a retry, a replay after a
    /// crash — recorded again as it went over the wire) draws nothing again ([`first_drawing`]).
    drawn_truth: Option<u64>,
    /// The same for the estimates.
    drawn_estimate: Option<u64>,
}

/// Whether `msg` is the first of its step to be drawn from its topic, whose newest step drawn is
/// `newest` (then `newest` becomes its step); a message without a step is always drawn.
fn first_drawing(newest: &mut Option<u64>, msg: &Value) -> bool {
    let Some(step) = msg["step"].as_u64() else { return true };
    if newest.is_some_and(|n| step <= n) {
        return false;
    }
    *newest = Some(step);
    true
}

const COLOURS: [[f64; 3]; 8] = [
    [0.12, 0.47, 0.71],
    [1.0, 0.5, 0.05],
    [0.17, 0.63, 0.17],
    [0.58, 0.4, 0.74],
    [0.55, 0.34, 0.29],
    [0.89, 0.47, 0.76],
    [0.5, 0.5, 0.5],
    [0.74, 0.74, 0.13],
];
const ESTIMATE_COLOUR: [f64; 3] = [0.84, 0.15, 0.16];
const TRUTH_COLOUR: [f64; 3] = [0.0, 0.0, 0.0];

fn colour(c: [f64; 3], a: f64) -> Value {
    json!({"r": c[0], "g": c[1], "b": c[2], "a": a})
}

/// A plane coordinate as drawn: to the centimetre (the display channels; uavloc's own keep every bit).
fn cm(v: f64) -> f64 {
    (v * 100.0).round() / 100.0
}

/// Degrees as drawn: to 1e-7° (1 cm), as MAVLink's degE7.
fn deg7(v: f64) -> f64 {
    (v * 1e7).round() / 1e7
}

fn time(ns: u64) -> Value {
    json!({"sec": ns / 1_000_000_000, "nsec": ns % 1_000_000_000})
}

fn point(p: [f64; 2]) -> Option<[f64; 2]> {
    (p[0].is_finite() && p[1].is_finite()).then_some(p)
}

fn pair(v: &Value) -> Option<[f64; 2]> {
    point([v.get(0)?.as_f64()?, v.get(1)?.as_f64()?])
}

fn pairs(v: &Value) -> Vec<[f64; 2]> {
    v.as_array().map(|a| a.iter().filter_map(pair).collect()).unwrap_or_default()
}

fn pose(p: [f64; 2], heading: f64) -> Value {
    let h = 0.5 * heading;
    json!({"position": {"x": cm(p[0]), "y": cm(p[1]), "z": 0.0}, "orientation": {"x": 0.0, "y": 0.0, "z": h.sin(), "w": h.cos()}})
}

fn sphere(p: [f64; 2], size: f64, c: [f64; 3]) -> Value {
    json!({"pose": pose(p, 0.0), "size": {"x": size, "y": size, "z": size}, "color": colour(c, 1.0)})
}

fn line(points: &[[f64; 2]], kind: u8, thickness: f64, c: [f64; 3]) -> Value {
    json!({
        "type": kind, "pose": pose([0.0, 0.0], 0.0), "thickness": thickness, "scale_invariant": true,
        "points": points.iter().map(|p| json!({"x": cm(p[0]), "y": cm(p[1]), "z": 0.0})).collect::<Vec<_>>(),
        "color": colour(c, 1.0), "colors": [], "indices": [],
    })
}

fn entity(stamp: &Value, id: &str, spheres: Vec<Value>, lines: Vec<Value>) -> Value {
    json!({
        "timestamp": stamp, "frame_id": LOCAL_FRAME, "id": id, "lifetime": {"sec": 0, "nsec": 0},
        "frame_locked": false, "metadata": [], "arrows": [], "cubes": [], "spheres": spheres, "cylinders": [],
        "lines": lines, "triangles": [], "texts": [], "models": [],
    })
}

impl FoxgloveView {
    /// The view of a run of `scenario` (the map channels only when it has an origin).
    pub fn new(scenario: &Scenario) -> Self {
        Self {
            frame: scenario.frame(),
            l_min: scenario.l_min,
            tracks: Vec::new(),
            truth: None,
            drawn_truth: None,
            drawn_estimate: None,
        }
    }

    /// The Foxglove messages of one recorded uavloc message (its topic and JSON, see
    /// `crate::recording`): nothing for most; for an estimate the map, the scene and the frames of its
    /// step; for a truth its map point. Values that are not finite (a failed estimate) draw nothing, nor
    /// does a step already drawn from the same topic.
    pub fn derive(&mut self, topic: &str, msg: &Value) -> Vec<FoxgloveMessage> {
        let ns = msg["stamps"]["published_ns"].as_u64().unwrap_or(0);
        match topic {
            "/truth" if first_drawing(&mut self.drawn_truth, msg) => {
                self.truth = pair(&msg["position"]);
                let (Some(frame), Some(z)) = (&self.frame, self.truth) else { return Vec::new() };
                location_fix(frame, z, None, None, ns, TRUTH_COLOUR)
                    .map(|json| vec![FoxgloveMessage { topic: TRUTH_TOPIC, schema: LOCATION_FIX, json }])
                    .unwrap_or_default()
            }
            "/estimate" if first_drawing(&mut self.drawn_estimate, msg) => self.of_estimate(msg, ns),
            _ => Vec::new(),
        }
    }

    fn of_estimate(&mut self, msg: &Value, ns: u64) -> Vec<FoxgloveMessage> {
        let uavs = pairs(&msg["uavs"]);
        let headings: Vec<f64> =
            msg["headings"].as_array().map(|a| a.iter().filter_map(Value::as_f64).collect()).unwrap_or_default();
        let estimate = pair(&msg["position"]);
        let cov = msg["covariance"].as_array().and_then(|rows| {
            let r0 = pair(rows.first()?)?;
            let r1 = pair(rows.get(1)?)?;
            Some([r0, r1])
        });
        if let Some(step) = msg["step"].as_u64()
            && !uavs.is_empty()
        {
            // Newer than every step drawn so far (`first_drawing`): the track stays in step order.
            self.tracks.push((step, uavs.clone()));
        }
        let ellipse = estimate.zip(cov).and_then(|(z, m)| confidence_ellipse(z, m, ELLIPSE_PROBABILITY, RING_POINTS));
        let standoff = estimate.map(|z| circle(z, self.l_min, RING_POINTS));
        // The map layer's tracks, thinned to at most MAP_TRACK_POINTS each (the message is re-sent whole
        // every step; the LocationFix channels carry every point).
        let picked: Vec<usize> = thinned(self.tracks.len(), MAP_TRACK_POINTS).collect();
        let tracks: Vec<Vec<[f64; 2]>> = (0..uavs.len())
            .map(|i| picked.iter().filter_map(|&k| self.tracks[k].1.get(i).copied()).collect())
            .collect();
        // The scene's track grows by one segment per step: an entity of its own, kept by Foxglove (lifetime
        // 0), so no message holds the whole track.
        let step = msg["step"].as_u64().unwrap_or(0);
        let segment = |i: usize| -> Option<Vec<[f64; 2]>> {
            let at = self.tracks.partition_point(|(k, _)| *k < step);
            let before = self.tracks[..at].last()?.1.get(i).copied()?;
            Some(vec![before, *uavs.get(i)?])
        };
        let mut out = Vec::new();
        if let Some(frame) = &self.frame {
            for (i, p) in uavs.iter().enumerate().take(UAV_TOPICS.len()) {
                let course = headings.get(i).map(|h| course_deg(*h).to_radians());
                if let Some(json) = location_fix(frame, *p, None, course, ns, COLOURS[i]) {
                    out.push(FoxgloveMessage { topic: UAV_TOPICS[i], schema: LOCATION_FIX, json });
                }
            }
            if let Some(json) = estimate.and_then(|z| location_fix(frame, z, cov, None, ns, ESTIMATE_COLOUR)) {
                out.push(FoxgloveMessage { topic: ESTIMATE_TOPIC, schema: LOCATION_FIX, json });
            }
            let geojson = geojson(frame, &tracks, ellipse.as_deref(), standoff.as_deref(), self.truth);
            out.push(FoxgloveMessage {
                topic: GEOJSON_TOPIC,
                schema: GEOJSON,
                json: json!({"geojson": geojson.to_string()}),
            });
        }
        let stamp = time(ns);
        let mut entities: Vec<Value> = uavs
            .iter()
            .enumerate()
            .flat_map(|(i, p)| {
                let colour = COLOURS[i % COLOURS.len()];
                let uav = entity(&stamp, &format!("uav{i}"), vec![sphere(*p, 300.0, colour)], Vec::new());
                let track = segment(i).map(|seg| {
                    entity(&stamp, &format!("uav{i}-track-{step}"), Vec::new(), vec![line(&seg, 0, 2.0, colour)])
                });
                std::iter::once(uav).chain(track)
            })
            .collect();
        if let Some(z) = estimate {
            let mut lines = Vec::new();
            if let Some(ring) = &ellipse {
                lines.push(line(ring, 0, 2.0, ESTIMATE_COLOUR));
            }
            if let Some(ring) = &standoff {
                lines.push(line(ring, 0, 1.0, [0.6, 0.0, 0.0]));
            }
            entities.push(entity(&stamp, "estimate", vec![sphere(z, 300.0, ESTIMATE_COLOUR)], lines));
        }
        if let Some(z) = self.truth {
            entities.push(entity(&stamp, "truth", vec![sphere(z, 200.0, TRUTH_COLOUR)], Vec::new()));
        }
        out.push(FoxgloveMessage {
            topic: SCENE_TOPIC,
            schema: SCENE_UPDATE,
            json: json!({"deletions": [], "entities": entities}),
        });
        for (i, p) in uavs.iter().enumerate() {
            let h = 0.5 * headings.get(i).copied().filter(|h| h.is_finite()).unwrap_or(0.0);
            out.push(FoxgloveMessage {
                topic: TF_TOPIC,
                schema: FRAME_TRANSFORM,
                json: json!({
                    "timestamp": stamp, "parent_frame_id": LOCAL_FRAME, "child_frame_id": format!("uav{i}"),
                    "translation": {"x": cm(p[0]), "y": cm(p[1]), "z": 0.0},
                    "rotation": {"x": 0.0, "y": 0.0, "z": h.sin(), "w": h.cos()},
                }),
            });
        }
        out
    }
}

/// Points of a track in one map layer, at most.
pub const MAP_TRACK_POINTS: usize = 60;
/// Points of a drawn ellipse or circle (closed with the first again).
pub const RING_POINTS: usize = 32;

/// The indices of at most `most` of `len` points, evenly spaced, the first and the last kept.
fn thinned(len: usize, most: usize) -> impl Iterator<Item = usize> {
    let last = len.saturating_sub(1);
    let all = len <= most || most < 2;
    let n = if all { len } else { most };
    (0..n).map(move |k| if all { k } else { (k * last).div_ceil(most - 1).min(last) })
}

/// A `foxglove.LocationFix` at `p` in the plane (altitude: the origin's), with `cov` (the plane's 2×2
/// in m², east/north) as a known ENU covariance, `course` in radians clockwise from north.
fn location_fix(
    frame: &LocalFrame,
    p: [f64; 2],
    cov: Option<[[f64; 2]; 2]>,
    course: Option<f64>,
    ns: u64,
    c: [f64; 3],
) -> Option<Value> {
    let at = frame.to_geodetic(p).ok()?;
    let (covariance, kind) = match cov {
        Some(m) => (vec![m[0][0], m[0][1], 0.0, m[1][0], m[1][1], 0.0, 0.0, 0.0, 0.0], 3),
        None => (vec![0.0; 9], 0),
    };
    let mut fix = json!({
        "timestamp": time(ns), "frame_id": LOCAL_FRAME, "latitude": at.lat_deg, "longitude": at.lon_deg,
        "altitude": frame.origin().alt_m, "position_covariance": covariance, "position_covariance_type": kind,
        "color": colour(c, 1.0),
    });
    if let Some(course) = course.filter(|c| c.is_finite()) {
        fix["heading"] = json!(course);
    }
    Some(fix)
}

/// The map layer: the tracks (LineStrings), the ellipse and the L_min circle (Polygons) and the truth
/// (a Point); GeoJSON coordinates are `[lon, lat]`.
fn geojson(
    frame: &LocalFrame,
    tracks: &[Vec<[f64; 2]>],
    ellipse: Option<&[[f64; 2]]>,
    standoff: Option<&[[f64; 2]]>,
    truth: Option<[f64; 2]>,
) -> Value {
    let lon_lat = |points: &[[f64; 2]]| -> Option<Vec<[f64; 2]>> {
        points.iter().map(|p| frame.to_geodetic(*p).ok().map(|q| [deg7(q.lon_deg), deg7(q.lat_deg)])).collect()
    };
    let feature =
        |name: String, geometry: Value| json!({"type": "Feature", "properties": {"name": name}, "geometry": geometry});
    let mut features = Vec::new();
    for (i, track) in tracks.iter().enumerate() {
        if let Some(coords) = lon_lat(track).filter(|c| c.len() >= 2) {
            features.push(feature(format!("UAV {i} track"), json!({"type": "LineString", "coordinates": coords})));
        }
    }
    for (name, ring) in [("95 % ellipse", ellipse), ("L_min circle", standoff)] {
        if let Some(coords) = ring.and_then(lon_lat) {
            features.push(feature(name.to_string(), json!({"type": "Polygon", "coordinates": [coords]})));
        }
    }
    if let Some(coords) = truth.and_then(|z| lon_lat(&[z])) {
        features.push(feature("emitter (truth)".to_string(), json!({"type": "Point", "coordinates": coords[0]})));
    }
    json!({"type": "FeatureCollection", "features": features})
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_long_track_is_thinned_evenly_keeping_its_ends() {
        let t: Vec<usize> = thinned(1000, 256).collect();
        assert_eq!(t.len(), 256);
        assert_eq!((t[0], t[255]), (0, 999));
        assert!(t.windows(2).all(|w| w[1] > w[0]), "in order, no repeats");
        assert_eq!(thinned(10, 256).collect::<Vec<_>>(), (0..10).collect::<Vec<_>>());
        assert_eq!(thinned(0, 256).count(), 0);
    }

    fn estimate_json(step: u64, z: Option<[f64; 2]>) -> Value {
        json!({
            "step": step, "seq": step, "stamps": {"published_ns": 1_500_000_000u64 + step},
            "uavs": [[1500.0, 500.0], [10000.0, 1500.0], [5000.0, 8500.0]], "headings": [0.0, 1.0, 2.0],
            "position": z.map_or(json!([null, null]), |z| json!(z)),
            "covariance": [[400.0, 100.0], [100.0, 900.0]],
        })
    }

    fn with_origin() -> Scenario {
        Scenario::from_toml_str(include_str!("../../scenarios/geo.toml")).unwrap()
    }

    #[test]
    fn an_estimate_draws_the_uavs_the_estimate_and_the_map_layer() {
        let mut view = FoxgloveView::new(&with_origin());
        assert!(view.derive("/truth", &json!({"position": [25000.0, 15000.0], "stamps": {}})).len() == 1);
        view.derive("/estimate", &estimate_json(0, Some([24000.0, 14000.0])));
        let out = view.derive("/estimate", &estimate_json(1, Some([24500.0, 14500.0])));
        let topics: Vec<&str> = out.iter().map(|m| m.topic).collect();
        assert_eq!(
            topics,
            ["/map/uav0", "/map/uav1", "/map/uav2", "/map/estimate", "/map/geojson", "/scene", "/tf", "/tf", "/tf"]
        );
        let fix = &out[3].json;
        assert_eq!(fix["position_covariance"][4], 900.0);
        assert_eq!(fix["position_covariance_type"], 3);
        assert_eq!(fix["timestamp"], json!({"sec": 1, "nsec": 500_000_001}));
        // UAV 1 heads 1 rad counter-clockwise from east: its course is 90° − 57.3° clockwise from north.
        assert!((out[1].json["heading"].as_f64().unwrap() - (std::f64::consts::FRAC_PI_2 - 1.0)).abs() < 1e-12);
        let layer: Value = serde_json::from_str(out[4].json["geojson"].as_str().unwrap()).unwrap();
        let names: Vec<&str> =
            layer["features"].as_array().unwrap().iter().map(|f| f["properties"]["name"].as_str().unwrap()).collect();
        assert_eq!(
            names,
            ["UAV 0 track", "UAV 1 track", "UAV 2 track", "95 % ellipse", "L_min circle", "emitter (truth)"]
        );
        // A track is [lon, lat] and has one point per step seen; the polygons close.
        let track = layer["features"][0]["geometry"]["coordinates"].as_array().unwrap();
        assert_eq!(track.len(), 2);
        assert!((track[0][0].as_f64().unwrap() - 8.565_470_406).abs() < 1e-8, "lon first");
        let ring = layer["features"][4]["geometry"]["coordinates"][0].as_array().unwrap();
        assert_eq!(ring.first(), ring.last());
        // The scene: each UAV, its track's newest segment (an entity of its own), the estimate.
        let ids: Vec<&str> =
            out[5].json["entities"].as_array().unwrap().iter().map(|e| e["id"].as_str().unwrap()).collect();
        assert_eq!(ids, ["uav0", "uav0-track-1", "uav1", "uav1-track-1", "uav2", "uav2-track-1", "estimate", "truth"]);
        // A step seen again (a retry, a replay after a restart) draws nothing again, from either topic; the
        // next step adds one point to the track.
        assert!(view.derive("/estimate", &estimate_json(1, Some([24500.0, 14500.0]))).is_empty());
        assert!(view.derive("/estimate", &estimate_json(0, Some([24000.0, 14000.0]))).is_empty());
        let truth = |k: u64| json!({"step": k, "position": [25000.0, 15000.0], "stamps": {}});
        assert_eq!(view.derive("/truth", &truth(1)).len(), 1);
        assert!(view.derive("/truth", &truth(1)).is_empty());
        let next = view.derive("/estimate", &estimate_json(2, Some([24600.0, 14600.0])));
        let layer: Value = serde_json::from_str(next[4].json["geojson"].as_str().unwrap()).unwrap();
        assert_eq!(layer["features"][0]["geometry"]["coordinates"].as_array().unwrap().len(), 3);
    }

    #[test]
    fn without_an_origin_only_the_local_scene_and_without_a_fix_no_estimate() {
        let mut view = FoxgloveView::new(&Scenario::default());
        let out = view.derive("/estimate", &estimate_json(0, Some([24000.0, 14000.0])));
        let topics: Vec<&str> = out.iter().map(|m| m.topic).collect();
        assert_eq!(topics, ["/scene", "/tf", "/tf", "/tf"]);
        let mut view = FoxgloveView::new(&with_origin());
        let out = view.derive("/estimate", &estimate_json(0, None));
        assert!(out.iter().all(|m| m.topic != ESTIMATE_TOPIC));
        let scene = &out.iter().find(|m| m.topic == SCENE_TOPIC).unwrap().json;
        assert_eq!(scene["entities"].as_array().unwrap().len(), 3, "the UAVs only (no track before step 1)");
        assert!(view.derive("/measurement", &json!({})).is_empty());
    }
}
