//! `uavloc replay FILE.mcap`: the estimator and the planner run again on the measurements of a recorded
//! run (`uavloc launch --record`), open loop — the UAVs are where they flew — and each step's new estimate
//! and plan are set beside the recorded ones. The way to compare estimators or planners on recorded
//! flights: with the recorded settings the estimates come out exactly as recorded.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use clap::Args;
use estimation::{EmitterModel, Estimator, EstimatorConfig, EstimatorKind};
use model::Scenario;
use planning::{ObjectiveKind, PlanRequest, SolverKind, plan_step};
use protocol::{Estimate, EstimateStatus, Measurement};
use record::recording::{RecordedMessage, read_recording};
use serde::Serialize;
use serde_json::Value;

use crate::error::CliError;
use crate::output::{Report, Table};

pub const LONG_ABOUT: &str = "\
Run the estimator and the planner again on the measurements of a recorded run (`uavloc launch --record
FILE.mcap`) and set each step's new estimate and plan beside the recorded ones. Open loop: the UAVs are
where they flew in the recording, whatever the new plans say — the way to compare estimators, objectives
or solvers on the same recorded flight.

Without flags the recorded settings are used (the scenario stored in the file; for each step the
objective and solver of its recorded command — a run whose planner was swapped is replayed with each
planner on its own steps; a step without a recorded command takes the settings of the last one before
it), and the estimates come out exactly as recorded (`estimates_equal` =
`estimates_compared`). A step measured more than once in the file (a replay after a crash) is taken
once, as first recorded.

A file that is not an MCAP recording of uavloc, or is cut short or corrupt, is refused with the byte
offset of the damage (exit 2).";

pub const AFTER_HELP: &str = "\
Examples:
  uavloc launch --headless --steps 24 --record run.mcap
  uavloc replay run.mcap
  uavloc replay run.mcap --estimator snapshot --json
  uavloc replay run.mcap --objective single --solver ga";

/// Flags of `uavloc replay`.
#[derive(Args, Debug, Clone, PartialEq)]
pub struct ReplayArgs {
    /// The recording (`uavloc launch --record FILE.mcap`).
    #[arg(value_name = "FILE.mcap")]
    pub file: PathBuf,
    /// The estimator: fused | snapshot (default: the recorded scenario's).
    #[arg(long, value_name = "KIND")]
    pub estimator: Option<EstimatorKind>,
    /// The fused estimator's emitter model: static | constant_velocity (default: the recorded one).
    #[arg(long, value_name = "MODEL")]
    pub emitter_model: Option<EmitterModel>,
    /// Planning objective (default: the recorded commands').
    #[arg(long, value_name = "NAME")]
    pub objective: Option<ObjectiveKind>,
    /// Solver: gradient | pso | ga | aco (default: the recorded commands').
    #[arg(long, value_name = "NAME")]
    pub solver: Option<SolverKind>,
}

/// One estimate, recorded or replayed.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EstimateView {
    /// `ok`, `ambiguous`, `rejected` or `failed`.
    pub status: String,
    /// ẑ, metres (a failed estimate: the standing one; `null` before any).
    pub estimate: [Option<f64>; 2],
    /// Its covariance, m².
    pub covariance: [[Option<f64>; 2]; 2],
}

/// One step of the replay.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReplayStep {
    /// The step.
    pub step: u64,
    /// The recorded estimate (`null` if none was recorded).
    pub recorded: Option<EstimateView>,
    /// The estimate of the replay.
    pub replayed: EstimateView,
    /// Whether the two are equal bit for bit (status, estimate, covariance).
    pub estimate_equal: bool,
    /// |ẑ_replayed − ẑ_recorded|, metres (`null` when either is missing).
    pub estimate_delta_m: Option<f64>,
    /// The recorded command's headings, radians (`null` on the last step, or if none was recorded).
    pub recorded_headings: Option<Vec<f64>>,
    /// The replay's planned headings (`null` on the last step, or with nothing to plan from).
    pub replayed_headings: Option<Vec<f64>>,
    /// The planner it was replayed with, `solver/objective` (`null` on the last step, which is not
    /// planned).
    pub planner: Option<String>,
    /// The largest heading difference, radians (wrapped to [0, π]).
    pub heading_delta_rad: Option<f64>,
}

/// The replay of one recording.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReplayReport {
    /// The recording.
    pub file: String,
    /// The estimator replayed with.
    pub estimator: String,
    /// The emitter model replayed with.
    pub emitter_model: String,
    /// The objective replayed with; several in the order first used, joined by ` → `, when the recording's
    /// planner changed (a swap) and no `--objective` was given.
    pub objective: String,
    /// The solver replayed with (several as `objective`).
    pub solver: String,
    /// Steps replayed.
    pub steps: u64,
    /// Steps with a recorded estimate to compare with.
    pub estimates_compared: u64,
    /// Of them, equal bit for bit.
    pub estimates_equal: u64,
    /// The largest estimate difference, metres.
    pub max_estimate_delta_m: Option<f64>,
    /// Steps with a recorded and a replayed plan.
    pub plans_compared: u64,
    /// Of them, with the same headings bit for bit.
    pub plans_equal: u64,
    /// The largest heading difference, radians.
    pub max_heading_delta_rad: Option<f64>,
    /// Per step.
    pub per_step: Vec<ReplayStep>,
}

fn f64s(v: &Value, what: &str, step: u64) -> Result<Vec<f64>, CliError> {
    let bad = || CliError::Input(format!("step {step}: the recorded {what} is not a list of numbers"));
    v.as_array()
        .ok_or_else(bad)?
        .iter()
        .map(|x| if x.is_null() { Ok(f64::NAN) } else { x.as_f64().ok_or_else(bad) })
        .collect()
}

fn pairs(v: &Value, what: &str, step: u64) -> Result<Vec<[f64; 2]>, CliError> {
    let bad = || CliError::Input(format!("step {step}: the recorded {what} are not [x, y] pairs"));
    v.as_array()
        .ok_or_else(bad)?
        .iter()
        .map(|p| match f64s(p, what, step)?.as_slice() {
            [x, y] => Ok([*x, *y]),
            _ => Err(bad()),
        })
        .collect()
}

/// The measurement a recorded JSON describes (the wire message, number for number): the arrivals of the
/// UAVs heard, or — a recording of an older layout — the range differences to UAV0.
fn measurement_of(json: &Value) -> Result<Measurement, CliError> {
    let step = json["step"].as_u64().ok_or_else(|| CliError::Input("a recorded measurement without a step".into()))?;
    let seq = json["seq"].as_u64().unwrap_or(0);
    let uavs = pairs(&json["uavs"], "UAV positions", step)?;
    let sigmas = f64s(&json["sigmas"], "sigmas", step)?;
    let headings = f64s(&json["headings"], "headings", step)?;
    let bad = |e| CliError::input_because(format!("step {step}: the recorded measurement"), e);
    if json.get("arrivals").is_none() {
        let diffs = f64s(&json["diffs"], "range differences", step)?;
        return Measurement::new(step, seq, &uavs, &diffs, &sigmas, &headings).map_err(bad);
    }
    let arrivals: Vec<f64> = f64s(&json["arrivals"], "arrivals", step)?;
    let mut heard = 0u8;
    for i in json["heard"].as_array().into_iter().flatten() {
        match i.as_u64() {
            Some(i) if (i as usize) < uavs.len() => heard |= 1u8 << i,
            _ => return Err(CliError::Input(format!("step {step}: the recorded heard list names no UAV: {i}"))),
        }
    }
    let arrivals: Vec<f64> = arrivals.iter().map(|a| if a.is_nan() { 0.0 } else { *a }).collect();
    let mut m = if json["silent"].as_bool() == Some(true) {
        Measurement::silent(step, seq, &uavs, &sigmas, &headings)
    } else {
        Measurement::heard(step, seq, &uavs, heard, &arrivals, &sigmas, &headings)
    }
    .map_err(bad)?;
    let n = m.len();
    for (key, field) in [
        ("position_sigmas", &mut m.position_sigmas),
        ("position_bias_sigmas", &mut m.position_bias_sigmas),
        ("clock_sigmas_ns", &mut m.clock_sigmas_ns),
        ("clock_bias_sigmas_ns", &mut m.clock_bias_sigmas_ns),
    ] {
        if json.get(key).is_some() {
            let v = f64s(&json[key], key, step)?;
            if v.len() != n {
                return Err(CliError::Input(format!(
                    "step {step}: the recorded {key} has {} values, not {n}",
                    v.len()
                )));
            }
            field[..n].copy_from_slice(&v);
        }
    }
    Ok(m)
}

fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

fn view_of_estimate(e: &Estimate) -> EstimateView {
    let (p, c) = (e.position, e.covariance);
    EstimateView {
        status: e.status().map_or("unknown", |s| s.name()).to_string(),
        estimate: [finite(p[0]), finite(p[1])],
        covariance: [[finite(c[0][0]), finite(c[0][1])], [finite(c[1][0]), finite(c[1][1])]],
    }
}

fn view_of_json(json: &Value, step: u64) -> Result<EstimateView, CliError> {
    let p = f64s(&json["position"], "estimate", step)?;
    let c = pairs(&json["covariance"], "covariance rows", step)?;
    if p.len() != 2 || c.len() != 2 {
        return Err(CliError::Input(format!("step {step}: the recorded estimate is not 2-D")));
    }
    Ok(EstimateView {
        status: json["status"].as_str().unwrap_or("unknown").to_string(),
        estimate: [finite(p[0]), finite(p[1])],
        covariance: [[finite(c[0][0]), finite(c[0][1])], [finite(c[1][0]), finite(c[1][1])]],
    })
}

/// The first message of each step on `topic`.
fn first_per_step<'a>(messages: &'a [RecordedMessage], topic: &str) -> BTreeMap<u64, &'a Value> {
    let mut out = BTreeMap::new();
    for m in messages.iter().filter(|m| m.topic == topic) {
        if let Some(step) = m.json["step"].as_u64() {
            out.entry(step).or_insert(&m.json);
        }
    }
    out
}

/// The objective and solver of each step's recorded command (from the command's `objective_name` and
/// `solver`); a name this uavloc does not know is an error naming the step and the flag to give instead.
fn recorded_planners(
    commands: &BTreeMap<u64, &Value>,
    file: &Path,
) -> Result<BTreeMap<u64, (ObjectiveKind, SolverKind)>, CliError> {
    let mut out = BTreeMap::new();
    for (&step, c) in commands {
        let name = |key: &str| c[key].as_str().unwrap_or_default().to_string();
        let unknown = |what: &str, name: String, flag: &str| {
            CliError::Input(format!(
                "{}: the recorded command of step {step} names the {what} `{name}`, which this uavloc does not know; \
                 give {flag}",
                file.display()
            ))
        };
        let objective =
            name("objective_name").parse().map_err(|_| unknown("objective", name("objective_name"), "--objective"))?;
        let solver = name("solver").parse().map_err(|_| unknown("solver", name("solver"), "--solver"))?;
        out.insert(step, (objective, solver));
    }
    Ok(out)
}

/// The estimator a recorded estimate comes from ([`Estimate::estimator_name`] of its JSON: `null` before
/// a fused estimator's first fix; a recording written before that rule names the wire's `estimator = 0`
/// "snapshot", which a fused estimator before its first fix sends too, so there a failed step's
/// "snapshot" does not tell).
fn estimator_of_recorded(estimate: &Value) -> Option<EstimatorKind> {
    let kind: EstimatorKind = estimate["estimator"].as_str()?.parse().ok()?;
    let failed = estimate["status"].as_str()? == EstimateStatus::Failed.name();
    (kind == EstimatorKind::Fused || !failed).then_some(kind)
}

/// `names`, each once in the order first seen, joined by ` → ` (one name when all are one).
fn in_order_used(names: impl Iterator<Item = &'static str>) -> String {
    let mut used: Vec<&str> = Vec::new();
    for name in names {
        if !used.contains(&name) {
            used.push(name);
        }
    }
    used.join(" → ")
}

/// Runs `uavloc replay`.
pub fn run(args: &ReplayArgs) -> Result<ReplayReport, CliError> {
    let recording = read_recording(&args.file).map_err(|e| CliError::input_because("the recording", e))?;
    let text = recording.metadata.get("scenario").ok_or_else(|| {
        CliError::Input(format!(
            "{}: not a uavloc recording (no `uavloc` metadata with the scenario)",
            args.file.display()
        ))
    })?;
    let mut sc: Scenario = serde_json::from_str(text)
        .map_err(|e| CliError::input_because(format!("{}: the recorded scenario", args.file.display()), e))?;
    if let Some(kind) = args.estimator {
        sc.estimator = kind;
    }
    if let Some(model) = args.emitter_model {
        sc.emitter_model = model;
    }
    let dynamics = sc.dynamics().map_err(|e| CliError::input_because("--emitter-model", e))?;
    let measurements = first_per_step(&recording.messages, "/measurement");
    let estimates = first_per_step(&recording.messages, "/estimate");
    let commands = first_per_step(&recording.messages, "/command");
    let planners = recorded_planners(&commands, &args.file)?;
    if measurements.is_empty() {
        return Err(CliError::Input(format!("{}: the recording has no measurement", args.file.display())));
    }
    // Without --estimator, each step with the estimator that made its recorded estimate (a run whose
    // estimator was swapped: the new one resumed from the last estimate of the old one, as it did).
    let recorded_kind = |step: u64| estimates.get(&step).and_then(|e| estimator_of_recorded(e));
    // The first estimate that tells (a fused run's first steps may have no fix), else the scenario's.
    let mut kind = args.estimator.or_else(|| estimates.keys().find_map(|k| recorded_kind(*k))).unwrap_or(sc.estimator);
    let mut kinds_used = vec![kind];
    let mut estimator = Estimator::with_config(EstimatorConfig::new(kind, dynamics));
    let mut last_replayed: Option<protocol::Estimate> = None;
    let mut per_step = Vec::new();
    // The objective and solver of each planned step, in step order.
    let mut planners_used: Vec<(ObjectiveKind, SolverKind)> = Vec::new();
    for (expected, (&step, json)) in measurements.iter().enumerate() {
        if step != expected as u64 {
            return Err(CliError::Input(format!(
                "{}: step {expected} is missing from the recording (the next one is {step}); the estimator needs \
                 every step in order",
                args.file.display()
            )));
        }
        let m = measurement_of(json)?;
        if args.estimator.is_none()
            && let Some(k) = recorded_kind(step).filter(|k| *k != kind)
        {
            let previous = last_replayed.as_ref().filter(|e| e.status().is_some_and(|s| s.is_usable()));
            estimator = match previous {
                Some(e) => estimator::chain::resumed(EstimatorConfig::new(k, dynamics), e),
                None => Estimator::with_config(EstimatorConfig::new(k, dynamics)),
            };
            kind = k;
            kinds_used.push(k);
        }
        let reply = estimator::chain::estimate_measurement(&mut estimator, &m);
        let replayed =
            reply.to_estimate(&m, 0, 0, 0).map_err(|e| CliError::failed_because(format!("step {step}"), e))?;
        let replayed_view = view_of_estimate(&replayed);
        last_replayed = Some(replayed);
        let recorded = estimates.get(&step).map(|e| view_of_json(e, step)).transpose()?;
        let estimate_equal = recorded.as_ref().is_some_and(|r| {
            let bits = |v: &EstimateView| {
                let all = [v.estimate[0], v.estimate[1], v.covariance[0][0], v.covariance[0][1], v.covariance[1][1]];
                all.map(|x| x.map(f64::to_bits))
            };
            r.status == replayed_view.status && bits(r) == bits(&replayed_view)
        });
        let estimate_delta_m = recorded.as_ref().and_then(|r| match (r.estimate, replayed_view.estimate) {
            ([Some(a), Some(b)], [Some(c), Some(d)]) => Some((a - c).hypot(b - d)),
            _ => None,
        });
        let planned = step < sc.steps as u64;
        // The flags, else the planner of this step's recorded command (or the last one before it).
        let as_recorded = planners.range(..=step).next_back().or_else(|| planners.iter().next()).map(|(_, p)| *p);
        let objective = args.objective.or(as_recorded.map(|p| p.0)).unwrap_or(ObjectiveKind::Analytical);
        let solver = args.solver.or(as_recorded.map(|p| p.1)).unwrap_or(SolverKind::Gradient);
        let replayed_headings = match replayed.plan_from() {
            Some((position, covariance)) if planned => {
                let (z, cov) = tdoa::estimate_from_arrays(&position, &covariance);
                let positions = tdoa::points_from_arrays(m.uavs());
                let stated = planner::wire::scenario_with_sigmas(&sc, replayed.range_sigmas());
                plan_step(&PlanRequest {
                    positions: &positions,
                    headings: m.headings(),
                    estimate: z,
                    covariance: cov,
                    scenario: stated.as_ref().unwrap_or(&sc),
                    objective,
                    solver,
                    run_seed: sc.seed,
                    step,
                    motion: planner::wire::motion_of(&replayed),
                })
                .ok()
                .map(|p| p.headings)
            }
            _ => None,
        };
        let recorded_headings =
            commands.get(&step).filter(|_| planned).map(|c| f64s(&c["headings"], "headings", step)).transpose()?;
        let heading_delta_rad = match (&recorded_headings, &replayed_headings) {
            (Some(a), Some(b)) if a.len() == b.len() => {
                Some(a.iter().zip(b).map(|(x, y)| model::wrap_angle(x - y).abs()).fold(0.0, f64::max))
            }
            _ => None,
        };
        if planned {
            planners_used.push((objective, solver));
        }
        per_step.push(ReplayStep {
            step,
            recorded,
            replayed: replayed_view,
            estimate_equal,
            estimate_delta_m,
            recorded_headings,
            replayed_headings,
            heading_delta_rad,
            planner: planned.then(|| format!("{}/{}", solver.name(), objective.name())),
        });
    }
    let max = |it: &mut dyn Iterator<Item = f64>| it.fold(None, |m: Option<f64>, v| Some(m.map_or(v, |m| m.max(v))));
    let plans: Vec<&ReplayStep> =
        per_step.iter().filter(|s| s.recorded_headings.is_some() && s.replayed_headings.is_some()).collect();
    Ok(ReplayReport {
        file: args.file.display().to_string(),
        estimator: in_order_used(kinds_used.iter().map(|k| k.name())),
        emitter_model: sc.emitter_model.name().to_string(),
        objective: in_order_used(planners_used.iter().map(|p| p.0.name())),
        solver: in_order_used(planners_used.iter().map(|p| p.1.name())),
        steps: per_step.len() as u64,
        estimates_compared: per_step.iter().filter(|s| s.recorded.is_some()).count() as u64,
        estimates_equal: per_step.iter().filter(|s| s.estimate_equal).count() as u64,
        max_estimate_delta_m: max(&mut per_step.iter().filter_map(|s| s.estimate_delta_m)),
        plans_compared: plans.len() as u64,
        plans_equal: plans.iter().filter(|s| s.recorded_headings == s.replayed_headings).count() as u64,
        max_heading_delta_rad: max(&mut per_step.iter().filter_map(|s| s.heading_delta_rad)),
        per_step,
    })
}

impl Report for ReplayReport {
    fn table(&self) -> Table {
        let opt = |v: Option<f64>, unit: &str| v.map_or("-".to_string(), |v| format!("{v:.3} {unit}"));
        let mut t = Table::new()
            .row("recording", self.file.clone())
            .row(
                "replayed with",
                format!("{} estimator ({}), {} / {}", self.estimator, self.emitter_model, self.objective, self.solver),
            )
            .row("steps", self.steps.to_string())
            .row("estimates equal", format!("{} of {}", self.estimates_equal, self.estimates_compared))
            .row("largest estimate difference", opt(self.max_estimate_delta_m, "m"))
            .row("plans equal", format!("{} of {}", self.plans_equal, self.plans_compared))
            .row("largest heading difference", opt(self.max_heading_delta_rad, "rad"));
        for s in &self.per_step {
            let est = |v: &EstimateView| match v.estimate {
                [Some(x), Some(y)] => format!("({x:.1}, {y:.1}) {}", v.status),
                _ => format!("- {}", v.status),
            };
            t = t.row(
                format!("step {:>3}", s.step),
                format!(
                    "recorded {}  replayed {}  Δ {}  heading Δ {}",
                    s.recorded.as_ref().map_or("-".into(), est),
                    est(&s.replayed),
                    opt(s.estimate_delta_m, "m"),
                    opt(s.heading_delta_rad, "rad")
                ),
            );
        }
        t
    }
}
