//! `aidnav process`: run the job, print its tables.

use std::path::Path;

use aidnav::jobs::{self, ProcessReport};
use anyhow::Result;

use super::ProcessArgs;

pub(crate) fn run_process(a: ProcessArgs) -> Result<()> {
    let stem = a
        .config
        .file_stem()
        .map_or_else(|| "process".into(), |s| s.to_string_lossy().into_owned());
    let out = a.out.unwrap_or_else(|| Path::new("results").join(stem));
    let r = jobs::process(&a.config, a.data.as_deref(), &out, !a.no_score)?;
    for w in &r.warnings {
        eprintln!("warning: {w}");
    }
    println!(
        "{} IMU samples, {} GNSS epochs; read {:.2} s, filter pass (+ smoother when on) {:.2} s ({:.0} IMU epochs/s), scoring {:.2} s; aidnav {}",
        r.imu_samples,
        r.gnss_epochs,
        r.timing_s[0],
        r.timing_s[1],
        r.imu_samples as f64 / r.timing_s[1],
        r.timing_s[2],
        aidnav::VERSION
    );
    let outcomes: Vec<String> = r.outcomes.iter().map(|(k, v)| format!("{k} {v}")).collect();
    println!(
        "all GNSS, policy {:?}: RMS 3-D antenna error over RTK-fixed epochs {:.4} m; updates: {}",
        r.policy,
        r.tracking_rms_m,
        outcomes.join(", ")
    );
    print_resets(&r);
    let conv: Vec<String> = r
        .instrument_convergence_s
        .iter()
        .map(|(thr, t)| {
            format!(
                "δ ≤ {:.0} %: {}",
                thr * 100.0,
                t.map_or("never".into(), |t| format!("{t:.1} s"))
            )
        })
        .collect();
    if !conv.is_empty() {
        println!(
            "instrument errors converged (spec 10's Cramér–Rao rule, after the first fix): {}",
            conv.join(", ")
        );
    }
    if let Some(s) = r.tracking_smoothed_rms_m {
        println!("RTS-smoothed: RMS 3-D antenna error over RTK-fixed epochs {s:.4} m");
    }
    print_outages(&r);
    print_anomalies(&r);
    for f in &r.files {
        println!("wrote {}", f.display());
    }
    Ok(())
}

/// The outage tables: coasting, free INS and smoothed drift; the bridged
/// drift; the efficiency criterion.
fn print_outages(r: &ProcessReport) {
    if !r.outages.is_empty() {
        println!("simulated outages — RMS over windows of the maximum drift [m]:");
        println!(
            "{:>6} {:>8} {:>12} {:>10} {:>8} {:>14} {:>12}",
            "L [s]", "windows", "horizontal", "vertical", "3-D", "free INS 3-D", "smoothed 3-D"
        );
        for (k, (s, f)) in r.outages.iter().zip(&r.outages_free_ins).enumerate() {
            let smoothed = r
                .outages_smoothed
                .get(k)
                .map_or_else(|| "—".to_string(), |o| format!("{:.2}", o.three_d_m));
            println!(
                "{:>6.0} {:>8} {:>12.2} {:>10.2} {:>8.2} {:>14.1} {:>12}",
                s.outage_s,
                s.windows,
                s.horizontal_m,
                s.vertical_m,
                s.three_d_m,
                f.three_d_m,
                smoothed
            );
        }
    }
    if !r.outages_bridged.is_empty() {
        println!(
            "the same outages bridged by spec 20's predictors (extrapolated GNSS corrections) — RMS 3-D [m]; coasting filter = a-priori model:"
        );
        for b in &r.outages_bridged {
            let cells: Vec<String> = b
                .scores
                .iter()
                .map(|s| format!("{:.0} s: {:.2}", s.outage_s, s.three_d_m))
                .collect();
            println!(
                "  {:<15} {}",
                aidnav::process::config_name(&b.predictor),
                cells.join("   ")
            );
        }
    }
    if !r.efficiency.is_empty() {
        println!(
            "efficiency criterion K_eff = σ_GNSS / σ_filter in the outages (clean run: K_eff > 1 at {:.1} % of the epochs):",
            100.0 * r.k_eff_integrated_fraction
        );
        for e in &r.efficiency {
            println!(
                "  {:>3.0} s: σ_GNSS {:.3} m; K_eff < 1 after {:.1} s (in {}/{} windows), actual error > σ_GNSS after {:.1} s (in {}/{})",
                e.outage_s,
                e.sigma_gnss_m,
                e.predicted_crossing_s,
                e.predicted_crossed,
                e.windows,
                e.actual_crossing_s,
                e.actual_crossed,
                e.windows
            );
        }
    }
}

/// The recovery's resets of the clean run, on stderr (they are the
/// filter overruling itself: worth seeing beside the warnings).
fn print_resets(r: &ProcessReport) {
    let first = r.recovery.events.first().map(|e| e.time_s);
    // The first few: a filter that resets all the time says so in the count.
    const SHOWN: usize = 6;
    let mut times: Vec<String> = r
        .recovery
        .events
        .iter()
        .take(SHOWN)
        .map(|e| {
            let what = match (e.position, e.velocity) {
                (true, true) => "position and velocity",
                (true, false) => "position",
                _ => "velocity",
            };
            format!(
                "{} GPST, fix {} ({what})",
                aidnav::io::text::date_time(e.time_s),
                e.index
            )
        })
        .collect();
    if r.recovery.events.len() > SHOWN {
        times.push("…".into());
    }
    match first {
        None => eprintln!("recovery: no reset"),
        Some(_) => eprintln!(
            "recovery: {} reset(s) to an agreeing run of refused fixes: {}",
            r.recovery.resets,
            times.join(", ")
        ),
    }
}

/// The anomaly tables: injected outliers, and bursts after outages (with
/// the recovery's resets of each run).
fn print_anomalies(r: &ProcessReport) {
    if !r.anomalies.is_empty() {
        println!(
            "injected outliers (5–50 m jumps, σ unchanged) — RMS 3-D error over RTK-fixed epochs [m] (recovery resets):"
        );
        for (k, (f, p, rms)) in r.anomalies.iter().enumerate() {
            let resets = r.anomaly_resets.get(k).copied().unwrap_or(0);
            println!(
                "  {:>3.0} %  {:<22} {:>8.3}   ({resets})",
                f * 100.0,
                p.name(),
                rms
            );
        }
    }
    if !r.post_outage_bursts.is_empty() {
        println!(
            "30 s outages, each followed by a burst (one 5–50 m jump on the first fixes back) — RMS 3-D error over RTK-fixed epochs with GNSS [m] (recovery resets):"
        );
        for (k, (p, burst, clean)) in r.post_outage_bursts.iter().enumerate() {
            let [with, without] = r.burst_resets.get(k).copied().unwrap_or([0, 0]);
            println!(
                "  {:<22} {:>8.3} ({with})   (same outages without bursts {:.3} ({without}))",
                p.name(),
                burst,
                clean
            );
        }
    }
}
