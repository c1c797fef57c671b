//! The backup manoeuvre of one UAV from where a planning step ends, and certified minima along it:
//! the continuation that the safety certificate ([`crate::safety`]) requires to exist for every UAV.
//!
//! Every backup starts by turning at the backup rate `ω = v/R_b` on a circle of radius `R_b` tangent to
//! the UAV's heading φ — clockwise (sense `σ = −1`, centre `c = w + R_b·(sin φ, −cos φ)`) or
//! anticlockwise (`σ = +1`, centre `c = w − R_b·(sin φ, −cos φ)`): at time t ≥ 0 the heading is
//! `h(t) = φ + σωt` and the position `c − σR_b·(−sin h, cos h)`. Then either
//!
//! - **circle** (clockwise): it keeps circling for ever — against a static emitter the certificate holds
//!   for all future time, since every UAV circling at the same rate in the same sense makes each pair's
//!   relative motion periodic;
//! - **fly away** (either sense, whichever keeps the emitter further away): at the exit heading `ĥ` it
//!   leaves the circle on the tangent and flies straight for ever. `ĥ` makes the UAV's velocity relative
//!   to a moving emitter point away from it as seen from the circle's centre: with
//!   `d = (c − ẑ)/|c − ẑ|` and the emitter's velocity `u` (`|u| < v`), `v·ĥ = u + s·d` with
//!   `s = d·u + sqrt((d·u)² + v² − |u|²) > 0`. The turn to it takes `T = ((σ(ĥ − φ)) mod 2π)/ω`, less
//!   than one period. A circle cannot keep an emitter that moves towards it away for long; flying away
//!   at `v > |u|` opens the distance at the rate `s` for as long as the velocity estimate holds.
//!
//! **Pair minima for all future time** ([`pair_min`]): two circles, closed form
//! `| |c_i − c_j| − 2R_b|sin((φ_i − φ_j)/2)| |`; otherwise the time axis is split where the UAVs exit —
//! while both circle in the same sense, the same closed form is a lower bound (a sub-interval of the
//! periodic motion), tightened where needed (and in opposite senses replaced) by a certified Lipschitz search ([`crate::arc::lipschitz_min_within`], the
//! relative speed is at most `2v` and the relative acceleration `2vω`); while one flies straight and the
//! other circles, the same search, and for a circle kept for ever past the moment the straight flight
//! has left it behind (the distance to its centre increases from then on), the closed form of that
//! distance less `R_b`; while both fly straight, the closed form of a linear relative motion.
//!
//! **Standoff over a window** ([`BackupPath::standoff_min`]): the circle against an emitter moving over
//! the window, the distance of the circle to the segment the emitter covers (closed form); a fly-away
//! turn, the arcs of the turn against the moving emitter (certified, [`crate::arc::moving_point_min_distance`]);
//! its straight flight, the closed form of the relative motion.
//!
//! Units: metres, seconds, radians.

use std::f64::consts::{FRAC_PI_2, TAU};

use nalgebra::Vector2;

use crate::arc::{Arc, MIN_TOLERANCE_M, lipschitz_min_within, moving_point_min_distance};

/// Most a fly-away turn's arc turns per piece when its standoff is bracketed, radians (an [`Arc`] turns
/// by less than π).
const TURN_PIECE: f64 = FRAC_PI_2;

/// The straight flight that ends a fly-away backup.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Exit {
    /// Time after the backup's start at which the UAV leaves the circle, seconds (`0 ≤ T < 2π/ω`).
    pub time: f64,
    /// The exit heading ĥ, radians.
    pub heading: f64,
    /// Where the UAV leaves the circle, metres.
    pub point: Vector2<f64>,
}

/// One UAV's backup manoeuvre from `(w, φ)`: see the module docs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BackupPath {
    /// Centre of the clockwise circle, metres.
    pub centre: Vector2<f64>,
    /// Its radius `R_b`, metres.
    pub radius: f64,
    /// Speed v, m/s.
    pub speed: f64,
    /// The heading φ at the start, radians.
    pub heading: f64,
    /// The sense of the turn: −1 clockwise (right), +1 anticlockwise (left).
    pub sense: f64,
    /// `None`: circles for ever; `Some`: flies away.
    pub exit: Option<Exit>,
}

/// `(−sin h, cos h)`: from a clockwise circle's centre to the UAV whose heading is h, per metre of radius.
fn radial(h: f64) -> Vector2<f64> {
    let (sin, cos) = h.sin_cos();
    Vector2::new(-sin, cos)
}

fn unit(h: f64) -> Vector2<f64> {
    let (sin, cos) = h.sin_cos();
    Vector2::new(cos, sin)
}

impl BackupPath {
    /// Circling clockwise for ever from `end` with heading `phi` (radius `radius`, speed `speed`).
    pub fn circle(end: Vector2<f64>, phi: f64, radius: f64, speed: f64) -> Self {
        Self::circle_with(end, phi, phi.sin_cos(), radius, speed)
    }

    /// [`Self::circle`] with `(sin φ, cos φ)` given (a caller that needs them anyway).
    pub fn circle_with(end: Vector2<f64>, phi: f64, (sin, cos): (f64, f64), radius: f64, speed: f64) -> Self {
        let centre = end + Vector2::new(sin, -cos) * radius;
        Self { centre, radius, speed, heading: phi, sense: -1.0, exit: None }
    }

    fn turning(end: Vector2<f64>, phi: f64, radius: f64, speed: f64, sense: f64) -> Self {
        let centre = end + radial(phi) * (sense * radius);
        Self { centre, radius, speed, heading: phi, sense, exit: None }
    }

    /// Turning from `end` with heading `phi` in `sense` (−1 clockwise, +1 anticlockwise) to the exit
    /// heading that flies away from an emitter at `emitter` moving at `velocity` (m/s), then straight
    /// for ever (see the module docs).
    pub fn fly_away(
        end: Vector2<f64>,
        phi: f64,
        radius: f64,
        speed: f64,
        sense: f64,
        emitter: Vector2<f64>,
        velocity: Vector2<f64>,
    ) -> Self {
        let circle = Self::turning(end, phi, radius, speed, sense);
        let away = circle.centre - emitter;
        let d = if away.norm() > 0.0 { away / away.norm() } else { unit(phi) };
        let du = d.dot(&velocity);
        let disc = du * du + speed * speed - velocity.norm_squared();
        let ground = if disc > 0.0 { velocity + d * (du + disc.sqrt()) } else { d };
        let heading = ground.y.atan2(ground.x);
        let rem = (sense * (heading - phi)).rem_euclid(TAU);
        let time = rem * radius / speed;
        let exit = Exit { time, heading, point: circle.centre - radial(heading) * (sense * radius) };
        Self { exit: Some(exit), ..circle }
    }

    /// The angular rate ω = v/R_b, rad/s.
    pub fn omega(&self) -> f64 {
        self.speed / self.radius
    }

    /// When the UAV leaves the circle, seconds (∞ for a circle).
    pub fn exit_time(&self) -> f64 {
        self.exit.map_or(f64::INFINITY, |e| e.time)
    }

    /// Position at `t ≥ 0` seconds after the backup's start, metres.
    pub fn at(&self, t: f64) -> Vector2<f64> {
        match self.exit {
            Some(e) if t > e.time => e.point + unit(e.heading) * (self.speed * (t - e.time)),
            _ => self.centre - radial(self.heading + self.sense * self.omega() * t) * (self.sense * self.radius),
        }
    }

    /// The distance of the circle to the segment `[from, to]` an emitter covers, metres (closed form;
    /// whatever the timing).
    #[inline]
    pub fn circle_standoff_min(&self, from: Vector2<f64>, to: Vector2<f64>) -> f64 {
        let (dmin, dmax) = segment_distance_range(self.centre, from, to);
        if (dmin..=dmax).contains(&self.radius) {
            0.0
        } else {
            (dmin - self.radius).abs().min((dmax - self.radius).abs())
        }
    }

    /// The smallest distance (a certified lower bound, metres) over backup times `t ∈ [0, horizon]` to an
    /// emitter at `emitter` at `t = 0` moving at `velocity`; only certified to be at least `threshold`
    /// when it is (pass `f64::INFINITY` for the bracket).
    pub fn standoff_min(&self, emitter: Vector2<f64>, velocity: Vector2<f64>, horizon: f64, threshold: f64) -> f64 {
        let z = |t: f64| emitter + velocity * t;
        let Some(exit) = self.exit else {
            return self.circle_standoff_min(emitter, z(horizon));
        };
        let omega = self.omega();
        let turn_end = exit.time.min(horizon);
        let mut least = f64::INFINITY;
        let mut t = 0.0;
        while t < turn_end {
            let piece = (turn_end - t).min(TURN_PIECE / omega);
            let h = self.heading + self.sense * omega * t;
            let arc = Arc::new(self.at(t), h, h + self.sense * omega * piece, self.speed * piece);
            least = least.min(moving_point_min_distance(&arc, z(t), velocity, piece, threshold).lower);
            t += piece;
        }
        if exit.time < horizon {
            let rel = |t: f64| exit.point + unit(exit.heading) * (self.speed * (t - exit.time)) - z(t);
            least = least.min(segment_distance_range(Vector2::zeros(), rel(exit.time), rel(horizon)).0);
        }
        least
    }
}

/// The smallest and largest distance from `c` to the segment `[q0, q1]`, metres.
fn segment_distance_range(c: Vector2<f64>, q0: Vector2<f64>, q1: Vector2<f64>) -> (f64, f64) {
    let d = q1 - q0;
    let len2 = d.norm_squared();
    let t = if len2 > 0.0 { ((c - q0).dot(&d) / len2).clamp(0.0, 1.0) } else { 0.0 };
    let dmin = (q0 + d * t - c).norm();
    let dmax = (q0 - c).norm().max((q1 - c).norm());
    (dmin, dmax)
}

/// `min_{τ ≥ 0} |r0 + u·τ|`, metres.
fn ray_min(r0: Vector2<f64>, u: Vector2<f64>) -> f64 {
    let uu = u.norm_squared();
    let tau = if uu > 0.0 { (-r0.dot(&u) / uu).max(0.0) } else { 0.0 };
    (r0 + u * tau).norm()
}

/// The closed-form pair minimum while both UAVs circle in the same sense (for ever, or any part of it):
/// the pair's relative position is `c_a − c_b` plus a vector of constant length `2R_b|sin((φ_a − φ_b)/2)|`.
fn circling_min(a: &BackupPath, b: &BackupPath) -> f64 {
    let chord = 2.0 * a.radius * (0.5 * (a.heading - b.heading)).sin().abs();
    ((a.centre - b.centre).norm() - chord).abs()
}

/// The certified minimum distance between `a` and `b` over `[t0, t1]` (finite), or at least
/// `threshold`: relative speed at most `2v`, relative acceleration at most the sum of the UAVs'.
fn window_min(a: &BackupPath, b: &BackupPath, t0: f64, t1: f64, both_turn: bool, threshold: f64) -> f64 {
    let span = t1 - t0;
    if span <= 0.0 {
        return (a.at(t0) - b.at(t0)).norm();
    }
    let f = |s: f64| (a.at(t0 + s * span) - b.at(t0 + s * span)).norm();
    let slope = (a.speed + b.speed) * span;
    let turning = if both_turn { 2.0 } else { 1.0 };
    let accel = turning * a.speed * a.omega().max(b.omega()) * span * span;
    let (f0, f1) = (f(0.0), f(1.0));
    lipschitz_min_within(&mut |s| f(s), &|_, _| slope, Some(accel), f0, f1, threshold, MIN_TOLERANCE_M).lower
}

/// The smallest distance between two UAVs flying their backups at the same time, for all future time
/// (a certified lower bound, metres; see the module docs), or only certified to be at least `threshold`
/// when it is. Both backups have the same radius and speed.
pub fn pair_min(a: &BackupPath, b: &BackupPath, threshold: f64) -> f64 {
    let (ta, tb) = (a.exit_time(), b.exit_time());
    // Circles are clockwise: two of them circle in the same sense.
    let circling = if a.sense == b.sense { circling_min(a, b) } else { 0.0 };
    if ta.is_infinite() && tb.is_infinite() {
        return circling;
    }
    let (first, second) = if ta <= tb { (a, b) } else { (b, a) };
    let (t1, t2) = (ta.min(tb), ta.max(tb));
    // [0, t1]: both circle.
    let mut least =
        if circling >= threshold { circling } else { circling.max(window_min(a, b, 0.0, t1, true, threshold)) };
    // [t1, t2]: `first` flies straight, `second` circles.
    if t2.is_finite() {
        least = least.min(window_min(first, second, t1, t2, false, threshold));
    } else {
        // `second` circles for ever: up to the moment the straight flight is `R_b + reach` from its
        // centre and moving away (its distance increases from its closest approach on), then the
        // distance to the centre less `R_b`.
        let exit = first.exit.expect("the first to exit has an exit");
        let u = unit(exit.heading) * first.speed;
        let p = |t: f64| exit.point + u * (t - exit.time);
        let closest = t1 + (-(p(t1) - second.centre).dot(&u) / u.norm_squared()).max(0.0);
        let reach = if threshold.is_finite() { threshold } else { 4.0 * second.radius };
        let far = closest + (second.radius + reach) / first.speed;
        least = least.min(window_min(first, second, t1, far, false, threshold));
        least = least.min((p(far) - second.centre).norm() - second.radius);
        return least;
    }
    // [t2, ∞): both fly straight.
    let (ea, eb) = (a.exit.expect("finite exit"), b.exit.expect("finite exit"));
    let rel = a.at(t2) - b.at(t2);
    let u = unit(ea.heading) * a.speed - unit(eb.heading) * b.speed;
    least.min(ray_min(rel, u))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::Lcg;
    use std::f64::consts::PI;

    fn random_path(r: &mut Lcg, fly: bool) -> BackupPath {
        let end = Vector2::new(r.next() * 6000.0, r.next() * 6000.0);
        let phi = (r.next() - 0.5) * 2.0 * PI;
        if fly {
            let v = Vector2::new(r.next() - 0.5, r.next() - 0.5) * 16.0;
            let sense = if r.next() < 0.5 { -1.0 } else { 1.0 };
            BackupPath::fly_away(end, phi, 1000.0, 50.0, sense, Vector2::new(3000.0, 3000.0), v)
        } else {
            BackupPath::circle(end, phi, 1000.0, 50.0)
        }
    }

    #[test]
    fn the_path_starts_at_the_end_point_flies_at_speed_and_leaves_on_the_tangent() {
        let mut r = Lcg(3);
        for _ in 0..200 {
            let p = random_path(&mut r, true);
            let start = p.centre - radial(p.heading) * (p.sense * p.radius);
            assert!((p.at(0.0) - start).norm() < 1e-9);
            // Unit speed by finite differences, on the circle, across the exit and on the straight.
            let e = p.exit.unwrap();
            for t in [0.3, e.time * 0.5, e.time, e.time + 7.0, e.time + 500.0] {
                let h = 1e-4;
                let speed = (p.at(t + h) - p.at((t - h).max(0.0))).norm() / (t + h - (t - h).max(0.0));
                assert!((speed - 50.0).abs() < 1e-3, "speed {speed} at t {t}");
            }
            assert!((p.at(e.time) - e.point).norm() < 1e-6, "the exit is on the circle");
            assert!(e.time >= 0.0 && e.time < TAU / p.omega() + 1e-9);
        }
    }

    #[test]
    fn flying_away_opens_the_distance_to_a_moving_emitter() {
        let mut r = Lcg(5);
        for case in 0..300 {
            let z = Vector2::new(r.next() - 0.5, r.next() - 0.5) * 4000.0;
            let u = Vector2::new(r.next() - 0.5, r.next() - 0.5) * 2.0 * 15.0;
            let end = z + unit(r.next() * TAU) * (3000.0 + r.next() * 3000.0);
            let sense = if case % 2 == 0 { -1.0 } else { 1.0 };
            let p = BackupPath::fly_away(end, (r.next() - 0.5) * 2.0 * PI, 800.0, 50.0, sense, z, u);
            let t = p.exit_time();
            // After the exit the range rate is positive and stays so.
            let d = |t: f64| (p.at(t) - (z + u * t)).norm();
            for k in 1..200 {
                let t = t + k as f64 * 20.0;
                assert!(d(t + 1.0) > d(t), "case {case}: closing at {t} s");
            }
        }
    }

    /// The minimum of `f` over a dense grid of `[t0, t1]` (the grid's step bounds the sampling error).
    fn sampled(f: impl Fn(f64) -> f64, t0: f64, t1: f64, n: usize) -> f64 {
        (0..=n).map(|k| f(t0 + (t1 - t0) * k as f64 / n as f64)).fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn pair_minima_are_lower_bounds_of_flying_them_and_close_to_them() {
        let mut r = Lcg(7);
        let mut tight = 0;
        for case in 0..400 {
            let a = random_path(&mut r, case % 3 != 0);
            let b = random_path(&mut r, case % 2 == 0);
            let bound = pair_min(&a, &b, f64::INFINITY);
            // Every path is straight or periodic after 3 periods plus 100 km of flight.
            let horizon = 3.0 * TAU / a.omega() + 100_000.0 / a.speed;
            let flown = sampled(|t| (a.at(t) - b.at(t)).norm(), 0.0, horizon, 400_000);
            assert!(bound <= flown + 1e-6, "case {case}: bound {bound} above the flown {flown}");
            if flown - bound < 5.0 {
                tight += 1;
            }
        }
        assert!(tight >= 300, "only {tight} of 400 bounds within 5 m of the flown minimum");
    }

    #[test]
    fn standoff_minima_are_lower_bounds_of_flying_them() {
        let mut r = Lcg(11);
        for case in 0..300 {
            let p = random_path(&mut r, case % 4 != 0);
            let z = Vector2::new(r.next() - 0.5, r.next() - 0.5) * 8000.0;
            let u = Vector2::new(r.next() - 0.5, r.next() - 0.5) * 20.0;
            let horizon = 50.0 + r.next() * 400.0;
            let bound = p.standoff_min(z, u, horizon, f64::INFINITY);
            let flown = sampled(|t| (p.at(t) - (z + u * t)).norm(), 0.0, horizon, 100_000);
            assert!(bound <= flown + 1e-6, "case {case}: bound {bound} above the flown {flown}");
            if p.exit.is_some() {
                assert!(flown - bound < 1.0, "case {case}: a fly-away's bound {bound} is {flown} flown");
            }
        }
    }
}
