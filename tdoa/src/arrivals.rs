//! One burst as a receiver front end gives it: the arrivals of the UAVs that heard it, as ranges with a
//! common unknown offset, and each UAV's error budget.
//!
//! A real front end does not hand over N − 1 range differences to UAV0. Each UAV's receiver times the
//! burst on its own clock; an arrival may be lost, the emitter may be silent, one arrival may be late by
//! a multipath reflection. [`Arrivals`] holds what one step really has: the reported UAV positions,
//! which UAVs heard the burst (any subset, any of them the reference), their arrival times as ranges
//! `a_i = c·(t_i − t_epoch)` with an unknown common epoch, and per UAV the 1σ of every error source.
//! [`Arrivals::heard`] turns it into the differences to the first UAV that heard it, with the effective
//! noise below, which every estimator and bound of the crate takes ([`Sensors`], [`RangeDiffs`]).
//!
//! ## The effective noise (derivation)
//! UAV i reports `ŝ_i = s_i + e_i` (GNSS error `e_i ~ N(0, σ_g² I₂)`) and times the burst at its true
//! position with clock error `δ_i` (range `c·δ_i ~ N(0, σ_c²)`) and range noise `n_i ~ N(0, σ_r²)`:
//! `a_i = |z − s_i| + c·δ_i + n_i`. To first order in `|e_i| / r_i`,
//! `|z − s_i| = |z − ŝ_i + e_i| ≈ r̂_i + u_iᵀ e_i` with `u_i = (z − ŝ_i)/r̂_i`, so the arrival error in
//! the reported frame is `u_iᵀ e_i + c·δ_i + n_i`: with `J_s = [u_iᵀ, 1]` and `Σ_s = diag(σ_g² I₂, σ_c²)`
//! its variance is `σ_r² + J_s Σ_s J_sᵀ = σ_r² + σ_g² + σ_c²` — independent of the direction `u_i`
//! because the GNSS error is isotropic. The arrivals of different UAVs stay independent, so the range
//! differences keep the structure of eq. 19 with `s_i² = σ_r² + σ_g² + σ_c²`: `Q_eff = Q + J Σ_s Jᵀ`.
//!
//! ## The persistent part
//! GNSS and clock errors are not white: a part of each lasts the whole flight (`σ_gb`, `σ_cb`). Such a
//! bias never averages out: fusing K snapshots shrinks the white part of the error like 1/K, not the
//! bias's. The estimators here keep the bias variance in the per-step noise (so that the χ² gate sees
//! the real spread of the innovations). [`bias_covariance`] is the covariance of the position error the
//! biases alone cause in one snapshot of the swarm's geometry, `(Hᵀ Q_b⁻¹ H)⁻¹` with `Q_b` built from
//! `s_i² = σ_gb² + σ_cb²` (the bound's bias part). The estimators carry the bias as a consider state
//! ([`crate::consider`]): the fused estimate keeps the bias error of the earlier steps' geometries too,
//! which this snapshot covariance at the current geometry misses (measured with it: mean NEES 2.4–3.6
//! instead of 2 at steps 5–15 with 5 m and 10 ns biases).
//!
//! Units: metres (positions, arrivals, σ), m² (covariances).

use nalgebra::{Matrix2, Vector2};

use crate::geometry::check_finite;
use crate::{MAX_UAVS, NoiseModel, RangeDiffs, Sensors, TdoaError};

/// One UAV's error sources beyond its range noise, 1σ, metres (clocks as `c·σ_t`).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct SensorErrors {
    /// GNSS position error per axis that changes every step.
    pub gnss_m: f64,
    /// GNSS position bias per axis that lasts the flight.
    pub gnss_bias_m: f64,
    /// Clock error (as range) that changes every step.
    pub clock_m: f64,
    /// Clock bias (as range) that lasts the flight.
    pub clock_bias_m: f64,
}

impl SensorErrors {
    /// The variance the white parts add to an arrival, `σ_g² + σ_c²`, m².
    pub fn white_variance(&self) -> f64 {
        self.gnss_m * self.gnss_m + self.clock_m * self.clock_m
    }

    /// The variance the persistent parts add to an arrival, `σ_gb² + σ_cb²`, m².
    pub fn bias_variance(&self) -> f64 {
        self.gnss_bias_m * self.gnss_bias_m + self.clock_bias_m * self.clock_bias_m
    }

    /// The effective range σ of an arrival with range noise `range_sigma`:
    /// `sqrt(σ_r² + σ_g² + σ_c² + σ_gb² + σ_cb²)`, metres.
    /// Exactly `range_sigma` without sensor errors (no rounding through the square root).
    pub fn effective_sigma(&self, range_sigma: f64) -> f64 {
        let extra = self.white_variance() + self.bias_variance();
        if extra == 0.0 { range_sigma } else { (range_sigma * range_sigma + extra).sqrt() }
    }

    /// Every σ finite and ≥ 0.
    pub fn validate(&self, uav: usize) -> Result<(), TdoaError> {
        for (what, v) in [
            ("GNSS σ", self.gnss_m),
            ("GNSS bias σ", self.gnss_bias_m),
            ("clock σ", self.clock_m),
            ("clock bias σ", self.clock_bias_m),
        ] {
            check_finite(format_args!("the {what} of UAV {uav}"), v)?;
            if v < 0.0 {
                return Err(TdoaError::NonPositive { what: format!("the {what} of UAV {uav} (or 0)"), value: v });
            }
        }
        Ok(())
    }
}

/// What the estimator does with a burst that fails its χ² gate (the estimator's `outliers` module
/// identifies the arrivals).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OutlierPolicy {
    /// Reject the whole burst (every arrival of it).
    Snapshot,
    /// Identify and drop the outlying arrivals, fuse the rest.
    #[default]
    Arrival,
}

impl OutlierPolicy {
    /// `snapshot` or `arrival`.
    pub fn name(self) -> &'static str {
        match self {
            OutlierPolicy::Snapshot => "snapshot",
            OutlierPolicy::Arrival => "arrival",
        }
    }

    /// From its name.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "snapshot" => Some(OutlierPolicy::Snapshot),
            "arrival" => Some(OutlierPolicy::Arrival),
            _ => None,
        }
    }
}

/// The arrivals of one step (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Arrivals {
    n: usize,
    positions: [Vector2<f64>; MAX_UAVS],
    arrivals: [f64; MAX_UAVS],
    heard: u8,
    /// Effective σ per UAV (range noise and every sensor error), metres.
    sigmas: [f64; MAX_UAVS],
    /// The persistent part alone, `sqrt(σ_gb² + σ_cb²)`, metres.
    bias_sigmas: [f64; MAX_UAVS],
}

/// The UAVs that heard one burst, as the estimators take them: the first of them is the reference.
#[derive(Debug, Clone, PartialEq)]
pub struct Heard {
    /// The UAV index of each sensor (ascending).
    pub uavs: Vec<usize>,
    /// The geometry with the effective noise.
    pub sensors: Sensors,
    /// `d_k = a_{uavs[k]} − a_{uavs[0]}`, metres.
    pub diffs: RangeDiffs,
}

/// The bit of UAV `i` in a heard mask.
pub fn bit(i: usize) -> u8 {
    1u8 << i
}

impl Arrivals {
    /// The arrivals of a swarm of `positions.len()` UAVs (3..=8) of which those in the mask `heard`
    /// (bit i: UAV i) heard the burst. `arrivals` (metres, a common offset) are read for the UAVs heard
    /// only; `sigmas` are the effective σ (> 0), `bias_sigmas` their persistent part (≥ 0, ≤ σ).
    pub fn new(
        positions: &[[f64; 2]],
        arrivals: &[f64],
        heard: u8,
        sigmas: &[f64],
        bias_sigmas: &[f64],
    ) -> Result<Self, TdoaError> {
        let n = positions.len();
        if !(3..=MAX_UAVS).contains(&n) {
            return Err(TdoaError::UavCount { got: n, min: 3, max: MAX_UAVS });
        }
        for (what, len) in [("arrivals", arrivals.len()), ("sigmas", sigmas.len()), ("bias sigmas", bias_sigmas.len())]
        {
            if len != n {
                return Err(TdoaError::LengthMismatch { what: what.into(), expected: n, got: len });
            }
        }
        if n < MAX_UAVS && heard >> n != 0 {
            return Err(TdoaError::OutOfRange {
                what: "the heard mask".into(),
                value: heard as f64,
                min: 0.0,
                max: ((1u32 << n) - 1) as f64,
            });
        }
        let mut a = Self {
            n,
            positions: [Vector2::zeros(); MAX_UAVS],
            arrivals: [0.0; MAX_UAVS],
            heard,
            sigmas: [0.0; MAX_UAVS],
            bias_sigmas: [0.0; MAX_UAVS],
        };
        for i in 0..n {
            check_finite(format_args!("x of UAV {i}"), positions[i][0])?;
            check_finite(format_args!("y of UAV {i}"), positions[i][1])?;
            a.positions[i] = Vector2::new(positions[i][0], positions[i][1]);
            check_finite(format_args!("the σ of UAV {i}"), sigmas[i])?;
            if sigmas[i] <= 0.0 {
                return Err(TdoaError::NonPositive { what: format!("the σ of UAV {i}"), value: sigmas[i] });
            }
            check_finite(format_args!("the bias σ of UAV {i}"), bias_sigmas[i])?;
            if !(0.0..=sigmas[i]).contains(&bias_sigmas[i]) {
                return Err(TdoaError::OutOfRange {
                    what: format!("the bias σ of UAV {i} (m)"),
                    value: bias_sigmas[i],
                    min: 0.0,
                    max: sigmas[i],
                });
            }
            a.sigmas[i] = sigmas[i];
            a.bias_sigmas[i] = bias_sigmas[i];
            if heard & bit(i) != 0 {
                check_finite(format_args!("the arrival of UAV {i}"), arrivals[i])?;
                a.arrivals[i] = arrivals[i];
            }
        }
        Ok(a)
    }

    /// Every UAV heard the burst: `arrivals[0] = 0`, `arrivals[i] = d_i` (today's range differences to
    /// UAV0), with the σ of `noise` and no bias.
    pub fn all(positions: &[[f64; 2]], d: &RangeDiffs, noise: &NoiseModel) -> Result<Self, TdoaError> {
        let n = positions.len();
        let mut arrivals = vec![0.0; n];
        if d.as_slice().len() + 1 != n {
            return Err(TdoaError::LengthMismatch {
                what: "range differences".into(),
                expected: n.saturating_sub(1),
                got: d.as_slice().len(),
            });
        }
        arrivals[1..].copy_from_slice(d.as_slice());
        let mask = if n >= 8 { u8::MAX } else { (1u8 << n) - 1 };
        Self::new(positions, &arrivals, mask, noise.sigmas(), &vec![0.0; n])
    }

    /// Number of UAVs in the swarm.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Never: a swarm has at least 3 UAVs.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The mask of the UAVs that heard the burst (bit i: UAV i).
    pub fn heard_mask(&self) -> u8 {
        self.heard
    }

    /// How many UAVs heard it.
    pub fn heard_count(&self) -> usize {
        self.heard.count_ones() as usize
    }

    /// UAV `i`'s arrival, metres (common offset); `None` when it did not hear the burst.
    pub fn arrival(&self, i: usize) -> Option<f64> {
        (i < self.n && self.heard & bit(i) != 0).then(|| self.arrivals[i])
    }

    /// The reported UAV positions, metres.
    pub fn positions(&self) -> &[Vector2<f64>] {
        &self.positions[..self.n]
    }

    /// The effective σ per UAV, metres.
    pub fn sigmas(&self) -> &[f64] {
        &self.sigmas[..self.n]
    }

    /// The persistent part of each UAV's σ, metres.
    pub fn bias_sigmas(&self) -> &[f64] {
        &self.bias_sigmas[..self.n]
    }

    /// The same burst without UAV `uav`'s arrival (e.g. one identified as an outlier).
    pub fn without(&self, uav: usize) -> Self {
        let mut a = *self;
        if uav < MAX_UAVS {
            a.heard &= !bit(uav);
            a.arrivals[uav] = 0.0;
        }
        a
    }

    /// The same burst with UAV `uav`'s σ (metres) set to `sigma`: finite, positive and at least its
    /// persistent part.
    pub fn with_sigma(&self, uav: usize, sigma: f64) -> Result<Self, TdoaError> {
        if uav >= self.n {
            return Err(TdoaError::OutOfRange {
                what: "the UAV whose σ is set".into(),
                value: uav as f64,
                min: 0.0,
                max: (self.n - 1) as f64,
            });
        }
        check_finite(format_args!("the σ of UAV {uav}"), sigma)?;
        if sigma <= 0.0 || sigma < self.bias_sigmas[uav] {
            return Err(TdoaError::OutOfRange {
                what: format!("the σ of UAV {uav} (m)"),
                value: sigma,
                min: self.bias_sigmas[uav],
                max: f64::INFINITY,
            });
        }
        let mut a = *self;
        a.sigmas[uav] = sigma;
        Ok(a)
    }

    /// The same burst without the arrivals of the UAVs in `mask` (bit i: UAV i).
    pub fn without_all(&self, mask: u8) -> Self {
        (0..self.n).filter(|&j| mask & bit(j) != 0).fold(*self, |a, j| a.without(j))
    }

    /// The whole swarm's geometry with the effective noise (what a planner or a bound of the swarm
    /// uses, whoever heard this burst).
    pub fn swarm(&self) -> Result<Sensors, TdoaError> {
        let pts: Vec<[f64; 2]> = self.positions().iter().map(|p| [p.x, p.y]).collect();
        Sensors::new(&pts, NoiseModel::from_range_sigmas(self.sigmas())?)
    }

    /// The UAVs that heard the burst as differences to the first of them; `Ok(None)` when fewer than
    /// two did (a silent step: nothing to fuse, the estimate is predicted).
    pub fn heard(&self) -> Result<Option<Heard>, TdoaError> {
        let uavs: Vec<usize> = (0..self.n).filter(|&i| self.heard & bit(i) != 0).collect();
        if uavs.len() < 2 {
            return Ok(None);
        }
        let pts: Vec<[f64; 2]> = uavs.iter().map(|&i| [self.positions[i].x, self.positions[i].y]).collect();
        let sig: Vec<f64> = uavs.iter().map(|&i| self.sigmas[i]).collect();
        let sensors = Sensors::heard(&pts, NoiseModel::heard(&sig)?)?;
        let r = self.arrivals[uavs[0]];
        let d: Vec<f64> = uavs[1..].iter().map(|&i| self.arrivals[i] - r).collect();
        Ok(Some(Heard { uavs, sensors, diffs: RangeDiffs::heard(&d)? }))
    }

    /// The consider covariance of the persistent errors at `z` (see the module documentation), m²; zero
    /// when no UAV has a bias, `None` when the swarm's geometry gives no bound there.
    pub fn bias_covariance(&self, z: &Vector2<f64>) -> Option<Matrix2<f64>> {
        bias_covariance(self.positions(), self.bias_sigmas(), z)
    }
}

/// `(Hᵀ Q_b⁻¹ H)⁻¹` of the swarm at `positions` with per-UAV bias σ `bias_sigmas` at `z` (see the module
/// documentation), m²: zero when every bias σ is 0; `None` when the geometry gives no bound.
pub fn bias_covariance(positions: &[Vector2<f64>], bias_sigmas: &[f64], z: &Vector2<f64>) -> Option<Matrix2<f64>> {
    if bias_sigmas.iter().all(|s| *s == 0.0) {
        return Some(Matrix2::zeros());
    }
    // A UAV without a bias: a tiny σ keeps Q_b invertible; it then pins its own range, as it should.
    let sig: Vec<f64> = bias_sigmas.iter().map(|s| s.max(crate::MIN_SIGMA_M * 1e3)).collect();
    let pts: Vec<[f64; 2]> = positions.iter().map(|p| [p.x, p.y]).collect();
    let sensors = Sensors::new(&pts, NoiseModel::from_range_sigmas(&sig).ok()?).ok()?;
    crate::crlb(&sensors, z).ok().map(|c| c.bound)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn swarm() -> Vec<[f64; 2]> {
        vec![[1500.0, 500.0], [10000.0, 1500.0], [5000.0, 8500.0], [-3000.0, 4000.0]]
    }

    #[test]
    fn all_heard_gives_todays_differences_and_noise() {
        let z = Vector2::new(25000.0, 15000.0);
        let noise = NoiseModel::from_range_sigmas(&[10.0, 20.0, 30.0, 40.0]).unwrap();
        let sensors = Sensors::new(&swarm(), noise.clone()).unwrap();
        let d = sensors.range_differences(&z);
        let a = Arrivals::all(&swarm(), &d, &noise).unwrap();
        let h = a.heard().unwrap().unwrap();
        assert_eq!(h.uavs, vec![0, 1, 2, 3]);
        assert_eq!(h.diffs, d);
        assert_eq!(h.sensors.noise(), &noise);
    }

    #[test]
    fn any_reference_gives_the_same_differences_of_the_arrivals() {
        // Arrivals with an unknown offset: losing UAV0 makes UAV1 the reference.
        let z = Vector2::new(20000.0, 9000.0);
        let pos = swarm();
        let r: Vec<f64> = pos.iter().map(|p| (z - Vector2::new(p[0], p[1])).norm() + 12345.0).collect();
        let a = Arrivals::new(&pos, &r, 0b1111, &[5.0; 4], &[0.0; 4]).unwrap().without(0);
        let h = a.heard().unwrap().unwrap();
        assert_eq!(h.uavs, vec![1, 2, 3]);
        let exact = h.sensors.range_differences(&z);
        for (got, want) in h.diffs.as_slice().iter().zip(exact.as_slice()) {
            assert!((got - want).abs() < 1e-8, "{got} vs {want}");
        }
        // Two heard: one difference; one heard: nothing.
        let two = a.without(3).heard().unwrap().unwrap();
        assert_eq!((two.uavs.clone(), two.diffs.as_slice().len()), (vec![1, 2], 1));
        assert!(a.without(3).without(2).heard().unwrap().is_none());
    }

    #[test]
    fn effective_sigma_adds_the_variances() {
        let e = SensorErrors { gnss_m: 3.0, gnss_bias_m: 4.0, clock_m: 12.0, clock_bias_m: 0.0 };
        assert!((e.effective_sigma(0.0) - 13.0).abs() < 1e-12);
        assert!((e.effective_sigma(5.0) - (25.0f64 + 169.0).sqrt()).abs() < 1e-12);
        assert!(SensorErrors { gnss_m: -1.0, ..e }.validate(0).is_err());
        assert!(SensorErrors { clock_m: f64::NAN, ..e }.validate(0).is_err());
    }

    #[test]
    fn the_gnss_error_adds_its_variance_along_any_line_of_sight() {
        // Monte Carlo of the first-order claim: the range from a position displaced by an isotropic
        // e ~ N(0, σ_g² I) varies by σ_g whatever the direction to the emitter.
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let g = Normal::new(0.0, 20.0).unwrap();
        let s = Vector2::new(1000.0, -2000.0);
        for z in [Vector2::new(30000.0, 0.0), Vector2::new(-5000.0, 25000.0)] {
            let r = (z - s).norm();
            let k = 20000;
            let var = (0..k)
                .map(|_| {
                    let e: Vector2<f64> = Vector2::new(g.sample(&mut rng), g.sample(&mut rng));
                    ((z - (s + e)).norm() - r).powi(2_i32)
                })
                .sum::<f64>()
                / k as f64;
            assert!((var.sqrt() - 20.0).abs() < 0.4, "{}", var.sqrt());
        }
    }

    #[test]
    fn bias_covariance_is_the_crlb_of_the_bias_alone() {
        let pos: Vec<Vector2<f64>> = swarm().iter().map(|p| Vector2::new(p[0], p[1])).collect();
        let z = Vector2::new(25000.0, 15000.0);
        assert_eq!(bias_covariance(&pos, &[0.0; 4], &z), Some(Matrix2::zeros()));
        let b = bias_covariance(&pos, &[10.0; 4], &z).unwrap();
        let sensors = Sensors::new(&swarm(), NoiseModel::uniform(4, 10.0).unwrap()).unwrap();
        let c = crate::crlb(&sensors, &z).unwrap().bound;
        assert!((b - c).norm() < 1e-9 * c.norm());
    }

    #[test]
    fn bad_arrivals_are_refused() {
        let pos = swarm();
        assert!(Arrivals::new(&pos, &[0.0; 4], 0b1_0000, &[5.0; 4], &[0.0; 4]).is_err());
        assert!(Arrivals::new(&pos, &[0.0, f64::NAN, 0.0, 0.0], 0b0010, &[5.0; 4], &[0.0; 4]).is_err());
        // A NaN where no arrival was heard is not read.
        assert!(Arrivals::new(&pos, &[0.0, f64::NAN, 0.0, 0.0], 0b1101, &[5.0; 4], &[0.0; 4]).is_ok());
        assert!(Arrivals::new(&pos, &[0.0; 4], 0b1111, &[5.0, 0.0, 5.0, 5.0], &[0.0; 4]).is_err());
        assert!(Arrivals::new(&pos, &[0.0; 4], 0b1111, &[5.0; 4], &[6.0, 0.0, 0.0, 0.0]).is_err());
        assert!(Arrivals::new(&pos[..2], &[0.0; 2], 0b11, &[5.0; 2], &[0.0; 2]).is_err());
    }

    #[test]
    fn a_sigma_is_set_as_new_would_set_it_or_refused() {
        let pos = swarm();
        let arrivals = [1.0, 2.0, 3.0, 4.0];
        let a = Arrivals::new(&pos, &arrivals, 0b1011, &[5.0; 4], &[0.0, 2.0, 0.0, 0.0]).unwrap();
        let b = Arrivals::new(&pos, &arrivals, 0b1011, &[5.0, 7.0, 5.0, 5.0], &[0.0, 2.0, 0.0, 0.0]).unwrap();
        assert_eq!(a.with_sigma(1, 7.0).unwrap(), b);
        for (uav, sigma) in [(1, 1.9), (1, 0.0), (0, f64::NAN), (4, 5.0)] {
            assert!(a.with_sigma(uav, sigma).is_err(), "UAV {uav}, σ {sigma}");
        }
    }
}
