//! `uavloc bench planner`: the planner's compute time per planning step, for every objective × solver,
//! measured side by side in one run on the same realistic planning inputs.
//!
//! 1. **Inputs.** The closed loop of `uavloc simulate` runs in-process with the reference combination
//!    (analytical × PSO) and keeps, for every planned step, the exact inputs of
//!    [`planning::plan_step`]: UAV positions and headings, the estimate ẑ and its covariance M (or the
//!    controlled target), the run seed and the step index. One run has the scenario's `steps` planned
//!    steps (24 for the paper), so `--steps N` takes the steps of as many runs as needed: run 0 with the
//!    scenario's seed (its inputs are exactly those of `uavloc simulate --objective analytical`), run
//!    r ≥ 1 with `derive_seed(seed, r, Purpose::OuterRun)`, and the first N steps of that sequence.
//!    Every combination plans the same N situations.
//! 2. **Timing.** Interleaved: for every input step (and every repeat of it), every combination plans it
//!    once, round-robin, the starting combination rotating by one each round, so the machine's noise
//!    (frequency changes, other processes, cache state) hits all combinations alike. One untimed warm-up
//!    call per combination comes first. Each call is timed with [`Instant`] around the whole
//!    `plan_step` (criterion preparation + solver + constraint check), its inputs and output passed
//!    through [`black_box`].
//! 3. **Report.** Per combination: n, median, p90, p99, max and mean in milliseconds (percentiles by
//!    linear interpolation between order statistics), criterion evaluations and solver iterations per
//!    plan, the ratio of the median to the reference's median, and the paper's Table 7 numbers (PSO rows
//!    of single / mc / analytical) beside the matching rows.

use std::hint::black_box;
use std::io::IsTerminal as _;
use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use model::Scenario;
use model::safety::SafetyMode;
use planning::{ObjectiveKind, SolverKind, plan_step};
use serde::Serialize;

use experiments::stats::quantile;

use crate::error::CliError;
use crate::simulate::scenario_from;

mod inputs;
mod quality;
mod report;

pub use inputs::{PlanInput, collect_inputs, collect_inputs_of_runs};
pub use quality::{Quality, WorstCase, quality};

pub const LONG_ABOUT: &str = "\
Time the planner's compute per planning step (one call of plan_step: prepare the criterion for the
step's uncertainty, run the solver over the heading cones, check the constraints) for every objective ×
solver, side by side in one run, on the same realistic inputs.

Inputs: the closed loop of `uavloc simulate` with the analytical objective and PSO is run in-process
and every planned step's exact planner inputs (UAV positions and headings, the estimate and its
covariance, the run seed and step) are kept. A run has the scenario's number of steps (24 for the
paper); --steps N takes the first N planned steps of consecutive runs: run 0 with the scenario's seed
(or --seed), run r >= 1 with a seed derived from it, as the outer runs of `uavloc paper` are.

Timing: interleaved. For each input step (and each of its --repeats), every combination plans it
once, round-robin, the starting combination rotating by one each round, so whatever the machine does
meanwhile hits all combinations alike. One untimed warm-up call per combination comes first. Each
call is timed with a monotonic clock around the whole plan_step; one thread.

Per combination: samples n (= steps × repeats), median, p90, p99, max and mean wall-clock time in
milliseconds (percentiles interpolated between order statistics), criterion evaluations per plan (the
JSON also has solver iterations; both 0 for formation, which runs no solver; early stopping makes them
vary), and the median as a multiple of analytical/pso's median (the reference; '-' when it is not among
the combinations timed).

Quality: every solver's plan of each input is compared with PSO's plan of the same input and objective
(paired; fitness = the constraint violation by priority tier, then the criterion; values within 1e-12
relative of each other tie): how often its fitness is at most PSO's, how often strictly better, and the
five worst cases (JSON: `quality`). --run-steps N
makes the input runs N steps long: runs longer than the paper's 24 steps reach the L_min ring, where the
planner gives up the heading cone to keep the standoff.

Paper Table 7 (single, mc and analytical, all with PSO) gives, per planning step and in seconds, the
time of the displayed CRLB, the optimisation and their total (mean and max). The PSO optimisation is
what is timed here, so 'paper opt' is the comparable number and 'paper total' is printed beside it
(both in ms). The paper's times are MATLAB R2024a on another machine; only the ratios between
objectives compare (paper: mc / analytical ≈ 7.8× total).

Units: milliseconds. Output: an aligned table, or JSON with --json. Progress goes to stderr (only when
it is a terminal). Exit codes: 0 success, 1 a planning call failed, 2 bad input.";

pub const AFTER_HELP: &str = "\
Examples:
  uavloc bench planner
  uavloc bench planner --objective analytical,mc --solver pso --steps 48 --json
  uavloc bench planner --objective single --objective analytical --solver pso,ga,aco --repeats 3
  uavloc bench planner --scenario scenarios/nominal.toml --seed 7
  uavloc bench planner --objective analytical --solver pso,gradient --steps 1000 --run-steps 200

The default (5 objectives × 4 solvers × 200 steps, one repeat) takes a few seconds (≈ 2 s on a 2-CPU
VM), most of it in mc, whose criterion averages the scenario's mc_samples points per candidate. For
steadier tails raise --repeats (each repeat is one more sample of the same step) rather than --steps.";

/// The reference combination of the ratios.
pub const REFERENCE: (ObjectiveKind, SolverKind) = (ObjectiveKind::Analytical, SolverKind::Pso);

/// Flags of `uavloc bench planner`.
#[derive(Args, Debug, Clone, PartialEq)]
pub struct PlannerBenchArgs {
    /// Objectives to time, repeatable or comma-separated: single | mc | analytical | cubature | formation.
    #[arg(
        long,
        value_name = "NAME,..",
        value_delimiter = ',',
        default_values = ["single", "mc", "analytical", "cubature", "formation"]
    )]
    pub objective: Vec<String>,
    /// Solvers to time, repeatable or comma-separated: pso | ga | aco | gradient (formation runs none, but is timed
    /// once per solver like every objective).
    #[arg(long, value_name = "NAME,..", value_delimiter = ',', default_values = ["pso", "ga", "aco", "gradient"])]
    pub solver: Vec<String>,
    /// Planning steps timed per combination (≥ 1); taken from consecutive closed-loop runs of the
    /// scenario when it has fewer.
    #[arg(long, value_name = "N", default_value_t = 200)]
    pub steps: usize,
    /// Scenario TOML file (default: the paper's nominal case; see scenarios/nominal.toml).
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<PathBuf>,
    /// Seed of the first input run (default: the scenario's); later runs derive theirs from it.
    #[arg(long, value_name = "N")]
    pub seed: Option<u64>,
    /// Times each planning call is repeated per step (≥ 1); every repeat is one timed sample.
    #[arg(long, value_name = "R", default_value_t = 1)]
    pub repeats: usize,
    /// Steps of each closed-loop input run (≥ 1; default: the scenario's `steps`). Runs longer than the
    /// paper's 24 steps reach the L_min ring, where the planner's standoff search runs.
    #[arg(long, value_name = "N")]
    pub run_steps: Option<usize>,
    /// Safety modes to time, repeatable or comma-separated: certified (every plan certified along the
    /// arcs with a backup for ever) | waypoints (the paper's constraints at the waypoints). Each
    /// objective × solver is timed once per mode, interleaved with the others.
    #[arg(long, value_name = "MODE,..", value_delimiter = ',', default_values = ["certified"])]
    pub safety: Vec<String>,
}

/// One timed combination: objective × solver × safety mode.
pub type Combo = (ObjectiveKind, SolverKind, SafetyMode);

/// `analytical/pso`, with `/waypoints` for the waypoint planner.
fn combo_label(c: Combo) -> String {
    match c.2 {
        SafetyMode::Certified => format!("{}/{}", c.0, c.1),
        SafetyMode::Waypoints => format!("{}/{}/waypoints", c.0, c.1),
    }
}

/// Parses `--safety`.
fn parse_safety(values: &[String]) -> Result<Vec<SafetyMode>, CliError> {
    let mut out = Vec::new();
    for v in values {
        let m = match v.trim() {
            "certified" => SafetyMode::Certified,
            "waypoints" => SafetyMode::Waypoints,
            other => {
                return Err(CliError::Input(format!(
                    "--safety: unknown mode '{other}' (expected certified or waypoints)"
                )));
            }
        };
        if !out.contains(&m) {
            out.push(m);
        }
    }
    if out.is_empty() {
        out.push(SafetyMode::Certified);
    }
    Ok(out)
}

/// The timing of one objective × solver.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Combination {
    pub objective: String,
    pub solver: String,
    /// `certified` or `waypoints`.
    pub safety: String,
    /// Timed samples (steps × repeats).
    pub n: usize,
    pub median_ms: f64,
    pub p90_ms: f64,
    pub p99_ms: f64,
    pub max_ms: f64,
    pub mean_ms: f64,
    /// Mean criterion evaluations by the solver per plan (0 for formation).
    pub evaluations_per_plan: f64,
    /// Mean solver iterations per plan (early stopping makes it vary; 0 for formation).
    pub iterations_per_plan: f64,
    /// `median_ms` / the reference's `median_ms` (`None` when the reference was not timed).
    pub ratio_to_reference: Option<f64>,
    /// Paper Table 7, total time per step, mean, ms (PSO rows of single / mc / analytical only).
    pub paper_total_mean_ms: Option<f64>,
    /// Paper Table 7, optimisation time per step, ms (the comparable number).
    pub paper_opt_ms: Option<f64>,
    /// The paper's total mean as a multiple of its analytical total mean (compare with
    /// `ratio_to_reference`).
    pub paper_ratio_to_reference: Option<f64>,
}

/// Solver sizes of the scenario (before early stopping).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SolverSettings {
    /// PSO particles × iterations.
    pub pso: [usize; 2],
    /// GA population × generations.
    pub ga: [usize; 2],
    /// ACO_R ants × iterations.
    pub aco: [usize; 2],
    /// K of the mc criterion.
    pub mc_samples: usize,
    /// Early stop after this many insignificant iterations.
    pub early_stop_window: usize,
}

/// What `uavloc bench planner` prints.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlannerBenchReport {
    /// Input steps timed per combination.
    pub steps: usize,
    /// Timed calls per input step and combination.
    pub repeats: usize,
    /// `"analytical/pso"`.
    pub reference: String,
    /// One entry per objective × solver, in the order of the flags (objective-major).
    pub combinations: Vec<Combination>,
    /// The machine (`cpus`, `cpu_model`); the benchmark itself uses one thread.
    #[serde(flatten)]
    pub machine: super::sys::Machine,
    /// The scenario file, or `"nominal"`.
    pub scenario: String,
    /// Seed of the first input run.
    pub seed: u64,
    /// Closed-loop runs (analytical/pso) the inputs came from.
    pub input_runs: usize,
    /// Planned steps per input run (the scenario's `steps`).
    pub steps_per_run: usize,
    /// The scenario's solver sizes.
    pub settings: SolverSettings,
    /// Each solver's plans against PSO's on the same inputs (empty when PSO was not timed).
    pub quality: Vec<Quality>,
}

/// Parses a list flag with `FromStr`, dropping repeats (first occurrence kept); empty = `all`.
fn parse_list<T: std::str::FromStr<Err = String> + PartialEq + Copy>(
    flag: &str,
    values: &[String],
    all: &[T],
) -> Result<Vec<T>, CliError> {
    if values.is_empty() {
        return Ok(all.to_vec());
    }
    let mut out = Vec::new();
    for v in values {
        let k: T = v.trim().parse().map_err(|e| CliError::input_because(flag.to_string(), e))?;
        if !out.contains(&k) {
            out.push(k);
        }
    }
    Ok(out)
}

/// The combinations timed in round `round` (0-based; one round per input step and repeat), as indices
/// into the list of `count` combinations: each exactly once, starting at `round mod count`.
pub fn round_order(round: usize, count: usize) -> impl Iterator<Item = usize> {
    (0..count).map(move |j| (round + j) % count)
}

/// Order statistics of one combination's samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stats {
    pub n: usize,
    pub median: f64,
    pub p90: f64,
    pub p99: f64,
    pub max: f64,
    pub mean: f64,
}

impl Stats {
    /// The statistics of `samples` (any order).
    pub fn of(samples: &[f64]) -> Self {
        let mut s = samples.to_vec();
        s.sort_by(f64::total_cmp);
        let n = s.len();
        Self {
            n,
            median: quantile(&s, 0.5),
            p90: quantile(&s, 0.9),
            p99: quantile(&s, 0.99),
            max: s.last().copied().unwrap_or(f64::NAN),
            mean: if n == 0 { f64::NAN } else { s.iter().sum::<f64>() / n as f64 },
        }
    }
}

/// The paper's Table 7 row for a combination: (total mean, opt. time), ms — PSO rows only.
fn paper_ms(objective: ObjectiveKind, solver: SolverKind) -> Option<(f64, f64)> {
    if solver != SolverKind::Pso {
        return None;
    }
    // s → ms, rounded to the ns so that 0.15202 s prints as 152.02 (not 152.01999999999998).
    let ms = |s: f64| (s * 1e9).round() / 1e6;
    experiments::paper::row(&experiments::paper::TABLE7, objective.name()).map(|r| (ms(r[2]), ms(r[1])))
}

/// Runs `uavloc bench planner`.
pub fn run(args: &PlannerBenchArgs) -> Result<PlannerBenchReport, CliError> {
    use model::scenario::{MAX_COUNT, MAX_STEPS};
    crate::args::require_count("--steps", args.steps, 1, MAX_STEPS)?;
    crate::args::require_count("--repeats", args.repeats, 1, MAX_COUNT)?;
    if let Some(n) = args.run_steps {
        crate::args::require_count("--run-steps", n, 1, MAX_STEPS)?;
    }
    let objectives = parse_list("--objective", &args.objective, &ObjectiveKind::ALL)?;
    let solvers = parse_list("--solver", &args.solver, &SolverKind::ALL)?;
    let sc = scenario_from(args.scenario.as_ref(), None, args.seed)?;
    let run_steps = args.run_steps.unwrap_or(sc.steps);
    let (inputs, input_runs) = collect_inputs_of_runs(&sc, args.steps, run_steps)?;

    let modes = parse_safety(&args.safety)?;
    let mut combos: Vec<Combo> = Vec::new();
    for &o in &objectives {
        for &s in &solvers {
            combos.extend(modes.iter().map(|&m| (o, s, m)));
        }
    }
    let count = combos.len();
    let with_mode = |m: SafetyMode| Scenario { safety: m, ..sc.clone() };
    let scenarios = [with_mode(SafetyMode::Certified), with_mode(SafetyMode::Waypoints)];
    let scenario_of = |m: SafetyMode| &scenarios[usize::from(m == SafetyMode::Waypoints)];
    let label = combo_label;
    let plan = |i: usize, c: Combo| {
        plan_step(black_box(&inputs[i].request(scenario_of(c.2), c.0, c.1)))
            .map_err(|e| CliError::failed_because(format!("{} at input {i} (step {})", label(c), inputs[i].step), e))
    };
    for &c in &combos {
        black_box(plan(0, c)?);
    }

    let rounds = args.steps * args.repeats;
    let mut samples = vec![Vec::with_capacity(rounds); count];
    let mut evaluations = vec![0usize; count];
    let mut iterations = vec![0usize; count];
    let mut fitness = vec![Vec::with_capacity(args.steps); count];
    let progress = std::io::stderr().is_terminal();
    let started = Instant::now();
    let mut shown = 0;
    for round in 0..rounds {
        let i = round / args.repeats;
        for j in round_order(round, count) {
            let t = Instant::now();
            let out = plan(i, combos[j])?;
            let ms = t.elapsed().as_secs_f64() * 1e3;
            let out = black_box(out);
            samples[j].push(ms);
            if round % args.repeats == 0 {
                fitness[j].push(out.fitness);
            }
            evaluations[j] += out.evaluations;
            iterations[j] += out.iterations;
        }
        let pct = (round + 1) * 10 / rounds;
        if progress && pct > shown {
            shown = pct;
            eprint!(
                "\rbench planner: {:>3} % ({} of {rounds} rounds, {:.1} s)",
                pct * 10,
                round + 1,
                started.elapsed().as_secs_f64()
            );
            if round + 1 == rounds {
                eprintln!();
            }
        }
    }

    let stats: Vec<Stats> = samples.iter().map(|s| Stats::of(s)).collect();
    let reference_combo = (REFERENCE.0, REFERENCE.1, modes[0]);
    let reference = combos.iter().position(|&c| c == reference_combo).map(|j| stats[j].median);
    let paper_reference = paper_ms(REFERENCE.0, REFERENCE.1).map(|p| p.0);
    let combinations = combos
        .iter()
        .zip(&stats)
        .enumerate()
        .map(|(j, (&(o, s, m), st))| {
            let paper = paper_ms(o, s);
            Combination {
                objective: o.name().to_string(),
                solver: s.name().to_string(),
                safety: m.name().to_string(),
                n: st.n,
                median_ms: st.median,
                p90_ms: st.p90,
                p99_ms: st.p99,
                max_ms: st.max,
                mean_ms: st.mean,
                evaluations_per_plan: evaluations[j] as f64 / st.n as f64,
                iterations_per_plan: iterations[j] as f64 / st.n as f64,
                ratio_to_reference: reference.map(|r| st.median / r),
                paper_total_mean_ms: paper.map(|p| p.0),
                paper_opt_ms: paper.map(|p| p.1),
                paper_ratio_to_reference: paper.zip(paper_reference).map(|(p, r)| p.0 / r),
            }
        })
        .collect();
    Ok(PlannerBenchReport {
        steps: args.steps,
        repeats: args.repeats,
        reference: label(reference_combo),
        combinations,
        machine: super::sys::Machine::this(),
        scenario: args.scenario.as_ref().map_or("nominal".to_string(), |p| p.display().to_string()),
        seed: sc.seed,
        input_runs,
        steps_per_run: run_steps,
        quality: quality(&combos, &fitness, &inputs),
        settings: SolverSettings {
            pso: [sc.pso.particles, sc.pso.iterations],
            ga: [sc.ga.population, sc.ga.generations],
            aco: [sc.aco.ants, sc.aco.iterations],
            mc_samples: sc.mc_samples,
            early_stop_window: sc.early_stop.window,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::Report;
    use tdoa::rng::{Purpose, derive_seed};

    fn args(objective: &[&str], solver: &[&str], steps: usize, repeats: usize) -> PlannerBenchArgs {
        PlannerBenchArgs {
            objective: objective.iter().map(|s| s.to_string()).collect(),
            solver: solver.iter().map(|s| s.to_string()).collect(),
            steps,
            scenario: None,
            seed: None,
            repeats,
            run_steps: None,
            safety: vec!["certified".into()],
        }
    }

    fn input_error(a: &PlannerBenchArgs) -> String {
        match run(a) {
            Err(e @ (CliError::Input(_) | CliError::InputBecause { .. })) => e.to_string(),
            other => panic!("expected an input error, got {other:?}"),
        }
    }

    #[test]
    fn percentiles_of_known_data() {
        let v: Vec<f64> = (1..=100).rev().map(f64::from).collect();
        let s = Stats::of(&v);
        assert_eq!(s.n, 100);
        assert!((s.median - 50.5).abs() < 1e-12, "{}", s.median);
        assert!((s.p90 - 90.1).abs() < 1e-9, "{}", s.p90);
        assert!((s.p99 - 99.01).abs() < 1e-9, "{}", s.p99);
        assert_eq!(s.max, 100.0);
        assert!((s.mean - 50.5).abs() < 1e-12);
        let odd = Stats::of(&[3.0, 1.0, 2.0]);
        assert_eq!((odd.median, odd.max, odd.mean), (2.0, 3.0, 2.0));
        let one = Stats::of(&[7.0]);
        assert_eq!((one.median, one.p90, one.p99, one.max), (7.0, 7.0, 7.0, 7.0));
        assert!(Stats::of(&[]).median.is_nan());
        let two = Stats::of(&[2.0, 1.0]);
        assert_eq!((two.median, two.max), (1.5, 2.0));
        assert!((two.p99 - 1.99).abs() < 1e-12);
    }

    #[test]
    fn round_robin_covers_every_combination_once_per_round() {
        for count in 1..=15 {
            let mut firsts = Vec::new();
            for round in 0..2 * count + 1 {
                let order: Vec<usize> = round_order(round, count).collect();
                let mut seen = order.clone();
                seen.sort_unstable();
                assert_eq!(seen, (0..count).collect::<Vec<_>>(), "round {round} of {count}");
                firsts.push(order[0]);
            }
            // The starting combination rotates: every combination starts equally often over `count` rounds.
            for j in 0..count {
                assert_eq!(firsts[..count].iter().filter(|&&f| f == j).count(), 1, "{count}: {firsts:?}");
            }
        }
    }

    #[test]
    fn bad_arguments_are_input_errors_naming_the_flag() {
        assert!(input_error(&args(&["analytical"], &["pso"], 0, 1)).contains("--steps"));
        assert!(input_error(&args(&["analytical"], &["pso"], 2, 0)).contains("--repeats"));
        let m = input_error(&args(&["analytical", "fast"], &["pso"], 2, 1));
        assert!(m.contains("--objective") && m.contains("fast"), "{m}");
        let m = input_error(&args(&["analytical"], &["pso", "sa"], 2, 1));
        assert!(m.contains("--solver") && m.contains("sa"), "{m}");
        let mut a = args(&["analytical"], &["pso"], 2, 1);
        a.scenario = Some(PathBuf::from("/nonexistent/uavloc-bench-scenario.toml"));
        assert!(input_error(&a).contains("--scenario"));
        let mut a = args(&["analytical"], &["pso"], 2, 1);
        a.safety = vec!["certified".into(), "safe".into()];
        let m = input_error(&a);
        assert!(m.contains("--safety") && m.contains("safe"), "{m}");
    }

    #[test]
    fn both_safety_modes_are_timed_side_by_side_and_compared_with_pso_in_their_own_mode() {
        let mut a = args(&["analytical"], &["pso", "gradient"], 3, 1);
        a.safety = vec!["certified".into(), "waypoints".into()];
        let r = run(&a).unwrap();
        let rows: Vec<(String, String)> = r.combinations.iter().map(|c| (c.solver.clone(), c.safety.clone())).collect();
        let want = [("pso", "certified"), ("pso", "waypoints"), ("gradient", "certified"), ("gradient", "waypoints")];
        assert_eq!(rows, want.map(|(s, m)| (s.to_string(), m.to_string())));
        assert_eq!(r.reference, "analytical/pso");
        let q: Vec<&str> = r.quality.iter().map(|q| q.safety.as_str()).collect();
        assert_eq!(q, ["certified", "waypoints"]);
    }

    #[test]
    fn lists_parse_with_defaults_and_without_repeats() {
        assert_eq!(parse_list::<SolverKind>("--solver", &[], &SolverKind::ALL).unwrap(), SolverKind::ALL.to_vec());
        let v: Vec<String> = ["ga", "pso", "ga"].iter().map(|s| s.to_string()).collect();
        assert_eq!(parse_list("--solver", &v, &SolverKind::ALL).unwrap(), vec![SolverKind::Ga, SolverKind::Pso]);
    }

    #[test]
    fn clap_flags_parse_lists_and_defaults() {
        #[derive(clap::Parser)]
        struct Wrap {
            #[command(flatten)]
            a: PlannerBenchArgs,
        }
        use clap::Parser as _;
        let w = Wrap::try_parse_from(["x"]).unwrap();
        assert_eq!(
            w.a,
            args(&["single", "mc", "analytical", "cubature", "formation"], &["pso", "ga", "aco", "gradient"], 200, 1)
        );
        let w = Wrap::try_parse_from(["x", "--objective", "analytical,single", "--objective", "mc", "--solver=ga"])
            .unwrap();
        assert_eq!(w.a.objective, ["analytical", "single", "mc"]);
        assert_eq!(w.a.solver, ["ga"]);
    }

    #[test]
    fn inputs_are_those_of_the_closed_loop() {
        let sc = Scenario { steps: 4, ..Scenario::default() };
        let (inputs, runs) = collect_inputs(&sc, 10).unwrap();
        assert_eq!((inputs.len(), runs), (10, 3));
        let run = closed_loop::run_closed_loop(&sc, REFERENCE.0, REFERENCE.1, |_, _| {}).expect("closed loop");
        for (k, input) in inputs[..4].iter().enumerate() {
            let rec = &run.steps[k];
            assert_eq!((input.run_seed, input.step), (sc.seed, k as u64));
            let uavs: Vec<[f64; 2]> = input.positions.iter().map(|p| [p.x, p.y]).collect();
            assert_eq!(uavs, rec.uavs, "step {k}");
            assert_eq!([input.estimate.x, input.estimate.y], rec.estimate, "step {k}");
            assert_eq!(crate::output::rows(&input.covariance), rec.estimate_cov, "step {k}");
            let expected = if k == 0 {
                model::world::World::from_scenario(&sc).unwrap().headings().to_vec()
            } else {
                run.steps[k - 1].headings_rad.clone()
            };
            assert_eq!(input.headings, expected, "step {k}");
        }
        // Later runs use derived seeds and start again at step 0.
        assert_eq!(inputs[4].step, 0);
        assert_eq!(inputs[4].run_seed, derive_seed(sc.seed, 1, Purpose::OuterRun));
        assert_eq!((inputs[9].step, inputs[9].run_seed), (1, derive_seed(sc.seed, 2, Purpose::OuterRun)));
    }

    #[test]
    fn small_run_reports_every_combination() {
        let r = run(&args(&["analytical", "single", "formation"], &["pso", "ga"], 3, 2)).unwrap();
        assert_eq!((r.steps, r.repeats, r.reference.as_str()), (3, 2, "analytical/pso"));
        assert_eq!(r.combinations.len(), 6);
        assert!(r.machine.cpus >= 1);
        assert_eq!(r.settings.pso, [40, 15]);
        for c in &r.combinations {
            let label = format!("{}/{}", c.objective, c.solver);
            assert_eq!(c.n, 6, "{label}");
            assert!(0.0 < c.median_ms && c.median_ms <= c.p90_ms, "{label}: {c:?}");
            assert!(c.p90_ms <= c.p99_ms && c.p99_ms <= c.max_ms, "{label}: {c:?}");
            assert!(c.ratio_to_reference.unwrap() > 0.0);
            let pso_paper = c.solver == "pso" && c.objective != "formation";
            assert_eq!(c.paper_total_mean_ms.is_some(), pso_paper, "{label}");
            assert_eq!(c.paper_opt_ms.is_some(), pso_paper, "{label}");
            assert_eq!(c.evaluations_per_plan == 0.0, c.objective == "formation", "{label}");
        }
        let reference = r.combinations.iter().find(|c| c.objective == "analytical" && c.solver == "pso").unwrap();
        assert_eq!(reference.ratio_to_reference, Some(1.0));
        assert_eq!((reference.paper_total_mean_ms, reference.paper_opt_ms), (Some(152.02), Some(149.38)));
        let json = serde_json::to_value(&r).unwrap();
        for key in ["steps", "repeats", "reference", "combinations", "cpus"] {
            assert!(json.get(key).is_some(), "{key}");
        }
        let text = r.text();
        let rows = text.lines().filter(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            w.len() == 14 && ["pso", "ga"].contains(&w[1])
        });
        assert_eq!(rows.count(), 6, "{text}");
        assert!(!r.table().render().is_empty());
        // Without the reference the ratios are absent.
        let r = run(&args(&["single"], &["ga"], 1, 1)).unwrap();
        assert_eq!(r.combinations[0].ratio_to_reference, None);
        assert!(r.combinations[0].paper_total_mean_ms.is_none());
    }
}
