//! Plots and exports of a run record: files written, their shape and content, robustness to missing or
//! non-finite values, empty records and bad paths; and the generic charts (`record::chart`: curves
//! with bands, grouped bars) — texts, element counts, colours, sizes, bad values, mismatched inputs.
//!
//! Set `UAVLOC_PLOT_CHECK_DIR=/some/dir` to keep a rendered set of figures for a visual check.

use std::fs;
use std::path::{Path, PathBuf};

use record::export::RUN_FILES;
use record::png::Raster;
use record::{
    BarGroup, ExportError, Metric, PlotError, RunRecord, Series, StepRecord, plot_bars, plot_comparison, plot_curves,
    plot_metrics, plot_trajectories, write_run, write_steps_csv, write_trajectory_csv,
};

const WIDTH: u32 = 900;
const HEIGHT: u32 = 700;
const UAV0_RGB: [u8; 3] = [0x1f, 0x77, 0xb4];

/// A fresh, empty directory for one test (removed by `done`).
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("uavloc-monitor-plots-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    dir
}

fn done(dir: &Path) {
    let _ = fs::remove_dir_all(dir);
}

/// A synthetic run: 3 UAVs flying `n` steps of 500 m towards the emitter of the paper's scenario, with
/// CRLB falling from ~2 km, estimates converging to the truth, the RMSE missing at step 2, the objective
/// value missing at step 1 and on the last step (nothing planned).
fn synthetic(n: usize, objective: &str, solver: &str, seed: u64) -> RunRecord {
    let scenario = model::Scenario::default();
    let emitter = scenario.emitter;
    let mut uavs = scenario.uavs.clone();
    let steps = (0..n)
        .map(|k| {
            let headings: Vec<f64> = uavs
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    // Towards the emitter, with a per-UAV sway so that the paths are not straight.
                    (emitter[1] - p[1]).atan2(emitter[0] - p[0]) + 0.25 * ((k as f64) * 0.4 + i as f64).sin()
                })
                .collect();
            let crlb = 2000.0 * 0.8f64.powi(k as i32) + 20.0;
            let wobble = crlb * ((k as f64) * 1.7).sin();
            let step = StepRecord {
                step: k as u64,
                geo: None,
                uavs: uavs.clone(),
                headings_rad: headings.clone(),
                estimate: [emitter[0] + wobble, emitter[1] - 0.5 * wobble],
                estimate_cov: [[crlb * crlb, 0.0], [0.0, crlb * crlb]],
                estimate_status: "ok".to_owned(),
                estimate_velocity: None,
                estimate_velocity_cov: None,
                truth: None,
                estimate_error_m: None,
                nees: None,
                pcrlb_m: None,
                min_true_distance_m: None,
                crlb_true_m: Some(crlb),
                crlb_at_estimate_m: None,
                pcrlb_at_estimate_m: None,
                rmse_m: (k != 2).then_some(1.2 * crlb + 5.0 * (k as f64).cos()),
                objective_value: (k != 1 && k + 1 != n).then_some(0.9 * crlb),
                plan_ms: (k + 1 != n).then_some(3.5 + k as f64),
                active_constraints: match k {
                    0 => vec![],
                    1 => vec!["d_min".to_owned()],
                    _ => vec!["d_min".to_owned(), "l_min".to_owned()],
                },
                planner: None,
                criterion_ess: None,
                range_sigmas_m: None,
                estimator: None,
                safety: None,
                receiver: None,
            };
            for (p, h) in uavs.iter_mut().zip(&headings) {
                p[0] += 500.0 * h.cos();
                p[1] += 500.0 * h.sin();
            }
            step
        })
        .collect();
    RunRecord::new(scenario, (objective, solver), seed, Some(emitter), "snapshot", steps)
}

fn read(path: &Path) -> String {
    fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Splits a CSV line into cells, honouring RFC 4180 quotes.
fn cells(line: &str) -> Vec<String> {
    let mut out = vec![String::new()];
    let mut quoted = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                chars.next();
                out.last_mut().unwrap().push('"');
            }
            ('"', _) => quoted = !quoted,
            (',', false) => out.push(String::new()),
            (c, _) => out.last_mut().unwrap().push(c),
        }
    }
    out
}

/// The value of attribute `name` in the element text `el`.
fn attr<'a>(el: &'a str, name: &str) -> Option<&'a str> {
    let key = format!(" {name}=\"");
    let at = el.find(&key)? + key.len();
    Some(&el[at..at + el[at..].find('"')?])
}

/// The stroke colours of the data lines of an SVG: its `<polyline>`s 2 px wide (axes and ticks are
/// 1 px polylines).
fn data_line_strokes(svg: &str) -> Vec<String> {
    svg.split("<polyline")
        .skip(1)
        .map(|el| &el[..el.find('>').unwrap()])
        .filter(|el| attr(el, "stroke-width") == Some("2"))
        .map(|el| attr(el, "stroke").expect("polyline without stroke").to_owned())
        .collect()
}

/// Checks the PNG signature and IHDR size, decodes it and returns the RGB image.
fn check_png(path: &Path) -> Raster {
    let bytes = fs::read(path).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{}: not a PNG", path.display());
    assert_eq!(&bytes[12..16], b"IHDR");
    let width = u32::from_be_bytes(bytes[16..20].try_into().unwrap());
    let height = u32::from_be_bytes(bytes[20..24].try_into().unwrap());
    assert_eq!((width, height), (WIDTH, HEIGHT), "{}", path.display());
    let img = record::png::read(path).unwrap();
    assert_eq!(img.dimensions(), (WIDTH, HEIGHT));
    let first = img.pixel(0, 0);
    assert!(img.pixels().any(|(_, _, p)| p != first), "{}: a single colour", path.display());
    img
}

/// Pixels within `tol` (per channel) of `rgb` in rows `rows`.
fn count_near(img: &Raster, rgb: [u8; 3], tol: u8, rows: std::ops::Range<u32>) -> usize {
    img.pixels().filter(|(_, y, p)| rows.contains(y) && p.iter().zip(rgb).all(|(&a, b)| a.abs_diff(b) <= tol)).count()
}

#[test]
fn write_run_writes_the_seven_files() {
    let dir = scratch("seven").join("nested/run");
    let run = synthetic(5, "mc", "pso", 7);
    let paths = write_run(&run, &dir).unwrap();
    let expected: Vec<PathBuf> = RUN_FILES.iter().map(|f| dir.join(f)).collect();
    assert_eq!(paths, expected);
    for name in [
        "trajectory.csv",
        "steps.csv",
        "trajectories.svg",
        "trajectories.png",
        "metrics.svg",
        "metrics.png",
        "run.json",
    ] {
        let len = fs::metadata(dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}")).len();
        assert!(len > 100, "{name}: {len} bytes");
    }
    // The JSON is the record (serde_json's default float parsing may be off by one ulp).
    let back: RunRecord = serde_json::from_str(&read(&dir.join("run.json"))).unwrap();
    assert_eq!((&back.objective, &back.solver, back.seed, back.steps.len()), (&run.objective, &run.solver, 7, 5));
    for (b, r) in back.steps.iter().zip(&run.steps) {
        assert_eq!(
            (b.step, &b.estimate_status, &b.active_constraints),
            (r.step, &r.estimate_status, &r.active_constraints)
        );
        assert_eq!(
            (b.rmse_m.is_some(), b.objective_value.is_some()),
            (r.rmse_m.is_some(), r.objective_value.is_some())
        );
        for (pb, pr) in b.uavs.iter().zip(&r.uavs) {
            assert!((pb[0] - pr[0]).abs() < 1e-9 && (pb[1] - pr[1]).abs() < 1e-9);
        }
        assert!((b.crlb_true_m.unwrap() - r.crlb_true_m.unwrap()).abs() < 1e-9);
    }
    done(&dir);
}

#[test]
fn trajectory_svg_has_one_line_per_uav_and_the_labels() {
    let dir = scratch("traj-svg");
    let run = synthetic(5, "mc", "pso", 7);
    let path = dir.join("t.svg");
    plot_trajectories(&run, &path).unwrap();
    let svg = read(&path);
    assert!(svg.starts_with("<svg"), "{}", &svg[..40]);
    let strokes = data_line_strokes(&svg);
    assert_eq!(strokes.len(), 3, "one polyline per UAV: {strokes:?}");
    let mut distinct = strokes.clone();
    distinct.sort();
    distinct.dedup();
    assert_eq!(distinct.len(), 3, "each UAV its own colour: {strokes:?}");
    assert!(strokes[0].eq_ignore_ascii_case("#1F77B4"), "{strokes:?}");
    for text in ["UAV0", "UAV1", "UAV2", "x (m)", "y (m)", "mc / pso, seed 7", "true emitter", "estimates"] {
        assert!(svg.contains(text), "missing {text:?}");
    }
    assert!(!svg.contains("UAV3"));
    assert!(!svg.contains("NaN"));
    done(&dir);
}

#[test]
fn trajectory_png_is_a_drawn_image_of_the_right_size() {
    let dir = scratch("traj-png");
    let run = synthetic(5, "mc", "pso", 7);
    let path = dir.join("t.png");
    plot_trajectories(&run, &path).unwrap();
    let img = check_png(&path);
    // UAV0's path is drawn in its colour, and the title (top strip) has dark text pixels: the embedded
    // font was rasterised.
    assert!(count_near(&img, UAV0_RGB, 12, 0..HEIGHT) > 50, "UAV0's path not drawn");
    assert!(count_near(&img, [0, 0, 0], 60, 0..32) > 100, "no title text");
    done(&dir);
}

#[test]
fn metrics_and_comparison_pngs_are_drawn() {
    let dir = scratch("metrics-png");
    let run = synthetic(5, "mc", "pso", 7);
    plot_metrics(&run, &dir.join("m.png")).unwrap();
    let img = check_png(&dir.join("m.png"));
    assert!(count_near(&img, UAV0_RGB, 12, 0..HEIGHT) > 50, "CRLB line not drawn");
    let other = synthetic(5, "single", "ga", 7);
    plot_comparison(&[&run, &other], Metric::Rmse, &dir.join("c.png")).unwrap();
    check_png(&dir.join("c.png"));
    done(&dir);
}

#[test]
fn metrics_axis_is_log_only_for_a_wide_range() {
    let dir = scratch("metrics-log");
    let wide = synthetic(12, "mc", "pso", 1); // CRLB 2020 m → ~190 m, RMSE ~2400 m → ~230 m
    plot_metrics(&wide, &dir.join("wide.svg")).unwrap();
    let svg = read(&dir.join("wide.svg"));
    assert!(svg.contains("log scale"), "a factor > 10 gets a log axis");
    assert!(svg.contains("CRLB (snapshot)") && svg.contains("RMSE") && svg.contains("PCRLB"));
    assert!(svg.contains("step") && svg.contains("error (m)"));
    // Two lines, the RMSE broken at step 2 (its None): 1 CRLB polyline + 2 RMSE polylines.
    assert_eq!(data_line_strokes(&svg).len(), 3);

    let mut narrow = synthetic(3, "mc", "pso", 1);
    for s in &mut narrow.steps {
        s.crlb_true_m = Some(50.0 + s.step as f64);
        s.rmse_m = Some(60.0);
    }
    plot_metrics(&narrow, &dir.join("narrow.svg")).unwrap();
    let svg = read(&dir.join("narrow.svg"));
    assert!(!svg.contains("log scale"));
    assert_eq!(data_line_strokes(&svg).len(), 2);
    done(&dir);
}

#[test]
fn comparison_labels_each_run() {
    let dir = scratch("comparison");
    let a = synthetic(6, "mc", "pso", 1);
    let b = synthetic(6, "analytical", "ga", 1);
    let c = synthetic(6, "mc", "pso", 2);
    let path = dir.join("c.svg");
    plot_comparison(&[&a, &b, &c], Metric::CrlbTrue, &path).unwrap();
    let svg = read(&path);
    assert!(svg.contains("analytical/ga"));
    // Two runs share "mc/pso": they are told apart by their seeds.
    assert!(svg.contains("mc/pso, seed 1") && svg.contains("mc/pso, seed 2"));
    assert!(svg.contains("CRLB at the truth per step"));
    assert_eq!(data_line_strokes(&svg).len(), 3);

    // No runs: an empty but valid figure.
    plot_comparison(&[], Metric::Rmse, &dir.join("none.svg")).unwrap();
    let svg = read(&dir.join("none.svg"));
    assert!(svg.contains("(no runs)") && data_line_strokes(&svg).is_empty());
    done(&dir);
}

fn step_safety(certified: bool) -> record::StepSafety {
    record::StepSafety {
        certified: Some(certified),
        min_pair_m: Some(812.5),
        standoff_margin_m: Some(40.0),
        min_true_distance_m: None,
    }
}

#[test]
fn csv_tables_have_one_row_per_step_and_empty_cells_for_none() {
    let dir = scratch("csv");
    let mut run = synthetic(5, "mc", "pso", 7);
    run.steps[3].active_constraints.push("turn, UAV1".to_owned()); // needs quoting
    for (k, certified) in [(0, true), (1, false)] {
        run.steps[k].safety = Some(step_safety(certified));
    }
    write_trajectory_csv(&run, &dir.join("trajectory.csv")).unwrap();
    write_steps_csv(&run, &dir.join("steps.csv")).unwrap();

    let traj = read(&dir.join("trajectory.csv"));
    let lines: Vec<&str> = traj.lines().collect();
    assert_eq!(lines[0], "step,uav,x_m,y_m,heading_rad");
    assert_eq!(lines.len(), 1 + 5 * 3);
    let row = cells(lines[1 + 3 + 2]); // step 1, UAV2
    assert_eq!(row.len(), 5);
    assert_eq!((row[0].as_str(), row[1].as_str()), ("1", "2"));
    assert_eq!(row[2].parse::<f64>().unwrap(), run.steps[1].uavs[2][0]);
    assert_eq!(row[4].parse::<f64>().unwrap(), run.steps[1].headings_rad[2]);

    let steps = read(&dir.join("steps.csv"));
    let lines: Vec<&str> = steps.lines().collect();
    assert_eq!(
        lines[0],
        "step,crlb_true_m,rmse_m,estimate_x_m,estimate_y_m,estimate_status,objective_value_m,plan_ms,active_constraints,\
         pcrlb_m,estimate_error_m,nees,min_true_distance_m,estimate_cov_xx_m2,estimate_cov_xy_m2,estimate_cov_yy_m2,crlb_at_estimate_m,\
         pcrlb_at_estimate_m,certified,min_pair_m,standoff_margin_m,min_true_distance_along_m"
    );
    assert_eq!(lines.len(), 1 + 5);
    let rows: Vec<Vec<String>> = lines[1..].iter().map(|l| cells(l)).collect();
    assert!(rows.iter().all(|r| r.len() == 22), "{rows:?}");
    // The safety columns: the planner's word and the margins along the arcs; empty on the last step.
    assert_eq!(rows[0][18], "true", "{:?}", rows[0]);
    assert_eq!(rows[1][18], "false", "{:?}", rows[1]);
    assert_eq!(rows[0][19].parse::<f64>().unwrap(), 812.5);
    assert!(rows[4][18..].iter().all(String::is_empty), "{:?}", rows[4]);
    // No truth in these records: the truth-based columns are empty, not zero.
    assert!(rows.iter().all(|r| r[9..13].iter().all(String::is_empty)), "{rows:?}");
    assert_eq!(rows[2][2], "", "rmse None at step 2");
    assert_ne!(rows[3][2], "");
    assert_eq!(rows[1][6], "", "objective None at step 1");
    assert_eq!(rows[0][6].parse::<f64>().unwrap(), run.steps[0].objective_value.unwrap());
    assert_eq!((rows[4][6].as_str(), rows[4][7].as_str()), ("", ""), "nothing planned on the last step");
    assert_eq!(rows[0][8], "");
    assert_eq!(rows[2][8], "d_min;l_min");
    assert_eq!(rows[3][8], "d_min;l_min;turn, UAV1");
    assert!(lines[4].contains(",\"d_min;l_min;turn, UAV1\","), "{}", lines[4]);
    assert_eq!(rows[4][5], "ok");
    done(&dir);
}

#[test]
fn unknown_extensions_are_errors() {
    let dir = scratch("ext");
    let run = synthetic(3, "mc", "pso", 7);
    for name in ["t.pdf", "t", "t.svg.txt"] {
        let path = dir.join(name);
        let err = plot_trajectories(&run, &path).unwrap_err();
        assert!(matches!(err, PlotError::UnsupportedFormat { .. }), "{err:?}");
        assert!(err.to_string().contains(name), "{err}");
        assert!(matches!(plot_metrics(&run, &path), Err(PlotError::UnsupportedFormat { .. })));
        assert!(matches!(plot_comparison(&[&run], Metric::Rmse, &path), Err(PlotError::UnsupportedFormat { .. })));
        assert!(!path.exists());
    }
    // Upper-case extensions are fine.
    plot_trajectories(&run, &dir.join("T.SVG")).unwrap();
    done(&dir);
}

/// Decision: a record with zero steps is not an error; it exports header-only CSVs and empty but valid
/// figures (axes, legend, title marked "(no steps)").
#[test]
fn a_record_without_steps_gives_empty_but_valid_files() {
    let dir = scratch("empty");
    let mut run = synthetic(0, "mc", "pso", 3);
    assert!(run.steps.is_empty());
    write_run(&run, &dir).unwrap();
    assert_eq!(read(&dir.join("trajectory.csv")), "step,uav,x_m,y_m,heading_rad\n");
    assert_eq!(read(&dir.join("steps.csv")).lines().count(), 1);
    for svg in ["trajectories.svg", "metrics.svg"] {
        let svg = read(&dir.join(svg));
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
        assert!(svg.contains("(no steps)"));
        assert!(data_line_strokes(&svg).is_empty());
    }
    check_png(&dir.join("trajectories.png"));
    check_png(&dir.join("metrics.png"));

    // Not even a finite emitter: still a figure.
    run.emitter = Some([f64::NAN, f64::INFINITY]);
    plot_trajectories(&run, &dir.join("nothing.png")).unwrap();
    check_png(&dir.join("nothing.png"));
    done(&dir);
}

#[test]
fn non_finite_values_are_skipped() {
    let dir = scratch("nonfinite");
    let mut run = synthetic(6, "mc", "pso", 7);
    run.steps[2].uavs[1] = [f64::NAN, 3000.0];
    run.steps[3].estimate = [f64::INFINITY, f64::NAN];
    run.steps[4].estimate = [1.0e9, -1.0e9]; // a wild but finite estimate: off-chart
    run.steps[1].crlb_true_m = Some(f64::INFINITY); // singular geometry
    run.steps[4].rmse_m = Some(f64::NAN);
    for name in ["t.svg", "t.png"] {
        plot_trajectories(&run, &dir.join(name)).unwrap();
    }
    for name in ["m.svg", "m.png"] {
        plot_metrics(&run, &dir.join(name)).unwrap();
    }
    let svg = read(&dir.join("t.svg"));
    assert_eq!(data_line_strokes(&svg).len(), 3, "UAV1 keeps one line without its NaN point");
    assert!(!svg.to_ascii_lowercase().contains("nan") && !svg.contains("inf\""));
    assert!(svg.contains("estimates (1 off-chart)"));
    let metrics = read(&dir.join("m.svg"));
    assert!(!metrics.to_ascii_lowercase().contains("nan"));
    check_png(&dir.join("t.png"));
    check_png(&dir.join("m.png"));
    // A wholly non-finite metric series leaves an empty but valid chart.
    for s in &mut run.steps {
        s.crlb_true_m = Some(f64::NAN);
        s.rmse_m = None;
    }
    plot_metrics(&run, &dir.join("m2.png")).unwrap();
    check_png(&dir.join("m2.png"));
    plot_metrics(&run, &dir.join("m2.svg")).unwrap();
    let svg = read(&dir.join("m2.svg"));
    assert!(svg.contains("no data") && data_line_strokes(&svg).is_empty());
    done(&dir);
}

#[test]
fn export_errors_name_the_path() {
    let dir = scratch("errors");
    let blocker = dir.join("a-file");
    fs::write(&blocker, "not a directory").unwrap();
    let run = synthetic(2, "mc", "pso", 7);
    let err = write_run(&run, &blocker.join("run")).unwrap_err();
    assert!(matches!(err, ExportError::Io { .. }), "{err:?}");
    assert!(err.to_string().contains("a-file"), "{err}");
    let err = plot_trajectories(&run, &blocker.join("t.png")).unwrap_err();
    assert!(matches!(err, PlotError::Draw { .. }), "{err:?}");
    assert!(err.to_string().contains("a-file"), "{err}");
    done(&dir);
}

/// Renders a realistic set of figures — into `$UAVLOC_PLOT_CHECK_DIR` when set (kept, for looking at
/// them), else into a scratch directory — and checks each: a PNG of the figure size, three distinct data
/// lines in the three-run comparison, empty charts still valid.
#[test]
fn a_realistic_set_of_figures_renders() {
    let kept = std::env::var_os("UAVLOC_PLOT_CHECK_DIR").map(PathBuf::from);
    let dir = kept.clone().unwrap_or_else(|| scratch("visual"));
    fs::create_dir_all(&dir).unwrap();
    let run = synthetic(24, "mc", "pso", 1);
    write_run(&run, &dir).unwrap();
    let b = synthetic(24, "analytical", "ga", 1);
    let mut c = synthetic(24, "single", "aco", 1);
    for s in &mut c.steps {
        s.crlb_true_m = s.crlb_true_m.map(|c| c * 1.4);
    }
    plot_comparison(&[&run, &b, &c], Metric::CrlbTrue, &dir.join("comparison.png")).unwrap();
    plot_comparison(&[&run, &b, &c], Metric::CrlbTrue, &dir.join("comparison.svg")).unwrap();
    let strokes = data_line_strokes(&read(&dir.join("comparison.svg")));
    assert_eq!(strokes.len(), 3, "{strokes:?}");
    assert!(strokes[0] != strokes[1] && strokes[1] != strokes[2] && strokes[0] != strokes[2], "{strokes:?}");
    let mut narrow = synthetic(8, "mc", "pso", 1);
    for s in &mut narrow.steps {
        s.crlb_true_m = Some(50.0 + s.step as f64);
        s.rmse_m = (s.step != 3).then_some(62.0 - s.step as f64);
    }
    plot_metrics(&narrow, &dir.join("metrics-linear.png")).unwrap();
    plot_trajectories(&synthetic(0, "mc", "pso", 1), &dir.join("empty-trajectories.png")).unwrap();
    plot_metrics(&synthetic(0, "mc", "pso", 1), &dir.join("empty-metrics.png")).unwrap();
    for png in ["comparison.png", "metrics-linear.png", "empty-trajectories.png", "empty-metrics.png"] {
        check_png(&dir.join(png));
    }
    if kept.is_none() {
        done(&dir);
    }
}

// The generic charts.

/// Step numbers 0..n.
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
