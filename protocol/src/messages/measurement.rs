//! The sensor side: one step's burst as the receivers give it — the UAV positions, which UAVs heard the
//! burst and when, and every UAV's error budget (emitter-sim or an external front end → estimator,
//! planner, monitor).

use super::*;

/// [`Measurement::flags`]: the emitter was silent at this step (no burst detected at all).
pub const FLAG_SILENT: u8 = 1;

/// emitter-sim or a front end → estimator: the UAV geometry and the arrivals of one step.
///
/// The arrivals are ranges with a common unknown offset: `arrivals[i] = c·(t_i − t_epoch)` for any
/// epoch the sender likes (only differences are used), metres. Any subset of UAVs may have heard the
/// burst (`heard`, bit i: UAV i), any of them serving as the reference; a step heard by fewer than two
/// UAVs — or a silent one (`flags & FLAG_SILENT`, then `heard` must be 0) — still carries every UAV's
/// position and heading, so the swarm is still commanded (the estimate is predicted).
///
/// The stated noise of UAV i's arrival: its range σ, its GNSS position σ per axis and its clock σ, each
/// split into a part that changes every step and a part that lasts the flight (bias).
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("uavloc::Measurement/v2")]
#[repr(C)]
pub struct Measurement {
    /// Common header.
    pub header: Header,
    /// Number of UAVs N (3..=8).
    pub count: u32,
    /// The UAVs whose arrival this step holds (bit i: UAV i; bits ≥ N must be 0).
    pub heard: u8,
    /// [`FLAG_SILENT`]; other bits 0.
    pub flags: u8,
    /// Explicit padding; 0 when sent.
    pub reserved: [u8; 2],
    /// UAV positions (metres) as the UAVs report them at the burst.
    pub uavs: [[f64; 2]; MAX_UAVS],
    /// Arrivals as ranges with a common unknown offset, metres (read for the UAVs heard only; 0 else).
    pub arrivals: [f64; MAX_UAVS],
    /// Per-UAV range noise standard deviation (metres, > 0).
    pub sigmas: [f64; MAX_UAVS],
    /// Current UAV headings (radians).
    pub headings: [f64; MAX_UAVS],
    /// GNSS position σ per axis that changes every step (metres, ≥ 0).
    pub position_sigmas: [f64; MAX_UAVS],
    /// GNSS position bias σ per axis that lasts the flight (metres, ≥ 0).
    pub position_bias_sigmas: [f64; MAX_UAVS],
    /// Clock σ that changes every step (nanoseconds, ≥ 0).
    pub clock_sigmas_ns: [f64; MAX_UAVS],
    /// Clock bias σ that lasts the flight (nanoseconds, ≥ 0).
    pub clock_bias_sigmas_ns: [f64; MAX_UAVS],
}

impl_message!(Measurement, MessageKind::Measurement, 2, "uavloc::Measurement/v2");

impl_per_uav!(Measurement {
    /// UAV positions in use.
    uavs: [f64; 2],
    /// Range sigmas in use.
    sigmas: f64,
    /// Headings in use.
    headings: f64,
    /// GNSS σ in use.
    position_sigmas: f64,
    /// GNSS bias σ in use.
    position_bias_sigmas: f64,
    /// Clock σ in use.
    clock_sigmas_ns: f64,
    /// Clock bias σ in use.
    clock_bias_sigmas_ns: f64,
});

/// Metres of range per nanosecond of clock.
pub const METRES_PER_NS: f64 = 299_792_458.0 * 1e-9;

impl Measurement {
    /// A step every UAV heard, as range differences to UAV0 (`diffs[i − 1] = r_i − r_0`: the arrivals
    /// `[0, d_1, …]`), with exact positions and clocks; `diffs` must have one entry fewer than `uavs`,
    /// `sigmas` and `headings` one per UAV. Content is checked by [`validate`](Self::validate).
    pub fn new(
        step: u64,
        seq: u64,
        uavs: &[[f64; 2]],
        diffs: &[f64],
        sigmas: &[f64],
        headings: &[f64],
    ) -> Result<Self, ProtocolError> {
        let n = check_count(uavs.len())?;
        check_len("diffs", n - 1, diffs.len())?;
        let mut arrivals = vec![0.0; n];
        arrivals[1..].copy_from_slice(diffs);
        Self::heard(step, seq, uavs, ((1u16 << n) - 1) as u8, &arrivals, sigmas, headings)
    }

    /// A step heard by the UAVs of the mask `heard` (bit i: UAV i) with `arrivals` (one per UAV, read
    /// for those heard), exact positions and clocks (see [`with_sensor_errors`](Self::with_sensor_errors)).
    pub fn heard(
        step: u64,
        seq: u64,
        uavs: &[[f64; 2]],
        heard: u8,
        arrivals: &[f64],
        sigmas: &[f64],
        headings: &[f64],
    ) -> Result<Self, ProtocolError> {
        let n = check_count(uavs.len())?;
        check_len("arrivals", n, arrivals.len())?;
        check_len("sigmas", n, sigmas.len())?;
        check_len("headings", n, headings.len())?;
        let mut m = Measurement {
            header: Header::new(Self::VERSION, step, seq),
            count: n as u32,
            heard,
            flags: 0,
            reserved: [0; 2],
            uavs: [[0.0; 2]; MAX_UAVS],
            arrivals: [0.0; MAX_UAVS],
            sigmas: [0.0; MAX_UAVS],
            headings: [0.0; MAX_UAVS],
            position_sigmas: [0.0; MAX_UAVS],
            position_bias_sigmas: [0.0; MAX_UAVS],
            clock_sigmas_ns: [0.0; MAX_UAVS],
            clock_bias_sigmas_ns: [0.0; MAX_UAVS],
        };
        m.uavs[..n].copy_from_slice(uavs);
        for (i, (slot, &a)) in m.arrivals.iter_mut().zip(arrivals).enumerate().take(n) {
            if heard & (1u8 << i) != 0 {
                *slot = a;
            }
        }
        m.sigmas[..n].copy_from_slice(sigmas);
        m.headings[..n].copy_from_slice(headings);
        Ok(m)
    }

    /// A step at which the emitter was silent: no arrival, every UAV's position and heading.
    pub fn silent(
        step: u64,
        seq: u64,
        uavs: &[[f64; 2]],
        sigmas: &[f64],
        headings: &[f64],
    ) -> Result<Self, ProtocolError> {
        let n = check_count(uavs.len())?;
        let mut m = Self::heard(step, seq, uavs, 0, &vec![0.0; n], sigmas, headings)?;
        m.flags = FLAG_SILENT;
        Ok(m)
    }

    /// This step with every UAV's GNSS σ per axis (white, bias; metres) and clock σ (white, bias; ns).
    pub fn with_sensor_errors(mut self, position: [f64; 2], clock_ns: [f64; 2]) -> Self {
        let n = self.len();
        self.position_sigmas[..n].fill(position[0]);
        self.position_bias_sigmas[..n].fill(position[1]);
        self.clock_sigmas_ns[..n].fill(clock_ns[0]);
        self.clock_bias_sigmas_ns[..n].fill(clock_ns[1]);
        self
    }

    /// Whether the emitter was silent.
    pub fn is_silent(&self) -> bool {
        self.flags & FLAG_SILENT != 0
    }

    /// The arrivals in use (one per UAV; 0 where not heard).
    pub fn arrivals(&self) -> &[f64] {
        &self.arrivals[..self.len()]
    }

    /// Whether UAV `i` heard the burst.
    pub fn has_heard(&self, i: usize) -> bool {
        i < self.len() && self.heard & (1u8 << i) != 0
    }

    /// Every UAV heard the burst.
    pub fn is_complete(&self) -> bool {
        (0..self.len()).all(|i| self.has_heard(i))
    }

    /// The range differences to UAV0 of a step every UAV heard (`None` otherwise).
    pub fn diffs(&self) -> Option<Vec<f64>> {
        self.is_complete().then(|| self.arrivals()[1..].iter().map(|a| a - self.arrivals[0]).collect())
    }

    /// The stated σ of each UAV's arrival: `sqrt(σ_r² + σ_g² + σ_gb² + σ_c² + σ_cb²)` (clock σ as range),
    /// and its persistent part `sqrt(σ_gb² + σ_cb²)`, metres (see `tdoa::arrivals`; the same sums in the
    /// same order as `tdoa::SensorErrors::effective_sigma`, so a process and the in-process loop agree
    /// bit for bit).
    pub fn stated_sigmas(&self) -> (Vec<f64>, Vec<f64>) {
        let n = self.len();
        let sq = |v: f64| v * v;
        let bias: Vec<f64> = (0..n)
            .map(|i| sq(self.position_bias_sigmas[i]) + sq(self.clock_bias_sigmas_ns[i] * METRES_PER_NS))
            .collect();
        let total = (0..n)
            .map(|i| {
                let extra = sq(self.position_sigmas[i]) + sq(self.clock_sigmas_ns[i] * METRES_PER_NS) + bias[i];
                // Exactly the range σ without sensor errors (no rounding through the square root).
                if extra == 0.0 { self.sigmas[i] } else { (sq(self.sigmas[i]) + extra).sqrt() }
            })
            .collect();
        (total, bias.into_iter().map(f64::sqrt).collect())
    }
}
