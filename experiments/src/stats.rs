//! Summary statistics over outer Monte Carlo runs: mean, standard deviation and the 95 % confidence
//! interval of the mean (Student's t, so small `--quick` run counts are not over-confident), plain and
//! paired.

/// Mean and CI95 of a sample.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Summary {
    /// Sample mean.
    pub mean: f64,
    /// Sample standard deviation (n − 1).
    pub sd: f64,
    /// Number of finite values used.
    pub n: usize,
    /// Half-width of the 95 % confidence interval of the mean, `t₀.₉₇₅(n−1)·sd/√n` (NaN for n < 2).
    pub ci95: f64,
}

impl Summary {
    /// `[mean − ci95, mean, mean + ci95]`.
    pub fn interval(&self) -> [f64; 3] {
        [self.mean - self.ci95, self.mean, self.mean + self.ci95]
    }

    /// Whether the whole CI95 lies below zero (a significant decrease).
    pub fn significantly_negative(&self) -> bool {
        self.mean + self.ci95 < 0.0
    }

    /// Whether the whole CI95 lies above zero (a significant increase).
    pub fn significantly_positive(&self) -> bool {
        self.mean - self.ci95 > 0.0
    }
}

/// Two-sided 97.5 % quantile of Student's t with `dof` degrees of freedom.
pub fn t975(dof: usize) -> f64 {
    const TABLE: [f64; 30] = [
        12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160, 2.145, 2.131,
        2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042,
    ];
    match dof {
        0 => f64::NAN,
        1..=30 => TABLE[dof - 1],
        // Cornish–Fisher expansion around the normal quantile; error < 1e-3 beyond 30 dof.
        _ => {
            let z: f64 = 1.959_964;
            let n = dof as f64;
            z + (z.powi(3) + z) / (4.0 * n) + (5.0 * z.powi(5) + 16.0 * z.powi(3) + 3.0 * z) / (96.0 * n * n)
        }
    }
}

/// Summary of the finite values of `values` (non-finite ones are left out and not counted).
pub fn summarize(values: &[f64]) -> Summary {
    let v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    let n = v.len();
    if n == 0 {
        return Summary { mean: f64::NAN, sd: f64::NAN, n, ci95: f64::NAN };
    }
    let mean = v.iter().sum::<f64>() / n as f64;
    if n < 2 {
        return Summary { mean, sd: f64::NAN, n, ci95: f64::NAN };
    }
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    let sd = var.sqrt();
    Summary { mean, sd, n, ci95: t975(n - 1) * sd / (n as f64).sqrt() }
}

/// Summary of the paired differences `a[m] − b[m]` over the runs where both are finite.
pub fn paired(a: &[f64], b: &[f64]) -> Summary {
    let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| x - y).collect();
    summarize(&d)
}

/// Median of the finite values (NaN when there are none).
pub fn median(values: &[f64]) -> f64 {
    quantile(values, 0.5)
}

/// The `q`-quantile (0 ≤ q ≤ 1) of the finite values by linear interpolation (NaN when there are none).
pub fn quantile(values: &[f64], q: f64) -> f64 {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let pos = q.clamp(0.0, 1.0) * (v.len() - 1) as f64;
    let (i, frac) = (pos.floor() as usize, pos.fract());
    if i + 1 < v.len() { v[i] + frac * (v[i + 1] - v[i]) } else { v[i] }
}

/// The median of `|e| / √tr Σ` over `e ~ N(0, Σ)`, pooled over ellipses of equal weight whose shapes are
/// `λ_min / (λ_min + λ_max)` of each `Σ` (0 a line, ½ a circle): what an efficient estimator's error over
/// its bound's root trace has as its median for these ellipses (≈ 0.674 for lines, 0.833 for circles;
/// the root mean square is 1 whatever the shapes). NaN without a shape in [0, ½].
///
/// Exact up to quadrature: with `e = ρ (√(1−s) cos θ, √s sin θ)`-scaled coordinates, `ρ² ~ χ²₂` is
/// independent of the angle θ, so `P(|e|/√tr Σ ≤ t) = E_θ[1 − exp(−t² / (2 g(θ)))]`,
/// `g(θ) = (1 − s) cos²θ + s sin²θ`; the mean over θ by the midpoint rule on 512 nodes (a smooth
/// periodic integrand: spectral accuracy), the median by bisection.
pub fn efficient_median_ratio(shapes: &[f64]) -> f64 {
    let shapes: Vec<f64> = shapes.iter().copied().filter(|s| (0.0..=0.5).contains(s)).collect();
    if shapes.is_empty() {
        return f64::NAN;
    }
    const NODES: usize = 512;
    let cos2: Vec<f64> =
        (0..NODES).map(|k| (std::f64::consts::FRAC_PI_2 * (k as f64 + 0.5) / NODES as f64).cos().powi(2)).collect();
    let cdf = |t: f64| -> f64 {
        let mut total = 0.0;
        for s in &shapes {
            let mean: f64 = cos2
                .iter()
                .map(|c| {
                    let g = (1.0 - s) * c + s * (1.0 - c);
                    if g <= 0.0 { 1.0 } else { 1.0 - (-t * t / (2.0 * g)).exp() }
                })
                .sum::<f64>()
                / NODES as f64;
            total += mean;
        }
        total / shapes.len() as f64
    };
    let (mut lo, mut hi) = (0.0, 5.0);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if cdf(mid) < 0.5 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The shape `λ_min / (λ_min + λ_max)` of a 2 × 2 covariance given by its rows (NaN when it is not
/// positive definite).
pub fn ellipse_shape(cov: &[[f64; 2]; 2]) -> f64 {
    let (small, large) = tdoa::fim::sym_eigenvalues(&tdoa::matrix_from_rows(cov));
    if !(small > 0.0 && large.is_finite()) {
        return f64::NAN;
    }
    small / (small + large)
}

/// Median wall-clock seconds per call of `f`, over 5 samples of `reps` calls each (the median damps a
/// sample that the scheduler interrupted on a noisy machine).
pub fn median_seconds_per_call(reps: usize, mut f: impl FnMut()) -> f64 {
    let reps = reps.max(1);
    let samples: Vec<f64> = (0..5)
        .map(|_| {
            let t = std::time::Instant::now();
            for _ in 0..reps {
                f();
            }
            t.elapsed().as_secs_f64() / reps as f64
        })
        .collect();
    median(&samples)
}

/// Relative difference `(a − b)/b` in percent.
pub fn rel_pct(a: f64, b: f64) -> f64 {
    (a - b) / b * 100.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn t_quantiles_approach_the_normal_one() {
        assert!((t975(1) - 12.706).abs() < 1e-9);
        assert!((t975(31) - 2.0395).abs() < 2e-3, "{}", t975(31));
        assert!((t975(199) - 1.972).abs() < 1e-3, "{}", t975(199));
        assert!((t975(100_000) - 1.95996).abs() < 1e-4);
        // Monotone decreasing across the table/expansion seam.
        for d in 1..200 {
            assert!(t975(d + 1) < t975(d), "dof {d}");
        }
    }

    #[test]
    fn the_efficient_median_is_known_for_circles_and_lines_and_matches_sampling_between() {
        // A circle: |e|²/tr Σ = χ²₂ / 2, median √(ln 2). A line: |z|, median Φ⁻¹(¾).
        assert!((efficient_median_ratio(&[0.5]) - 2f64.ln().sqrt()).abs() < 1e-9);
        assert!((efficient_median_ratio(&[0.0]) - 0.674_489_750_196_081_7).abs() < 1e-3);
        // A mixture of shapes against plain sampling of the same ellipses.
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let shapes = [0.02, 0.1, 0.3, 0.45];
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut r = Vec::new();
        for s in shapes {
            for _ in 0..50_000 {
                let (x, y): (f64, f64) = (StandardNormal.sample(&mut rng), StandardNormal.sample(&mut rng));
                r.push(((1.0 - s) * x * x + s * y * y).sqrt());
            }
        }
        let sampled = median(&r);
        let exact = efficient_median_ratio(&shapes);
        assert!((sampled - exact).abs() < 0.006, "{sampled} vs {exact}");
        assert!(efficient_median_ratio(&[]).is_nan() && efficient_median_ratio(&[0.7]).is_nan());
    }

    #[test]
    fn an_ellipse_s_shape_is_its_small_eigenvalue_s_share() {
        assert!((ellipse_shape(&[[4.0, 0.0], [0.0, 1.0]]) - 0.2).abs() < 1e-12);
        // Rotated by 30°: the same shape.
        let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let m = [[4.0 * c * c + s * s, 3.0 * c * s], [3.0 * c * s, 4.0 * s * s + c * c]];
        assert!((ellipse_shape(&m) - 0.2).abs() < 1e-12);
        assert!(ellipse_shape(&[[1.0, 2.0], [2.0, 1.0]]).is_nan());
    }

    #[test]
    fn summary_of_a_known_sample() {
        let s = summarize(&[1.0, 2.0, 3.0, 4.0, f64::NAN]);
        assert_eq!(s.n, 4);
        assert!((s.mean - 2.5).abs() < 1e-15);
        assert!((s.sd - (5.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert!((s.ci95 - 3.182 * s.sd / 2.0).abs() < 1e-12);
        assert!(summarize(&[]).mean.is_nan());
        assert!(summarize(&[7.0]).ci95.is_nan());
    }

    #[test]
    fn coverage_of_the_ci_is_about_95_percent() {
        // 2000 samples of size 10 from a deterministic pseudo-normal sequence: the CI covers the true mean
        // about 95 % of the time (binomial 3σ band ±1.5 %).
        let mut state = 0x1234_5678_u64;
        let mut uniform = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let mut covered = 0;
        for _ in 0..2000 {
            let xs: Vec<f64> = (0..10)
                .map(|_| {
                    let (u, v) = (uniform(), uniform());
                    (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
                })
                .collect();
            let s = summarize(&xs);
            covered += usize::from(s.mean.abs() <= s.ci95);
        }
        let rate = covered as f64 / 2000.0;
        assert!((0.935..=0.965).contains(&rate), "coverage {rate}");
    }

    #[test]
    fn paired_differences_and_quantiles() {
        let p = paired(&[3.0, 5.0, 7.0], &[1.0, 2.0, 3.0]);
        assert!((p.mean - 3.0).abs() < 1e-15);
        assert!(p.significantly_positive() && !p.significantly_negative());
        assert_eq!(median(&[3.0, 1.0, 2.0, f64::INFINITY]), 2.0);
        assert_eq!(quantile(&[0.0, 10.0], 0.25), 2.5);
        assert!((rel_pct(90.0, 100.0) + 10.0).abs() < 1e-12);
    }
}
