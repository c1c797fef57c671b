//! A planner's command as guided targets: per UAV its waypoint (the end of the arc it flies this
//! interval) as latitude/longitude, and its heading as a yaw clockwise from north.

use model::geo::{LocalFrame, course_deg};
use protocol::Command;

/// One UAV's guided target, in MAVLink's units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Target {
    /// Latitude, degE7.
    pub lat_e7: i32,
    /// Longitude, degE7.
    pub lon_e7: i32,
    /// Yaw, radians clockwise from north in [0, 2π).
    pub yaw: f32,
}

impl Target {
    /// The target at `waypoint` (plane, metres) with `heading` (plane radians); `None` when the
    /// waypoint is not finite or too far from the origin for the plane.
    pub fn of(frame: &LocalFrame, waypoint: [f64; 2], heading: f64) -> Option<Self> {
        let p = frame.to_geodetic(waypoint).ok()?;
        let yaw = course_deg(heading).to_radians() as f32;
        yaw.is_finite().then(|| Self {
            lat_e7: (p.lat_deg * 1e7).round() as i32,
            lon_e7: (p.lon_deg * 1e7).round() as i32,
            yaw,
        })
    }
}

/// The targets of a command, one per UAV (`None` for a UAV whose waypoint has no place).
pub fn targets(frame: &LocalFrame, command: &Command) -> Vec<Option<Target>> {
    command.waypoints().iter().zip(command.headings()).map(|(w, h)| Target::of(frame, *w, *h)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::geo::Origin;

    #[test]
    fn a_waypoint_north_east_of_the_origin_and_a_heading_north_east() {
        let frame = LocalFrame::new(Origin { lat_deg: 47.0, lon_deg: 8.0, alt_m: 400.0 }).unwrap();
        let t = Target::of(&frame, [1000.0, 1000.0], std::f64::consts::FRAC_PI_4).unwrap();
        // 1 km north is 1/111.2 km of a degree of latitude at 47°; 1 km east 1/(111.3 cos 47°) of longitude.
        assert!((f64::from(t.lat_e7) * 1e-7 - 47.008_99).abs() < 2e-5, "{t:?}");
        assert!((f64::from(t.lon_e7) * 1e-7 - 8.013_17).abs() < 3e-5, "{t:?}");
        assert!(
            (f64::from(t.yaw) - std::f64::consts::FRAC_PI_4).abs() < 1e-6,
            "north-east is 45° clockwise from north"
        );
        let back = frame
            .to_local(model::geo::LatLon::new(f64::from(t.lat_e7) * 1e-7, f64::from(t.lon_e7) * 1e-7).unwrap())
            .unwrap();
        assert!((back[0] - 1000.0).abs() < 0.02 && (back[1] - 1000.0).abs() < 0.02, "degE7 keeps 1 cm");
        assert!(Target::of(&frame, [f64::NAN, 0.0], 0.0).is_none());
        assert!(Target::of(&frame, [5.0e6, 0.0], 0.0).is_none(), "beyond the plane");
    }
}
