//! The solvers' settings as the scenario carries them (`[pso]`, `[ga]`, `[aco]`, `[gradient]`, `[early_stop]`): plain
//! data, so that every process can read a scenario without the planner. The solvers themselves are in
//! `uavloc-planning`.

/// PSO sizes (paper Table 1/3: 40 particles × 15 iterations) and the velocity clamp.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PsoConfig {
    /// Swarm size N (paper: 40).
    pub particles: usize,
    /// Maximum iterations k_max after initialisation (paper: 15).
    pub iterations: usize,
    /// `v_max` as a fraction of each interval's width — our choice, 0.2.
    pub v_max_fraction: f64,
}

impl Default for PsoConfig {
    fn default() -> Self {
        Self { particles: 40, iterations: 15, v_max_fraction: 0.2 }
    }
}

/// GA sizes (paper Table 3: 40 individuals × 15 generations) and operator settings (our choice).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GaConfig {
    /// Population size (paper: 40).
    pub population: usize,
    /// Generations after the initial population (paper: 15).
    pub generations: usize,
    /// Tournament size — our choice, 2.
    pub tournament: usize,
    /// Probability that a pair of parents is recombined — our choice, 0.9.
    pub crossover_rate: f64,
    /// α of BLX-α — our choice, 0.5.
    pub blx_alpha: f64,
    /// Per-gene mutation probability — our choice, 0.2.
    pub mutation_rate: f64,
    /// Mutation standard deviation as a fraction of the interval width — our choice, 0.1.
    pub mutation_scale: f64,
    /// Individuals copied unchanged into the next generation — our choice, 2.
    pub elites: usize,
}

impl Default for GaConfig {
    fn default() -> Self {
        Self {
            population: 40,
            generations: 15,
            tournament: 2,
            crossover_rate: 0.9,
            blx_alpha: 0.5,
            mutation_rate: 0.2,
            mutation_scale: 0.1,
            elites: 2,
        }
    }
}

/// ACO_R sizes and parameters (paper Table 3).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AcoConfig {
    /// Archive size k — our choice, 40 (equal to the ant count).
    pub archive: usize,
    /// Ants per iteration (paper: 40).
    pub ants: usize,
    /// Iterations after the initial archive (paper: 15).
    pub iterations: usize,
    /// ξ, the width of the Gaussian kernels relative to the archive spread (paper: "evaporation" 0.35).
    pub evaporation: f64,
    /// q, the locality of the rank weights (paper: "elite fraction" 0.25).
    pub elite_fraction: f64,
}

impl Default for AcoConfig {
    fn default() -> Self {
        Self { archive: 40, ants: 40, iterations: 15, evaporation: 0.35, elite_fraction: 0.25 }
    }
}

/// Settings of the gradient solver (ours; not in the paper).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GradientConfig {
    /// Local searches, from the best of the evaluated starts (current headings, cone centre, cone
    /// corners) — 2.
    pub starts: usize,
    /// Most quasi-Newton iterations per local search — 30.
    pub iterations: usize,
    /// A local search stops when its step moves no heading by more than this, radians — 1e-7.
    pub tolerance: f64,
}

impl Default for GradientConfig {
    fn default() -> Self {
        Self { starts: 2, iterations: 30, tolerance: 1e-7 }
    }
}

/// The paper's stopping rule (Section 4.3), shared by all solvers: stop when the best fitness has
/// improved by less than a threshold over `window` consecutive iterations (or at the iteration limit).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EarlyStop {
    /// Consecutive insignificant iterations that stop the search (the paper's 5).
    pub window: usize,
    /// Relative improvement of the best objective below which an iteration is insignificant — our
    /// choice, 1e-4 (the paper calls it "a predefined threshold"). A drop in violation by more than
    /// this fraction, or the first feasible best, always counts as significant.
    pub tolerance: f64,
}

impl Default for EarlyStop {
    fn default() -> Self {
        Self { window: 5, tolerance: 1e-4 }
    }
}
