//! Where the FIM is singular, and whether a support square reaches it.
//!
//! `F` is singular at `z` exactly when the Jacobian rows `u_i − u_0` are all parallel. For unit vectors
//! that happens iff the bearings from `z` to the UAVs take at most two distinct values, i.e. the UAVs
//! lie on at most two rays from `z`. For 3 UAVs this is the union of the three baseline *extensions*
//! (the emitter collinear with two UAVs, outside their segment); with more UAVs it shrinks to isolated
//! points (intersections of two baseline lines) unless three or more UAVs are collinear. Near the set
//! `tr F⁻¹` grows like 1/distance², so the global CRLB integral (eq. 51) over a support that reaches it
//! diverges: its exact value is +∞.

use nalgebra::Vector2;

use crate::{Sensors, Uncertainty};

/// One connected piece of the singular set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SingularPiece {
    /// `origin + t·dir`, t ≥ 0 (dir a unit vector).
    Ray { origin: Vector2<f64>, dir: Vector2<f64> },
    /// The closed segment between two points.
    Segment { a: Vector2<f64>, b: Vector2<f64> },
    /// One isolated point.
    Point(Vector2<f64>),
}

impl SingularPiece {
    /// Euclidean distance from `p` to the piece, metres.
    pub fn distance(&self, p: &Vector2<f64>) -> f64 {
        match *self {
            SingularPiece::Point(q) => (p - q).norm(),
            SingularPiece::Ray { origin, dir } => {
                let t = (p - origin).dot(&dir).max(0.0);
                (p - (origin + dir * t)).norm()
            }
            SingularPiece::Segment { a, b } => {
                let ab = b - a;
                let t = ((p - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0);
                (p - (a + ab * t)).norm()
            }
        }
    }

    /// Whether the piece meets the axis-aligned box `[lo, hi]` (Liang–Barsky clipping).
    pub fn meets_box(&self, lo: &Vector2<f64>, hi: &Vector2<f64>) -> bool {
        let (start, delta, t_max) = match *self {
            SingularPiece::Point(q) => return (0..2).all(|k| q[k] >= lo[k] && q[k] <= hi[k]),
            SingularPiece::Ray { origin, dir } => (origin, dir, f64::INFINITY),
            SingularPiece::Segment { a, b } => (a, b - a, 1.0),
        };
        let (mut t0, mut t1) = (0.0_f64, t_max);
        for k in 0..2 {
            if delta[k].abs() < 1e-15 {
                if start[k] < lo[k] || start[k] > hi[k] {
                    return false;
                }
            } else {
                let ta = (lo[k] - start[k]) / delta[k];
                let tb = (hi[k] - start[k]) / delta[k];
                t0 = t0.max(ta.min(tb));
                t1 = t1.min(ta.max(tb));
            }
        }
        t0 <= t1
    }
}

/// What the singular set means for one support.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SingularReport {
    /// The support square reaches the singular set: the exact global CRLB is +∞.
    pub intersects_support: bool,
    /// Distance from `ẑ` to the nearest singular point, metres (+∞ if the set is empty).
    pub distance_m: f64,
}

fn cross(a: &Vector2<f64>, b: &Vector2<f64>) -> f64 {
    a.x * b.y - a.y * b.x
}

/// All pieces of the singular set of this UAV geometry.
pub fn singular_set(sensors: &Sensors) -> Vec<SingularPiece> {
    let w = sensors.positions();
    let n = w.len();
    let scale = w.iter().map(|p| p.norm()).fold(1.0, f64::max);
    let tol = 1e-9 * scale;
    let mut pieces = Vec::new();
    for i in 0..n {
        for j in i + 1..n {
            let dir = (w[j] - w[i]).normalize();
            let on_line: Vec<usize> = (0..n).filter(|&k| cross(&(w[k] - w[i]), &dir).abs() <= tol).collect();
            // Handle each line once: from its lexicographically first pair.
            if on_line[0] != i || on_line[1] != j {
                continue;
            }
            let off: Vec<usize> = (0..n).filter(|k| !on_line.contains(k)).collect();
            let mut ts: Vec<f64> = on_line.iter().map(|&k| (w[k] - w[i]).dot(&dir)).collect();
            ts.sort_by(f64::total_cmp);
            let (t_min, t_max) = (ts[0], ts[ts.len() - 1]);
            let at = |t: f64| w[i] + dir * t;
            match off.len() {
                0 => {
                    // All UAVs on one line: the whole line is singular.
                    pieces.push(SingularPiece::Ray { origin: at(t_max), dir });
                    pieces.push(SingularPiece::Ray { origin: at(t_min), dir: -dir });
                    pieces.push(SingularPiece::Segment { a: at(t_min), b: at(t_max) });
                }
                1 => {
                    // The on-line UAVs form one bearing group on each outer ray, the off-line UAV the other.
                    pieces.push(SingularPiece::Ray { origin: at(t_max), dir });
                    pieces.push(SingularPiece::Ray { origin: at(t_min), dir: -dir });
                }
                _ => {
                    // The off-line UAVs must share one bearing: z on their common line, beyond all of them.
                    let a = w[off[0]];
                    let d2 = (w[off[1]] - a).normalize();
                    if off.iter().any(|&k| cross(&(w[k] - a), &d2).abs() > tol) {
                        continue;
                    }
                    let denom = cross(&dir, &d2);
                    if denom.abs() < 1e-12 {
                        continue;
                    }
                    // Solve w_i + dir t = a + d2 s.
                    let t = cross(&(a - w[i]), &d2) / denom;
                    if t > t_min && t < t_max {
                        continue; // between on-line UAVs: already two groups there
                    }
                    let p = at(t);
                    let s: Vec<f64> = off.iter().map(|&k| (w[k] - p).dot(&d2)).collect();
                    if s.iter().all(|&v| v > 0.0) || s.iter().all(|&v| v < 0.0) {
                        pieces.push(SingularPiece::Point(p));
                    }
                }
            }
        }
    }
    pieces
}

/// Whether the support of `unc` reaches the singular set of `sensors`, and how far `ẑ` is from it.
pub fn singular_report(sensors: &Sensors, unc: &Uncertainty) -> SingularReport {
    let (lo, hi) = unc.bounds();
    let z = unc.estimate();
    let mut out = SingularReport { intersects_support: false, distance_m: f64::INFINITY };
    for piece in singular_set(sensors) {
        out.distance_m = out.distance_m.min(piece.distance(&z));
        out.intersects_support |= piece.meets_box(&lo, &hi);
    }
    out
}
