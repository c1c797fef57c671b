//! What `uavloc launch` prints.

use std::collections::BTreeMap;

use protocol::resources::DomainResources;
use record::RunRecord;
use serde::Serialize;

use crate::output::{Diagnostic, Report, Table};

fn as_true<S: serde::Serializer>(_: &Option<String>, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_bool(true)
}

/// One child's outcome (every instance, also the crashed ones).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ChildReport {
    pub role: String,
    pub pid: u32,
    pub exit: String,
    pub rejected: u64,
    /// Whether it crashed and was replaced by a restarted instance.
    pub restarted: bool,
    /// Its `summary` line (none if it was killed).
    pub summary: Option<serde_json::Value>,
}

/// What `uavloc launch` prints: the monitor's run record (the JSON shape of `uavloc simulate --json`)
/// plus `restarts` and `rejected`.
#[derive(Debug, Clone, Serialize)]
pub struct LaunchReport {
    #[serde(flatten)]
    pub run: RunRecord,
    /// Set when the launch was stopped by SIGINT/SIGTERM: `steps` are those done (JSON: `"interrupted":
    /// true`, absent otherwise).
    #[serde(rename = "interrupted", serialize_with = "as_true", skip_serializing_if = "Option::is_none")]
    pub interrupted: Option<String>,
    /// Set when a process ended the run before its last step with an error no restart could mend (a
    /// step 0 without a fix, a front end of another formation, a crashed monitor with an external front
    /// end): the error; `steps` are those done. Exit code 1.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub failed: Option<String>,
    /// Children restarted after a crash.
    pub restarts: u64,
    /// Invalid messages counted and ignored by all four processes.
    pub rejected: u64,
    /// The same count per process role.
    pub rejected_by: BTreeMap<String, u64>,
    /// Realtime mode: steps whose command had not reached emitter-sim when the next step was due (the UAVs
    /// flew the hold of a step without a plan); 0 in lock-step mode.
    pub missed_commands: u64,
    /// Steps whose command was the planner's hold: no fresh estimate within --estimate-deadline-ms, or
    /// none yet to plan from (`held_before_first_fix` of them).
    pub stale_steps: u64,
    /// Of `stale_steps`, those held before a first fix (the estimate failed: nothing to plan from).
    pub held_before_first_fix: u64,
    /// Every process instance the launch started, in start order.
    #[serde(rename = "processes")]
    pub children: Vec<ChildReport>,
    #[serde(skip)]
    pub domain: String,
    #[serde(skip)]
    pub mode: String,
    #[serde(skip)]
    pub wall_s: f64,
    #[serde(skip)]
    pub latency: Option<serde_json::Value>,
    #[serde(skip)]
    pub leftovers: DomainResources,
    /// CPU use of the waiting monitor, planner and estimator before the run, % of one core (only with
    /// an idle probe, see [`super::LaunchArgs::idle_probe_ms`]).
    #[serde(skip)]
    pub idle_cpu: BTreeMap<String, f64>,
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or("-".to_string(), |x| format!("{x:.digits$}"))
}

impl LaunchReport {
    /// The holds for an estimate later than the planner's deadline (not those before a first fix).
    fn late_estimates(&self) -> u64 {
        self.stale_steps.saturating_sub(self.held_before_first_fix)
    }
}

impl Report for LaunchReport {
    fn table(&self) -> Table {
        let r = &self.run;
        let last = r.steps.last();
        let p50 = |key: &str| {
            self.latency
                .as_ref()
                .and_then(|l| l[key]["p50_us"].as_f64())
                .map_or("-".to_string(), |v| format!("{v:.0} µs"))
        };
        let mut t = Table::new()
            .row("domain", self.domain.clone())
            .row("objective / solver", format!("{} / {}", r.objective, r.solver))
            .row("mode", self.mode.clone())
            .row("seed", r.seed.to_string())
            .row("steps recorded", format!("{} (0..{})", r.steps.len(), r.steps.len().saturating_sub(1)))
            .row(
                "emitter (truth)",
                r.emitter
                    .map_or("- (no truth: external front end)".into(), |e| format!("({:.1}, {:.1}) m", e[0], e[1])),
            )
            .row("final CRLB at truth", format!("{} m", opt(last.and_then(|s| s.crlb_true_m), 2)))
            .row("final RMSE", format!("{} m", opt(last.and_then(|s| s.rmse_m), 2)))
            .row("final |ẑ − z|", format!("{} m", opt(last.and_then(|s| s.estimate_error_m), 1)))
            .row(
                "median hops",
                format!(
                    "command {}, measurement {}, estimate {}",
                    p50("command_hop"),
                    p50("measurement_hop"),
                    p50("estimate_hop")
                ),
            )
            .row("median cycle", p50("cycle"))
            .row("rejected messages", self.rejected.to_string())
            .row("missed commands", self.missed_commands.to_string())
            .row("stale estimates (held)", self.late_estimates().to_string())
            .row("held before a first fix", self.held_before_first_fix.to_string())
            .row("restarts", self.restarts.to_string())
            .row("wall time", format!("{:.2} s", self.wall_s));
        for c in &self.children {
            let restarted = if c.restarted { " (crashed, restarted)" } else { "" };
            t = t
                .row(format!("  {}", c.role), format!("pid {}, {}, rejected {}{restarted}", c.pid, c.exit, c.rejected));
        }
        t
    }

    fn diagnostics(&self) -> Vec<Diagnostic> {
        let mut out = Vec::new();
        if let Some(why) = self.interrupted.as_ref().or(self.failed.as_ref()) {
            out.push(Diagnostic::Failure(format!("{why}; the record holds the {} step(s) done", self.run.steps.len())));
        }
        // Writing the monitor's files failed at the end: the run's record is still printed, the exit
        // code says the outputs are missing.
        for c in self.children.iter().filter(|c| c.role == "monitor") {
            if let Some(e) = c.summary.as_ref().and_then(|s| s["output_error"].as_str()) {
                out.push(Diagnostic::Failure(format!("the run completed, but {e}")));
            }
        }
        if !self.leftovers.is_empty() {
            out.push(Diagnostic::Warning(format!(
                "iceoryx2 resources of domain {} are left: nodes {:?}, services {:?}",
                self.domain,
                self.leftovers.nodes.iter().map(|n| format!("{} ({})", n.name, n.state)).collect::<Vec<_>>(),
                self.leftovers.services
            )));
        }
        let late = self.late_estimates();
        if late > 0 {
            out.push(Diagnostic::Warning(format!(
                "{late} step(s) had no fresh estimate within the planner's deadline (the planner held): see \
                 active_constraints \"estimate_stale\""
            )));
        }
        if self.held_before_first_fix > 0 {
            out.push(Diagnostic::Warning(format!(
                "{} step(s) were held before a first fix (no estimate to plan from: the UAVs loitered on their \
                 backup circles): see estimate_status \"failed\" with active_constraints \"estimate_stale\"",
                self.held_before_first_fix
            )));
        }
        if self.missed_commands > 0 {
            out.push(Diagnostic::Warning(format!(
                "{} step(s) missed their command (it reached emitter-sim after the next step was due; the UAVs \
                 flew the hold: their backup circles): see active_constraints \"command_missed\"",
                self.missed_commands
            )));
        }
        out.extend(record::safety_warnings(&self.run).into_iter().map(Diagnostic::Warning));
        let n = self.run.steps.iter().filter(|s| s.estimate_status != "ok").count();
        if n > 0 {
            out.push(Diagnostic::Warning(format!(
                "{n} step(s) had an ambiguous or failed estimate (see estimate_status)"
            )));
        }
        out
    }
}
