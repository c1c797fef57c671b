//! The monitor's status line: one line on stderr per recorded step (what `monitor` shows unless
//! `--quiet`).
//!
//! Its fields: step, CRLB at the truth, RMSE, estimate error,
//! the hops measurement→estimator and estimate→planner, the planning time, the whole cycle, the active
//! planner and the rejected-message count; `COMMAND MISSED` for a step flown without its command,
//! `ESTIMATE STALE` for a step whose command was the planner's hold.

use crate::assemble::CompletedStep;

fn fmt_us(ns: Option<u64>) -> String {
    match ns {
        Some(v) if v >= 10_000_000 => format!("{:.1} ms", v as f64 / 1e6),
        Some(v) => format!("{} µs", v / 1000),
        None => "-".into(),
    }
}

fn fmt_m(v: Option<f64>) -> String {
    v.map_or("-".into(), |x| format!("{x:.1}"))
}

/// One status line of a completed step.
/// What the receivers delivered at a step, for its status line: empty for a complete burst.
fn receiver_note(r: Option<&record::record::StepReceiver>) -> String {
    let Some(r) = r else { return String::new() };
    let list = |v: &[usize]| v.iter().map(|i| i.to_string()).collect::<Vec<_>>().join(",");
    if r.silent == Some(true) {
        return "  SILENT".to_string();
    }
    let mut note = format!("  heard {}", list(&r.heard));
    if !r.outliers.is_empty() {
        note += &format!(" outliers {}", list(&r.outliers));
    }
    note
}

pub(crate) fn status_line(done: &CompletedStep, last: u64, rejected: u64) -> String {
    let r = &done.record;
    let l = &done.latencies;
    let planner = done
        .planner
        .as_ref()
        .map_or("-".to_string(), |p| format!("{}/{} #{:x}", p.solver, p.objective, p.instance >> 32));
    // The 95 % ellipse of the reported covariance: semi-axes sqrt(χ²₂(0.95) λ) = sqrt(5.991 λ).
    let c = &r.estimate_cov;
    let (lo, hi) = tdoa::fim::sym_eigenvalues(&tdoa::matrix_from_rows(c));
    // χ²₂(0.95) = −2 ln 0.05 (the 2-dof quantile has this closed form).
    let k95 = -2.0 * 0.05f64.ln();
    // Without a truth the closest UAV is the one closest to the estimate.
    let (to, z) = done.truth.map_or(("ẑ", r.estimate), |t| ("z", t));
    let closest = r.uavs.iter().map(|w| (w[0] - z[0]).hypot(w[1] - z[1])).fold(f64::INFINITY, f64::min);
    format!(
        "step {:>3}/{last}  CRLB {:>8} m  CRLB@ẑ {:>8} m  RMSE {:>8} m  |ẑ−z| {:>8} m  95% ellipse {:.0}×{:.0} m  \
         closest UAV to {to} {:.0} m  meas→est {:>7}  est→plan {:>7}  plan {:>8}  cycle {:>8}  planner {planner}  \
         rejected {rejected}{}{}",
        r.step,
        fmt_m(r.crlb_true_m),
        fmt_m(r.crlb_at_estimate_m),
        fmt_m(r.rmse_m),
        fmt_m(done.error_m),
        (k95 * hi.max(0.0)).sqrt(),
        (k95 * lo.max(0.0)).sqrt(),
        closest,
        fmt_us(l.measurement_hop_ns),
        fmt_us(l.estimate_hop_ns),
        r.plan_ms.map_or("-".into(), |ms| format!("{ms:.3} ms")),
        fmt_us(l.cycle_ns),
        receiver_note(r.receiver.as_ref()),
        if done.missed {
            "  COMMAND MISSED (flew the hold)"
        } else if done.held {
            "  ESTIMATE STALE (planner held)"
        } else {
            ""
        },
    )
}

#[cfg(test)]
mod tests {
    use super::receiver_note;
    use record::record::StepReceiver;

    #[test]
    fn the_status_line_names_who_heard_the_burst() {
        assert_eq!(receiver_note(None), "");
        assert_eq!(receiver_note(Some(&StepReceiver::from_masks(4, 0, 0, Some(true), None))), "  SILENT");
        assert_eq!(receiver_note(Some(&StepReceiver::from_masks(4, 0b1101, 0, Some(false), None))), "  heard 0,2,3");
        assert_eq!(
            receiver_note(Some(&StepReceiver::from_masks(4, 0b1111, 0b0010, Some(false), None))),
            "  heard 0,1,2,3 outliers 1"
        );
    }
}
