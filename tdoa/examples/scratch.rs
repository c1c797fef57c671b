use nalgebra::{Matrix2, Vector2};
use tdoa::*;
fn main() {
    let s =
        Sensors::new(&[[1500.0, 500.0], [10000.0, 1500.0], [5000.0, 8500.0]], NoiseModel::uniform(3, 28.7712).unwrap())
            .unwrap();
    let z = Vector2::new(25000.0, 15000.0);
    let c = crlb(&s, &z).unwrap();
    println!("crlb {} ratio {} cond {}", c.crlb_m, c.crlb_m / 28.7712, c.cond);
    let d = s.range_differences(&z);
    let sol = chan(&s, &d, None).unwrap();
    println!("{:?}", sol);
    let mut amb = 0;
    let mut wrong = 0;
    let mut rng = tdoa::rng::stream(1, 0, tdoa::rng::Purpose::RmseResamples);
    for _ in 0..2000 {
        let d = montecarlo::noisy_range_diffs(&s, &z, &mut rng);
        if let Ok(sol) = chan(&s, &d, None) {
            if sol.ambiguous {
                amb += 1;
                if (sol.position - z).norm() > 5000.0 {
                    wrong += 1;
                }
            }
        }
    }
    println!("ambiguous {amb} wrong-first {wrong}");
    println!("{:?}", montecarlo::rmse(&s, &z, 2000, 1, None));
    println!("{:?}", montecarlo::rmse(&s, &z, 2000, 1, Some(Vector2::new(24000.0, 14000.0))));
    let m = c.bound;
    for sc in [0.25, 0.5, 0.75, 1.0] {
        let cov = m * sc * sc;
        let u = Uncertainty::with_eq36_side(z, cov, s.mean_range(&z), DEFAULT_KAPPA).unwrap();
        print!("scale {sc} side {:.0} ", u.side());
        for meth in Method::ALL {
            let g = meth.build(200, 7).unwrap();
            let r = global_crlb(g.as_ref(), &s, &u);
            print!("{}={:.1} ", meth, r.value.trace_m2.sqrt());
        }
        println!("sing {:?}", singular_report(&s, &u));
    }
    // 4 UAVs
    let s4 = Sensors::new(
        &[[1500.0, 500.0], [10000.0, 1500.0], [5000.0, 8500.0], [0.0, 9000.0]],
        NoiseModel::uniform(4, 28.7712).unwrap(),
    )
    .unwrap();
    let d4 = s4.range_differences(&z);
    let sol4 = chan(&s4, &d4, None).unwrap();
    println!("{:?} crlb {:?}", sol4, crlb(&s4, &z).unwrap().bound);
    println!("{:?}", montecarlo::rmse(&s4, &z, 2000, 1, None));
    let _ = Matrix2::<f64>::identity();
}
