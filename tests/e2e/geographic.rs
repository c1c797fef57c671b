//! Runs placed on the Earth (`[origin]`, positions as latitude/longitude): the nominal run placed at an
//! origin is the same run in the plane bit for bit, its outputs give every position as latitude/longitude
//! too, and the recording of a pipeline run carries Foxglove's map and 3D channels, each message valid
//! against Foxglove's published JSON schemas (from the npm registry) as read back by the Python `mcap`
//! package.

use crate::common;

use std::path::Path;
use std::process::Command;

use common::{Launch, domain, foxglove_schemas, json_of, python, scratch};
use serde_json::Value;

const GEO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/geo.toml");
const NOMINAL: &str = include_str!("../../scenarios/nominal.toml");

/// A step without its latitude/longitude and its planning time (a wall-clock measurement).
fn in_the_plane(step: &Value) -> Value {
    let mut s = step.clone();
    let s_ = s.as_object_mut().unwrap();
    s_.remove("geo");
    s_.remove("plan_ms");
    s
}

#[test]
fn the_nominal_run_placed_at_an_origin_is_the_same_run_in_the_plane() {
    let _scenario = common::scenario(module_path!());
    let dir = scratch("geo-same");
    let placed = dir.join("placed.toml");
    std::fs::write(&placed, format!("{NOMINAL}\n[origin]\nlat_deg = 47.3977\nlon_deg = 8.5456\nalt_m = 488.0\n"))
        .unwrap();
    let plain = json_of(&["simulate", "--json"]);
    let run = json_of(&["simulate", "--json", "--scenario", placed.to_str().unwrap()]);
    let (a, b) = (plain["steps"].as_array().unwrap(), run["steps"].as_array().unwrap());
    assert_eq!(a.len(), b.len());
    for (k, (x, y)) in a.iter().zip(b).enumerate() {
        assert!(x.get("geo").is_none(), "no origin, no latitude/longitude");
        assert_eq!(in_the_plane(y), in_the_plane(x), "step {k}: the same run in the plane, bit for bit");
    }
    // The latitude/longitude of the placed run are those geo.toml gives (its positions in degrees).
    let given = json_of(&["simulate", "--json", "--steps", "1", "--scenario", GEO]);
    let at = |run: &Value, what: &str| run["steps"][0]["geo"][what].clone();
    for (p, q) in
        at(&run, "uavs_lat_lon_deg").as_array().unwrap().iter().zip(at(&given, "uavs_lat_lon_deg").as_array().unwrap())
    {
        for c in 0..2 {
            assert!((p[c].as_f64().unwrap() - q[c].as_f64().unwrap()).abs() < 1e-8, "{p} vs {q}");
        }
    }
    let last = &b.last().unwrap()["geo"];
    assert_eq!(last["ellipse_95_lat_lon_deg"].as_array().unwrap().len(), 65, "a closed 64-point polygon");
    assert!(last["truth_lat_lon_deg"][0].as_f64().unwrap() > 47.5);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_pipeline_recording_draws_on_foxglove_map_and_3d_panels() {
    let _scenario = common::scenario(module_path!());
    let dir = scratch("geo-foxglove");
    let file = dir.join("run.mcap");
    let out = dir.join("out");
    let steps = 6u64;
    let d = domain("geo", "fox");
    let run = Launch::start(
        &d,
        &dir,
        &[
            "--scenario",
            GEO,
            "--steps",
            &steps.to_string(),
            "--record",
            file.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
    )
    .finish_json();

    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/python/check_foxglove.py");
    let res = Command::new(python()).arg(script).arg(&file).arg(foxglove_schemas()).output().expect("run the checker");
    let read: Value = serde_json::from_slice(&res.stdout)
        .unwrap_or_else(|e| panic!("not JSON ({e}): {}", String::from_utf8_lossy(&res.stderr)));
    assert!(res.status.success(), "invalid Foxglove messages: {read}");
    let topics = &read["topics"];
    for (topic, schema, count) in [
        ("/map/uav0", "foxglove.LocationFix", steps + 1),
        ("/map/uav2", "foxglove.LocationFix", steps + 1),
        ("/map/estimate", "foxglove.LocationFix", steps + 1),
        ("/map/truth", "foxglove.LocationFix", steps + 1),
        ("/map/geojson", "foxglove.GeoJSON", steps + 1),
        ("/scene", "foxglove.SceneUpdate", steps + 1),
        ("/tf", "foxglove.FrameTransform", 3 * (steps + 1)),
    ] {
        let t = &topics[topic];
        assert_eq!((t["schema"].as_str(), t["count"].as_u64()), (Some(schema), Some(count)), "{topic}: {topics}");
        assert_eq!((t["invalid"].as_u64(), t["schema_as_published"].as_bool()), (Some(0), Some(true)), "{topic}");
        assert_eq!((t["message_encoding"].as_str(), t["schema_encoding"].as_str()), (Some("json"), Some("jsonschema")));
    }
    // The map draws the run's own numbers: the last estimate where run.json puts it, and its covariance.
    let last = run["steps"].as_array().unwrap().last().unwrap();
    let fix = &read["last_fix"]["/map/estimate"];
    let (lat, lon) = (
        last["geo"]["estimate_lat_lon_deg"][0].as_f64().unwrap(),
        last["geo"]["estimate_lat_lon_deg"][1].as_f64().unwrap(),
    );
    assert_eq!((fix["latitude"].as_f64(), fix["longitude"].as_f64()), (Some(lat), Some(lon)));
    assert_eq!(fix["position_covariance"][0], last["estimate_cov"][0][0]);
    let names: Vec<&str> = read["features"].as_array().unwrap().iter().map(|f| f["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["UAV 0 track", "UAV 1 track", "UAV 2 track", "95 % ellipse", "L_min circle", "emitter (truth)"]);
    let track = &read["features"][0]["coordinates"];
    assert_eq!(track.as_array().unwrap().len() as u64, steps + 1, "one point per step");
    // GeoJSON is [lon, lat], drawn to 1e-7° (1 cm).
    let start = &run["steps"][0]["geo"]["uavs_lat_lon_deg"][0];
    let near = |a: &Value, b: &Value| (a.as_f64().unwrap() - b.as_f64().unwrap()).abs() <= 0.6e-7;
    assert!(near(&track[0][0], &start[1]) && near(&track[0][1], &start[0]), "{track} vs {start}");
    // The map of the recording (what Foxglove's Map panel draws), as a figure.
    let map = dir.join("map.svg");
    let drawn = common::json_of(&["--json", "map", file.to_str().unwrap(), "--out", map.to_str().unwrap()]);
    assert_eq!(drawn["step"], steps, "{drawn}");
    let svg = std::fs::read_to_string(&map).unwrap();
    assert!(svg.contains("UAV 2") && svg.contains("latitude"), "the map's legend and axes");
    // The CSV files give latitude/longitude columns.
    let csv = std::fs::read_to_string(out.join("trajectory.csv")).unwrap();
    assert!(csv.starts_with("step,uav,x_m,y_m,heading_rad,lat_deg,lon_deg\n"), "{csv}");
    let steps_csv = std::fs::read_to_string(out.join("steps.csv")).unwrap();
    assert!(steps_csv.lines().next().unwrap().ends_with(",estimate_lat_deg,estimate_lon_deg"));
    std::fs::remove_dir_all(&dir).ok();
}
