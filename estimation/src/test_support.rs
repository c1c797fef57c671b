//! What the estimator's unit tests share: noise-free bursts, a static posterior, the default three
//! UAVs and a geometry where Chan's fix has two physical roots.

use nalgebra::Vector2;
use tdoa::{EmitterModel, NoiseModel, RangeDiffs, Sensors, chan};

pub(crate) fn noise(n: usize) -> NoiseModel {
    NoiseModel::uniform(n, 28.7712).unwrap()
}

pub(crate) fn diffs(uavs: &[Vector2<f64>], z: Vector2<f64>) -> RangeDiffs {
    let r: Vec<f64> = uavs.iter().map(|w| (z - w).norm()).collect();
    RangeDiffs::from_slice(&r[1..].iter().map(|ri| ri - r[0]).collect::<Vec<_>>()).unwrap()
}

/// A static emitter's posterior at `z` (metres) with variance `var` (m²) on every axis.
pub(crate) fn static_at(z: Vector2<f64>, var: f64) -> tdoa::Posterior {
    tdoa::Posterior::new(
        EmitterModel::Static,
        nalgebra::Vector4::new(z.x, z.y, 0.0, 0.0),
        nalgebra::Matrix4::identity() * var,
    )
    .unwrap()
}

pub(crate) fn nominal() -> Vec<Vector2<f64>> {
    vec![Vector2::new(1500.0, 500.0), Vector2::new(10000.0, 1500.0), Vector2::new(5000.0, 8500.0)]
}

/// A noise-free 3-UAV case where both roots are physical.
pub(crate) fn ambiguous_case() -> (Vec<Vector2<f64>>, Vector2<f64>, Vector2<f64>) {
    let uavs = vec![Vector2::new(0.0, 0.0), Vector2::new(4000.0, 0.0), Vector2::new(0.0, 4000.0)];
    let sensors = Sensors::new(&[[0.0, 0.0], [4000.0, 0.0], [0.0, 4000.0]], noise(3)).unwrap();
    for i in -20..=20 {
        for j in -20..=20 {
            let z = Vector2::new(1000.0 * i as f64 + 137.0, 1000.0 * j as f64 + 71.0);
            if let Ok(sol) = chan(&sensors, &diffs(&uavs, z), None)
                && sol.ambiguous
                && sol.candidates.len() == 2
            {
                let other = if (sol.candidates[0] - z).norm() < 1e-3 { sol.candidates[1] } else { sol.candidates[0] };
                if (other - z).norm() > 1000.0 {
                    return (uavs, z, other);
                }
            }
        }
    }
    panic!("no ambiguous geometry found");
}
