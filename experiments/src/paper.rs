//! The paper's own numbers (Sensors 2026, 26, 5393, Tables 2–10 and Section 5.4), printed beside ours.
//! Units as in the paper: metres, seconds, percent.

/// Table 2 columns: mean CRLB, final CRLB, CI95 (final CRLB), mean RMSE, final RMSE, CI95 (final RMSE), m.
pub const TABLE2: [(&str, [f64; 6]); 3] = [
    ("single", [662.05, 241.62, 1.43, 667.65, 239.20, 14.52]),
    ("mc", [589.03, 224.80, 1.14, 592.07, 222.49, 13.59]),
    ("analytical", [601.63, 223.72, 1.27, 605.34, 221.24, 12.97]),
];

/// Section 5.4, PSO: the fixed formation's terminal CRLB and RMSE, m (Table 2 has no formation row).
pub const FORMATION_FINAL: [f64; 2] = [324.12, 322.59];

/// Section 5.3: average and final CRLB improvement and average RMSE improvement over single-point, %:
/// (method, mean CRLB, final CRLB, mean RMSE).
pub const TABLE2_IMPROVEMENT: [(&str, [f64; 3]); 2] =
    [("mc", [10.41, 6.96, 10.62]), ("analytical", [9.11, 7.41, 9.27])];

/// Table 4: (metric, mean abs. diff %, max abs. diff %, final diff %), analytical vs MC.
pub const TABLE4: [(&str, [f64; 3]); 3] =
    [("crlb", [1.62, 3.43, -0.48]), ("global_crlb_objective", [3.66, 12.42, 0.37]), ("rmse", [1.67, 3.55, -0.56])];

/// Table 5: (uncertainty scale, mean abs. diff %, max abs. diff %, mean time ratio MC/analytical).
pub const TABLE5: [(f64, [f64; 3]); 4] = [
    (0.25, [0.0867, 0.0936, 14.04]),
    (0.50, [1.8186, 3.7193, 14.84]),
    (0.75, [3.3792, 4.8135, 10.47]),
    (1.00, [6.2287, 16.0896, 9.49]),
];

/// Table 6: (scale s, [single RMSE, single deg %, MC RMSE, MC deg %, analytical RMSE, analytical deg %,
/// robustness gain pp]).
pub const TABLE6: [(f64, [f64; 7]); 5] = [
    (0.00, [237.510, 0.00, 237.510, 0.00, 237.510, 0.00, 0.00]),
    (0.25, [239.662, 0.91, 239.174, 0.70, 239.130, 0.68, 0.22]),
    (0.50, [253.214, 6.61, 245.187, 3.23, 245.244, 3.26, 3.36]),
    (0.75, [281.314, 18.44, 262.120, 10.36, 261.637, 10.16, 8.28]),
    (1.00, [383.250, 61.36, 351.036, 47.80, 334.489, 40.83, 20.53]),
];

/// Section 5.6: time-averaged RMSE degradation at s = 1, % (single, analytical).
pub const TABLE6_TIME_AVERAGED_DEGRADATION: [f64; 2] = [19.53, 13.31];

/// Table 7: (method, [CRLB time, opt. time, total mean, total max]), seconds.
pub const TABLE7: [(&str, [f64; 4]); 3] = [
    ("single", [0.00478, 0.02580, 0.03131, 2.26727]),
    ("mc", [0.00184, 1.17992, 1.18225, 3.09303]),
    ("analytical", [0.00211, 0.14938, 0.15202, 0.35784]),
];

/// Table 8: (nodes, [CRLB time s, MC time s, analytical time s, time ratio, FIM cond., RMSE m]).
pub const TABLE8: [(usize, [f64; 6]); 3] = [
    (3, [0.001147, 0.004469, 0.000447, 9.99, 345.83, 1686.79]),
    (4, [0.000149, 0.003729, 0.000416, 8.97, 119.19, 1029.87]),
    (5, [0.000044, 0.004178, 0.000440, 9.49, 82.04, 115.32]),
];

/// Table 9: (noise scale, factor, [CRLB 3, 4, 5 nodes, RMSE 3, 4, 5 nodes]), m.
pub const TABLE9: [(f64, f64, [f64; 6]); 4] = [
    (0.5, 100.0, [827.79, 480.62, 61.66, 817.57, 489.93, 61.61]),
    (1.0, 200.0, [1655.58, 961.23, 123.32, 1777.46, 896.42, 123.39]),
    (1.5, 300.0, [2483.37, 1441.85, 184.98, 2499.05, 1450.57, 183.68]),
    (2.0, 400.0, [3311.16, 1922.46, 246.64, 3743.33, 1869.20, 250.36]),
];

/// Table 10: (geometry, [initial FIM cond., initial CRLB m, analytical final CRLB m, analytical final
/// RMSE m, analytical vs MC final CRLB diff %, analytical speed-up vs MC]).
pub const TABLE10: [(&str, [f64; 6]); 3] = [
    ("nominal", [345.83, 1655.58, 223.72, 221.24, -0.48, 8.19]),
    ("favorable_wide_baseline", [53.19, 177.20, 53.92, 53.52, 8.74, 8.27]),
    ("moderately_asymmetric", [271.08, 1325.73, 188.98, 187.03, -0.71, 7.70]),
];

/// Section 5.4: terminal CRLB and RMSE, m, per solver for (formation, single, mc, analytical).
pub const OPTIMIZERS: [(&str, [f64; 4], [f64; 4]); 3] = [
    ("pso", [324.12, 240.26, 224.11, 223.29], [322.59, 238.58, 222.52, 221.76]),
    ("ga", [324.12, 240.43, 223.63, 222.56], [322.59, 238.91, 222.15, 221.05]),
    ("aco", [324.12, 242.07, 224.00, 222.75], [322.59, 240.16, 222.59, 221.12]),
];

/// The paper's row for `key` in a table of `(key, values)`.
pub fn row<const N: usize>(table: &[(&str, [f64; N])], key: &str) -> Option<[f64; N]> {
    table.iter().find(|(k, _)| *k == key).map(|(_, v)| *v)
}
