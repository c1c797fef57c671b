//! MCAP recordings of a pipeline run: every valid message the monitor receives — measurement, estimate,
//! command, truth, control — as one MCAP message on the channel of its kind (`/measurement`, …),
//! JSON-encoded with a JSON schema per channel, so that Foxglove, the Python `mcap` package or any MCAP
//! reader opens the file without uavloc. Read back by [`read_recording`] (what `uavloc replay` runs on).
//!
//! - Each message's JSON has `step`, `seq`, `stamps` (the header's latency stamps, CLOCK_MONOTONIC ns)
//!   and the type's fields, per-UAV arrays trimmed to the `count` UAVs in use. Numbers are written so that
//!   they read back to the same `f64` bit for bit; a NaN (a failed estimate without a standing one) is
//!   `null`. `log_time` is when the monitor received the message, `publish_time` its `published_ns`.
//! - A metadata record `uavloc` holds the run: the scenario (JSON), steps, seed, domain and source.
//! - Beside these channels, messages in Foxglove's own schemas that its Map and 3D panels draw
//!   (`crate::foxglove`: the UAVs, the estimate with its ellipse, the tracks, the L_min circle).
//! - Messages are written unchunked and the file is flushed after every recorded step, so a monitor killed
//!   mid-run leaves a file whose messages up to the last flush are intact; the restarted monitor
//!   (`--resume`) copies them into a new file and records on (the summary and footer are written at the
//!   end). What a replay re-published is recorded again, as the monitor saw it on the wire.
//! - Reading walks the file record by record and names the byte offset of the first damaged one (a
//!   truncated or corrupt file is an error, not a shorter recording).

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Write as _};
use std::path::{Path, PathBuf};

use protocol::{Command, Control, ControlKind, Estimate, Measurement, Message, MessageKind, Stamps, Truth};
use serde_json::{Value, json};

use crate::foxglove::{FoxgloveSchema, FoxgloveView};

/// The MCAP channel (topic) of each message kind.
pub fn topic(kind: MessageKind) -> &'static str {
    match kind {
        MessageKind::Measurement => "/measurement",
        MessageKind::Estimate => "/estimate",
        MessageKind::Command => "/command",
        MessageKind::Truth => "/truth",
        MessageKind::Control => "/control",
        // Not recorded (the monitor's own answers to the estimator); named for completeness.
        MessageKind::State => "/state",
        // Not recorded (the bridge's 10 Hz report; the UAVs of each step are in its measurement).
        MessageKind::Swarm => "/swarm",
    }
}

/// The name of the metadata record that describes the run.
pub const METADATA_NAME: &str = "uavloc";

/// The `uavloc` metadata of a recording: the scenario (JSON), its steps and seed, the domain and the
/// measurement source.
pub fn run_metadata(scenario: &model::Scenario, domain: &str, source: &str) -> BTreeMap<String, String> {
    BTreeMap::from([
        ("scenario".to_string(), serde_json::to_string(scenario).unwrap_or_default()),
        ("steps".to_string(), scenario.steps.to_string()),
        ("seed".to_string(), scenario.seed.to_string()),
        ("domain".to_string(), domain.to_string()),
        ("source".to_string(), source.to_string()),
    ])
}

/// A message type as it is recorded: its JSON and its JSON schema's properties.
pub trait Recordable: Message {
    /// The message as JSON (see the module docs).
    fn to_json(&self) -> Value;
    /// The JSON schema properties of the type's own fields (besides `step`, `seq`, `stamps`).
    fn schema_properties() -> Value;
}

fn stamps_json(s: &Stamps) -> Value {
    json!({
        "published_ns": s.published_ns,
        "trigger_command_published_ns": s.trigger_command_published_ns,
        "trigger_command_received_ns": s.trigger_command_received_ns,
        "measurement_published_ns": s.measurement_published_ns,
        "measurement_received_ns": s.measurement_received_ns,
        "estimate_published_ns": s.estimate_published_ns,
        "estimate_received_ns": s.estimate_received_ns,
        "command_published_ns": s.command_published_ns,
    })
}

fn with_header<T: Message>(m: &T, mut fields: Value) -> Value {
    let h = m.header();
    fields["step"] = json!(h.step);
    fields["seq"] = json!(h.seq);
    fields["stamps"] = stamps_json(&h.stamps);
    fields
}

const NUMBERS: &str = r#"{"type": "array", "items": {"type": ["number", "null"]}}"#;
const POINTS: &str = r#"{"type": "array", "items": {"type": "array", "items": {"type": ["number", "null"]}, "minItems": 2, "maxItems": 2}}"#;

fn numbers() -> Value {
    serde_json::from_str(NUMBERS).expect("schema")
}
fn points() -> Value {
    serde_json::from_str(POINTS).expect("schema")
}
fn integer() -> Value {
    json!({"type": "integer", "minimum": 0})
}
fn string() -> Value {
    json!({"type": "string"})
}

impl Recordable for Measurement {
    fn to_json(&self) -> Value {
        with_header(
            self,
            json!({"count": self.count, "uavs": self.uavs(),
                   "heard": (0..self.len()).filter(|&i| self.has_heard(i)).collect::<Vec<_>>(),
                   "silent": self.is_silent(),
                   "arrivals": (0..self.len()).map(|i| self.has_heard(i).then(|| self.arrivals[i])).collect::<Vec<_>>(),
                   "sigmas": self.sigmas(), "headings": self.headings(),
                   "position_sigmas": self.position_sigmas(), "position_bias_sigmas": self.position_bias_sigmas(),
                   "clock_sigmas_ns": self.clock_sigmas_ns(), "clock_bias_sigmas_ns": self.clock_bias_sigmas_ns()}),
        )
    }
    fn schema_properties() -> Value {
        json!({"count": integer(), "uavs": points(), "heard": {"type": "array", "items": integer()},
               "silent": {"type": "boolean"}, "arrivals": {"type": "array", "items": {"type": ["number", "null"]}},
               "sigmas": numbers(), "headings": numbers(), "position_sigmas": numbers(),
               "position_bias_sigmas": numbers(), "clock_sigmas_ns": numbers(), "clock_bias_sigmas_ns": numbers()})
    }
}

impl Recordable for Estimate {
    fn to_json(&self) -> Value {
        with_header(
            self,
            json!({
                "instance": self.instance, "count": self.count,
                "status": self.status().map_or("unknown", |s| s.name()),
                "estimator": self.estimator_name(),
                "model": if self.model == 1 { "constant_velocity" } else { "static" },
                "rejected_run": self.rejected_run,
                "heard": (0..self.len()).filter(|&i| self.heard & (1u8 << i) != 0).collect::<Vec<_>>(),
                "outliers": (0..self.len()).filter(|&i| self.outliers & (1u8 << i) != 0).collect::<Vec<_>>(),
                "bias_cov": self.bias_cov,
                "position": self.position, "covariance": self.covariance,
                "uavs": self.uavs(), "headings": self.headings(),
                "velocity": self.velocity, "cross_cov": self.cross_cov, "velocity_cov": self.velocity_cov,
            }),
        )
    }
    fn schema_properties() -> Value {
        json!({
            "instance": integer(), "count": integer(), "status": string(),
            "estimator": {"type": ["string", "null"]}, "model": string(),
            "rejected_run": integer(), "heard": {"type": "array", "items": integer()},
            "outliers": {"type": "array", "items": integer()}, "bias_cov": points(), "position": numbers(), "covariance": points(), "uavs": points(),
            "headings": numbers(), "velocity": numbers(), "cross_cov": points(), "velocity_cov": points(),
        })
    }
}

impl Recordable for Command {
    fn to_json(&self) -> Value {
        with_header(
            self,
            json!({
                "planner_instance": self.planner_instance, "plan_time_us": self.plan_time_us,
                "active_constraints": self.active_constraints, "violated_constraints": self.violated_constraints,
                "count": self.count, "hold": self.is_hold(), "objective": self.objective,
                "certified": self.certified(),
                "headings": self.headings(), "waypoints": self.waypoints(),
                "solver": self.solver().unwrap_or("?"), "objective_name": self.objective_name().unwrap_or("?"),
            }),
        )
    }
    fn schema_properties() -> Value {
        json!({
            "planner_instance": integer(), "plan_time_us": integer(), "active_constraints": integer(),
            "violated_constraints": integer(), "count": integer(), "hold": {"type": "boolean"},
            "certified": {"type": ["boolean", "null"]},
            "objective": {"type": "number"}, "headings": numbers(), "waypoints": points(), "solver": string(),
            "objective_name": string(),
        })
    }
}

impl Recordable for Truth {
    fn to_json(&self) -> Value {
        let previous = match self.previous_command() {
            Some(protocol::CommandOutcome::Flown) => "flown",
            Some(protocol::CommandOutcome::Missed) => "missed",
            _ => "none",
        };
        let multipath: Vec<u32> = (0..8).filter(|i| self.multipath & (1 << i) != 0).collect();
        with_header(self, json!({"position": self.position, "previous_command": previous, "multipath": multipath}))
    }
    fn schema_properties() -> Value {
        json!({"position": numbers(), "previous_command": string(), "multipath": {"type": "array", "items": integer()}})
    }
}

impl Recordable for Control {
    fn to_json(&self) -> Value {
        with_header(
            self,
            json!({
                "instance": self.instance, "started_ns": self.started_ns,
                "kind": self.kind().map_or("unknown", ControlKind::name), "run": format!("{:016x}", self.run),
                "role": self.role().unwrap_or("?"), "detail": self.detail(),
            }),
        )
    }
    fn schema_properties() -> Value {
        json!({
            "instance": integer(), "started_ns": integer(), "kind": string(), "run": string(), "role": string(),
            "detail": string(),
        })
    }
}

/// The JSON schema of `T`'s recorded JSON.
pub fn schema_of<T: Recordable>() -> Value {
    let mut properties = T::schema_properties();
    properties["step"] = integer();
    properties["seq"] = integer();
    properties["stamps"] = json!({"type": "object", "additionalProperties": {"type": "integer"}});
    json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": T::TYPE_NAME,
        "type": "object",
        "properties": properties,
        "required": ["step", "seq", "stamps"],
    })
}

/// A message read back from a recording.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedMessage {
    /// Its channel (`/measurement`, …).
    pub topic: String,
    /// When the monitor received it, CLOCK_MONOTONIC ns.
    pub log_time: u64,
    /// Its JSON (see the module docs).
    pub json: Value,
}

/// A recording read back: the run's metadata and every message in file order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Recording {
    /// The `uavloc` metadata record (empty if absent).
    pub metadata: BTreeMap<String, String>,
    /// The messages, in the order they were written.
    pub messages: Vec<RecordedMessage>,
}

/// Writes a recording (see the module docs).
pub struct Recorder {
    path: PathBuf,
    writer: mcap::Writer<BufWriter<File>>,
    channels: BTreeMap<&'static str, u16>,
    sequence: u32,
    error: Option<String>,
    /// Foxglove's channels, derived from the recorded messages (absent when the metadata holds no
    /// scenario).
    view: Option<FoxgloveView>,
}

impl std::fmt::Debug for Recorder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Recorder").field("path", &self.path).finish_non_exhaustive()
    }
}

fn channel_of<T: Recordable>(
    writer: &mut mcap::Writer<BufWriter<File>>,
    channels: &mut BTreeMap<&'static str, u16>,
) -> mcap::McapResult<u16> {
    let topic = topic(T::KIND);
    if let Some(id) = channels.get(topic) {
        return Ok(*id);
    }
    let schema = serde_json::to_vec(&schema_of::<T>()).expect("a JSON value");
    let schema_id = writer.add_schema(T::TYPE_NAME, "jsonschema", &schema)?;
    let id = writer.add_channel(schema_id, topic, "json", &BTreeMap::new())?;
    channels.insert(topic, id);
    Ok(id)
}

/// The channel of a Foxglove topic, declared with its published schema on first use.
fn foxglove_channel(
    writer: &mut mcap::Writer<BufWriter<File>>,
    channels: &mut BTreeMap<&'static str, u16>,
    topic: &'static str,
    schema: FoxgloveSchema,
) -> mcap::McapResult<u16> {
    if let Some(id) = channels.get(topic) {
        return Ok(*id);
    }
    let schema_id = writer.add_schema(schema.name, "jsonschema", schema.json_schema.as_bytes())?;
    let id = writer.add_channel(schema_id, topic, "json", &BTreeMap::new())?;
    channels.insert(topic, id);
    Ok(id)
}

impl Recorder {
    /// Creates the recording at `path` with the run's `metadata`. With `resume`, the messages of a
    /// recording already at `path` (a monitor's predecessor's, possibly cut short by a kill) are copied
    /// into the new file first.
    pub fn create(path: &Path, metadata: BTreeMap<String, String>, resume: bool) -> Result<Self, String> {
        let fail = |e: &dyn std::fmt::Display| format!("--mcap {}: {e}", path.display());
        let earlier = if resume && path.exists() {
            let bytes = std::fs::read(path).map_err(|e| fail(&e))?;
            let earlier = parse(&bytes, false).unwrap_or_default();
            // Another run's messages would make one recording of two runs.
            if let (Some(theirs), Some(ours)) = (earlier.metadata.get("scenario"), metadata.get("scenario"))
                && theirs != ours
            {
                return Err(fail(
                    &"the recording of another run (another scenario, steps or seed); give this run's \
                                  recording, or start without --resume",
                ));
            }
            earlier.messages
        } else {
            Vec::new()
        };
        let view = metadata
            .get("scenario")
            .and_then(|text| serde_json::from_str::<model::Scenario>(text).ok())
            .map(|scenario| FoxgloveView::new(&scenario));
        let file = File::create(path).map_err(|e| fail(&e))?;
        let options = mcap::WriteOptions::new()
            .compression(None)
            .use_chunks(false)
            .emit_message_indexes(false)
            .profile("")
            .library(concat!("uavloc ", env!("CARGO_PKG_VERSION")));
        let mut writer = options.create(BufWriter::new(file)).map_err(|e| fail(&with_causes(&e)))?;
        writer
            .write_metadata(&mcap::records::Metadata { name: METADATA_NAME.into(), metadata })
            .map_err(|e| fail(&with_causes(&e)))?;
        let mut r =
            Recorder { path: path.to_path_buf(), writer, channels: BTreeMap::new(), sequence: 0, error: None, view };
        for m in earlier {
            r.write_json(&m.topic, m.log_time, &m.json);
        }
        r.flush();
        r.check()?;
        Ok(r)
    }

    /// Records one message received at `received_ns`.
    pub fn record<T: Recordable>(&mut self, msg: &T, received_ns: u64) {
        let channel = channel_of::<T>(&mut self.writer, &mut self.channels);
        let json = msg.to_json();
        self.write(channel, received_ns, msg.header().stamps.published_ns, &json);
        self.write_foxglove(topic(T::KIND), received_ns, &json);
    }

    /// Writes the Foxglove messages derived from one uavloc message (see `crate::foxglove`).
    fn write_foxglove(&mut self, topic_name: &str, log_time: u64, json: &Value) {
        let Some(view) = self.view.as_mut() else { return };
        for m in view.derive(topic_name, json) {
            let channel = foxglove_channel(&mut self.writer, &mut self.channels, m.topic, m.schema);
            let published = json["stamps"]["published_ns"].as_u64().unwrap_or(0);
            self.write(channel, log_time, published, &m.json);
        }
    }

    /// Re-writes a message read back from an earlier recording (its type from its topic).
    fn write_json(&mut self, topic_name: &str, log_time: u64, json: &Value) {
        let channel = match topic_name {
            "/measurement" => channel_of::<Measurement>(&mut self.writer, &mut self.channels),
            "/estimate" => channel_of::<Estimate>(&mut self.writer, &mut self.channels),
            "/command" => channel_of::<Command>(&mut self.writer, &mut self.channels),
            "/truth" => channel_of::<Truth>(&mut self.writer, &mut self.channels),
            "/control" => channel_of::<Control>(&mut self.writer, &mut self.channels),
            // Foxglove's channels are derived again from the uavloc messages copied.
            _ => return,
        };
        self.write(channel, log_time, json["stamps"]["published_ns"].as_u64().unwrap_or(0), json);
        self.write_foxglove(topic_name, log_time, json);
    }

    /// Writes one message on `channel` (the first error is kept, and nothing is written after it).
    fn write(&mut self, channel: mcap::McapResult<u16>, log_time: u64, publish_time: u64, json: &Value) {
        if self.error.is_some() {
            return;
        }
        let data = serde_json::to_vec(json).expect("a JSON value");
        let result = channel.and_then(|channel_id| {
            self.sequence = self.sequence.wrapping_add(1);
            self.writer.write_to_known_channel(
                &mcap::records::MessageHeader { channel_id, sequence: self.sequence, log_time, publish_time },
                &data,
            )
        });
        if let Err(e) = result {
            self.error = Some(self.failed(&e));
        }
    }

    /// A write error naming the file, with its cause (the mcap crate's own message hides the I/O error's:
    /// "No space left on device" and the like).
    fn failed(&self, e: &dyn std::error::Error) -> String {
        format!("--mcap {}: {}", self.path.display(), with_causes(e))
    }

    /// Pushes what was recorded to the file (a kill after this loses none of it).
    pub fn flush(&mut self) {
        if self.error.is_none()
            && let Err(e) = self.writer.flush()
        {
            self.error = Some(self.failed(&e));
        }
    }

    /// The first write error, naming the file.
    pub fn check(&self) -> Result<(), String> {
        self.error.clone().map_or(Ok(()), Err)
    }

    /// Writes the summary and the footer and closes the file.
    pub fn finish(mut self) -> Result<(), String> {
        self.check()?;
        if let Err(e) = self.writer.finish() {
            return Err(self.failed(&e));
        }
        let path = self.path.clone();
        let mut inner = self.writer.into_inner();
        inner.flush().map_err(|e| format!("--mcap {}: {e}", path.display()))
    }
}

/// An error with its causes, `outer: inner: …`.
fn with_causes(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut source = e.source();
    while let Some(cause) = source {
        text.push_str(&format!(": {cause}"));
        source = cause.source();
    }
    text
}

/// A damaged recording: where and what.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{path}: {what} at byte offset {offset}")]
pub struct RecordingError {
    /// The file.
    pub path: String,
    /// The byte offset of the damage (of the record that cannot be read).
    pub offset: u64,
    /// What is wrong there.
    pub what: String,
}

const MAGIC: &[u8] = b"\x89MCAP0\r\n";
const OP_FOOTER: u8 = 0x02;
const OP_CHUNK: u8 = 0x06;

/// Reads the recording at `path`: an error names the byte offset of the first damaged record (a file
/// cut short, a corrupt record, a missing end), or the file if it cannot be read.
pub fn read_recording(path: &Path) -> Result<Recording, RecordingError> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| RecordingError {
        path: name.clone(),
        offset: 0,
        what: format!("cannot read it ({e})"),
    })?;
    parse(&bytes, true).map_err(|(offset, what)| RecordingError { path: name, offset, what })
}

/// Walks the records; `strict`: the file must end with a footer and the magic, else (a recording a killed
/// monitor left) the records before the first damage — a cut, a torn or corrupt record — are the result.
fn parse(bytes: &[u8], strict: bool) -> Result<Recording, (u64, String)> {
    if bytes.len() < MAGIC.len() || &bytes[..MAGIC.len()] != MAGIC {
        return Err((0, "not an MCAP file (no MCAP magic at the start)".into()));
    }
    let mut out = Recording::default();
    match walk(bytes, &mut out) {
        Ok(()) => Ok(out),
        Err(_) if !strict => Ok(out),
        Err(e) => Err(e),
    }
}

/// Reads the records after the magic into `out`, up to the footer; an error at the first damage (what
/// was read before it stays in `out`).
fn walk(bytes: &[u8], out: &mut Recording) -> Result<(), (u64, String)> {
    let mut topics: BTreeMap<u16, String> = BTreeMap::new();
    // Where the summary section starts (just after the DataEnd record).
    let mut summary_from = None::<usize>;
    let mut at = MAGIC.len();
    loop {
        let offset = at as u64;
        if at == bytes.len() {
            return Err((offset, "the file ends without a footer (cut short?)".into()));
        }
        if bytes.len() - at < 9 {
            return Err((offset, "a record header cut short (the file ends inside it)".into()));
        }
        let op = bytes[at];
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().expect("8 bytes"));
        let body_start = at + 9;
        let Some(body_end) = usize::try_from(len).ok().and_then(|l| body_start.checked_add(l)) else {
            return Err((offset, format!("a record (opcode {op:#04x}) claims an impossible length {len}")));
        };
        if body_end > bytes.len() {
            return Err((
                offset,
                format!(
                    "a record (opcode {op:#04x}) of {len} bytes cut short: the file ends {} bytes into it",
                    bytes.len() - body_start
                ),
            ));
        }
        let body = &bytes[body_start..body_end];
        if op == OP_CHUNK {
            return Err((offset, "a chunk: this reader takes the unchunked recordings uavloc writes".into()));
        }
        let record = mcap::read::parse_record(op, body)
            .map_err(|e| (offset, format!("a corrupt record (opcode {op:#04x}): {e}")))?;
        match record {
            mcap::records::Record::Channel(c) => {
                topics.insert(c.id, c.topic);
            }
            mcap::records::Record::Message { header, data } => {
                let topic = topics.get(&header.channel_id).cloned().ok_or_else(|| {
                    (offset, format!("a message on channel {} that was never declared", header.channel_id))
                })?;
                let json = serde_json::from_slice(&data)
                    .map_err(|e| (offset, format!("a message on {topic} that is not JSON: {e}")))?;
                out.messages.push(RecordedMessage { topic, log_time: header.log_time, json });
            }
            mcap::records::Record::Metadata(m) if m.name == METADATA_NAME => out.metadata = m.metadata,
            // The data section's CRC32 covers every byte before this record, the magic included (0: not
            // computed by the writer).
            mcap::records::Record::DataEnd(end) => {
                let crc = crc32fast::hash(&bytes[..at]);
                if end.data_section_crc != 0 && end.data_section_crc != crc {
                    return Err((
                        offset,
                        format!(
                            "the data section's CRC does not match (stored {:#010x}, computed {crc:#010x}): the \
                             bytes before this offset were changed",
                            end.data_section_crc
                        ),
                    ));
                }
                summary_from = Some(body_end);
            }
            // The summary's CRC32 covers the summary section and the footer up to its own field.
            mcap::records::Record::Footer(footer) if footer.summary_crc != 0 => {
                let from = summary_from.unwrap_or(at);
                let crc = crc32fast::hash(&bytes[from..body_start + 16]);
                if footer.summary_crc != crc {
                    return Err((
                        from as u64,
                        format!(
                            "the summary section's CRC does not match (stored {:#010x}, computed {crc:#010x})",
                            footer.summary_crc
                        ),
                    ));
                }
            }
            _ => {}
        }
        at = body_end;
        if op == OP_FOOTER {
            if bytes.get(at..) != Some(MAGIC) {
                return Err((at as u64, "no MCAP magic after the footer".into()));
            }
            return Ok(());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::Fix;

    const UAVS: [[f64; 2]; 3] = [[1500.0, 500.0], [10000.0, 1500.0], [5000.0, 8500.0]];

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("uavloc-mcap-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir.join("run.mcap")
    }

    fn measurement(k: u64) -> Measurement {
        Measurement::new(k, 100 + k, &UAVS, &[0.1 + 0.2, -4010.9], &[28.7712; 3], &[0.1, 0.2, 0.3]).unwrap()
    }

    #[test]
    fn a_command_records_its_safety_certificate() {
        let plan = protocol::PlanInfo {
            headings: &[0.1, 0.2, 0.3],
            waypoints: &UAVS,
            objective: 1.0,
            solver: "gradient",
            objective_name: "analytical",
            plan_time_us: 5,
            active_constraints: 0,
            violated_constraints: 0,
        };
        let mut c = Command::new(3, 4, 5, &plan).unwrap();
        assert!(c.to_json()["certified"].is_null(), "neither bit: not certified by design");
        for (flag, word) in [(Command::FLAG_CERTIFIED, true), (Command::FLAG_UNCERTIFIED, false)] {
            c.flags = flag;
            assert_eq!(c.to_json()["certified"].as_bool(), Some(word));
        }
        assert_eq!(Command::schema_properties()["certified"]["type"][0], "boolean");
    }

    #[test]
    fn an_estimate_records_the_estimator_that_made_it_and_none_before_a_fused_first_fix() {
        let fix = Fix::Ok { position: [100.0, 200.0], covariance: [[4.0, 0.0], [0.0, 9.0]] };
        let mut e = Estimate::new(2, 3, 4, &UAVS, &[0.1, 0.2, 0.3], fix).unwrap();
        assert_eq!(e.to_json()["estimator"], "snapshot");
        e.estimator = 1;
        assert_eq!(e.to_json()["estimator"], "fused");
        // A fused estimator's failed step before its first fix carries the wire's 0 ("no posterior"):
        // recorded as no estimator, not as the snapshot estimator's.
        let failed = Estimate::new(2, 3, 4, &UAVS, &[0.1, 0.2, 0.3], Fix::Failed).unwrap();
        assert!(failed.to_json()["estimator"].is_null(), "{}", failed.to_json());
        assert_eq!(Estimate::schema_properties()["estimator"]["type"][1], "null");
    }

    #[test]
    fn what_is_recorded_reads_back_bit_for_bit_with_its_metadata() {
        let path = scratch("roundtrip");
        let meta = BTreeMap::from([("steps".to_string(), "2".to_string())]);
        let mut r = Recorder::create(&path, meta.clone(), false).unwrap();
        r.record(&measurement(0), 11);
        let failed = Estimate::from_measurement(&measurement(0), 12, 1, 7, Fix::Failed).unwrap();
        r.record(&failed, 13);
        r.record(&measurement(1), 14);
        r.finish().unwrap();
        let back = read_recording(&path).unwrap();
        assert_eq!(back.metadata, meta);
        let topics: Vec<&str> = back.messages.iter().map(|m| m.topic.as_str()).collect();
        assert_eq!(topics, ["/measurement", "/estimate", "/measurement"]);
        let m = &back.messages[0].json;
        assert_eq!(m["arrivals"][1].as_f64().unwrap().to_bits(), (0.1f64 + 0.2).to_bits());
        assert_eq!(m["heard"], json!([0, 1, 2]));
        assert_eq!(m["uavs"].as_array().unwrap().len(), 3, "trimmed to the UAVs in use");
        assert_eq!(back.messages[0].log_time, 11);
        let e = &back.messages[1].json;
        assert_eq!((e["status"].as_str(), e["position"][0].is_null()), (Some("failed"), true), "NaN is null");
        std::fs::remove_dir_all(path.parent().unwrap()).ok();
    }

    /// One changed digit in a recorded range difference still parses as a valid message: only the data
    /// section's CRC tells. Every byte of the data section is covered, and so is the summary's.
    #[test]
    fn a_changed_byte_anywhere_is_refused_by_its_crc() {
        let path = scratch("crc");
        let mut r = Recorder::create(&path, BTreeMap::new(), false).unwrap();
        for k in 0..3 {
            r.record(&measurement(k), k);
        }
        r.finish().unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert!(read_recording(&path).is_ok());
        let digit = bytes.windows(7).position(|w| w == b"-4010.9").expect("the recorded range difference") + 3;
        let mut changed = bytes.clone();
        changed[digit] = if changed[digit] == b'1' { b'2' } else { b'1' };
        std::fs::write(&path, &changed).unwrap();
        let e = read_recording(&path).unwrap_err();
        assert!(e.what.contains("data section's CRC"), "{e}");
        assert!(e.offset > digit as u64, "the DataEnd record, after the change: {e}");
        // The last byte before the footer's CRC field, in the summary section (or the footer itself).
        let footer_crc = bytes.len() - MAGIC.len() - 4;
        let mut changed = bytes.clone();
        changed[footer_crc - 1] ^= 0x01;
        std::fs::write(&path, &changed).unwrap();
        let e = read_recording(&path).unwrap_err();
        assert!(e.what.contains("CRC"), "{e}");
        std::fs::remove_dir_all(path.parent().unwrap()).ok();
    }

    #[test]
    fn a_cut_or_corrupt_file_is_an_error_naming_the_offset_and_a_resume_keeps_what_was_flushed() {
        let path = scratch("damage");
        let mut r = Recorder::create(&path, BTreeMap::new(), false).unwrap();
        for k in 0..5 {
            r.record(&measurement(k), k);
        }
        r.finish().unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let cut = bytes.len() - 40;
        std::fs::write(&path, &bytes[..cut]).unwrap();
        let e = read_recording(&path).unwrap_err();
        assert!(e.offset > 0 && e.offset < cut as u64, "{e}");
        assert!(e.to_string().contains("byte offset"), "{e}");
        // A flipped opcode in the middle: a corrupt record at its offset.
        let mut bad = bytes.clone();
        let mut first_message = MAGIC.len();
        while bytes[first_message] != 0x05 {
            let len = u64::from_le_bytes(bytes[first_message + 1..first_message + 9].try_into().unwrap());
            first_message += 9 + len as usize;
        }
        bad[first_message + 1] = 0xff; // its length: now beyond the end of the file
        std::fs::write(&path, &bad).unwrap();
        let e = read_recording(&path).unwrap_err();
        assert_eq!(e.offset, first_message as u64, "{e}");
        std::fs::write(&path, b"not mcap").unwrap();
        assert_eq!(read_recording(&path).unwrap_err().offset, 0);
        // A monitor killed after 3 messages; its successor resumes the file and records on.
        let mut r = Recorder::create(&path, BTreeMap::new(), false).unwrap();
        for k in 0..3 {
            r.record(&measurement(k), k);
        }
        r.flush();
        std::mem::forget(r); // killed: no footer
        assert!(read_recording(&path).is_err(), "no footer");
        let mut r = Recorder::create(&path, BTreeMap::new(), true).unwrap();
        r.record(&measurement(3), 3);
        r.finish().unwrap();
        let steps: Vec<u64> =
            read_recording(&path).unwrap().messages.iter().map(|m| m.json["step"].as_u64().unwrap()).collect();
        assert_eq!(steps, [0, 1, 2, 3]);
        // Killed in the middle of writing a record (its buffer flushed in part): the records before the
        // tear are kept, the torn one is not (before, nothing of the earlier recording was kept).
        let mut r = Recorder::create(&path, BTreeMap::new(), false).unwrap();
        for k in 0..3 {
            r.record(&measurement(k), k);
        }
        r.flush();
        std::mem::forget(r);
        let whole = std::fs::read(&path).unwrap();
        std::fs::write(&path, &whole[..whole.len() - 30]).unwrap();
        let mut r = Recorder::create(&path, BTreeMap::new(), true).unwrap();
        r.record(&measurement(2), 2);
        r.finish().unwrap();
        let steps: Vec<u64> =
            read_recording(&path).unwrap().messages.iter().map(|m| m.json["step"].as_u64().unwrap()).collect();
        assert_eq!(steps, [0, 1, 2]);
        // A resume into the recording of another run (other metadata) is refused, the file left as it was.
        let run = |seed: &str| BTreeMap::from([("scenario".to_string(), format!("{{\"seed\":{seed}}}"))]);
        Recorder::create(&path, run("1"), false).unwrap().finish().unwrap();
        let before = std::fs::read(&path).unwrap();
        let e = Recorder::create(&path, run("2"), true).map(|_| ()).unwrap_err();
        assert!(e.contains("another run") && e.contains("run.mcap"), "{e}");
        assert_eq!(std::fs::read(&path).unwrap(), before);
        Recorder::create(&path, run("1"), true).unwrap().finish().unwrap();
        std::fs::remove_dir_all(path.parent().unwrap()).ok();
    }
}
