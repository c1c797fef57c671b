use nalgebra::Vector2;
use tdoa::global::*;
use tdoa::*;
fn main() {
    let s = Sensors::new(
        &[[-13143.509208019279, 0.0], [13718.924205146921, -6997.3804266435], [16046.972168813067, -8575.246053861854]],
        NoiseModel::uniform(3, 5.0).unwrap(),
    )
    .unwrap();
    let z = Vector2::new(-29610.73043753697, 0.0);
    let c = crlb(&s, &z).unwrap();
    println!("cond {} crlb {}", c.cond, c.crlb_m);
    for eps in [0.05, 0.2, 0.5] {
        let r = s.positions().iter().map(|w| (w - z).norm()).fold(f64::INFINITY, f64::min);
        let ell = r / c.cond.sqrt();
        let lmax = tdoa::fim::sym_eigenvalues(&c.bound).1;
        let cov = c.bound * (eps * ell).powi(2) / lmax;
        let u = Uncertainty::with_eq36_side(z, cov, s.mean_range(&z), DEFAULT_KAPPA).unwrap();
        let exact = global_crlb(&Quadrature::default(), &s, &u).value;
        let mut zs = vec![];
        for seed in 0..400 {
            let r = global_crlb(&MonteCarlo::new(1000, seed, McScheme::UniformWeighted).unwrap(), &s, &u).value;
            zs.push((r.trace_m2 - exact.trace_m2) / r.stderr_m2.unwrap());
        }
        zs.sort_by(f64::total_cmp);
        let mean: f64 = zs.iter().sum::<f64>() / 400.0;
        let sd = (zs.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / 400.0).sqrt();
        println!(
            "eps {eps} side {} sing {:?} exact {:?} z mean {mean:.3} sd {sd:.3} min {:.2} max {:.2}",
            u.side(),
            singular_report(&s, &u),
            exact,
            zs[0],
            zs[399]
        );
    }
}
