//! Whether a scenario can be flown: every key within its range, a start that can be localised and is
//! safe, an emitter that stays within the plane model's extent — each refusal naming its key.

use super::*;

impl Scenario {
    /// A certified run starts safe: no two UAVs closer than `D_min` and no UAV within `L_min` of the
    /// emitter at step 0 (a start that is safe but admits no certified plan — two UAVs converging inside
    /// their turn radii — runs, flagged uncertified from step 0).
    fn check_safe_start(&self) -> Result<(), ScenarioError> {
        let n = self.uavs.len();
        for a in 0..n {
            for b in a + 1..n {
                let d = dist(self.uavs[a], self.uavs[b]);
                if self.d_min > 0.0 && d < self.d_min {
                    return Err(invalid(
                        "uavs",
                        format!(
                            "UAV {a} and UAV {b} start {d:.1} m apart, closer than d_min = {} m: an unsafe start \
                             (safety = \"certified\"; \"waypoints\" runs it)",
                            self.d_min
                        ),
                    ));
                }
            }
        }
        for (i, p) in self.uavs.iter().enumerate() {
            let d = dist(*p, self.emitter);
            if self.l_min > 0.0 && d < self.l_min {
                return Err(invalid(
                    "uavs",
                    format!(
                        "UAV {i} starts {d:.1} m from the emitter, inside l_min = {} m: an unsafe start \
                         (safety = \"certified\"; \"waypoints\" runs it)",
                        self.l_min
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Checks every value; the error names the first offending key.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        if self.uavs_lat_lon_deg.is_some() || self.emitter_lat_lon_deg.is_some() {
            return Err(invalid(
                "uavs_lat_lon_deg",
                "latitude/longitude positions are read from TOML only (from_toml_str)",
            ));
        }
        if let Some(origin) = self.origin {
            let frame = LocalFrame::new(origin).map_err(|e| invalid("origin", e.to_string()))?;
            for (key, p) in self
                .uavs
                .iter()
                .enumerate()
                .map(|(i, p)| (format!("uavs[{i}]"), p))
                .chain([("emitter".to_string(), &self.emitter)])
            {
                frame.to_geodetic(*p).map_err(|e| invalid(&key, e.to_string()))?;
            }
        }
        let n = self.uavs.len();
        if !(3..=MAX_UAVS).contains(&n) {
            return Err(invalid("uavs", format!("need 3 to {MAX_UAVS} UAVs, got {n}")));
        }
        if !self.autopilots.is_empty() {
            if self.autopilots.len() != n {
                return Err(invalid(
                    "autopilots",
                    format!(
                        "{} endpoints for {n} UAVs: one MAVLink endpoint per UAV, UAV0 first",
                        self.autopilots.len()
                    ),
                ));
            }
            if self.origin.is_none() {
                return Err(invalid("autopilots", "aircraft need an `[origin]`: their targets are latitude/longitude"));
            }
            if let Some(i) = self.autopilots.iter().position(|e| !e.contains(':') || e.trim() != e) {
                return Err(invalid(
                    &format!("autopilots[{i}]"),
                    format!(
                        "{:?} is not an endpoint (udpin:HOST:PORT, udpout:HOST:PORT, tcpout:HOST:PORT, serial:DEVICE:BAUD)",
                        self.autopilots[i]
                    ),
                ));
            }
        }
        for (i, p) in self.uavs.iter().enumerate() {
            within_extent(&format!("uavs[{i}]"), p)?;
        }
        for a in 0..n {
            for b in a + 1..n {
                let d = dist(self.uavs[a], self.uavs[b]);
                if d < COINCIDENCE_TOLERANCE_M {
                    return Err(invalid("uavs", format!("UAV {a} and UAV {b} coincide (distance {d:.3e} m)")));
                }
            }
        }
        within_extent("emitter", &self.emitter)?;
        for (i, p) in self.uavs.iter().enumerate() {
            if dist(*p, self.emitter) < COINCIDENCE_TOLERANCE_M {
                return Err(invalid("emitter", format!("the emitter sits on UAV {i}")));
            }
        }
        if let Some(h) = &self.headings {
            if h.len() != n {
                return Err(invalid("headings_deg", format!("expected {n} headings (one per UAV), got {}", h.len())));
            }
            finite_all("headings_deg", h)?;
        }
        positive("speed", self.speed)?;
        positive("dt", self.dt)?;
        length("speed", "the distance flown per step, speed × dt", self.speed * self.dt)?;
        match &self.sigma {
            RangeSigma::Uniform(s) => positive("sigma", *s)?,
            RangeSigma::PerUav(s) => {
                if s.len() != n {
                    return Err(invalid("sigma", format!("expected {n} values (one per UAV), got {}", s.len())));
                }
                for v in s {
                    positive("sigma", *v)?;
                }
            }
        }
        self.noise_model()?;
        count("steps", self.steps, 1, MAX_STEPS)?;
        finite("delta_alpha_deg", self.delta_alpha)?;
        if !(self.delta_alpha > 0.0 && self.delta_alpha <= std::f64::consts::PI) {
            return Err(invalid(
                "delta_alpha_deg",
                format!("must be in (0, 180] degrees, got {}", self.delta_alpha.to_degrees()),
            ));
        }
        for (key, v) in [("l_min", self.l_min), ("d_min", self.d_min), ("r_min", self.r_min)] {
            non_negative(key, v)?;
            length(key, key, v)?;
        }
        positive("sigma_t", self.sigma_t)?;
        length("sigma_t", "sigma_t", self.sigma_t)?;
        non_negative("kappa", self.kappa)?;
        count("mc_samples", self.mc_samples, 2, MAX_COUNT)?;
        count("rmse_resamples", self.rmse_resamples, 1, MAX_COUNT)?;
        within_extent("e0", &self.e0)?;
        non_negative("scale", self.scale)?;
        length(
            "scale",
            "the controlled error scale × max(|e0|, sigma_t)",
            self.scale * self.sigma_t.max(norm(self.e0)),
        )?;
        non_negative("process_noise_accel", self.process_noise_accel)?;
        positive("velocity_prior_sigma", self.velocity_prior_sigma)?;
        self.dynamics()?;
        finite_all("emitter_velocity", &self.emitter_velocity)?;
        length(
            "emitter_velocity",
            "the distance the emitter moves per step, |emitter_velocity| × dt",
            norm(self.emitter_velocity) * self.dt,
        )?;
        finite("standoff_confidence", self.standoff_confidence)?;
        positive("safety_horizon_s", self.safety_horizon_s)?;
        if self.safety == SafetyMode::Certified {
            self.check_safe_start()?;
        }
        if !(0.0..1.0).contains(&self.standoff_confidence) {
            return Err(invalid(
                "standoff_confidence",
                format!(
                    "must be in [0, 1) (0: the paper's constraint at the estimate), got {}",
                    self.standoff_confidence
                ),
            ));
        }
        self.receiver.validate().map_err(|(key, reason)| invalid(&key, reason))?;
        non_negative("early_stop.tolerance", self.early_stop.tolerance)?;
        count("pso.particles", self.pso.particles, 1, MAX_COUNT)?;
        count("pso.iterations", self.pso.iterations, 1, MAX_COUNT)?;
        positive("pso.v_max_fraction", self.pso.v_max_fraction)?;
        count("ga.population", self.ga.population, 2, MAX_COUNT)?;
        count("ga.generations", self.ga.generations, 1, MAX_COUNT)?;
        count("ga.tournament", self.ga.tournament, 1, MAX_COUNT)?;
        probability("ga.crossover_rate", self.ga.crossover_rate)?;
        non_negative("ga.blx_alpha", self.ga.blx_alpha)?;
        probability("ga.mutation_rate", self.ga.mutation_rate)?;
        non_negative("ga.mutation_scale", self.ga.mutation_scale)?;
        if self.ga.elites >= self.ga.population {
            return Err(invalid("ga.elites", format!("must be below ga.population ({})", self.ga.population)));
        }
        count("aco.archive", self.aco.archive, 1, MAX_COUNT)?;
        count("aco.ants", self.aco.ants, 1, MAX_COUNT)?;
        count("aco.iterations", self.aco.iterations, 1, MAX_COUNT)?;
        positive("aco.evaporation", self.aco.evaporation)?;
        positive("aco.elite_fraction", self.aco.elite_fraction)?;
        count("gradient.starts", self.gradient.starts, 1, MAX_COUNT)?;
        count("gradient.iterations", self.gradient.iterations, 1, MAX_COUNT)?;
        positive("gradient.tolerance", self.gradient.tolerance)?;
        if self.gradient.tolerance > std::f64::consts::PI {
            return Err(invalid(
                "gradient.tolerance",
                format!("must be at most π rad (half a turn of heading), got {:e}", self.gradient.tolerance),
            ));
        }
        Ok(())
    }

    /// Whether the emitter stays within the plane model's extent (±[`MAX_EXTENT_M`]) to the last step: its
    /// whole path is known (`emitter + k·dt·emitter_velocity`), and the extent is convex, so the end of the
    /// path decides. Checked by [`load_scenario`] once `--steps` is applied (a file may be fine for fewer
    /// steps than its own).
    pub fn check_path(&self) -> Result<(), ScenarioError> {
        let end = self.emitter_at(self.steps as u64);
        if end.iter().all(|c| c.abs() <= MAX_EXTENT_M) {
            return Ok(());
        }
        let speed = norm(self.emitter_velocity) * self.dt;
        let first = (1..=self.steps as u64).find(|&k| self.emitter_at(k).iter().any(|c| c.abs() > MAX_EXTENT_M));
        Err(invalid(
            "emitter_velocity",
            format!(
                "the emitter ({speed:e} m per step) leaves the plane model's extent, ±{MAX_EXTENT_M:e} m, at step \
                 {} of {}: slow it down or shorten the run",
                first.unwrap_or(self.steps as u64),
                self.steps
            ),
        ))
    }

    /// Whether the run can localise the emitter from its start: Chan must solve the noise-free step 0
    /// (it refuses three collinear UAVs, for one), and the CRLB at the true emitter must be below
    /// [`START_CRLB_FACTOR`] = 100 times the UAVs' mean distance to it. The bound of n fused snapshots of
    /// one geometry shrinks like 1/√n, so beyond that factor not even 10 000 snapshots would bring it
    /// below the range: no fix can mean anything, and Chan has no physical root for most draws. A run that fails here would fail at step 0 every time: it is refused up front,
    /// naming the key to change (`uavloc simulate` and `launch`, and every process, through
    /// [`load_scenario`]).
    pub fn check_start(&self) -> Result<(), ScenarioError> {
        let noise = self.noise_model()?;
        let sensors = tdoa::Sensors::new(&self.uavs, noise).map_err(|e| invalid("uavs", e.to_string()))?;
        let z = self.emitter_position();
        let d = sensors.range_differences(&z);
        let why = |what: String| {
            invalid(
                "uavs",
                format!(
                    "the emitter cannot be localised from the start of the run: {what}; move the UAVs (or the emitter)"
                ),
            )
        };
        tdoa::chan(&sensors, &d, Some(z)).map_err(|e| why(e.to_string()))?;
        let bound = tdoa::crlb(&sensors, &z).map_err(|e| why(e.to_string()))?.crlb_m;
        let range = sensors.mean_range(&z);
        if bound.is_nan() || bound >= START_CRLB_FACTOR * range {
            return Err(invalid(
                "sigma",
                format!(
                    "the emitter cannot be localised from the start of the run: the CRLB at the true emitter \
                     ({bound:.3e} m) is not below {START_CRLB_FACTOR} times the UAVs' mean distance to it \
                     ({range:.0} m); lower sigma"
                ),
            ));
        }
        Ok(())
    }
}

/// The factor of [`Scenario::check_start`]: a start whose CRLB at the truth is this many times the UAVs'
/// mean distance to the emitter or more is refused.
pub const START_CRLB_FACTOR: f64 = 100.0;

/// The most steps a run may have: the run record is held in memory at its end (≈ 1.5 KB per step).
pub const MAX_STEPS: usize = 1_000_000;

/// The most of any solver's population or iterations, of the `mc` criterion's samples and of the RMSE's
/// resamples: the criterion is evaluated for every candidate of every step, and a population is held in
/// memory; beyond this a step takes hours, or the allocation fails (a count of 10¹¹ aborted the run).
pub const MAX_COUNT: usize = 100_000;

fn finite(key: &str, v: f64) -> Result<(), ScenarioError> {
    if v.is_finite() { Ok(()) } else { Err(invalid(key, format!("must be a finite number, got {v}"))) }
}

fn finite_all(key: &str, v: &[f64]) -> Result<(), ScenarioError> {
    v.iter().try_for_each(|x| finite(key, *x))
}

/// Every coordinate of a point within ±[`MAX_EXTENT_M`] (finite first).
fn within_extent(key: &str, v: &[f64]) -> Result<(), ScenarioError> {
    finite_all(key, v)?;
    match v.iter().find(|x| x.abs() > MAX_EXTENT_M) {
        Some(x) => Err(invalid(
            key,
            format!("coordinates must be within ±{MAX_EXTENT_M:e} m (the plane model's extent), got {x:e}"),
        )),
        None => Ok(()),
    }
}

/// A length `what` (metres) at most [`MAX_EXTENT_M`].
fn length(key: &str, what: &str, v: f64) -> Result<(), ScenarioError> {
    if v <= MAX_EXTENT_M {
        Ok(())
    } else {
        Err(invalid(key, format!("{what} must be at most {MAX_EXTENT_M:e} m (the plane model's extent), got {v:e} m")))
    }
}

fn positive(key: &str, v: f64) -> Result<(), ScenarioError> {
    finite(key, v)?;
    if v > 0.0 { Ok(()) } else { Err(invalid(key, format!("must be > 0, got {v}"))) }
}

fn non_negative(key: &str, v: f64) -> Result<(), ScenarioError> {
    finite(key, v)?;
    if v >= 0.0 { Ok(()) } else { Err(invalid(key, format!("must be ≥ 0, got {v}"))) }
}

fn probability(key: &str, v: f64) -> Result<(), ScenarioError> {
    finite(key, v)?;
    if (0.0..=1.0).contains(&v) { Ok(()) } else { Err(invalid(key, format!("must be in [0, 1], got {v}"))) }
}

/// A count `v` of `key` within `min..=max`.
fn count(key: &str, v: usize, min: usize, max: usize) -> Result<(), ScenarioError> {
    if (min..=max).contains(&v) { Ok(()) } else { Err(invalid(key, format!("must be in {min}..={max}, got {v}"))) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_start_that_cannot_be_localised_is_refused() {
        Scenario::default().check_start().unwrap();
        Scenario { sigma: RangeSigma::Uniform(500.0), ..Scenario::default() }.check_start().unwrap();
        let collinear = Scenario { uavs: vec![[0.0, 0.0], [5000.0, 0.0], [10000.0, 0.0]], ..Scenario::default() };
        assert_eq!(collinear.check_start().unwrap_err().key(), Some("uavs"));
        let noisy = Scenario { sigma: RangeSigma::Uniform(1e9), ..Scenario::default() };
        assert_eq!(noisy.check_start().unwrap_err().key(), Some("sigma"));
        // Four UAVs on a square with the emitter on its axis: Chan's first step cannot tell r₀ from the
        // position, but the emitter is fixed — not refused.
        let square = "uavs = [[-5000.0, 20000.0], [5000.0, 20000.0], [-5000.0, 30000.0], [5000.0, 30000.0]]\n\
                      emitter = [0.0, 0.0]\n";
        Scenario::from_toml_str(square).unwrap().check_start().unwrap();
    }

    #[test]
    fn an_unsafe_start_is_refused_naming_the_uavs_unless_the_waypoint_planner_flies_it() {
        let close = "uavs = [[0.0, 0.0], [300.0, 0.0], [0.0, 5000.0]]\nemitter = [40000.0, 0.0]\n";
        let e = Scenario::from_toml_str(close).unwrap_err().to_string();
        assert!(e.contains("UAV 0 and UAV 1") && e.contains("d_min = 500") && e.contains("unsafe start"), "{e}");
        let inside = "uavs = [[0.0, 0.0], [3000.0, 0.0], [0.0, 5000.0]]\nemitter = [1000.0, 1000.0]\n";
        let e = Scenario::from_toml_str(inside).unwrap_err().to_string();
        assert!(e.contains("UAV 0 starts") && e.contains("l_min = 3000"), "{e}");
        // The paper's planner keeps its constraints at the waypoints and runs such a start.
        Scenario::from_toml_str(&format!("{close}safety = \"waypoints\"\n")).unwrap();
        // A safe start is not refused.
        Scenario::from_toml_str("uavs = [[0.0, 0.0], [600.0, 0.0], [0.0, 5000.0]]\nemitter = [40000.0, 0.0]\n")
            .unwrap();
    }

    #[test]
    fn invalid_values_are_named() {
        let cases = [
            ("uavs = [[0.0, 0.0], [1.0, 0.0]]", "uavs"),
            ("uavs = [[0,0],[1,0],[2,0],[3,0],[4,0],[5,0],[6,0],[7,0],[8,0]]", "uavs"),
            ("uavs = [[0.0, 0.0], [1000.0, 0.0], [0.0, 0.0]]", "uavs"),
            ("uavs = [[0.0, 0.0], [1000.0, 0.0], [0.0, inf]]", "uavs[2]"),
            ("uavs = [[0.0, 0.0], [1000.0, 0.0], [0.0, 1e400]]", "uavs"),
            ("emitter = [1500.0, 500.0]", "emitter"),
            ("emitter = [nan, 0.0]", "emitter"),
            ("speed = 0", "speed"),
            ("speed = -5.0", "speed"),
            ("speed = inf", "speed"),
            ("dt = 0", "dt"),
            ("steps = 0", "steps"),
            ("sigma = 0.0", "sigma"),
            ("sigma = [1.0, -1.0, 1.0]", "sigma"),
            ("delta_alpha_deg = 0", "delta_alpha_deg"),
            ("delta_alpha_deg = 181", "delta_alpha_deg"),
            ("l_min = -1", "l_min"),
            ("d_min = -1", "d_min"),
            ("r_min = -1", "r_min"),
            ("sigma_t = 0", "sigma_t"),
            ("kappa = -0.1", "kappa"),
            ("mc_samples = 1", "mc_samples"),
            ("mc_samples = 100001", "mc_samples"),
            ("steps = 1000001", "steps"),
            ("[pso]\nparticles = 100001", "pso.particles"),
            ("[gradient]\niterations = 100001", "gradient.iterations"),
            ("rmse_resamples = 0", "rmse_resamples"),
            ("scale = -1", "scale"),
            ("headings_deg = [0.0, 1.0]", "headings_deg"),
            ("[pso]\nparticles = 0", "pso.particles"),
            ("[pso]\niterations = 0", "pso.iterations"),
            ("[ga]\npopulation = 0", "ga.population"),
            ("[ga]\nmutation_rate = 2.0", "ga.mutation_rate"),
            ("[ga]\nelites = 40", "ga.elites"),
            ("[aco]\nants = 0", "aco.ants"),
            ("[gradient]\nstarts = 0", "gradient.starts"),
            ("[gradient]\ntolerance = 0", "gradient.tolerance"),
            ("[aco]\nevaporation = 0", "aco.evaporation"),
            ("[early_stop]\ntolerance = -1", "early_stop.tolerance"),
            // Finite but beyond the model's lengths: refused, never a panic or a NaN in the run.
            ("uavs = [[1500.0, 500.0], [10000.0, 1500.0], [5000.0, 2e7]]", "uavs[2]"),
            ("emitter = [-2e7, 15000.0]", "emitter"),
            ("speed = 1e300", "speed"),
            ("dt = 1e300", "speed"),
            ("l_min = 1e300", "l_min"),
            ("d_min = 2e7", "d_min"),
            ("r_min = 1e300", "r_min"),
            ("sigma_t = 1e300", "sigma_t"),
            ("sigma = 1e300", "sigma"),
            ("sigma = 1e-300", "sigma"),
            ("e0 = [1e300, 0.0]", "e0"),
            ("scale = 1e300", "scale"),
            ("emitter_velocity = [1e300, 0.0]", "emitter_velocity"),
            ("velocity_prior_sigma = 1e300", "velocity_prior_sigma"),
            ("process_noise_accel = 1e300", "process_noise_accel"),
            ("[gradient]\ntolerance = 1e300", "gradient.tolerance"),
        ];
        for (text, key) in cases {
            let e = Scenario::from_toml_str(text).unwrap_err();
            assert_eq!(e.key(), Some(key), "{text}: {e}");
        }
    }

    #[test]
    fn an_emitter_that_leaves_the_extent_before_the_last_step_is_refused_for_that_run_only() {
        // 50 km/s × 10 s per step: within the per-step bound; out of ±1e7 m at step 20 (x = 25 km + 20 · 500 km).
        let s = Scenario::from_toml_str("emitter_velocity = [50000.0, 0.0]").unwrap();
        let e = s.check_path().unwrap_err();
        assert_eq!(e.key(), Some("emitter_velocity"), "{e}");
        assert!(e.to_string().contains("at step 20 of 24"), "{e}");
        let short = Scenario { steps: 19, ..s };
        assert!(short.check_path().is_ok());
    }
}
