//! The few distribution functions the estimator and the planner need: the regularised incomplete gamma
//! function, and from it the χ² and standard normal CDFs and quantiles.
//!
//! - χ² gate of a fused snapshot: `χ²_{N−1}` quantile of the gate probability ([`chi2_quantile`]);
//! - NEES bands of the consistency checks: `χ²_{2M}` quantiles;
//! - the standoff chance constraint: `k(c) = Φ⁻¹(c)` ([`normal_quantile`]).
//!
//! `P(a, x)` is computed by its series for `x < a + 1` and by the Lentz continued fraction of `Q(a, x)`
//! otherwise (Numerical Recipes §6.2), to ~1e-14 relative; `ln Γ` by the Lanczos approximation (g = 7,
//! n = 9). Quantiles are found by a safeguarded Newton iteration on the CDF (bisection where Newton
//! would leave the bracket), so they invert the CDF to its own precision.

// Negated comparisons are deliberate here: `!(a > b)` also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

/// `ln Γ(x)` for `x > 0` (Lanczos, g = 7, n = 9; ~1e-15 relative).
pub fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Reflection: Γ(x) Γ(1 − x) = π / sin(πx).
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + G + 0.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// The regularised lower incomplete gamma function `P(a, x) = γ(a, x)/Γ(a)`, `a > 0`, `x ≥ 0`.
pub fn gamma_p(a: f64, x: f64) -> f64 {
    if x.is_nan() || a.is_nan() || a <= 0.0 {
        return f64::NAN;
    }
    if x <= 0.0 {
        return 0.0;
    }
    if x.is_infinite() {
        return 1.0;
    }
    if x < a + 1.0 { gamma_series(a, x) } else { 1.0 - gamma_cf(a, x) }
}

/// The regularised upper incomplete gamma function `Q(a, x) = 1 − P(a, x)`, accurate in the upper tail.
pub fn gamma_q(a: f64, x: f64) -> f64 {
    if x.is_nan() || a.is_nan() || a <= 0.0 {
        return f64::NAN;
    }
    if x <= 0.0 {
        return 1.0;
    }
    if x.is_infinite() {
        return 0.0;
    }
    if x < a + 1.0 { 1.0 - gamma_series(a, x) } else { gamma_cf(a, x) }
}

fn gamma_series(a: f64, x: f64) -> f64 {
    let mut ap = a;
    let mut term = 1.0 / a;
    let mut sum = term;
    for _ in 0..10_000 {
        ap += 1.0;
        term *= x / ap;
        sum += term;
        if term.abs() < sum.abs() * 1e-16 {
            break;
        }
    }
    (sum.ln() - x + a * x.ln() - ln_gamma(a)).exp()
}

fn gamma_cf(a: f64, x: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let mut b = x + 1.0 - a;
    let mut c = 1.0 / TINY;
    let mut d = 1.0 / b;
    let mut h = d;
    for i in 1..10_000 {
        let an = -(i as f64) * (i as f64 - a);
        b += 2.0;
        d = an * d + b;
        if d.abs() < TINY {
            d = TINY;
        }
        c = b + an / c;
        if c.abs() < TINY {
            c = TINY;
        }
        d = 1.0 / d;
        let delta = d * c;
        h *= delta;
        if (delta - 1.0).abs() < 1e-16 {
            break;
        }
    }
    (-x + a * x.ln() - ln_gamma(a)).exp() * h
}

/// CDF of the χ² distribution with `dof` degrees of freedom at `x`.
pub fn chi2_cdf(dof: f64, x: f64) -> f64 {
    gamma_p(0.5 * dof, 0.5 * x)
}

/// The `p`-quantile of the χ² distribution with `dof > 0` degrees of freedom (`p` in [0, 1]; 0 → 0,
/// 1 → +∞, NaN outside).
pub fn chi2_quantile(dof: f64, p: f64) -> f64 {
    if dof.is_nan() || dof <= 0.0 || !(0.0..=1.0).contains(&p) {
        return f64::NAN;
    }
    if p == 0.0 {
        return 0.0;
    }
    if p == 1.0 {
        return f64::INFINITY;
    }
    // Wilson–Hilferty start, then safeguarded Newton on F(x) − p (density = dF/dx).
    let z = normal_quantile_start(p);
    let h = 2.0 / (9.0 * dof);
    let mut x = (dof * (1.0 - h + z * h.sqrt()).powi(3)).max(1e-8);
    let (mut lo, mut hi) = (0.0_f64, f64::INFINITY);
    let ln_norm = 0.5 * dof * std::f64::consts::LN_2 + ln_gamma(0.5 * dof);
    for _ in 0..200 {
        // f(x) = F(x) − p, increasing in x; computed on the smaller tail for precision.
        let f = if p > 0.5 { (1.0 - p) - gamma_q(0.5 * dof, 0.5 * x) } else { chi2_cdf(dof, x) - p };
        if f < 0.0 {
            lo = lo.max(x);
        } else {
            hi = hi.min(x);
        }
        let density = ((0.5 * dof - 1.0) * x.ln() - 0.5 * x - ln_norm).exp();
        let mut next = x - f / density;
        if !(next > lo && next < hi && next.is_finite()) {
            next = if hi.is_finite() { 0.5 * (lo + hi) } else { 2.0 * x.max(lo) + 1.0 };
        }
        if (next - x).abs() <= 1e-15 * x.abs().max(1e-300) {
            return next;
        }
        x = next;
    }
    x
}

/// The standard normal CDF `Φ(x)`.
pub fn normal_cdf(x: f64) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    // Φ(x) = ½ (1 + sign(x) P(½, x²/2)); the tail through Q for precision.
    let q = 0.5 * gamma_q(0.5, 0.5 * x * x);
    if x >= 0.0 { 1.0 - q } else { q }
}

/// The standard normal quantile `Φ⁻¹(p)` (`p` in [0, 1]; ±∞ at the ends, NaN outside).
pub fn normal_quantile(p: f64) -> f64 {
    if !(0.0..=1.0).contains(&p) {
        return f64::NAN;
    }
    if p == 0.5 {
        return 0.0;
    }
    // z² is the (2p − 1)-quantile of χ²₁ for p > ½; use the tail probability for precision.
    let tail = if p > 0.5 { 1.0 - p } else { p };
    if tail == 0.0 {
        return if p > 0.5 { f64::INFINITY } else { f64::NEG_INFINITY };
    }
    let z = chi2_quantile(1.0, 1.0 - 2.0 * tail).sqrt();
    if p > 0.5 { z } else { -z }
}

/// A rough `Φ⁻¹(p)` (Abramowitz–Stegun 26.2.23, |error| < 4.5e-4): only a starting point.
fn normal_quantile_start(p: f64) -> f64 {
    let (q, sign) = if p < 0.5 { (p, -1.0) } else { (1.0 - p, 1.0) };
    let t = (-2.0 * q.max(1e-300).ln()).sqrt();
    let z = t
        - (2.515_517 + 0.802_853 * t + 0.010_328 * t * t)
            / (1.0 + 1.432_788 * t + 0.189_269 * t * t + 0.001_308 * t * t * t);
    sign * z
}

/// The two-sided `level` band of the mean of `runs` independent χ²_`dof` variables (the mean NEES of a
/// consistent estimator over `runs` Monte Carlo runs): `[χ²_{runs·dof}((1−level)/2), χ²_{runs·dof}((1+level)/2)] / runs`.
pub fn mean_chi2_band(dof: f64, runs: usize, level: f64) -> (f64, f64) {
    let n = runs as f64;
    let total = dof * n;
    (chi2_quantile(total, 0.5 * (1.0 - level)) / n, chi2_quantile(total, 0.5 * (1.0 + level)) / n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ln_gamma_matches_factorials_and_half_integers() {
        let mut f = 1.0_f64;
        for n in 1..30 {
            assert!((ln_gamma(n as f64) - f.ln()).abs() < 1e-12 * f.ln().abs().max(1.0), "n = {n}");
            f *= n as f64;
        }
        // Γ(1/2) = √π.
        assert!((ln_gamma(0.5) - std::f64::consts::PI.sqrt().ln()).abs() < 1e-14);
    }

    #[test]
    fn chi2_two_dof_is_exponential() {
        // χ²₂: F(x) = 1 − exp(−x/2), quantile −2 ln(1 − p): a closed form to compare with.
        for &p in &[1e-6_f64, 0.01, 0.025, 0.5, 0.9, 0.95, 0.975, 0.99, 0.9999, 1.0 - 1e-9] {
            let exact = -2.0 * (1.0 - p).ln();
            let q = chi2_quantile(2.0, p);
            assert!((q - exact).abs() <= 1e-9 * exact.max(1e-6), "p = {p}: {q} vs {exact}");
            assert!((chi2_cdf(2.0, exact) - p).abs() < 1e-13, "p = {p}");
        }
    }

    #[test]
    fn normal_quantile_matches_reference_values() {
        // Reference values (e.g. R's qnorm).
        for &(p, z) in &[
            (0.975, 1.959_963_984_540_054),
            (0.99, 2.326_347_874_040_841),
            (0.999, 3.090_232_306_167_813),
            (0.8413447460685429, 1.0),
            (0.05, -1.644_853_626_951_472),
        ] {
            assert!((normal_quantile(p) - z).abs() < 1e-9, "p = {p}: {} vs {z}", normal_quantile(p));
            assert!((normal_cdf(z) - p).abs() < 1e-12);
        }
        assert_eq!(normal_quantile(0.5), 0.0);
        assert_eq!(normal_quantile(1.0), f64::INFINITY);
        assert!(normal_quantile(1.5).is_nan());
    }

    #[test]
    fn chi2_quantile_inverts_a_fine_quadrature_of_the_density() {
        // The CDF by a fine Simpson quadrature of the density, independent of the gamma functions.
        for &dof in &[1.0_f64, 3.0, 7.0, 40.0, 400.0] {
            for &p in &[0.025, 0.5, 0.975, 0.999] {
                let x = chi2_quantile(dof, p);
                let ln_norm = 0.5 * dof * std::f64::consts::LN_2 + ln_gamma(0.5 * dof);
                // ∫₀ˣ pdf with a substitution t = s² for dof = 1 (integrable singularity at 0).
                let n = 200_000;
                let (a, b) = (0.0, x.sqrt());
                let h = (b - a) / n as f64;
                // g(s) = 2 s pdf(s²) = 2 s^{dof−1} e^{−s²/2} / norm.
                let g = |s: f64| 2.0 * ((dof - 1.0) * s.max(1e-300).ln() - 0.5 * s * s - ln_norm).exp();
                let mut sum = g(a) + g(b);
                for i in 1..n {
                    sum += g(a + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
                }
                let cdf = sum * h / 3.0;
                assert!((cdf - p).abs() < 1e-7, "dof {dof}, p {p}: quadrature {cdf}");
            }
        }
        // The mean-NEES band of 200 runs, 2 dof: around 2 ± 0.28.
        let (lo, hi) = mean_chi2_band(2.0, 200, 0.95);
        assert!((lo - 1.73).abs() < 0.02 && (hi - 2.29).abs() < 0.02, "{lo} {hi}");
    }
}
