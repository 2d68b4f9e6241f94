//! `aidnav tune`: run the job, print its tables.

use std::path::Path;

use aidnav::app::jobs::{self, TuneJob};
use aidnav::app::process::tune::{PARAMETERS, TuneResult};
use anyhow::Result;

use super::TuneArgs;

pub(crate) fn run_tune(a: TuneArgs) -> Result<()> {
    let stem = a
        .config
        .file_stem()
        .map_or_else(|| "tune".into(), |s| s.to_string_lossy().into_owned());
    let out = a
        .out
        .unwrap_or_else(|| Path::new("results").join(format!("{stem}_tune")));
    let r = jobs::tune(&TuneJob {
        config: a.config,
        data_dir: a.data,
        out,
        max_evaluations: a.max_evaluations.map(|n| n as usize),
    })?;
    for w in &r.warnings {
        eprintln!("note: {w}");
    }
    println!(
        "{} IMU samples, {} GNSS epochs; read {:.2} s, standstill and Allan deviation {:.2} s, likelihood search {:.1} s ({} filter passes); aidnav {}",
        r.imu_samples,
        r.gnss_epochs,
        r.timing_s[0],
        r.timing_s[1],
        r.timing_s[2],
        r.tuning.passes,
        aidnav::VERSION
    );
    print_allan(&r.tuning);
    print_fit(&r.tuning);
    for f in &r.files {
        println!("wrote {}", f.display());
    }
    Ok(())
}

/// The standstill and the Allan table.
pub(crate) fn print_allan(t: &TuneResult) {
    match &t.stretch {
        Some(s) => println!(
            "longest standstill: {:.1} s, {:.1} s into the log ({}, {} samples)",
            s.duration_s,
            s.after_first_sample_s,
            aidnav::io::text::date_time(s.start_s),
            s.samples
        ),
        None => println!("longest standstill: none"),
    }
    let Some(a) = &t.allan else {
        println!("no Allan deviation (see the note); the search starts from the configured noise");
        return;
    };
    println!(
        "Allan deviation of the unsmoothed samples at rest (τ {:.2}–{:.1} s; white noise on the −½ slope, bias instability = minimum / 0.664, ≤: the curve still falls at the longest τ):",
        a.axes
            .first()
            .and_then(|x| x.curve.tau_s.first())
            .unwrap_or(&f64::NAN),
        a.axes
            .first()
            .and_then(|x| x.curve.tau_s.last())
            .unwrap_or(&f64::NAN),
    );
    println!(
        "  {:<8} {:>34} {:>26} {:>24}",
        "axis", "white noise", "bias instability", "rate random walk"
    );
    for (k, x) in a.axes.iter().enumerate() {
        let gyro = k < 3;
        let (wu, bu, ku) = if gyro {
            ("deg/√h", "deg/h", "deg/h/√h")
        } else {
            ("m/s/√h", "mg", "mg/√h")
        };
        let white = match (x.white_datasheet, x.white) {
            (Some(v), Some(f)) => format!(
                "{v:.4} {wu} (τ {:.2}–{:.2} s)",
                f.tau_range_s.0, f.tau_range_s.1
            ),
            _ => "— (no −½ slope)".to_string(),
        };
        let bias = match (x.bias_datasheet, x.bias_instability) {
            (Some(v), Some(b)) => format!(
                "{}{v:.3} {bu} at {:.1} s",
                if b.upper_bound { "≤ " } else { "" },
                b.tau_s
            ),
            _ => "—".to_string(),
        };
        let walk = x
            .random_walk_datasheet
            .map_or_else(|| "—".to_string(), |v| format!("{v:.3} {ku}"));
        println!("  {:<8} {white:>34} {bias:>26} {walk:>24}", x.axis);
    }
    let opt = |v: Option<f64>, bound: bool| {
        v.map_or("—".to_string(), |v| {
            format!("{}{v:.4}", if bound { "≤ " } else { "" })
        })
    };
    println!(
        "  filter terms (RMS over the axes): ARW {} deg/√h, VRW {} m/s/√h, gyro bias instability {} deg/h, accelerometer {} mg",
        opt(a.arw_deg_per_sqrt_h, false),
        opt(a.vrw_mps_per_sqrt_h, false),
        opt(a.gyro_bias_deg_per_h, a.gyro_bias_upper_bound),
        opt(a.accel_bias_mg, a.accel_bias_upper_bound)
    );
}

/// The fitted values and the likelihood gain.
pub(crate) fn print_fit(t: &TuneResult) {
    println!(
        "maximum {}, from the {} values:",
        t.objective_text(),
        t.search_start
    );
    println!(
        "  {:<22} {:>12} {:>26} {:>12} {:>18}",
        "parameter", "configured", "Allan (from)", "fitted", "fitted/configured"
    );
    let (c, a, f) = (
        t.configured.parameters(),
        t.allan_values.parameters(),
        t.fitted.parameters(),
    );
    for (i, name) in PARAMETERS.iter().enumerate() {
        let from = t.allan_sources.get(i).copied().unwrap_or("");
        println!(
            "  {:<22} {:>12.4} {:>26} {:>12.4} {:>18}{}",
            name,
            c[i],
            format!("{:.4} ({from})", a[i]),
            f[i],
            format!("×{:.3}", t.factors.get(i).copied().unwrap_or(f64::NAN)),
            if i >= t.searched {
                "  (not searched: no non-holonomic constraint)"
            } else if t.at_bound.contains(name) {
                "  (at the search's edge)"
            } else {
                ""
            }
        );
    }
    println!(
        "  log-likelihood: configured {:.1}, Allan {}, fitted {:.1}: gain {:+.1} over the configured ({:+.4} per epoch); {} passes, {} iterations, {}",
        t.log_likelihood_configured,
        t.log_likelihood_allan
            .map_or_else(|| "—".to_string(), |v| format!("{v:.1}")),
        t.log_likelihood_fitted,
        t.gain(),
        t.gain() / t.updates.max(1) as f64,
        t.evaluations,
        t.iterations,
        if t.converged {
            "converged"
        } else {
            "stopped by tune.max_evaluations"
        }
    );
}
