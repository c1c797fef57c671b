//! What the live view shows, as plain data: fed step by step from `StepRecord`s (`simulate --live`) or
//! from the monitor's JSON-lines log events (`launch`), which carry the same records.

use record::StepRecord;
use serde_json::Value;

/// One process of a launch, as the launcher sees it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ProcessRow {
    /// Its role.
    pub role: String,
    /// The current instance's pid.
    pub pid: u32,
    /// Whether it runs.
    pub running: bool,
    /// Restarts of the role so far.
    pub restarts: u64,
}

/// What the receivers delivered, as the steps come in.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReceiverCounts {
    /// The newest step's receiver view (`None`: a complete burst, nothing dropped).
    pub last: Option<record::StepReceiver>,
    /// Steps the emitter was silent.
    pub silent_steps: u64,
    /// Arrivals lost (a UAV that did not hear a burst that was sent).
    pub arrivals_lost: u64,
    /// Arrivals dropped as outliers, per UAV.
    pub outliers_by_uav: Vec<u64>,
}

impl ReceiverCounts {
    /// Takes the receiver view of a step of `n` UAVs.
    pub fn add(&mut self, n: usize, r: Option<&record::StepReceiver>) {
        self.last = r.cloned();
        let Some(r) = r else { return };
        if r.silent == Some(true) {
            self.silent_steps += 1;
        } else {
            self.arrivals_lost += n.saturating_sub(r.heard.len()) as u64;
        }
        if self.outliers_by_uav.len() < n {
            self.outliers_by_uav.resize(n, 0);
        }
        for &i in &r.outliers {
            if let Some(c) = self.outliers_by_uav.get_mut(i) {
                *c += 1;
            }
        }
    }

    /// One line: the newest step (heard by whom, silent, outliers) and the run's counts.
    pub fn line(&self) -> String {
        let uavs = |v: &[usize]| v.iter().map(|i| format!("U{i}")).collect::<Vec<_>>().join(" ");
        let now = match &self.last {
            None => "every UAV heard the burst".to_string(),
            Some(r) if r.silent == Some(true) => "SILENT (estimate predicted)".to_string(),
            Some(r) if r.heard.len() < 2 => format!("heard by {} UAV(s) only (estimate predicted)", r.heard.len()),
            Some(r) if r.outliers.is_empty() => format!("heard by {}", uavs(&r.heard)),
            Some(r) => format!("heard by {}, outliers dropped: {}", uavs(&r.heard), uavs(&r.outliers)),
        };
        let outliers: Vec<String> = self
            .outliers_by_uav
            .iter()
            .enumerate()
            .filter(|(_, n)| **n > 0)
            .map(|(i, n)| format!("U{i}×{n}"))
            .collect();
        format!(
            "receiver: {now}; silent steps {}, arrivals lost {}, outliers {}",
            self.silent_steps,
            self.arrivals_lost,
            if outliers.is_empty() { "0".to_string() } else { outliers.join(" ") }
        )
    }
}

/// Everything the view draws.
#[derive(Debug, Clone, Default)]
pub struct LiveState {
    /// What runs, e.g. `launch uavloc-123 (lockstep)`.
    pub title: String,
    /// The last step of the run.
    pub last_step: u64,
    /// Steps recorded so far.
    pub steps: u64,
    /// The UAVs' positions, one track per UAV, metres.
    pub tracks: Vec<Vec<[f64; 2]>>,
    /// The true emitter of the latest step (none with an external front end).
    pub truth: Option<[f64; 2]>,
    /// The latest estimate and its covariance, metres and m².
    pub estimate: Option<([f64; 2], [[f64; 2]; 2])>,
    /// The standoff radius L_min circle, metres (0: none).
    pub standoff_m: f64,
    /// RMSE per step, metres (step, value).
    pub rmse: Vec<(f64, f64)>,
    /// PCRLB per step, metres.
    pub pcrlb: Vec<(f64, f64)>,
    /// CRLB at the truth per step, metres.
    pub crlb: Vec<(f64, f64)>,
    /// The processes (launch only).
    pub processes: Vec<ProcessRow>,
    /// Messages the monitor rejected.
    pub rejected: u64,
    /// Messages the other processes rejected, per (role, instance), from their `status` announcements.
    pub rejected_by: std::collections::BTreeMap<(String, u64), u64>,
    /// The last hop latencies, µs: (name, value).
    pub hops: Vec<(&'static str, Option<f64>)>,
    /// The planner in charge, e.g. `pso/analytical #1a2b`.
    pub planner: Option<String>,
    /// The last line worth showing (a restart, a rejection, the end).
    pub note: String,
    /// The planner's safety word on the newest planned step (`None`: not certified by design — the
    /// waypoint planner, a hold — or nothing planned yet).
    pub certified: Option<bool>,
    /// Planned steps whose command said that no certified plan existed.
    pub uncertified: u64,
    /// The newest such step.
    pub last_uncertified: Option<u64>,
    /// What the receivers delivered: the newest step's view (`None`: every UAV heard it, nothing
    /// dropped) and the run's counts so far.
    pub receiver: ReceiverCounts,
    /// The posterior CRLB as the steps come in (the records' `pcrlb_m` is computed only at the end of a
    /// run); see [`LiveState::with_bound`].
    bound: Option<record::RunningBound>,
    /// With aircraft: each UAV's link as the bridge last reported it (`flying`, `not_guided`, `quiet`).
    pub links: Vec<String>,
    /// The run's local plane when its scenario has an origin: the estimate is also shown as
    /// latitude/longitude.
    pub frame: Option<model::geo::LocalFrame>,
}

impl LiveState {
    /// A view of a run of `last_step + 1` steps with the standoff radius `standoff_m`.
    pub fn new(title: impl Into<String>, last_step: u64, standoff_m: f64) -> Self {
        Self { title: title.into(), last_step, standoff_m, ..Self::default() }
    }

    /// The same view computing the PCRLB series as the steps come in, with the scenario's σ and emitter
    /// model ([`record::RunningBound`]; without it the series is what the records carry).
    pub fn with_bound(mut self, scenario: &model::Scenario) -> Self {
        self.bound = Some(record::RunningBound::new(scenario));
        self.frame = scenario.frame();
        self
    }

    /// Messages rejected by the processes of `role` so far (every instance's count; the monitor's are the
    /// ones it logged).
    pub fn rejected_of(&self, role: &str) -> u64 {
        if role == "monitor" {
            return self.rejected;
        }
        self.rejected_by.iter().filter(|((r, _), _)| r == role).map(|(_, n)| n).sum()
    }

    /// Takes a recorded step.
    pub fn apply_step(&mut self, r: &StepRecord) {
        if self.tracks.len() < r.uavs.len() {
            self.tracks.resize(r.uavs.len(), Vec::new());
        }
        for (track, p) in self.tracks.iter_mut().zip(&r.uavs) {
            track.push(*p);
        }
        self.receiver.add(r.uavs.len(), r.receiver.as_ref());
        self.truth = r.truth;
        self.estimate = r.estimate.iter().all(|v| v.is_finite()).then_some((r.estimate, r.estimate_cov));
        let k = r.step as f64;
        let push = |series: &mut Vec<(f64, f64)>, v: Option<f64>| {
            if let Some(v) = v.filter(|v| v.is_finite()) {
                series.push((k, v));
            }
        };
        push(&mut self.rmse, r.rmse_m);
        // At the truth when there is one, else along the estimates (`pcrlb_at_estimate_m`).
        let at = r.truth.unwrap_or(r.estimate);
        let z = nalgebra::Vector2::new(at[0], at[1]);
        let pcrlb = match &mut self.bound {
            Some(b) if z.iter().all(|v| v.is_finite()) => {
                b.add(r.step, &r.uavs, r.range_sigmas_m.as_deref(), r.receiver.as_ref().map(|x| x.heard.as_slice()), &z)
            }
            Some(_) => None,
            None => r.pcrlb_m.or(r.pcrlb_at_estimate_m),
        };
        push(&mut self.pcrlb, pcrlb);
        push(&mut self.crlb, r.crlb_true_m);
        if let Some(p) = &r.planner {
            self.planner = Some(format!("{}/{} #{:x}", p.solver, p.objective, p.instance >> 32));
        }
        if r.step < self.last_step {
            self.certified = r.safety.and_then(|x| x.certified);
            if self.certified == Some(false) {
                self.uncertified += 1;
                self.last_uncertified = Some(r.step);
            }
        }
        self.steps = r.step + 1;
    }

    /// The safety line of the view: certified, or how many steps had no certified plan.
    pub fn safety_line(&self) -> String {
        let word = match self.certified {
            Some(true) => "certified",
            Some(false) => "NOT CERTIFIED (largest minimum margin flown)",
            None => "not certified by design (waypoint planner or hold)",
        };
        match self.last_uncertified {
            Some(k) => format!("safety: {word}; {} step(s) without a certified plan, last step {k}", self.uncertified),
            None => format!("safety: {word}"),
        }
    }

    /// Takes one event of the monitor's log (`step`, `restart`, `rejected`; others are ignored).
    pub fn apply_event(&mut self, e: &Value) {
        match e["event"].as_str() {
            Some("step") => {
                let Ok(record) = serde_json::from_value::<StepRecord>(e["record"].clone()) else { return };
                self.apply_step(&record);
                let l = &e["latency_us"];
                self.hops = ["measurement_hop", "estimate_hop", "command_hop", "estimator", "planner", "cycle"]
                    .into_iter()
                    .map(|k| (k, l[k].as_f64()))
                    .collect();
                if e["command_missed"] == true {
                    self.note = format!("step {}: command missed (flew the hold)", record.step);
                }
            }
            Some("restart") => {
                self.note = format!(
                    "{} restarted (attempt {}, {})",
                    e["role"].as_str().unwrap_or("?"),
                    e["attempt"],
                    e["exit"].as_str().unwrap_or("?")
                );
            }
            Some("rejected") => {
                self.rejected += 1;
                self.note =
                    format!("rejected a {}: {}", e["kind"].as_str().unwrap_or("?"), e["detail"].as_str().unwrap_or(""));
            }
            Some("status") => {
                if let (Some(role), Some(instance), Some(n)) =
                    (e["role"].as_str(), e["instance"].as_u64(), e["rejected"].as_u64())
                {
                    self.rejected_by.insert((role.to_string(), instance), n);
                }
            }
            Some("link") => {
                if let (Some(i), Some(state)) = (e["uav"].as_u64(), e["state"].as_str()) {
                    let i = i as usize;
                    if self.links.len() <= i {
                        self.links.resize(i + 1, "unknown".into());
                    }
                    self.links[i] = state.to_string();
                    if state == "quiet" {
                        self.note = format!("UAV {i}: link quiet (step {}): not heard, its margins widened", e["step"]);
                    }
                }
            }
            Some("start") => {
                if let Some(steps) = e["steps"].as_u64() {
                    self.last_step = steps;
                }
            }
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn log_events_build_the_tracks_the_estimate_and_the_series() {
        let mut s = LiveState::new("t", 2, 3000.0);
        let step = |k: u64, x: f64| {
            json!({"event": "step", "step": k, "record": {
                "step": k, "uavs": [[x, 0.0], [x, 1000.0], [x, 2000.0]], "headings_rad": [0.0, 0.0, 0.0],
                "estimate": [25000.0, 15000.0], "estimate_cov": [[4.0e4, 0.0], [0.0, 9.0e4]],
                "estimate_status": "ok", "truth": [25100.0, 15000.0], "crlb_true_m": 900.0, "rmse_m": 950.0,
                "pcrlb_m": null, "objective_value": 30.0, "plan_ms": 0.1, "active_constraints": [],
                "planner": {"solver": "pso", "objective": "analytical", "instance": 0x1234_0000_0000u64}},
                "latency_us": {"measurement_hop": 41.0, "cycle": 300.0}})
        };
        s.apply_event(&step(0, 1000.0));
        s.apply_event(&step(1, 1500.0));
        s.apply_event(&json!({"event": "restart", "role": "planner", "attempt": 1, "exit": "signal 9"}));
        s.apply_event(&json!({"event": "rejected", "kind": "measurement", "detail": "diffs is not finite"}));
        assert_eq!(s.tracks.len(), 3);
        assert_eq!(s.tracks[0], vec![[1000.0, 0.0], [1500.0, 0.0]]);
        assert_eq!(s.truth, Some([25100.0, 15000.0]));
        assert_eq!(s.rmse, vec![(0.0, 950.0), (1.0, 950.0)]);
        assert!(s.pcrlb.is_empty(), "null is no point");
        // With the scenario's bound: the PCRLB at the truth as the steps come in, shrinking.
        let mut b = LiveState::new("t", 2, 3000.0).with_bound(&model::Scenario::default());
        b.apply_event(&step(0, 1000.0));
        b.apply_event(&step(1, 1500.0));
        assert_eq!(b.pcrlb.len(), 2);
        assert!(b.pcrlb[1].1 < b.pcrlb[0].1, "{:?}", b.pcrlb);
        assert_eq!(s.planner.as_deref(), Some("pso/analytical #1234"));
        assert_eq!((s.steps, s.rejected), (2, 1));
        assert!(s.note.contains("diffs is not finite"));
        assert!(s.hops.contains(&("measurement_hop", Some(41.0))) && s.hops.contains(&("planner", None)));
        // Every process's rejections, summed over its instances (a restarted one counts from 0 again).
        for (instance, n) in [(1u64, 2u64), (1, 3), (2, 1)] {
            s.apply_event(&json!({"event": "status", "role": "estimator", "instance": instance, "rejected": n}));
        }
        assert_eq!((s.rejected_of("estimator"), s.rejected_of("monitor"), s.rejected_of("planner")), (4, 1, 0));
    }

    #[test]
    fn the_safety_line_says_which_steps_had_no_certified_plan() {
        let mut s = LiveState::new("t", 3, 3000.0);
        assert!(s.safety_line().contains("not certified by design"), "{}", s.safety_line());
        let mut r = crate::live::state::tests::record_of(0);
        r.safety = Some(record::StepSafety { certified: Some(true), ..Default::default() });
        s.apply_step(&r);
        assert_eq!(s.safety_line(), "safety: certified");
        r.step = 1;
        r.safety = Some(record::StepSafety { certified: Some(false), ..Default::default() });
        s.apply_step(&r);
        assert!(s.safety_line().starts_with("safety: NOT CERTIFIED"), "{}", s.safety_line());
        assert!(s.safety_line().ends_with("1 step(s) without a certified plan, last step 1"), "{}", s.safety_line());
        r.step = 2;
        r.safety = Some(record::StepSafety { certified: Some(true), ..Default::default() });
        s.apply_step(&r);
        assert!(s.safety_line().starts_with("safety: certified; 1 step(s)"), "{}", s.safety_line());
        assert_eq!(s.uncertified, 1);
    }

    #[test]
    fn the_receiver_line_says_who_heard_the_burst_and_counts_what_was_lost() {
        let mut s = LiveState::new("t", 4, 3000.0);
        s.apply_step(&record_of(0));
        assert_eq!(
            s.receiver.line(),
            "receiver: every UAV heard the burst; silent steps 0, arrivals lost 0, outliers 0"
        );
        let mut r = record_of(1);
        r.receiver = Some(record::StepReceiver::from_masks(3, 0b101, 0b100, Some(false), None));
        s.apply_step(&r);
        assert_eq!(
            s.receiver.line(),
            "receiver: heard by U0 U2, outliers dropped: U2; silent steps 0, arrivals lost 1, outliers U2×1"
        );
        r.step = 2;
        r.receiver = Some(record::StepReceiver::from_masks(3, 0, 0, Some(true), None));
        s.apply_step(&r);
        assert_eq!(
            s.receiver.line(),
            "receiver: SILENT (estimate predicted); silent steps 1, arrivals lost 1, outliers U2×1"
        );
        r.step = 3;
        r.receiver = Some(record::StepReceiver::from_masks(3, 0b010, 0, Some(false), None));
        s.apply_step(&r);
        assert!(s.receiver.line().starts_with("receiver: heard by 1 UAV(s) only"), "{}", s.receiver.line());
        assert_eq!((s.receiver.silent_steps, s.receiver.arrivals_lost), (1, 3));
    }

    pub(crate) fn record_of(step: u64) -> StepRecord {
        serde_json::from_value(json!({
            "step": step, "uavs": [[0.0, 0.0], [0.0, 1000.0], [0.0, 2000.0]], "headings_rad": [0.0, 0.0, 0.0],
            "estimate": [25000.0, 15000.0], "estimate_cov": [[4.0e4, 0.0], [0.0, 9.0e4]],
            "estimate_status": "ok", "rmse_m": null, "objective_value": null, "plan_ms": null,
            "active_constraints": []
        }))
        .unwrap()
    }
}
