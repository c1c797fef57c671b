//! `uavloc map FILE.mcap`: the map of a run placed on the Earth (a scenario with an `[origin]`), drawn
//! from its recording's map layer — the figure of Foxglove's Map panel without Foxglove.

use std::path::PathBuf;

use clap::Args;
use record::recording::read_recording;
use serde::Serialize;

use crate::error::CliError;
use crate::output::{Report, Table};

pub const LONG_ABOUT: &str = "\
Draw the map of a recorded run placed on the Earth (a scenario with an [origin], recorded with
--record FILE.mcap): the UAVs' tracks, the estimate's 95 % ellipse, the L_min circle around it and the
true emitter, on latitude/longitude axes at equal ground scale. It draws the last map layer of the
recording (its /map/geojson channel, the one Foxglove's Map panel shows), so a recording of a run
cut short draws as far as it went. The format follows the extension of --out: .png or .svg.";

pub const AFTER_HELP: &str = "\
Examples:
  uavloc simulate --scenario scenarios/geo.toml --record run.mcap
  uavloc map run.mcap --out map.png
  uavloc launch --scenario scenarios/geo.toml --record run.mcap && uavloc map run.mcap --out map.svg

Exit codes: 0 the map is written; 2 a file that is not a uavloc recording, is damaged (the byte offset
is named), or holds no map layer (its run had no [origin]); 1 the figure could not be written.";

/// Flags of `uavloc map`.
#[derive(Args, Debug, Clone, PartialEq)]
pub struct MapArgs {
    /// The recording (`--record FILE.mcap` of `simulate` or `launch`).
    #[arg(value_name = "FILE.mcap")]
    pub file: PathBuf,
    /// The figure to write (.png or .svg).
    #[arg(long, value_name = "FILE", default_value = "map.png")]
    pub out: PathBuf,
}

/// What was drawn.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MapReport {
    /// The figure written.
    pub written: PathBuf,
    /// The step of the layer drawn.
    pub step: u64,
    /// Its features (tracks, ellipse, L_min circle, truth).
    pub features: Vec<String>,
}

impl Report for MapReport {
    fn table(&self) -> Table {
        Table::new()
            .row("map of step", self.step.to_string())
            .row("features", self.features.join(", "))
            .row("wrote", self.written.display().to_string())
    }
}

/// Draws the map of `args.file` into `args.out`.
pub fn run(args: &MapArgs) -> Result<MapReport, CliError> {
    let recording = read_recording(&args.file).map_err(|e| CliError::input_because("the recording", e))?;
    let (step, text) = recording
        .messages
        .iter()
        .rev()
        .find(|m| m.topic == record::foxglove::GEOJSON_TOPIC)
        .and_then(|m| Some((m.json["stamps"]["step"].as_u64().unwrap_or(0), m.json["geojson"].as_str()?.to_string())))
        .ok_or_else(|| {
            CliError::Input(format!(
                "{}: no map layer ({}): the run had no [origin] (see scenarios/geo.toml)",
                args.file.display(),
                record::foxglove::GEOJSON_TOPIC
            ))
        })?;
    let layer: serde_json::Value = serde_json::from_str(&text)
        .map_err(|e| CliError::input_because(format!("{}: the map layer", args.file.display()), e))?;
    let features: Vec<String> = layer["features"]
        .as_array()
        .map(|f| f.iter().filter_map(|f| f["properties"]["name"].as_str().map(str::to_string)).collect())
        .unwrap_or_default();
    let steps =
        recording.messages.iter().filter(|m| m.topic == "/estimate").filter_map(|m| m.json["step"].as_u64()).max();
    let title = format!(
        "{} — step {}",
        args.file.file_name().map_or("map".into(), |n| n.to_string_lossy()),
        steps.unwrap_or(step)
    );
    record::map::plot_map(&layer, &title, &args.out)
        .map_err(|e| CliError::failed_because(format!("--out {}", args.out.display()), e))?;
    Ok(MapReport { written: args.out.clone(), step: steps.unwrap_or(step), features })
}
