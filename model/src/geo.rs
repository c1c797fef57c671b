//! The geographic frame of a run: a WGS84 origin and the local plane the method works in.
//!
//! uavloc's maths is two-dimensional on a flat plane, in metres (x east, y north). A scenario with an
//! [`Origin`] ties that plane to the Earth: the plane is the east/north plane of the local tangent frame
//! (ENU) at the origin, and a point of the plane stands for the point **at the origin's altitude** whose
//! ENU east and north are its coordinates. Both ways are exact inverses of each other (to < 1 mm within
//! 100 km, see the tests): [`LocalFrame::to_local`] takes a latitude/longitude to the plane,
//! [`LocalFrame::to_geodetic`] a point of the plane back to latitude/longitude.
//!
//! The ellipsoid maths (geodetic ↔ ECEF ↔ ENU on WGS84) is the `map_3d` crate's; this module adds only
//! the choice of the plane and the search for the point at the origin's altitude.
//!
//! What the plane does not describe: the Earth's curvature. The tangent plane drops below the surface
//! by d²/(2R) (785 m at 100 km) and a distance d in the plane is the surface's to within about
//! d³/(6R²) (4 m at 100 km, 4 mm at 10 km): for the tens of kilometres of a localisation run the flat
//! model's error is far below a TDOA σ.
//!
//! Headings stay the plane's angles (radians counter-clockwise from east, as everywhere in uavloc); a
//! compass course (clockwise from north) is `π/2 − heading` ([`course_deg`]).

use map_3d::Ellipsoid;
use thiserror::Error;

/// The largest distance from the origin a geographic position may lie at, metres. Far beyond a run's
/// tens of kilometres; beyond it the flat plane no longer describes the ground (see the module docs).
pub const MAX_GEO_DISTANCE_M: f64 = 1.0e6;

/// The largest |latitude| of an origin, degrees: the east/north directions of the plane are undefined at
/// a pole.
pub const MAX_ORIGIN_LATITUDE_DEG: f64 = 89.0;

/// Why a geographic position or origin was refused.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum GeoError {
    /// A latitude outside [−90°, 90°] (an origin: outside ±[`MAX_ORIGIN_LATITUDE_DEG`]) or not finite.
    #[error("latitude {0}° is outside [-{1}°, {1}°]")]
    Latitude(f64, f64),
    /// A longitude outside [−180°, 180°] or not finite.
    #[error("longitude {0}° is outside [-180°, 180°]")]
    Longitude(f64),
    /// An altitude that is not finite or not between −1 km and 100 km above the ellipsoid.
    #[error("altitude {0} m is outside [-1000 m, 100000 m] above the WGS84 ellipsoid")]
    Altitude(f64),
    /// A point too far from the origin for the flat plane (or not finite).
    #[error("{0:.0} m from the origin: farther than {MAX_GEO_DISTANCE_M} m, where the flat plane no longer holds")]
    TooFar(f64),
}

/// The origin of a run's local plane: WGS84 latitude and longitude (degrees) and altitude above the
/// ellipsoid (metres). TOML: `[origin]` with `lat_deg`, `lon_deg`, `alt_m`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Origin {
    /// Latitude, degrees north.
    pub lat_deg: f64,
    /// Longitude, degrees east.
    pub lon_deg: f64,
    /// Altitude above the WGS84 ellipsoid, metres (0 when not given): the altitude the plane stands for.
    #[serde(default)]
    pub alt_m: f64,
}

/// A geographic position: WGS84 latitude and longitude, degrees.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LatLon {
    /// Latitude, degrees north.
    pub lat_deg: f64,
    /// Longitude, degrees east.
    pub lon_deg: f64,
}

impl LatLon {
    /// Checks the ranges of a latitude and a longitude.
    pub fn new(lat_deg: f64, lon_deg: f64) -> Result<Self, GeoError> {
        if !(lat_deg.is_finite() && lat_deg.abs() <= 90.0) {
            return Err(GeoError::Latitude(lat_deg, 90.0));
        }
        if !(lon_deg.is_finite() && lon_deg.abs() <= 180.0) {
            return Err(GeoError::Longitude(lon_deg));
        }
        Ok(Self { lat_deg, lon_deg })
    }

    /// `[lat, lon]` in degrees.
    pub fn pair(self) -> [f64; 2] {
        [self.lat_deg, self.lon_deg]
    }
}

/// The local plane of an [`Origin`]: conversions both ways (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalFrame {
    origin: Origin,
    lat0: f64,
    lon0: f64,
}

impl LocalFrame {
    /// The plane at `origin`; refuses an origin outside the ranges of [`GeoError`].
    pub fn new(origin: Origin) -> Result<Self, GeoError> {
        LatLon::new(origin.lat_deg, origin.lon_deg)?;
        if origin.lat_deg.abs() > MAX_ORIGIN_LATITUDE_DEG {
            return Err(GeoError::Latitude(origin.lat_deg, MAX_ORIGIN_LATITUDE_DEG));
        }
        if !(origin.alt_m.is_finite() && (-1000.0..=100_000.0).contains(&origin.alt_m)) {
            return Err(GeoError::Altitude(origin.alt_m));
        }
        Ok(Self { origin, lat0: origin.lat_deg.to_radians(), lon0: origin.lon_deg.to_radians() })
    }

    /// The origin.
    pub fn origin(&self) -> Origin {
        self.origin
    }

    /// The point of the plane (x east, y north, metres) of `p` taken at the origin's altitude.
    pub fn to_local(&self, p: LatLon) -> Result<[f64; 2], GeoError> {
        let p = LatLon::new(p.lat_deg, p.lon_deg)?;
        let (e, n, _) = map_3d::geodetic2enu(
            p.lat_deg.to_radians(),
            p.lon_deg.to_radians(),
            self.origin.alt_m,
            self.lat0,
            self.lon0,
            self.origin.alt_m,
            Ellipsoid::WGS84,
        );
        let d = e.hypot(n);
        if !d.is_finite() || d > MAX_GEO_DISTANCE_M {
            return Err(GeoError::TooFar(d));
        }
        Ok([e, n])
    }

    /// The latitude/longitude of a point of the plane: the point at the origin's altitude whose ENU east
    /// and north are `xy`. The ENU up coordinate is found by a fixed-point iteration on the altitude
    /// (its derivative is the cosine of the angle between the two verticals, 1 − 10⁻⁴ at 100 km), which
    /// settles to 10⁻⁹ m in a few steps.
    pub fn to_geodetic(&self, xy: [f64; 2]) -> Result<LatLon, GeoError> {
        let d = xy[0].hypot(xy[1]);
        if !d.is_finite() || d > MAX_GEO_DISTANCE_M {
            return Err(GeoError::TooFar(d));
        }
        let at =
            |up: f64| map_3d::enu2geodetic(xy[0], xy[1], up, self.lat0, self.lon0, self.origin.alt_m, Ellipsoid::WGS84);
        // The sphere's drop as the first guess, then Newton with the slope 1.
        let mut up = -d * d / (2.0 * 6_371_000.0);
        let mut point = at(up);
        for _ in 0..8 {
            let miss = point.2 - self.origin.alt_m;
            if miss.abs() < 1e-9 {
                break;
            }
            up -= miss;
            point = at(up);
        }
        LatLon::new(point.0.to_degrees(), point.1.to_degrees())
    }

    /// [`Self::to_geodetic`] of several points, as `[lat, lon]` pairs in degrees; `None` when any point is
    /// not finite or too far.
    pub fn pairs(&self, points: &[[f64; 2]]) -> Option<Vec<[f64; 2]>> {
        points.iter().map(|p| self.to_geodetic(*p).ok().map(LatLon::pair)).collect()
    }
}

/// A compass course (degrees clockwise from north, in [0, 360)) of a plane heading (radians
/// counter-clockwise from east).
pub fn course_deg(heading_rad: f64) -> f64 {
    (90.0 - heading_rad.to_degrees()).rem_euclid(360.0)
}

/// The boundary of the `p`-probability ellipse of N(`centre`, `cov`) in the plane, `n` points (closed:
/// the first point repeated at the end). `None` when `cov` is not symmetric positive semi-definite and
/// finite. The ellipse is `(x − c)ᵀ cov⁻¹ (x − c) = χ²₂(p) = −2 ln(1 − p)`.
pub fn confidence_ellipse(centre: [f64; 2], cov: [[f64; 2]; 2], p: f64, n: usize) -> Option<Vec<[f64; 2]>> {
    let (a, b, c) = (cov[0][0], 0.5 * (cov[0][1] + cov[1][0]), cov[1][1]);
    if ![a, b, c, centre[0], centre[1]].iter().all(|v| v.is_finite()) || !(0.0..1.0).contains(&p) || n < 3 {
        return None;
    }
    // Eigen-decomposition of the symmetric 2×2.
    let mean = 0.5 * (a + c);
    let half = (0.25 * (a - c) * (a - c) + b * b).sqrt();
    let (l1, l2) = (mean + half, mean - half);
    if l2 < -1e-9 * l1.abs().max(1.0) {
        return None;
    }
    let angle = 0.5 * (2.0 * b).atan2(a - c);
    let k = (-2.0 * (1.0 - p).ln()).sqrt();
    let (r1, r2) = (k * l1.max(0.0).sqrt(), k * l2.max(0.0).sqrt());
    let (ca, sa) = (angle.cos(), angle.sin());
    let mut out: Vec<[f64; 2]> = (0..n)
        .map(|i| {
            let t = std::f64::consts::TAU * i as f64 / n as f64;
            let (u, v) = (r1 * t.cos(), r2 * t.sin());
            [centre[0] + ca * u - sa * v, centre[1] + sa * u + ca * v]
        })
        .collect();
    out.push(out[0]);
    Some(out)
}

/// A circle of `radius` metres around `centre` in the plane, `n` points, closed.
pub fn circle(centre: [f64; 2], radius: f64, n: usize) -> Vec<[f64; 2]> {
    let mut out: Vec<[f64; 2]> = (0..n)
        .map(|i| {
            let t = std::f64::consts::TAU * i as f64 / n as f64;
            [centre[0] + radius * t.cos(), centre[1] + radius * t.sin()]
        })
        .collect();
    out.push(out[0]);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn ecef(p: LatLon, alt: f64) -> [f64; 3] {
        let (x, y, z) = map_3d::geodetic2ecef(p.lat_deg.to_radians(), p.lon_deg.to_radians(), alt, Ellipsoid::WGS84);
        [x, y, z]
    }

    fn apart(a: [f64; 3], b: [f64; 3]) -> f64 {
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    }

    /// lat/lon → plane → lat/lon within 1 mm (as a distance on the ground) everywhere within 100 km of
    /// origins from the equator to 85°, over the date line and at both altitude ends.
    #[test]
    fn a_round_trip_within_100_km_is_within_a_millimetre() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut worst = 0.0f64;
        for origin in [
            (0.0, 0.0, 0.0),
            (47.3977, 8.5456, 488.0),
            (-33.9, 151.2, 30.0),
            (64.0, 179.9, 5000.0),
            (85.0, -60.0, -100.0),
        ] {
            let frame = LocalFrame::new(Origin { lat_deg: origin.0, lon_deg: origin.1, alt_m: origin.2 }).unwrap();
            for _ in 0..400 {
                let (r, t) = (rng.random_range(0.0..100_000.0f64), rng.random_range(0.0..std::f64::consts::TAU));
                let xy = [r * t.cos(), r * t.sin()];
                // Plane → lat/lon → plane.
                let back = frame.to_local(frame.to_geodetic(xy).unwrap()).unwrap();
                let miss = (back[0] - xy[0]).hypot(back[1] - xy[1]);
                // lat/lon → plane → lat/lon, as a distance on the ground.
                let p = frame.to_geodetic(xy).unwrap();
                let q = frame.to_geodetic(frame.to_local(p).unwrap()).unwrap();
                let ground = apart(ecef(p, origin.2), ecef(q, origin.2));
                worst = worst.max(miss).max(ground);
            }
        }
        assert!(worst < 1e-3, "worst round trip {worst} m");
    }

    /// Against PROJ (pyproj 3.6, `+proj=topocentric` on WGS84 geodetic coordinates) for GeographicLib's own
    /// example: origin Paris (48°50′ N, 2°20′ E, 0 m), Calais (50.9° N, 1.8° E, 0 m) at
    /// E −37 518.6, N 229 949.7, U −4 260.4 — the plane keeps E and N.
    #[test]
    fn calais_from_paris_matches_an_independent_implementation() {
        let frame =
            LocalFrame::new(Origin { lat_deg: 48.0 + 50.0 / 60.0, lon_deg: 2.0 + 20.0 / 60.0, alt_m: 0.0 }).unwrap();
        let [e, n] = frame.to_local(LatLon::new(50.9, 1.8).unwrap()).unwrap();
        assert!((e - -37_518.6).abs() < 0.1 && (n - 229_949.7).abs() < 0.1, "{e} {n}");
        // The way back lands on Calais at the origin's altitude.
        let back = frame.to_geodetic([e, n]).unwrap();
        assert!((back.lat_deg - 50.9).abs() < 1e-10 && (back.lon_deg - 1.8).abs() < 1e-10, "{back:?}");
    }

    /// A distance in the plane is the straight-line (chord) distance between the two points at the
    /// origin's altitude, to within the curvature bound of the module docs.
    #[test]
    fn distances_in_the_plane_are_ground_distances_to_within_the_curvature_bound() {
        let origin = Origin { lat_deg: 47.3977, lon_deg: 8.5456, alt_m: 488.0 };
        let frame = LocalFrame::new(origin).unwrap();
        for (a, b) in [([0.0f64, 0.0], [10_000.0f64, 0.0]), ([-5_000.0, 3_000.0], [20_000.0, 15_000.0])] {
            let plane = (a[0] - b[0]).hypot(a[1] - b[1]);
            let (pa, pb) = (frame.to_geodetic(a).unwrap(), frame.to_geodetic(b).unwrap());
            let chord = apart(ecef(pa, origin.alt_m), ecef(pb, origin.alt_m));
            let far = a[0].hypot(a[1]).max(b[0].hypot(b[1])).max(plane);
            let bound = far.powi(3) / (6.0 * 6.3e6f64.powi(2)) * 4.0 + 1e-6;
            assert!((plane - chord).abs() <= bound, "plane {plane} chord {chord} bound {bound}");
        }
    }

    #[test]
    fn bad_origins_and_positions_are_refused_by_name() {
        let bad = |lat, lon, alt| LocalFrame::new(Origin { lat_deg: lat, lon_deg: lon, alt_m: alt }).unwrap_err();
        assert!(matches!(bad(91.0, 0.0, 0.0), GeoError::Latitude(..)));
        assert!(matches!(bad(89.5, 0.0, 0.0), GeoError::Latitude(_, 89.0)));
        assert!(matches!(bad(f64::NAN, 0.0, 0.0), GeoError::Latitude(..)));
        assert!(matches!(bad(0.0, 181.0, 0.0), GeoError::Longitude(_)));
        assert!(matches!(bad(0.0, 0.0, f64::INFINITY), GeoError::Altitude(_)));
        let frame = LocalFrame::new(Origin { lat_deg: 10.0, lon_deg: 10.0, alt_m: 0.0 }).unwrap();
        assert!(matches!(frame.to_local(LatLon { lat_deg: 30.0, lon_deg: 10.0 }), Err(GeoError::TooFar(_))));
        assert!(matches!(frame.to_geodetic([f64::NAN, 0.0]), Err(GeoError::TooFar(_))));
        assert!(frame.to_geodetic([2.0e6, 0.0]).unwrap_err().to_string().contains("from the origin"));
    }

    /// The ellipse's points sit on the χ² contour, and the fraction of Gaussian draws inside it is p.
    #[test]
    fn the_ellipse_holds_its_probability() {
        let cov = [[400.0, 150.0], [150.0, 100.0]];
        let pts = confidence_ellipse([10.0, -5.0], cov, 0.95, 64).unwrap();
        assert_eq!(pts.len(), 65);
        let det = cov[0][0] * cov[1][1] - cov[0][1] * cov[1][0];
        let m2 = |x: f64, y: f64| (cov[1][1] * x * x - 2.0 * cov[0][1] * x * y + cov[0][0] * y * y) / det;
        for p in &pts {
            assert!((m2(p[0] - 10.0, p[1] + 5.0) - 5.991_464_547).abs() < 1e-6);
        }
        let l = nalgebra::Matrix2::new(cov[0][0], cov[0][1], cov[1][0], cov[1][1]).cholesky().unwrap().l();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let n = 20_000;
        let inside = (0..n)
            .filter(|_| {
                let z: nalgebra::Vector2<f64> =
                    nalgebra::Vector2::from_fn(|_, _| rng.sample(rand_distr::StandardNormal));
                let d = l * z;
                m2(d.x, d.y) <= 5.991_464_547
            })
            .count();
        assert!((inside as f64 / n as f64 - 0.95).abs() < 0.006, "{inside}");
        assert!(confidence_ellipse([0.0, 0.0], [[1.0, 2.0], [2.0, 1.0]], 0.95, 16).is_none(), "indefinite");
        assert!((course_deg(0.0) - 90.0).abs() < 1e-12 && (course_deg(std::f64::consts::FRAC_PI_2)).abs() < 1e-12);
    }
}
